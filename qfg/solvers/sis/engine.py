"""Sequential importance sampling over camera trajectories, batched over triplets: the engine of
``method="full"`` (the paper's Algorithm 1) and of the default ``method="fast"`` (the same with
small budgets).

Per view i of every triplet (AB frame, A = (0, 0), B = (0, 1)):

* sampling step (view 1): ``n_samples`` camera poses near the locus arc of (phi_A, phi_B): the
  bearings to A and B drawn from N(measured, sigma_v^2), a position on the drawn arc at a
  stratified arc parameter (:func:`._arcs.arc_parameter`), the heading from phi_A. The
  importance weight is the arc's change of variables times the per-point prior.
* motion step (views 2..n): for each hypothesis, ``motion_samples`` draws of the heading noise and
  of the view's A/B bearing noise; the ray from X_{i-1} along ``alpha_{i-1} + psi + eps`` meets
  the drawn locus arc at 0, 1 or 2 points, each a new hypothesis. The drawn noise carries the
  heading and A/B likelihoods exactly; the weight is the change of variables
  ``t / |grad Gamma . u|`` (:func:`._arcs.log_ray_jacobian`) times the per-point prior.
* odometry distances (optional, views 3..n): the weight also carries
  :func:`log_distance_factor` of the step-length ratio; such triplets draw half their children
  at the step length the distance ratio predicts instead of along the heading (a circle about
  X_{i-1} meets the arc), weighted by the balance heuristic (:func:`_mixture_weight`).
* noise models (optional): one heading sigma per step (``SISState.step_sigma``, the step's
  column going in before its motion step), a two-normal tail on the step-length ratio
  (``distance_tail``: a factor in the weights) and on the headings (``heading_tail``: the motion
  step draws from the mixture, so the weights again carry no heading factor).
* C (views 2..n): its integral ``∫ p1(L) prod_t N(phi_C,t - f(L, X_t); sigma_v) dL`` is
  estimated with ``landmark_samples`` draws from a defensive mixture (Laplace Gaussian about the
  triangulation, and draws along the lines of sight: :func:`._landmarks.sample_landmarks`), which
  stays right when the lines of sight coincide. Every view costs the same whatever the views
  so far: where C's depth is resolved a hypothesis carries a Gaussian summary of C's integral
  (mode, information, log integral) that each child updates with its one new line of sight
  (:func:`._laplace.update_landmark`, O(1)); only hypotheses without one (the second view, an
  unresolved depth, a bearing tail) are refitted over all their views. Trajectories are kept
  as ancestry (``levels``: per view the poses and each one's parent), so a step adds one level
  and copies no past pose; whole trajectories are gathered only for the final sample, refits
  and moves (:func:`trajectories`).
* pruning and resampling per triplet: hypotheses below ``prune_ratio`` x the heaviest are
  dropped; above ``max_hypotheses`` the set is resampled (systematic), the C weight divided out as
  in sequential importance resampling.

These intermediate weights use a per-point prior ``p1`` (:func:`._prior.point_log_prior`).
The answer does not: :func:`finish` resamples ``posterior_samples`` trajectories per triplet,
draws C for each, and weights every (trajectory, C) sample by the prior's ``log_density`` of the
whole configuration [C, X_1..X_n] over the intermediate target, so the estimate targets the
exact posterior under any :class:`qfg.priors.Prior`.

Every random draw of triplet t at view i comes from its own stream
``SeedSequence(root_t, spawn_key=(i, purpose))``, so a triplet solved alone, in a batch, or view
by view gives the same numbers. Views whose three bearings repeat the previous view's exactly are
taken as the camera not having moved (flagged). With both sigmas zero a triplet draws no noise in
the motion step (one child per hypothesis) and spends the same budget on the first view
(``n_samples x motion_samples``). Likelihood widths are ``max(sigma, floor)``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ... import priors as _priors
from ...geometry import (
    bearing,
    heading_on_locus,
    locus_circle,
    locus_point,
    wrap_angle,
)
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
from ..common.odometry import log_distance_factor
from . import landmarks as _landmarks
from . import model_check as _model_check
from . import rejuvenation as _rejuvenation


@dataclass(frozen=True, eq=False)
class SISState(_estimate.TripletBatchSizes):
    """Hypotheses of T triplets after the views so far (flat arrays sorted by triplet)."""

    bearings: np.ndarray       # (T, i, 3)
    headings: np.ndarray       # (T, i - 1)
    sigma_bearing: np.ndarray  # (T,)
    sigma_heading: np.ndarray  # (T,)
    distances: np.ndarray      # (T, i - 1) odometry's travelled distances (0: unknown, no factor)
    sigma_distance: np.ndarray  # (T,) width of the step-length-ratio factor (floored)
    roots: tuple               # T SeedSequences
    opts: dict
    part: object
    method: str
    tid: np.ndarray            # (N,) triplet of each hypothesis
    levels: tuple              # i pairs (poses (M_t, 3), parent row at view t - 1 (M_t,)): the
                               # trajectories as ancestry; the last level's rows are the N
                               # hypotheses (:func:`trajectories` gathers them)
    lw_base: np.ndarray        # (N,) log change of variables x per-point prior (+ resampling)
    lp_x: np.ndarray           # (N,) the per-point prior part of lw_base
    lw_c: np.ndarray           # (N,) log estimate of C's integral (0 with one view)
    c_sum: np.ndarray          # (N, 7) Gaussian summary of C's integral (_laplace.update_landmark;
                               # NaN rows: none, the next view refits them over all views)
    same_pose: np.ndarray      # (T, i) views taken as "camera did not move"
    lost: np.ndarray           # (T,) view (1-based) at which nothing survived, 0 if alive
    full_opts: dict | None = None  # the caller's options while ``opts`` is their few-views
                               # budget (:data:`FEW_VIEWS`): the next view rebuilds the
                               # hypotheses with these; None: ``opts`` are the caller's
    step_sigma: np.ndarray | None = None  # (T, i - 1) each step's heading sigma (a step's
                               # column goes in before its motion step, like ``distances``;
                               # None: ``sigma_heading`` for every step)

    @property
    def poses(self) -> np.ndarray:
        """(N, i, 3) every hypothesis' trajectory (gathered: O(N i))."""
        return trajectories(self.levels)

    @property
    def last(self) -> np.ndarray:
        """(N, 3) every hypothesis' latest pose."""
        return self.levels[-1][0]

    def sigma_v(self) -> np.ndarray:
        """(T,) C-bearing likelihood width ``max(sigma_v, floor)``."""
        return _options.effective_sigma(self.sigma_bearing, self.opts["bearing_floor"])

    def noiseless(self) -> np.ndarray:
        return (self.sigma_bearing == 0) & (self.sigma_heading == 0)

    def step_sigmas(self, tid, n_steps: int | None = None) -> np.ndarray:
        """(J, n_steps) the heading sigma of each step of triplets ``tid`` (J,) (default: every
        step so far)."""
        k = self.headings.shape[1] if n_steps is None else n_steps
        if self.step_sigma is None:
            return np.repeat(self.sigma_heading[tid][:, None], k, axis=1)
        return self.step_sigma[tid][:, :k]

    def current_sigma(self, ct) -> np.ndarray:
        """(B,) the heading sigma of the step being made, for triplets ``ct`` (B,)."""
        return self.sigma_heading[ct] if self.step_sigma is None else self.step_sigma[ct, -1]


def trajectories(levels, rows=None, last=None) -> np.ndarray:
    """(J, i, 3) trajectories of the hypotheses ``rows`` (rows of the last level; None: all)
    of ancestry ``levels`` (pairs (poses (M_t, 3), parent row in level t - 1 (M_t,))), walked
    back from the last view: O(J i), and no step of the sampler copies the past poses. With
    ``last``, only the latest ``last`` views (J, min(i, last), 3).

    >>> lv = ((np.zeros((2, 3)), np.zeros(2, dtype=int)), (np.ones((3, 3)), np.array([1, 0, 1])))
    >>> trajectories(lv, np.array([2])).tolist()
    [[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]]
    """
    pose, up = levels[-1]
    j = np.arange(pose.shape[0]) if rows is None else np.asarray(rows, dtype=np.int64)
    n = len(levels) if last is None else min(len(levels), int(last))
    out = np.empty((j.size, n, 3))
    for t in range(n - 1, -1, -1):
        pose, up = levels[len(levels) - n + t]
        out[:, t] = pose[j]
        j = up[j]
    return out


def _with_last(levels, pose, up) -> tuple:
    """``levels`` with the last level replaced."""
    return levels[:-1] + ((pose, up),)


def _take_last(levels, idx) -> tuple:
    """``levels`` keeping the hypotheses ``idx`` (rows of the last level): O(len(idx)), the
    earlier levels shared."""
    pose, up = levels[-1]
    return _with_last(levels, pose[idx], up[idx])


def _view_patterns(keep) -> list:
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
    twice), with the quadrature of the rejuvenation's target (:func:`_target_prior`)."""
    prior = _target_prior(opts["prior"])
    if keep is None or np.all(keep):
        return prior.log_density(X)
    out = np.empty(X.shape[0])
    for pat, rows in _view_patterns(keep):
        out[rows] = prior.log_density(X[rows][:, pat])
    return out


def _log_camera_prior(opts, X) -> np.ndarray:
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


def _log_camera_step(state, pj, X) -> np.ndarray:
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
    prior = _target_prior(opts["prior"])
    K = pj.size
    if isinstance(prior, _priors.WorldBoxPrior):
        # each parent's extents once, each child adds its point: O(1) per child in the views
        # (the stacked path below is O(i) per child)
        out = np.empty(K)
        group = np.empty(up.size, dtype=np.intp)
        local = np.empty(up.size, dtype=np.intp)
        for g, (pat, ug) in enumerate(_view_patterns(keep)):
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


def _gens(roots, view, purpose):
    """One generator per triplet for (view, purpose); every draw of that stage comes from it, in
    a fixed order, so a triplet's numbers do not depend on the batch."""
    return [_seeds.stream(r, view, purpose) for r in roots]


_per_triplet = _seeds.per_triplet


def _landmark_draws(gens, tid, n, k, ray_fraction):
    kr = k if n == 1 else min(k, int(round(k * ray_fraction)))
    kg = k - kr
    counts = np.bincount(tid, minlength=len(gens))

    def draw(rng, m):
        return (rng.standard_normal((m, kg, 2)), rng.integers(0, n, size=(m, kr)),
                rng.standard_normal((m, kr)), rng.random((m, kr)))

    z, t, e, u = _per_triplet(gens, counts, draw)
    return {"z": z, "t": t, "eps": e, "u": u}


def _c_weight(state_like, tid, poses, bearings_c, gens, k, laplace=None):
    """(L, log q, log lik, spread) for hypotheses (N, i, 3) of triplets ``tid``."""
    n = poses.shape[1]
    draws = _landmark_draws(gens, tid, n, k, state_like.opts["ray_fraction"])
    return _landmarks.sample_landmarks(None, poses, bearings_c[tid], state_like.sigma_v()[tid], k,
                                       state_like.opts["ray_fraction"], draws=draws, laplace=laplace,
                                       tail=state_like.opts.get("bearing_tail"))


#: Depth spread below which the intermediate C weight uses the Laplace approximation; above it
#: (C's depth poorly resolved, e.g. lines of sight that nearly coincide) it is sampled.
_LAPLACE_SPREAD = 0.25

#: Depth spread below which a hypothesis keeps a C summary for the next views to update
#: (:func:`_child_c`); above it C is refitted over the views at the next view.
_SUMMARY_SPREAD = _LAPLACE_SPREAD


def _log_intermediate_c(state_like, tid, poses, bearings_c, gens):
    """log of C's integral with the per-point prior, for the intermediate weights: Laplace about
    the triangulation where C's depth is resolved, a :func:`._landmarks.sample_landmarks` estimate
    elsewhere. ``poses``: (N, n, 3), or a function of a row selection returning those rows (the
    motion step's children are then never gathered all at once). Returns (log integral (N,),
    summaries (N, 7)): the Laplace fit's :func:`._laplace.summary_from_parts` where it is used
    (the next view updates it, :func:`_child_c`), NaN where C was sampled."""
    get = poses if callable(poses) else poses.__getitem__
    prior = state_like.opts["prior"]
    tail = state_like.opts.get("bearing_tail")
    sig = state_like.sigma_v()[tid]
    N = tid.size
    out, hard, lap = np.empty(N), [], []
    summ = np.empty((N, _laplace.SUMMARY_COLUMNS))
    for lo in range(0, N, _laplace.CHUNK_ROWS):
        sl = slice(lo, lo + _laplace.CHUNK_ROWS)
        P = get(sl)
        lz, Ls, spread, parts = _laplace.laplace_landmark(P, bearings_c[tid[sl]], sig[sl],
                                                          parts=True)
        if state_like.opts.get("c_anchors", False):
            # with the option c_anchors refits take the Laplace approximation about C's mode in
            # the bearing residuals (_at_mode) rather than about the lines' least-squares point
            # (a bearing tail's correction is then taken at the mode too)
            lz, Ls, spread, parts = _at_mode(P, bearings_c[tid[sl]], sig[sl], lz, spread, parts)
        out[sl] = lz + _prior.point_log_prior(prior, Ls)
        if tail is not None:
            out[sl] += _tail_correction(P, bearings_c[tid[sl]], sig[sl], Ls, tail)
        easy = spread < _LAPLACE_SPREAD
        summ[sl] = _laplace.summary_from_parts(lz, parts, spread < _SUMMARY_SPREAD)
        h = np.flatnonzero(~easy)
        hard.append(lo + h)
        lap.append(tuple(v[h] for v in parts))
    hard = np.concatenate(hard) if hard else np.zeros(0, dtype=int)
    if hard.size:
        k = state_like.opts["landmark_samples"]
        lap = tuple(np.concatenate(v) for v in zip(*lap, strict=True))
        L, log_q, log_lik, _ = _c_weight(state_like, tid[hard], get(hard), bearings_c, gens, k,
                                         laplace=lap)
        lw = _prior.point_log_prior(prior, L) + log_lik - log_q
        lw = np.where(np.isnan(lw), -np.inf, lw)
        out[hard] = _likelihood.logsumexp(lw, axis=1) - np.log(k)
    return np.where(np.isnan(out), -np.inf, out), summ


#: Most views a refit of C takes (the latest ones): a child without a usable C summary (C's
#: depth unresolved, a bearing tail) is refitted at every view, so its cost is bounded by this
#: instead of growing with the views. Only the intermediate weights see the window (the final
#: weights use every view); with up to this many views nothing changes.
REFIT_VIEWS = 20

def _at_mode(P, phi_c, sig, lz, spread, parts):
    """:func:`._laplace.laplace_landmark`'s outputs moved to C's mode over the views of ``P``
    (J, n, 3) where C's depth is resolved (:func:`._laplace.refine_mode` from the least-squares
    point): the Laplace value ``sum_t log N(r_t; sigma) + log(2 pi sigma^2 / sqrt(det H))`` there,
    as the carried summaries have it. Rows not resolved keep the least-squares values."""
    easy = np.flatnonzero(spread < _LAPLACE_SPREAD)
    if not easy.size:
        return lz, parts[0], spread, parts
    X, th = P[easy, :, :2], P[easy, :, 2] + phi_c[easy]
    L, ok, h00, h01, h11, det, r2min = _laplace.refine_mode(X, th, parts[0][easy])
    res = wrap_angle(bearing(P[easy], L[:, None, :]) - phi_c[easy])
    s = sig[easy]
    with np.errstate(divide="ignore", invalid="ignore"):
        lzm = _laplace.laplace_value(np.sum(res * res, axis=1), P.shape[1], s, det)
    good = ok & np.isfinite(lzm)
    e = easy[good]
    lz, spread = lz.copy(), spread.copy()
    new = [np.array(v, copy=True) for v in parts]
    for k, v in enumerate((L, ok, h00, h01, h11, det, r2min)):
        new[k][e] = v[good]
    lz[e] = lzm[good]
    spread[e] = _laplace.depth_spread(True, h00[good], h01[good], h11[good], det[good],
                                      r2min[good], s[good])
    return lz, new[0], spread, tuple(new)


#: Whether the motion step updates the parents' C summaries with the new view
#: (:func:`_child_c`, O(1) per child) instead of refitting C over all views (O(views)); a
#: switch for the tests, which compare both.
_INCREMENTAL_C = True


def _anchor(view: int) -> bool:
    """Whether ``view`` (1-based) refits every child's C, with the option ``c_anchors``: over the
    (latest REFIT_VIEWS) views about C's mode (:func:`_at_mode`) instead of updated, so that the
    summaries' frozen early gradients do not persist: 4, 8, 16, then every 16th view (the refits
    then cost at most about 2 x REFIT_VIEWS / 16 pose-views per child and view on average: time
    stays linear)."""
    return view >= 4 and (view in (4, 8) or view % 16 == 0)


def _child_c(st, state, parent, pose, phi_c, has_sum):
    """Intermediate C weights of children (parents ``parent`` (K,), rows of ``state``; new poses
    ``pose`` (K, 3)) whose parents carry a C summary (``has_sum`` (N,)): the parent's summary
    updated with the new view's line of sight (:func:`._laplace.update_landmark`), plus the
    per-point prior at its mode. Returns (log integral (K,), summaries (K, 7)); NaN in both where
    C is to be refitted over all views (no summary, or the update leaves C's depth unresolved:
    spread >= :data:`_LAPLACE_SPREAD`)."""
    K = parent.size
    lw_c = np.full(K, np.nan)
    summ = np.full((K, _laplace.SUMMARY_COLUMNS), np.nan)
    rows = np.flatnonzero(has_sum[parent])
    if rows.size:
        ct = state.tid[parent[rows]]
        new, spread = _laplace.update_landmark(state.c_sum[parent[rows]], pose[rows, :2],
                                               pose[rows, 2] + phi_c[ct], st.sigma_v()[ct])
        ok = spread < _SUMMARY_SPREAD
        rows, new = rows[ok], new[ok]
        lw_c[rows] = new[:, 5] + _prior.point_log_prior(st.opts["prior"], new[:, :2])
        summ[rows] = new
    return lw_c, summ


def _tail_correction(poses, phi_c, sig, L, tail):
    """(J,) log of the tail model's C-bearing likelihood over the normal's at the triangulation
    ``L`` (J, 2): the Laplace value of C's integral (a normal likelihood) moved toward the tail
    model for the intermediate weights (the final weights use the tail model exactly)."""
    res = wrap_angle(bearing(poses, L[:, None, :]) - phi_c)
    s = sig[:, None]
    return np.sum(_likelihood.log_bearing(res, s, tail) - _likelihood.log_bearing(res, s), axis=1)


def _segment_max(tid, x, T, out=None):
    """(T,) the largest ``x`` of each triplet ``tid`` (-inf for none; NaN propagates), into
    ``out`` (updated in place: the larger of it and the segment's) if given. Sorted ``tid`` (the
    hypotheses' order) take one ``maximum.reduceat`` pass, far cheaper than ``maximum.at``."""
    mx = np.full(T, -np.inf) if out is None else out
    if tid.size == 0:
        return mx
    if tid.size > 1 and np.any(tid[1:] < tid[:-1]):
        np.maximum.at(mx, tid, x)
        return mx
    starts = np.flatnonzero(np.concatenate(([True], tid[1:] != tid[:-1])))
    seg = tid[starts]
    mx[seg] = np.maximum(mx[seg], np.maximum.reduceat(x, starts))
    return mx


def _systematic(tid, logw, T, counts_out, offsets):
    """Per-triplet systematic resampling: ``counts_out[t]`` indices of triplet t's elements drawn
    by weights exp(logw), with offsets (T,) in [0, 1). Triplets whose weights are all -inf (or
    counts_out = 0) draw nothing. Returns indices sorted by triplet."""
    mx = _segment_max(tid, logw, T)
    ok = np.isfinite(mx)
    w = np.where(np.isfinite(logw), np.exp(logw - np.where(ok, mx, 0.0)[tid]), 0.0)
    tot = np.bincount(tid, weights=w, minlength=T)
    cum = np.cumsum(w)
    start = np.concatenate([[0.0], cum])[np.searchsorted(tid, np.arange(T))]
    # position of each element's right edge within its triplet, in [0, 1], plus triplet index
    key = tid + (cum - start[tid]) / np.where(tot > 0, tot, 1.0)[tid]
    key = np.where(tot[tid] > 0, key, tid + 1.0)
    co = np.where(ok & (tot > 0), counts_out, 0)
    pt = np.repeat(np.arange(T), co)
    pos = pt + (offsets[pt] + (np.arange(pt.size) - np.repeat(np.cumsum(co) - co, co))) / \
        np.repeat(np.maximum(co, 1), co)
    idx = np.searchsorted(key, pos, side="right")
    # stay inside the triplet's own range (rounding at the right edge)
    hi = np.searchsorted(tid, pt, side="right") - 1
    return np.minimum(idx, hi)


def _offsets(gens):
    return np.array([g.random() for g in gens])


def _kept(tid, total, T, ratio):
    """(N,) hypotheses that survive pruning: finite and at least ``ratio`` x the heaviest of
    their triplet. Applying it twice keeps the same set (the heaviest always stays)."""
    mx = _segment_max(tid, total, T)
    floor = mx + np.log(ratio) if ratio > 0 else np.full(T, -np.inf)
    return np.isfinite(total) & (total >= floor[tid])


def _prune(st: SISState, gens) -> SISState:
    T = st.n_triplets
    keep = _kept(st.tid, st.lw_base + st.lw_c, T, st.opts["prune_ratio"])
    if not keep.all():
        st = _take(st, np.flatnonzero(keep))
    plan = _resampling(st, st.tid, st.lw_base + st.lw_c, gens)
    if plan is None:
        return st
    idx, over, mean_log, moving = plan
    new = _take(st, idx)
    lw_base = np.where(over[new.tid], mean_log[new.tid] - new.lw_c, new.lw_base)
    st = replace(new, lw_base=lw_base)
    return _moves(st, moving, mean_log) if np.any(moving) else st


def _resampling(st: SISState, tid, total, gens):
    """The resampling :func:`_prune` does after pruning, on hypotheses ``tid`` (N,) with
    weights ``total`` (N,) (kept by :func:`_kept`) of the triplets of ``st``: None when nothing
    is resampled, else (rows kept (sorted by triplet), triplets resampled (T,), their mean log
    weight (T,), triplets to move (T,)). Every survivor of a resampled triplet carries the mean
    weight. Draws one offset per triplet from ``gens`` every time."""
    T = st.n_triplets
    cap = st.opts["max_hypotheses"]
    counts = np.bincount(tid, minlength=T)
    # drawn for every triplet every time, so that a triplet's later draws do not depend on others
    off = _offsets(gens)
    # triplets whose hypotheses are moved are resampled to the cap at every view (resample-move:
    # the moves need equal weights, and pruning alone leaves the descendants of few early poses)
    moving = (counts > 0) & _movable(st) & _moves_now(st)
    if not (counts.size and (counts.max() > cap or np.any(moving))):
        return None
    over = (counts > cap) | moving
    idx_over = _systematic(tid, total, T, np.where(over, cap, 0), off)
    keep_under = np.flatnonzero(~over[tid])
    # every survivor of an over-full triplet carries the mean weight, the total is unchanged
    mx = _segment_max(tid, total, T)
    w = np.exp(total - np.where(np.isfinite(mx), mx, 0.0)[tid])
    with np.errstate(divide="ignore"):
        mean_log = mx + np.log(np.bincount(tid, weights=w, minlength=T) / cap)
    idx = np.concatenate([keep_under, idx_over])
    return idx[np.argsort(tid[idx], kind="stable")], over, mean_log, moving


#: Noise sigmas (radians) within which the trajectories are moved after resampling: below, the
#: intermediate target is too narrow for a random walk; above, its wrapped normals are not the
#: plain normals :func:`_log_pose_target` evaluates.
_MOVE_SIGMAS = (1e-6, 0.5)


def _movable(st: SISState) -> np.ndarray:
    """(T,) triplets whose trajectories the MH moves may change: noise in both sigmas within
    :data:`_MOVE_SIGMAS`, and no view taken as "camera did not move" (a pose repeated exactly is
    not a density the random walk can target)."""
    lo, hi = _MOVE_SIGMAS
    return ((st.sigma_bearing >= lo) & (st.sigma_bearing <= hi) & (st.sigma_heading >= lo)
            & (st.sigma_heading <= hi) & ~np.any(st.same_pose, axis=1))


def _log_pose_target(st: SISState, tid, poses):
    """log of the intermediate target of trajectories ``poses`` (J, i, 3) of triplets ``tid``,
    without C and up to a constant per triplet: per view the per-point prior and the A/B bearing
    likelihoods, per move the heading likelihood,

        sum_t [log p1(X_t) + log N(phi_A,t - f_A(X_t); sv) + log N(phi_B,t - f_B(X_t); sv)]
        + sum_t log N(psi_t - g(X_t+1, X_t); sw),

    plus the odometry's step-length-ratio factors (:func:`log_distance_factor`) where distances
    are given: the density (in x, y, alpha) that the sampling and motion steps' weights make the
    hypotheses represent. Returns (log target (J,), its prior part (J,): sum_t log p1(X_t), or
    with ``camera_prior="joint"`` :func:`_log_camera_prior`'s)."""
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
    lp = _log_camera_prior(st.opts, X)
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


#: Random-walk scale: the proposal covariance is ``(_MOVE_SCALE^2 / D)`` times the covariance of
#: the triplet's resampled trajectories (D = 3 i coordinates).
_MOVE_SCALE = 1.0


def _move(st: SISState, which, mean_log) -> SISState:
    """Resample-move (Gilks and Berzuini 2001): ``move_steps`` random-walk Metropolis-Hastings
    steps per hypothesis of the triplets ``which`` (T,), just resampled, each targeting the
    intermediate posterior of the views so far (:func:`_log_pose_target` times C's integral).
    The proposal is a Gaussian random walk on the whole trajectory (x, y, alpha per view) with
    the covariance of the triplet's resampled hypotheses, scaled; C's integral is re-estimated
    at the proposal (:func:`_log_intermediate_c`, a pseudo-marginal step where it is sampled).
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
    lt, lp = _log_pose_target(st, tid, poses)
    chol = _rejuvenation.walk_factor(poses, tid, which, _MOVE_SCALE)
    gens = _gens(st.roots, n - 1, _seeds.STREAM_MOVE)
    counts = np.bincount(tid, minlength=T)
    bc = st.bearings[..., 2]
    for _ in range(st.opts["move_steps"]):
        (z,) = _per_triplet(gens, counts, lambda g, m: (g.standard_normal((m, D)),))
        prop = poses + np.einsum("jde,je->jd", chol[tid], z).reshape(-1, n, 3)
        prop[..., 2] = wrap_angle(prop[..., 2])
        lt2, lp2 = _log_pose_target(st, tid, prop)
        ok = np.isfinite(lt2)
        lc2 = np.full(rows.size, -np.inf)
        cs2 = np.full((rows.size, _laplace.SUMMARY_COLUMNS), np.nan)
        if np.any(ok):
            lc2[ok], cs2[ok] = _log_intermediate_c(st, tid[ok], prop[ok], bc, gens)
        (u,) = _per_triplet(gens, counts, lambda g, m: (g.random(m),))
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


def _moves_now(st: SISState) -> bool:
    """Whether the hypotheses are moved after this view's resampling: every view from the second
    with ``move_steps``, the views of :func:`._rejuvenation.scheduled` with ``rejuvenate``."""
    return bool((st.opts.get("move_steps", 0) > 0 and st.n_views >= 2)
                or (st.opts.get("rejuvenate", 0) > 0 and _rejuvenation.scheduled(st.n_views)))


def _moves(st: SISState, which, mean_log) -> SISState:
    """The moves of the triplets ``which`` (T,), just resampled to equal weights ``mean_log``."""
    if st.opts.get("rejuvenate", 0) > 0 and _rejuvenation.scheduled(st.n_views):
        st = _rejuvenate(st, which, mean_log)
    if st.opts.get("move_steps", 0) > 0:
        st = _move(st, which, mean_log)
    return st


#: Proposals of a rejuvenation sweep (:func:`._rejuvenation.sweeps`).
_KINDS = ("walk", "ridge", "noise")


#: Quadrature points in rho of the world prior inside the rejuvenation's target (the final
#: weights keep :data:`._prior.SOLVER_N_RHO`): the target may be any fixed density, since the
#: hypotheses carry its prior part (``lp_x``) and the final weights divide it out; 16 points
#: are within about 0.16 nats (sd) of 32 on whole configurations, at about half the cost.
_TARGET_N_RHO = 16


def _target_prior(prior):
    """``prior`` with :data:`_TARGET_N_RHO` quadrature points if it is a world-box prior with
    more, else ``prior``."""
    if isinstance(prior, _priors.WorldBoxPrior) and prior.n_rho > _TARGET_N_RHO:
        return prior.replace(n_rho=_TARGET_N_RHO)
    return prior


def _joint_target(st: SISState, stc: SISState, tid, poses, gens, prior=None):
    """The rejuvenation's target at trajectories ``poses`` (J, n, 3) of triplets ``tid``: the
    pose likelihoods of :func:`_log_pose_target`, C's integral (:func:`_log_intermediate_c` of
    ``stc``: the Laplace fit at C's mode, sampled where C's depth is unresolved) and the prior of
    the whole configuration at C's mode ``L*``,

        log pi = log lik(X) + log Z(X) + log prior([L*, X]) - log p1(L*),

    where C's depth is resolved (the exact joint prior, :func:`._prior.log_joint_prior`, which the
    per-point priors of the other steps only approximate); the per-point priors elsewhere.
    ``prior``: the prior of the joint term (None: the solver's). Returns (log pi (J,), the prior
    part as ``lp_x`` carries it (J,), log Z with p1(L*) as ``lw_c`` carries it (J,), C summaries
    (J, 7))."""
    lt, lp = _log_pose_target(st, tid, poses)
    lc, cs = _log_intermediate_c(stc, tid, poses, st.bearings[..., 2], gens)
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
    """Resample-move along the measurements (:mod:`._rejuvenation`) for the triplets ``which``
    (T,), just resampled to equal weights: the hypotheses are first reweighted from the
    intermediate target to :func:`_joint_target` (the exact joint prior at C's mode and C's
    Laplace fit at its mode in place of the per-point priors and the carried C summaries) and
    resampled (systematic, per triplet); then ``rejuvenate`` sweeps of Metropolis-Hastings
    steps per hypothesis target it. A sweep proposes

    * a walk: the whole trajectory (x, y, alpha per view) moved by a Gaussian with ``1 / D``
      times the covariance of the triplet's hypotheses (D = 3 n,
      :func:`._rejuvenation.walk_factor`);
    * a ridge step in the chart of :func:`._rejuvenation.chart_of`: camera 1 moved ``s`` along
      its arc, every bearing and heading residual held, so the whole trajectory slides along
      what the A/B bearings and headings leave open and only the priors, the Jacobian and C's
      integral decide (the move that brings back early poses the resampling lost);
    * a noise step in that chart: every residual moved by ``s sigma z``, camera 1 held;

    the chart steps accepted on the target times the chart's Jacobian. Step scales ``s`` are
    drawn log-uniformly per hypothesis (a scale mixture, symmetric whatever the state;
    :func:`._rejuvenation.sweeps`). The target is invariant, so equal weights stay
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
    gens = _gens(st.roots, n, _seeds.STREAM_REJUVENATE)
    counts = np.bincount(tid, minlength=T)
    prior = _target_prior(st.opts["prior"])
    cur, lpx, lc, cs = _joint_target(st, stc, tid, poses, gens, prior)
    # from the intermediate target to the joint one: importance weights, then resampling
    switch = (lpx + lc) - (st.lp_x[rows] + st.lw_c[rows])
    idx = _systematic(tid, np.where(np.isfinite(cur), switch, -np.inf), T,
                      np.where(which, counts, 0), _offsets(gens))
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


def _take(st: SISState, idx) -> SISState:
    return replace(st, tid=st.tid[idx], levels=_take_last(st.levels, idx), lw_base=st.lw_base[idx],
                   lp_x=st.lp_x[idx], lw_c=st.lw_c[idx], c_sum=st.c_sum[idx])


#: Views up to which the option ``few_views_budget`` replaces the budget (docs/solvers.md,
#: "Issue 20, item 2 (time)").
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

    gens = _gens(roots, 0, _seeds.STREAM_CAMERAS)
    z, u, *uv = _per_triplet(gens, M, draw)
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
    st = _extend(state, phi, psi, state.opts["motion_spread"], _seeds.STREAM_CAMERAS)
    alive = np.bincount(st.tid, minlength=T) > 0
    retry = ~alive & (state.lost == 0)
    if np.any(retry):
        sub = _extend(_subset(state, retry), phi[retry], psi[retry], RETRY_SPREAD,
                      _seeds.STREAM_RETRY)
        st = _merge(st, sub, np.flatnonzero(retry), state, np.flatnonzero(retry[state.tid]))
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


def _subset(st: SISState, mask) -> SISState:
    """The triplets ``mask`` (T,) of a state, renumbered."""
    rows = np.flatnonzero(mask[st.tid])
    new_id = np.cumsum(mask) - 1
    return replace(st, bearings=st.bearings[mask], headings=st.headings[mask],
                   sigma_bearing=st.sigma_bearing[mask], sigma_heading=st.sigma_heading[mask],
                   distances=st.distances[mask], sigma_distance=st.sigma_distance[mask],
                   step_sigma=None if st.step_sigma is None else st.step_sigma[mask],
                   roots=tuple(r for r, m in zip(st.roots, mask, strict=True) if m),
                   tid=new_id[st.tid[rows]],
                   levels=_take_last(st.levels, rows), lw_base=st.lw_base[rows],
                   lp_x=st.lp_x[rows],
                   lw_c=st.lw_c[rows], c_sum=st.c_sum[rows], same_pose=st.same_pose[mask],
                   lost=st.lost[mask])


def _merge(st: SISState, sub: SISState, where, parent, sub_rows) -> SISState:
    """``st`` with the hypotheses of triplets ``where`` replaced by those of ``sub``; both are
    one view on from ``parent``, ``sub`` from its hypotheses ``sub_rows`` (:func:`_subset`)."""
    keep = ~np.isin(st.tid, where)
    tid = np.concatenate([st.tid[keep], where[sub.tid]])
    order = np.argsort(tid, kind="stable")

    def cat(a, b):
        return np.concatenate([a[keep], b])[order]

    def same(a, b):
        return len(a) == len(b) and all(x[0] is y[0] for x, y in zip(a, b, strict=True))

    if same(st.levels[:-1], parent.levels) and same(sub.levels[:-2], parent.levels[:-1]):
        # the ancestry is shared: sub's children point into the parent's hypotheses sub_rows
        (ps, us), (pm, um) = sub.levels[-1], st.levels[-1]
        levels = _with_last(st.levels, cat(pm, ps), cat(um, sub_rows[us]))
    else:
        # a move rebuilt one of them: flat levels from whole trajectories (rare: a retry)
        P = cat(st.poses, sub.poses)
        levels = tuple((P[:, t].copy(), np.arange(P.shape[0])) for t in range(P.shape[1]))
    return replace(st, tid=tid[order], levels=levels,
                   lw_base=cat(st.lw_base, sub.lw_base), lp_x=cat(st.lp_x, sub.lp_x),
                   lw_c=cat(st.lw_c, sub.lw_c), c_sum=cat(st.c_sum, sub.c_sum))


def _extend(state: SISState, phi, psi, spread: float, purpose: int) -> SISState:
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

    gens = _gens(state.roots, i, purpose)
    if tail is None and htail is None:
        # the same draws as _per_triplet(gens, counts, draw), written in place (no
        # concatenation of a million rows)
        z, uv = np.empty((int(counts.sum()), 3)), []
        ends = np.cumsum(counts)
        for g, lo, hi in zip(gens, ends - counts, ends, strict=True):
            g.standard_normal(out=z[lo:hi])
    else:
        z, *uv = _per_triplet(gens, counts, draw)
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
        lc, cs = _child_c(st, state, par[j], pose, phi_c, has_sum)
        if incremental and j.size:
            cj = ct[j]
            tot = lw + lc
            _segment_max(cj, np.where(np.isnan(tot), -np.inf, tot), T, out=best)
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
        sc, ss = _child_c(st, state, par[sj], prev[par[sj]], phi_c, has_sum)
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
        lw_c[refit], refit_sum = _log_intermediate_c(
            st, ntid[refit], lambda sel: child_poses(refit[sel]),
            bearings[:, -REFIT_VIEWS:, 2], gens)
    # pruning and resampling planned on the weights alone: only the children that survive both
    # are gathered (as _prune would leave them)
    total = lw + lw_c
    rows = np.flatnonzero(_kept(ntid, total, T, opts["prune_ratio"]))
    plan = _resampling(st, ntid[rows], total[rows], gens)
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
        st = _moves(st, moving, mean_log)
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
    component choices and outlier places, :func:`._likelihood.bearing_noise`).

    Returns (child index (offset + row), pose (K, 3), log weight,
    log per-point prior) of the K children: those whose ray (or circle) meets the drawn locus
    arc, and the odometry draws of mixed parents (:func:`_mix_counts`)."""
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
    mixed = _mixed(state, ct, r, spread)
    if np.any(mixed):
        # each parent's r draws: the first n_odo from the odometry alone, then n_ray along
        # the heading (the ray above), the last n_circ at the step length of the distance
        # ratio (t = t* exp(sigma z0)) instead of the heading: the circle of radius t about
        # X_(i-1) meets the drawn locus arc at 0, 1 or 2 points (_mix_counts)
        first = np.cumsum(r[state.tid]) - r[state.tid]
        kk = offset + np.arange(par.size) - first[par]
        n_circ, n_odo = _mix_counts(state, ct, r)
        rows = np.flatnonzero(mixed & (kk >= r[ct] - n_circ))
        p, tt = par[rows], ct[rows]
        t = _ratio_step(state, p, tt, z[rows, 0])
        circ = locus_circle(pa[rows], pb[rows])
        pts[rows], valid[rows] = _circle_arc_intersection(
            prev[p, :2], t, circ.center, circ.radius, circ.side)
        # the odometry draws: X = X_(i-1) + t (cos theta, sin theta) with the ray's heading
        # draw theta and t from the ratio (its normal from the B column, which these draws
        # leave unused); alpha from the drawn A bearing as for every child. Where the odometry
        # is sharper than the locus arc (short steps seen from afar, as on MRCLAM) the arc's
        # children land where the heading and the ratio reject them
        rows = np.flatnonzero(mixed & (kk < n_odo))
        if rows.size:
            p, tt = par[rows], ct[rows]
            t = _ratio_step(state, p, tt, z[rows, 2])
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
    lpx = _log_camera_step(state, pj, X)
    lw = state.lw_base[pj] + _arcs.log_ray_jacobian_u(X, pp[j, :2], ux[j], uy[j]) + lpx
    if lcorr is not None:
        lw += lcorr[j]
    lw -= np.log(r)[ct[j]]
    # every child's alpha points its drawn A bearing at A
    alpha = _arcs.wrap(np.arctan2(-X[:, 1], -X[:, 0]) - pa[j])
    i = state.n_views
    if i >= 2 and np.any(state.distances[:, -1] > 0) and np.any(state.distances[ct[j], -1] > 0):
        pj, tj = par[j], ct[j]
        lw = lw + log_distance_factor(np.hypot(*(X - prev[pj, :2]).T), _prev_step(state, pj),
                                      state.distances[tj, -1], state.distances[tj, -2],
                                      state.sigma_distance[tj], state.opts.get("distance_tail"))
        m = np.flatnonzero(mixed[j])
        if m.size:
            pm = par[j[m]]
            lw[m] = state.lw_base[pm] + lpx[m] - np.log(r[ct[j[m]]]) \
                + _mixture_weight(state, X[m], prev, psi, r, pm, phi, alpha[m])
    pose = np.empty((j.size, 3))
    pose[:, :2] = X
    pose[:, 2] = alpha
    return j + offset, pose, lw, lpx


#: Heading noise (radians) up to which the motion step also proposes children from the distance
#: ratio: above it the heading's wrapped normal is no longer the plain normal the mixture
#: density evaluates.
_MIX_MAX_SIGMA_HEADING = 0.5
#: Whether triplets with distances draw some of their motion-step children from the step-length
#: ratio and the odometry (a switch for the tests, which compare the proposals).
_MIX_DISTANCE_PROPOSAL = True
#: Shares of a mixed parent's motion-step draws (ray, circle, odometry) (:func:`_mix_counts`;
#: the ray takes what the floors of the other two leave).
_MIX_SHARES = (0.375, 0.25, 0.375)


def _mixed(state: SISState, ct, r, spread) -> np.ndarray:
    """(B,) children (of triplets ``ct``) proposed by the two-component mixture of
    :func:`_mixture_weight`: the triplet has a step-length-ratio factor at this view, the
    noise is drawn at the model's width, and its heading noise is within
    (0, :data:`_MIX_MAX_SIGMA_HEADING`]."""
    if not _MIX_DISTANCE_PROPOSAL or state.n_views < 2 or spread != 1.0 \
            or not np.any(state.distances[:, -1] > 0):
        return np.zeros(ct.size, dtype=bool)
    d = state.distances[ct]
    sh = state.current_sigma(ct)
    htail = state.opts.get("heading_tail")
    if htail is not None:
        # the mixture's wide component must stay a plain (unwrapped) normal too
        sh = sh * htail.scale
    return (d[:, -1] > 0) & (d[:, -2] > 0) & (r[ct] >= 2) & (sh > 0) \
        & (sh <= _MIX_MAX_SIGMA_HEADING)


def _prev_step(state: SISState, par) -> np.ndarray:
    """(B,) length of the last step of hypotheses ``par`` (AB units)."""
    last, up = state.levels[-1]
    return np.hypot(*(last[par, :2] - state.levels[-2][0][up[par], :2]).T)


def _ratio_step(state: SISState, par, ct, z) -> np.ndarray:
    """(B,) step lengths drawn from the distance ratio for parents ``par`` of triplets ``ct``:
    the parent's last step times ``d_i / d_(i-1)`` times ``exp(sigma_d z)``, ``z`` (B,) standard
    normals."""
    return _prev_step(state, par) * state.distances[ct, -1] / state.distances[ct, -2] \
        * np.exp(state.sigma_distance[ct] * z)


def _circle_arc_intersection(origin, radius, center, arc_radius, side):
    """Points at distance ``radius`` (B,) from ``origin`` (B, 2) on locus arcs (centre (B, 2),
    radius (B,), side (B,) as :func:`qfg.geometry.ray_circle_intersection`): (points (B, 2, 2),
    valid (B, 2)); invalid slots hold the origin."""
    q = center - origin
    dd = np.hypot(q[:, 0], q[:, 1])
    R = np.where(np.isfinite(arc_radius), arc_radius, 0.0)
    ok = np.isfinite(arc_radius) & (radius > 0) & (dd > 0) & (dd <= radius + R) \
        & (dd >= np.abs(radius - R))
    dsafe = np.where(ok, dd, 1.0)
    a = (radius * radius - R * R + dsafe * dsafe) / (2.0 * dsafe)
    h = np.sqrt(np.maximum(radius * radius - a * a, 0.0))
    ex, ey = q[:, 0] / dsafe, q[:, 1] / dsafe
    pts = np.repeat(origin[:, None, :], 2, axis=1)
    valid = np.zeros((origin.shape[0], 2), dtype=bool)
    for k, sgn in enumerate((1.0, -1.0)):
        px = origin[:, 0] + a * ex - sgn * h * ey
        py = origin[:, 1] + a * ey + sgn * h * ex
        v = ok & ((side * px) < 0)
        pts[:, k, 0], pts[:, k, 1] = np.where(v, px, origin[:, 0]), np.where(v, py, origin[:, 1])
        valid[:, k] = v
    return pts, valid


def _mix_counts(state: SISState, ct, r):
    """(n_circ, n_odo) (B,): of the ``r`` draws of a mixed parent (triplets ``ct``), how many
    come from the distance ratio's circle and how many from the odometry alone
    (:data:`_MIX_SHARES`; no odometry draws with noiseless bearings, whose B bearing such a
    draw cannot meet); the rest follow the heading's ray."""
    rr = r[ct]
    n_circ = np.floor(rr * _MIX_SHARES[1]).astype(rr.dtype)
    n_odo = np.where(state.sigma_bearing[ct] > 0,
                     np.floor(rr * _MIX_SHARES[2]).astype(rr.dtype), 0)
    return n_circ, n_odo


def _mixture_weight(state: SISState, X, prev, psi, r, par, phi, alpha):
    """Log of the target's view-i factors over the proposal density, for children ``X`` (K, 2)
    of parents ``par`` whose triplets propose them from a mixture (:func:`_mix_counts`):
    ``n_ray`` draws along the heading (ray, meeting the drawn locus arc), ``n_circ`` at the
    step length of the distance ratio (circle, meeting the arc) and ``n_odo`` from the
    odometry alone (heading and step length); ``alpha`` (K,) the children's camera headings
    (each from its drawn A bearing). Over (position, alpha), with the A bearing's density (common to
    all three) and the prior left out,

        q_ray  = L_B N(theta(X) - theta*; sigma_w) |grad Gamma . u| / t
        q_circ = L_B N(log t - log t*; sigma_d) |grad Gamma . u_perp| / t
        q_odo  = N(theta(X) - theta*; sigma_w) N(log t - log t*; sigma_d) / t^2

    (t = |X - X_(i-1)|, u its direction, theta* = alpha_(i-1) + psi, t* the previous step times
    the distance ratio, L_B the B bearing's likelihood at (X, alpha), ``phi`` (T, 3) the
    view's bearings), and the target's factors are L_B and those two Gaussians (with a
    ``distance_tail`` the target's distance factor is its mixture, the circle's and the
    odometry's density still the core normal they draw from; with a heading tail the heading
    density is its mixture, which the ray and the odometry draw from): returns
    ``log(L_B N_theta F / q_mix)``, ``q_mix = (n_ray q_ray + n_circ q_circ + n_odo q_odo) / r``
    (balance heuristic). Without odometry draws L_B cancels and is not evaluated (noiseless
    bearings); with the circle left out as well it is the ray-only ``F t / |grad Gamma . u|``.
    A parent whose last step is 0 draws no circle or odometry children (q = 0 there)."""
    ct = state.tid[par]
    O = prev[par, :2]
    dx, dy = X[:, 0] - O[:, 0], X[:, 1] - O[:, 1]
    t = np.hypot(dx, dy)
    th = np.arctan2(dy, dx)
    sh, sd = state.current_sigma(ct), state.sigma_distance[ct]
    half_log_2pi = 0.5 * np.log(2.0 * np.pi)
    htail = state.opts.get("heading_tail")
    if htail is None:
        log_n_th = _likelihood.log_gauss(wrap_angle(th - prev[par, 2] - psi[ct]), sh) \
            - half_log_2pi
    else:
        # the ray children's heading density and the target's heading factor: the mixture
        log_n_th = _likelihood.log_bearing(wrap_angle(th - prev[par, 2] - psi[ct]), sh, htail)
    sp = _prev_step(state, par)
    dist = state.distances[ct, -1], state.distances[ct, -2]
    # the circle and odometry draws come from the core normal; with a distance tail the
    # target's factor is the wider mixture (the ray draws cover its tail)
    log_q_f = log_distance_factor(t, sp, *dist, sd)
    tail = state.opts.get("distance_tail")
    log_f = log_q_f if tail is None else log_distance_factor(t, sp, *dist, sd, tail)
    lj_ray = _arcs.log_ray_jacobian(X, O, th)   # log t - log |grad Gamma . u|
    # log t - log |grad Gamma . u_perp|: the ray Jacobian along u_perp from one unit back
    perp = np.stack([-np.sin(th), np.cos(th)], axis=1)
    with np.errstate(divide="ignore"):
        lj_circ = np.log(t) + _arcs.log_ray_jacobian(X, X - perp, th + 0.5 * np.pi)
    log_q_ray = log_n_th - lj_ray
    log_q_circ = np.where(sp > 0, log_q_f - lj_circ, -np.inf)
    rr = r[ct].astype(float)
    n_circ, n_odo = (c.astype(float) for c in _mix_counts(state, ct, r))
    n_ray = rr - n_circ - n_odo
    odo = n_odo > 0
    log_b = np.zeros(X.shape[0])
    if np.any(odo):
        # the B bearing's likelihood at (X, alpha)
        rb = wrap_angle(phi[ct, 1] - (np.arctan2(1.0 - X[:, 1], -X[:, 0]) - alpha))
        log_b = np.where(odo, _likelihood.log_bearing(rb, state.sigma_bearing[ct],
                                                      state.opts.get("bearing_tail")), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_q_odo = np.where(odo & (sp > 0), log_n_th + log_q_f - 2.0 * np.log(t), -np.inf)
        log_mix = np.logaddexp(np.log(n_ray / rr) + log_q_ray,
                               np.log(n_circ / rr) + log_q_circ)
        # L_B multiplies the arc's two proposals and the target: it cancels without odometry
        # draws (log_b = 0 there)
        log_mix = np.logaddexp(log_b + log_mix, np.log(n_odo / rr) + log_q_odo)
        out = log_b + log_n_th + log_f - log_mix
    return np.where(np.isnan(out), -np.inf, out)


#: Whether the final C draws centre on the carried summaries' modes (:func:`_final_proposal`);
#: a switch for the tests, which compare both.
_FINAL_AT_MODE = True


def _final_proposal(state: SISState, idx, poses):
    """The Gaussian part of the final C proposal for trajectories ``idx`` (rows of ``state``,
    poses (J, n, 3)), as :func:`._landmarks.sample_landmarks` takes it (``laplace=``): the
    Laplace approximation about C's mode over every view (:func:`._laplace.refine_mode`, O(n)
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
    gens = _gens(state.roots, n, _seeds.STREAM_POSTERIOR)
    off = _offsets(gens)
    idx = _systematic(state.tid, total, T, np.where(alive, M, 0), off)
    tid, poses = state.tid[idx], trajectories(state.levels, idx)
    k = opts["one_view_samples"] if n == 1 else opts["landmark_samples"]
    if tid.size:
        L, log_q, log_lik, spread = _c_weight(state, tid, poses, state.bearings[..., 2], gens,
                                              k, laplace=_final_proposal(state, idx, poses))
        lp = np.empty(L.shape[:2])
        # the prior of the distinct points: views taken as "not moved" repeat a camera
        for pat, rows in _view_patterns(~state.same_pose[tid]):
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
    mx = _segment_max(flat_tid, flw, T)
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
