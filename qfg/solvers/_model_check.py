"""A check that notices when a history's bearings and headings contradict the model, and the
widening of an answer that fails it.

The check is a posterior predictive check (Gelman, Meng and Stern 1996) with the discrepancy

    D(y, theta) = sum_bearings d(r / sigma_v) + sum_headings (r / sigma_w)^2,

``r`` the residuals of the measured bearings (A, B and C of every view) and headings at a
configuration theta = [C, X_1..X_n] (AB frame), ``d(u) = -2 log(p(u) / p(0))`` the deviance of
the bearing noise (``u^2`` for the normal; for a :class:`._likelihood.BearingTail` its
mixture's). Replicated data given theta have residuals that are the noise itself, so
``D(y_rep, theta)`` has a known distribution F (chi-square with 3n + n - 1 degrees of freedom for
normal noise; for a tail, the sum of the mixture's deviances, tabulated by simulation once per
shape), and the posterior predictive p-value is exact given the posterior sample:

    p = P(D(y_rep, theta) >= D(y, theta) | y) = sum_j w_j (1 - F(D(y, theta_j))).

A small p says no configuration the posterior holds explains the measurements at the stated
noise. The odometry's distance ratios are not in D. The check can only see what the data
over-determine: 3n bearings and n - 1 headings against 3n + 2 unknowns (C and the poses, A and B
fixed by the frame) leave n - 3 degrees of freedom, so with 3 views it rests on the prior's
constraints and one redundant measurement, and a history without headings (the baseline model)
has nothing to check.

An answer with ``p < level`` is widened toward the prior's state distribution q (what the prior
alone says): ``(1 - lam) P + lam q`` with ``lam = 1 - p / level``, so the answer moves all the
way to the prior as p goes to 0; it is also flagged.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.special import chdtrc

from ..geometry import bearing, motion_heading, wrap_angle
from ._likelihood import BearingTail, log_bearing

#: Draws of the tabulated reference distribution of D under a bearing tail.
REFERENCE_DRAWS = 20_000


def residuals(bearings, headings, poses, landmark):
    """Residuals of the measurements at configurations: ``bearings`` (n, 3), ``headings``
    (n - 1,) or None, ``poses`` (n, K, 3) camera poses (x, y, alpha), ``landmark`` (K, 2) C
    (None: ``bearings`` (n, 2) of A and B only). Returns (bearing residuals (n, 3, K), heading
    residuals (n - 1, K)), wrapped to (-pi, pi].

    >>> P = np.array([[[-1.0, 0.0, 0.0]]])       # one view at (-1, 0) facing +x
    >>> rb, rh = residuals(np.array([[0.0, np.pi / 4, 0.1]]), None, P, np.array([[0.0, -1.0]]))
    >>> np.round(rb[0, :, 0], 4).tolist(), rh.shape
    ([0.0, 0.0, 0.8854], (0, 1))
    """
    P = np.asarray(poses, dtype=float)
    ab = [bearing(P, np.zeros(2)), bearing(P, np.array([0.0, 1.0]))]
    if landmark is not None:
        ab.append(bearing(P, np.broadcast_to(np.asarray(landmark, dtype=float),
                                             P.shape[1:2] + (2,))[None]))
    pred = np.stack(ab, axis=1)
    rb = wrap_angle(np.asarray(bearings, dtype=float)[:, :, None] - pred)
    n = P.shape[0]
    if headings is None or n < 2:
        return rb, np.zeros((max(n - 1, 0), P.shape[1]))
    g = motion_heading(P[:-1], P[1:, :, :2])
    return rb, wrap_angle(np.asarray(headings, dtype=float)[:, None] - g)


def discrepancy(rb, rh, sigma_bearing, sigma_heading, tail: BearingTail | None = None):
    """(K,) the discrepancy D of residuals ``rb`` (n, 3, K) and ``rh`` (n - 1, K): bearing
    deviances under the normal of width ``sigma_bearing`` (or ``tail``'s mixture) plus squared
    standardized heading residuals.

    >>> float(discrepancy(np.full((1, 3, 1), 0.02), np.zeros((0, 1)), 0.01, 0.1)[0])
    12.0
    """
    u = np.asarray(rb, dtype=float)
    d = -2.0 * (log_bearing(u, sigma_bearing, tail) - log_bearing(0.0, sigma_bearing, tail))
    out = d.reshape(-1, d.shape[-1]).sum(axis=0)
    sh = np.asarray(sigma_heading, dtype=float)
    if rh.size and np.all(sh > 0):
        with np.errstate(over="ignore"):   # inf: a residual the model cannot explain (p = 0)
            # one sigma, or one per step (n - 1,)
            out = out + np.sum((np.asarray(rh) / (sh[:, None] if sh.ndim else sh)) ** 2, axis=0)
    return out


@lru_cache(maxsize=64)
def _reference_table(n_bearings: int, n_headings: int, tail: BearingTail,
                     sigma: float) -> np.ndarray:
    """Sorted draws of D under the model: ``n_bearings`` deviances of the tail's mixture (core
    width ``sigma``: the outlier share's density is per radian, so D depends on it) plus a
    chi-square with ``n_headings`` degrees of freedom."""
    from ._likelihood import bearing_noise

    rng = np.random.default_rng(20201)
    R = REFERENCE_DRAWS
    e = bearing_noise(rng.standard_normal((R, n_bearings)), rng.random((R, n_bearings)),
                      rng.random((R, n_bearings)), sigma, tail)
    e = wrap_angle(e)
    D = np.sum(-2.0 * (log_bearing(e, sigma, tail) - log_bearing(0.0, sigma, tail)), axis=1)
    if n_headings:
        D = D + rng.chisquare(n_headings, R)
    return np.sort(D)


def reference_sf(D, n_bearings: int, n_headings: int, tail: BearingTail | None = None,
                 sigma_bearing: float = 1.0):
    """P(D(y_rep, theta) >= D) under the model, for an array ``D``: the chi-square survival
    function with ``n_bearings + n_headings`` degrees of freedom for normal noise; with a tail,
    the tabulated distribution at core width ``sigma_bearing`` (add-one estimate, never 0).

    >>> round(float(reference_sf(np.array([9.0]), 9, 0)[0]), 4)
    0.4373
    """
    D = np.asarray(D, dtype=float)
    if tail is None:
        return chdtrc(n_bearings + n_headings, D)    # chi2.sf's function, without its wrapper
    tab = _reference_table(int(n_bearings), int(n_headings), tail, float(sigma_bearing))
    above = tab.size - np.searchsorted(tab, D, side="left")
    return (above + 1.0) / (tab.size + 1.0)


def posterior_predictive_p(bearings, headings, poses, landmark, weights, sigma_bearing,
                           sigma_heading, tail: BearingTail | None = None,
                           per_pose: int = 1) -> float:
    """The posterior predictive p-value of the measurements given a weighted posterior sample
    (``poses`` (n, K, 3) with ``landmark`` (K, 2), ``weights`` (K,) summing to 1); NaN when the
    sample is empty. See the module docstring. With ``per_pose`` r > 1 the sample holds r
    landmarks per trajectory: ``poses`` (n, K / r, 3), trajectory j's landmarks
    ``landmark[j r:(j + 1) r]`` (its A, B and heading residuals are computed once).

    >>> P = np.array([[[-1.0, 0.0, 0.0]], [[-1.0, 1.0, 0.0]]])     # two views, one trajectory
    >>> b = np.array([[0.0, np.pi / 4, 0.0], [-np.pi / 4, 0.0, 0.0]])
    >>> L = np.array([[1.0, 0.0], [1.0, 0.1]])
    >>> a = posterior_predictive_p(b, [0.5], P, L, [0.5, 0.5], 0.01, 0.1, per_pose=2)
    >>> c = posterior_predictive_p(b, [0.5], np.repeat(P, 2, axis=1), L, [0.5, 0.5], 0.01, 0.1)
    >>> bool(np.isclose(a, c))
    True
    """
    w = np.asarray(weights, dtype=float)
    if w.size == 0 or not np.any(w > 0):
        return float("nan")
    if per_pose == 1:
        keep = w > 0
        rb, rh = residuals(bearings, headings, poses[:, keep], np.asarray(landmark)[keep])
        D = discrepancy(rb, rh, sigma_bearing, sigma_heading, tail)
        n_b, n_h = rb.shape[0] * 3, rh.shape[0]
    else:
        P, L = np.asarray(poses, dtype=float), np.asarray(landmark, dtype=float)
        n, J = P.shape[:2]
        if L.shape[0] != J * per_pose or w.size != J * per_pose:
            raise ValueError(f"landmark, weights: expected {J} x per_pose = {J * per_pose} rows, "
                             f"got {L.shape[0]} and {w.size}")
        # A, B and the headings per trajectory; C per (trajectory, landmark)
        rb, rh = residuals(np.asarray(bearings, dtype=float)[:, :2], headings, P, None)
        d = discrepancy(rb, rh, sigma_bearing, sigma_heading, tail)
        rc = wrap_angle(np.asarray(bearings, dtype=float)[:, 2:3]
                        - bearing(np.repeat(P, per_pose, axis=1), L[None]))
        D = np.repeat(d, per_pose) + discrepancy(rc[:, None], np.zeros((0, rc.shape[1])),
                                                 sigma_bearing, 0.0, tail)
        keep = w > 0
        D = D[keep]
        n_b, n_h = n * 3, rh.shape[0]
    sf = reference_sf(D, n_b, n_h if np.all(np.asarray(sigma_heading) > 0) else 0, tail,
                      sigma_bearing)
    return float(np.sum(w[keep] * sf) / np.sum(w[keep]))


def widening(p: float, level: float) -> float:
    """Share of the prior's state distribution mixed into an answer whose check gave ``p``
    at ``level``: ``1 - p / level`` below the level, else 0 (and 0 when p is NaN).

    >>> widening(0.0, 0.01), widening(0.005, 0.01), widening(0.2, 0.01)
    (1.0, 0.5, 0.0)
    """
    if not level > 0 or not np.isfinite(p) or p >= level:
        return 0.0
    return float(min(1.0, max(0.0, 1.0 - p / level)))


_PRIOR_STATES: dict = {}


def prior_states(prior, part) -> tuple[np.ndarray, np.ndarray]:
    """(C's (m,), one camera's (m,)) state distributions under ``prior`` alone
    (:func:`qfg.combine.prior_state_distribution`, 50,000 draws, cached per prior and
    partition)."""
    from ..combine import prior_state_distribution

    key = (type(prior).__name__, repr(prior), part.name)
    if key not in _PRIOR_STATES:
        if len(_PRIOR_STATES) > 32:
            _PRIOR_STATES.clear()
        _PRIOR_STATES[key] = tuple(
            prior_state_distribution(prior, part, point=k, n_cameras=k, samples=50_000, seed=7)
            for k in (0, 1))
    return _PRIOR_STATES[key]
