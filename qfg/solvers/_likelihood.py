"""Likelihood arithmetic in log space: the Gaussian kernel, log-sum-exp, normalization, sums
over the (short) views axis.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians; lengths in |AB|.
"""

from __future__ import annotations

import numpy as np

NEG_INF = -np.inf


def log_gauss(residual, sigma):
    """Log of a Gaussian likelihood up to a constant: ``-r^2 / (2 sigma^2) - log(sigma)``."""
    r = np.asarray(residual) / sigma
    return -0.5 * r * r - np.log(sigma)


def sum_views(a):
    """Sum over the first axis (views) of an (n, J) array, row by row."""
    out = a[0].copy()
    for r in a[1:]:
        out += r
    return out


def normalize_log(logw: np.ndarray) -> np.ndarray:
    """exp(logw) normalized to sum 1 along the last axis; all -inf rows give all zeros."""
    logw = np.asarray(logw, dtype=float)
    if logw.size == 0:
        return np.zeros_like(logw)
    mx = np.max(logw, axis=-1, keepdims=True)
    ok = np.isfinite(mx)
    w = np.exp(logw - np.where(ok, mx, 0.0))
    w = np.where(ok, w, 0.0)
    s = w.sum(axis=-1, keepdims=True)
    return np.where(s > 0, w / np.where(s > 0, s, 1.0), 0.0)


def logsumexp(a, axis=-1) -> np.ndarray:
    """``log(sum(exp(a)))`` along ``axis``; -inf where every entry is -inf (no warning).

    The same values as ``scipy.special.logsumexp`` (``tests/test_solvers.py`` checks it), kept
    here because scipy's is 2-16x slower on the solvers' shapes (scipy 1.17, 2 cores, unloaded:
    ``benchmarks/bench_solvers.py --logsumexp``; e.g. (3, 4096, 4) over the views axis 0.10 vs
    1.57 ms, (4096, 16) over axis 1 0.29 vs 1.78 ms). Over ``axis=0`` (the short views axis in
    front of many rows) it works on whole rows: numpy's reductions over a short axis are
    several times slower.

    >>> float(logsumexp(np.log([1.0, 2.0, 3.0]))), logsumexp(np.full((2, 3), -np.inf), axis=0)
    (1.791759469228055, array([-inf, -inf, -inf]))
    """
    a = np.asarray(a, dtype=float)
    if axis == 0 and a.ndim >= 2 and a.shape[0] > 0:
        mx = a[0].copy()
        for r in a[1:]:
            np.maximum(mx, r, out=mx)
        ok = np.isfinite(mx)
        m0 = np.where(ok, mx, 0.0)
        s = np.exp(a[0] - m0)
        for r in a[1:]:
            s += np.exp(r - m0)
        with np.errstate(divide="ignore"):
            return np.where(ok, mx + np.log(np.where(ok, s, 1.0)), -np.inf)
    mx = np.max(a, axis=axis, keepdims=True, initial=-np.inf)
    ok = np.isfinite(mx)
    s = np.sum(np.exp(a - np.where(ok, mx, 0.0)), axis=axis, keepdims=True)
    with np.errstate(divide="ignore"):
        out = np.where(ok, mx + np.log(np.where(ok, s, 1.0)), -np.inf)
    return np.squeeze(out, axis=axis)
