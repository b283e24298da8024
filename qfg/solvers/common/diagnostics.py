"""Importance-sampling diagnostics of a weighted sample: the Pareto k-hat of the weights' upper
tail (Vehtari, Simpson, Gelman, Yao and Gabry, "Pareto smoothed importance sampling", JMLR 2024).

k-hat estimates the shape of a generalized Pareto distribution fitted to the largest weights:
the weights have finite variance for k < 1/2, and above about 0.7 a self-normalized estimate is
unreliable whatever its ESS says (the ESS itself is computed from the same heavy-tailed weights).
"""

from __future__ import annotations

import numpy as np


def pareto_k(log_weights) -> float:
    """Pareto k-hat of importance weights given as logs (any shape; -inf entries ignored): the
    shape of a generalized Pareto fitted (Zhang and Stephens 2009, with the weakly informative
    prior of the PSIS paper) to the exceedances of the ``M = min(0.2 S, 3 sqrt(S))`` largest of
    the S weights over the next one. NaN with fewer than 100 positive weights (the fit of a
    handful of tail points is meaningless) or a flat tail.

    >>> rng = np.random.default_rng(0)
    >>> round(pareto_k(-0.3 * np.log(rng.random(20000))), 1)    # Pareto tail of shape 0.3
    0.3
    """
    lw = np.asarray(log_weights, dtype=float).ravel()
    lw = np.sort(lw[np.isfinite(lw)])
    S = lw.size
    if S < 100:
        return float("nan")
    M = int(min(np.ceil(0.2 * S), np.ceil(3.0 * np.sqrt(S))))
    x = np.exp(lw[-M:] - lw[-1]) - np.exp(lw[-M - 1] - lw[-1])
    x = x[x > 0]
    if x.size < 5:
        return float("nan")
    return _gpd_shape(np.sort(x))


def _gpd_shape(x) -> float:
    """Shape k of a generalized Pareto with location 0 fitted to sorted exceedances ``x`` (n,)
    > 0: the posterior mean of Zhang and Stephens' profile parameter b on a grid, then
    ``k = mean(log(1 - b x))`` (k > 0: heavy tail), shrunk toward 1/2 by 10 pseudo-points."""
    n = x.size
    m = 30 + int(np.sqrt(n))
    j = np.arange(1, m + 1)
    b = 1.0 / x[-1] + (1.0 - np.sqrt(m / (j - 0.5))) / (3.0 * x[int(n / 4 + 0.5) - 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.mean(np.log1p(-b[:, None] * x[None, :]), axis=1)
        L = n * (np.log(-b / k) - k - 1.0)
    L = np.where(np.isfinite(L), L, -np.inf)
    if not np.any(np.isfinite(L)):
        return float("nan")
    w = np.exp(L - L.max())
    bp = float(np.sum(b * w) / np.sum(w))
    kh = float(np.mean(np.log1p(-bp * x)))
    return (n * kh + 10 * 0.5) / (n + 10)
