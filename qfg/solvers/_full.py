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
    lw_base: np.ndarray   # (J,) log prior x motion weights (+ resampling adjustment)
    lw_res: np.ndarray    # (J,) log resection weight at the current triangulation (+ C prior)
    landmark: np.ndarray  # (J, 2) triangulated C (zeros before the second view)
    reasons: tuple


def _triangulate(X, theta, how):
    if how == "lsq":
        L, ok = triangulate_lsq(X, theta)
    else:
        L, ok, _ = triangulate_pairwise_centroid(X, theta)
    return L, ok


def _resection(poses, phi_c, sigma_v, opts):
    """(L (J, 2), log wr summed over views + log prior of L) for trajectories (J, i, 3)."""
    theta = poses[..., 2] + phi_c[None, :]
    L, ok = _triangulate(poses[..., :2], theta, opts["resection"])
    d = L[:, None, :] - poses[..., :2]
    res = wrap_angle(np.arctan2(d[..., 1], d[..., 0]) - theta)
    lw = C.log_gauss(res, sigma_v).sum(axis=-1)
    if opts["landmark_volume"] and poses.shape[-2] >= 2:
        lw = lw + C.log_landmark_volume(poses[..., :2], L, sigma_v, opts["prior_window"])
    lw = lw + C.log_c_prior(L, opts["prior"])
    return L, np.where(ok, lw, -np.inf)


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
        lw_base = mean_log - lw_res
    return replace(state, poses=state.poses[idx], lw_base=lw_base, lw_res=lw_res,
                   landmark=state.landmark[idx])


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
    poses, lp = C.sample_view(rng, meas.bearings[0], sv, n1, opts["prior"], opts["prior_window"])
    st = FullState(meas=replace(meas, bearings=meas.bearings[:1],
                                headings=None if meas.headings is None else meas.headings[:0]),
                   root=root, opts=opts, part=part, poses=poses[:, None, :], lw_base=lp,
                   lw_res=np.zeros(lp.shape), landmark=np.zeros((lp.size, 2)), reasons=())
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
    lw = C.log_ray_jacobian(X, prev[par[valid], :2], thv)
    lw = lw + C.log_point_prior(X, opts["prior"], opts["prior_window"])
    alpha = wrap_angle(np.arctan2(-X[:, 1], -X[:, 0]) - pav)
    return par[valid], np.concatenate([X, alpha[:, None]], axis=-1), lw


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
    if opts["motion"] == "sample":
        r = 1 if _noiseless(meas, opts) else opts["motion_samples"]
        jj, Y, lpY = _propose(rng, state.poses[:, -1, :], phi, psi, float(meas.sigma_bearing),
                              float(meas.sigma_heading), r, opts)
        poses = np.concatenate([state.poses[jj], Y[:, None, :]], axis=1)
        lw_base = state.lw_base[jj] + lpY - np.log(r)
    else:
        Y, lpY = C.sample_view(rng, phi, float(meas.sigma_bearing), opts["n_samples"],
                               opts["prior"], opts["prior_window"])
        good = np.isfinite(lpY)
        Y, lpY = Y[good], lpY[good]
        if state.poses.shape[0] == 0 or Y.shape[0] == 0:
            return replace(state, meas=new_meas, poses=np.zeros((0, i + 1, 3)),
                           lw_base=np.zeros(0), lw_res=np.zeros(0), landmark=np.zeros((0, 2)),
                           reasons=reasons or (f"view {i + 1}: no hypothesis to extend",))
        jj, kk, res = _match(state.poses[:, -1, :], psi, Y, opts["match_sigmas"] * float(sw))
        poses = np.concatenate([state.poses[jj], Y[kk][:, None, :]], axis=1)
        lw_base = state.lw_base[jj] + lpY[kk] + C.log_gauss(res, sw)
    L, lw_res = _resection(poses, new_meas.bearings[:, 2], sv, opts)
    st = FullState(meas=new_meas, root=state.root, opts=opts, part=state.part, poses=poses,
                   lw_base=lw_base, lw_res=lw_res, landmark=L, reasons=reasons)
    st = _prune(st, i)
    if st.poses.shape[0] == 0 and not reasons:
        what = "motion step" if jj.size == 0 else "resection step"
        st = replace(st, reasons=(f"view {i + 1}: no hypothesis survived the {what}",))
    return st


def finish(state: FullState, method: str = "full"):
    """State probabilities (eqs. slamapprox1/2) from the hypotheses: (estimate, hypotheses)."""
    part, opts, meas = state.part, state.opts, state.meas
    n = meas.n_views
    reasons = list(state.reasons)
    bad = C.nominal_degenerate(meas.bearings)
    if bad:
        reasons.insert(0, "camera on line AB (phi_A = phi_B or opposite) in view(s) "
                       + ", ".join(str(b + 1) for b in bad))
    J = state.poses.shape[0]
    if J == 0:
        return C.uniform_estimate(method, part, n, "; ".join(reasons) or "no hypothesis", opts)
    total = state.lw_base + state.lw_res
    if n == 1:
        k = opts["one_view_samples"]
        rng = C.stream(state.root, 0, C.STREAM_ONE_VIEW)
        cam = state.poses[:, 0, :]
        ang = (cam[:, 2] + meas.bearings[0, 2])[:, None] + \
            float(meas.sigma_bearing) * rng.standard_normal((J, k))
        q = rng.random((J, k, 1))
        origins = np.broadcast_to(cam[:, None, :2], (J, k, 2))
        if opts["prior"] == "world":
            pts, log_mass = C.landmarks_on_rays_world(origins, ang, q)
            log_mass = log_mass[..., 0]
        else:
            pts, log_mass = C.landmarks_on_rays(origins, ang, q, opts["prior_window"])
        lw_l = (total[:, None] + log_mass).reshape(-1)
        lw_cam = total + C.logsumexp(log_mass, axis=1) - np.log(k)
        l_samples = pts.reshape(-1, 2)
        l_w = C.normalize_log(lw_l)
        c_w = C.normalize_log(lw_cam)[None, :]
        joint = False
    else:
        l_samples = state.landmark
        l_w = C.normalize_log(total)
        c_w = np.broadcast_to(l_w, (n, J)).copy()
        joint = True
    landmark, ok = C.state_histogram(part, l_samples, l_w)
    cams = np.stack([C.state_histogram(part, state.poses[:, t, :2], c_w[t])[0] for t in range(n)])
    if not ok:
        reasons.append("every hypothesis has zero weight")
    hyp = C.Hypotheses(landmark_samples=l_samples, landmark_weights=l_w,
                       camera_samples=np.transpose(state.poses, (1, 0, 2)), camera_weights=c_w,
                       joint=joint)
    return C.make_estimate(method, part, n, landmark, cams, hypotheses=hyp, reasons=reasons,
                           opts=opts)
