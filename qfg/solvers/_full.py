"""The full sampling solver (the paper's Algorithm 1, section 4d), incremental over views.

Per view i (AB frame, A = (0, 0), B = (0, 1)):

* sampling step (view 1): ``n_samples`` camera poses near the locus arc of (phi_A, phi_B) under
  bearing noise (:func:`._common.sample_view`), each with its prior importance weight;
* motion step (views 2..n), two ways:

  - ``motion="sample"`` (default): for each hypothesis j, ``motion_samples`` draws of the heading
    noise and of the bearing noise to A and B; the ray from X_{i-1}^j along
    ``alpha_{i-1}^j + psi_{i-1} + eps`` meets the drawn locus arc in 0, 1 or 2 points, each a new
    hypothesis. The drawn noise carries the heading and A/B bearing likelihoods exactly, so the
    importance weight is the prior times the change of variables ``t / |grad Gamma . u|``
    (:func:`._common.log_ray_jacobian`). With zero noise this is exactly the noiseless geometry.
  - ``motion="match"`` (the paper's wording taken literally): ``n_samples`` independent samples of
    view i (sampling step again), every pair (j, k) whose direction from X_{i-1}^j is within
    ``match_sigmas`` heading sigmas of ``alpha_{i-1}^j + psi_{i-1}`` becomes a hypothesis with
    ``wm = N(psi - g(X_i^k, X_{i-1}^j); sigma_w)``. Slower and less accurate for the same budget
    (docs/solvers.md).

* resection step: C is triangulated from the cameras' lines of sight (pairwise centroid as in the
  paper, or least squares), ``wr_t = N(phi_C,t - f(L^j, X_t^j); sigma_v)`` for every view t;
* pruning: hypotheses lighter than ``prune_ratio`` x the heaviest are dropped; above
  ``max_hypotheses`` the set is resampled (systematic) down to it, keeping its total weight.

The weight of a hypothesis is the paper's ``prior x prod_i wm_i x prod_t wr_t`` (eq. slamapprox1/2),
where wr is recomputed from the current triangulation at every view (after a resampling the old wr
is divided out, as in sequential importance resampling). One view: C is sampled along each camera
sample's line of sight under the prior (:data:`._common.PRIORS`).

Likelihood widths are ``max(sigma, floor)`` so that zero noise works. Every random draw of view i
comes from its own stream (:func:`._common.stream`), so adding a view to an estimate gives exactly
the estimate of all views solved at once.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..geometry import (
    locus_circle,
    ray_circle_intersection,
    triangulate_lsq,
    triangulate_pairwise_centroid,
    wrap_angle,
)
from . import _common as C

#: Pair evaluations per chunk in the motion step (bounds memory).
_CHUNK = 1 << 18


@dataclass(frozen=True, eq=False)
class FullState:
    """Hypotheses after the views so far (what an incremental update continues from)."""

    meas: C.Measurements
    root: np.random.SeedSequence
    opts: dict
    part: object
    poses: np.ndarray     # (J, i, 3) camera poses per hypothesis
    lw_base: np.ndarray   # (J,) log per-point prior x change of variables (+ resampling)
    lp_x: np.ndarray      # (J,) the per-point prior part of lw_base (divided out at the end)
    lw_res: np.ndarray    # (J,) log resection weight at the current triangulation (+ C prior)
    reasons: tuple
    same_pose: tuple = ()  # views whose bearings repeat the previous view's exactly


def _triangulate(X, theta, how):
    if how == "lsq":
        L, ok = triangulate_lsq(X, theta)
    else:
        L, ok, _ = triangulate_pairwise_centroid(X, theta)
    return L, ok


def _landmark_weight(rng, poses, phi_c, sigma_v, opts):
    """log of an unbiased estimate of ``integral p1(L) prod_t N(phi_C,t - f(L, X_t)) dL`` for
    trajectories (J, i, 3) (``landmark_samples`` C samples each, :func:`._common.sample_landmarks`;
    p1 the per-point prior), the intermediate weight of C."""
    k = opts["landmark_samples"]
    L, log_q, log_lik, _ = C.sample_landmarks(rng, poses, phi_c, float(sigma_v), k,
                                              opts["ray_fraction"])
    lw = C.point_log_prior(opts["prior"], L) + log_lik - log_q
    lw = np.where(np.isnan(lw), -np.inf, lw)
    return C.logsumexp(lw, axis=1) - np.log(k)


def _match(prev, psi, Y, tol):
    """Pairs (j, k) with |wrap(dir(Y_k - X_j) - alpha_j - psi)| <= tol and their residuals."""
    J, M = prev.shape[0], Y.shape[0]
    jj_all, kk_all, res_all = [], [], []
    step = max(1, _CHUNK // max(M, 1))
    narrow = tol < np.pi / 2
    tan_tol = np.tan(tol) if narrow else np.inf
    for j0 in range(0, J, step):
        X = prev[j0:j0 + step]
        th = X[:, 2] + psi
        ux, uy = np.cos(th)[:, None], np.sin(th)[:, None]
        dx = Y[None, :, 0] - X[:, 0, None]
        dy = Y[None, :, 1] - X[:, 1, None]
        dot = dx * ux + dy * uy
        cross = ux * dy - uy * dx
        if narrow:
            cand = (dot > 0) & (np.abs(cross) <= tan_tol * dot)
        else:
            cand = np.ones(dot.shape, dtype=bool)
        jj, kk = np.nonzero(cand)
        res = np.arctan2(cross[jj, kk], dot[jj, kk])
        keep = np.abs(res) <= tol
        jj_all.append(jj[keep] + j0)
        kk_all.append(kk[keep])
        res_all.append(res[keep])
    if not jj_all:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0)
    return np.concatenate(jj_all), np.concatenate(kk_all), np.concatenate(res_all)


def _prune(state: FullState, view: int) -> FullState:
    total = state.lw_base + state.lw_res
    if total.size == 0:
        return state
    mx = np.max(total)
    if not np.isfinite(mx):
        keep = np.zeros(total.shape, dtype=bool)
    else:
        ratio = state.opts["prune_ratio"]
        floor = mx + np.log(ratio) if ratio > 0 else -np.inf
        keep = np.isfinite(total) & (total >= floor)
    idx = np.flatnonzero(keep)
    cap = state.opts["max_hypotheses"]
    lw_base = state.lw_base[idx]
    lw_res = state.lw_res[idx]
    lp_x = state.lp_x[idx]
    if idx.size > cap:
        # systematic resampling: every survivor carries the mean weight, the total is unchanged
        w = np.exp(total[idx] - mx)
        cdf = np.cumsum(w)
        cdf /= cdf[-1]
        rng = C.stream(state.root, view, C.STREAM_RESAMPLE)
        pick = np.searchsorted(cdf, (rng.random() + np.arange(cap)) / cap, side="right")
        pick = np.minimum(pick, idx.size - 1)
        mean_log = mx + np.log(w.sum() / cap)
        idx = idx[pick]
        lw_res = state.lw_res[idx]
        lp_x = state.lp_x[idx]
        lw_base = mean_log - lw_res
    return replace(state, poses=state.poses[idx], lw_base=lw_base, lw_res=lw_res, lp_x=lp_x)


def _noiseless(meas, opts) -> bool:
    return opts["motion"] == "sample" and meas.sigma_bearing == 0 and meas.sigma_heading == 0


def start(meas: C.Measurements, root, opts, part) -> FullState:
    """State after the first view (sampling step only)."""
    sv = float(meas.sigma_bearing)
    rng = C.stream(root, 0, C.STREAM_CAMERAS)
    n1 = opts["n_samples"]
    if _noiseless(meas, opts):
        # no noise to draw in the motion step (one child per hypothesis instead of
        # motion_samples): spend the same hypothesis budget on the first view instead
        n1 *= opts["motion_samples"]
    poses, lp = C.sample_view(rng, meas.bearings[0], sv, n1, opts["prior"])
    st = FullState(meas=replace(meas, bearings=meas.bearings[:1],
                                headings=None if meas.headings is None else meas.headings[:0]),
                   root=root, opts=opts, part=part, poses=poses[:, None, :], lw_base=lp,
                   lp_x=C.point_log_prior(opts["prior"], poses[:, :2]),
                   lw_res=np.zeros(lp.shape), reasons=())
    st = _prune(st, 0)
    if st.poses.shape[0] == 0:
        st = replace(st, reasons=("view 1: no valid camera sample on the locus arc",))
    return st


def _propose(rng, prev, phi, psi, sigma_v, sigma_w, r, opts):
    """Motion proposal: every hypothesis' ray (heading noise sampled) meets a locus circle drawn
    under bearing noise. Returns (parent index, poses (K, 3), log weight (K,))."""
    J = prev.shape[0]
    eps = sigma_w * rng.standard_normal((J, r))
    pa = phi[0] + sigma_v * rng.standard_normal((J, r))
    pb = phi[1] + sigma_v * rng.standard_normal((J, r))
    circ = locus_circle(pa, pb)
    th = prev[:, None, 2] + psi + eps
    pts, valid = ray_circle_intersection(prev[:, None, :2], th, circ.center, circ.radius, circ.side)
    # (J, r, 2 branches)
    par = np.broadcast_to(np.arange(J)[:, None, None], valid.shape)
    X = pts[valid]
    thv = np.broadcast_to(th[..., None], valid.shape)[valid]
    pav = np.broadcast_to(pa[..., None], valid.shape)[valid]
    # sampled noise cancels the heading and A/B bearing likelihoods; what is left is the change of
    # variables (eps, gamma) -> (x, y)
    lpx = C.point_log_prior(opts["prior"], X)
    lw = C.log_ray_jacobian(X, prev[par[valid], :2], thv) + lpx
    alpha = wrap_angle(np.arctan2(-X[:, 1], -X[:, 0]) - pav)
    return par[valid], np.concatenate([X, alpha[:, None]], axis=-1), lw, lpx


def step(state: FullState, phi, psi) -> FullState:
    """Add one view: bearings ``phi`` (3,) and heading ``psi`` from the previous view."""
    meas = state.meas
    i = meas.n_views
    opts = state.opts
    new_meas = replace(meas, bearings=np.vstack([meas.bearings, phi[None, :]]),
                       headings=np.append(meas.headings if meas.headings is not None
                                          else np.zeros(0), psi))
    sv = C.effective_sigma(meas.sigma_bearing, opts["bearing_floor"])
    sw = C.effective_sigma(meas.sigma_heading, opts["heading_floor"])
    rng = C.stream(state.root, i, C.STREAM_CAMERAS)
    reasons = state.reasons
    if np.all(np.abs(wrap_angle(phi - meas.bearings[-1])) <= C.SAME_POSE_TOL):
        # the same bearings again: the camera may not have moved (a move that repeats all three
        # bearings exactly has probability 0). Keep the pose; the view adds no constraint on C
        # beyond its line of sight, so C stays spread along it as far as the other views allow.
        st = replace(state, meas=new_meas,
                     poses=np.concatenate([state.poses, state.poses[:, -1:]], axis=1),
                     same_pose=state.same_pose + (i,))
        lw_res = _landmark_weight(C.stream(state.root, i, C.STREAM_LANDMARKS), st.poses,
                                  new_meas.bearings[:, 2], sv, opts)
        return _prune(replace(st, lw_res=lw_res), i)
    if opts["motion"] == "sample":
        r = 1 if _noiseless(meas, opts) else opts["motion_samples"]
        jj, Y, lpY, lpx = _propose(rng, state.poses[:, -1, :], phi, psi, float(meas.sigma_bearing),
                                   float(meas.sigma_heading), r, opts)
        poses = np.concatenate([state.poses[jj], Y[:, None, :]], axis=1)
        lw_base = state.lw_base[jj] + lpY - np.log(r)
    else:
        Y, lpY = C.sample_view(rng, phi, float(meas.sigma_bearing), opts["n_samples"],
                               opts["prior"])
        good = np.isfinite(lpY)
        Y, lpY = Y[good], lpY[good]
        if state.poses.shape[0] == 0 or Y.shape[0] == 0:
            return replace(state, meas=new_meas, poses=np.zeros((0, i + 1, 3)),
                           lw_base=np.zeros(0), lp_x=np.zeros(0), lw_res=np.zeros(0),
                           reasons=reasons or (f"view {i + 1}: no hypothesis to extend",))
        jj, kk, res = _match(state.poses[:, -1, :], psi, Y, opts["match_sigmas"] * float(sw))
        poses = np.concatenate([state.poses[jj], Y[kk][:, None, :]], axis=1)
        lw_base = state.lw_base[jj] + lpY[kk] + C.log_gauss(res, sw)
        lpx = C.point_log_prior(opts["prior"], Y[kk, :2])
    lw_res = _landmark_weight(C.stream(state.root, i, C.STREAM_LANDMARKS), poses,
                              new_meas.bearings[:, 2], sv, opts)
    st = replace(state, meas=new_meas, poses=poses, lw_base=lw_base,
                 lp_x=state.lp_x[jj] + lpx, lw_res=lw_res)
    st = _prune(st, i)
    if st.poses.shape[0] == 0 and not reasons:
        what = "motion step" if jj.size == 0 else "resection step"
        st = replace(st, reasons=(f"view {i + 1}: no hypothesis survived the {what}",))
    return st


def _resample(rng, logw, n):
    """Systematic resampling of n indices by weights exp(logw) (finite somewhere)."""
    w = np.exp(logw - np.max(logw))
    cdf = np.cumsum(w)
    cdf /= cdf[-1]
    return np.minimum(np.searchsorted(cdf, (rng.random() + np.arange(n)) / n, side="right"),
                      logw.size - 1)


def posterior_samples(state: FullState):
    """The final weighted sample of (trajectory, C): trajectories resampled by their
    intermediate weights (``posterior_samples`` of them), ``landmark_samples`` C samples each
    (:func:`._common.sample_landmarks`; ``one_view_samples`` with one view), weighted by the
    exact prior of the whole configuration over the intermediate one:

        w_jk  ∝  prior([L_jk, X_j]) prod_t N(phi_C,t - f(L_jk, X_jt)) / q(L_jk | X_j)
                 / (prod_t p1(X_jt) Z(X_j))

    where ``p1`` is the per-point prior and ``Z`` the triangulation weight the intermediate
    steps used. Returns (poses (M, n, 3), L (M, k, 2), log w (M, k), depth spread (M,)), or
    None when no trajectory has a finite weight."""
    opts, meas = state.opts, state.meas
    n = meas.n_views
    total = state.lw_base + state.lw_res
    if total.size == 0 or not np.any(np.isfinite(total)):
        return None
    rng = C.stream(state.root, n, C.STREAM_POSTERIOR)
    M = opts["posterior_samples"]
    idx = _resample(rng, total, M)
    poses = state.poses[idx]
    k = opts["one_view_samples"] if n == 1 else opts["landmark_samples"]
    sv = float(C.effective_sigma(meas.sigma_bearing, opts["bearing_floor"]))
    L, log_q, log_lik, spread = C.sample_landmarks(rng, poses, meas.bearings[:, 2], sv, k,
                                                   opts["ray_fraction"])
    keep = [t for t in range(n) if t not in state.same_pose]
    X = np.broadcast_to(poses[:, None, keep, :2], (M, k, len(keep), 2))
    lp = C.log_joint_prior(opts["prior"], L, X)
    with np.errstate(invalid="ignore"):
        lw = lp + log_lik - log_q - (state.lw_res[idx] + state.lp_x[idx])[:, None]
    lw = np.where(np.isnan(lw), -np.inf, lw)
    return poses, L, lw, spread


def finish(state: FullState, method: str = "full"):
    """State probabilities (eqs. slamapprox1/2) from the final weighted sample:
    (estimate, hypotheses)."""
    part, opts, meas = state.part, state.opts, state.meas
    n = meas.n_views
    reasons = list(state.reasons)
    reasons[:0] = C.geometry_reasons(meas.bearings, meas.sigma_bearing)
    if state.same_pose:
        reasons.append("view(s) " + ", ".join(str(v + 1) for v in state.same_pose)
                       + " repeat the previous view's bearings (camera taken as not moved)")
    ps = posterior_samples(state) if state.poses.shape[0] else None
    if ps is None:
        return C.uniform_estimate(method, part, n, "; ".join(reasons) or "no hypothesis", opts)
    poses, L, lw, spread = ps
    M, k = lw.shape
    w = C.normalize_log(lw.ravel())
    if not np.any(w > 0):
        reasons.append("every hypothesis has zero weight")
        return C.uniform_estimate(method, part, n, "; ".join(reasons), opts)
    l_samples = L.reshape(-1, 2)
    landmark, _ = C.state_histogram(part, l_samples, w)
    cw = w.reshape(M, k).sum(axis=1)
    cams = np.stack([C.state_histogram(part, poses[:, t, :2], cw)[0] for t in range(n)])
    if n >= 2 and np.sum(cw * (spread > C.DEPTH_SPREAD)) > 0.5:
        reasons.append("lines of sight to C (nearly) coincide: its depth along them is set by "
                       "the prior")
    hyp = C.Hypotheses(landmark_samples=l_samples, landmark_weights=w,
                       camera_samples=np.transpose(np.repeat(poses, k, axis=0), (1, 0, 2)),
                       camera_weights=np.broadcast_to(w, (n, w.size)).copy(), joint=True)
    return C.make_estimate(method, part, n, landmark, cams, hypotheses=hyp, reasons=reasons,
                           mc_error=C.weighted_state_error(part, l_samples, w), opts=opts)
