"""MRCLAM study (paper section 6d, Table 2): qualitative mapping on real data, scored so that it
cannot flatter.

For one MRCLAM dataset directory (:func:`run_dataset`):

1. Load it (:func:`qfg.datasets.mrclam.load`); landmark pairs seen at each other's ground-truth
   position (:func:`~qfg.datasets.mrclam.check_landmarks`) are swapped back before scoring
   (dataset 1: subjects 11 and 17); the swaps are in every row (``gt_swaps``).
2. Histories (:func:`~qfg.datasets.mrclam.triplet_histories`): the views of a pass where the
   robot moved (``min_travel`` = 0.02 m), passes split where the triplet goes unseen for
   ``max_gap`` = 120 s; of each pass, ``spread_views`` = 3 views spread evenly over it, with the
   odometry's headings between them (wide baselines; chosen on dataset 6, docs/results/mrclam.md).
   ``spread_views=0`` keeps every view; ``max_views`` truncates each pass to its first views.
3. ``mode``: ``"honest"`` solves the measured bearings and odometry headings; ``"paper"``
   (paper emulation, needs motion capture: dataset 6) replaces them by the bearings and headings
   computed from the captured poses (:func:`paper_history`), to show what clean inputs give.
4. The prior (``prior``): ``"arena"`` (default) is :class:`qfg.priors.WorldBoxPrior` with the
   box of the arena (:func:`arena_extent`: the landmarks' and the robots' area); ``"world"`` the
   simulator's 6 x 7 m box. Every history is solved with :func:`qfg.solvers.solve_triplets`
   under it; robots without odometry get the baseline model (the row's ``method``).
5. Histories of one ordered triplet (separate passes, other robots) are combined at the state
   level with the prior counted once: ``combine="prior-once"`` (independent passes,
   :func:`qfg.combine.combine_posteriors`) or ``"geometric"`` (passes that repeat the same
   evidence, :func:`qfg.combine.geometric_pool`); ``"product"`` (the plain product of posteriors,
   the prior counted k times) is kept to measure the difference.
6. The whole qualitative map (:func:`qfg.graph.full_map`, every ordered triplet), the combined
   estimates as priors, the rest propagated by pooled composition (:func:`qfg.propagation.propagate_pooled`;
   ``propagation="best"``: the paper's Algorithm 2, :func:`qfg.propagation.propagate`).
7. Scores (:mod:`qfg.metrics`) against the landmark ground truth (:func:`qfg.graph.truth_states`)
   of seen and propagated triplets: the probability of the truth, log score (clip 1e-4), Brier,
   GT rating with ties split, truth under 1%, DMSE, entropy, flagged and uniform estimates; each
   beside two baselines: ``uniform_*`` and ``prior_*`` (the state distribution the prior alone
   gives, :func:`qfg.combine.prior_state_distribution`). With motion capture, every view of every
   history is also scored as a camera state (rows of kind ``"camera"``).

Rows: one per ordered triplet (``kind`` ``"seen"`` / ``"propagated"``) and one per scored camera
view (``"camera"``); ``probabilities`` holds the estimate (m numbers, ``;``-separated) so that
summaries and calibration figures are computed from the rows alone. :func:`write_outputs` writes
``triplets.csv``, ``cameras.csv``, ``summary.json``, ``table.md`` and figures.

Command: ``qfg mrclam PATH`` (one dataset); ``qfg experiment mrclam --preset paper`` (every
dataset under ``data``, one runner task each).
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from qfg import metrics
from qfg.combine import (
    combine_posteriors,
    geometric_pool,
    prior_state_distribution,
    product_of_posteriors,
    temper,
)
from qfg.datasets import mrclam as _mrclam
from qfg.harness.runner import Study, figure_format, param_spec, save_figure, write_table
from qfg.partitions import get as get_partition
from qfg.priors import WorldBoxPrior
from qfg.priors import get as get_prior

COMBINE = ("prior-once", "geometric", "product")
METHODS = ("fast", "full", "baseline")
MODES = ("honest", "paper")
PRIORS = ("arena", "world")
KINDS = ("seen", "propagated", "camera")
#: Scores of every row, each also with the ``uniform_`` and ``prior_`` baselines.
SCORES = ("p_truth", "log_score", "brier", "gt_rating", "truth_under_1pct")
#: Samples behind each prior's state distribution (standard error <= 1.2e-3 per state).
PRIOR_SAMPLES = 200_000

DEFAULTS = {
    "data": "",                            # directory holding MRCLAM_Dataset* ("": $QFG_MRCLAM_DIR)
    "datasets": [],                        # dataset numbers (empty: every one found)
    "robots": [],                          # robot numbers (empty: every robot)
    "method": "full",
    "mode": "honest",
    "prior": "arena",
    "combine": "geometric",
    "partition": "edc",
    "fix_landmarks": True,                 # swap back landmark pairs found by check_landmarks
    "tensor": "",                          # .npz file; "" = the shipped tensor of the partition
    "min_travel": 0.02,                    # m between kept views (0.02: every view with motion)
    "max_gap": 120.0,                      # s unseen that ends a pass
    "max_views": 0,                        # first views of each pass kept (0: all)
    "propagate": True,                     # map and propagate (False: seen triplets only)
    "propagation": "mean",                 # "mean": pooled composition; "best": Algorithm 2
    "sigma_bearing_deg": 0.0,              # bearing sigma the solver assumes (0: loader default)
    "sigma_heading_deg": 0.0,              # heading sigma the solver assumes (0: loader default)
    "temper": 1.0,                         # power on each estimate's likelihood part (1: none)
    "spread_views": 3,                     # views spread over each pass (0: all)
    "distances": True,                     # odometry's travelled distances in the motion model
                                           # (off: no gain on dataset 6, docs/mrclam.md)
    "sigma_distance_ratio": 0.0,           # their log-ratio noise (0: loader default, 0.074)
}


# ----------------------------------------------------------------------------- data, prior
def prepare(path, *, fix_landmarks: bool = True):
    """Load a dataset directory; returns (dataset with ground truth fixed, swaps applied)."""
    ds = _mrclam.load(path)
    swaps = _mrclam.check_landmarks(ds).swaps if fix_landmarks else ()
    if swaps:
        ds = _mrclam.swap_landmarks(ds, swaps)
    return ds, tuple(tuple(int(x) for x in s) for s in swaps)


def arena_extent(ds, *, max_residual: float = 0.15) -> dict:
    """The arena's axis-aligned box: the landmarks' ground truth and the robots' positions.

    Robot positions come from motion capture when the dataset has it, else from landmark fixes
    (:func:`qfg.datasets.mrclam.landmark_fixes`, rms residual <= ``max_residual`` m); the 0.5th
    and 99.5th percentiles of the robot positions are used, so that a few bad fixes cannot widen
    the box. Returns ``{"x": (lo, hi), "y": (lo, hi), "width", "height", "robots_from"}`` (m).
    """
    pts = [ds.landmark_xy]
    src = "fixes"
    for r, rd in ds.robots.items():
        if rd.groundtruth is not None:
            pts.append(rd.groundtruth[:, 1:3])
            src = "motion capture"
        else:
            f = _mrclam.landmark_fixes(ds, r, min_landmarks=3)
            pts.append(f.poses[f.residual <= max_residual, :2])
    lm = ds.landmark_xy
    rob = np.concatenate(pts[1:]) if len(pts) > 1 else lm
    lo = np.minimum(lm.min(axis=0), np.percentile(rob, 0.5, axis=0))
    hi = np.maximum(lm.max(axis=0), np.percentile(rob, 99.5, axis=0))
    return {"x": (float(lo[0]), float(hi[0])), "y": (float(lo[1]), float(hi[1])),
            "width": float(hi[0] - lo[0]), "height": float(hi[1] - lo[1]), "robots_from": src}


def make_prior(ds, name: str = "arena"):
    """``"arena"``: :class:`~qfg.priors.WorldBoxPrior` on :func:`arena_extent`'s box (metres; d_min
    stays 0.01 m); ``"world"``: the simulator's box (:func:`qfg.priors.get`)."""
    if name not in PRIORS:
        raise ValueError(f"prior: expected one of {PRIORS}, got {name!r}")
    if name == "world":
        return get_prior("world")
    e = arena_extent(ds)
    return WorldBoxPrior(width=e["width"], height=e["height"])


# ----------------------------------------------------------------------------- histories
def _select(h, idx):
    """The views ``idx`` (increasing) of a history, every per-view field cut alike; headings and
    distances kept only for consecutive runs (callers recompute them otherwise)."""
    idx = np.asarray(idx, dtype=int)
    t = h.truth
    truth = dataclasses.replace(
        t, poses_world=None if t.poses_world is None else t.poses_world[idx],
        poses_ab=None if t.poses_ab is None else t.poses_ab[idx],
        camera_states=None if t.camera_states is None else t.camera_states[idx])
    step = idx[:-1]
    extra = {}
    if hasattr(h, "distances"):
        extra["distances"] = None if h.distances is None else h.distances[step]
        extra["groundtruth_valid"] = (None if h.groundtruth_valid is None
                                      else h.groundtruth_valid[idx])
    return dataclasses.replace(h, bearings=h.bearings[idx], headings=h.headings[step],
                               views=h.views[idx], truth=truth, **extra)


def truncate(h, n: int):
    """The first ``n`` views of a history (every per-view field cut alike; 0: all)."""
    if n <= 0 or h.n_views <= n:
        return h
    return _select(h, np.arange(n))


def spread(h, n: int, poses=None, view_times=None):
    """``n`` views spread evenly over the history (first and last included; 0: all): wider
    baselines than consecutive views. The headings and distances between the kept views are
    recomputed from ``poses`` (the robot's dead-reckoned view poses, :func:`qfg.datasets.mrclam.
    view_poses`, indexed like ``view_times``); without them (no odometry, or inputs recomputed
    from the capture afterwards, :func:`paper_history`) they are left as cut."""
    if n <= 0 or h.n_views <= n:
        return h
    out = _select(h, np.unique(np.round(np.linspace(0, h.n_views - 1, n)).astype(int)))
    if poses is None or not h.has_motion:
        return out
    from qfg.geometry import motion_heading

    vi = np.searchsorted(view_times, out.views)
    P = poses[vi]
    return dataclasses.replace(out, headings=motion_heading(P[:-1], P[1:, :2]),
                               distances=np.hypot(*np.diff(P[:, :2], axis=0).T))


def paper_history(h):
    """Paper emulation: the history with bearings, headings and distances computed from the
    captured camera poses (``truth.poses_world``) instead of measured, or None when the capture
    does not cover every view. Bearings ``bearing(pose_i, L)`` for L = A, B, C; headings
    ``motion_heading(pose_i, position_{i+1})`` (conventions.md); distances
    ``|position_{i+1} - position_i|`` (when the history has distances); sigmas unchanged."""
    from qfg.geometry import bearing, motion_heading

    t = h.truth
    if t.poses_world is None or (h.groundtruth_valid is not None
                                 and not np.all(h.groundtruth_valid)):
        return None
    P = np.asarray(t.poses_world, dtype=float)
    phi = bearing(P[:, None, :], np.asarray(t.landmarks_world)[None, :, :])
    psi = motion_heading(P[:-1], P[1:, :2])
    extra = {}
    if getattr(h, "distances", None) is not None:
        # clean inputs throughout: odometry distances next to captured bearings would mix
        # measured and true geometry
        extra["distances"] = np.hypot(*np.diff(P[:, :2], axis=0).T)
    return dataclasses.replace(h, bearings=phi, headings=psi, has_motion=True, **extra)


def histories(ds, robots=None, *, mode: str = "honest", max_views: int = 0,
              spread_views: int = 0, **options):
    """(robot, history) pairs of ``robots`` (None / empty: every robot), robot-major; ``mode``
    ``"paper"`` keeps the histories the capture covers, with clean inputs (:func:`paper_history`);
    ``spread_views`` > 0 keeps that many views spread over each pass (:func:`spread`, headings
    from the odometry between the kept views, or from the capture in paper mode)."""
    if mode not in MODES:
        raise ValueError(f"mode: expected one of {MODES}, got {mode!r}")
    robots = sorted(ds.robots) if not robots else [int(r) for r in robots]
    if mode == "paper" and not any(ds.robot(r).groundtruth is not None for r in robots):
        raise ValueError(f"mode: 'paper' needs motion capture (RobotN_Groundtruth); "
                         f"{ds.name} has none")
    out = []
    for r in robots:
        rd = ds.robot(r)
        P = _mrclam.view_poses(rd)[0] if spread_views and rd.has_odometry else None
        for h in _mrclam.triplet_histories(ds, r, **options):
            h = spread(truncate(h, int(max_views)), int(spread_views),
                       None if mode == "paper" else P, rd.view_times)
            if mode == "paper":
                h = paper_history(h)
                if h is None:
                    continue
            out.append((r, h))
    return out


#: Histories solved per call: only the (m,) vectors are kept, chunk by chunk (an estimate may
#: keep solver state; dataset 5 in one call once exhausted 24 GB).
CHUNK = 128


@dataclass(frozen=True)
class _Light:
    landmark: np.ndarray
    cameras: np.ndarray
    method: str
    degenerate: bool


def _solve(hs, method, part, seed, options) -> list[_Light]:
    """Solve in chunks of :data:`CHUNK`; chunk c gets child c of ``SeedSequence(seed)``."""
    from qfg.solvers import solve_triplets

    n_chunks = -(-len(hs) // CHUNK)
    seeds = np.random.SeedSequence(seed).spawn(n_chunks) if n_chunks else []
    out: list[_Light] = []
    for c in range(n_chunks):
        ests = solve_triplets(hs[c * CHUNK:(c + 1) * CHUNK], method=method, partition=part,
                              seed=seeds[c], **options)
        out += [_Light(e.landmark, e.cameras, e.method, bool(e.degenerate)) for e in ests]
        del ests
    return out


# ----------------------------------------------------------------------------- scoring
def _enc(p) -> str:
    return ";".join(f"{x:.6g}" for x in p)


def decode(text: str) -> np.ndarray:
    """A row's ``probabilities`` back to an (m,) vector (renormalized: 6 digits were written)."""
    p = np.array([float(x) for x in str(text).split(";")])
    return p / p.sum()


def _scores(P, g, prefix=""):
    """Scores of estimates (n, m) at truths (n,): dict of (n,) arrays, keys prefixed."""
    return {f"{prefix}p_truth": metrics.gt_likelihood(P, g),
            f"{prefix}log_score": metrics.log_score(P, g),
            f"{prefix}brier": metrics.brier(P, g),
            f"{prefix}gt_rating": metrics.gt_rating(P, g),
            f"{prefix}truth_under_1pct": metrics.truth_under(P, g, 0.01).astype(float)}


def _score_rows(P, g, q, centroids):
    """Per row: the estimate's scores, DMSE, entropy, whether it is uniform, and the baselines
    (uniform; the prior's state distribution ``q``)."""
    n, m = P.shape
    out = _scores(P, g)
    out.update(_scores(np.full((n, m), 1.0 / m), g, "uniform_"))
    out.update(_scores(np.broadcast_to(q, (n, m)), g, "prior_"))
    out["dmse"] = metrics.dmse(P, g)
    out["entropy"] = metrics.entropy(P)
    out["uniform_estimate"] = (np.ptp(P, axis=1) < 1e-9).astype(float)
    return out


_temper = temper


def _combine(V, q, how):
    if how == "prior-once":
        return combine_posteriors(V, q)
    if how == "geometric":
        return geometric_pool(V, q)
    return product_of_posteriors(V)


def _load_tensor(partition: str, path: str | None):
    from qfg.composition import load, tensor

    return load(path, partition) if path else tensor(partition)


def run_dataset(path, *, robots=None, method: str = "full", mode: str = "honest",
                prior: str = "arena", combine: str = "geometric", partition: str = "edc",
                tensor=None, fix_landmarks: bool = True, seed=0, min_travel: float = 0.02,
                max_gap: float = 120.0, max_views: int = 0, propagate: bool = True,
                sigma_bearing_deg: float = 0.0, sigma_heading_deg: float = 0.0,
                temper: float = 1.0, spread_views: int = 3, return_details: bool = False,
                propagation: str = "mean", distances: bool = True,
                sigma_distance_ratio: float = 0.0, **solver_options):
    """Solve, combine, map, propagate and score one dataset directory.

    Args:
        path: an MRCLAM dataset directory.
        robots: robot numbers (None: all).
        method: single-triplet solver (``"fast"``, ``"full"``, ``"baseline"``); robots without
            odometry always get the baseline (the row's ``method``).
        mode: ``"honest"`` (measured inputs) or ``"paper"`` (inputs from motion capture).
        prior: ``"arena"`` or ``"world"`` (:func:`make_prior`).
        combine: ``"prior-once"`` or ``"product"`` (module docstring, step 5).
        tensor: composition tensor ((m, m, m) array or CompositionTensor); None: the shipped one.
        seed: solver seed (chunk c of :data:`CHUNK` histories gets child c of
            ``SeedSequence(seed)``).
        min_travel, max_gap, max_views: history options (module docstring, step 2).
        propagate: build the map and propagate (False: seen triplets and cameras only).
        propagation: ``"mean"`` (:func:`qfg.propagation.propagate_pooled`: every unseen triplet
            the mean of its compositions from the nearest updated triplets) or ``"best"`` (the
            paper's Algorithm 2, :func:`qfg.propagation.propagate`: the sharpest proposal).
        sigma_bearing_deg, sigma_heading_deg: noise the solver assumes, degrees (0: the loader's
            measured defaults, ``DEFAULT_SIGMA_BEARING`` / ``DEFAULT_SIGMA_HEADING``).
        temper: each history's estimate (C and cameras) tempered before anything else,
            :func:`qfg.combine.temper` with the prior's state distribution: ``p ∝ prior
            (p / prior)^temper`` (1: as solved). Chosen on a development dataset, never on the
            one reported (docs/results/mrclam.md).
        spread_views: keep this many views spread evenly over each pass (0: all).
        distances: the histories' odometry distances (between the kept views) go to the solver
            (``full``/``fast``: a factor on ratios of consecutive step lengths; default: the
            seen triplets of dataset 6 score -1.16 with them, -1.21 without,
            docs/results/mrclam.md); False solves without them.
        sigma_distance_ratio: noise of their log ratio the solver assumes (0: the loader's
            ``DEFAULT_SIGMA_DISTANCE_RATIO``).

    Returns:
        rows (list of dicts; module docstring). With ``return_details``: ``(rows, details)``.
    """
    from qfg.graph import full_map, truth_states
    from qfg.propagation import propagate as _propagate

    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    if combine not in COMBINE:
        raise ValueError(f"combine: expected one of {COMBINE}, got {combine!r}")
    part = get_partition(partition)
    ds, swaps = prepare(path, fix_landmarks=fix_landmarks)
    pr = make_prior(ds, prior)
    q_c = prior_state_distribution(pr, part, samples=PRIOR_SAMPLES, seed=1)
    q_x = prior_state_distribution(pr, part, point=1, n_cameras=1, samples=PRIOR_SAMPLES, seed=2)
    t0 = time.perf_counter()
    sig = {}
    if sigma_bearing_deg:
        sig["sigma_bearing"] = np.deg2rad(float(sigma_bearing_deg))
    if sigma_heading_deg:
        sig["sigma_heading"] = np.deg2rad(float(sigma_heading_deg))
    rh = histories(ds, robots, mode=mode, max_views=max_views, spread_views=spread_views,
                   partition=part,
                   min_travel=min_travel, max_gap=max_gap, **sig)
    hs = [h for _, h in rh]
    if not distances:
        hs = [dataclasses.replace(h, distances=None) for h in hs]
    elif sigma_distance_ratio:
        hs = [dataclasses.replace(h, sigma_distance_ratio=float(sigma_distance_ratio))
              for h in hs]
    ests = _solve(hs, method, part, seed, dict(solver_options, prior=pr))
    t_solve = time.perf_counter() - t0
    if temper != 1:
        ests = [_Light(_temper(e.landmark, q_c, temper), _temper(e.cameras, q_x, temper),
                       e.method, e.degenerate) for e in ests]

    groups: dict[tuple, list[int]] = {}
    for k, h in enumerate(hs):
        groups.setdefault(tuple(ds.landmark_index(h.landmarks).tolist()), []).append(k)
    combined = {t: _combine(np.array([ests[k].landmark for k in ks]), q_c, combine)
                for t, ks in groups.items()}

    ids = ds.landmark_ids
    swap_txt = ";".join(f"{a}-{b}" for a, b in swaps)
    common = {"dataset": ds.name, "path": str(Path(path)), "mode": mode, "prior": prior,
              "combine": combine, "temper": float(temper), "gt_swaps": swap_txt}
    t0 = time.perf_counter()
    if propagate:
        T = _load_tensor(part.name, None) if tensor is None else tensor
        g = full_map(ids.size, partition=part.name, tensor=T,
                     priors={t: c.probabilities for t, c in combined.items()})
        res = _propagate(g, rule=propagation)
        trip = np.array(g.triplets, dtype=np.intp)
        P = np.asarray(res.probabilities, dtype=float)
        seen = np.asarray(g.seen, dtype=bool)
        reached = np.asarray(res.info["reached"], dtype=bool)
    else:
        g = res = None
        trip = np.array(sorted(combined), dtype=np.intp).reshape(-1, 3)
        P = np.array([combined[tuple(t)].probabilities for t in trip.tolist()]).reshape(-1, part.n_states)
        seen = np.ones(len(trip), bool)
        reached = np.zeros(len(trip), bool)
    t_prop = time.perf_counter() - t0
    P = P / P.sum(axis=1, keepdims=True)
    truth = truth_states(trip, ds.landmark_xy, part.name) if len(trip) else np.zeros(0, int)
    sc = _score_rows(P, truth, q_c, part.centroids) if len(trip) else {}
    rows = []
    for v, t in enumerate(map(tuple, trip.tolist())):
        ks = groups.get(t, [])
        row = {**common, "kind": "seen" if seen[v] else "propagated",
               "A": int(ids[t[0]]), "B": int(ids[t[1]]), "C": int(ids[t[2]]),
               "truth_state": int(truth[v]), "map_state": int(np.argmax(P[v])),
               "n_histories": len(ks), "n_views": int(sum(hs[k].n_views for k in ks)),
               "robots": ";".join(str(r) for r in sorted({rh[k][0] for k in ks})),
               "method": ";".join(sorted({ests[k].method for k in ks})) if ks else "propagated",
               # share of the row's histories the solver flagged (degenerate geometry, low ESS)
               "flagged": float(np.mean([ests[k].degenerate for k in ks])) if ks else 0.0,
               "conflict": bool(combined[t].conflict) if t in combined else False,
               "reached": bool(reached[v])}
        for key, arr in sc.items():
            row[key] = float(arr[v])
        row["probabilities"] = _enc(P[v])
        rows.append(row)
    rows += _camera_rows(hs, rh, ests, q_x, part, common)
    if rows:
        rows[0]["time_solve_s"] = t_solve
        rows[0]["time_propagate_s"] = t_prop
    if not return_details:
        return rows
    return rows, {"dataset": ds, "swaps": swaps, "histories": rh, "estimates": ests, "graph": g,
                  "propagation": res, "partition": part, "prior": pr, "prior_states": q_c,
                  "prior_camera_states": q_x, "combined": combined}


def _camera_rows(hs, rh, ests, q, part, common) -> list[dict]:
    """One row per view covered by motion capture: P(S^{AB:X}_i | H) against the captured
    camera's state."""
    rows = []
    for k, h in enumerate(hs):
        cs = h.truth.camera_states
        if cs is None:
            continue
        ok = np.ones(h.n_views, bool) if h.groundtruth_valid is None else np.asarray(
            h.groundtruth_valid, bool)
        ok &= np.asarray(cs) >= 0
        idx = np.flatnonzero(ok)
        if idx.size == 0:
            continue
        Pc = np.asarray(ests[k].cameras, dtype=float)[idx]
        Pc = Pc / Pc.sum(axis=1, keepdims=True)
        g = np.asarray(cs)[idx].astype(int)
        sc = _score_rows(Pc, g, q, part.centroids)
        for j, i in enumerate(idx):
            row = {**common, "kind": "camera", "A": int(h.landmarks[0]), "B": int(h.landmarks[1]),
                   "C": int(h.landmarks[2]), "robot": int(rh[k][0]), "history": k,
                   "view": int(i), "time": float(h.views[i]), "n_views": int(h.n_views),
                   "truth_state": int(g[j]), "map_state": int(np.argmax(Pc[j])),
                   "method": ests[k].method, "flagged": float(ests[k].degenerate)}
            for key, arr in sc.items():
                row[key] = float(arr[j])
            row["probabilities"] = _enc(Pc[j])
            rows.append(row)
    return rows


# ----------------------------------------------------------------------------- summaries
def _mean(rows, key) -> float:
    v = [float(r[key]) for r in rows if r.get(key) not in (None, "")]
    return float(np.mean(v)) if v else float("nan")


def kind_summary(rows: list[dict]) -> dict:
    """Scores of rows of one kind: ``n``; mean log score, Brier, GT rating, truth-under-1% rate
    of the estimate and of both baselines (``uniform_*``, ``prior_*``); flagged and uniform
    estimates; median DMSE; expected calibration error (top state)."""
    out: dict = {"n": len(rows)}
    for pre in ("", "uniform_", "prior_"):
        for k in ("log_score", "brier", "gt_rating", "truth_under_1pct"):
            out[f"{pre}{k}"] = _mean(rows, f"{pre}{k}")
    out["flagged"] = _mean(rows, "flagged")
    out["uniform_estimate"] = _mean(rows, "uniform_estimate")
    out["dmse_median"] = float(np.median([float(r["dmse"]) for r in rows])) if rows else float("nan")
    if rows:
        P = np.array([decode(r["probabilities"]) for r in rows])
        g = np.array([int(r["truth_state"]) for r in rows])
        out["ece"] = metrics.expected_calibration_error(P, g)
    else:
        out["ece"] = float("nan")
    return out


def summary(rows: list[dict]) -> dict:
    """``{mode: {kind: kind_summary}}`` plus counts: seen triplets whose histories conflict,
    propagated triplets reached, baseline-solved seen triplets."""
    out: dict = {"n_rows": len(rows)}
    for mode in sorted({r["mode"] for r in rows}):
        sel = [r for r in rows if r["mode"] == mode]
        d = {kind: kind_summary([r for r in sel if r["kind"] == kind]) for kind in KINDS}
        d["n_conflict"] = int(sum(str(r.get("conflict")) == "True" for r in sel
                                  if r["kind"] == "seen"))
        d["n_reached"] = int(sum(str(r.get("reached")) == "True" for r in sel
                                 if r["kind"] == "propagated"))
        d["n_baseline"] = int(sum("baseline" in str(r["method"]) for r in sel
                                  if r["kind"] == "seen"))
        out[mode] = d
    out["gt_swaps"] = sorted({r["gt_swaps"] for r in rows if r.get("gt_swaps")})
    return out


def _fmt(x, d=2) -> str:
    return "nan" if x is None or not np.isfinite(x) else f"{x:.{d}f}"


def table_lines(summ: dict) -> list[str]:
    """Markdown rows: per dataset, mode and kind, each score as estimate / uniform / prior."""
    lines = ["| dataset | mode | kind | n | log score | Brier | GT rating | truth < 1% | flagged | "
             "uniform est. | ECE |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    names = list(summ.get("datasets", {})) + ["all"]
    for name in names:
        s = summ if name == "all" else summ["datasets"][name]
        for mode in MODES:
            if mode not in s:
                continue
            for kind in KINDS:
                k = s[mode][kind]
                if not k["n"]:
                    continue
                trio = [" / ".join(_fmt(k[f"{p}{key}"], 3 if key == "brier" else 2)
                                   for p in ("", "uniform_", "prior_"))
                        for key in ("log_score", "brier", "gt_rating", "truth_under_1pct")]
                lines.append(f"| {name} | {mode} | {kind} | {k['n']} | " + " | ".join(trio)
                             + f" | {_fmt(k['flagged'])} | {_fmt(k['uniform_estimate'])} | "
                             f"{_fmt(k['ece'])} |")
    return lines


def write_outputs(outdir, rows: list[dict], *, figures: bool = True, figure_robot=None,
                  details=None) -> dict:
    """``triplets.csv`` (seen and propagated rows), ``cameras.csv`` (camera rows, when any),
    ``summary.json``, ``table.md`` and figures; returns the summary dict."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    trip = [r for r in rows if r["kind"] != "camera"]
    cams = [r for r in rows if r["kind"] == "camera"]
    write_table(out / "triplets.csv", trip, digits=None)
    if cams:
        write_table(out / "cameras.csv", cams, digits=None)
    names = list(dict.fromkeys(r["dataset"] for r in rows))
    summ = summary(rows)
    summ["datasets"] = {n: summary([r for r in rows if r["dataset"] == n]) for n in names}
    (out / "summary.json").write_text(json.dumps(summ, indent=2) + "\n")
    (out / "table.md").write_text("\n".join(table_lines(summ)) + "\n")
    if figures and rows:
        make_figures(out, rows, details=details, robot=figure_robot)
    return summ


# ----------------------------------------------------------------------------- figures
def make_figures(outdir: Path, rows: list[dict], *, details=None, robot=None) -> list[Path]:
    """Reliability (calibration) figures of each mode's seen, propagated and camera rows, and
    one robot's path with the views of the seen triplet with most views (first dataset)."""
    from qfg.harness.plotting_mrclam import reliability_figure

    paths = []
    for mode in sorted({r["mode"] for r in rows}):
        groups = {}
        for kind in KINDS:
            sel = [r for r in rows if r["mode"] == mode and r["kind"] == kind]
            if sel:
                groups[kind] = (np.array([decode(r["probabilities"]) for r in sel]),
                                np.array([int(r["truth_state"]) for r in sel]))
        if groups:
            fig = reliability_figure(groups, title=f"{mode} mode: reliability")
            paths.append(save_figure(fig, outdir, f"reliability_{mode}"))
    paths += _path_figure(outdir, rows, details, robot)
    return paths


def _path_figure(outdir, rows, details, robot):
    from qfg.harness.plotting_mrclam import dataset_figure

    seen = [r for r in rows if r["kind"] == "seen" and r["mode"] == rows[0]["mode"]
            and r["dataset"] == rows[0]["dataset"]
            and (robot is None or str(robot) in str(r["robots"]).split(";"))]
    if not seen:
        return []
    row = max(seen, key=lambda r: (int(r["n_views"]), -int(r["A"]), -int(r["B"]), -int(r["C"])))
    if details is not None:
        ds = details["dataset"]
    else:
        ds, _ = prepare(row["path"], fix_landmarks=bool(row["gt_swaps"]))
    r = int(str(row["robots"]).split(";")[0]) if robot is None else int(robot)
    trip = (int(row["A"]), int(row["B"]), int(row["C"]))
    hs = [h for h in _mrclam.triplet_histories(ds, r, min_travel=0.02) if tuple(h.landmarks) == trip]
    h = max(hs, key=lambda x: x.n_views) if hs else None
    figdir = Path(outdir) / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    p = figdir / f"{ds.name}_robot{r}.{figure_format()}"
    return [Path(dataset_figure(ds, r, p, history=h))]


# ----------------------------------------------------------------------------- views curve
def views_curve(path, caps=(3, 5, 8, 13, 0), **options) -> list[dict]:
    """Seen-triplet scores against the views kept per pass: for each cap n (0: all), every pass
    truncated to its first n views, solved, combined and scored (no propagation). Returns one
    dict per (cap, mode, kind) with the :func:`kind_summary` entries and ``max_views``."""
    out = []
    for n in caps:
        rows = run_dataset(path, max_views=int(n), propagate=False, **options)
        for mode, d in summary(rows).items():
            if mode not in MODES:
                continue
            for kind in ("seen", "camera"):
                if d[kind]["n"]:
                    views = [int(r["n_views"]) / max(int(r.get("n_histories") or 1), 1)
                             for r in rows if r["kind"] == kind]
                    out.append({"dataset": rows[0]["dataset"], "max_views": int(n), "mode": mode,
                                "kind": kind, "views_median": float(np.median(views)),
                                **d[kind]})
    return out


def temper_scores(details, taus=(1.0, 0.5, 0.3, 0.2, 0.1, 0.05, 0.0), combine="prior-once"):
    """Mean scores of the seen triplets of one solved dataset (``run_dataset(...,
    return_details=True)`` with ``temper=1``) for each tempering exponent, without solving again:
    each history's estimate tempered, the histories of each ordered triplet combined, scored
    against the landmark ground truth. Returns a list of dicts (``temper``, ``n``, ``log_score``,
    ``brier``, ``truth_under_1pct``)."""
    ds, part, q = details["dataset"], details["partition"], details["prior_states"]
    from qfg.graph import truth_states

    hs = [h for _, h in details["histories"]]
    L = np.array([e.landmark for e in details["estimates"]])
    groups: dict[tuple, list[int]] = {}
    for k, h in enumerate(hs):
        groups.setdefault(tuple(ds.landmark_index(h.landmarks).tolist()), []).append(k)
    trip = np.array(sorted(groups), dtype=np.intp).reshape(-1, 3)
    g = truth_states(trip, ds.landmark_xy, part.name)
    out = []
    for tau in taus:
        Lt = temper(L, q, tau)
        P = np.array([_combine(Lt[groups[tuple(t)]], q, combine).probabilities
                      for t in trip.tolist()])
        out.append({"temper": float(tau), "n": int(len(trip)),
                    "log_score": float(metrics.log_score(P, g).mean()),
                    "brier": float(metrics.brier(P, g).mean()),
                    "truth_under_1pct": float(metrics.truth_under(P, g, 0.01).mean())})
    return out


def curve_lines(recs: list[dict]) -> list[str]:
    """Markdown rows of :func:`views_curve` records."""
    lines = ["| dataset | mode | kind | views per pass (cap) | median views | n | log score | "
             "Brier | GT rating | truth < 1% | flagged |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in recs:
        lines.append(f"| {r['dataset']} | {r['mode']} | {r['kind']} | "
                     f"{r['max_views'] or 'all'} | {r['views_median']:g} | {r['n']} | "
                     f"{_fmt(r['log_score'])} | {_fmt(r['brier'], 3)} | {_fmt(r['gt_rating'])} | "
                     f"{_fmt(r['truth_under_1pct'])} | {_fmt(r['flagged'])} |")
    return lines


def write_curve(outdir, recs: list[dict], *, figures: bool = True) -> None:
    """``curve.csv``, ``curve.md`` and (``figures``) ``figures/views_curve.<format>``."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    write_table(out / "curve.csv", recs, digits=None)
    (out / "curve.md").write_text("\n".join(curve_lines(recs)) + "\n")
    if figures and recs:
        from qfg.harness.plotting_mrclam import curve_figure

        save_figure(curve_figure(recs), out, "views_curve")


# ----------------------------------------------------------------------------- runner study
def _params(params: dict) -> dict:
    unknown = set(params) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"params: unknown keys {sorted(unknown)}; known: {sorted(DEFAULTS)}")
    p = {**DEFAULTS, **params}
    for key, allowed in (("method", METHODS), ("combine", COMBINE), ("mode", MODES),
                         ("propagation", ("mean", "best")),
                         ("prior", PRIORS)):
        if p[key] not in allowed:
            raise ValueError(f"{key}: expected one of {allowed}, got {p[key]!r}")
    return p


def dataset_dirs(data, numbers=()) -> list[Path]:
    """``MRCLAM_Dataset<N>`` directories under ``data`` (only ``numbers`` if given), by N. An empty
    ``data`` means the directory named by ``$QFG_MRCLAM_DIR`` (:func:`qfg.datasets.mrclam.data_root`)."""
    root = _mrclam.data_root(data or None)
    if not root.is_dir():
        raise ValueError(f"data: {root} is not a directory")
    found = {}
    for d in root.iterdir():
        if d.is_dir() and d.name.startswith("MRCLAM_Dataset") and d.name[14:].isdigit():
            found[int(d.name[14:])] = d
    want = [int(n) for n in numbers] if numbers else sorted(found)
    missing = [n for n in want if n not in found]
    if missing:
        raise ValueError(f"datasets: {missing} not found under {root} (has {sorted(found)})")
    return [found[n] for n in want]


_TASK_KEYS = ("method", "mode", "prior", "combine", "partition", "fix_landmarks", "tensor",
              "min_travel", "max_gap", "max_views", "propagate", "sigma_bearing_deg",
              "sigma_heading_deg", "temper", "spread_views", "propagation", "distances",
              "sigma_distance_ratio")


def tasks(params: dict) -> list[dict]:
    """One task per dataset directory."""
    p = _params(params)
    return [{"index": i, "path": str(d), "robots": list(p["robots"]),
             **{k: p[k] for k in _TASK_KEYS}}
            for i, d in enumerate(dataset_dirs(p["data"], p["datasets"]))]


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    T = _load_tensor(task["partition"], task["tensor"] or None) if task["propagate"] else None
    opts = {k: task[k] for k in _TASK_KEYS if k not in ("tensor",)}
    return run_dataset(task["path"], robots=task["robots"] or None, tensor=T,
                       seed=int(rng.integers(2**63)), **opts)


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    print("\n".join(table_lines(write_outputs(outdir, rows))))


STUDY = Study(name="mrclam", tasks=tasks, run_task=run_task, summarize=summarize,
              description="MRCLAM datasets: triplet estimates, full map, propagation (paper 6d), "
                          "scored with log score, Brier and both baselines",
              params=param_spec(DEFAULTS, method={"choices": METHODS},
                                combine={"choices": COMBINE}, mode={"choices": MODES},
                                prior={"choices": PRIORS}, partition={"choices": ("edc",)}))

__all__ = ["run_dataset", "summary", "kind_summary", "write_outputs", "make_figures",
           "dataset_dirs", "tasks", "run_task", "summarize", "STUDY", "DEFAULTS", "prepare",
           "histories", "table_lines", "arena_extent", "make_prior", "paper_history", "truncate",
           "views_curve", "decode", "curve_lines", "write_curve", "temper_scores"]
