"""The UTIAS MRCLAM dataset: loader, odometry integration and landmark-triplet histories.

MRCLAM (Leung, Halpern, Barfoot and Liu, IJRR 2011) has five robots with monocular cameras moving
among 15 point landmarks; each robot measures range and bearing to the barcoded landmarks (and to
the other robots) and logs its commanded forward and angular velocity ("odometry"). A dataset
directory holds, in the dataset's own text format (``#`` header lines, whitespace-separated
columns), each file plain (``.dat``) or gzip-compressed (``.dat.gz``):

=============================  =============================================================
``Barcodes.dat``               subject #, barcode #
``Landmark_Groundtruth.dat``   subject #, x [m], y [m], x std-dev [m], y std-dev [m]
``RobotN_Measurement.dat``     time [s], barcode #, range [m], bearing [rad]
``RobotN_Odometry.dat``        time [s], forward velocity [m/s], angular velocity [rad/s]
``RobotN_Groundtruth.dat``     time [s], x [m], y [m], orientation [rad]   (optional)
=============================  =============================================================

:func:`load` reads a directory into a :class:`MRCLAMDataset`. Measurements name what they saw by
barcode; barcodes are mapped to subjects through ``Barcodes.dat``, and only subjects listed in
``Landmark_Groundtruth.dat`` are landmarks: measurements of robots and of barcodes missing from
``Barcodes.dat`` are counted and set aside. Landmark measurements sharing one time stamp came from
one image and form one *view*.

:func:`triplet_histories` turns one robot's views into :class:`qfg.simulation.TripletHistory`
objects (landmark ids are MRCLAM *subject numbers*, 6-20 in the real data): for every landmark
triplet the views that saw all three, split where the triplet went unseen for longer than
``max_gap`` seconds and thinned so that consecutive kept views are at least ``min_travel`` metres
apart by odometry; the heading between kept views is the direction of travel from the odometry
integrated between their time stamps (:func:`integrate_odometry`), relative to the heading at the
earlier view. ``docs/mrclam.md`` explains and measures these choices.

Data flows one way: this module reads files and produces measurements (histories); it does not
import solvers or plotting (figures are in ``qfg.plotting_mrclam``).

Run ``python -m qfg.datasets.mrclam DIR [DIR ...]`` for a per-robot summary of datasets.
"""

from __future__ import annotations

import gzip
import itertools
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .. import partitions as _partitions
from .._validate import as_float_array, non_negative, positive_int
from ..geometry import bearing, motion_heading, poses_to_frame, to_frame, wrap_angle
from ..simulation import TripletHistory, TripletTruth

__all__ = [
    "DataFormatError",
    "Odometry",
    "RobotData",
    "MRCLAMDataset",
    "load",
    "integrate_odometry",
    "dead_reckon",
    "landmark_fixes",
    "LandmarkFixes",
    "LandmarkCheck",
    "check_landmarks",
    "swap_landmarks",
    "anchored_dead_reckoning",
    "bearing_residuals",
    "odometry_check",
    "TripletSegment",
    "triplet_segments",
    "triplet_histories",
    "history_counts",
    "summary_rows",
    "DEFAULT_SIGMA_BEARING",
    "DEFAULT_SIGMA_HEADING",
    "DEFAULT_MAX_GAP",
    "DEFAULT_MIN_TRAVEL",
    "DEFAULT_MIN_INTERVAL",
]

#: Bearing noise (radians) the solver is told to assume by default: 2 degrees, the paper's headline
#: noise level; the landmark-fix residuals of the real data (docs/mrclam.md) are of that order.
DEFAULT_SIGMA_BEARING = float(np.deg2rad(2.0))
#: Heading noise (radians) assumed for odometry headings by default (docs/mrclam.md measures it).
DEFAULT_SIGMA_HEADING = float(np.deg2rad(5.0))
#: Longest time (s) a triplet may go unseen inside one history; beyond it a new history starts.
DEFAULT_MAX_GAP = 10.0
#: Least odometry displacement (m) between consecutive kept views of a history.
DEFAULT_MIN_TRAVEL = 0.2
#: Least time (s) between consecutive kept views of a history for robots without odometry.
DEFAULT_MIN_INTERVAL = 4.0


class DataFormatError(ValueError):
    """A dataset file is missing or malformed. ``path`` and ``line`` (1-based, or None) locate it.

    The message reads ``"<path>, line <n>: <what is wrong>"``.
    """

    def __init__(self, path, line, message):
        self.path = str(path)
        self.line = line
        where = self.path if line is None else f"{self.path}, line {line}"
        super().__init__(f"{where}: {message}")


# ----------------------------------------------------------------------------------------------
# Reading tables

def _find_file(directory: Path, stem: str) -> Path | None:
    """``stem.dat`` or ``stem.dat.gz`` in ``directory`` (plain first: the dataset's own format)."""
    for name in (f"{stem}.dat", f"{stem}.dat.gz"):
        p = directory / name
        if p.is_file():
            return p
    return None


def _open_text(path: Path):
    if path.name.endswith(".gz"):
        return gzip.open(path, "rt", encoding="utf-8", errors="replace")
    return open(path, encoding="utf-8", errors="replace")


def _data_lines(path: Path):
    """Yield (1-based line number, fields) for every line that is not blank or a comment."""
    with _open_text(path) as fh:
        for no, line in enumerate(fh, start=1):
            text = line.split("#", 1)[0].strip()
            if text:
                yield no, text.split()


def _line_of_row(path: Path, row: int) -> int | None:
    """File line number of the ``row``-th (0-based) data line."""
    for k, (no, _) in enumerate(_data_lines(path)):
        if k == row:
            return no
    return None


def _first_bad_line(path: Path, ncols: int, names: tuple[str, ...]):
    """The first data line with the wrong number of columns or a non-number: (line, message)."""
    for no, fields in _data_lines(path):
        if len(fields) != ncols:
            return no, (f"expected {ncols} columns ({', '.join(names)}), got {len(fields)}: "
                        f"{' '.join(fields)!r}")
        for name, tok in zip(names, fields, strict=True):
            try:
                val = float(tok)
            except ValueError:
                return no, f"column '{name}': expected a number, got {tok!r}"
            if not np.isfinite(val):
                return no, f"column '{name}': expected a finite number, got {tok!r}"
    return None


def _read_table(path: Path, names: tuple[str, ...], *, min_rows: int = 0) -> np.ndarray:
    """A whitespace-separated numeric table (rows, len(names)); '#' starts a comment.

    Fast path: one ``numpy.loadtxt`` call. Any failure (or a shape or finiteness problem) triggers a
    line-by-line pass that finds the offending line for the error message.
    """
    ncols = len(names)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            data = np.loadtxt(path, comments="#", dtype=float, ndmin=2)
    except (ValueError, IndexError) as exc:
        bad = _first_bad_line(path, ncols, names)
        if bad is None:  # pragma: no cover - numpy failed on something the slow pass accepts
            raise DataFormatError(path, None, f"could not read the table: {exc}") from None
        raise DataFormatError(path, *bad) from None
    except (OSError, EOFError) as exc:
        raise DataFormatError(path, None, f"could not read the file: {exc}") from None
    if data.size == 0:
        data = np.zeros((0, ncols))
    if data.shape[1] != ncols or not np.all(np.isfinite(data)):
        bad = _first_bad_line(path, ncols, names)
        raise DataFormatError(path, *(bad or (None, f"expected {ncols} finite columns")))
    if data.shape[0] < min_rows:
        raise DataFormatError(path, None, f"expected at least {min_rows} data line(s), got "
                                          f"{data.shape[0]}")
    return data


def _check_integer_column(path, data, col, name):
    vals = data[:, col]
    bad = np.flatnonzero(vals != np.round(vals))
    if bad.size:
        raise DataFormatError(path, _line_of_row(path, int(bad[0])),
                              f"column '{name}': expected an integer, got {vals[bad[0]]!r}")
    return vals.astype(np.int64)


def _check_time_order(path, t):
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        k = int(back[0]) + 1
        raise DataFormatError(path, _line_of_row(path, k),
                              f"time goes backwards: {t[k]!r} after {t[k - 1]!r}")


def _check_unique(path, ids, name):
    _, first, counts = np.unique(ids, return_index=True, return_counts=True)
    if np.any(counts > 1):
        dup_val = ids[first[counts > 1][0]]
        rows = np.flatnonzero(ids == dup_val)
        raise DataFormatError(path, _line_of_row(path, int(rows[1])),
                              f"{name} {int(dup_val)} appears more than once")


# ----------------------------------------------------------------------------------------------
# Data types

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
        return integrate_odometry(self.time, self.v, self.omega, times, start=start)

    @property
    def max_gap(self) -> float:
        """Longest interval (s) between consecutive records."""
        return float(np.max(np.diff(self.time))) if self.time.size > 1 else 0.0


@dataclass(frozen=True, eq=False)
class RobotData:
    """One robot's records and views.

    Attributes:
        robot: the robot number N of the ``RobotN_*`` files (its subject number).
        time, barcode, range, bearing: (k,) every measurement row in file order (s, -, m, rad).
        subject: (k,) subject number of each row's barcode, -1 for barcodes not in Barcodes.dat.
        is_landmark: (k,) True for rows that observe a landmark (subject in the landmark ground truth).
        view_times: (V,) time stamp of each view (distinct landmark-measurement times), increasing.
        visible: (V, L) True where the view saw landmark column l (``MRCLAMDataset.landmark_ids``).
        view_bearings: (V, L) bearing (rad) of each seen landmark; 0.0 where not seen.
        view_ranges: (V, L) range (m) of each seen landmark; 0.0 where not seen.
        odometry: the velocity log, or None when the robot has no odometry file.
        groundtruth: (g, 4) rows (time, x, y, orientation), or None when absent.
        n_landmark, n_robot, n_unknown: measurement rows of landmarks, of robots (or other
            non-landmark subjects) and of barcodes missing from Barcodes.dat.
        unknown_barcodes: the distinct unknown barcodes, sorted.
        n_duplicate: landmark rows dropped because their view already had that landmark (the
            first row is kept).
        n_repeated_views: views identical to the previous view (same landmarks, same bearings and
            ranges): frames the logger repeated while waiting for a new image.
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

    @property
    def has_odometry(self) -> bool:
        return self.odometry is not None

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
    """

    path: str
    barcodes: dict
    landmark_ids: np.ndarray
    landmark_xy: np.ndarray
    landmark_std: np.ndarray
    robots: dict = field(default_factory=dict)

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


# ----------------------------------------------------------------------------------------------
# Loading

_BARCODE_COLS = ("subject", "barcode")
_LANDMARK_COLS = ("subject", "x", "y", "x std-dev", "y std-dev")
_MEAS_COLS = ("time", "barcode", "range", "bearing")
_ODO_COLS = ("time", "forward velocity", "angular velocity")
_GT_COLS = ("time", "x", "y", "orientation")


def _robot_numbers(directory: Path, kind: str) -> set[int]:
    out = set()
    for p in directory.glob(f"Robot*_{kind}.dat*"):
        stem = p.name.split("_", 1)[0][len("Robot"):]
        if stem.isdigit() and p.name.endswith((".dat", ".dat.gz")):
            out.add(int(stem))
    return out


def _views(time, subject, rng_, brg, landmark_ids):
    """Group landmark rows by time stamp: view times, (V, L) visibility, bearings and ranges."""
    ut, view = np.unique(time, return_inverse=True)
    col = np.searchsorted(landmark_ids, subject)
    L = landmark_ids.size
    cell = view * L + col
    _, first = np.unique(cell, return_index=True)  # first row of each (view, landmark) cell
    n_dup = cell.size - first.size
    visible = np.zeros((ut.size, L), dtype=bool)
    bearings = np.zeros((ut.size, L))
    ranges = np.zeros((ut.size, L))
    visible[view[first], col[first]] = True
    bearings[view[first], col[first]] = brg[first]
    ranges[view[first], col[first]] = rng_[first]
    same = (np.all(visible[1:] == visible[:-1], axis=1)
            & np.all(bearings[1:] == bearings[:-1], axis=1)
            & np.all(ranges[1:] == ranges[:-1], axis=1))
    return ut, visible, bearings, ranges, int(n_dup), int(np.count_nonzero(same))


def _load_robot(directory: Path, n: int, b2s: dict, landmark_ids: np.ndarray) -> RobotData:
    mpath = _find_file(directory, f"Robot{n}_Measurement")
    m = _read_table(mpath, _MEAS_COLS)
    _check_time_order(mpath, m[:, 0])
    barcode = _check_integer_column(mpath, m, 1, "barcode")
    codes, inv = np.unique(barcode, return_inverse=True)
    subject = np.array([b2s.get(int(b), -1) for b in codes], dtype=np.int64)[inv.ravel()]
    is_lm = np.isin(subject, landmark_ids)
    unknown = subject < 0
    vt, vis, vb, vr, n_dup, n_rep = _views(m[is_lm, 0], subject[is_lm], m[is_lm, 2], m[is_lm, 3],
                                           landmark_ids)
    odo = None
    opath = _find_file(directory, f"Robot{n}_Odometry")
    if opath is not None:
        o = _read_table(opath, _ODO_COLS, min_rows=2)
        _check_time_order(opath, o[:, 0])
        odo = Odometry(time=o[:, 0], v=o[:, 1], omega=o[:, 2], path=str(opath))
    gt = None
    gpath = _find_file(directory, f"Robot{n}_Groundtruth")
    if gpath is not None:
        gt = _read_table(gpath, _GT_COLS, min_rows=1)
        _check_time_order(gpath, gt[:, 0])
    return RobotData(robot=n, time=m[:, 0], barcode=barcode, range=m[:, 2], bearing=m[:, 3],
                     subject=subject, is_landmark=is_lm, view_times=vt, visible=vis,
                     view_bearings=vb, view_ranges=vr, odometry=odo, groundtruth=gt,
                     n_landmark=int(is_lm.sum()), n_robot=int((~is_lm & ~unknown).sum()),
                     n_unknown=int(unknown.sum()),
                     unknown_barcodes=tuple(int(b) for b in np.unique(barcode[unknown])),
                     n_duplicate=n_dup, n_repeated_views=n_rep)


def load(path) -> MRCLAMDataset:
    """Read an MRCLAM dataset directory (files plain or ``.gz``).

    Raises :class:`DataFormatError` (a ValueError) naming the file and line for a missing
    ``Barcodes``/``Landmark_Groundtruth`` file, a wrong number of columns, text where numbers belong,
    a non-integer subject or barcode, a subject or barcode listed twice, or time going backwards.
    A robot is loaded for every ``RobotN_Measurement`` file; its odometry and ground truth are
    optional (``RobotData.odometry`` / ``groundtruth`` are then None). When a file exists both plain
    and compressed, the plain one is read.

    Example: ``ds = load("../shared/data/mrclam/MRCLAM_Dataset1")``; then ``sorted(ds.robots)`` is
    ``[1, 2, 3, 4, 5]`` and ``ds.robot(1).view_times`` the robot's view time stamps.
    """
    directory = Path(path)
    if not directory.is_dir():
        raise DataFormatError(directory, None, "not a directory")
    bpath = _find_file(directory, "Barcodes")
    if bpath is None:
        raise DataFormatError(directory / "Barcodes.dat", None, "file not found (nor .dat.gz)")
    lpath = _find_file(directory, "Landmark_Groundtruth")
    if lpath is None:
        raise DataFormatError(directory / "Landmark_Groundtruth.dat", None,
                              "file not found (nor .dat.gz): landmark ground truth is required")
    bc = _read_table(bpath, _BARCODE_COLS, min_rows=1)
    subj = _check_integer_column(bpath, bc, 0, "subject")
    code = _check_integer_column(bpath, bc, 1, "barcode")
    _check_unique(bpath, subj, "subject")
    _check_unique(bpath, code, "barcode")
    b2s = dict(zip(code.tolist(), subj.tolist(), strict=True))
    lm = _read_table(lpath, _LANDMARK_COLS, min_rows=3)
    lid = _check_integer_column(lpath, lm, 0, "subject")
    _check_unique(lpath, lid, "subject")
    order = np.argsort(lid, kind="stable")
    landmark_ids = lid[order]
    robots_m = _robot_numbers(directory, "Measurement")
    for kind in ("Odometry", "Groundtruth"):
        orphan = sorted(_robot_numbers(directory, kind) - robots_m)
        if orphan:
            raise DataFormatError(directory / f"Robot{orphan[0]}_Measurement.dat", None,
                                  f"file not found, but Robot{orphan[0]}_{kind} exists")
    robots = {n: _load_robot(directory, n, b2s, landmark_ids) for n in sorted(robots_m)}
    return MRCLAMDataset(path=str(directory),
                         barcodes=dict(zip(subj.tolist(), code.tolist(), strict=True)),
                         landmark_ids=landmark_ids, landmark_xy=lm[order, 1:3],
                         landmark_std=lm[order, 3:5], robots=robots)


# ----------------------------------------------------------------------------------------------
# Odometry

def integrate_odometry(time, v, omega, query_times, *, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Dead-reckoned poses (n, 3) ``(x, y, theta)`` at ``query_times`` (n,) from a velocity log.

    Command k, ``(v[k], omega[k])``, holds on ``[time[k], time[k+1])``; the robot is at ``start``
    at ``time[0]``. Over an interval of length dt with heading theta at its start the motion is the
    exact circular arc: the heading turns by ``d = omega dt`` and the position moves along the chord

        ``v dt * sinc(d / 2) * (cos(theta + d / 2), sin(theta + d / 2))``,  sinc(u) = sin(u) / u,

    which is the straight segment ``v dt`` when omega = 0 (no division by omega anywhere). Headings
    and positions at the records are prefix sums (vectorized); a query inside an interval applies
    the partial arc from the record before it. Headings are wrapped to (-pi, pi].

    ``query_times`` must lie in ``[time[0], time[-1]]``: the last command's duration is unknown.

    >>> integrate_odometry([0, 1, 2], [1, 1, 0], [0, np.pi / 2, 0], [1, 2]).round(6).tolist()
    [[1.0, 0.0, 0.0], [1.63662, 0.63662, 1.570796]]
    """
    t = as_float_array("time", time, ndim=1)
    v = as_float_array("v", v, ndim=1)
    w = as_float_array("omega", omega, ndim=1)
    if not (t.shape == v.shape == w.shape):
        raise ValueError(f"time, v, omega: expected equal lengths, got {t.shape}, {v.shape}, {w.shape}")
    if t.size < 2:
        raise ValueError(f"time: expected at least 2 records, got {t.size}")
    if np.any(np.diff(t) < 0):
        raise ValueError("time: expected non-decreasing values")
    q = as_float_array("query_times", query_times)
    s = as_float_array("start", start, ndim=1, last_dim=3)
    if q.size and (q.min() < t[0] or q.max() > t[-1]):
        raise ValueError(f"query_times: expected values in [{t[0]!r}, {t[-1]!r}] (the odometry's "
                         f"span), got [{q.min()!r}, {q.max()!r}]")
    dt = np.diff(t)
    dth = w[:-1] * dt
    theta = s[2] + np.concatenate([[0.0], np.cumsum(dth)])  # heading at each record
    chord = v[:-1] * dt * np.sinc(dth / (2 * np.pi))
    mid = theta[:-1] + dth / 2
    x = s[0] + np.concatenate([[0.0], np.cumsum(chord * np.cos(mid))])
    y = s[1] + np.concatenate([[0.0], np.cumsum(chord * np.sin(mid))])
    k = np.clip(np.searchsorted(t, q, side="right") - 1, 0, t.size - 2)
    tau = q - t[k]
    d = w[k] * tau
    c = v[k] * tau * np.sinc(d / (2 * np.pi))
    m = theta[k] + d / 2
    out = np.stack([x[k] + c * np.cos(m), y[k] + c * np.sin(m), wrap_angle(theta[k] + d)], axis=-1)
    return out


def dead_reckon(robot: RobotData, times=None, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Odometry poses (n, 3) of a robot at ``times`` (default: its view times), from ``start``
    at its first odometry record. ValueError when the robot has no odometry."""
    if robot.odometry is None:
        raise ValueError(f"robot: robot {robot.robot} has no odometry")
    times = robot.view_times if times is None else times
    return robot.odometry.poses(times, start=start)


# ----------------------------------------------------------------------------------------------
# Landmark fixes: a pose per view from range and bearing to known landmarks (diagnostic only)

@dataclass(frozen=True, eq=False)
class LandmarkFixes:
    """Robot poses estimated from range and bearing to known landmarks, one per view with >= 2.

    Not ground truth (robot ground truth is absent from the provided data); used to check the
    odometry and the bearing noise and to place a dead-reckoned path in the world frame.

    Attributes:
        times: (F,) view times (s).
        view_index: (F,) indices into ``RobotData.view_times``.
        poses: (F, 3) world poses (x, y, theta).
        n_landmarks: (F,) landmarks used.
        residual: (F,) root-mean-square distance (m) between the landmarks and their measured
            positions after the fit.
    """

    times: np.ndarray
    view_index: np.ndarray
    poses: np.ndarray
    n_landmarks: np.ndarray
    residual: np.ndarray


def _rigid_fits(ranges, bearings, visible, landmark_xy):
    """Poses (V, 3) and rms residuals (V,) of rigid fits, vectorized over views (see
    :func:`landmark_fixes`). ``visible`` (V, L) must have at least 2 True per row."""
    vis = visible.astype(float)
    n = vis.sum(axis=1)
    q = ranges[..., None] * np.stack([np.cos(bearings), np.sin(bearings)], axis=-1)
    p = np.broadcast_to(landmark_xy, q.shape)
    qm = np.einsum("vl,vld->vd", vis, q) / n[:, None]
    pm = np.einsum("vl,vld->vd", vis, p) / n[:, None]
    qc, pc = q - qm[:, None], p - pm[:, None]
    cross = np.einsum("vl,vl->v", vis, qc[..., 0] * pc[..., 1] - qc[..., 1] * pc[..., 0])
    dot = np.einsum("vl,vl->v", vis, np.sum(qc * pc, axis=-1))
    th = np.arctan2(cross, dot)
    c, s = np.cos(th), np.sin(th)
    t = pm - np.stack([c * qm[:, 0] - s * qm[:, 1], s * qm[:, 0] + c * qm[:, 1]], axis=-1)
    rq = np.stack([c[:, None] * q[..., 0] - s[:, None] * q[..., 1],
                   s[:, None] * q[..., 0] + c[:, None] * q[..., 1]], axis=-1) + t[:, None]
    res = np.sqrt(np.einsum("vl,vl->v", vis, np.sum((rq - p) ** 2, axis=-1)) / n)
    return np.column_stack([t, wrap_angle(th)]), res


def landmark_fixes(dataset: MRCLAMDataset, robot, *, min_landmarks: int = 2,
                   exclude=None) -> LandmarkFixes:
    """Least-squares rigid fit of each view's measured landmark positions to their ground truth.

    A landmark seen at range r and bearing phi is at ``q = r (cos phi, sin phi)`` in the robot
    frame. For views with at least ``min_landmarks`` landmarks, the pose (R(theta), t) minimizing
    ``sum_i |R q_i + t - p_i|^2`` is the 2-D Procrustes solution: with centred points,
    ``theta = atan2(sum q x p, sum q . p)`` and ``t = mean(p) - R mean(q)`` (vectorized over views).
    ``exclude``: landmark subject numbers left out of every fit.
    """
    rd = dataset.robot(robot)
    min_landmarks = positive_int("min_landmarks", min_landmarks, minimum=2)
    visible = rd.visible
    if exclude is not None:
        visible = visible.copy()
        visible[:, dataset.landmark_index(np.atleast_1d(exclude))] = False
    sel = np.flatnonzero(visible.sum(axis=1) >= min_landmarks)
    poses, res = _rigid_fits(rd.view_ranges[sel], rd.view_bearings[sel], visible[sel],
                             dataset.landmark_xy)
    return LandmarkFixes(times=rd.view_times[sel], view_index=sel, poses=poses,
                         n_landmarks=visible[sel].sum(axis=1).astype(int), residual=res)


@dataclass(frozen=True, eq=False)
class LandmarkCheck:
    """Where each landmark is seen, against its ground truth (:func:`check_landmarks`).

    Attributes:
        landmark_ids: (L,) subject numbers.
        n_observations: (L,) measurements used (seen from a good fix made without the landmark).
        observed_xy: (L, 2) median world position of those measurements (m); ground truth where
            there are none.
        error: (L,) distance (m) from ``observed_xy`` to the landmark's ground truth.
        nearest: (L,) subject whose ground truth is nearest to ``observed_xy``.
        swaps: pairs (a, b), a < b, each seen at the other's ground-truth position.
    """

    landmark_ids: np.ndarray
    n_observations: np.ndarray
    observed_xy: np.ndarray
    error: np.ndarray
    nearest: np.ndarray
    swaps: tuple


def check_landmarks(dataset: MRCLAMDataset, *, min_landmarks: int = 3, max_residual: float = 0.15,
                    tolerance: float = 0.5) -> LandmarkCheck:
    """Check the barcode -> landmark -> ground-truth chain against the measurements themselves.

    For each landmark l and robot, fix the robot's pose in every view from the *other* landmarks
    (:func:`landmark_fixes` with ``exclude=l``, at least ``min_landmarks``, rms residual at most
    ``max_residual`` m) and place l's range-bearing measurement in the world. The median of those
    positions should be at l's ground truth; a pair of landmarks each seen within ``tolerance`` m
    of the other's ground truth (and not of its own) is reported as a swap.
    """
    L = dataset.landmark_ids.size
    n_obs = np.zeros(L, dtype=int)
    obs_xy = dataset.landmark_xy.copy()
    for li, lid in enumerate(dataset.landmark_ids):
        pts = []
        for n, rd in dataset.robots.items():
            f = landmark_fixes(dataset, n, min_landmarks=min_landmarks, exclude=lid)
            ok = (f.residual <= max_residual) & rd.visible[f.view_index, li]
            v, P = f.view_index[ok], f.poses[ok]
            r, b = rd.view_ranges[v, li], rd.view_bearings[v, li]
            pts.append(P[:, :2] + r[:, None] * np.stack([np.cos(P[:, 2] + b), np.sin(P[:, 2] + b)], -1))
        pts = np.concatenate(pts) if pts else np.zeros((0, 2))
        n_obs[li] = pts.shape[0]
        if pts.shape[0]:
            obs_xy[li] = np.median(pts, axis=0)
    d = np.linalg.norm(obs_xy[:, None, :] - dataset.landmark_xy[None, :, :], axis=-1)  # (L, L)
    nearest_col = np.argmin(d, axis=1)
    err = d[np.arange(L), np.arange(L)]
    swaps = []
    for i in range(L):
        j = int(nearest_col[i])
        if (j > i and nearest_col[j] == i and d[i, j] <= tolerance and d[j, i] <= tolerance
                and err[i] > tolerance and err[j] > tolerance):
            swaps.append((int(dataset.landmark_ids[i]), int(dataset.landmark_ids[j])))
    return LandmarkCheck(landmark_ids=dataset.landmark_ids.copy(), n_observations=n_obs,
                         observed_xy=obs_xy, error=err, nearest=dataset.landmark_ids[nearest_col],
                         swaps=tuple(swaps))


def swap_landmarks(dataset: MRCLAMDataset, pairs) -> MRCLAMDataset:
    """A copy of ``dataset`` with the ground truth (position, std-dev) of each landmark pair (a, b)
    exchanged. Measurements, barcodes and views are unchanged: only what the ids are scored
    against moves. Use with :func:`check_landmarks`: ``swap_landmarks(ds, check_landmarks(ds).swaps)``.
    """
    xy, sd = dataset.landmark_xy.copy(), dataset.landmark_std.copy()
    for pair in pairs:
        if len(pair) != 2:
            raise ValueError(f"pairs: expected (a, b) pairs of landmark subjects, got {pair!r}")
        i, j = dataset.landmark_index(pair)
        xy[[i, j]] = xy[[j, i]]
        sd[[i, j]] = sd[[j, i]]
    return replace(dataset, landmark_xy=xy, landmark_std=sd)


def bearing_residuals(dataset: MRCLAMDataset, robot, *, min_landmarks: int = 4,
                      max_residual: float = 0.3) -> np.ndarray:
    """Measured minus predicted bearings (radians) at the landmark fixes of views with at least
    ``min_landmarks`` landmarks (rms residual at most ``max_residual`` m).

    The fit uses the same measurements (3 pose parameters from 2n numbers), so the spread of
    these residuals underestimates the bearing noise by about ``sqrt((2n - 3) / 2n)``.
    """
    rd = dataset.robot(robot)
    f = landmark_fixes(dataset, robot, min_landmarks=min_landmarks)
    ok = f.residual <= max_residual
    v = f.view_index[ok]
    pred = bearing(f.poses[ok][:, None, :], dataset.landmark_xy[None, :, :])
    return wrap_angle(rd.view_bearings[v] - pred)[rd.visible[v]]


def odometry_check(dataset: MRCLAMDataset, robot, *, bins=((0.5, 3.0), (3.0, 10.0), (10.0, 30.0),
                                                           (30.0, 100.0)),
                   max_residual: float = 0.1, min_landmarks: int = 3) -> list[dict]:
    """How far the odometry's turn drifts from the landmark fixes' turn, by time between fixes.

    For every pair of good fixes (rms residual at most ``max_residual`` m) whose time difference
    falls in a bin ``(lo, hi]`` seconds, the error is ``wrap((theta_j - theta_i)_fixes -
    (theta_j - theta_i)_odometry)``. Returns one row per bin: ``lo, hi, n`` and the median and
    90th percentile of the absolute error in degrees (NaN-free: bins without pairs have n = 0 and
    zeros). Empty for a robot without odometry.
    """
    rd = dataset.robot(robot)
    if rd.odometry is None:
        return []
    f = landmark_fixes(dataset, robot, min_landmarks=min_landmarks)
    o = rd.odometry
    good = (f.residual <= max_residual) & (f.times >= o.time[0]) & (f.times <= o.time[-1])
    ft, fth = f.times[good], f.poses[good, 2]
    oth = o.poses(ft)[:, 2]
    dt = ft[None, :] - ft[:, None]
    rows = []
    for lo, hi in bins:
        i, j = np.nonzero((dt > lo) & (dt <= hi))
        err = np.degrees(np.abs(wrap_angle((fth[j] - fth[i]) - (oth[j] - oth[i]))))
        rows.append({"lo": float(lo), "hi": float(hi), "n": int(i.size),
                     "median_abs_deg": float(np.median(err)) if i.size else 0.0,
                     "p90_abs_deg": float(np.percentile(err, 90)) if i.size else 0.0})
    return rows


def anchored_dead_reckoning(dataset: MRCLAMDataset, robot, times=None, *, anchor_time=None,
                            max_residual: float = 0.15, min_landmarks: int = 3):
    """Dead-reckoned world poses (n, 3) of a robot at ``times`` (default: its odometry records).

    Robot ground truth being absent, the odometry path is placed in the world by the rigid
    transform that makes it pass through one landmark fix (at least ``min_landmarks`` landmarks,
    rms residual at most ``max_residual`` m) with the fix's heading: the first such fix, or the
    one nearest to ``anchor_time``. Drift then shows as the distance to other fixes. Returns
    ``(poses, anchor_time)``; ValueError if the robot has no odometry or no such fix.
    """
    rd = dataset.robot(robot)
    if rd.odometry is None:
        raise ValueError(f"robot: robot {rd.robot} of {dataset.name} has no odometry")
    f = landmark_fixes(dataset, robot, min_landmarks=min_landmarks)
    o = rd.odometry
    good = np.flatnonzero((f.residual <= max_residual) & (f.times >= o.time[0]) & (f.times <= o.time[-1]))
    if good.size == 0:
        raise ValueError(f"robot: robot {rd.robot} has no landmark fix with >= {min_landmarks} "
                         f"landmarks and residual <= {max_residual} m")
    k = good[0] if anchor_time is None else good[np.argmin(np.abs(f.times[good] - anchor_time))]
    times = o.time if times is None else as_float_array("times", times, ndim=1)
    D = o.poses(np.concatenate([[f.times[k]], times]))
    phi = f.poses[k, 2] - D[0, 2]
    c, s = np.cos(phi), np.sin(phi)
    rel = D[1:, :2] - D[0, :2]
    xy = f.poses[k, :2] + np.column_stack([c * rel[:, 0] - s * rel[:, 1], s * rel[:, 0] + c * rel[:, 1]])
    return np.column_stack([xy, wrap_angle(D[1:, 2] + phi)]), float(f.times[k])


# ----------------------------------------------------------------------------------------------
# Triplet histories

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


def _view_poses(rd: RobotData):
    """Dead-reckoned poses (V, 3) at every view (zeros where not covered) and the (V,) mask of
    views inside the odometry's time span; ``(None, all True)`` without odometry."""
    if rd.odometry is None:
        return None, np.ones(rd.n_views, dtype=bool)
    t = rd.odometry.time
    covered = (rd.view_times >= t[0]) & (rd.view_times <= t[-1])
    poses = np.zeros((rd.n_views, 3))
    poses[covered] = rd.odometry.poses(rd.view_times[covered])
    return poses, covered


def triplet_segments(dataset: MRCLAMDataset, robot, *, min_views: int = 3,
                     max_gap: float = DEFAULT_MAX_GAP, min_travel: float = DEFAULT_MIN_TRAVEL,
                     min_interval: float = DEFAULT_MIN_INTERVAL, max_views: int | None = None
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
    poses, covered = _view_poses(rd)
    rich = np.flatnonzero((rd.visible.sum(axis=1) >= 3) & covered)
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


def _interp_poses(gt: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Ground-truth poses at ``times``: linear in x, y and in the unwrapped orientation."""
    th = np.unwrap(gt[:, 3])
    return np.column_stack([np.interp(times, gt[:, 0], gt[:, 1]), np.interp(times, gt[:, 0], gt[:, 2]),
                            wrap_angle(np.interp(times, gt[:, 0], th))])


def triplet_histories(dataset: MRCLAMDataset, robot, *, min_views: int = 3,
                      max_gap: float = DEFAULT_MAX_GAP, min_travel: float = DEFAULT_MIN_TRAVEL,
                      min_interval: float = DEFAULT_MIN_INTERVAL, max_views: int | None = None,
                      sigma_bearing: float = DEFAULT_SIGMA_BEARING,
                      sigma_heading: float = DEFAULT_SIGMA_HEADING, partition="edc"
                      ) -> list[TripletHistory]:
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
    * ``truth``: the landmark ground truth (``landmarks_world``, ``C_ab``, ``state`` in
      ``partition``). Camera poses are only known when ``RobotN_Groundtruth`` is present; otherwise
      ``poses_world``, ``poses_ab`` and ``camera_states`` are None.

    Every segment gives the six orderings of its three landmarks; a triplet seen in several passes
    gives several histories. Sorted by (landmarks, first view time).
    """
    rd = dataset.robot(robot)
    sb = non_negative("sigma_bearing", sigma_bearing)
    sh = non_negative("sigma_heading", sigma_heading)
    part = _partitions.get(partition)
    segs = triplet_segments(dataset, robot, min_views=min_views, max_gap=max_gap,
                            min_travel=min_travel, min_interval=min_interval, max_views=max_views)
    if not segs:
        return []
    poses, _ = _view_poses(rd)
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
        else:
            psi = np.zeros(vi.size - 1)
        gt_poses = None if rd.groundtruth is None else _interp_poses(rd.groundtruth, times)
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
            out.append(TripletHistory(landmarks=perm, bearings=phi, headings=psi, sigma_bearing=sb,
                                      sigma_heading=sh, views=times, truth=truth,
                                      has_motion=rd.odometry is not None))
    out.sort(key=lambda h: (h.landmarks, h.views[0]))
    return out


def history_counts(dataset: MRCLAMDataset, **options) -> dict:
    """Per robot: views, views with >= 3 landmarks, unordered triplets seen in >= ``min_views``
    views before thinning, segments (unordered histories) and ordered histories, after grouping
    with ``options`` (those of :func:`triplet_segments`). Also the dataset totals under ``"all"``,
    including ``distinct_triplets``: unordered triplets with a history from any robot.
    """
    min_views = options.get("min_views", 3)
    rows = {}
    distinct = set()
    for n, rd in dataset.robots.items():
        segs = triplet_segments(dataset, n, **options)
        L = dataset.landmark_ids.size
        combos = np.array(list(itertools.combinations(range(L), 3)))
        vis = rd.visible
        together = vis[:, combos[:, 0]] & vis[:, combos[:, 1]] & vis[:, combos[:, 2]]
        trip = {s.landmarks for s in segs}
        distinct |= trip
        rows[n] = {"views": rd.n_views, "views_3plus": int((vis.sum(axis=1) >= 3).sum()),
                   "triplets_raw": int((together.sum(axis=0) >= min_views).sum()),
                   "triplets": len(trip), "segments": len(segs), "histories": 6 * len(segs),
                   "has_odometry": rd.has_odometry}
    tot = {k: sum(r[k] for r in rows.values())
           for k in ("views", "views_3plus", "triplets_raw", "triplets", "segments", "histories")}
    tot["distinct_triplets"] = len(distinct)
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


def _main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python -m qfg.datasets.mrclam",
                                 description="Per-robot summary of MRCLAM dataset directories.")
    ap.add_argument("paths", nargs="+", help="dataset directories (MRCLAM_DatasetN)")
    ap.add_argument("--min-views", type=int, default=3)
    ap.add_argument("--max-gap", type=float, default=DEFAULT_MAX_GAP)
    ap.add_argument("--min-travel", type=float, default=DEFAULT_MIN_TRAVEL)
    ap.add_argument("--min-interval", type=float, default=DEFAULT_MIN_INTERVAL)
    ap.add_argument("--max-views", type=int, default=None)
    ap.add_argument("--check", action="store_true",
                    help="also check the data: landmark identities, bearing residuals, odometry drift")
    a = ap.parse_args(argv)
    opts = dict(min_views=a.min_views, max_gap=a.max_gap, min_travel=a.min_travel,
                min_interval=a.min_interval, max_views=a.max_views)
    cols = ["dataset", "robot", "has_odometry", "measurements", "landmark", "robot_meas", "unknown",
            "repeated_views", "views", "views_3plus", "triplets_raw", "triplets", "segments",
            "histories"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for p in a.paths:
        ds = load(p)
        rows = summary_rows(ds, **opts)
        for r in rows:
            print("| " + " | ".join(str(r[c]) for c in cols) + " |")
        tot = history_counts(ds, **opts)["all"]
        print(f"| {ds.name} | all | | | | | | | {tot['views']} | {tot['views_3plus']} | "
              f"{tot['triplets_raw']} | {tot['triplets']} (distinct {tot['distinct_triplets']}) | "
              f"{tot['segments']} | {tot['histories']} |")
    if a.check:
        for p in a.paths:
            _print_check(load(p))
    return 0


def _rng_str(vals, fmt="{:.2f}") -> str:
    vals = [v for v in vals if v is not None]
    return (fmt + ".." + fmt).format(min(vals), max(vals)) if vals else "-"


def _print_check(ds: MRCLAMDataset) -> None:
    rds = list(ds.robots.values())
    odo = [rd.odometry for rd in rds if rd.odometry is not None]
    span = _rng_str([np.ptp(rd.time) for rd in rds], "{:.0f}")
    gap = _rng_str([np.median(np.diff(rd.view_times)) for rd in rds])
    rich = _rng_str([100 * np.mean(rd.visible.sum(axis=1) >= 3) for rd in rds], "{:.1f}")
    lo, hi = _rng_str([rd.bearing.min() for rd in rds]), _rng_str([rd.bearing.max() for rd in rds])
    print(f"\n{ds.name}: measurement span per robot {span} s; median time between views {gap} s; "
          f"views with >= 3 landmarks {rich}%; bearings min {lo}, max {hi} rad")
    if odo:
        firsts = [rd.time[0] - rd.odometry.time[0] for rd in rds if rd.odometry is not None]
        lasts = [rd.odometry.time[-1] - rd.time[-1] for rd in rds if rd.odometry is not None]
        print(f"  odometry: median record interval "
              f"{_rng_str([np.median(np.diff(o.time)) for o in odo], '{:.3f}')} s, max gap "
              f"{_rng_str([o.max_gap for o in odo])} s, v min {_rng_str([o.v.min() for o in odo])} "
              f"max {_rng_str([o.v.max() for o in odo])} m/s, omega min "
              f"{_rng_str([o.omega.min() for o in odo])} max {_rng_str([o.omega.max() for o in odo])}"
              f" rad/s; starts {_rng_str(firsts)} s before the first measurement, ends "
              f"{_rng_str(lasts, '{:.3f}')} s after the last")
    chk = check_landmarks(ds)
    print(f"  landmark check: swaps {list(chk.swaps)}; distance of each landmark's "
          f"measured position to its ground truth (m): median {np.median(chk.error):.2f}, "
          f"max {chk.error.max():.2f} (subject {int(chk.landmark_ids[np.argmax(chk.error)])})")
    fixed = swap_landmarks(ds, chk.swaps)
    if chk.swaps:
        chk2 = check_landmarks(fixed)
        print(f"  after swapping {list(chk.swaps)}: swaps {list(chk2.swaps)}; median "
              f"{np.median(chk2.error):.2f} m, max {chk2.error.max():.2f} m")
    res_m = np.concatenate([landmark_fixes(fixed, n, min_landmarks=4).residual for n in ds.robots])
    print(f"  fix residual (>= 4 landmarks) median {np.median(res_m):.3f} m")
    res = np.degrees(np.concatenate([bearing_residuals(fixed, n) for n in ds.robots]))
    if res.size:
        mad = 1.4826 * np.median(np.abs(res - np.median(res)))
        print(f"  bearing residuals at fixes with >= 4 landmarks (after swaps): n {res.size}, "
              f"std {res.std():.2f} deg, robust std {mad:.2f} deg, mean {res.mean():.2f} deg")
    pooled: dict = {}
    for n in ds.robots:
        for row in odometry_check(fixed, n):
            pooled.setdefault((row["lo"], row["hi"]), []).append(row)
    for (lo, hi), rows in pooled.items():
        tot = sum(r["n"] for r in rows)
        meds = [r["median_abs_deg"] for r in rows if r["n"]]
        p90s = [r["p90_abs_deg"] for r in rows if r["n"]]
        if tot:
            print(f"  odometry turn error vs fixes, pairs {lo:g}-{hi:g} s apart: n {tot}, median |err| "
                  f"per robot {min(meds):.1f}-{max(meds):.1f} deg, 90th pct {min(p90s):.1f}-"
                  f"{max(p90s):.1f} deg")


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(_main())
