"""A check that notices when a history's bearings and headings contradict the model, and the
widening of an answer that fails it.

The check is a posterior predictive check (Gelman, Meng and Stern 1996) with the discrepancy

    D(y, theta) = sum_bearings d(r / sigma_v) + sum_headings (r / sigma_w)^2,

``r`` the residuals of the measured bearings (A, B and C of every view) and headings at a
configuration theta = [C, X_1..X_n] (AB frame), ``d(u) = -2 log(p(u) / p(0))`` the deviance of
the bearing noise (``u^2`` for the normal; for a :class:`.likelihood.BearingTail` its
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

from ...geometry import bearing, motion_heading, wrap_angle
from ..common.likelihood import BearingTail, log_bearing

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


def deviance(u, sigma, tail: BearingTail | None = None) -> np.ndarray:
    """``d(u) = -2 log(p(u) / p(0))`` of bearing residuals ``u`` (radians) under the normal of
    width ``sigma`` or ``tail``'s mixture (broadcasts): ``(u / sigma)^2`` for the normal.

    >>> float(deviance(0.02, 0.01))
    4.0
    """
    return -2.0 * (log_bearing(np.asarray(u, dtype=float), sigma, tail)
                   - log_bearing(0.0, sigma, tail))


def discrepancy(rb, rh, sigma_bearing, sigma_heading, tail: BearingTail | None = None):
    """(K,) the discrepancy D of residuals ``rb`` (n, 3, K) and ``rh`` (n - 1, K): bearing
    deviances under the normal of width ``sigma_bearing`` (or ``tail``'s mixture) plus squared
    standardized heading residuals.

    >>> float(discrepancy(np.full((1, 3, 1), 0.02), np.zeros((0, 1)), 0.01, 0.1)[0])
    12.0
    """
    d = deviance(rb, sigma_bearing, tail)
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
    from ..common.likelihood import bearing_noise

    rng = np.random.default_rng(20201)
    R = REFERENCE_DRAWS
    e = bearing_noise(rng.standard_normal((R, n_bearings)), rng.random((R, n_bearings)),
                      rng.random((R, n_bearings)), sigma, tail)
    D = np.sum(deviance(wrap_angle(e), sigma, tail), axis=1)
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
    ``landmark[j r:(j + 1) r]`` (its A, B and heading residuals are computed once). One triplet
    of :func:`posterior_predictive_batch`.

    >>> P = np.array([[[-1.0, 0.0, 0.0]], [[-1.0, 1.0, 0.0]]])     # two views, one trajectory
    >>> b = np.array([[0.0, np.pi / 4, 0.0], [-np.pi / 4, 0.0, 0.0]])
    >>> L = np.array([[1.0, 0.0], [1.0, 0.1]])
    >>> a = posterior_predictive_p(b, [0.5], P, L, [0.5, 0.5], 0.01, 0.1, per_pose=2)
    >>> c = posterior_predictive_p(b, [0.5], np.repeat(P, 2, axis=1), L, [0.5, 0.5], 0.01, 0.1)
    >>> bool(np.isclose(a, c))
    True
    """
    P = np.asarray(poses, dtype=float)
    L, w = np.asarray(landmark, dtype=float), np.asarray(weights, dtype=float)
    n, J = P.shape[:2]
    if L.shape[0] != J * per_pose or w.size != J * per_pose:
        raise ValueError(f"landmark, weights: expected {J} x per_pose = {J * per_pose} rows, "
                         f"got {L.shape[0]} and {w.size}")
    b = np.asarray(bearings, dtype=float)
    h = np.zeros(max(n - 1, 0)) if headings is None else np.asarray(headings, dtype=float)
    sh = np.asarray(sigma_heading, dtype=float)
    if headings is None:
        sh = np.zeros(())
    return float(posterior_predictive_batch(
        b[None], h.reshape(1, -1), np.transpose(P, (1, 0, 2)), np.zeros(J, dtype=np.intp), L,
        w, np.array([float(sigma_bearing)]), sh[None], tail, per_pose)[0])


def posterior_predictive_batch(bearings, headings, poses, tid, landmark, weights,
                               sigma_bearing, sigma_heading, tail: BearingTail | None = None,
                               per_pose: int = 1, c_loglik=None) -> np.ndarray:
    """:func:`posterior_predictive_p` of T triplets at once (the SIS engine's final samples).

    Args:
        bearings: (T, n, 3) measured [phi_A, phi_B, phi_C] per view (radians).
        headings: (T, n - 1) measured headings (radians).
        poses: (J, n, 3) the sample's trajectories, trajectory j of triplet ``tid[j]``.
        tid: (J,) int, each trajectory's triplet.
        landmark: (J r, 2) C draws, r = ``per_pose`` per trajectory (rows j r .. j r + r - 1).
        weights: (J r,) their weights (any positive scale per triplet).
        sigma_bearing: (T,) bearing width per triplet (NaN p where it is not > 0).
        sigma_heading: (T,) or (T, n - 1) heading widths; a triplet whose widths are not all
            > 0 leaves its headings out of D (and out of the reference distribution).
        tail: the bearing noise's :class:`BearingTail`, or None for the normal.
        c_loglik: (J r,) optional, each draw's C-bearing log likelihood summed over the views
            (:func:`.landmarks.sample_landmarks`' ``log lik``, at these widths and tail): C's
            deviances are then ``-2 (c_loglik - n log p(0))`` instead of recomputed.

    Returns (T,) p-values, NaN for a triplet without a positive weight.
    """
    b = np.asarray(bearings, dtype=float)
    T, n = b.shape[:2]
    P = np.asarray(poses, dtype=float)
    tid = np.asarray(tid, dtype=np.intp)
    L, w = np.asarray(landmark, dtype=float), np.asarray(weights, dtype=float)
    r = int(per_pose)
    J = P.shape[0]
    if L.shape[0] != J * r or w.size != J * r:
        raise ValueError(f"landmark, weights: expected {J} x per_pose = {J * r} rows, got "
                         f"{L.shape[0]} and {w.size}")
    sv_in = np.asarray(sigma_bearing, dtype=float).reshape(T)
    sv = np.where(sv_in > 0, sv_in, 1.0)             # (NaN p where not > 0: below)
    sh = np.asarray(sigma_heading, dtype=float).reshape(T, -1)
    with_h = np.all(sh > 0, axis=1) & (n >= 2)                         # (T,)
    svj = sv[tid][:, None, None]
    # A, B and the headings once per trajectory
    pred = np.stack([bearing(P, np.zeros(2)), bearing(P, np.array([0.0, 1.0]))], axis=-1)
    rb = wrap_angle(b[tid, :, :2] - pred)                             # (J, n, 2)
    d = deviance(rb, svj, tail).reshape(J, -1).sum(axis=1)
    if n >= 2 and np.any(with_h):
        rh = wrap_angle(np.asarray(headings, dtype=float).reshape(T, n - 1)[tid]
                        - motion_heading(P[:, :-1], P[:, 1:, :2]))   # (J, n - 1)
        shj = np.where(with_h[:, None], sh, 1.0)[tid]
        with np.errstate(over="ignore"):   # inf: a residual the model cannot explain (p = 0)
            d = d + np.where(with_h[tid], np.sum((rh / shj) ** 2, axis=1), 0.0)
    # C per (trajectory, draw)
    tr = np.repeat(tid, r)
    if c_loglik is None:
        rc = wrap_angle(b[tr, :, 2] - bearing(np.repeat(P, r, axis=0), L[:, None, :]))
        dc = np.sum(deviance(rc, sv[tr][:, None], tail), axis=1)
    else:
        dc = -2.0 * (np.asarray(c_loglik, dtype=float).reshape(J * r)
                     - n * log_bearing(0.0, sv[tr], tail))
    D = np.repeat(d, r) + dc
    n_h = np.where(with_h, n - 1, 0)
    keep = w > 0
    sf = np.zeros(D.size)
    if tail is None:
        sf[keep] = chdtrc((3 * n + n_h)[tr[keep]], D[keep])
    else:
        for s, k in {(float(a), int(c)) for a, c in zip(sv, n_h, strict=True)}:
            rows = keep & (sv[tr] == s) & (n_h[tr] == k)
            sf[rows] = reference_sf(D[rows], 3 * n, k, tail, s)
    wk = np.where(keep, w, 0.0)
    num = np.bincount(tr, weights=wk * sf, minlength=T)
    den = np.bincount(tr, weights=wk, minlength=T)
    with np.errstate(invalid="ignore", divide="ignore"):
        p = num / den
    return np.where((den > 0) & (sv_in > 0), p, np.nan)


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
    from ...combine import prior_state_distribution

    key = (type(prior).__name__, repr(prior), part.name)
    if key not in _PRIOR_STATES:
        if len(_PRIOR_STATES) > 32:
            _PRIOR_STATES.clear()
        _PRIOR_STATES[key] = tuple(
            prior_state_distribution(prior, part, point=k, n_cameras=k, samples=50_000, seed=7)
            for k in (0, 1))
    return _PRIOR_STATES[key]
