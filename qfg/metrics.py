"""Metrics of a qualitative estimate against ground truth, and of its information.

Every function takes estimates ``p`` of shape (..., m) (probability vectors over m states) and,
for ground-truth metrics, 0-based true states ``g`` of shape (...); it returns shape (...).
Natural logarithms throughout (conventions.md).

>>> import numpy as np
>>> u = np.full(20, 1 / 20)
>>> round(float(dmse(u, 3)), 3), round(float(entropy(u)), 3), float(information_score(u))
(0.975, 2.996, 0.0)
>>> float(gt_rating(u, 3)), round(float(log_score(u, 3)), 3)
(10.5, -2.996)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import as_float_array, positive_int

__all__ = [
    "dmse",
    "gt_rating",
    "gmd",
    "gt_likelihood",
    "gt_likelihood_ratio",
    "log_score",
    "brier",
    "truth_under",
    "expected_log_score",
    "expected_truth_under",
    "clustered_se",
    "Reliability",
    "reliability",
    "expected_calibration_error",
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


def _clip(clip) -> float:
    c = float(clip)
    if not (0 < c <= 1):
        raise ValueError(f"clip: expected a number in (0, 1], got {clip!r}")
    return c


def _pg(p, g):
    return np.take_along_axis(p, g[..., None], axis=-1)[..., 0]


def dmse(p, g) -> np.ndarray:
    """``sqrt(sum_i (p_i - [i = g])^2)``: distance to the one-hot truth (uniform EDC: 0.975)."""
    p = _probs(p)
    g = _truth(p, g)
    onehot = np.arange(p.shape[-1]) == g[..., None]
    return np.sqrt(np.sum((p - onehot) ** 2, axis=-1))


#: Two probabilities closer than this count as tied in :func:`gt_rating`.
TIE_TOL = 1e-12


def gt_rating(p, g) -> np.ndarray:
    """Expected rank of the truth with ties split evenly:
    ``1 + #{i : p_i > p_g} + #{i != g : p_i = p_g} / 2`` (1 = the single most likely state; equal
    within :data:`TIE_TOL`). It is the mean rank over the orderings of tied states, so a uniform
    estimate over m states rates (m + 1) / 2, not 1.

    >>> float(gt_rating([0.5, 0.3, 0.2], 1)), float(gt_rating([0.25] * 4, 0))
    (2.0, 2.5)
    """
    p = _probs(p)
    g = _truth(p, g)
    pg = _pg(p, g)[..., None]
    above = np.sum(p > pg + TIE_TOL, axis=-1)
    tied = np.sum(np.abs(p - pg) <= TIE_TOL, axis=-1) - 1          # the truth itself excluded
    return 1.0 + above + 0.5 * tied


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


def log_score(p, g, clip: float = 1e-4) -> np.ndarray:
    """``log(max(p_g, clip))``: the (clipped) logarithmic score of each estimate, in nats; higher
    is better, 0 for certainty on the truth. Its mean over estimates is the proper score the
    solvers are compared by; the clip keeps one zero-probability truth from dominating a mean.

    >>> round(float(log_score([0.5, 0.3, 0.2], 1)), 4), round(float(log_score([1.0, 0.0], 1)), 4)
    (-1.204, -9.2103)
    """
    p = _probs(p)
    return np.log(np.maximum(_pg(p, _truth(p, g)), _clip(clip)))


def brier(p, g) -> np.ndarray:
    """Multi-class Brier score ``sum_s (p_s - 1[s = g])^2`` in [0, 2] (lower is better; it is
    ``dmse**2``); strictly proper.

    >>> round(float(brier([0.5, 0.3, 0.2], 1)), 4)
    0.78
    """
    p = _probs(p)
    onehot = np.arange(p.shape[-1]) == _truth(p, g)[..., None]
    return np.sum((p - onehot) ** 2, axis=-1)


def truth_under(p, g, threshold: float = 0.01) -> np.ndarray:
    """``p_g < threshold``: the truth was given under ``threshold`` (bool per estimate; the mean is
    the fraction of truths under it).

    >>> truth_under([[0.995, 0.005], [0.5, 0.5]], [1, 1]).tolist()
    [True, False]
    """
    p = _probs(p)
    return _pg(p, _truth(p, g)) < float(threshold)


def expected_log_score(p, clip: float = 1e-4) -> np.ndarray:
    """``sum_s p_s log(max(p_s, clip))``: the :func:`log_score` an estimate expects of itself,
    its mean over truths drawn from the estimate. Over many estimates, a calibrated forecaster's
    mean log score equals the mean of this up to sampling error; a mean log score below it says
    the truths are less likely than the estimates claim (over-confidence, or a model that does
    not fit the data), with no reference solver needed. ``-entropy(p)`` but for the clip.

    >>> round(float(expected_log_score([0.5, 0.5])), 4), round(float(expected_log_score([1.0, 0.0])), 4)
    (-0.6931, 0.0)
    """
    p = _probs(p)
    return np.sum(p * np.log(np.maximum(p, _clip(clip))), axis=-1)


def expected_truth_under(p, threshold: float = 0.01) -> np.ndarray:
    """``sum_s p_s 1[p_s < threshold]``: the chance an estimate gives itself of :func:`truth_under`
    (its truth in a state it gives under ``threshold``). The mean over estimates is the share of
    truths under ``threshold`` that calibrated estimates would show; it is at most
    ``m * threshold`` for m states, and usually far below that bound.

    >>> round(float(expected_truth_under([0.995, 0.005])), 4), float(expected_truth_under([0.5, 0.5]))
    (0.005, 0.0)
    """
    p = _probs(p)
    return np.sum(np.where(p < float(threshold), p, 0.0), axis=-1)


@dataclass(frozen=True)
class Reliability:
    """Reliability (calibration) table of probabilistic estimates, per probability bin.

    Attributes (bins of equal width on [0, 1]; the last bin includes 1):
        edges: (bins + 1,) bin edges.
        top_confidence: (bins,) mean probability of the most likely state, over the estimates
            whose top probability falls in the bin (NaN where the bin is empty).
        top_accuracy: (bins,) fraction of those estimates whose most likely state is the truth.
        top_count: (bins,) number of estimates in the bin.
        all_confidence: (bins,) mean probability over every (estimate, state) pair in the bin.
        all_frequency: (bins,) fraction of those pairs whose state is the truth.
        all_count: (bins,) number of pairs in the bin.

    A calibrated forecaster has confidence = accuracy (frequency) in every bin, up to sampling
    error ~ sqrt(c (1 - c) / count).
    """

    edges: np.ndarray
    top_confidence: np.ndarray
    top_accuracy: np.ndarray
    top_count: np.ndarray
    all_confidence: np.ndarray
    all_frequency: np.ndarray
    all_count: np.ndarray


def clustered_se(values, cluster) -> float:
    """Standard error of the mean of ``values`` (n,) whose members sharing a ``cluster`` label
    (n,) are dependent (the orderings of one landmark set, the triplets of one graph):
    ``sqrt(sum_c (sum_{i in c} (v_i - mean))^2) / n``, the cluster-robust sandwich estimate.
    With one value per cluster it is the plain ``std(ddof=0) / sqrt(n)``; 0 for fewer than two
    values. Labels may be any values numpy can sort (ints, strings).

    >>> v = np.array([1.0, 1.0, -1.0, -1.0])
    >>> round(clustered_se(v, [0, 0, 1, 1]), 3), round(clustered_se(v, ["a", "b", "c", "d"]), 3)
    (0.707, 0.5)
    """
    v = np.asarray(values, dtype=float).ravel()
    c = np.asarray(cluster).ravel()
    if c.size != v.size:
        raise ValueError(f"clustered_se: {v.size} values but {c.size} cluster labels")
    if v.size < 2:
        return 0.0
    ids = np.unique(c, return_inverse=True)[1].ravel()
    res = np.bincount(ids, weights=v - v.mean())
    return float(np.sqrt(np.sum(res ** 2)) / v.size)


def _binned(conf, hit, edges):
    b = np.clip(np.searchsorted(edges, conf, side="right") - 1, 0, edges.size - 2)
    nb = edges.size - 1
    cnt = np.bincount(b, minlength=nb)
    sc = np.bincount(b, weights=conf, minlength=nb)
    sh = np.bincount(b, weights=hit.astype(float), minlength=nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(cnt > 0, sc / cnt, np.nan), np.where(cnt > 0, sh / cnt, np.nan), cnt


def reliability(p, g, bins: int = 10) -> Reliability:
    """Reliability table of estimates ``p`` (..., m) against truths ``g`` (...), for the top
    state (confidence ``max_s p_s``, hit ``argmax = g``) and for every state (confidence ``p_s``,
    hit ``s = g``). Ties for the top state go to the lowest index.

    >>> r = reliability([[0.9, 0.1], [0.6, 0.4]], [0, 1], bins=2)
    >>> r.top_count.tolist(), r.top_accuracy.tolist(), r.all_count.tolist()
    ([0, 2], [nan, 0.5], [2, 2])
    """
    p = _probs(p)
    g = _truth(p, g)
    nb = positive_int("bins", bins)
    edges = np.linspace(0.0, 1.0, nb + 1)
    flat = p.reshape(-1, p.shape[-1])
    gf = g.reshape(-1)
    top = np.argmax(flat, axis=-1) if flat.size else np.zeros(0, int)
    tc, ta, tn = _binned(flat.max(axis=-1, initial=0.0), top == gf, edges)
    onehot = np.arange(p.shape[-1])[None, :] == gf[:, None]
    ac, af, an = _binned(flat.ravel(), onehot.ravel(), edges)
    return Reliability(edges=edges, top_confidence=tc, top_accuracy=ta, top_count=tn,
                       all_confidence=ac, all_frequency=af, all_count=an)


def expected_calibration_error(p, g, bins: int = 10, kind: str = "top") -> float:
    """``ECE = sum_b (n_b / n) |accuracy_b - confidence_b|`` over the non-empty bins of
    :func:`reliability`; ``kind="top"`` for the top state, ``"all"`` for every (estimate, state)
    pair. 0 for a perfectly calibrated table (it is biased upwards by sampling noise in
    small bins).

    >>> round(expected_calibration_error([[0.9, 0.1], [0.6, 0.4]], [0, 1], bins=2), 3)
    0.25
    """
    if kind not in ("top", "all"):
        raise ValueError(f"kind: expected 'top' or 'all', got {kind!r}")
    r = reliability(p, g, bins)
    conf, acc, cnt = ((r.top_confidence, r.top_accuracy, r.top_count) if kind == "top" else
                      (r.all_confidence, r.all_frequency, r.all_count))
    n = cnt.sum()
    if n == 0:
        return 0.0
    ok = cnt > 0
    return float(np.sum(cnt[ok] * np.abs(acc[ok] - conf[ok])) / n)


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


GT_METRICS = ("dmse", "gt_rating", "gmd", "gt_likelihood", "gt_likelihood_ratio", "log_score",
              "brier", "truth_under_1pct")
INFO_METRICS = ("entropy", "likelihood_ratio", "information_score")


def evaluate(p, g, centroids) -> dict[str, np.ndarray]:
    """All metrics at once: a dict name -> array of shape (...)."""
    return {
        "dmse": dmse(p, g),
        "gt_rating": gt_rating(p, g),
        "gmd": gmd(p, g, centroids),
        "gt_likelihood": gt_likelihood(p, g),
        "gt_likelihood_ratio": gt_likelihood_ratio(p, g),
        "log_score": log_score(p, g),
        "brier": brier(p, g),
        "truth_under_1pct": truth_under(p, g, 0.01).astype(float),
        "entropy": entropy(p),
        "likelihood_ratio": likelihood_ratio(p),
        "information_score": information_score(p),
    }
