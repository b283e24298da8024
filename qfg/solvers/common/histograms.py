"""Weighted state histograms of AB-frame points and their Monte Carlo error.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians; lengths in |AB|.
"""

from __future__ import annotations

import numpy as np


def weighted_state_error(part, points, weights) -> float:
    """Monte Carlo standard error of a self-normalized weighted state histogram (delta method:
    ``sqrt(sum_i w_i^2 (1[s_i = s] - p_s)^2)``), the largest over states. ``weights`` sum to 1."""
    w = np.asarray(weights, dtype=float)
    if w.size == 0 or not np.any(w > 0):
        return float("nan")
    s = part.state_of(points)
    return float(weighted_state_errors(s, w, np.zeros(s.size, dtype=np.intp), 1,
                                       part.n_states)[0])


def weighted_state_errors(states, weights, groups, n_groups: int, m: int) -> np.ndarray:
    """:func:`weighted_state_error` of several weighted samples at once: ``states`` (K,) ints in
    [0, m), ``weights`` (K,) summing to 1 within each group, ``groups`` (K,) ints in
    [0, n_groups) -> (n_groups,), NaN for a group without positive weight.

    >>> s, w = np.array([0, 1, 1, 0]), np.array([0.5, 0.5, 0.25, 0.75])
    >>> weighted_state_errors(s, w, np.array([0, 0, 1, 1]), 2, 2).round(4).tolist()
    [0.3536, 0.2652]
    """
    return weighted_state_histograms(states, weights, groups, n_groups, m)[1]


def weighted_state_histograms(states, weights, groups, n_groups: int, m: int) -> tuple:
    """``(p, errors)``: each group's weighted state histogram ``p`` (n_groups, m) and its
    :func:`weighted_state_errors` (n_groups,), from one pass over the samples (the histogram is
    the delta method's mean)."""
    w = np.asarray(weights, dtype=float)
    g = np.asarray(groups, dtype=np.intp)
    cell = g * m + np.asarray(states, dtype=np.intp)
    p = np.bincount(cell, weights=w, minlength=n_groups * m).reshape(n_groups, m)
    w2 = w * w
    # sum over i in s of w_i^2, and over all i
    a = np.bincount(cell, weights=w2, minlength=n_groups * m).reshape(n_groups, m)
    tot = np.bincount(g, weights=w2, minlength=n_groups)[:, None]
    var = a * (1 - p) ** 2 + (tot - a) * p**2
    has = np.bincount(g, weights=w > 0, minlength=n_groups) > 0
    return p, np.where(has, np.sqrt(var.max(axis=1, initial=0.0)), np.nan)


def state_histogram(part, points, weights) -> tuple[np.ndarray, bool]:
    """Weighted histogram of the states of AB-frame ``points`` (J, 2) -> ((m,), ok). Uniform and
    ok = False when the weights are all zero."""
    m = part.n_states
    w = np.asarray(weights, dtype=float)
    if w.size == 0 or not np.any(w > 0):
        return np.full(m, 1.0 / m), False
    keep = w > 0
    s = part.state_of(points[keep])
    h = np.bincount(s, weights=w[keep], minlength=m)[:m]
    return h / h.sum(), True
