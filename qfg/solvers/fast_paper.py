"""The fast variant (the paper's section 4e), batched over triplets.

Samples represent only the prior: the first camera is placed at ``n_samples`` deterministic points
of its exact locus arc (measured phi_A, phi_B taken as exact). No measurement or motion noise is
sampled: each hypothesis is carried to the next view by intersecting the ray from X_{i-1} along
``alpha_{i-1} + psi_{i-1}`` with that view's exact locus arc (0, 1 or 2 new hypotheses), and C is
triangulated from the lines of sight. The noise enters only through the weights, evaluated at this
deterministic geometry: ``prior(X_1 .. X_n, L) x prod_t N(phi_C,t - f(L, X_t); sigma)`` (sigma =
``max(sigma_v, bearing_floor)``, or combined with sigma_w: option ``kernel``) and, with
``jacobian=True``, the change of variables of each motion step, ``t / |grad Gamma . u|``
(:func:`.arcs.log_ray_jacobian`: the density of positions reached along the rays, the noiseless
limit of the full solver's weights). The first camera's arc parameter is integrated adaptively:
after the coarse grid, the cells of the heaviest hypotheses are split and solved again
(``refine_*`` options). One view: C at deterministic quantiles along each camera's line of sight.

Hypotheses of all triplets of a batch live in flat arrays with a triplet index (no padding), kept
sorted by triplet, so one triplet solved alone and the same triplet solved in a batch give the same
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
from .common import arcs as _arcs
from .common import degenerate as _degenerate
from .common import estimate as _estimate
from .common import laplace as _laplace
from .common import likelihood as _likelihood
from .common import options as _options
from .common import prior as _prior


@dataclass(frozen=True, eq=False)
class FastState(_estimate.TripletBatchSizes):
    """Hypotheses of T triplets after the views so far (flat, sorted by triplet)."""

    bearings: np.ndarray       # (T, i, 3)
    headings: np.ndarray       # (T, i - 1)
    sigma_bearing: np.ndarray  # (T,)
    sigma_heading: np.ndarray  # (T,)
    opts: dict
    part: object
    tid: np.ndarray            # (N,) triplet of each hypothesis
    poses: np.ndarray          # (N, i, 3)
    lw: np.ndarray             # (N,) log prior x cell width
    w: np.ndarray              # (N,) first camera's arc parameter (its cell centre)
    lwidth: np.ndarray         # (N,) log width of that cell

    def kernel_sigma(self) -> np.ndarray:
        """(T,) width of the C-bearing likelihood: ``max(sigma_v, floor)``, combined in quadrature
        with sigma_w when ``kernel="combined"`` (the headings taken as exact move the cameras, and
        so the predicted C bearings, by about that much)."""
        sv = _options.effective_sigma(self.sigma_bearing, self.opts["bearing_floor"])
        if self.opts["kernel"] == "combined":
            sv = np.hypot(sv, self.sigma_heading)
        return sv

    def take(self, t: int) -> "FastState":
        """The state of triplet t alone (T = 1)."""
        a, b = np.searchsorted(self.tid, [t, t + 1])
        sl = slice(t, t + 1)
        return replace(self, bearings=self.bearings[sl], headings=self.headings[sl],
                       sigma_bearing=self.sigma_bearing[sl], sigma_heading=self.sigma_heading[sl],
                       tid=np.zeros(b - a, dtype=np.int64), poses=self.poses[a:b], lw=self.lw[a:b],
                       w=self.w[a:b], lwidth=self.lwidth[a:b])


def _rank_within(tid, key):
    """Rank (0 = largest key) of every element within its triplet; dead (-inf) ones rank last."""
    order = np.lexsort((-key, tid))
    rank = np.empty(tid.size, dtype=np.int64)
    st = tid[order]
    first = np.searchsorted(st, st, side="left")
    rank[order] = np.arange(tid.size) - first
    return rank


#: Quadrature points along the line of sight when the lines of sight coincide (n >= 2): C's
#: depth then spreads over several states, which a handful of points would not resolve.
COINCIDE_POINTS = 64


def _ray_landmarks(tid, poses, phi_c, sigma_v, opts):
    """C integrated along the first camera's line of sight by deterministic quadrature, for
    trajectories (N, i, 3) whose lines of sight to C coincide (C's depth is then left to the
    prior): ``k = one_view_samples`` points at quantiles of the ray proposal
    (:func:`.arcs.ray_points`), weighted ``prior(L) t / q(t)`` (the area element ``t dt dtheta``
    with view 1's angular likelihood integrated out) times the C-bearing likelihood of the other
    views (``k = COINCIDE_POINTS`` with more than one view). Returns (points (N, k, 2), log
    weights (N, k))."""
    k = opts["one_view_samples"] if poses.shape[1] == 1 else max(opts["one_view_samples"],
                                                                 COINCIDE_POINTS)
    cam = poses[:, 0, :]
    ang = cam[:, 2] + phi_c[tid, 0]
    q = (np.arange(k) + 0.5) / k
    pts, lq = _arcs.ray_points(cam[:, :2], ang, np.zeros((ang.size, k)),
                               np.broadcast_to(q, (ang.size, k)), 1.0)
    # lq is log[N(0; 1) q(t) / t]: without the angular factor it is log q(t) - log t
    lq = lq - _likelihood.log_gauss(0.0, 1.0) + 0.5 * np.log(2 * np.pi)
    lw = _prior.point_log_prior(opts["prior"], pts) - lq
    if poses.shape[1] > 1:
        d = pts[:, :, None, :] - poses[:, None, 1:, :2]                  # (N, k, i - 1, 2)
        th = poses[:, None, 1:, 2] + phi_c[tid][:, None, 1:]
        res = wrap_angle(np.arctan2(d[..., 1], d[..., 0]) - th)
        lw = lw + _likelihood.log_gauss(res, sigma_v[tid][:, None, None]).sum(axis=-1)
    return pts, lw


def _resection(tid, poses, phi_c, sigma_v, opts, along_ray=None):
    """(L (N, 2), log wr + log C prior (N,)) for trajectories (N, i, 3) of triplets ``tid``.
    Triplets with ``along_ray`` (T,) True get C integrated along the line of sight instead
    (:func:`_ray_landmarks`; L is then its heaviest point)."""
    if along_ray is not None and np.any(along_ray[tid]):
        r = along_ray[tid]
        L, lw = np.empty((tid.size, 2)), np.empty(tid.size)
        L[~r], lw[~r] = _resection(tid[~r], poses[~r], phi_c, sigma_v, opts)
        pts, lq = _ray_landmarks(tid[r], poses[r], phi_c, sigma_v, opts)
        L[r] = pts[np.arange(pts.shape[0]), np.argmax(lq, axis=1)]
        lw[r] = _likelihood.logsumexp(lq, axis=1) - np.log(lq.shape[1])
        return L, lw
    theta = poses[..., 2] + phi_c[tid]
    if opts["resection"] == "lsq":
        L, ok = triangulate_lsq(poses[..., :2], theta)
    else:
        L, ok, _ = triangulate_pairwise_centroid(poses[..., :2], theta)
    d = L[:, None, :] - poses[..., :2]
    res = wrap_angle(np.arctan2(d[..., 1], d[..., 0]) - theta)
    sv = sigma_v[tid]
    lw = _likelihood.log_gauss(res, sv[:, None]).sum(axis=-1)
    if opts["landmark_volume"] and poses.shape[1] >= 2:
        lw = lw + _laplace.log_landmark_volume(poses[..., :2], L, sv)
    lw = lw + _prior.point_log_prior(opts["prior"], L)
    return L, np.where(ok, lw, -np.inf)


def _first(b0, tid, w, lwidth, opts):
    """First-view hypotheses at arc parameters ``w`` (N,) of triplets ``tid``; alive ones only."""
    poses, lp = _arcs.arc_poses(b0[tid, 0], b0[tid, 1], w[:, None], opts["prior"])
    lw = lp[:, 0] + lwidth
    keep = np.isfinite(lw)
    return tid[keep], poses[keep], lw[keep], w[keep], lwidth[keep]


def _extend(hyp, bearings, headings, sv, opts, along_ray=None):
    """One motion step: rays along alpha + psi meet the next view's exact arc. ``bearings``
    (T, i + 1, 3) include the new view, ``headings`` (T, i). A view that repeats the previous
    one's bearings (:func:`.degenerate.repeated_views`) keeps every camera where it was (the
    camera taken as not moved: no ray, no new point in the prior)."""
    tid, poses, lw, w, lwidth = hyp
    phi, psi = bearings[:, -1], headings[:, -1]
    prev = poses[:, -1, :]
    circ = locus_circle(phi[:, 0], phi[:, 1])
    th = prev[:, 2] + psi[tid]
    pts, valid = ray_circle_intersection(prev[:, :2], th, circ.center[tid], circ.radius[tid],
                                         circ.side[tid])
    same = np.all(np.abs(wrap_angle(phi - bearings[:, -2])) <= _degenerate.SAME_POSE_TOL,
                  axis=1)[tid]
    pts[same, 0], valid[same, 0], valid[same, 1:] = prev[same, :2], True, False
    j, b = np.nonzero(valid)                      # parent, branch; parents stay in order
    X = pts[j, b]
    stay = same[j]
    alpha = np.where(stay, prev[j, 2], heading_on_locus(X, phi[tid[j], 0]))
    lw_new = lw[j] + np.where(stay, 0.0, _prior.point_log_prior(opts["prior"], X))
    if opts["jacobian"]:
        with np.errstate(invalid="ignore"):
            lw_new = lw_new + np.where(stay, 0.0, _arcs.log_ray_jacobian(X, prev[j, :2], th[j]))
    keep = np.isfinite(lw_new)
    j, X, alpha, lw_new = j[keep], X[keep], alpha[keep], lw_new[keep]
    poses = np.concatenate([poses[j], np.concatenate([X, alpha[:, None]], axis=-1)[:, None, :]],
                           axis=1)
    tid, w, lwidth = tid[j], w[j], lwidth[j]
    cap = opts["max_hypotheses"]
    if tid.size and np.bincount(tid).max() > cap:
        # rank by the current total (prior x resection), keep the prior part: wr is recomputed
        _, lr = _resection(tid, poses, bearings[..., 2], sv, opts, along_ray)
        keep = _rank_within(tid, lw_new + lr) < cap
        return tid[keep], poses[keep], lw_new[keep], w[keep], lwidth[keep]
    return tid, poses, lw_new, w, lwidth


def _chain(bearings, headings, sv, tid, w, lwidth, opts, along_ray=None):
    """Hypotheses after every view, for first-camera parameters ``w`` (N,) of triplets ``tid``."""
    hyp = _first(bearings[:, 0], tid, w, lwidth, opts)
    for i in range(1, bearings.shape[1]):
        hyp = _extend(hyp, bearings[:, :i + 1], headings[:, :i], sv, opts, along_ray)
    return hyp


def start(bearings0, sigma_bearing, sigma_heading, opts, part) -> FastState:
    """First view of T triplets: bearings0 (T, 3), sigmas (T,)."""
    T, M = bearings0.shape[0], opts["n_samples"]
    tid = np.repeat(np.arange(T), M)
    w = np.tile((np.arange(M) + 0.5) / M, T)
    tid, poses, lw, w, lwidth = _first(bearings0, tid, w, np.full(T * M, -np.log(M)), opts)
    return FastState(bearings=bearings0[:, None, :], headings=np.zeros((T, 0)),
                     sigma_bearing=np.asarray(sigma_bearing, dtype=float).reshape(T),
                     sigma_heading=np.asarray(sigma_heading, dtype=float).reshape(T),
                     opts=opts, part=part, tid=tid, poses=poses, lw=lw, w=w, lwidth=lwidth)


def step(state: FastState, phi, psi) -> FastState:
    """Add one view to T triplets: ``phi`` (T, 3), ``psi`` (T,)."""
    bearings = np.concatenate([state.bearings, phi[:, None, :]], axis=1)
    headings = np.concatenate([state.headings, psi[:, None]], axis=1)
    hyp = (state.tid, state.poses, state.lw, state.w, state.lwidth)
    tid, poses, lw, w, lwidth = _extend(hyp, bearings, headings, state.kernel_sigma(), state.opts,
                                        _along_ray(bearings, headings, state))
    return replace(state, bearings=bearings, headings=headings, tid=tid, poses=poses, lw=lw, w=w,
                   lwidth=lwidth)


def _along_ray(bearings, headings, state) -> np.ndarray:
    """(T,) triplets whose lines of sight to C coincide whatever the trajectory: every view after
    the first repeats its predecessor (:func:`.degenerate.repeated_views`), or the camera travels
    along its line of sight to C between every pair of views (the flag of
    :func:`.degenerate.geometry_reasons`). Their C is integrated along the line of sight."""
    T, n = bearings.shape[:2]
    out = np.zeros(T, dtype=bool)
    if n < 2:
        return out
    for t in range(T):
        rep = _degenerate.repeated_views(bearings[t])
        out[t] = bool(np.all(rep[1:])) or any(
            "coincide" in r for r in _degenerate.geometry_reasons(
                bearings[t], state.sigma_bearing[t], headings[t], state.sigma_heading[t]))
    return out


def _refine(state: FastState, sv):
    """Adaptive quadrature over the first camera's arc parameter: the cells of each triplet's
    ``refine_cells`` heaviest hypotheses are split into ``refine_factor`` sub-cells and solved
    again, ``refine_levels`` times. Returns (tid, poses, total log weight, triangulated C),
    sorted by triplet."""
    opts = state.opts
    b, h = state.bearings, state.headings
    ray = _along_ray(b, h, state)
    tid, poses, lw, w, lwidth = state.tid, state.poses, state.lw, state.w, state.lwidth
    L, lr = _resection(tid, poses, b[..., 2], sv, opts, ray)
    total = lw + lr
    K, R = opts["refine_cells"], opts["refine_factor"]
    for _ in range(opts["refine_levels"]):
        pick = (_rank_within(tid, total) < K) & np.isfinite(total)
        if not pick.any():
            break
        # one refinement per cell, even if several of its branches were picked
        order = np.lexsort((w[pick], tid[pick]))
        pt, pw, plw = tid[pick][order], w[pick][order], lwidth[pick][order]
        new = np.ones(pt.size, dtype=bool)
        new[1:] = (pt[1:] != pt[:-1]) | (pw[1:] != pw[:-1])
        pt, pw, plw = pt[new], pw[new], plw[new]
        off = (np.arange(R) + 0.5) / R - 0.5
        nt = np.repeat(pt, R)
        nw = (pw[:, None] + np.exp(plw)[:, None] * off).ravel()
        nlw = np.repeat(plw - np.log(R), R)
        hn = _chain(b, h, sv, nt, nw, nlw, opts, ray)
        Ln, lrn = _resection(hn[0], hn[1], b[..., 2], sv, opts, ray)
        # the refined cells' coarse hypotheses are replaced by their sub-cells'
        key = tid * 4.0 + w
        gone = np.isin(key, pt * 4.0 + pw)
        keep = ~gone
        tid = np.concatenate([tid[keep], hn[0]])
        order = np.argsort(tid, kind="stable")
        tid = tid[order]
        poses = np.concatenate([poses[keep], hn[1]])[order]
        total = np.concatenate([total[keep], hn[2] + lrn])[order]
        w = np.concatenate([w[keep], hn[3]])[order]
        lwidth = np.concatenate([lwidth[keep], hn[4]])[order]
        L = np.concatenate([L[keep], Ln])[order]
    return tid, poses, total, L, ray


def _segment_normalize(tid, lw, T):
    """exp(lw) normalized within each triplet; all-dead triplets give zeros."""
    mx = np.full(T, -np.inf)
    np.maximum.at(mx, tid, lw)
    ok = np.isfinite(mx)
    e = np.where(np.isfinite(lw), np.exp(lw - np.where(ok, mx, 0.0)[tid]), 0.0)
    s = np.bincount(tid, weights=e, minlength=T)
    return np.where(s[tid] > 0, e / np.where(s > 0, s, 1.0)[tid], 0.0)


def finish(state: FastState, hypotheses: bool = False):
    """One (estimate, hypotheses or None) pair per triplet of the batch; the hypotheses are
    built only when asked for (the solver object asks, batched solves do not)."""
    opts, part = state.opts, state.part
    m, T, n = part.n_states, state.n_triplets, state.n_views
    sv = state.kernel_sigma()
    if n == 1:
        k = opts["one_view_samples"]
        tid, poses, lw = state.tid, state.poses, state.lw
        # C at deterministic quantiles along the line of sight
        pts, lw_q = _ray_landmarks(tid, poses, state.bearings[..., 2], sv, opts)
        lw_l = (lw[:, None] + lw_q - np.log(k)).ravel()
        lw_cam = lw + _likelihood.logsumexp(lw_q, axis=-1) - np.log(k)
        l_samples, l_tid = pts.reshape(-1, 2), np.repeat(tid, k)
    else:
        tid, poses, lw_cam, l_samples, ray = _refine(state, sv)
        lw_l, l_tid = lw_cam, tid
        if np.any(ray):
            # C along the line of sight: the quadrature points, each with its share of its
            # trajectory's weight (rows of a triplet stay together, in triplet order)
            r = ray[tid]
            pts, lw_q = _ray_landmarks(tid[r], poses[r], state.bearings[..., 2], sv, opts)
            share = lw_q - _likelihood.logsumexp(lw_q, axis=1)[:, None]
            k = lw_q.shape[1]
            reps = np.where(r, k, 1)
            l_tid = np.repeat(tid, reps)
            l_samples = np.repeat(l_samples, reps, axis=0)
            lw_l = np.repeat(lw_cam, reps)
            at = np.flatnonzero(np.repeat(r, reps))
            l_samples[at] = pts.reshape(-1, 2)
            lw_l[at] = (lw_cam[r][:, None] + share).ravel()
    l_w = _segment_normalize(l_tid, lw_l, T)
    c_w = _segment_normalize(tid, lw_cam, T)
    # state histograms for the whole batch at once: one bincount over (triplet, state)
    lm = np.bincount(l_tid * m + part.state_of(l_samples), weights=l_w,
                     minlength=T * m).reshape(T, m)
    cs = part.state_of(poses[..., :2])                                # (N, n)
    idx = (tid[:, None] * n + np.arange(n)) * m + cs
    cm = np.bincount(idx.ravel(), weights=np.repeat(c_w, n), minlength=T * n * m).reshape(T, n, m)
    lb = np.searchsorted(l_tid, np.arange(T + 1))
    cb = np.searchsorted(tid, np.arange(T + 1))
    out = []
    for t in range(T):
        reasons = _degenerate.geometry_reasons(state.bearings[t], state.sigma_bearing[t],
                                               state.headings[t], state.sigma_heading[t])
        rep = _degenerate.repeated_views(state.bearings[t])
        if np.any(rep):
            reasons.append(_degenerate.repeated_reason(rep))
        cw = c_w[cb[t]:cb[t + 1]]
        alive = cw > 0
        if not np.any(alive):
            reasons.append("no hypothesis survived (rays miss the locus arcs or C cannot be "
                           "triangulated)")
            out.append(_estimate.uniform_estimate("fast-paper", part, n, "; ".join(reasons), opts))
            continue
        lw_t = l_w[lb[t]:lb[t + 1]]
        keep_l = lw_t > 0
        na = int(alive.sum())
        hyp = _estimate.Hypotheses(
            landmark_samples=l_samples[lb[t]:lb[t + 1]][keep_l], landmark_weights=lw_t[keep_l],
            camera_samples=np.transpose(poses[cb[t]:cb[t + 1]][alive], (1, 0, 2)),
            camera_weights=np.broadcast_to(cw[alive], (n, na)).copy(), joint=n > 1)
        est, hyp = _estimate.make_estimate("fast-paper", part, n, lm[t] / lm[t].sum(),
                                           cm[t] / cm[t].sum(axis=1, keepdims=True),
                                           hypotheses=hyp, reasons=reasons, opts=opts)
        out.append((est, hyp if hypotheses else None))
    return out
