"""Qualitative states from a :class:`qfg.joint.JointPosterior`: :func:`triplet_marginals` (the
state distribution of every ordered landmark triplet, a labelled
:class:`qfg.inference.results.Marginals` keyed by landmark ids) and :func:`camera_marginals`
(the state of camera poses in triplet frames, a ``Marginals`` keyed by those triplets), both
method ``"joint"``, each counted over samples of the posterior and
mixed toward the prior's states where the map cannot say (weights ``floor``, ``widen``, 1).
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

import numpy as np

from .. import nonlinear as _nl
from .. import partitions as _partitions
from .._validate import as_float_array, as_rng, non_negative
from ..geometry import poses_to_frame, to_frame
from ._laplace import _points_cov
from .posterior import JointPosterior
from .sampling import sample_landmarks

if TYPE_CHECKING:
    from ..inference.results import Marginals

__all__ = ["triplet_marginals", "camera_marginals", "FLOOR"]

#: Weight of the prior's state distribution mixed into every row: insurance against a confident
#: wrong set of samples (it bounds what one triplet can lose) at a cost too small to matter where
#: the map is right (docs/joint.md, "Covariance scale and floor").
FLOOR = 1e-3


def _all_triplets(L):
    return [t for t in itertools.permutations(range(L), 3)]



def _mix(P, q, w):
    return (1.0 - w)[:, None] * P + w[:, None] * q[None, :]


def triplet_marginals(posterior: JointPosterior, triplets=None, *, partition="edc",
                      samples: int = 2000, seed=0, prior_states=None, floor: float = FLOOR,
                      widen: float = 0.5) -> "Marginals":
    """State distribution of every ordered triplet (landmark ids ``(A, B, C)``) from samples of
    the posterior: ``P(S) = (1 - w) #{samples in S} / n + w q`` with ``q`` = ``prior_states``
    (m,) (default uniform) and ``w`` = ``floor``, or ``widen`` for triplets with an
    inconsistent landmark (or when a robot sat in a wrong minimum that could not be dropped), or
    1 for triplets with an unconstrained landmark.

    Returns a :class:`qfg.inference.results.Marginals` keyed by landmark-id triplets, method
    ``"joint"``, ``info["flagged"]`` (n,) bool, ``info["widen"]`` (n,) the weight given to the
    prior, ``info["flags"]`` (the posterior's). When nothing was solved
    (``posterior.method == "none"``) every row is the prior and every row is flagged.
    """
    from ..inference.results import Marginals

    part = _partitions.get(partition)
    m = part.n_states
    ids = posterior.landmark_ids
    if triplets is None:
        tri_idx = np.array(_all_triplets(len(ids)), dtype=np.intp).reshape(-1, 3)
    else:
        tl = [tuple(t) for t in triplets]
        if any(len(t) != 3 or len(set(t)) != 3 for t in tl):
            raise ValueError("triplets: expected (A, B, C) triplets of three distinct ids")
        tri_idx = posterior.index([x for t in tl for x in t]).reshape(-1, 3)
    q = (np.full(m, 1.0 / m) if prior_states is None
         else as_float_array("prior_states", prior_states, ndim=1))
    if q.size != m or q.min() < 0 or not np.isclose(q.sum(), 1.0):
        raise ValueError(f"prior_states: expected {m} probabilities summing to 1")
    floor = non_negative("floor", floor)
    widen = non_negative("widen", widen)
    if floor > 1 or widen > 1:
        raise ValueError("floor, widen: expected weights in [0, 1]")
    n = len(tri_idx)
    P = np.tile(q, (n, 1))
    lf = np.array(posterior.landmark_flags)
    w = np.full(n, floor)
    if posterior.method != "none" and n:
        S = sample_landmarks(posterior, samples, seed)
        solvable = posterior.constrained[tri_idx].all(axis=1)
        idx = np.flatnonzero(solvable)
        P[idx] = state_counts(S, tri_idx[idx], part) / samples
        bad = (lf[tri_idx] == "inconsistent").any(axis=1)
        if "local_minimum" in posterior.flags and all(
                v != "local_minimum" for v in posterior.robot_flags.values()):
            bad[:] = True  # the only run sits in a wrong minimum: nothing is trustworthy
        w = np.where(bad, np.maximum(widen, floor), w)
        w = np.where(solvable, w, 1.0)
    else:
        w[:] = 1.0
    P = _mix(P, q, w)
    keys = tuple(tuple(int(ids[i]) for i in t) for t in tri_idx.tolist())
    return Marginals(keys, part.name, P, "joint",
                     {"flagged": w > floor, "widen": w, "flags": posterior.flags})


def state_counts(S, tri, part, chunk: int = 256):
    """Counts (T, m) of each triplet's state over the samples ``S`` (n, L, 2) of the landmarks'
    world positions: ``tri`` (T, 3) ordered landmark indices, ``part`` the partition; rows sum to
    n. Chunked over the triplets so that the (n, chunk) frames stay small."""
    m = part.n_states
    out = np.zeros((len(tri), m))
    for a in range(0, len(tri), chunk):
        t = tri[a:a + chunk]
        A, B, C = S[:, t[:, 0]], S[:, t[:, 1]], S[:, t[:, 2]]
        s = part.state_of(_safe_frame(C, A, B))                     # (n, T')
        k = np.arange(len(t))[None, :] * m + np.where(s >= 0, s, 0)
        out[a:a + chunk] = np.bincount(k.ravel(), minlength=len(t) * m).reshape(len(t), m)
    return out


def _safe_frame(C, A, B):
    """to_frame, with a sample where A and B coincide moved by a hair (measure zero)."""
    d = B - A
    near = np.sum(d * d, axis=-1) <= 1e-24
    if near.any():
        B = np.where(near[..., None], B + 1e-9, B)
    return to_frame(C, A, B)


def camera_marginals(posterior: JointPosterior, robot, pose_index, triplets, *,
                     partition="edc", samples: int = 500, seed=0, prior_states=None,
                     floor: float = FLOOR) -> "Marginals":
    """State distributions of camera poses in triplet frames: row i is the state of pose
    ``pose_index[i]`` of ``robot`` in the AB frame of ``triplets[i]`` (landmark ids
    ``(A, B, C)``), from samples of the joint Gaussian of that pose and the landmarks (best
    mode). Rows whose robot was not solved, or whose A or B is unconstrained, are
    ``prior_states`` (default uniform); every row is mixed with it by ``floor``.

    Returns a :class:`qfg.inference.results.Marginals`: rows (n, m) in the order of
    ``pose_index``, keyed by ``triplets`` (a triplet given for several poses is one key: look
    such rows up by position, ``res[i]``, or in ``res.probabilities``), method ``"joint"``,
    ``info["robot"]`` and ``info["pose_index"]`` (n,).
    """
    from ..inference.results import Marginals

    part = _partitions.get(partition)
    m = part.n_states
    pose_index = np.asarray(pose_index, dtype=np.intp).reshape(-1)
    tl = [tuple(t) for t in triplets]
    if len(tl) != pose_index.size:
        raise ValueError(f"triplets: expected {pose_index.size} triplets (one per pose), "
                         f"got {len(tl)}")
    if any(len(t) != 3 for t in tl):
        raise ValueError("triplets: expected (A, B, C) triplets of landmark ids")
    q = np.full(m, 1.0 / m) if prior_states is None else np.asarray(prior_states, float)
    out = np.tile(q, (pose_index.size, 1))

    def labelled(P):
        return Marginals(tuple(tl), part.name, P, "joint",
                         {"robot": robot, "pose_index": pose_index})
    if robot not in posterior.robot_flags:
        raise KeyError(f"robot: {robot} is not in this posterior")
    if (posterior.method == "none" or posterior._pose_offset is None
            or robot not in posterior._pose_offset or not pose_index.size):
        return labelled(_mix(out, q, np.full(len(out), 1.0)))
    rng = as_rng(seed)
    pr, fit = posterior._problem, posterior._fit
    ok = np.flatnonzero(posterior.constrained)
    col = -np.ones(len(posterior.landmark_ids), np.intp)
    col[ok] = np.arange(ok.size)
    marg = posterior.info["marginals"]
    off = posterior._pose_offset[robot]
    AB = posterior.index([x for t in tl for x in t[:2]]).reshape(-1, 2)
    for p in np.unique(pose_index).tolist():
        rows = np.flatnonzero(pose_index == p)
        need = np.unique(col[AB[rows]])
        if (need < 0).any():
            continue
        try:
            C = _points_cov(marg, pr, need, [off + p])
        except _nl.SingularInformation:  # this pose cannot be placed: its rows stay the prior
            continue
        mu = np.concatenate([fit.points[need].ravel(), fit.poses[off + p]])
        z = _nl.sample_gaussian(mu, C, samples, rng)
        d = z[:, -3:] - fit.poses[off + p]
        th = fit.poses[off + p, 2]
        X = fit.poses[off + p] + np.stack([np.cos(th) * d[:, 0] - np.sin(th) * d[:, 1],
                                           np.sin(th) * d[:, 0] + np.cos(th) * d[:, 1],
                                           d[:, 2]], -1)
        pos = {int(c): i for i, c in enumerate(need.tolist())}
        for i in rows.tolist():
            a, b = pos[int(col[AB[i, 0]])], pos[int(col[AB[i, 1]])]
            A, B = z[:, 2 * a:2 * a + 2], z[:, 2 * b:2 * b + 2]
            s = part.state_of(poses_to_frame(X, A, B)[:, :2])
            out[i] = np.bincount(s[s >= 0], minlength=m)[:m] / samples
    return labelled(_mix(out, q, np.full(len(out), non_negative("floor", floor))))

