"""The fast variant (the paper's section 4e), batched over triplets.

Samples represent only the prior: the first camera is placed at ``n_samples`` deterministic points
of its exact locus arc (measured phi_A, phi_B taken as exact). No measurement or motion noise is
sampled: each hypothesis is carried to the next view by intersecting the ray from X_{i-1} along
``alpha_{i-1} + psi_{i-1}`` with that view's exact locus arc (0, 1 or 2 new hypotheses), and C is
triangulated from the lines of sight. The noise enters only through the weights, evaluated at this
deterministic geometry: ``prior(X_1 .. X_n, L) x prod_t N(phi_C,t - f(L, X_t); sigma_v)`` (with the
width floored at ``bearing_floor``) and, with ``jacobian=True``, the change of variables of each
motion step, ``t / |grad Gamma . u|`` (:func:`._common.log_ray_jacobian`: the density of
positions reached along the rays, the noiseless limit of the full solver's weights). One view: C
at deterministic quantiles along each camera's line of sight.

Arrays carry a leading triplet axis T; hypotheses that died are kept as -inf weights until the set
is compacted, so one triplet solved alone and the same triplet solved in a batch give the same
numbers.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..geometry import (
    heading_on_locus,
    locus_circle,
    ray_circle_intersection,
    triangulate_lsq,
    triangulate_pairwise_centroid,
    wrap_angle,
)
from . import _common as C


@dataclass(frozen=True, eq=False)
class FastState:
    """Hypotheses of T triplets after the views so far."""

    bearings: np.ndarray   # (T, i, 3)
    headings: np.ndarray   # (T, i - 1)
    sigma_bearing: np.ndarray  # (T,)
    sigma_heading: np.ndarray  # (T,)
    opts: dict
    part: object
    poses: np.ndarray      # (T, H, i, 3)
    lw_base: np.ndarray    # (T, H) log prior x cell width (-inf: dead)
    w: np.ndarray          # (T, H) first camera's arc parameter (the cell centre)
    lwidth: np.ndarray     # (T, H) log width of its cell in w

    @property
    def n_views(self) -> int:
        return self.bearings.shape[1]

    def kernel_sigma(self) -> np.ndarray:
        """(T,) width of the C-bearing likelihood: ``max(sigma_v, floor)``, combined in quadrature
        with sigma_w when ``kernel="combined"`` (the headings taken as exact move the cameras, and
        so the predicted C bearings, by about that much)."""
        sv = C.effective_sigma(self.sigma_bearing, self.opts["bearing_floor"])
        if self.opts["kernel"] == "combined":
            sv = np.hypot(sv, self.sigma_heading)
        return sv

    def take(self, t: int) -> "FastState":
        """The state of triplet t alone (T = 1)."""
        sl = slice(t, t + 1)
        return replace(self, bearings=self.bearings[sl], headings=self.headings[sl],
                       sigma_bearing=self.sigma_bearing[sl],
                       sigma_heading=self.sigma_heading[sl], poses=self.poses[sl],
                       lw_base=self.lw_base[sl], w=self.w[sl], lwidth=self.lwidth[sl])


def _take(idx, poses, *arrays):
    return (np.take_along_axis(poses, idx[:, :, None, None], axis=1),
            *(np.take_along_axis(a, idx, axis=1) for a in arrays))


def _compact(rank, keep_max, poses, *arrays):
    """Keep at most ``keep_max`` hypotheses per triplet, the heaviest by ``rank`` (T, H), dropping
    dead ones (-inf); the kept ones stay in their original order."""
    T, H = rank.shape
    alive = np.isfinite(rank)
    k = int(min(keep_max, max(1, alive.sum(axis=1).max(initial=0))))
    if k >= H:
        return (poses, *arrays)
    idx = np.sort(np.argpartition(-np.where(alive, rank, -np.inf), k - 1, axis=1)[:, :k], axis=1)
    return _take(idx, poses, *arrays)


def _resection(poses, phi_c, sigma_v, opts, alive=None):
    """(L (T, H, 2), log wr + log C prior (T, H)) for trajectories (T, H, i, 3); only the
    ``alive`` (T, H) ones are computed (flattened: much faster than 4-d fancy indexing)."""
    T, H, n = poses.shape[:3]
    if alive is None:
        alive = np.ones((T, H), dtype=bool)
    tt, hh = np.nonzero(alive)
    P = poses[tt, hh]                                    # (N, n, 3)
    theta = P[..., 2] + phi_c[tt]
    if opts["resection"] == "lsq":
        L, ok = triangulate_lsq(P[..., :2], theta)
    else:
        L, ok, _ = triangulate_pairwise_centroid(P[..., :2], theta)
    d = L[:, None, :] - P[..., :2]
    res = wrap_angle(np.arctan2(d[..., 1], d[..., 0]) - theta)
    sv = sigma_v[tt]
    lw = C.log_gauss(res, sv[:, None]).sum(axis=-1)
    if opts["landmark_volume"] and n >= 2:
        lw = lw + C.log_landmark_volume(P[..., :2], L, sv, opts["prior_window"])
    lw = lw + C.log_c_prior(L, opts["prior"])
    L_out = np.zeros((T, H, 2))
    lw_out = np.full((T, H), -np.inf)
    L_out[tt, hh] = L
    lw_out[tt, hh] = np.where(ok, lw, -np.inf)
    return L_out, lw_out


def _first(b0, w, lwidth, opts):
    poses, lp = C.arc_poses(b0[:, 0], b0[:, 1], w, opts["prior"], opts["prior_window"])
    return poses[:, :, None, :], lp + lwidth


def _extend(poses, lw, w, lwidth, bearings, phi, psi, sv, opts):
    """One motion step for hypotheses (T, H, i, 3): rays along alpha + psi meet view i+1's exact
    arc. ``bearings`` (T, i + 1, 3) are the views including the new one."""
    prev = poses[:, :, -1, :]
    circ = locus_circle(phi[:, 0], phi[:, 1])
    th = prev[..., 2] + psi[:, None]
    pts, valid = ray_circle_intersection(prev[..., :2], th, circ.center[:, None, :],
                                         circ.radius[:, None], circ.side[:, None])
    T, H = lw.shape
    X = pts.reshape(T, 2 * H, 2)
    alpha = heading_on_locus(X, phi[:, None, 0])
    poses = np.concatenate([np.repeat(poses, 2, axis=1),
                            np.concatenate([X, alpha[..., None]], axis=-1)[:, :, None, :]], axis=2)
    lw = np.repeat(lw, 2, axis=1) + C.log_point_prior(X, opts["prior"], opts["prior_window"])
    if opts["jacobian"]:
        lw = lw + C.log_ray_jacobian(X, np.repeat(prev[..., :2], 2, axis=1),
                                     np.repeat(th, 2, axis=1))
    lw = np.where(valid.reshape(T, 2 * H), lw, -np.inf)
    w, lwidth = np.repeat(w, 2, axis=1), np.repeat(lwidth, 2, axis=1)
    if 2 * H > opts["max_hypotheses"]:
        # rank by the current total (prior x resection), keep the prior part: wr is recomputed
        _, lw_res = _resection(poses, bearings[..., 2], sv, opts, np.isfinite(lw))
        return _compact(lw + lw_res, opts["max_hypotheses"], poses, lw, w, lwidth)
    return _compact(lw, 2 * H, poses, lw, w, lwidth)


def _chain(bearings, headings, sv, w, lwidth, opts):
    """Hypotheses of every view for first-camera parameters ``w`` (T, K)."""
    poses, lw = _first(bearings[:, 0], w, lwidth, opts)
    for i in range(1, bearings.shape[1]):
        poses, lw, w, lwidth = _extend(poses, lw, w, lwidth, bearings[:, :i + 1],
                                       bearings[:, i], headings[:, i - 1], sv, opts)
    return poses, lw, w, lwidth


def start(bearings0, sigma_bearing, sigma_heading, opts, part) -> FastState:
    """First view of T triplets: bearings0 (T, 3), sigmas (T,)."""
    T, M = bearings0.shape[0], opts["n_samples"]
    w = np.broadcast_to((np.arange(M) + 0.5) / M, (T, M))
    lwidth = np.full((T, M), -np.log(M))
    poses, lw = _first(bearings0, w, lwidth, opts)
    return FastState(bearings=bearings0[:, None, :], headings=np.zeros((T, 0)),
                     sigma_bearing=np.asarray(sigma_bearing, dtype=float).reshape(T),
                     sigma_heading=np.asarray(sigma_heading, dtype=float).reshape(T),
                     opts=opts, part=part, poses=poses, lw_base=lw, w=w, lwidth=lwidth)


def step(state: FastState, phi, psi) -> FastState:
    """Add one view to T triplets: ``phi`` (T, 3), ``psi`` (T,)."""
    bearings = np.concatenate([state.bearings, phi[:, None, :]], axis=1)
    sv = state.kernel_sigma()
    poses, lw, w, lwidth = _extend(state.poses, state.lw_base, state.w, state.lwidth, bearings,
                                   phi, psi, sv, state.opts)
    return replace(state, bearings=bearings,
                   headings=np.concatenate([state.headings, psi[:, None]], axis=1),
                   poses=poses, lw_base=lw, w=w, lwidth=lwidth)


def _refine(state: FastState, sv):
    """Adaptive quadrature over the first camera's arc parameter: the cells of the
    ``refine_cells`` heaviest hypotheses are split into ``refine_factor`` sub-cells and solved
    again, ``refine_levels`` times. Returns (poses, total log weight, triangulated C)."""
    opts = state.opts
    b, h = state.bearings, state.headings
    poses, lw, w, lwidth = state.poses, state.lw_base, state.w, state.lwidth
    L, lr = _resection(poses, b[..., 2], sv, opts, np.isfinite(lw))
    total = lw + lr
    K, R = opts["refine_cells"], opts["refine_factor"]
    for _ in range(opts["refine_levels"]):
        T, H = total.shape
        k = min(K, H)
        pick = np.argpartition(-total, k - 1, axis=1)[:, :k]
        ok = np.isfinite(np.take_along_axis(total, pick, axis=1))
        wp = np.take_along_axis(w, pick, axis=1)
        lwp = np.take_along_axis(lwidth, pick, axis=1)
        # one refinement per cell, even if several of its branches were picked
        order = np.argsort(np.where(ok, wp, np.inf), axis=1)
        wp, lwp, ok = (np.take_along_axis(a, order, axis=1) for a in (wp, lwp, ok))
        ok[:, 1:] &= wp[:, 1:] != wp[:, :-1]
        if not ok.any():
            break
        off = (np.arange(R) + 0.5) / R - 0.5
        wn = (wp[..., None] + np.exp(lwp)[..., None] * off).reshape(T, k * R)
        # sub-cells of duplicate or dead picks start dead (-inf width)
        lwn = np.repeat(np.where(ok, lwp - np.log(R), -np.inf), R, axis=1)
        pn, lwn_base, wn, lwn = _chain(b, h, sv, wn, lwn, opts)
        Ln, lrn = _resection(pn, b[..., 2], sv, opts, np.isfinite(lwn_base))
        tn = lwn_base + lrn
        replaced = np.any((w[:, :, None] == wp[:, None, :]) & ok[:, None, :], axis=2)
        total = np.where(replaced, -np.inf, total)
        poses = np.concatenate([poses, pn], axis=1)
        total = np.concatenate([total, tn], axis=1)
        w = np.concatenate([w, wn], axis=1)
        lwidth = np.concatenate([lwidth, lwn], axis=1)
        Lx, Ly = np.concatenate([L, Ln], axis=1).transpose(2, 0, 1)
        poses, total, w, lwidth, Lx, Ly = _compact(total, total.shape[1], poses, total, w,
                                                   lwidth, Lx, Ly)
        L = np.stack([Lx, Ly], axis=-1)
    return poses, total, L


def finish(state: FastState) -> list[C.TripletEstimate]:
    """One estimate per triplet of the batch."""
    opts, part = state.opts, state.part
    m = part.n_states
    T, H, n = state.poses.shape[0], state.poses.shape[1], state.n_views
    sv = state.kernel_sigma()
    if n == 1:
        k = opts["one_view_samples"]
        poses = state.poses
        cam = poses[:, :, 0, :]
        ang = cam[..., 2] + state.bearings[:, None, 0, 2]
        q = (np.arange(k) + 0.5) / k
        if opts["prior"] == "world":
            pts, lw_q = C.landmarks_on_rays_world(cam[..., :2], ang, q)
            lw_l = (state.lw_base[..., None] + lw_q - np.log(k)).reshape(T, H * k)
            lw_cam = state.lw_base + C.logsumexp(lw_q, axis=-1) - np.log(k)
        else:
            pts, log_mass = C.landmarks_on_rays(cam[..., :2], ang, q, opts["prior_window"])
            lw_cam = state.lw_base + log_mass
            lw_l = np.repeat(lw_cam, k, axis=1) - np.log(k)
        l_samples = pts.reshape(T, H * k, 2)
    else:
        poses, lw_cam, l_samples = _refine(state, sv)
        H = poses.shape[1]
        lw_l = lw_cam
    l_w = C.normalize_log(lw_l)
    c_w = C.normalize_log(lw_cam)
    # state histograms for the whole batch at once: one bincount over (triplet, state)
    ls = part.state_of(l_samples)
    lm = np.bincount((ls + m * np.arange(T)[:, None]).ravel(), weights=l_w.ravel(),
                     minlength=T * m).reshape(T, m)
    cs = part.state_of(poses[..., :2])  # (T, H, n)
    idx = cs + m * (np.arange(T)[:, None, None] * n + np.arange(n)[None, None, :])
    cm = np.bincount(idx.ravel(), weights=np.repeat(c_w[:, :, None], n, axis=2).ravel(),
                     minlength=T * n * m).reshape(T, n, m)
    out = []
    for t in range(T):
        reasons = []
        bad = C.nominal_degenerate(state.bearings[t])
        if bad:
            reasons.append("camera on line AB (phi_A = phi_B or opposite) in view(s) "
                           + ", ".join(str(b + 1) for b in bad))
        alive = c_w[t] > 0
        st_t = state.take(t)
        if not np.any(alive):
            reasons.append("no hypothesis survived (rays miss the locus arcs or C cannot be "
                           "triangulated)")
            out.append(C.uniform_estimate("fast", part, n, "; ".join(reasons), opts, st_t))
            continue
        land = lm[t] / lm[t].sum()
        cams = cm[t] / cm[t].sum(axis=1, keepdims=True)
        keep_l = l_w[t] > 0
        out.append(C.TripletEstimate(
            landmark=land, cameras=cams, n_hypotheses=int(alive.sum()),
            degenerate=bool(reasons), reason="; ".join(reasons), method="fast",
            partition=part.name, n_views=n, landmark_samples=l_samples[t][keep_l],
            landmark_weights=l_w[t][keep_l],
            camera_samples=np.transpose(poses[t][alive], (1, 0, 2)),
            camera_weights=np.broadcast_to(c_w[t][alive], (n, int(alive.sum()))).copy(),
            joint=n > 1, options=opts, _state=st_t))
    return out
