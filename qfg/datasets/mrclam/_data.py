"""MRCLAM data types: a loaded dataset, its robots, odometry and the load report (quirk counts)."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from ..._validate import as_float_array
from ...geometry import wrap_angle
from ._constants import DEFAULT_GROUNDTRUTH_MAX_GAP


def interpolate_poses(records, times, *, max_gap: float = DEFAULT_GROUNDTRUTH_MAX_GAP):
    """Poses (n, 3) at ``times`` (n,) from time-sorted pose records (g, 4) ``(t, x, y, theta)``,
    and a (n,) mask of the covered times.

    Linear interpolation in x, y and the unwrapped orientation between the two records around
    each time. A time is *covered* when it is a record's time or both records around it exist and
    are at most ``max_gap`` seconds apart (motion capture drops out now and then); other times get
    the clamped interpolation (the nearest record's pose at either end) and False.

    >>> P, ok = interpolate_poses([[0.0, 0, 0, 3.1], [0.1, 1, 0, -3.1]], [0.05, 0.2])
    >>> P.round(3).tolist(), ok.tolist()
    ([[0.5, 0.0, 3.142], [1.0, 0.0, -3.1]], [True, False])
    """
    gt = as_float_array("records", records, ndim=2, last_dim=4)
    t = as_float_array("times", times, ndim=1)
    th = np.unwrap(gt[:, 3])
    P = np.column_stack([np.interp(t, gt[:, 0], gt[:, 1]), np.interp(t, gt[:, 0], gt[:, 2]),
                         wrap_angle(np.interp(t, gt[:, 0], th))])
    g = gt.shape[0]
    k = np.searchsorted(gt[:, 0], t, side="right")  # records at or before t: gt[:k]
    exact = (k > 0) & (gt[np.clip(k - 1, 0, g - 1), 0] == t)
    kk = np.clip(k, 1, max(g - 1, 1))
    inside = (k > 0) & (k < g)
    covered = exact | (inside & (gt[kk, 0] - gt[kk - 1, 0] <= max_gap))
    return P, covered


def repeated_views(rd) -> np.ndarray:
    """(V,) True for views of ``rd`` (:class:`RobotData`) identical to the view before: same
    landmarks, bearings and ranges (the logger repeating a frame)."""
    return _repeated(rd.visible, rd.view_bearings, rd.view_ranges)


def _repeated(visible, bearings, ranges) -> np.ndarray:
    same = (np.all(visible[1:] == visible[:-1], axis=1)
            & np.all(bearings[1:] == bearings[:-1], axis=1)
            & np.all(ranges[1:] == ranges[:-1], axis=1))
    return np.concatenate([np.zeros(min(1, visible.shape[0]), dtype=bool), same])


@dataclass(frozen=True, eq=False)
class Odometry:
    """A robot's velocity log: command k holds on [time[k], time[k+1]).

    Attributes:
        time: (k,) seconds, non-decreasing.
        v: (k,) forward velocity, m/s.
        omega: (k,) angular velocity, rad/s (counter-clockwise positive).
        path: the file it was read from.
    """

    time: np.ndarray
    v: np.ndarray
    omega: np.ndarray
    path: str = ""

    def poses(self, times, start=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Dead-reckoned poses (n, 3) at ``times`` (see :func:`integrate_odometry`)."""
        from ._odometry import integrate_odometry

        return integrate_odometry(self.time, self.v, self.omega, times, start=start)

    def travelled(self, times) -> np.ndarray:
        """(n, 2) path length (m) and total turning (rad) from the first record to each of
        ``times`` (n,) (see :func:`travelled`).

        >>> od = Odometry(np.array([0.0, 1.0, 2.0]), np.array([1.0, -1.0, 0.0]),
        ...               np.array([0.0, 0.5, 0.0]))
        >>> od.travelled([0.5, 2.0]).tolist()
        [[0.5, 0.0], [2.0, 0.5]]
        """
        from ._odometry import travelled

        return travelled(self.time, self.v, self.omega, times)

    @property
    def max_gap(self) -> float:
        """Longest interval (s) between consecutive records."""
        return float(np.max(np.diff(self.time))) if self.time.size > 1 else 0.0


@dataclass(frozen=True, eq=False)
class RobotData:
    """One robot's records and views.

    Attributes:
        robot: the robot number N of the ``RobotN_*`` files (its subject number).
        time, barcode, range, bearing: (k,) every measurement row in time order (s, -, m, rad);
            file order except where the file's stamps go backwards (a stable sort, counted in
            ``quirks.measurements_out_of_order``).
        subject: (k,) subject number of each row's barcode, -1 for barcodes not in Barcodes.dat.
        is_landmark: (k,) True for rows that observe a landmark (subject in the landmark ground truth).
        view_times: (V,) time stamp of each view, increasing: landmark rows whose stamps follow each
            other within the load's ``view_gap`` (one image logged row by row) form one view,
            stamped with its first row's time.
        visible: (V, L) True where the view saw landmark column l (``MRCLAMDataset.landmark_ids``).
        view_bearings: (V, L) bearing (rad) of each seen landmark; 0.0 where not seen.
        view_ranges: (V, L) range (m) of each seen landmark; 0.0 where not seen.
        odometry: the velocity log, or None when the robot has no odometry file.
        groundtruth: (g, 4) motion-capture rows (time, x, y, orientation), time order, or None
            when ``RobotN_Groundtruth`` is absent (see :meth:`groundtruth_poses`).
        n_landmark, n_robot, n_unknown: measurement rows of landmarks, of robots (or other
            non-landmark subjects) and of barcodes missing from Barcodes.dat.
        unknown_barcodes: the distinct unknown barcodes, sorted.
        n_duplicate: landmark rows dropped because their view already had that landmark (the
            first row is kept).
        n_repeated_views: views identical to the previous view (same landmarks, same bearings and
            ranges): frames the logger repeated while waiting for a new image.
        quirks: what the loader found and did for this robot (:class:`RobotQuirks`).
    """

    robot: int
    time: np.ndarray
    barcode: np.ndarray
    range: np.ndarray
    bearing: np.ndarray
    subject: np.ndarray
    is_landmark: np.ndarray
    view_times: np.ndarray
    visible: np.ndarray
    view_bearings: np.ndarray
    view_ranges: np.ndarray
    odometry: Odometry | None
    groundtruth: np.ndarray | None
    n_landmark: int
    n_robot: int
    n_unknown: int
    unknown_barcodes: tuple
    n_duplicate: int
    n_repeated_views: int
    quirks: RobotQuirks | None = None

    @property
    def has_odometry(self) -> bool:
        return self.odometry is not None

    @property
    def has_groundtruth(self) -> bool:
        return self.groundtruth is not None

    def groundtruth_poses(self, times, *, max_gap: float = DEFAULT_GROUNDTRUTH_MAX_GAP):
        """Motion-capture poses (n, 3) at ``times`` (n,) and a (n,) mask of the covered ones
        (:func:`interpolate_poses`). ValueError when the robot has no ground truth."""
        if self.groundtruth is None:
            raise ValueError(f"robot: robot {self.robot} has no ground truth (RobotN_Groundtruth)")
        return interpolate_poses(self.groundtruth, times, max_gap=max_gap)

    @property
    def n_views(self) -> int:
        return int(self.view_times.shape[0])


@dataclass(frozen=True, eq=False)
class MRCLAMDataset:
    """A loaded MRCLAM dataset directory.

    Attributes:
        path: the directory.
        barcodes: subject number -> barcode.
        landmark_ids: (L,) landmark subject numbers, increasing (the column order of views).
        landmark_xy: (L, 2) landmark positions in the world frame (m).
        landmark_std: (L, 2) their standard deviations (m).
        robots: robot number -> :class:`RobotData`, for every ``RobotN_Measurement`` file.
        report: the :class:`LoadReport` (quirk counts) of :func:`load`.
    """

    path: str
    barcodes: dict
    landmark_ids: np.ndarray
    landmark_xy: np.ndarray
    landmark_std: np.ndarray
    robots: dict = field(default_factory=dict)
    report: LoadReport | None = None

    @property
    def name(self) -> str:
        return Path(self.path).name

    def landmark_index(self, subjects) -> np.ndarray:
        """Column indices of landmark subject numbers; ValueError for a subject that is no landmark."""
        s = np.asarray(subjects, dtype=np.int64)
        idx = np.clip(np.searchsorted(self.landmark_ids, s), 0, self.landmark_ids.size - 1)
        if np.any(self.landmark_ids[idx] != s):
            bad = s[self.landmark_ids[idx] != s]
            raise ValueError(f"subjects: {bad.tolist()} are not landmarks of {self.name}")
        return idx

    def landmark_position(self, subjects) -> np.ndarray:
        """World positions (..., 2) of landmark subject numbers (...)."""
        return self.landmark_xy[self.landmark_index(subjects)]

    def robot(self, robot) -> RobotData:
        """The :class:`RobotData` of robot number ``robot``; ValueError naming the known ones."""
        if robot not in self.robots:
            raise ValueError(f"robot: {robot!r} is not in {self.name}; robots: {sorted(self.robots)}")
        return self.robots[robot]




@dataclass(frozen=True)
class RobotQuirks:
    """What the loader found in one robot's files and what it did (counts; times in seconds).

    Measurement file:
        measurement_rows: data rows. ``empty_measurement_file``: it had its header but no rows
            (the robot then has no views).
        landmark_rows / robot_rows / unknown_rows: rows seeing a landmark / a robot (or another
            subject that is no landmark) / a barcode missing from Barcodes.dat; only landmark rows
            make views. ``unknown_barcodes``: those barcodes.
        measurements_out_of_order: rows stamped earlier than the row before them; the rows were
            sorted by time (stably). ``measurements_max_backstep``: the largest such step back.
        merged_stamps: distinct landmark-row stamps merged into the view before them because they
            followed it within ``view_gap`` (one image logged row by row, 1 ms apart).
            ``max_view_span``: the longest first-to-last stamp span of a view.
        duplicate_landmarks: rows dropped because their view already had that landmark (the first
            is kept). ``repeated_views``: views identical to the one before (landmarks, ranges and
            bearings), kept and counted.
        views: views after merging.
    Odometry (zeros without a file):
        odometry_rows; odometry_out_of_order / odometry_max_backstep: records stamped earlier than
            the one before, sorted by time (stably), so a command lasts until the next stamp;
        odometry_duplicate_stamps: records with the stamp of the record before (a zero-length
            command: it moves nothing, the next one takes over);
        views_outside_odometry: views before the first or after the last record (no motion is
            known for them; histories leave them out).
    Ground truth (zeros without a file): groundtruth_rows, groundtruth_out_of_order,
        groundtruth_duplicate_stamps (the later record of each such pair is dropped: the capture
        cannot be in two places at once), views_outside_groundtruth (views not covered by two
        records at most ``DEFAULT_GROUNDTRUTH_MAX_GAP`` apart, :meth:`RobotData.groundtruth_poses`).
    """

    robot: int
    measurement_rows: int = 0
    empty_measurement_file: bool = False
    landmark_rows: int = 0
    robot_rows: int = 0
    unknown_rows: int = 0
    unknown_barcodes: tuple = ()
    measurements_out_of_order: int = 0
    measurements_max_backstep: float = 0.0
    merged_stamps: int = 0
    max_view_span: float = 0.0
    duplicate_landmarks: int = 0
    repeated_views: int = 0
    views: int = 0
    odometry_rows: int = 0
    odometry_out_of_order: int = 0
    odometry_max_backstep: float = 0.0
    odometry_duplicate_stamps: int = 0
    views_outside_odometry: int = 0
    groundtruth_rows: int = 0
    groundtruth_out_of_order: int = 0
    groundtruth_duplicate_stamps: int = 0
    views_outside_groundtruth: int = 0

    def as_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


#: Counts of :class:`RobotQuirks` that are summed in :meth:`LoadReport.totals` (the rest are
#: maxima, flags or lists).
_SUMMED = tuple(f.name for f in fields(RobotQuirks)
                if f.type in ("int", int) and f.name != "robot")


@dataclass(frozen=True)
class LoadReport:
    """The quirks of one loaded dataset: per-robot :class:`RobotQuirks` and what was done.

    Attributes:
        dataset: the directory's name. ``view_gap``: the merge gap (s) the views were built with.
        robots: one :class:`RobotQuirks` per robot, by robot number.
        files: the files read, relative to the dataset directory.
    """

    dataset: str
    view_gap: float
    robots: tuple
    files: tuple = ()

    def robot(self, n) -> RobotQuirks:
        for q in self.robots:
            if q.robot == n:
                return q
        raise ValueError(f"robot: {n!r} is not in {self.dataset}; robots: "
                         f"{[q.robot for q in self.robots]}")

    def totals(self) -> dict:
        """Sums of the counts over robots, the largest back-steps and view span, the union of the
        unknown barcodes and the number of robots with an empty measurement file."""
        out = {k: sum(getattr(q, k) for q in self.robots) for k in _SUMMED}
        for k in ("measurements_max_backstep", "odometry_max_backstep", "max_view_span"):
            out[k] = max((getattr(q, k) for q in self.robots), default=0.0)
        out["unknown_barcodes"] = tuple(sorted({b for q in self.robots for b in q.unknown_barcodes}))
        out["empty_measurement_files"] = sum(q.empty_measurement_file for q in self.robots)
        return out

    def describe(self) -> str:
        """The totals as sentences saying what the loader did."""
        t = self.totals()
        lines = [f"{self.dataset}: {len(self.robots)} robot(s), {t['measurement_rows']} measurement "
                 f"rows, {t['views']} views (rows within {1000 * self.view_gap:g} ms form one view)."]
        lines.append(f"  merged {t['merged_stamps']} stamps into the view before them (longest view "
                     f"span {1000 * t['max_view_span']:.0f} ms); kept {t['repeated_views']} views "
                     f"that repeat the one before; dropped {t['duplicate_landmarks']} repeated "
                     f"landmark rows within a view.")
        lines.append(f"  set aside {t['robot_rows']} rows of robots and {t['unknown_rows']} of "
                     f"unknown barcodes {list(t['unknown_barcodes'])}.")
        lines.append(f"  sorted {t['measurements_out_of_order']} measurement rows and "
                     f"{t['odometry_out_of_order']} odometry records stamped before the one above "
                     f"them (largest step back {t['measurements_max_backstep']:.3f} s / "
                     f"{t['odometry_max_backstep']:.3f} s); {t['odometry_duplicate_stamps']} odometry "
                     f"records repeat a stamp (zero-length commands).")
        lines.append(f"  {t['views_outside_odometry']} views lie outside their odometry's span "
                     f"(left out of histories).")
        if t["groundtruth_rows"]:
            lines.append(f"  ground truth: {t['groundtruth_rows']} records, "
                         f"{t['groundtruth_out_of_order']} sorted, {t['groundtruth_duplicate_stamps']} "
                         f"duplicate stamps dropped, {t['views_outside_groundtruth']} views not "
                         f"covered by it.")
        if t["empty_measurement_files"]:
            lines.append(f"  {t['empty_measurement_files']} measurement file(s) hold only a header.")
        return "\n".join(lines)
