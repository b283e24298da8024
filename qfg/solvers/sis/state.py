"""The SIS engine's state: :class:`SISState` (the hypotheses of T triplets after the views so
far, flat arrays sorted by triplet), the trajectories kept as ancestry (``levels``: per view the
poses and each one's parent, so a step adds one level and copies no past pose;
:func:`trajectories` gathers whole trajectories), the selections of hypotheses and triplets, and
the per-triplet random streams (:func:`streams`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..common import estimate as _estimate
from ..common import options as _options
from ..common import seeds as _seeds


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
    c_sum: np.ndarray          # (N, 7) Gaussian summary of C's integral (common.laplace.update_landmark;
                               # NaN rows: none, the next view refits them over all views)
    same_pose: np.ndarray      # (T, i) views taken as "camera did not move"
    lost: np.ndarray           # (T,) view (1-based) at which nothing survived, 0 if alive
    full_opts: dict | None = None  # the caller's options while ``opts`` is their few-views
                               # budget (:data:`.engine.FEW_VIEWS`): the next view rebuilds the
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


def with_last(levels, pose, up) -> tuple:
    """``levels`` with the last level replaced."""
    return levels[:-1] + ((pose, up),)


def take_last(levels, idx) -> tuple:
    """``levels`` keeping the hypotheses ``idx`` (rows of the last level): O(len(idx)), the
    earlier levels shared."""
    pose, up = levels[-1]
    return with_last(levels, pose[idx], up[idx])


def take(st: SISState, idx) -> SISState:
    return replace(st, tid=st.tid[idx], levels=take_last(st.levels, idx), lw_base=st.lw_base[idx],
                   lp_x=st.lp_x[idx], lw_c=st.lw_c[idx], c_sum=st.c_sum[idx])


def subset(st: SISState, mask) -> SISState:
    """The triplets ``mask`` (T,) of a state, renumbered."""
    rows = np.flatnonzero(mask[st.tid])
    new_id = np.cumsum(mask) - 1
    return replace(st, bearings=st.bearings[mask], headings=st.headings[mask],
                   sigma_bearing=st.sigma_bearing[mask], sigma_heading=st.sigma_heading[mask],
                   distances=st.distances[mask], sigma_distance=st.sigma_distance[mask],
                   step_sigma=None if st.step_sigma is None else st.step_sigma[mask],
                   roots=tuple(r for r, m in zip(st.roots, mask, strict=True) if m),
                   tid=new_id[st.tid[rows]],
                   levels=take_last(st.levels, rows), lw_base=st.lw_base[rows],
                   lp_x=st.lp_x[rows],
                   lw_c=st.lw_c[rows], c_sum=st.c_sum[rows], same_pose=st.same_pose[mask],
                   lost=st.lost[mask])


def merge(st: SISState, sub: SISState, where, parent, sub_rows) -> SISState:
    """``st`` with the hypotheses of triplets ``where`` replaced by those of ``sub``; both are
    one view on from ``parent``, ``sub`` from its hypotheses ``sub_rows`` (:func:`subset`)."""
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
        levels = with_last(st.levels, cat(pm, ps), cat(um, sub_rows[us]))
    else:
        # a move rebuilt one of them: flat levels from whole trajectories (rare: a retry)
        P = cat(st.poses, sub.poses)
        levels = tuple((P[:, t].copy(), np.arange(P.shape[0])) for t in range(P.shape[1]))
    return replace(st, tid=tid[order], levels=levels,
                   lw_base=cat(st.lw_base, sub.lw_base), lp_x=cat(st.lp_x, sub.lp_x),
                   lw_c=cat(st.lw_c, sub.lw_c), c_sum=cat(st.c_sum, sub.c_sum))


def streams(roots, view, purpose):
    """One generator per triplet for (view, purpose); every draw of that stage comes from it, in
    a fixed order, so a triplet's numbers do not depend on the batch."""
    return [_seeds.stream(r, view, purpose) for r in roots]
