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
from qfg.configurations import PositionSummary, summarize_position
from qfg.datasets import mrclam as _mrclam
from qfg.harness.runner import Study, figure_format, param_spec, save_figure, write_table
from qfg.partitions import get as get_partition
from qfg.priors import WorldBoxPrior
from qfg.priors import get as get_prior

COMBINE = ("prior-once", "geometric", "product")
#: single-triplet solvers; ``"none"``: no solver, every history's estimate the prior alone (for
#: map methods that work from the raw measurements, e.g. ``--map joint``)
METHODS = ("fast", "full", "baseline", "none")
MODES = ("honest", "paper")
PRIORS = ("arena", "world", "arena-logscale")
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
    "map": "",                             # map method by name (mrclam_maps; "": from the two
                                           # above: "seen", "pooled" or "best")
    "sigma_bearing_deg": 0.0,              # bearing sigma the solver assumes (0: loader default)
    "sigma_heading_deg": 0.0,              # heading sigma the solver assumes (0: loader default)
    "temper": 1.0,                         # power on each estimate's likelihood part (1: none)
    "spread_views": 3,                     # views spread over each pass (0: all)
    "distances": True,                     # odometry's travelled distances in the motion model
                                           # (off: no gain on dataset 6, docs/mrclam.md)
    "sigma_distance_ratio": 0.0,           # their log-ratio noise (0: loader default, 0.074)
    "bearing_tail": "normal",              # bearing-noise model (BEARING_TAILS)
    "model_check": 0.0,                    # level of the solvers' model check (0: report only)
    "heading_drift": False,                # heading sigma from each history's longest step
    "distance_tail": "normal",             # step-length-ratio noise model (DISTANCE_TAILS)
    "heading_walk": 0.0,                   # per-step heading sigma b sqrt(step duration), b in
                                           # deg / sqrt(s) (0: off; HEADING_WALK measured)
    "heading_tail": "normal",              # "measured": the headings' two-normal tail
                                           # (HEADING_WALK_TAIL), for the solvers
    "budget": 1.0,                         # the full/fast solvers' budget (n_samples,
                                           # max_hypotheses, posterior_samples) times this
    "bearing_calibration": "none",         # "measured": each robot's bearing bias and scale
                                           # measured on dataset 6 undone first (every dataset)
    "camera_prior": "point",               # the solvers' camera_prior ("joint": the cameras'
                                           # joint prior in the intermediate weights)
    "populations": 1,                      # the full/fast solvers' independent SIS
                                           # populations (their populations option)
}

#: Bearing calibrations of ``--bearing-calibration``: none, or each robot's bias and scale
#: measured against motion capture on dataset 6 (:mod:`qfg.datasets.mrclam._calibration`).
BEARING_CALIBRATIONS = ("none", "measured")

#: Options added after runs were recorded without them: a run's params leave them out at their
#: defaults, so that those runs resume (``qfg mrclam --resume``) as before.
LATER_KEYS = ("bearing_tail", "model_check", "heading_drift", "distance_tail", "heading_walk",
              "heading_tail", "camera_prior", "budget", "populations", "bearing_calibration")


#: The odometry's direction-of-travel error (``sigma90``, degrees) against motion capture by the
#: step's duration (centre of the measured bins 3-10 s, 10-30 s, 30-100 s; dataset 6,
#: docs/mrclam.md "From views to triplet histories"): the odometry's heading drifts over a step.
HEADING_SIGMA_BY_STEP = ((6.5, 1.59), (20.0, 5.04), (65.0, 9.76))


#: The odometry's heading as a random walk: the direction of travel of a step of duration dt
#: seconds is off by about ``HEADING_WALK sqrt(dt)`` degrees. Maximum-likelihood fit of ``b
#: sqrt(dt)`` (a constant term fitted to 0) to 2,802 steps of dataset 6's histories (robots 1-5,
#: 120-s passes, 2, 3, 5 and 8 views spread over each, steps of 2 cm or more) against motion
#: capture; per step it scores 0.2-0.4 nats above one sigma per history from the longest step,
#: and the loader's 1.57 deg 7-51 nats below (docs/mrclam.md, "The odometry's heading over a
#: step"; ``experiments/mrclam_heading_steps.py``).
HEADING_WALK = 1.21
#: The same walk with the solvers' two-normal tail (``heading_tail``), fitted the same way:
#: (b in deg / sqrt(s), (share, scale)); ``--heading-walk measured-tail``.
HEADING_WALK_TAIL = (0.85, (0.046, 4.84))


def walk_sigma_heading(h, sigma_heading: float, walk: float) -> np.ndarray:
    """(n - 1,) each step's heading sigma (radians) for history ``h`` with ``heading_walk``
    ``walk`` (degrees per sqrt(second)): ``walk sqrt(dt)`` for a step of ``dt`` seconds (``h.
    views`` are the view times), never below ``sigma_heading``.

    >>> import types
    >>> h = types.SimpleNamespace(views=np.array([0.0, 4.0, 29.0]))
    >>> np.degrees(walk_sigma_heading(h, np.deg2rad(1.57), 1.0)).round(2).tolist()
    [2.0, 5.0]
    """
    dt = np.diff(np.asarray(h.views, dtype=float))
    return np.maximum(float(sigma_heading), np.deg2rad(float(walk)) * np.sqrt(np.maximum(dt, 0.0)))


def drift_sigma_heading(h, sigma_heading: float) -> float:
    """The heading sigma (radians) for history ``h`` with ``heading_drift``: the measured
    ``sigma90`` of a step as long as the history's longest step, interpolated linearly in the
    duration over :data:`HEADING_SIGMA_BY_STEP` (constant beyond its ends), never below
    ``sigma_heading``. One value per history: the solvers take one heading sigma per triplet.

    >>> import types
    >>> h = types.SimpleNamespace(views=np.array([0.0, 5.0, 25.0]))
    >>> round(float(np.degrees(drift_sigma_heading(h, np.deg2rad(1.57)))), 3)
    5.04
    """
    if len(h.views) < 2:
        return float(sigma_heading)
    t, sg = np.array(HEADING_SIGMA_BY_STEP).T
    dt = float(np.max(np.diff(np.asarray(h.views, dtype=float))))
    return float(max(sigma_heading, np.deg2rad(np.interp(dt, t, sg))))


#: Bearing-noise models for the solvers, by name: (bearing sigma in degrees, heading sigma in
#: degrees, (share, scale, outlier) of :class:`qfg.solvers._likelihood.BearingTail`); None: the
#: loader's. Fitted by EM to dataset 6's bearing residuals against motion capture
#: (docs/mrclam.md, "A heavy-tailed bearing model"): ``measured`` per landmark row;
#: ``within-view`` to the residuals minus their image's mean (a per-image offset shared by A, B
#: and C is absorbed by the camera heading, so only the motion headings see it: their sigma
#: grows to hypot(1.57, 0.58) deg).
BEARING_TAILS = {
    "normal": (None, None, None),
    "measured": (0.345, None, (0.271, 2.79, 0.0011)),
    "within-view": (0.166, 1.67, (0.425, 2.74, 0.0014)),
}


#: Noise models of the log ratio of consecutive odometry step lengths, by name: (sigma of the
#: core normal, (share, scale) of the wider normal, the solvers' ``distance_tail``); None: the
#: loader's normal (``sigma_distance_ratio`` 0.074). ``measured``: fitted by EM (two zero-mean
#: normals) to 1,791 ratios of dataset 6's histories (robots 1-5, 120-s passes, 3, 5 and 8 views
#: spread over each, steps of 2 cm or more) against motion capture, where the loader's normal
#: scores 3.1 nats per ratio below the mixture (docs/mrclam.md, "The odometry's step-length
#: ratios"; ``experiments/mrclam_distance_ratios.py``).
DISTANCE_TAILS = {
    "normal": (None, None),
    "measured": (0.092, (0.088, 7.2)),
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
    stays 0.01 m); ``"arena-logscale"``: the same box with every scale of the pair AB equally
    likely (``scale_power=-2``: landmarks that stand in clusters, docs/results/mrclam.md);
    ``"world"``: the simulator's box (:func:`qfg.priors.get`)."""
    if name not in PRIORS:
        raise ValueError(f"prior: expected one of {PRIORS}, got {name!r}")
    if name == "world":
        return get_prior("world")
    e = arena_extent(ds)
    return WorldBoxPrior(width=e["width"], height=e["height"],
                         scale_power=-2 if name == "arena-logscale" else 0)


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
    model_check: float = float("nan")
    # C's AB-frame position (qfg.configurations.PositionSummary), kept for the histories whose
    # landmarks are in ascending order (one ordering per set and pass: the metric configuration
    # map's evidence); None for the others and for runs recorded before summaries were kept
    position: object = None


# ----------------------------------------------------------------------------- the pipeline
# run_dataset and ``qfg mrclam`` run the same phases: prepare_run (load, prior, histories),
# solve_piece for each piece of PIECE histories (``qfg mrclam`` records each piece as it
# finishes), then finish: temper, combine, map (a named method, mrclam_maps), score.

#: The options that fix the solved estimates (what a piece record depends on).
SOLVE_KEYS = ("path", "robots", "method", "mode", "prior", "partition", "fix_landmarks",
              "min_travel", "max_gap", "max_views", "spread_views", "sigma_bearing_deg",
              "sigma_heading_deg", "distances", "sigma_distance_ratio", "bearing_tail",
              "model_check", "heading_drift", "distance_tail", "heading_walk", "heading_tail",
              "camera_prior", "budget", "populations", "bearing_calibration", "piece")


@dataclass(frozen=True, eq=False)
class Prepared:
    """One dataset ready to solve: what :func:`prepare_run` made.

    ``histories``: (robot, history) pairs in solving order (robot-major); piece c of a run is
    histories ``[c * piece, (c + 1) * piece)``, solved with ``SeedSequence(seed,
    spawn_key=(c,))``. ``prior_states`` / ``prior_camera_states``: the state distributions of C
    and of a camera the prior alone gives (the ``prior_`` baselines, and tempering).
    """

    path: str
    dataset: object
    swaps: tuple
    prior: object
    partition: object
    prior_states: np.ndarray
    prior_camera_states: np.ndarray
    histories: list
    mode: str
    prior_name: str
    solver_options: dict = dataclasses.field(default_factory=dict)


def prepare_run(path, *, robots=None, mode: str = "honest", prior: str = "arena",
                partition: str = "edc", fix_landmarks: bool = True, min_travel: float = 0.02,
                max_gap: float = 120.0, max_views: int = 0, spread_views: int = 3,
                sigma_bearing_deg: float = 0.0, sigma_heading_deg: float = 0.0,
                distances: bool = True, sigma_distance_ratio: float = 0.0,
                bearing_tail: str = "normal", model_check: float = 0.0,
                heading_drift: bool = False, distance_tail: str = "normal",
                heading_walk: float = 0.0, heading_tail: str = "normal",
                camera_prior: str = "point", budget: float = 1.0, populations: int = 1,
                bearing_calibration: str = "none", dataset=None) -> Prepared:
    """Load (or take ``dataset``, loaded from ``path``), fix the landmark ground truth, make the
    prior and its state distributions, and the histories to solve (module docstring, steps
    1-4). Every data file is read and checked here, before anything is solved."""
    if mode not in MODES:
        raise ValueError(f"mode: expected one of {MODES}, got {mode!r}")
    part = get_partition(partition)
    if dataset is None:
        ds, swaps = prepare(path, fix_landmarks=fix_landmarks)
    else:
        swaps = tuple(tuple(int(x) for x in s) for s in
                      (_mrclam.check_landmarks(dataset).swaps if fix_landmarks else ()))
        ds = _mrclam.swap_landmarks(dataset, swaps) if swaps else dataset
    if bearing_calibration not in BEARING_CALIBRATIONS:
        raise ValueError(f"bearing_calibration: expected one of {BEARING_CALIBRATIONS}, got "
                         f"{bearing_calibration!r}")
    if bearing_calibration == "measured":
        ds = _mrclam.calibrate_bearings(ds, _mrclam.DEFAULT_BEARING_CALIBRATION)
    pr = make_prior(ds, prior)
    q_c = prior_state_distribution(pr, part, samples=PRIOR_SAMPLES, seed=1)
    q_x = prior_state_distribution(pr, part, point=1, n_cameras=1, samples=PRIOR_SAMPLES, seed=2)
    if bearing_tail not in BEARING_TAILS:
        raise ValueError(f"bearing_tail: expected one of {tuple(BEARING_TAILS)}, "
                         f"got {bearing_tail!r}")
    tail_sb, tail_sh, tail = BEARING_TAILS[bearing_tail]
    if distance_tail not in DISTANCE_TAILS:
        raise ValueError(f"distance_tail: expected one of {tuple(DISTANCE_TAILS)}, "
                         f"got {distance_tail!r}")
    tail_sd, dtail = DISTANCE_TAILS[distance_tail]
    if heading_tail not in ("normal", "measured"):
        raise ValueError(f"heading_tail: expected 'normal' or 'measured', got {heading_tail!r}")
    htail = HEADING_WALK_TAIL[1] if heading_tail == "measured" else None
    from qfg.solvers.common.options import CAMERA_PRIORS, scaled_budget

    if camera_prior not in CAMERA_PRIORS:
        raise ValueError(f"camera_prior: expected one of {CAMERA_PRIORS}, got {camera_prior!r}")
    scaled_budget("full", budget)   # checks the factor here, before anything is solved
    if isinstance(populations, bool) or int(populations) != populations or populations < 1:
        raise ValueError(f"populations: expected a whole number >= 1, got {populations!r}")
    budget = float(budget)
    sigma_distance_ratio = sigma_distance_ratio or tail_sd
    sig = {}
    if tail_sb and not sigma_bearing_deg:
        sig["sigma_bearing"] = np.deg2rad(tail_sb)
    if tail_sh and not sigma_heading_deg:
        sig["sigma_heading"] = np.deg2rad(tail_sh)
    if sigma_bearing_deg:
        sig["sigma_bearing"] = np.deg2rad(float(sigma_bearing_deg))
    if sigma_heading_deg:
        sig["sigma_heading"] = np.deg2rad(float(sigma_heading_deg))
    rh = histories(ds, robots, mode=mode, max_views=max_views, spread_views=spread_views,
                   partition=part, min_travel=min_travel, max_gap=max_gap, **sig)
    if heading_drift and heading_walk:
        raise ValueError("heading_walk: one heading model at a time (heading_drift is on)")
    if heading_drift:
        rh = [(r, dataclasses.replace(h, sigma_heading=drift_sigma_heading(h, h.sigma_heading))
               if h.has_motion else h) for r, h in rh]
    if heading_walk:
        rh = [(r, dataclasses.replace(h, sigma_heading=walk_sigma_heading(
            h, h.sigma_heading, heading_walk)) if h.has_motion and h.n_views > 1 else h)
              for r, h in rh]
    if not distances:
        rh = [(r, dataclasses.replace(h, distances=None)) for r, h in rh]
    elif sigma_distance_ratio:
        rh = [(r, dataclasses.replace(h, sigma_distance_ratio=float(sigma_distance_ratio)))
              for r, h in rh]
    return Prepared(path=str(Path(path)), dataset=ds, swaps=swaps, prior=pr, partition=part,
                    prior_states=q_c, prior_camera_states=q_x, histories=rh, mode=mode,
                    prior_name=prior,
                    solver_options={"bearing_tail": tail, "model_check": float(model_check),
                                    "distance_tail": dtail if distances else None,
                                    "heading_tail": htail,
                                    # only where set: runs without it solve as before
                                    "camera_prior": None if camera_prior == "point"
                                    else camera_prior,
                                    # a factor, turned into the solver's options in solve_piece
                                    "budget": None if budget == 1.0 else budget,
                                    "populations": None if populations == 1
                                    else int(populations)})


def n_pieces(prep: Prepared, piece: int = CHUNK) -> int:
    """How many pieces of ``piece`` histories the run has."""
    return -(-len(prep.histories) // int(piece))


def solve_piece(prep: Prepared, index: int, *, method: str = "full", seed=0, piece: int = CHUNK,
                **solver_options) -> list[_Light]:
    """Solve piece ``index`` (histories ``[index * piece, (index + 1) * piece)``) with the
    random stream ``SeedSequence(seed, spawn_key=(index,))`` (= child ``index`` of
    ``SeedSequence(seed)``): the same numbers whether pieces are solved in one go, one by one,
    or some of them again after an interruption. Only the (m,) vectors are kept (an estimate
    may keep solver state; dataset 5 in one call once exhausted 24 GB)."""
    from qfg.solvers import solve_triplets

    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    hs = [h for _, h in prep.histories[index * piece:(index + 1) * piece]]
    if method == "none":
        return [_Light(prep.prior_states.copy(), np.tile(prep.prior_camera_states, (h.n_views, 1)),
                       "none", False) for h in hs]
    ss = np.random.SeedSequence(int(seed), spawn_key=(int(index),))
    # the run's noise model and check (prepare_run), only where set: the solvers' defaults
    # otherwise (the baseline takes no model check)
    opts = {k: v for k, v in prep.solver_options.items() if v}
    budget = opts.pop("budget", None)
    if budget is not None:
        from qfg.solvers.common.options import scaled_budget

        opts.update(scaled_budget(method, budget))
    if method == "baseline":
        # no model check, and no odometry distances in its model
        opts.pop("model_check", None)
        opts.pop("distance_tail", None)
        opts.pop("heading_tail", None)
        opts.pop("camera_prior", None)
        opts.pop("populations", None)
    pairs = solve_triplets(hs, method=method, partition=prep.partition, seed=ss,
                           hypotheses=True, **dict(opts, **solver_options, prior=prep.prior))
    out = []
    for k, (h, (e, hyp)) in enumerate(zip(hs, pairs, strict=True)):
        pos = None
        if hyp is not None and _ascending(h.landmarks):
            pos = summarize_position(hyp, e.landmark, prep.prior, partition=prep.partition.name,
                                     seed=np.random.SeedSequence(int(seed),
                                                                 spawn_key=(int(index), k, 1)))
        out.append(_Light(e.landmark, e.cameras, e.method, bool(e.degenerate),
                          float(getattr(e, "model_check", float("nan"))), pos))
    return out


def _ascending(landmarks) -> bool:
    """Whether a history's landmarks are in ascending order (its set's first ordering)."""
    a, b, c = (int(x) for x in landmarks)
    return a < b < c


def _exact(p) -> str:
    """A vector as text that reads back to the same floats (``repr``: shortest exact)."""
    return ";".join(repr(float(x)) for x in np.ravel(p))


def _unexact(text: str, shape=None) -> np.ndarray:
    a = np.array([float(x) for x in str(text).split(";")]) if text else np.zeros(0)
    return a.reshape(shape) if shape is not None else a


def piece_rows(prep: Prepared, index: int, ests: list[_Light], piece: int = CHUNK) -> list[dict]:
    """The record of a solved piece: one row per history with its estimates written exactly
    (``landmark``: P(S^{AB:C} | H), m numbers; ``cameras``: the views' camera states, n_views x m,
    kept only when the capture gives them a truth to be scored against)."""
    rows = []
    for k, e in enumerate(ests):
        hk = index * piece + k
        r, h = prep.histories[hk]
        cams = h.truth.camera_states is not None
        rows.append({"history": hk, "robot": int(r), "A": int(h.landmarks[0]),
                     "B": int(h.landmarks[1]), "C": int(h.landmarks[2]),
                     "n_views": int(h.n_views), "method": e.method, "degenerate": e.degenerate,
                     "model_check": repr(float(e.model_check)),
                     "landmark": _exact(e.landmark),
                     "cameras": _exact(e.cameras) if cams else "",
                     "position": (json.dumps(e.position.to_dict()) if e.position is not None
                                  else "")})
    return rows


def estimates_from_rows(prep: Prepared, rows: list[dict]) -> list[_Light]:
    """The solved estimates of every history back from piece records (:func:`piece_rows`);
    ValueError when the records do not cover the run's histories one by one."""
    by = {int(r["history"]): r for r in rows}
    n = len(prep.histories)
    if sorted(by) != list(range(n)):
        raise ValueError(f"records: {len(by)} solved histories recorded, the data give {n}: "
                         "the data changed since the run was recorded; pass --overwrite")
    m = prep.partition.n_states
    out = []
    for k in range(n):
        r = by[k]
        h = prep.histories[k][1]
        if (int(r["A"]), int(r["B"]), int(r["C"])) != tuple(int(x) for x in h.landmarks):
            raise ValueError(f"records: history {k} is of another triplet than the data give: "
                             "the data changed since the run was recorded; pass --overwrite")
        cams = (_unexact(r["cameras"], (h.n_views, m)) if r.get("cameras")
                else np.full((h.n_views, m), 1.0 / m))
        pos = r.get("position") or ""
        out.append(_Light(_unexact(r["landmark"]), cams, str(r["method"]),
                          str(r["degenerate"]) == "True" or r["degenerate"] is True,
                          float(r.get("model_check", "nan")),
                          PositionSummary.from_dict(json.loads(pos)) if pos else None))
    return out


def _solver_of(ests) -> str:
    names = sorted({e.method for e in ests})
    return "none" if names == ["none"] else ",".join(n for n in names if n != "none")


#: Tempering powers the cross-pass check chooses from (``temper="auto"``), largest first.
AUTO_TEMPERS = (1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1)


def _history_groups(prep: Prepared) -> dict:
    """{ordered triplet (landmark indices): [history index, ...]}."""
    ds = prep.dataset
    groups: dict[tuple, list[int]] = {}
    for k, (_, h) in enumerate(prep.histories):
        groups.setdefault(tuple(ds.landmark_index(h.landmarks).tolist()), []).append(k)
    return groups


def _history_pairs(groups: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(first, second, cluster index) of every pair of histories of one group; a cluster is an
    unordered landmark set (its orderings' histories share their measurements)."""
    pairs, keys = [], []
    for g, ks in groups.items():
        for i, a in enumerate(ks):
            for b in ks[i + 1:]:
                pairs.append((a, b))
                keys.append(tuple(sorted(g)))
    if not pairs:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty, empty
    a, b = np.array(pairs).T
    return a, b, np.unique(np.array(keys), axis=0, return_inverse=True)[1].ravel()


def _pair_agreements(P, a, b, q, tau: float) -> np.ndarray:
    """Per pair (a, b) of histories: ``log sum_s t_a t_b / q``, t tempered by ``tau``."""
    T = temper(np.asarray(P, dtype=float), q, tau)
    return np.log(np.sum(T[a] * T[b] / q, axis=1))


def cross_pass_agreement(P, groups: dict, q, tau: float) -> tuple[float, int]:
    """How well the histories of one ordered triplet (separate passes, other robots) predict
    each other once tempered by ``tau``: the mean over pairs (i, j) of histories of one group of

        log sum_s t_i(s) t_j(s) / q(s),   t = temper(p, q, tau),

    which is log P(D_j | D_i) / P(D_j) when the two passes are independent given the state and
    the tempered estimates are their posteriors (q the prior's state distribution). No ground
    truth enters. ``P`` (H, m) the histories' estimates; returns (mean, number of pairs); (0, 0)
    without a group of two.

    >>> q = np.full(4, 0.25)
    >>> P = np.array([[0.97, 0.01, 0.01, 0.01], [0.01, 0.97, 0.01, 0.01]])
    >>> a1, n = cross_pass_agreement(P, {(0, 1, 2): [0, 1]}, q, 1.0)
    >>> a0, _ = cross_pass_agreement(P, {(0, 1, 2): [0, 1]}, q, 0.0)
    >>> n, round(a1, 3), round(a0, 3)      # confident and contradicting: worse than the prior
    (1, -2.546, 0.0)
    """
    a, b, _ = _history_pairs(groups)
    if not a.size:
        return 0.0, 0
    return float(np.mean(_pair_agreements(P, a, b, q, tau))), int(a.size)


#: ``--temper`` rules of the check over histories: ``auto`` the power with the best agreement;
#: ``auto-1se`` the smallest power whose agreement is within one (cluster-robust) standard error
#: of the best, the one-standard-error rule: among powers the passes cannot tell apart, the most
#: cautious (chosen on the development sets, docs/results/mrclam.md).
TEMPER_RULES = ("auto", "auto-1se")


def choose_temper(prep: Prepared, ests: list[_Light], taus=AUTO_TEMPERS,
                  rule: str = "auto") -> tuple[float, list]:
    """The model check over histories: the tempering power (of ``taus``) under which the
    histories of each ordered triplet agree best (:func:`cross_pass_agreement`). Passes that
    contradict each other under the model (each confident, on different states) choose a power
    below 1, which widens every estimate toward the prior; where they agree it stays 1. With
    ``rule="auto-1se"`` the smallest power within one standard error (:func:`qfg.metrics.clustered_se`, by
    unordered landmark set) of the best. Returns (the power, [(tau, agreement, pairs, se),
    ...]); 1 when no triplet has two histories."""
    P = np.array([e.landmark for e in ests], dtype=float)
    return choose_power(P, _history_groups(prep), prep.prior_states, taus, rule)


def choose_power(P, groups: dict, q, taus=AUTO_TEMPERS, rule: str = "auto") -> tuple[float, list]:
    """:func:`choose_temper` on arrays: ``P`` (H, m) the histories' estimates, ``groups``
    {ordered triplet: [history index, ...]}, ``q`` (m,) the prior's state distribution."""
    if rule not in TEMPER_RULES:
        raise ValueError(f"rule: expected one of {TEMPER_RULES}, got {rule!r}")
    a, b, cid = _history_pairs(groups)
    if not a.size:
        return 1.0, [(float(t), 0.0, 0, 0.0) for t in taus]
    table = []
    for t in taus:
        ag = _pair_agreements(P, a, b, q, t)
        table.append((float(t), float(np.mean(ag)), int(ag.size), metrics.clustered_se(ag, cid)))
    if not table:
        return 1.0, table
    best = max(table, key=lambda r: (r[1], r[0]))
    if rule == "auto":
        return best[0], table
    ok = [r[0] for r in table if r[1] >= best[1] - best[3]]
    return min(ok), table


def seen_estimates(prep: Prepared, ests: list[_Light], *, combine: str = "geometric",
                   temper: float = 1.0, seed: int = 0, tensor=None) -> tuple:
    """Temper each history's estimate, combine those of each ordered triplet (module docstring,
    step 5). Returns (:class:`~qfg.harness.studies.mrclam_maps.SeenEstimates`, the tempered
    estimates, ``{triplet: Combined}``)."""
    from qfg.harness.studies.mrclam_maps import SeenEstimates

    if combine not in COMBINE:
        raise ValueError(f"combine: expected one of {COMBINE}, got {combine!r}")
    ds, q_c, q_x = prep.dataset, prep.prior_states, prep.prior_camera_states
    if temper != 1:
        ests = [_Light(_temper(e.landmark, q_c, temper), _temper(e.cameras, q_x, temper),
                       e.method, e.degenerate, e.model_check, e.position) for e in ests]
    groups = _history_groups(prep)
    combined = {t: _combine(np.array([ests[k].landmark for k in ks]), q_c, combine)
                for t, ks in groups.items()}
    trip = np.array(sorted(combined), dtype=np.intp).reshape(-1, 3)
    m = prep.partition.n_states
    seen = SeenEstimates(
        dataset=ds, partition=prep.partition, triplets=trip,
        probabilities=np.array([combined[tuple(t)].probabilities for t in trip.tolist()],
                               dtype=float).reshape(-1, m),
        conflict=np.array([bool(combined[tuple(t)].conflict) for t in trip.tolist()], bool),
        estimates=np.array([e.landmark for e in ests], dtype=float).reshape(-1, m),
        groups=groups, prior_states=q_c, seed=int(seed),
        histories=lambda: list(prep.histories), tensor=tensor, prior=prep.prior,
        prior_camera_states=prep.prior_camera_states, solver=_solver_of(ests),
        positions={k: e.position for k, e in enumerate(ests) if e.position is not None},
        temper=float(temper))
    return seen, ests, combined


def say_map_info(name: str, info, say) -> None:
    """Tell the user which map answered and what it flagged: a fallback and why, bearings the
    joint fit found taken from on their landmark, the joint map's flags and, when it widened
    its covariance, by how much."""
    info = dict(info or {})
    by = info.get("answered_by", name)
    if by != name:
        say(f"map {name}: answered by {by}: {info.get('why', '')}")
        return
    close, out = int(info.get("too_close", 0)), int(info.get("too_close_dropped", 0))
    if close:
        say(f"map {name}: {close} bearing{'s' if close > 1 else ''} from poses the fit had put "
            f"on the landmark seen ({out} left out, the others kept once the poses moved off)")
    flags = info.get("flags") or []
    extra = ""
    if "overdispersion" in info:
        scale = float(info.get("covariance_scale", 1.0))
        why = (f"covariance x{scale:.2f}" if scale != 1.0 else "not widened: "
               + ("no more than it allows" if "kinematic_prior" in flags
                  else "every run has odometry"))
        extra = (f"the robots' own maps scatter {info['overdispersion']:.2f}x what its "
                 f"covariance allows ({why})")
    if flags:
        say(f"map {name}: flags {', '.join(flags)}" + (f"; {extra}" if extra else ""))
    elif extra:
        say(f"map {name}: {extra}")


def score_map(prep: Prepared, seen, result, ests: list[_Light], common: dict) -> list[dict]:
    """Rows of a map (module docstring, step 7): every row of ``result`` scored against the
    landmark ground truth, beside the uniform and prior-alone baselines."""
    from qfg.graph import truth_states

    ds, part = prep.dataset, prep.partition
    trip = np.asarray(result.triplets, dtype=np.intp).reshape(-1, 3)
    P = np.asarray(result.probabilities, dtype=float).reshape(len(trip), part.n_states)
    P = P / P.sum(axis=1, keepdims=True)
    missing = {tuple(t) for t in seen.triplets.tolist()} - {tuple(t) for t in trip.tolist()}
    if missing:
        raise ValueError(f"map {common.get('map')!r}: leaves out {len(missing)} seen triplet(s)")
    truth = truth_states(trip, ds.landmark_xy, part.name) if len(trip) else np.zeros(0, int)
    sc = _score_rows(P, truth, prep.prior_states, part.centroids) if len(trip) else {}
    conflict = {tuple(t): bool(c) for t, c in zip(seen.triplets.tolist(), seen.conflict,
                                                   strict=True)}
    rh, ids = prep.histories, ds.landmark_ids
    rows = []
    for v, t in enumerate(map(tuple, trip.tolist())):
        ks = seen.groups.get(t, [])
        row = {**common, "kind": "seen" if result.seen[v] else "propagated",
               "A": int(ids[t[0]]), "B": int(ids[t[1]]), "C": int(ids[t[2]]),
               "truth_state": int(truth[v]), "map_state": int(np.argmax(P[v])),
               "n_histories": len(ks), "n_views": int(sum(rh[k][1].n_views for k in ks)),
               "robots": ";".join(str(r) for r in sorted({rh[k][0] for k in ks})),
               "method": ";".join(sorted({ests[k].method for k in ks})) if ks else "propagated",
               # share of the row's histories the solver flagged (degenerate geometry, low ESS)
               "flagged": float(np.mean([ests[k].degenerate for k in ks])) if ks else 0.0,
               "conflict": conflict.get(t, False),
               "reached": bool(result.reached[v])}
        for key, arr in sc.items():
            row[key] = float(arr[v])
        row["probabilities"] = _enc(P[v])
        rows.append(row)
    return rows


def map_name(propagate: bool = True, propagation: str = "mean", map_method: str = "") -> str:
    """The map method the older options name: ``propagate=False`` -> ``"seen"``;
    ``propagation`` ``"mean"`` -> ``"pooled"``, ``"best"`` -> ``"best"``; ``map_method`` wins."""
    if map_method:
        return map_method
    if not propagate:
        return "seen"
    if propagation not in ("mean", "best"):
        raise ValueError(f"propagation: expected 'mean' or 'best', got {propagation!r}")
    return {"mean": "pooled", "best": "best"}[propagation]


def finish(prep: Prepared, ests: list[_Light], *, combine: str = "geometric",
           temper: float = 1.0, map_method: str = "pooled", tensor=None, seed: int = 0,
           say=None, record_dir=None, tensor_name: str = "") -> tuple[list[dict], dict]:
    """From the solved estimates to scored rows: temper, combine, the map method, scores of the
    map's rows and of the camera views. ``say``: a callable told each phase (progress);
    ``record_dir``: the map is recorded there (``maps/<name>.npz``) and a record made from the
    same inputs is used instead of making it again. Returns (rows, details)."""
    from qfg.harness.studies import mrclam_maps

    say = say or (lambda msg: None)
    method = mrclam_maps.get(map_method)
    temper_check = None
    if temper in TEMPER_RULES:
        rule = temper
        temper, temper_check = choose_temper(prep, ests, rule=rule)
        say(f"temper {rule}: the histories of one ordered triplet "
            f"{'agree best' if rule == 'auto' else 'agree within one standard error of the best'}"
            f" at {temper:g} ({temper_check[0][2] if temper_check else 0} pairs; agreement at 1: "
            f"{temper_check[0][1] if temper_check else 0:.3f}, at {temper:g}: "
            f"{dict((r[0], r[1]) for r in temper_check).get(temper, 0.0):.3f})")
    seen, ests, combined = seen_estimates(prep, ests, combine=combine, temper=temper, seed=seed,
                                          tensor=tensor)
    say(f"combined: {len(ests)} histories into {len(seen.triplets)} seen ordered triplets "
        f"({combine}{'' if temper == 1 else f', tempered {temper:g}'})")
    ds = prep.dataset
    swap_txt = ";".join(f"{a}-{b}" for a, b in prep.swaps)
    common = {"dataset": ds.name, "path": prep.path, "mode": prep.mode,
              "prior": prep.prior_name, "combine": combine, "temper": float(temper),
              "map": method.name, "gt_swaps": swap_txt}
    t0 = time.perf_counter()
    result = None
    rec = None
    if record_dir is not None:
        mrclam_maps.save_seen(Path(record_dir) / "seen.npz", seen, combine=combine,
                              temper=float(temper))
        digest = mrclam_maps.inputs_digest(method.name, seen, tensor_name)
        rec = Path(record_dir) / "maps" / f"{method.name}.npz"
        result = mrclam_maps.load_map(rec, digest)
        if result is not None:
            say(f"map {method.name}: {len(result.triplets)} triplets, as recorded in {rec}")
    if result is None:
        say(f"map {method.name}: {method.description} ...")
        if method.name == "joint":
            # solved here to tell its phases; the map finds the answer remembered
            mrclam_maps.joint_of(seen, progress=say)
        result = method.fn(seen)
        if rec is not None:
            mrclam_maps.save_map(rec, result, digest)
        n_prop = int(np.count_nonzero(~np.asarray(result.seen)))
        say(f"map {method.name}: {len(result.triplets)} triplets ({n_prop} not seen, "
            f"{int(np.count_nonzero(result.reached))} reached) in "
            f"{time.perf_counter() - t0:.1f} s")
    t_map = time.perf_counter() - t0
    say_map_info(method.name, result.info, say)
    rows = score_map(prep, seen, result, ests, common)
    if result.cameras is not None:  # the map answered the cameras too (e.g. the joint map)
        answered = str(result.info.get("camera_method", method.name))
        ests = [_Light(e.landmark, np.asarray(c, dtype=float), answered, e.degenerate,
                       e.model_check, e.position)
                for e, c in zip(ests, result.cameras, strict=True)]
    rows += _camera_rows([h for _, h in prep.histories], prep.histories, ests,
                         prep.prior_camera_states, prep.partition, common)
    say(f"scores: {sum(r['kind'] == 'seen' for r in rows)} seen, "
        f"{sum(r['kind'] == 'propagated' for r in rows)} propagated, "
        f"{sum(r['kind'] == 'camera' for r in rows)} camera views")
    if rows:
        rows[0]["time_propagate_s"] = t_map
    return rows, {"dataset": ds, "swaps": prep.swaps, "histories": prep.histories,
                  "estimates": ests, "seen": seen, "map": result, "partition": prep.partition,
                  "prior": prep.prior, "prior_states": prep.prior_states,
                  "prior_camera_states": prep.prior_camera_states, "combined": combined,
                  "temper": float(temper), "temper_check": temper_check}


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
                sigma_distance_ratio: float = 0.0, map_method: str = "",
                piece: int = CHUNK, bearing_tail: str = "normal", model_check: float = 0.0,
                heading_drift: bool = False, distance_tail: str = "normal",
                heading_walk: float = 0.0, heading_tail: str = "normal",
                camera_prior: str = "point", budget: float = 1.0, populations: int = 1,
                bearing_calibration: str = "none", **solver_options):
    """Solve, combine, map, propagate and score one dataset directory, in memory (``qfg
    mrclam`` runs the same phases and records them: :func:`prepare_run`, :func:`solve_piece`
    per piece, :func:`finish`).

    Args:
        path: an MRCLAM dataset directory.
        robots: robot numbers (None: all).
        method: single-triplet solver (``"fast"``, ``"full"``, ``"baseline"``); robots without
            odometry always get the baseline (the row's ``method``).
        mode: ``"honest"`` (measured inputs) or ``"paper"`` (inputs from motion capture).
        prior: ``"arena"`` or ``"world"`` (:func:`make_prior`).
        combine: ``"prior-once"``, ``"geometric"`` or ``"product"`` (module docstring, step 5).
        tensor: composition tensor ((m, m, m) array or CompositionTensor); None: the shipped one.
        seed: solver seed (piece c of ``piece`` histories gets child c of
            ``SeedSequence(seed)``).
        min_travel, max_gap, max_views: history options (module docstring, step 2).
        map_method: the map method by name (:mod:`qfg.harness.studies.mrclam_maps`:
            ``"pooled"``, ``"best"``, ``"seen"``, ...); empty: named by the two options below.
        propagate: build the map and propagate (False: seen triplets and cameras only, the map
            method ``"seen"``).
        propagation: ``"mean"`` (map method ``"pooled"``: :func:`qfg.propagation.propagate_pooled`,
            every unseen triplet the mean of its compositions from the nearest updated
            triplets) or ``"best"`` (the paper's Algorithm 2, :func:`qfg.propagation.propagate`:
            the sharpest proposal).
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
        piece: histories solved per call (and per recorded piece of ``qfg mrclam``).
        bearing_tail: the solvers' bearing-noise model by name (:data:`BEARING_TAILS`).
        model_check: level of the solvers' model check (``full``/``fast``: answers whose
            posterior predictive p is below it are widened toward the prior; 0: report only).
        heading_drift: each history's heading sigma from its longest step
            (:func:`drift_sigma_heading`).
        distance_tail: the step-length ratios' noise model by name (:data:`DISTANCE_TAILS`;
            ``"measured"`` also sets their core sigma unless ``sigma_distance_ratio`` is given).
        heading_walk: each step's heading sigma ``heading_walk sqrt(dt)`` degrees
            (:func:`walk_sigma_heading`; :data:`HEADING_WALK` measured; 0: off).
        heading_tail: ``"measured"``: the solvers' headings get the two-normal tail of
            :data:`HEADING_WALK_TAIL` (with ``heading_walk`` its 0.85).
        camera_prior: the solvers' ``camera_prior`` (``"joint"``: the cameras' joint prior in
            the intermediate weights; docs/solvers.md).
        budget: the full/fast solvers' budget times this factor
            (:func:`qfg.solvers._options.scaled_budget`).
        populations: the full/fast solvers' independent SIS populations (their
            ``populations`` option; 1: the default; given, the few-views package is off,
            docs/solvers.md).
        bearing_calibration: ``"measured"``: each robot's bearings corrected by its bias and
            scale measured against motion capture on dataset 6
            (:data:`qfg.datasets.mrclam.DEFAULT_BEARING_CALIBRATION`) before anything else.

    Returns:
        rows (list of dicts; module docstring). With ``return_details``: ``(rows, details)``.
    """
    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    if combine not in COMBINE:
        raise ValueError(f"combine: expected one of {COMBINE}, got {combine!r}")
    name = map_name(propagate, propagation, map_method)
    from qfg.harness.studies import mrclam_maps

    mrclam_maps.get(name)
    prep = prepare_run(path, robots=robots, mode=mode, prior=prior, partition=partition,
                       fix_landmarks=fix_landmarks, min_travel=min_travel, max_gap=max_gap,
                       max_views=max_views, spread_views=spread_views,
                       sigma_bearing_deg=sigma_bearing_deg, sigma_heading_deg=sigma_heading_deg,
                       distances=distances, sigma_distance_ratio=sigma_distance_ratio,
                       bearing_tail=bearing_tail, model_check=model_check,
                       heading_drift=heading_drift, distance_tail=distance_tail,
                       heading_walk=heading_walk, heading_tail=heading_tail,
                       camera_prior=camera_prior, budget=budget, populations=populations,
                       bearing_calibration=bearing_calibration)
    t0 = time.perf_counter()
    ests = []
    for c in range(n_pieces(prep, piece)):
        ests += solve_piece(prep, c, method=method, seed=seed, piece=piece, **solver_options)
    t_solve = time.perf_counter() - t0
    rows, details = finish(prep, ests, combine=combine, temper=temper, map_method=name,
                           tensor=tensor, seed=int(seed))
    if rows:
        rows[0]["time_solve_s"] = t_solve
    if not return_details:
        return rows
    details["graph"] = None
    details["propagation"] = details["map"]
    return rows, details


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


#: What the table's columns mean (printed under it by ``qfg mrclam``).
TABLE_KEY = ("Key: each score of the estimates (est.) beside two baselines: uniform (every state "
             "1/m) and prior (the state distribution the prior alone gives, no measurement). "
             "log score: mean ln p(truth), clipped at 1e-4, higher is better; Brier: lower is "
             "better; GT rating: rank of the true state, 1 best; truth < 1%: share of rows giving "
             "the truth under 1%; flagged: share of solves flagged degenerate; flat: share of "
             "uniform estimates; ECE: expected calibration error of the top state.")

_TABLE_SCORES = (("log_score", "log score", 2), ("brier", "Brier", 3), ("gt_rating", "GT rating", 2),
                 ("truth_under_1pct", "truth < 1%", 2))


def table_lines(summ: dict) -> list[str]:
    """Markdown rows: per dataset, mode and kind, each score of the estimates beside its uniform
    and prior-alone baselines, in labelled columns (:data:`TABLE_KEY`)."""
    head = ["dataset", "mode", "kind", "n"]
    for _, label, _ in _TABLE_SCORES:
        head += [f"{label} est.", "uniform", "prior"]
    head += ["flagged", "flat", "ECE"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
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
                cells = [name, mode, kind, str(k["n"])]
                for key, _, d in _TABLE_SCORES:
                    cells += [_fmt(k[f"{p}{key}"], d) for p in ("", "uniform_", "prior_")]
                cells += [_fmt(k["flagged"]), _fmt(k["uniform_estimate"]), _fmt(k["ece"])]
                lines.append("| " + " | ".join(cells) + " |")
    return lines


def write_outputs(outdir, rows: list[dict], *, figures: bool = True, figure_robot=None,
                  details=None, options=None) -> dict:
    """``triplets.csv`` (seen and propagated rows), ``cameras.csv`` (camera rows, when any),
    ``summary.json`` (with ``options``, when given), ``table.md`` (the table and its key) and
    figures; returns the summary dict."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    # timings stay out of the tables (the runner's timings.csv has them), so that the same
    # inputs write the same bytes, however often the run was interrupted
    untimed = [{k: v for k, v in r.items() if not k.startswith("time_")} for r in rows]
    trip = [r for r in untimed if r["kind"] != "camera"]
    cams = [r for r in untimed if r["kind"] == "camera"]
    write_table(out / "triplets.csv", trip, digits=None)
    if cams:
        write_table(out / "cameras.csv", cams, digits=None)
    names = list(dict.fromkeys(r["dataset"] for r in rows))
    summ = summary(rows)
    summ["datasets"] = {n: summary([r for r in rows if r["dataset"] == n]) for n in names}
    if options is not None:
        summ["options"] = options
    (out / "summary.json").write_text(json.dumps(summ, indent=2) + "\n")
    (out / "table.md").write_text("\n".join(table_lines(summ)) + "\n\n" + TABLE_KEY + "\n")
    if figures and rows:
        make_figures(out, rows, details=details, robot=figure_robot)
    return summ


# ----------------------------------------------------------------------------- figures
def make_figures(outdir: Path, rows: list[dict], *, details=None, robot=None) -> list[Path]:
    """Reliability (calibration) figures of each mode's seen, propagated and camera rows, one
    robot's path with the views of the seen triplet with most views (first dataset) and, for a
    joint map or a configuration map, the map against the ground truth (``joint_map``,
    ``configuration_map``)."""
    from qfg.harness.plotting_mrclam import (
        configuration_map_figure,
        joint_map_figure,
        reliability_figure,
    )

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
    geom = dict(getattr((details or {}).get("map"), "info", None) or {}).get("map_geometry")
    if geom and geom.get("kind") == "configurations":
        paths.append(save_figure(configuration_map_figure(geom, details["dataset"]), outdir,
                                 "configuration_map"))
    elif geom:
        paths.append(save_figure(joint_map_figure(geom, details["dataset"]), outdir,
                                 "joint_map"))
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


# ----------------------------------------------------------------------------- qfg mrclam: pieces
# ``qfg mrclam`` is a runner run whose scenarios are the pieces of one dataset's histories: a
# piece's record holds its histories' estimates (piece_rows), the runner's summary step makes
# the rest from them (estimates_from_rows, finish). The command prepares the dataset once
# (checking every file before anything is written) and hands it to the pieces through
# ``remember``; a worker process that was not handed it prepares it again from the params.

_PREPARED: dict[str, Prepared] = {}


def _prep_key(params: dict) -> str:
    return json.dumps({k: params.get(k, DEFAULTS.get(k)) for k in SOLVE_KEYS
                       if k not in ("method", "piece")},
                      sort_keys=True, default=str)


def remember(params: dict, prep: Prepared) -> None:
    """Keep ``prep`` for the pieces of the run with ``params`` (one dataset at a time)."""
    _PREPARED.clear()
    _PREPARED[_prep_key(params)] = prep


def prepared(params: dict) -> Prepared:
    """The prepared dataset of a run's params (:data:`SOLVE_KEYS`), made once per process."""
    key = _prep_key(params)
    if key not in _PREPARED:
        remember(params, prepare_run(
            params["path"], robots=params["robots"] or None,
            **{k: params.get(k, DEFAULTS[k]) for k in SOLVE_KEYS
               if k not in ("path", "robots", "method", "piece")}))
    return _PREPARED[key]


def piece_tasks(params: dict) -> list[dict]:
    """One task per piece of ``params["piece"]`` histories (the params of ``qfg mrclam``:
    :data:`SOLVE_KEYS` and ``seed``)."""
    return [{"index": c, **params} for c in range(n_pieces(prepared(params), params["piece"]))]


def run_piece(task: dict, rng) -> list[dict]:
    """Solve one piece (:func:`solve_piece`, with the command's seed, not the runner's stream:
    piece c gets child c of ``SeedSequence(seed)`` as the in-memory :func:`run_dataset` does)."""
    prep = prepared(task)
    t0 = time.perf_counter()
    ests = solve_piece(prep, task["index"], method=task["method"], seed=task["seed"],
                       piece=task["piece"])
    rows = piece_rows(prep, task["index"], ests, task["piece"])
    if rows:
        rows[0]["time_solve_s"] = time.perf_counter() - t0
    return rows


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
    if p["map"]:
        from qfg.harness.studies.mrclam_maps import MAP_METHODS

        if p["map"] not in MAP_METHODS:
            raise ValueError(f"map: expected one of {tuple(MAP_METHODS)}, got {p['map']!r}")
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
              "sigma_distance_ratio", "map")


def tasks(params: dict) -> list[dict]:
    """One task per dataset directory."""
    p = _params(params)
    return [{"index": i, "path": str(d), "robots": list(p["robots"]),
             **{k: p[k] for k in _TASK_KEYS}}
            for i, d in enumerate(dataset_dirs(p["data"], p["datasets"]))]


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    T = _load_tensor(task["partition"], task["tensor"] or None) if task["propagate"] and \
        task.get("map", "") != "seen" else None
    opts = {k: task[k] for k in _TASK_KEYS if k not in ("tensor", "map")}
    return run_dataset(task["path"], robots=task["robots"] or None, tensor=T,
                       map_method=task.get("map", ""), seed=int(rng.integers(2**63)), **opts)


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    print("\n".join(table_lines(write_outputs(outdir, rows))))
    print(TABLE_KEY)


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
