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
    m = part.n_states
    p = np.bincount(s, weights=w, minlength=m)
    w2 = w * w
    a = np.bincount(s, weights=w2, minlength=m)           # sum over i in s of w_i^2
    tot = w2.sum()
    var = a * (1 - p) ** 2 + (tot - a) * p**2
    return float(np.sqrt(var.max()))


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
