"""Triplet histories: which views of a robot make a history of a landmark triplet, and the
:class:`MRCLAMHistory` objects (measured bearings, odometry headings and distances, ground truth)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from ... import partitions as _partitions
from ..._validate import as_float_array, non_negative, positive_int
from ...geometry import motion_heading, poses_to_frame, to_frame
from ...simulation import TripletHistory, TripletTruth
from ._constants import (
    DEFAULT_MAX_GAP,
    DEFAULT_MIN_INTERVAL,
    DEFAULT_MIN_TRAVEL,
    DEFAULT_ODOMETRY_LEAD,
    DEFAULT_SIGMA_BEARING,
    DEFAULT_SIGMA_DISTANCE_RATIO,
    DEFAULT_SIGMA_HEADING,
)
from ._data import MRCLAMDataset, RobotData, repeated_views


@dataclass(frozen=True)
class MRCLAMHistory(TripletHistory):
    """A :class:`qfg.simulation.TripletHistory` from MRCLAM, with what the data add.

    Attributes (beyond TripletHistory's):
        robot: the robot number.
        distances: (n - 1,) metres the robot moved from view i to view i+1 by its odometry (the
            straight-line distance between the dead-reckoned positions), or None without
            odometry. Scale-free use: ratios of consecutive entries (the SIS solvers' motion
            model uses them, with noise ``sigma_distance_ratio``, default
            :data:`DEFAULT_SIGMA_DISTANCE_RATIO`, measured on dataset 6).
        groundtruth_valid: (n,) True where ``truth.poses_world`` is covered by motion capture
            (:meth:`RobotData.groundtruth_poses`), or None without ground truth.
    """

    robot: int = 0
    distances: np.ndarray | None = field(default=None)
    groundtruth_valid: np.ndarray | None = field(default=None)
    sigma_distance_ratio: float | None = DEFAULT_SIGMA_DISTANCE_RATIO



@dataclass(frozen=True, eq=False)
class TripletSegment:
    """The views of one unordered landmark triplet that make one history.

    Attributes:
        landmarks: (a, b, c) subject numbers, increasing.
        view_index: (n,) indices into ``RobotData.view_times`` of the kept views, time order.
        n_seen: views of the triplet in this segment before thinning.
    """

    landmarks: tuple
    view_index: np.ndarray
    n_seen: int


def view_poses(rd: RobotData, odometry_lead: float = DEFAULT_ODOMETRY_LEAD):
    """Dead-reckoned poses (V, 3) of a robot at its views (zeros where not covered) and the (V,)
    mask of views inside the odometry's time span; ``(None, all True)`` without odometry.

    The odometry is read at ``view time - odometry_lead``: a command stamped t moves the robot as
    seen by the camera at t + lead (:data:`DEFAULT_ODOMETRY_LEAD`, measured by
    :func:`measure_noise`)."""
    lead = float(as_float_array("odometry_lead", odometry_lead, ndim=0))
    if rd.odometry is None:
        return None, np.ones(rd.n_views, dtype=bool)
    t = rd.odometry.time
    q = rd.view_times - lead
    covered = (q >= t[0]) & (q <= t[-1])
    poses = np.zeros((rd.n_views, 3))
    poses[covered] = rd.odometry.poses(q[covered])
    return poses, covered


def triplet_segments(dataset: MRCLAMDataset, robot, *, min_views: int = 3,
                     max_gap: float = DEFAULT_MAX_GAP, min_travel: float = DEFAULT_MIN_TRAVEL,
                     min_interval: float = DEFAULT_MIN_INTERVAL, max_views: int | None = None,
                     drop_repeated: bool = True, odometry_lead: float = DEFAULT_ODOMETRY_LEAD
                     ) -> list[TripletSegment]:
    """How one robot's views are grouped into histories, per unordered landmark triplet.

    1. The views that saw all three landmarks, in time order.
    2. Split where consecutive views of the triplet are more than ``max_gap`` seconds apart: the
       odometry between the pieces is long and unconstrained, so its heading would be unreliable,
       and the views no longer form one pass of the robot.
    (Views outside the odometry's time span, which has no motion for them, are left out for
    robots with odometry.)
    3. Thin each piece greedily: keep its first view, then each view whose dead-reckoned position
       is at least ``min_travel`` metres from the last kept one (robots without odometry: at
       least ``min_interval`` seconds after it). Near-identical consecutive views (the logger
       repeats frames, and the robots often stand still) would otherwise dominate, and a heading
       between two nearly equal positions is noise.
    With ``drop_repeated``, views that repeat the view before exactly (:func:`repeated_views`)
    are left out first.
    4. Keep pieces with at least ``min_views`` kept views; with ``max_views``, longer pieces are
       cut into consecutive chunks of ``max_views`` (a last chunk shorter than ``min_views``
       joins the previous one).

    Returns segments sorted by (landmarks, first view time).
    """
    rd = dataset.robot(robot)
    min_views = positive_int("min_views", min_views)
    max_gap = non_negative("max_gap", max_gap)
    min_travel = non_negative("min_travel", min_travel)
    min_interval = non_negative("min_interval", min_interval)
    if max_views is not None:
        max_views = positive_int("max_views", max_views, minimum=min_views)
    L = dataset.landmark_ids.size
    poses, covered = view_poses(rd, odometry_lead)
    usable = (rd.visible.sum(axis=1) >= 3) & covered
    if drop_repeated:
        usable &= ~repeated_views(rd)
    rich = np.flatnonzero(usable)
    if rich.size == 0 or L < 3:
        return []
    combos = np.array(list(itertools.combinations(range(L), 3)))
    vis = rd.visible[rich]
    together = vis[:, combos[:, 0]] & vis[:, combos[:, 1]] & vis[:, combos[:, 2]]  # (V3, C)
    counts = together.sum(axis=0)
    xy = None if poses is None else poses[rich, :2]
    times = rd.view_times[rich]
    out = []
    for ci in np.flatnonzero(counts >= min_views):
        idx = np.flatnonzero(together[:, ci])
        breaks = np.flatnonzero(np.diff(times[idx]) > max_gap) + 1
        for piece in np.split(idx, breaks):
            if piece.size < min_views:
                continue
            kept = [piece[0]]
            for j in piece[1:]:
                last = kept[-1]
                if xy is not None:
                    ok = np.hypot(*(xy[j] - xy[last])) >= min_travel
                else:
                    ok = times[j] - times[last] >= min_interval
                if ok:
                    kept.append(j)
            if len(kept) < min_views:
                continue
            kept = np.asarray(kept)
            chunks = [kept]
            if max_views is not None and kept.size > max_views:
                chunks = [kept[i:i + max_views] for i in range(0, kept.size, max_views)]
                if chunks[-1].size < min_views:
                    tail = chunks.pop()
                    chunks[-1] = np.concatenate([chunks[-1], tail])
            lms = tuple(int(x) for x in dataset.landmark_ids[combos[ci]])
            for ch in chunks:
                out.append(TripletSegment(landmarks=lms, view_index=rich[ch], n_seen=int(piece.size)))
    out.sort(key=lambda s: (s.landmarks, rd.view_times[s.view_index[0]]))
    return out


def triplet_histories(dataset: MRCLAMDataset, robot, *, min_views: int = 3,
                      max_gap: float = DEFAULT_MAX_GAP, min_travel: float = DEFAULT_MIN_TRAVEL,
                      min_interval: float = DEFAULT_MIN_INTERVAL, max_views: int | None = None,
                      sigma_bearing: float = DEFAULT_SIGMA_BEARING,
                      sigma_heading: float = DEFAULT_SIGMA_HEADING, partition="edc",
                      drop_repeated: bool = True, odometry_lead: float = DEFAULT_ODOMETRY_LEAD
                      ) -> list[MRCLAMHistory]:
    """Triplet histories of one robot: every ordered triplet AB:C of landmarks seen together in at
    least ``min_views`` kept views (grouping: :func:`triplet_segments`), views in time order.

    * ``landmarks``: MRCLAM subject numbers (A, B, C); ``views``: the views' time stamps (s).
    * ``bearings`` (n, 3): the measured [phi_A, phi_B, phi_C] of each view (radians).
    * ``headings`` (n - 1,): direction of travel from view i to view i+1 by the odometry integrated
      between their time stamps, relative to the heading at view i:
      ``psi_i = motion_heading(pose_i, position_{i+1})`` (conventions.md). A robot without odometry
      gives ``has_motion=False`` and zero headings (to be solved without motion model).
    * ``sigma_bearing``, ``sigma_heading``: what the solver should assume (radians); defaults
      :data:`DEFAULT_SIGMA_BEARING` and :data:`DEFAULT_SIGMA_HEADING`.
    * ``distances`` (n - 1,): metres between the dead-reckoned positions of consecutive views
      (None without odometry); ``robot``: the robot number.
    * ``truth``: the landmark ground truth (``landmarks_world``, ``C_ab``, ``state`` in
      ``partition``). Camera poses are known when ``RobotN_Groundtruth`` is present (dataset 6):
      ``poses_world`` (n, 3) from motion capture at the view times, ``poses_ab`` and
      ``camera_states`` in each ordering's AB frame, ``groundtruth_valid`` (n,) where the capture
      covers the view; otherwise they are None.

    ``min_travel=0.02`` keeps every view of a pass where the robot moved (``min_travel=0`` also
    keeps steps where it stood still, whose headings are noise: docs/mrclam.md); with
    ``max_views=None`` (default) a pass is not cut, so ``max_gap`` alone sets how long passes
    are. ``drop_repeated`` leaves out views that repeat the view before exactly (the logger's
    repeated frames: the same measurement twice).

    Every segment gives the six orderings of its three landmarks; a triplet seen in several passes
    gives several histories. Sorted by (landmarks, first view time).
    """
    rd = dataset.robot(robot)
    sb = non_negative("sigma_bearing", sigma_bearing)
    sh = non_negative("sigma_heading", sigma_heading)
    part = _partitions.get(partition)
    segs = triplet_segments(dataset, robot, min_views=min_views, max_gap=max_gap,
                            min_travel=min_travel, min_interval=min_interval, max_views=max_views,
                            drop_repeated=drop_repeated, odometry_lead=odometry_lead)
    if not segs:
        return []
    poses, _ = view_poses(rd, odometry_lead)
    # C in the AB frame and its state, for every ordered triplet of landmarks at once
    L = dataset.landmark_ids.size
    perms = np.array(list(itertools.permutations(range(L), 3)))
    P = dataset.landmark_xy[perms]  # (K, 3, 2)
    c_ab_all = to_frame(P[:, 2], P[:, 0], P[:, 1])
    state_all = part.state_of(c_ab_all)
    perm_row = {tuple(p): k for k, p in enumerate(perms.tolist())}
    out = []
    for seg in segs:
        vi = seg.view_index
        times = rd.view_times[vi]
        if poses is not None:
            psi = motion_heading(poses[vi[:-1]], poses[vi[1:], :2])
            dist = np.hypot(*np.diff(poses[vi, :2], axis=0).T)
        else:
            psi, dist = np.zeros(vi.size - 1), None
        gt_poses = gt_ok = None
        if rd.groundtruth is not None:
            gt_poses, gt_ok = rd.groundtruth_poses(times)
        for perm in itertools.permutations(seg.landmarks):
            cols = dataset.landmark_index(perm)
            k = perm_row[tuple(cols.tolist())]
            phi = rd.view_bearings[np.ix_(vi, cols)]
            Lw = P[k]
            if gt_poses is not None:
                p_ab = poses_to_frame(gt_poses, Lw[0], Lw[1])
                cam_states = part.state_of(p_ab[:, :2])
            else:
                p_ab = cam_states = None
            truth = TripletTruth(landmarks_world=Lw, poses_world=gt_poses, C_ab=c_ab_all[k],
                                 poses_ab=p_ab, partition=part.name, state=int(state_all[k]),
                                 camera_states=cam_states)
            out.append(MRCLAMHistory(landmarks=perm, bearings=phi, headings=psi, sigma_bearing=sb,
                                     sigma_heading=sh, views=times, truth=truth,
                                     has_motion=rd.odometry is not None, robot=rd.robot,
                                     distances=dist, groundtruth_valid=gt_ok))
    out.sort(key=lambda h: (h.landmarks, h.views[0]))
    return out


def history_counts(dataset: MRCLAMDataset, **options) -> dict:
    """Per robot: views, views with >= 3 landmarks, unordered triplets seen in >= ``min_views``
    views before thinning, segments (unordered histories) and ordered histories, after grouping
    with ``options`` (those of :func:`triplet_segments`). Also the dataset totals under ``"all"``,
    including ``distinct_triplets``: unordered triplets with a history from any robot, and
    ``distinct_triplets_raw``: unordered triplets seen together in >= ``min_views`` views of one
    robot before grouping (landmark column indices, not subject numbers, for the raw set).
    """
    min_views = options.get("min_views", 3)
    rows = {}
    distinct, distinct_raw = set(), set()
    for n, rd in dataset.robots.items():
        segs = triplet_segments(dataset, n, **options)
        L = dataset.landmark_ids.size
        combos = np.array(list(itertools.combinations(range(L), 3)))
        vis = rd.visible
        together = vis[:, combos[:, 0]] & vis[:, combos[:, 1]] & vis[:, combos[:, 2]]
        trip = {s.landmarks for s in segs}
        distinct |= trip
        distinct_raw |= {tuple(c) for c in combos[together.sum(axis=0) >= min_views].tolist()}
        rows[n] = {"views": rd.n_views, "views_3plus": int((vis.sum(axis=1) >= 3).sum()),
                   "triplets_raw": int((together.sum(axis=0) >= min_views).sum()),
                   "triplets": len(trip), "segments": len(segs), "histories": 6 * len(segs),
                   "has_odometry": rd.has_odometry}
    tot = {k: sum(r[k] for r in rows.values())
           for k in ("views", "views_3plus", "triplets_raw", "triplets", "segments", "histories")}
    tot["distinct_triplets"] = len(distinct)
    tot["distinct_triplets_raw"] = len(distinct_raw)
    rows["all"] = tot
    return rows


def summary_rows(dataset: MRCLAMDataset, **options) -> list[dict]:
    """Flat rows (one per robot) of loader counts and :func:`history_counts`, for tables."""
    counts = history_counts(dataset, **options)
    out = []
    for n, rd in dataset.robots.items():
        row = {"dataset": dataset.name, "robot": n, "measurements": int(rd.time.size),
               "landmark": rd.n_landmark, "robot_meas": rd.n_robot, "unknown": rd.n_unknown,
               "unknown_barcodes": " ".join(map(str, rd.unknown_barcodes)),
               "repeated_views": rd.n_repeated_views, "duplicates": rd.n_duplicate}
        row.update(counts[n])
        out.append(row)
    return out


