"""The SIS engine's motion step (views 2..n): every hypothesis draws ``motion_samples`` children
(heading and A/B bearing noise; the ray from X_(i-1) meets the drawn locus arc at 0, 1 or 2
points), weighted by the change of variables, the per-point prior and, with odometry, the
step-length-ratio factor (:func:`extend`); C's intermediate weight is carried or refitted
(:mod:`.c_integral`), then the children are pruned and resampled.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...geometry import locus_circle, wrap_angle
from ..common import arcs as _arcs
from ..common import degenerate as _degenerate
from ..common import laplace as _laplace
from ..common import likelihood as _likelihood
from ..common.odometry import log_distance_factor
from ..common.seeds import per_triplet
from .c_integral import child_c, log_intermediate_c
from .distance_proposal import (
    circle_arc_intersection,
    is_mixed,
    mix_counts,
    mixture_weight,
    prev_step,
    ratio_step,
)
from .moves import after_resampling
from .resampling import kept, plan_resampling, segment_max
from .state import SISState, streams, trajectories
from .target import log_camera_step

#: Most views a refit of C takes (the latest ones): a child without a usable C summary (C's
#: depth unresolved, a bearing tail) is refitted at every view, so its cost is bounded by this
#: instead of growing with the views. Only the intermediate weights see the window (the final
#: weights use every view); with up to this many views nothing changes.
REFIT_VIEWS = 20


#: Whether the motion step updates the parents' C summaries with the new view
#: (:func:`.c_integral.child_c`, O(1) per child) instead of refitting C over all views (O(views)); a
#: switch for the tests, which compare both.
_INCREMENTAL_C = True


def _anchor(view: int) -> bool:
    """Whether ``view`` (1-based) refits every child's C, with the option ``c_anchors``: over the
    (latest REFIT_VIEWS) views about C's mode (:func:`.c_integral._at_mode`) instead of updated, so that the
    summaries' frozen early gradients do not persist: 4, 8, 16, then every 16th view (the refits
    then cost at most about 2 x REFIT_VIEWS / 16 pose-views per child and view on average: time
    stays linear)."""
    return view >= 4 and (view in (4, 8) or view % 16 == 0)


def extend(state: SISState, phi, psi, spread: float, purpose: int) -> SISState:
    """The motion step and the intermediate C weights for one more view. The heading and A/B
    bearing noise is drawn ``spread`` times wider than the model's (weights corrected by the
    likelihood over the proposal density), which keeps hypotheses alive when the kept ones are
    slightly off."""
    opts, T, i = state.opts, state.n_triplets, state.n_views
    bearings = np.concatenate([state.bearings, phi[:, None, :]], axis=1)
    headings = np.concatenate([state.headings, psi[:, None]], axis=1)
    same = np.all(np.abs(wrap_angle(phi - state.bearings[:, -1])) <= _degenerate.SAME_POSE_TOL, axis=1)
    quiet = state.noiseless()
    r = np.where(same | quiet, 1, opts["motion_samples"])
    tid, prev = state.tid, state.last
    counts = np.bincount(tid, minlength=T) * r

    tail = opts.get("bearing_tail")
    htail = opts.get("heading_tail")

    def draw(rng, m):
        z = rng.standard_normal((m, 3))
        out = (z,) if tail is None else (z, rng.random((m, 2)), rng.random((m, 2)))
        # the heading tail's component choice last: without it the streams are unchanged
        return out if htail is None else out + (rng.random((m, 1)),)

    gens = streams(state.roots, i, purpose)
    if tail is None and htail is None:
        # the same draws as per_triplet(gens, counts, draw), written in place (no
        # concatenation of a million rows)
        z, uv = np.empty((int(counts.sum()), 3)), []
        ends = np.cumsum(counts)
        for g, lo, hi in zip(gens, ends - counts, ends, strict=True):
            g.standard_normal(out=z[lo:hi])
    else:
        z, *uv = per_triplet(gens, counts, draw)
    if uv:
        # columns: [heading, A, B] noise; then A/B component choices and outlier places (with
        # a bearing tail); then the heading's component choice (with a heading tail)
        z = np.concatenate([z, *uv], axis=1)
    par = np.repeat(np.arange(tid.size), r[tid])
    ct = tid[par]
    st = replace(state, bearings=bearings, headings=headings,
                 same_pose=np.concatenate([state.same_pose, same[:, None]], axis=1))
    # children of parents with a C summary: the summary updated with the new line of sight,
    # O(1) per child; the others (and those the update leaves unresolved) refitted over all views
    incremental = _INCREMENTAL_C and tail is None and not (
        opts.get("c_anchors", False) and _anchor(i + 1))
    has_sum = np.isfinite(state.c_sum[:, 0]) if incremental else np.zeros(tid.size, dtype=bool)
    phi_c = phi[:, 2]

    # the heaviest child of each triplet so far: a child lighter than prune_ratio x it is
    # pruned whatever the later blocks hold, and is dropped at once (same set as pruning after
    # all blocks; children whose C is still to be refitted are kept)
    best = np.full(T, -np.inf)
    log_ratio = np.log(opts["prune_ratio"]) if opts["prune_ratio"] > 0 else -np.inf

    def block(lo):
        # children in blocks whose temporaries stay in cache; every child is independent of the
        # others
        j, pose, lw, lpx = _children(state, prev, phi, psi, r, spread,
                                     par[lo:lo + _laplace.CHUNK_ROWS],
                                     z[lo:lo + _laplace.CHUNK_ROWS], lo)
        lc, cs = child_c(st, state, par[j], pose, phi_c, has_sum)
        if incremental and j.size:
            cj = ct[j]
            tot = lw + lc
            segment_max(cj, np.where(np.isnan(tot), -np.inf, tot), T, out=best)
            k = np.flatnonzero(~(tot < best[cj] + log_ratio))
            if k.size < j.size:
                return j[k], pose[k], lw[k], lpx[k], lc[k], cs[k]
        return j, pose, lw, lpx, lc, cs

    blocks = [block(lo) for lo in range(0, par.size, _laplace.CHUNK_ROWS)]
    if blocks:
        # the per-child scalars in one array each; poses and C summaries stay in their blocks
        # until the survivors of pruning and resampling are known (:func:`_gather`)
        j, lw, lpx, lw_c = (np.concatenate([b[c] for b in blocks]) for c in (0, 2, 3, 4))
        new_pose, c_sum = [b[1] for b in blocks], [b[5] for b in blocks]
    else:
        j, lw, lpx, lw_c = (np.zeros(0, dtype=int), np.zeros(0), np.zeros(0), np.zeros(0))
        new_pose, c_sum = [np.zeros((0, 3))], [np.zeros((0, _laplace.SUMMARY_COLUMNS))]
    # same-pose triplets: the one child is the parent's pose again, weight unchanged
    sp = same[ct]
    if np.any(sp):
        new_pose, c_sum = np.concatenate(new_pose), np.concatenate(c_sum)
        keep = ~sp[j]
        sj = np.flatnonzero(sp)
        sc, ss = child_c(st, state, par[sj], prev[par[sj]], phi_c, has_sum)
        j = np.concatenate([j[keep], sj])
        new_pose = np.concatenate([new_pose[keep], prev[par[sj]]])
        lw = np.concatenate([lw[keep], state.lw_base[par[sj]]])
        lpx = np.concatenate([lpx[keep], np.zeros(sj.size)])
        lw_c = np.concatenate([lw_c[keep], sc])
        c_sum = np.concatenate([c_sum[keep], ss])
        order = np.argsort(ct[j], kind="stable")
        j, new_pose, lw, lpx, lw_c, c_sum = (j[order], new_pose[order], lw[order], lpx[order],
                                             lw_c[order], c_sum[order])
        new_pose, c_sum = [new_pose], [c_sum]
    parent = par[j]
    ntid = tid[parent]

    def child_poses(rows):
        """(J, w, 3) the latest w = min(i + 1, REFIT_VIEWS) poses of the children ``rows``:
        O(w) each, for the few whose C is refitted."""
        return np.concatenate([trajectories(state.levels, parent[rows], REFIT_VIEWS - 1),
                               _gather(new_pose, rows)[:, None, :]], axis=1)

    refit = np.flatnonzero(np.isnan(lw_c))
    refit_sum = None
    if refit.size:
        lw_c[refit], refit_sum = log_intermediate_c(
            st, ntid[refit], lambda sel: child_poses(refit[sel]),
            bearings[:, -REFIT_VIEWS:, 2], gens)
    # pruning and resampling planned on the weights alone: only the children that survive both
    # are gathered (as _prune would leave them)
    total = lw + lw_c
    rows = np.flatnonzero(kept(ntid, total, T, opts["prune_ratio"]))
    plan = plan_resampling(st, ntid[rows], total[rows], gens)
    base = lw
    if plan is not None:
        idx, over, mean_log, moving = plan
        rows = rows[idx]
        base = np.where(over[ntid], mean_log[ntid] - lw_c, lw)
    cs = _gather(c_sum, rows)
    if refit_sum is not None:
        at = np.minimum(np.searchsorted(refit, rows), refit.size - 1)
        hit = refit[at] == rows
        cs[hit] = refit_sum[at[hit]]
    st = replace(st, tid=ntid[rows],
                 levels=state.levels + ((_gather(new_pose, rows), parent[rows]),),
                 lw_base=base[rows], lp_x=state.lp_x[parent[rows]] + lpx[rows], lw_c=lw_c[rows],
                 c_sum=cs)
    if plan is not None and np.any(moving):
        st = after_resampling(st, moving, mean_log)
    return st


def _gather(parts, rows) -> np.ndarray:
    """``np.concatenate(parts)[rows]`` without concatenating: the rows of blocks ``parts``
    (arrays with a common trailing shape)."""
    rows = np.asarray(rows, dtype=np.int64)
    if len(parts) == 1:
        return parts[0][rows]
    starts = np.cumsum([0] + [p.shape[0] for p in parts])
    out = np.empty((rows.size,) + parts[0].shape[1:], dtype=parts[0].dtype)
    order = None if np.all(rows[1:] >= rows[:-1]) else np.argsort(rows, kind="stable")
    r = rows if order is None else rows[order]
    bounds = np.searchsorted(r, starts)
    tmp = out if order is None else np.empty_like(out)
    for k, part in enumerate(parts):
        lo, hi = bounds[k], bounds[k + 1]
        if hi > lo:
            tmp[lo:hi] = part[r[lo:hi] - starts[k]]
    if order is not None:
        out[order] = tmp
    return out


def _children(state: SISState, prev, phi, psi, r, spread, par, z, offset):
    """One block of the motion step's children: parents ``par`` (B,) (rows of ``prev``), their
    noise draws ``z`` (B, 3) (heading, A, B), with a bearing tail (B, 7) (then also the A/B
    component choices and outlier places, :func:`.likelihood.bearing_noise`).

    Returns (child index (offset + row), pose (K, 3), log weight,
    log per-point prior) of the K children: those whose ray (or circle) meets the drawn locus
    arc, and the odometry draws of mixed parents (:func:`.distance_proposal.mix_counts`)."""
    ct = state.tid[par]
    sb, sh = state.sigma_bearing[ct], state.current_sigma(ct)
    pp = prev[par]
    htail = state.opts.get("heading_tail")
    if htail is None:
        th = pp[:, 2] + psi[ct] + spread * sh * z[:, 0]
    else:
        # the heading noise drawn from the heading tail's mixture (its choice: the last column)
        hn = np.where(z[:, -1] < htail.share, htail.scale, 1.0) * spread * sh * z[:, 0]
        th = pp[:, 2] + psi[ct] + hn
    tail = state.opts.get("bearing_tail")
    if tail is None:
        pa = phi[ct, 0] + spread * sb * z[:, 1]
        pb = phi[ct, 1] + spread * sb * z[:, 2]
    else:
        uc = np.where((sb > 0)[:, None], z[:, 3:5], 1.0)
        nab = _likelihood.bearing_noise(z[:, 1:3], uc, z[:, 5:7], sb[:, None], tail, spread)
        pa, pb = phi[ct, 0] + nab[:, 0], phi[ct, 1] + nab[:, 1]
    # likelihood over proposal of the drawn noise: N(x; s) / N(x; spread s) per drawn component
    # (exactly 0 when the noise is drawn at the model's width)
    if spread == 1.0:
        lcorr = None
    elif tail is None and htail is None:
        noisy = np.stack([sh, sb, sb], axis=1) > 0
        lcorr = np.sum(np.where(noisy, -0.5 * z[:, :3] ** 2 * (spread * spread - 1.0)
                                + np.log(spread), 0.0), axis=1)
    else:
        # the heading's part: the normal's ratio, or its mixture over the spread mixture
        if htail is None:
            lh = -0.5 * z[:, 0] ** 2 * (spread * spread - 1.0) + np.log(spread)
        else:
            lh = _likelihood.log_bearing(hn, sh, htail) \
                - _likelihood.log_bearing(hn, spread * sh, htail)
        # the A/B part: the normal's ratio per bearing, or the bearing tail's
        if tail is None:
            lab = -0.5 * z[:, 1:3] ** 2 * (spread * spread - 1.0) + np.log(spread)
        else:
            s2 = sb[:, None]
            lab = _likelihood.log_bearing(nab, s2, tail) \
                - _likelihood.log_bearing_proposal(nab, s2, tail, spread)
        with np.errstate(invalid="ignore"):
            lcorr = np.where(sh > 0, lh, 0.0) \
                + np.sum(np.where((sb > 0)[:, None], lab, 0.0), axis=1)
    pts, valid, (ux, uy) = _arcs.ray_locus(pp[:, :2], th, pa, pb)
    mixed = is_mixed(state, ct, r, spread)
    if np.any(mixed):
        # each parent's r draws: the first n_odo from the odometry alone, then n_ray along
        # the heading (the ray above), the last n_circ at the step length of the distance
        # ratio (t = t* exp(sigma z0)) instead of the heading: the circle of radius t about
        # X_(i-1) meets the drawn locus arc at 0, 1 or 2 points (mix_counts)
        first = np.cumsum(r[state.tid]) - r[state.tid]
        kk = offset + np.arange(par.size) - first[par]
        n_circ, n_odo = mix_counts(state, ct, r)
        rows = np.flatnonzero(mixed & (kk >= r[ct] - n_circ))
        p, tt = par[rows], ct[rows]
        t = ratio_step(state, p, tt, z[rows, 0])
        circ = locus_circle(pa[rows], pb[rows])
        pts[rows], valid[rows] = circle_arc_intersection(
            prev[p, :2], t, circ.center, circ.radius, circ.side)
        # the odometry draws: X = X_(i-1) + t (cos theta, sin theta) with the ray's heading
        # draw theta and t from the ratio (its normal from the B column, which these draws
        # leave unused); alpha from the drawn A bearing as for every child. Where the odometry
        # is sharper than the locus arc (short steps seen from afar, as on MRCLAM) the arc's
        # children land where the heading and the ratio reject them
        rows = np.flatnonzero(mixed & (kk < n_odo))
        if rows.size:
            p, tt = par[rows], ct[rows]
            t = ratio_step(state, p, tt, z[rows, 2])
            c, s = _arcs.cos_sin(th[rows])
            pts[rows, 0, 0] = pp[rows, 0] + t * c
            pts[rows, 0, 1] = pp[rows, 1] + t * s
            valid[rows, 0] = t > 0
            valid[rows, 1] = False
    # the valid (row, slot) pairs in row-major order, as np.nonzero(valid) gives them
    flat = np.flatnonzero(valid)
    j = flat >> 1
    X = pts.reshape(-1, 2)[flat]
    pj = par[j]
    lpx = log_camera_step(state, pj, X)
    lw = state.lw_base[pj] + _arcs.log_ray_jacobian_u(X, pp[j, :2], ux[j], uy[j]) + lpx
    if lcorr is not None:
        lw += lcorr[j]
    lw -= np.log(r)[ct[j]]
    # every child's alpha points its drawn A bearing at A
    alpha = _arcs.wrap(np.arctan2(-X[:, 1], -X[:, 0]) - pa[j])
    i = state.n_views
    if i >= 2 and np.any(state.distances[:, -1] > 0) and np.any(state.distances[ct[j], -1] > 0):
        pj, tj = par[j], ct[j]
        lw = lw + log_distance_factor(np.hypot(*(X - prev[pj, :2]).T), prev_step(state, pj),
                                      state.distances[tj, -1], state.distances[tj, -2],
                                      state.sigma_distance[tj], state.opts.get("distance_tail"))
        m = np.flatnonzero(mixed[j])
        if m.size:
            pm = par[j[m]]
            lw[m] = state.lw_base[pm] + lpx[m] - np.log(r[ct[j[m]]]) \
                + mixture_weight(state, X[m], prev, psi, r, pm, phi, alpha[m])
    pose = np.empty((j.size, 3))
    pose[:, :2] = X
    pose[:, 2] = alpha
    return j + offset, pose, lw, lpx
