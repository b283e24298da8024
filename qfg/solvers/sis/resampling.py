"""Pruning and systematic resampling of the SIS engine's hypotheses, per triplet: the survivors of
pruning (:func:`kept`), the plan of a resampling to ``max_hypotheses`` (:func:`plan_resampling`;
to the cap at every view for the triplets whose hypotheses are moved after it), and systematic
resampling itself (:func:`systematic`).
"""

from __future__ import annotations

import numpy as np

from . import rejuvenation as _rejuvenation
from .state import SISState


def segment_max(tid, x, T, out=None):
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


def systematic(tid, logw, T, counts_out, offsets):
    """Per-triplet systematic resampling: ``counts_out[t]`` indices of triplet t's elements drawn
    by weights exp(logw), with offsets (T,) in [0, 1). Triplets whose weights are all -inf (or
    counts_out = 0) draw nothing. Returns indices sorted by triplet."""
    mx = segment_max(tid, logw, T)
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


def draw_offsets(gens):
    return np.array([g.random() for g in gens])


def kept(tid, total, T, ratio):
    """(N,) hypotheses that survive pruning: finite and at least ``ratio`` x the heaviest of
    their triplet. Applying it twice keeps the same set (the heaviest always stays)."""
    mx = segment_max(tid, total, T)
    floor = mx + np.log(ratio) if ratio > 0 else np.full(T, -np.inf)
    return np.isfinite(total) & (total >= floor[tid])


def plan_resampling(st: SISState, tid, total, gens):
    """The resampling :func:`.engine._prune` does after pruning, on hypotheses ``tid`` (N,) with
    weights ``total`` (N,) (kept by :func:`kept`) of the triplets of ``st``: None when nothing
    is resampled, else (rows kept (sorted by triplet), triplets resampled (T,), their mean log
    weight (T,), triplets to move (T,)). Every survivor of a resampled triplet carries the mean
    weight. Draws one offset per triplet from ``gens`` every time."""
    T = st.n_triplets
    cap = st.opts["max_hypotheses"]
    counts = np.bincount(tid, minlength=T)
    # drawn for every triplet every time, so that a triplet's later draws do not depend on others
    off = draw_offsets(gens)
    # triplets whose hypotheses are moved are resampled to the cap at every view (resample-move:
    # the moves need equal weights, and pruning alone leaves the descendants of few early poses)
    moving = (counts > 0) & _movable(st) & _moves_now(st)
    if not (counts.size and (counts.max() > cap or np.any(moving))):
        return None
    over = (counts > cap) | moving
    idx_over = systematic(tid, total, T, np.where(over, cap, 0), off)
    keep_under = np.flatnonzero(~over[tid])
    # every survivor of an over-full triplet carries the mean weight, the total is unchanged
    mx = segment_max(tid, total, T)
    w = np.exp(total - np.where(np.isfinite(mx), mx, 0.0)[tid])
    with np.errstate(divide="ignore"):
        mean_log = mx + np.log(np.bincount(tid, weights=w, minlength=T) / cap)
    idx = np.concatenate([keep_under, idx_over])
    return idx[np.argsort(tid[idx], kind="stable")], over, mean_log, moving


#: Noise sigmas (radians) within which the trajectories are moved after resampling: below, the
#: intermediate target is too narrow for a random walk; above, its wrapped normals are not the
#: plain normals :func:`.target.log_pose_target` evaluates.
_MOVE_SIGMAS = (1e-6, 0.5)


def _movable(st: SISState) -> np.ndarray:
    """(T,) triplets whose trajectories the MH moves may change: noise in both sigmas within
    :data:`_MOVE_SIGMAS`, and no view taken as "camera did not move" (a pose repeated exactly is
    not a density the random walk can target)."""
    lo, hi = _MOVE_SIGMAS
    return ((st.sigma_bearing >= lo) & (st.sigma_bearing <= hi) & (st.sigma_heading >= lo)
            & (st.sigma_heading <= hi) & ~np.any(st.same_pose, axis=1))


def _moves_now(st: SISState) -> bool:
    """Whether the hypotheses are moved after this view's resampling: every view from the second
    with ``move_steps``, the views of :func:`.rejuvenation.scheduled` with ``rejuvenate``."""
    return bool((st.opts.get("move_steps", 0) > 0 and st.n_views >= 2)
                or (st.opts.get("rejuvenate", 0) > 0 and _rejuvenation.scheduled(st.n_views)))
