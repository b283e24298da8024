"""The SIS engine's entry points, batched over triplets: :func:`start` (the sampling step of view
1), :func:`step` (one more view: the motion step, :mod:`.motion`) and :func:`finish` (the final
weighted sample of (trajectory, C) under the prior of the whole configuration, and the
estimates); the package docstring (:mod:`qfg.solvers.sis`) gives the algorithm.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...geometry import heading_on_locus, locus_point, wrap_angle
from ..common import arcs as _arcs
from ..common import degenerate as _degenerate
from ..common import estimate as _estimate
from ..common import histograms as _histograms
from ..common import input as _input
from ..common import laplace as _laplace
from ..common import likelihood as _likelihood
from ..common import options as _options
from ..common import prior as _prior
from ..common import seeds as _seeds
from ..common.seeds import per_triplet
from . import model_check as _model_check
from . import motion as _motion
from .c_integral import c_weight
from .moves import after_resampling
from .resampling import draw_offsets, kept, plan_resampling, segment_max, systematic
from .state import SISState, merge, streams, subset, take, trajectories
from .target import view_patterns

#: Views up to which the option ``few_views_budget`` replaces the budget
#: (docs/results/solvers_options.md, "The few-views package").
FEW_VIEWS = 3


def start(bearings0, sigma_bearing, sigma_heading, roots, opts, part, method,
          sigma_distance_ratio=None, n_views=None) -> SISState:
    """First view of T triplets: bearings0 (T, 3), sigmas (T,), roots: T SeedSequences;
    ``sigma_distance_ratio`` (T,) the noise of the log ratio of the distances :func:`step` is
    given (None: no distances). ``n_views``: how many views the triplets will have, when the
    caller knows (None: not known).

    With the option ``few_views_budget`` (a dict of budget options) the views up to
    :data:`FEW_VIEWS` are solved with that budget, unless ``n_views`` says more views will
    come; the view after :data:`FEW_VIEWS` then first solves the earlier views again with the
    caller's options (:func:`_rebuild`), so an answer after n views depends on n and the seed
    only, whether the views came one at a time or together."""
    few = opts.get("few_views_budget")
    full_opts = None
    if few and (n_views is None or n_views <= FEW_VIEWS):
        full_opts, opts = opts, {**opts, **few}
    b0 = np.asarray(bearings0, dtype=float).reshape(-1, 3)
    T = b0.shape[0]
    sb = np.asarray(sigma_bearing, dtype=float).reshape(T)
    sh = np.asarray(sigma_heading, dtype=float).reshape(T)
    sd = np.zeros(T) if sigma_distance_ratio is None else \
        np.asarray(sigma_distance_ratio, dtype=float).reshape(T)
    sd = _options.effective_sigma(np.nan_to_num(sd), _input.DISTANCE_RATIO_FLOOR)
    quiet = (sb == 0) & (sh == 0)
    M = np.where(quiet, opts["n_samples"] * opts["motion_samples"], opts["n_samples"])

    tail = opts.get("bearing_tail")

    def draw(rng, m):
        out = rng.standard_normal((m, 2)), (rng.permutation(m) + rng.random(m)) / m
        # the tail's component choices after the normal draws: without a tail the streams
        # are the same as before it existed
        return out if tail is None else out + (rng.random((m, 2)), rng.random((m, 2)))

    gens = streams(roots, 0, _seeds.STREAM_CAMERAS)
    z, u, *uv = per_triplet(gens, M, draw)
    tid = np.repeat(np.arange(T), M)
    if tail is None:
        pa = b0[tid, 0] + sb[tid] * z[:, 0]
        pb = b0[tid, 1] + sb[tid] * z[:, 1]
    else:
        # noiseless triplets draw no outliers
        uc = np.where((sb[tid] > 0)[:, None], uv[0], 1.0)
        nz = _likelihood.bearing_noise(z, uc, uv[1], sb[tid][:, None], tail)
        pa, pb = b0[tid, 0] + nz[:, 0], b0[tid, 1] + nz[:, 1]
    gamma = wrap_angle(pb - pa)
    a, log_dadw = _arcs.arc_parameter(gamma, u)
    X = locus_point(gamma, a)
    alpha = heading_on_locus(X, pa)
    lw = _arcs.log_camera_prior(X, gamma, log_dadw, opts["prior"])
    poses = np.concatenate([X, alpha[:, None]], axis=-1)
    st = SISState(bearings=b0[:, None, :], headings=np.zeros((T, 0)), sigma_bearing=sb,
                  sigma_heading=sh, distances=np.zeros((T, 0)), sigma_distance=sd,
                  roots=tuple(roots), opts=opts, part=part, method=method,
                  tid=tid, levels=((poses, np.zeros(tid.size, dtype=np.int64)),), lw_base=lw,
                  lp_x=_prior.point_log_prior(opts["prior"], X),
                  lw_c=np.zeros(tid.size), same_pose=np.zeros((T, 1), dtype=bool),
                  c_sum=np.full((tid.size, _laplace.SUMMARY_COLUMNS), np.nan),
                  lost=np.zeros(T, dtype=int), full_opts=full_opts)
    st = _prune(st, gens)
    alive = np.bincount(st.tid, minlength=T) > 0
    return replace(st, lost=np.where(alive, 0, 1))


def step(state: SISState, phi, psi, distance=None, sigma_heading=None) -> SISState:
    """Add one view to T triplets: ``phi`` (T, 3), ``psi`` (T,), ``distance`` (T,) travelled
    from the previous view by odometry (0 or None: unknown), ``sigma_heading`` (T,) this step's
    heading sigma (None: the triplets' ``sigma_heading``). From the third view on, each
    child's weight carries :func:`log_distance_factor` of its step and its parent's last step.
    A triplet whose hypotheses all die (every ray misses its locus arc) is proposed again with
    the noise drawn ``RETRY_SPREAD`` times wider (importance-weighted), before it is given up."""
    if state.full_opts is not None and state.n_views >= FEW_VIEWS:
        state = _rebuild(state)
    phi = np.asarray(phi, dtype=float).reshape(-1, 3)
    psi = np.asarray(psi, dtype=float).reshape(-1)
    T, i = state.n_triplets, state.n_views
    dist = np.zeros(T) if distance is None else np.asarray(distance, dtype=float).reshape(T)
    # the new distance goes in first: the motion step reads it as distances[:, -1]
    state = replace(state, distances=np.concatenate([state.distances, dist[:, None]], axis=1))
    if sigma_heading is not None or state.step_sigma is not None:
        # likewise this step's heading sigma (columns only once some step has its own)
        sh = state.sigma_heading if sigma_heading is None else \
            np.asarray(sigma_heading, dtype=float).reshape(T)
        past = state.step_sigmas(np.arange(T), i - 1)
        state = replace(state, step_sigma=np.concatenate([past, sh[:, None]], axis=1))
    st = _motion.extend(state, phi, psi, state.opts["motion_spread"], _seeds.STREAM_CAMERAS)
    alive = np.bincount(st.tid, minlength=T) > 0
    retry = ~alive & (state.lost == 0)
    if np.any(retry):
        sub = _motion.extend(subset(state, retry), phi[retry], psi[retry], RETRY_SPREAD,
                      _seeds.STREAM_RETRY)
        st = merge(st, sub, np.flatnonzero(retry), state, np.flatnonzero(retry[state.tid]))
        alive = np.bincount(st.tid, minlength=T) > 0
    return replace(st, lost=np.where((state.lost == 0) & ~alive, i + 1, state.lost))


def _rebuild(state: SISState) -> SISState:
    """The state's views solved again from the first with the caller's options
    (``state.full_opts``): the same streams and steps as if the few-views budget had never
    been used."""
    st = start(state.bearings[:, 0], state.sigma_bearing, state.sigma_heading, state.roots,
               state.full_opts, state.part, state.method, state.sigma_distance,
               n_views=state.n_views + 1)
    for i in range(1, state.n_views):
        st = step(st, state.bearings[:, i], state.headings[:, i - 1], state.distances[:, i - 1],
                  None if state.step_sigma is None else state.step_sigma[:, i - 1])
    return st


#: Noise spread of the second proposal for a triplet that lost every hypothesis.
RETRY_SPREAD = 4.0


def _prune(st: SISState, gens) -> SISState:
    T = st.n_triplets
    keep = kept(st.tid, st.lw_base + st.lw_c, T, st.opts["prune_ratio"])
    if not keep.all():
        st = take(st, np.flatnonzero(keep))
    plan = plan_resampling(st, st.tid, st.lw_base + st.lw_c, gens)
    if plan is None:
        return st
    idx, over, mean_log, moving = plan
    new = take(st, idx)
    lw_base = np.where(over[new.tid], mean_log[new.tid] - new.lw_c, new.lw_base)
    st = replace(new, lw_base=lw_base)
    return after_resampling(st, moving, mean_log) if np.any(moving) else st


#: Whether the final C draws centre on the carried summaries' modes (:func:`_final_proposal`);
#: a switch for the tests, which compare both.
_FINAL_AT_MODE = True


def _final_proposal(state: SISState, idx, poses):
    """The Gaussian part of the final C proposal for trajectories ``idx`` (rows of ``state``,
    poses (J, n, 3)), as :func:`.landmarks.sample_landmarks` takes it (``laplace=``): the
    Laplace approximation about C's mode over every view (:func:`.laplace.refine_mode`, O(n)
    per trajectory, once), started from the carried summary's mode where there is one, else from
    the lines' least-squares triangulation. The least-squares point alone is a posterior
    standard deviation or more off the mode at 10 views, which left a few draws with most of
    the final weight."""
    X, theta = poses[..., :2], poses[..., 2] + state.bearings[state.tid[idx], :, 2]
    tri = _laplace.triangulate(X, theta)
    if not _FINAL_AT_MODE or state.n_views < 2:
        return tri
    cs = state.c_sum[idx]
    start = np.where(np.isfinite(cs[:, :1]), cs[:, :2], tri[0])
    ref = _laplace.refine_mode(X, theta, start)
    # keep the triangulation where it has none and the refinement found none either
    use = ref[1] | ~tri[1]
    return tuple(np.where(use[:, None] if np.ndim(a) == 2 else use, a, b)
                 for a, b in zip(ref, tri, strict=True))


def finish(state: SISState, hypotheses: bool = False):
    """One (estimate, hypotheses or None) pair per triplet: the final weighted sample of
    (trajectory, C), weighted by the prior of the whole configuration:

        w_jk  ∝  prior([L_jk, X_j]) prod_t N(phi_C,t - f(L_jk, X_jt)) / q(L_jk | X_j)
                 / (prod_t p1(X_jt) Z(X_j))

    over trajectories X_j resampled by their intermediate weights (p1 the per-point prior, Z the
    intermediate C weight)."""
    opts, part, T, n = state.opts, state.part, state.n_triplets, state.n_views
    m = part.n_states
    total = state.lw_base + state.lw_c
    M = opts["posterior_samples"]
    alive = np.bincount(state.tid, weights=np.isfinite(total), minlength=T) > 0
    gens = streams(state.roots, n, _seeds.STREAM_POSTERIOR)
    off = draw_offsets(gens)
    idx = systematic(state.tid, total, T, np.where(alive, M, 0), off)
    tid, poses = state.tid[idx], trajectories(state.levels, idx)
    k = opts["one_view_samples"] if n == 1 else opts["landmark_samples"]
    if tid.size:
        L, log_q, log_lik, spread = c_weight(state, tid, poses, state.bearings[..., 2], gens,
                                              k, laplace=_final_proposal(state, idx, poses))
        lp = np.empty(L.shape[:2])
        # the prior of the distinct points: views taken as "not moved" repeat a camera
        for pat, rows in view_patterns(~state.same_pose[tid]):
            lp[rows] = _prior.log_joint_prior_draws(opts["prior"], L[rows],
                                                    poses[rows][:, pat, :2])
        with np.errstate(invalid="ignore"):
            lw = lp + log_lik - log_q - (state.lw_c[idx] + state.lp_x[idx])[:, None]
        lw = np.where(np.isnan(lw), -np.inf, lw)
    else:
        L, lw, spread = np.zeros((0, k, 2)), np.zeros((0, k)), np.zeros(0)
    # normalize per triplet
    flat_tid = np.repeat(tid, k)
    flw = lw.ravel()
    mx = segment_max(flat_tid, flw, T)
    e = np.where(np.isfinite(flw), np.exp(flw - np.where(np.isfinite(mx), mx, 0.0)[flat_tid]),
                 0.0)
    s = np.bincount(flat_tid, weights=e, minlength=T)
    w = np.where(s[flat_tid] > 0, e / np.where(s > 0, s, 1.0)[flat_tid], 0.0)
    Lf = L.reshape(-1, 2)
    ls = part.state_of(Lf) if Lf.size else np.zeros(0, dtype=int)
    lm, mc_errors = _histograms.weighted_state_histograms(ls, w, flat_tid, T, m)
    cw = w.reshape(-1, k).sum(axis=1) if w.size else np.zeros(0)
    cs = part.state_of(poses[..., :2]) if poses.size else np.zeros((0, n), dtype=int)
    cidx = (tid[:, None] * n + np.arange(n)) * m + cs
    cm = np.bincount(cidx.ravel(), weights=np.repeat(cw, n), minlength=T * n * m).reshape(T, n, m)
    unresolved = np.bincount(tid, weights=cw * (spread > _degenerate.DEPTH_SPREAD), minlength=T)
    lb = np.searchsorted(flat_tid, np.arange(T + 1))
    sv = state.sigma_v()
    # the estimate reports the caller's options (their few-views budget among them)
    shown = opts if state.full_opts is None else state.full_opts
    cb = np.searchsorted(tid, np.arange(T + 1))
    shs_all = state.step_sigmas(np.arange(T))                       # (T, n - 1)
    pvals = np.full(T, np.nan)
    if tid.size:
        # the heading width floored like the bearings' (a sigma of 1e-300 is the noiseless
        # model to the solver, and its residuals of 1e-16 must not read as a misfit); with a
        # heading tail the headings are left out (the check's reference is for normal headings)
        use_h = np.all(shs_all > 0, axis=1) & (opts.get("heading_tail") is None)
        sh_check = np.where(use_h[:, None], np.maximum(shs_all, float(opts["bearing_floor"])),
                            0.0)
        pvals = _model_check.posterior_predictive_batch(
            state.bearings, state.headings, poses, tid, Lf, w,
            np.where(state.sigma_bearing > 0, sv, 0.0), sh_check, opts.get("bearing_tail"),
            per_pose=k, c_loglik=log_lik)
    out = []
    for t in range(T):
        shs = float(state.sigma_heading[t]) if state.step_sigma is None else \
            state.step_sigma[t, :n - 1]
        reasons = _degenerate.geometry_reasons(state.bearings[t], state.sigma_bearing[t],
                                               state.headings[t], shs)
        if np.any(state.same_pose[t]):
            reasons.append(_degenerate.repeated_reason(state.same_pose[t]))
        if lm[t].sum() <= 0:
            v = int(state.lost[t])
            reasons.append(f"view {v}: no hypothesis survived (rays miss the locus arcs)"
                           if v else "every hypothesis has zero weight")
            out.append(_estimate.uniform_estimate(state.method, part, n, "; ".join(reasons),
                                                  shown))
            continue
        if (n >= 2 and unresolved[t] > _degenerate.UNRESOLVED_SHARE
                and not any("coincide" in r for r in reasons)):
            reasons.append(_degenerate.UNRESOLVED_REASON)
        wt = w[lb[t]:lb[t + 1]]
        Lt = Lf[lb[t]:lb[t + 1]]
        cam = np.transpose(np.repeat(poses[cb[t]:cb[t + 1]], k, axis=0), (1, 0, 2))
        hyp = _estimate.Hypotheses(
            landmark_samples=Lt, landmark_weights=wt, camera_samples=cam,
            camera_weights=np.broadcast_to(wt, (n, wt.size)).copy(), joint=True)
        p_land, p_cams = lm[t] / lm[t].sum(), cm[t] / cm[t].sum(axis=1, keepdims=True)
        pval = float(pvals[t])
        lam = _model_check.widening(pval, opts.get("model_check", 0.0))
        widen = None
        if lam > 0:
            widen = (lam,) + _model_check.prior_states(opts["prior"], part)
            reasons.append(f"model check: the bearings and headings fit the model with posterior "
                           f"predictive p = {pval:.2g} < {opts['model_check']:g}; widened toward "
                           f"the prior's states by {lam:.2f}")
        est, hyp = _estimate.make_estimate(
            state.method, part, n, p_land, p_cams, hypotheses=hyp, reasons=reasons, opts=shown,
            mc_error=mc_errors[t], model_check=pval,
            widen=widen, depth_unresolved=float(unresolved[t]) if n >= 2 else float("nan"))
        out.append((est, hyp if hypotheses else None))
    return out
