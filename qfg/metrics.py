"""Metrics of a qualitative estimate against ground truth, and of its information.

Every function takes estimates ``p`` of shape (..., m) (probability vectors over m states) and,
for ground-truth metrics, 0-based true states ``g`` of shape (...); it returns shape (...).
Natural logarithms throughout (conventions.md).

>>> import numpy as np
>>> u = np.full(20, 1 / 20)
>>> round(float(dmse(u, 3)), 3), round(float(entropy(u)), 3), float(information_score(u))
(0.975, 2.996, 0.0)
"""

from __future__ import annotations

import numpy as np

from ._validate import as_float_array

__all__ = [
    "dmse",
    "gt_rating",
    "gmd",
    "gt_likelihood",
    "gt_likelihood_ratio",
    "entropy",
    "likelihood_ratio",
    "information_score",
    "evaluate",
    "GT_METRICS",
    "INFO_METRICS",
]

#: Tolerance on sum(p) = 1.
SUM_TOL = 1e-6


def _probs(p) -> np.ndarray:
    p = as_float_array("p", p, min_ndim=1)
    if p.shape[-1] < 2:
        raise ValueError(f"p: expected at least 2 states on the last axis, got shape {p.shape}")
    if np.any(p < 0):
        raise ValueError("p: negative probabilities")
    s = p.sum(axis=-1)
    if np.any(np.abs(s - 1.0) > SUM_TOL):
        worst = float(s.flat[np.argmax(np.abs(s - 1.0))])
        raise ValueError(f"p: each estimate must sum to 1 (found a sum of {worst:.6g})")
    return p


def _truth(p, g) -> np.ndarray:
    g = np.asarray(g)
    if not np.issubdtype(g.dtype, np.integer):
        raise ValueError(f"g: expected integer states, got dtype {g.dtype}")
    m = p.shape[-1]
    if np.any((g < 0) | (g >= m)):
        raise ValueError(f"g: states must be in 0..{m - 1}")
    try:
        np.broadcast_shapes(g.shape, p.shape[:-1])
    except ValueError:
        raise ValueError(f"g: shape {g.shape} does not match estimates {p.shape}") from None
    return np.broadcast_to(g, p.shape[:-1])


def _pg(p, g):
    return np.take_along_axis(p, g[..., None], axis=-1)[..., 0]


def dmse(p, g) -> np.ndarray:
    """``sqrt(sum_i (p_i - [i = g])^2)``: distance to the one-hot truth (uniform EDC: 0.975)."""
    p = _probs(p)
    g = _truth(p, g)
    onehot = np.arange(p.shape[-1]) == g[..., None]
    return np.sqrt(np.sum((p - onehot) ** 2, axis=-1))


def gt_rating(p, g) -> np.ndarray:
    """``1 + #{i : p_i > p_g}``: rank of the truth (1 = most likely; ties favour the truth)."""
    p = _probs(p)
    g = _truth(p, g)
    return 1 + np.sum(p > _pg(p, g)[..., None], axis=-1)


def gmd(p, g, centroids) -> np.ndarray:
    """``sum_i p_i |c_i - c_g|``: expected distance (units of |AB|) from the truth's centroid."""
    p = _probs(p)
    g = _truth(p, g)
    c = as_float_array("centroids", centroids, ndim=2, last_dim=2)
    if c.shape[0] != p.shape[-1]:
        raise ValueError(f"centroids: expected {p.shape[-1]} rows, got {c.shape[0]}")
    dist = np.linalg.norm(c[None, :, :] - c[:, None, :], axis=-1)  # (m, m)
    return np.sum(p * dist[g], axis=-1)


def gt_likelihood(p, g) -> np.ndarray:
    """``p_g``: the probability given to the true state."""
    p = _probs(p)
    return _pg(p, _truth(p, g))


def gt_likelihood_ratio(p, g) -> np.ndarray:
    """``p_g / max_i p_i`` (1 when the truth is a most likely state)."""
    p = _probs(p)
    return _pg(p, _truth(p, g)) / p.max(axis=-1)


def entropy(p) -> np.ndarray:
    """``-sum_i p_i log p_i`` with 0 log 0 = 0 (uniform over 20 states: log 20 = 3.00)."""
    p = _probs(p)
    safe = np.where(p > 0, p, 1.0)
    return -np.sum(p * np.log(safe), axis=-1)


def likelihood_ratio(p) -> np.ndarray:
    """Second largest ``p_i`` over the largest: how decisive the estimate is (0 = decisive)."""
    p = _probs(p)
    top2 = -np.partition(-p, 1, axis=-1)[..., :2]
    return top2[..., 1] / top2[..., 0]


def information_score(p) -> np.ndarray:
    """``ISC = (log m - H) / log m`` in [0, 1]: 0 for uniform, 1 for a certain state."""
    p = _probs(p)
    hmax = np.log(p.shape[-1])
    return np.clip((hmax - entropy(p)) / hmax, 0.0, 1.0)


GT_METRICS = ("dmse", "gt_rating", "gmd", "gt_likelihood", "gt_likelihood_ratio")
INFO_METRICS = ("entropy", "likelihood_ratio", "information_score")


def evaluate(p, g, centroids) -> dict[str, np.ndarray]:
    """All metrics at once: a dict name -> array of shape (...)."""
    return {
        "dmse": dmse(p, g),
        "gt_rating": gt_rating(p, g),
        "gmd": gmd(p, g, centroids),
        "gt_likelihood": gt_likelihood(p, g),
        "gt_likelihood_ratio": gt_likelihood_ratio(p, g),
        "entropy": entropy(p),
        "likelihood_ratio": likelihood_ratio(p),
        "information_score": information_score(p),
    }
