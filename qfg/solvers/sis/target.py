"""The intermediate target of the SIS engine: the density (in x, y, alpha per view) that the
sampling and motion steps' weights make the hypotheses represent, without C
(:func:`log_pose_target`), and the cameras' prior inside it (option ``camera_prior``: per-point
priors or the joint prior of the cameras so far, :func:`log_camera_prior`,
:func:`log_camera_step`).
"""

from __future__ import annotations

import numpy as np

from ... import priors as _priors
from ...geometry import wrap_angle
from ..common import likelihood as _likelihood
from ..common import prior as _prior
from ..common.odometry import log_distance_factor
from .state import SISState, trajectories


def view_patterns(keep) -> list:
    """``[(pattern (i,) bool, rows)]``: the rows of ``keep`` (J, i) grouped by their pattern of
    kept views (views taken as "camera did not move" repeat a point, which the prior of distinct
    points must not count twice); one group without a sort when every view is kept."""
    if keep.all():
        return [(keep[0] if keep.shape[0] else np.ones(keep.shape[1], dtype=bool),
                 np.arange(keep.shape[0]))]
    pat, inv = np.unique(keep, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    return [(pat[g], np.flatnonzero(inv == g)) for g in range(pat.shape[0])]


def _log_joint_cameras(opts, X, keep=None) -> np.ndarray:
    """(J,) log of the prior of the camera positions ``X`` (J, i, 2) together, up to a
    constant: ``prior.log_density`` of the views ``keep`` (J, i) marks (None: all; views taken
    as "camera did not move" repeat a point, which the prior of distinct points must not count
    twice), with the quadrature of the rejuvenation's target (:func:`target_prior`)."""
    prior = target_prior(opts["prior"])
    if keep is None or np.all(keep):
        return prior.log_density(X)
    out = np.empty(X.shape[0])
    for pat, rows in view_patterns(keep):
        out[rows] = prior.log_density(X[rows][:, pat])
    return out


def log_camera_prior(opts, X) -> np.ndarray:
    """(J,) the prior part of the intermediate target of camera trajectories ``X`` (J, i, 2):
    with ``camera_prior="point"`` the product of per-point priors ``sum_t log p1(X_t)``; with
    ``"joint"`` the per-point prior of the first camera times the joint prior's conditional of
    the others given it,

        log p1(X_1) + log prior(X_1..X_i) - log prior(X_1).

    Why ``"joint"``: when the cameras stay close together far from A and B (a short baseline
    seen from afar, as on MRCLAM), the product counts the prior of one far-away place i times
    where the joint prior counts it about once, so the intermediate weights push every
    hypothesis toward A and B by a factor that grows with the views, and the final weights
    (the whole configuration's prior) rest on the few that survive."""
    lp = _prior.point_log_prior(opts["prior"], X)
    if opts.get("camera_prior", "point") == "point" or X.shape[1] < 2:
        return np.sum(lp, axis=1)
    with np.errstate(invalid="ignore"):
        out = lp[:, 0] + _log_joint_cameras(opts, X) - _log_joint_cameras(opts, X[:, :1])
    # a first camera outside the prior's support gives -inf - (-inf): no weight
    return np.where(np.isnan(out), -np.inf, out)


def log_camera_step(state, pj, X) -> np.ndarray:
    """(K,) the log prior factor a child at ``X`` (K, 2) adds to its parent's trajectory (rows
    ``pj`` (K,) of ``state``'s hypotheses): ``log p1(X)`` with ``camera_prior="point"``, the
    joint prior's conditional ``log prior(X_1..X_i, X) - log prior(X_1..X_i)`` with ``"joint"``
    (the distinct views only: :func:`_log_joint_cameras`)."""
    opts = state.opts
    if opts.get("camera_prior", "point") == "point" or pj.size == 0:
        return _prior.point_log_prior(opts["prior"], X)
    if np.all(pj[1:] >= pj[:-1]):       # children come in their parents' order: no sort
        first = np.r_[True, pj[1:] != pj[:-1]]
        up, back = pj[first], np.cumsum(first) - 1
    else:
        up, back = np.unique(pj, return_inverse=True)
        back = back.reshape(-1)
    past = trajectories(state.levels, up)[..., :2]
    keep = ~state.same_pose[state.tid[up]]
    prior = target_prior(opts["prior"])
    K = pj.size
    if isinstance(prior, _priors.WorldBoxPrior):
        # each parent's extents once, each child adds its point: O(1) per child in the views
        # (the stacked path below is O(i) per child)
        out = np.empty(K)
        group = np.empty(up.size, dtype=np.intp)
        local = np.empty(up.size, dtype=np.intp)
        for g, (pat, ug) in enumerate(view_patterns(keep)):
            group[ug], local[ug] = g, np.arange(ug.size)
            ch = np.flatnonzero(group[back] == g)
            base = past[ug][:, pat]
            with np.errstate(invalid="ignore"):
                kids, before = prior.log_density_extended(base, X[ch], local[back[ch]],
                                                          with_base=True)
                out[ch] = kids - before[local[back[ch]]]
        return np.where(np.isnan(out), -np.inf, out)
    before = _log_joint_cameras(opts, past, keep)
    both = np.concatenate([past[back], X[:, None, :]], axis=1)
    kb = np.concatenate([keep[back], np.ones((K, 1), dtype=bool)], axis=1)
    with np.errstate(invalid="ignore"):
        out = _log_joint_cameras(opts, both, kb) - before[back]
    return np.where(np.isnan(out), -np.inf, out)


#: Quadrature points in rho of the world prior inside the rejuvenation's target (the final
#: weights keep :data:`.prior.SOLVER_N_RHO`): the target may be any fixed density, since the
#: hypotheses carry its prior part (``lp_x``) and the final weights divide it out; 16 points
#: are within about 0.16 nats (sd) of 32 on whole configurations, at about half the cost.
_TARGET_N_RHO = 16


def target_prior(prior):
    """``prior`` with :data:`_TARGET_N_RHO` quadrature points if it is a world-box prior with
    more, else ``prior``."""
    if isinstance(prior, _priors.WorldBoxPrior) and prior.n_rho > _TARGET_N_RHO:
        return prior.replace(n_rho=_TARGET_N_RHO)
    return prior


def log_pose_target(st: SISState, tid, poses):
    """log of the intermediate target of trajectories ``poses`` (J, i, 3) of triplets ``tid``,
    without C and up to a constant per triplet: per view the per-point prior and the A/B bearing
    likelihoods, per move the heading likelihood,

        sum_t [log p1(X_t) + log N(phi_A,t - f_A(X_t); sv) + log N(phi_B,t - f_B(X_t); sv)]
        + sum_t log N(psi_t - g(X_t+1, X_t); sw),

    plus the odometry's step-length-ratio factors (:func:`log_distance_factor`) where distances
    are given: the density (in x, y, alpha) that the sampling and motion steps' weights make the
    hypotheses represent. Returns (log target (J,), its prior part (J,): sum_t log p1(X_t), or
    with ``camera_prior="joint"`` :func:`log_camera_prior`'s)."""
    X, al = poses[..., :2], poses[..., 2]
    b = st.bearings[tid]
    sv = st.sigma_bearing[tid][:, None]
    # (J, 1) one sigma per triplet, else (J, i - 1) one per step
    sw = st.sigma_heading[tid][:, None] if st.step_sigma is None else \
        st.step_sigmas(tid, poses.shape[1] - 1)
    fa = np.arctan2(-X[..., 1], -X[..., 0]) - al
    fb = np.arctan2(1.0 - X[..., 1], -X[..., 0]) - al
    ra, rb = wrap_angle(b[..., 0] - fa), wrap_angle(b[..., 1] - fb)
    d = X[:, 1:] - X[:, :-1]
    rh = wrap_angle(st.headings[tid] - (np.arctan2(d[..., 1], d[..., 0]) - al[:, :-1]))
    lp = log_camera_prior(st.opts, X)
    tail = st.opts.get("bearing_tail")
    htail = st.opts.get("heading_tail")
    if htail is not None:
        # the headings' mixture (normalised per step: a constant per triplet)
        out = lp + np.sum(_likelihood.log_bearing(rh, sw, htail), axis=1)
        if tail is None:
            out = out - 0.5 * np.sum(ra * ra + rb * rb, axis=1) / sv[:, 0] ** 2
        else:
            out = out + np.sum(_likelihood.log_bearing(ra, sv, tail)
                               + _likelihood.log_bearing(rb, sv, tail), axis=1)
    elif tail is None:
        out = lp - 0.5 * (np.sum(ra * ra + rb * rb, axis=1) / sv[:, 0] ** 2
                          + _heading_sum(rh, sw))
    else:
        out = lp + np.sum(_likelihood.log_bearing(ra, sv, tail)
                          + _likelihood.log_bearing(rb, sv, tail), axis=1) \
            - 0.5 * _heading_sum(rh, sw)
    dist = st.distances[tid]
    if X.shape[1] >= 3 and np.any(dist > 0):
        step = np.hypot(d[..., 0], d[..., 1])
        out = out + np.sum(log_distance_factor(step[:, 1:], step[:, :-1], dist[:, 1:],
                                               dist[:, :-1], st.sigma_distance[tid][:, None],
                                               st.opts.get("distance_tail")), axis=1)
    return np.where(np.isnan(out), -np.inf, out), lp


def _heading_sum(rh, sw) -> np.ndarray:
    """(J,) sum over steps of (rh / sw)^2 for residuals (J, i - 1) and sigmas (J, 1) or
    (J, i - 1) (the one-sigma form keeps the arithmetic of the runs recorded before per-step
    sigmas)."""
    if sw.shape[1] == 1:
        return np.sum(rh * rh, axis=1) / sw[:, 0] ** 2
    return np.sum(rh * rh / (sw * sw), axis=1)
