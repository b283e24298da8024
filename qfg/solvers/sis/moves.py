"""Metropolis-Hastings moves of the SIS engine's hypotheses after resampling (resample-move):
random-walk moves of whole trajectories (option ``move_steps``) and the rejuvenation sweeps along
the measurements (option ``rejuvenate``, :mod:`.rejuvenation`), both leaving the target
invariant so that the equal weights after resampling stay right
(:func:`after_resampling`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...geometry import wrap_angle
from ..common import laplace as _laplace
from ..common import prior as _prior
from ..common import seeds as _seeds
from ..common.seeds import per_triplet
from . import rejuvenation as _rejuvenation
from .c_integral import log_intermediate_c
from .resampling import draw_offsets, systematic
from .state import SISState, streams, trajectories
from .target import log_pose_target, target_prior

#: Random-walk scale: the proposal covariance is ``(_MOVE_SCALE^2 / D)`` times the covariance of
#: the triplet's resampled trajectories (D = 3 i coordinates).
_MOVE_SCALE = 1.0


def _move(st: SISState, which, mean_log) -> SISState:
    """Resample-move (Gilks and Berzuini 2001): ``move_steps`` random-walk Metropolis-Hastings
    steps per hypothesis of the triplets ``which`` (T,), just resampled, each targeting the
    intermediate posterior of the views so far (:func:`.target.log_pose_target` times C's integral).
    The proposal is a Gaussian random walk on the whole trajectory (x, y, alpha per view) with
    the covariance of the triplet's resampled hypotheses, scaled; C's integral is re-estimated
    at the proposal (:func:`.c_integral.log_intermediate_c`, a pseudo-marginal step where it is sampled).
    The target is invariant, so the equal weights stay right while the copies that resampling
    made of one trajectory spread apart again (path degeneracy). The hypotheses of other
    triplets are untouched; every draw comes from the triplet's own stream."""
    T, n = st.n_triplets, st.n_views
    rows = np.flatnonzero(which[st.tid])
    if rows.size == 0:
        return st
    D = 3 * n
    tid = st.tid[rows]
    poses = st.poses[rows].copy()
    lc = st.lw_c[rows].copy()
    cs = st.c_sum[rows].copy()
    lt, lp = log_pose_target(st, tid, poses)
    chol = _rejuvenation.walk_factor(poses, tid, which, _MOVE_SCALE)
    gens = streams(st.roots, n - 1, _seeds.STREAM_MOVE)
    counts = np.bincount(tid, minlength=T)
    bc = st.bearings[..., 2]
    for _ in range(st.opts["move_steps"]):
        (z,) = per_triplet(gens, counts, lambda g, m: (g.standard_normal((m, D)),))
        prop = poses + np.einsum("jde,je->jd", chol[tid], z).reshape(-1, n, 3)
        prop[..., 2] = wrap_angle(prop[..., 2])
        lt2, lp2 = log_pose_target(st, tid, prop)
        ok = np.isfinite(lt2)
        lc2 = np.full(rows.size, -np.inf)
        cs2 = np.full((rows.size, _laplace.SUMMARY_COLUMNS), np.nan)
        if np.any(ok):
            lc2[ok], cs2[ok] = log_intermediate_c(st, tid[ok], prop[ok], bc, gens)
        (u,) = per_triplet(gens, counts, lambda g, m: (g.random(m),))
        with np.errstate(invalid="ignore"):
            acc = ok & (np.log(u) < (lt2 + lc2) - (lt + lc))
        poses[acc], lt[acc], lp[acc], lc[acc] = prop[acc], lt2[acc], lp2[acc], lc2[acc]
        cs[acc] = cs2[acc]
    # moved trajectories share no ancestors any more: the levels are rebuilt flat (moves cost
    # O(N i) per view anyway)
    new_poses = st.poses
    new_poses[rows] = poses
    flat = tuple((new_poses[:, t].copy(), np.arange(new_poses.shape[0])) for t in range(n))
    lp_x, lw_c, lw_base = st.lp_x.copy(), st.lw_c.copy(), st.lw_base.copy()
    lp_x[rows], lw_c[rows] = lp, lc
    lw_base[rows] = mean_log[tid] - lc
    c_sum = st.c_sum.copy()
    c_sum[rows] = cs
    return replace(st, levels=flat, lp_x=lp_x, lw_c=lw_c, lw_base=lw_base, c_sum=c_sum)


def after_resampling(st: SISState, which, mean_log) -> SISState:
    """The moves of the triplets ``which`` (T,), just resampled to equal weights ``mean_log``."""
    if st.opts.get("rejuvenate", 0) > 0 and _rejuvenation.scheduled(st.n_views):
        st = _rejuvenate(st, which, mean_log)
    if st.opts.get("move_steps", 0) > 0:
        st = _move(st, which, mean_log)
    return st


#: Proposals of a rejuvenation sweep (:func:`.rejuvenation.sweeps`).
_KINDS = ("walk", "ridge", "noise")


def _joint_target(st: SISState, stc: SISState, tid, poses, gens, prior=None):
    """The rejuvenation's target at trajectories ``poses`` (J, n, 3) of triplets ``tid``: the
    pose likelihoods of :func:`.target.log_pose_target`, C's integral
    (:func:`.c_integral.log_intermediate_c` of ``stc``: the Laplace fit at C's mode, sampled where
    C's depth is unresolved) and the prior of the whole configuration at C's mode ``L*``,

        log pi = log lik(X) + log Z(X) + log prior([L*, X]) - log p1(L*),

    where C's depth is resolved (the exact joint prior, :func:`.prior.log_joint_prior`, which the
    per-point priors of the other steps only approximate); the per-point priors elsewhere.
    ``prior``: the prior of the joint term (None: the solver's). Returns (log pi (J,), the prior
    part as ``lp_x`` carries it (J,), log Z with p1(L*) as ``lw_c`` carries it (J,), C summaries
    (J, 7))."""
    lt, lp = log_pose_target(st, tid, poses)
    lc, cs = log_intermediate_c(stc, tid, poses, st.bearings[..., 2], gens)
    lpx = lp.copy()
    r = np.flatnonzero(np.isfinite(cs[:, 0]) & np.isfinite(lt))
    # a trajectory outside the prior's support gives -inf - (-inf); the NaN is read as -inf
    # below, so numpy's warning would only alarm a user
    with np.errstate(invalid="ignore"):
        if r.size:
            L = cs[r, :2]
            lpx[r] = _prior.log_joint_prior(st.opts["prior"] if prior is None else prior, L,
                                            poses[r, :, :2]) \
                - _prior.point_log_prior(st.opts["prior"], L)
        out = lt - lp + lpx + lc
    return np.where(np.isnan(out), -np.inf, out), lpx, lc, cs


def _rejuvenate(st: SISState, which, mean_log) -> SISState:
    """Resample-move along the measurements (:mod:`.rejuvenation`) for the triplets ``which``
    (T,), just resampled to equal weights: the hypotheses are first reweighted from the
    intermediate target to :func:`_joint_target` (the exact joint prior at C's mode and C's
    Laplace fit at its mode in place of the per-point priors and the carried C summaries) and
    resampled (systematic, per triplet); then ``rejuvenate`` sweeps of Metropolis-Hastings
    steps per hypothesis target it. A sweep proposes

    * a walk: the whole trajectory (x, y, alpha per view) moved by a Gaussian with ``1 / D``
      times the covariance of the triplet's hypotheses (D = 3 n,
      :func:`.rejuvenation.walk_factor`);
    * a ridge step in the chart of :func:`.rejuvenation.chart_of`: camera 1 moved ``s`` along
      its arc, every bearing and heading residual held, so the whole trajectory slides along
      what the A/B bearings and headings leave open and only the priors, the Jacobian and C's
      integral decide (the move that brings back early poses the resampling lost);
    * a noise step in that chart: every residual moved by ``s sigma z``, camera 1 held;

    the chart steps accepted on the target times the chart's Jacobian. Step scales ``s`` are
    drawn log-uniformly per hypothesis (a scale mixture, symmetric whatever the state;
    :func:`.rejuvenation.sweeps`). The target is invariant, so equal weights stay
    right; the hypotheses leave with C refitted at its mode (summaries the later views update),
    ``lp_x`` the target's prior part (the final weights divide it out) and equal total weights.
    Every draw comes from the triplet's own stream ``(view, STREAM_REJUVENATE)``; vectorised over
    hypotheses (loops over sweeps, and over views inside the chart)."""
    T, n = st.n_triplets, st.n_views
    rows = np.flatnonzero(which[st.tid])
    if rows.size == 0:
        return st
    tid = st.tid[rows]
    poses = trajectories(st.levels, rows)
    stc = replace(st, opts={**st.opts, "c_anchors": True})
    gens = streams(st.roots, n, _seeds.STREAM_REJUVENATE)
    counts = np.bincount(tid, minlength=T)
    prior = target_prior(st.opts["prior"])
    cur, lpx, lc, cs = _joint_target(st, stc, tid, poses, gens, prior)
    # from the intermediate target to the joint one: importance weights, then resampling
    switch = (lpx + lc) - (st.lp_x[rows] + st.lw_c[rows])
    idx = systematic(tid, np.where(np.isfinite(cur), switch, -np.inf), T,
                      np.where(which, counts, 0), draw_offsets(gens))
    keep = np.bincount(tid[idx], minlength=T) > 0
    # a triplet with no finite reweighted hypothesis keeps its hypotheses unmoved
    idx = np.sort(np.concatenate([idx, np.flatnonzero(~keep[tid])]))
    poses, cur, lpx, lc, cs = poses[idx], cur[idx], lpx[idx], lc[idx], cs[idx]
    movable = which & keep

    def target(k, P):
        out, *extras = _joint_target(st, stc, tid[k], P, gens, prior)
        return out, tuple(extras)

    poses, cur, (lpx, lc, cs) = _rejuvenation.sweeps(
        poses, tid, movable, target, (cur, (lpx, lc, cs)), gens, st.opts["rejuvenate"],
        st.sigma_bearing, st.sigma_heading, _KINDS, _MOVE_SCALE)
    # moved trajectories share no ancestors any more: the levels are rebuilt flat (O(N n), as
    # the moves themselves)
    # (a triplet left unmoved keeps its hypotheses' weights and summaries as they were)
    u = keep[tid]
    ru = rows[u]
    allp = trajectories(st.levels)
    allp[ru] = poses[u]
    flat = tuple((allp[:, t].copy(), np.arange(allp.shape[0])) for t in range(n))
    lp_x, lw_c, lw_base = st.lp_x.copy(), st.lw_c.copy(), st.lw_base.copy()
    lp_x[ru], lw_c[ru] = lpx[u], lc[u]
    # equal totals within a triplet (the constant is immaterial: weights are per triplet)
    lw_base[ru] = mean_log[tid[u]] - lc[u]
    c_sum = st.c_sum.copy()
    c_sum[ru] = cs[u]
    return replace(st, levels=flat, lp_x=lp_x, lw_c=lw_c, lw_base=lw_base, c_sum=c_sum)
