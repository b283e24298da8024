"""From a dataset directory to the histories the solvers get (the study's steps 1-4): the
dataset loaded with its landmark swaps undone (:func:`prepare`), the prior on the arena's box
(:func:`arena_extent`, :func:`make_prior`), the (robot, history) pairs (:func:`histories`) cut
to their first views (:func:`truncate`) or to views spread over each pass (:func:`spread`), with
clean inputs in paper mode (:func:`paper_history`), and the measured noise models the solvers
may assume (heading sigmas by step, :func:`walk_sigma_heading`, :func:`drift_sigma_heading`;
:data:`BEARING_TAILS`, :data:`DISTANCE_TAILS`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from qfg.datasets import mrclam as _mrclam
from qfg.priors import WorldBoxPrior
from qfg.priors import get as get_prior

#: ``mode``: measured inputs, or the bearings and headings computed from the motion capture.
MODES = ("honest", "paper")
#: ``prior``: the world-box prior on the arena, the same with every pair scale equally likely,
#: or the simulator's box (:func:`make_prior`).
PRIORS = ("arena", "world", "arena-logscale")

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
#: step"; ``experiments/mrclam/mrclam_heading_steps.py``).
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
#: degrees, (share, scale, outlier) of :class:`qfg.solvers.common.likelihood.BearingTail`); None: the
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
#: ratios"; ``experiments/mrclam/mrclam_distance_ratios.py``).
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
