"""Likelihood arithmetic in log space: the Gaussian kernel, log-sum-exp, normalization, sums
over the (short) views axis.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians; lengths in |AB|.
"""

from __future__ import annotations

from dataclasses import dataclass

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
    if axis in (1, -1) and a.ndim == 2 and 0 < a.shape[1] < 8:
        # a few columns (C samples per trajectory): the same sums in the same order as numpy's
        # reduction of fewer than 8 elements, over the transposed view's rows (7x faster)
        return logsumexp(a.T, axis=0)
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


def logaddexp(a, b) -> np.ndarray:
    """``log(exp(a) + exp(b))`` elementwise: ``max(a, b) + log1p(exp(-|a - b|))``, the max itself
    where both are the same infinity; ``np.logaddexp``'s values to rounding
    (``tests/test_sis_fast_math.py``) at a tenth of its cost (numpy's is a scalar loop, about 20
    ns an element here).

    >>> round(float(logaddexp(np.log(1.0), np.log(3.0))), 12), float(logaddexp(-np.inf, -np.inf))
    (1.38629436112, -inf)
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    mx = np.maximum(a, b)
    with np.errstate(invalid="ignore"):
        d = -np.abs(a - b)
    out = mx + np.log1p(np.exp(d))
    # a - b is NaN where both are the same infinity: the sum is that infinity
    return np.where(np.isnan(d) & ~np.isnan(mx), mx, out)


_HALF_LOG_2PI = 0.5 * np.log(2.0 * np.pi)


@dataclass(frozen=True)
class BearingTail:
    """A heavy-tailed bearing-noise model: the normal of width sigma (the history's
    ``sigma_bearing``, the core), a wider normal and a uniform outlier share on the circle,

        p(r) = (1 - share - outlier) N(r; sigma) + share N(r; scale sigma) + outlier / (2 pi).

    ``share``, ``outlier`` in [0, 1) with ``share + outlier < 1``; ``scale`` >= 1. Measured on
    MRCLAM against motion capture (docs/mrclam.md): sigma 0.345 deg, share 0.271, scale 2.79,
    outlier 0.0011 (:data:`qfg.datasets.mrclam` ``DEFAULT_BEARING_TAIL``).

    >>> t = BearingTail(share=0.2, scale=3.0, outlier=0.01)
    >>> round(float(log_bearing(0.0, 0.01, t)), 4), round(float(log_bearing(1.0, 0.01, t)), 4)
    (3.5316, -6.443)
    """

    share: float = 0.0
    scale: float = 1.0
    outlier: float = 0.0

    def __post_init__(self):
        for k in ("share", "scale", "outlier"):
            v = getattr(self, k)
            if not isinstance(v, (int, float, np.floating, np.integer)) or not np.isfinite(v):
                raise ValueError(f"bearing_tail: {k} expected a finite number, got {v!r}")
        if not (0 <= self.share < 1 and 0 <= self.outlier < 1 and self.share + self.outlier < 1):
            raise ValueError(f"bearing_tail: expected share, outlier >= 0 with share + outlier "
                             f"< 1, got share={self.share}, outlier={self.outlier}")
        if self.scale < 1:
            raise ValueError(f"bearing_tail: scale expected >= 1, got {self.scale}")

    @property
    def active(self) -> bool:
        return self.share > 0 or self.outlier > 0

    @property
    def width_factor(self) -> float:
        """Standard deviation of the normal part of the mixture over sigma: the width the
        proposals of C use (a proposal as narrow as the core would miss the wide component)."""
        core = 1.0 - self.share - self.outlier
        return float(np.sqrt((core + self.share * self.scale ** 2) / (core + self.share)))


def as_tail(value) -> BearingTail | None:
    """The option ``bearing_tail``: None (the normal), a :class:`BearingTail`, a tuple
    ``(share, scale, outlier)`` or a dict of those; a tail with no share is None."""
    if value is None:
        return None
    if isinstance(value, BearingTail):
        t = value
    elif isinstance(value, dict):
        t = BearingTail(**value)
    else:
        try:
            t = BearingTail(*value)
        except TypeError:
            raise ValueError(f"bearing_tail: expected None, a BearingTail or (share, scale, "
                             f"outlier), got {value!r}") from None
    return t if t.active else None


def as_normal_tail(value, name: str) -> BearingTail | None:
    """The options ``distance_tail`` and ``heading_tail`` (``name``): None (the normal),
    ``(share, scale)``, a dict of those or a :class:`BearingTail` without outliers (a uniform
    share has no meaning on an unbounded log ratio, and the motion step draws no outlier
    headings); a tail with no share is None.

    >>> as_normal_tail((0.1, 7.0), "distance_tail")
    BearingTail(share=0.1, scale=7.0, outlier=0.0)
    """
    if value is None:
        return None
    if not isinstance(value, (BearingTail, dict)):
        try:
            share, scale = value
        except (TypeError, ValueError):
            raise ValueError(f"{name}: expected None or (share, scale), got "
                             f"{value!r}") from None
        value = {"share": share, "scale": scale}
    try:
        t = value if isinstance(value, BearingTail) else BearingTail(**value)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: {e}".replace("bearing_tail: ", "")) from None
    if t.outlier:
        raise ValueError(f"{name}: expected no outlier share, got {t.outlier}")
    return t if t.active else None


def log_bearing(residual, sigma, tail: BearingTail | None = None):
    """Normalized log density of bearing residuals (radians) under the normal of width
    ``sigma`` or, with ``tail``, under the :class:`BearingTail` mixture. Broadcasts.

    >>> bool(np.isclose(log_bearing(0.0, 1.0), -0.5 * np.log(2 * np.pi)))
    True
    """
    r = np.asarray(residual, dtype=float)
    ln = log_gauss(r, sigma) - _HALF_LOG_2PI
    if tail is None:
        return ln
    lw = log_gauss(r, tail.scale * sigma) - _HALF_LOG_2PI
    core = 1.0 - tail.share - tail.outlier
    with np.errstate(divide="ignore"):
        out = np.logaddexp(np.log(core) + ln, np.log(tail.share) + lw if tail.share > 0
                           else -np.inf)
        if tail.outlier > 0:
            out = np.logaddexp(out, np.log(tail.outlier) - np.log(2.0 * np.pi))
    return out


def bearing_noise(z, u, v, sigma, tail: BearingTail | None, spread: float = 1.0):
    """Draws of bearing noise from the :class:`BearingTail` mixture with its normal components
    ``spread`` times wider: ``z`` standard normals, ``u`` uniforms choosing the component, ``v``
    uniforms placing an outlier on (-pi, pi) (outliers are never spread). Without a tail,
    ``spread sigma z``. Broadcasts.

    >>> bearing_noise(np.array([1.0, 1.0, 1.0]), np.array([0.5, 0.05, 0.001]),
    ...               np.array([0.5, 0.5, 0.75]), 0.1, BearingTail(0.1, 3.0, 0.01)).round(4)
    array([0.1   , 0.3   , 1.5708])
    """
    z = np.asarray(z, dtype=float)
    if tail is None:
        return spread * sigma * z
    width = np.where(u < tail.outlier + tail.share, tail.scale, 1.0) * spread * sigma * z
    return np.where(u < tail.outlier, np.pi * (2.0 * np.asarray(v) - 1.0), width)


def log_bearing_proposal(x, sigma, tail: BearingTail | None, spread: float):
    """Log density of :func:`bearing_noise` draws ``x`` (the mixture with its normal components
    ``spread`` times wider; the outlier share uniform on (-pi, pi)), for the importance weight
    ``log_bearing(x) - log_bearing_proposal(x)``. With ``spread`` 1 it is :func:`log_bearing`.

    >>> t = BearingTail(0.2, 3.0, 0.01)
    >>> bool(np.isclose(log_bearing_proposal(0.3, 0.1, t, 1.0), log_bearing(0.3, 0.1, t)))
    True
    """
    if tail is None or spread == 1.0 or tail.outlier <= 0:
        return log_bearing(x, spread * sigma, tail)
    x = np.asarray(x, dtype=float)
    # the normal components at spread * sigma; the uniform part only inside (-pi, pi)
    normal = log_bearing(x, spread * sigma, BearingTail(tail.share / (1.0 - tail.outlier),
                                                        tail.scale, 0.0)) + np.log1p(-tail.outlier)
    return np.logaddexp(normal, np.where(np.abs(x) <= np.pi,
                                         np.log(tail.outlier) - np.log(2.0 * np.pi), -np.inf))
