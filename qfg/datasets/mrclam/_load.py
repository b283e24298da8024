"""Loading an MRCLAM dataset directory: files -> :class:`MRCLAMDataset` with its :class:`LoadReport`."""

from __future__ import annotations

import math
import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..._validate import non_negative
from ._constants import DATA_ENV, DEFAULT_VIEW_GAP
from ._data import LoadReport, MRCLAMDataset, Odometry, RobotData, RobotQuirks, _repeated
from ._io import Column, DataFormatError, Table, check_unique, find_file, read_table

_BARCODE_COLS = (Column("subject", integer=True), Column("barcode", integer=True))
_LANDMARK_COLS = (Column("subject", integer=True), Column("x"), Column("y"),
                  Column("x std-dev", lo=0.0), Column("y std-dev", lo=0.0))
# bearings are written with 3 decimals, so +-pi may read as +-3.142
_PI = math.pi + 5e-4
_MEAS_COLS = (Column("time"), Column("barcode", integer=True), Column("range", lo=0.0),
              Column("bearing", lo=-_PI, hi=_PI))
_ODO_COLS = (Column("time"), Column("forward velocity"), Column("angular velocity"))
_GT_COLS = (Column("time"), Column("x"), Column("y"), Column("orientation"))
# two stamps closer than this are equal: stamps are written to the millisecond and a float holds
# 1.2e9 s to about 2.4e-7 s
_STAMP_TOL = 1e-6


def _robot_numbers(directory: Path, kind: str) -> set[int]:
    """Robot numbers N of the ``RobotN_<kind>.dat(.gz)`` names in ``directory``. A number written
    with a leading zero (``Robot01_...``) is a DataFormatError naming the file: the loader looks
    files up as ``Robot1_...``, so it would otherwise go unread or be read twice."""
    out = set()
    for p in sorted(directory.glob(f"Robot*_{kind}.dat*")):
        stem = p.name.split("_", 1)[0][len("Robot"):]
        if stem.isdigit() and p.name.endswith((".dat", ".dat.gz")):
            if stem != str(int(stem)):
                raise DataFormatError(p, None, f"robot number written as {stem!r}: MRCLAM names "
                                               f"robot files Robot1_ ... Robot5_; rename it "
                                               f"Robot{int(stem)}_{p.name.split('_', 1)[1]}")
            out.add(int(stem))
    return out


def _time_order(table: Table):
    """Stable time order of a table's rows: (order or None when already sorted, rows stamped
    earlier than the row before, largest step back in seconds)."""
    dt = np.diff(table.data[:, 0])
    back = int(np.count_nonzero(dt < 0))
    if not back:
        return None, 0, 0.0
    return np.argsort(table.data[:, 0], kind="stable"), back, float(-dt.min())


def _views(time, subject, rng_, brg, landmark_ids, gap):
    """Group landmark rows (time-sorted) into views: a row within ``gap`` s of the row before
    joins its view. Returns view times, (V, L) visibility, bearings and ranges, and the counts
    (merged stamps, duplicate rows, repeated views, longest view span)."""
    L = landmark_ids.size
    if time.size == 0:
        z = np.zeros((0, L))
        return np.zeros(0), z.astype(bool), z, z.copy(), 0, 0, 0, 0.0
    dt = np.diff(time)
    new = np.concatenate([[True], dt > gap + _STAMP_TOL])
    view = np.cumsum(new) - 1
    starts = np.flatnonzero(new)
    vt = time[starts]
    ends = np.concatenate([starts[1:], [time.size]]) - 1
    span = float(np.max(time[ends] - vt))
    n_stamps = 1 + int(np.count_nonzero(dt > _STAMP_TOL))
    col = np.searchsorted(landmark_ids, subject)
    cell = view * L + col
    _, first = np.unique(cell, return_index=True)  # first row of each (view, landmark) cell
    n_dup = cell.size - first.size
    visible = np.zeros((vt.size, L), dtype=bool)
    bearings = np.zeros((vt.size, L))
    ranges = np.zeros((vt.size, L))
    visible[view[first], col[first]] = True
    bearings[view[first], col[first]] = brg[first]
    ranges[view[first], col[first]] = rng_[first]
    return (vt, visible, bearings, ranges, n_stamps - vt.size, int(n_dup),
            int(np.count_nonzero(_repeated(visible, bearings, ranges))), span)


def _load_robot(directory: Path, n: int, b2s: dict, landmark_ids: np.ndarray, gap: float):
    q: dict = {"robot": n}
    mtab = read_table(find_file(directory, f"Robot{n}_Measurement"), _MEAS_COLS)
    m = mtab.data
    order, q["measurements_out_of_order"], q["measurements_max_backstep"] = _time_order(mtab)
    if order is not None:
        m = m[order]
    q["measurement_rows"] = m.shape[0]
    q["empty_measurement_file"] = m.shape[0] == 0
    barcode = m[:, 1].astype(np.int64)
    codes, inv = np.unique(barcode, return_inverse=True)
    subject = np.array([b2s.get(int(b), -1) for b in codes], dtype=np.int64)[inv.ravel()]
    is_lm = np.isin(subject, landmark_ids)
    unknown = subject < 0
    vt, vis, vb, vr, q["merged_stamps"], n_dup, n_rep, q["max_view_span"] = _views(
        m[is_lm, 0], subject[is_lm], m[is_lm, 2], m[is_lm, 3], landmark_ids, gap)
    q.update(landmark_rows=int(is_lm.sum()), robot_rows=int((~is_lm & ~unknown).sum()),
             unknown_rows=int(unknown.sum()),
             unknown_barcodes=tuple(int(b) for b in np.unique(barcode[unknown])),
             duplicate_landmarks=n_dup, repeated_views=n_rep, views=int(vt.size))
    odo = None
    opath = find_file(directory, f"Robot{n}_Odometry")
    if opath is not None:
        otab = read_table(opath, _ODO_COLS, min_rows=2)
        o = otab.data
        order, q["odometry_out_of_order"], q["odometry_max_backstep"] = _time_order(otab)
        if order is not None:
            o = o[order]
        q["odometry_rows"] = o.shape[0]
        q["odometry_duplicate_stamps"] = int(np.count_nonzero(np.diff(o[:, 0]) == 0))
        q["views_outside_odometry"] = int(np.count_nonzero((vt < o[0, 0]) | (vt > o[-1, 0])))
        odo = Odometry(time=o[:, 0], v=o[:, 1], omega=o[:, 2], path=str(opath))
    gt = None
    gpath = find_file(directory, f"Robot{n}_Groundtruth")
    if gpath is not None:
        gtab = read_table(gpath, _GT_COLS, min_rows=2)
        gt = gtab.data
        order, q["groundtruth_out_of_order"], _ = _time_order(gtab)
        if order is not None:
            gt = gt[order]
        q["groundtruth_rows"] = gt.shape[0]
        dup = np.concatenate([[False], np.diff(gt[:, 0]) == 0])
        q["groundtruth_duplicate_stamps"] = int(dup.sum())
        gt = gt[~dup]
    rd = RobotData(robot=n, time=m[:, 0], barcode=barcode, range=m[:, 2], bearing=m[:, 3],
                   subject=subject, is_landmark=is_lm, view_times=vt, visible=vis,
                   view_bearings=vb, view_ranges=vr, odometry=odo, groundtruth=gt,
                   n_landmark=q["landmark_rows"], n_robot=q["robot_rows"],
                   n_unknown=q["unknown_rows"], unknown_barcodes=q["unknown_barcodes"],
                   n_duplicate=n_dup, n_repeated_views=n_rep)
    if gt is not None:
        q["views_outside_groundtruth"] = int(np.count_nonzero(~rd.groundtruth_poses(vt)[1]))
    return replace(rd, quirks=RobotQuirks(**q))


def _natural_key(p: Path):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name)]


def find_datasets(root) -> list[Path]:
    """Dataset directories (those holding ``Barcodes.dat(.gz)``) directly inside ``root``, in
    natural order (``MRCLAM_Dataset2`` before ``MRCLAM_Dataset10``); ``[root]`` when ``root`` is
    itself one. DataFormatError when ``root`` is not a directory or holds none."""
    root = Path(root)
    if not root.is_dir():
        raise DataFormatError(root, None, "not a directory")
    if find_file(root, "Barcodes") is not None:
        return [root]
    found = sorted((p for p in root.iterdir() if p.is_dir() and find_file(p, "Barcodes")),
                   key=_natural_key)
    if not found:
        raise DataFormatError(root, None, "no MRCLAM dataset here: neither Barcodes.dat(.gz) nor "
                                          "a sub-directory holding one")
    return found


def data_root(path=None) -> Path:
    """The directory holding the MRCLAM datasets: ``path`` when given, else the environment
    variable ``QFG_MRCLAM_DIR``. ValueError naming both when neither is set."""
    if path is None:
        path = os.environ.get(DATA_ENV) or None
    if path is None:
        raise ValueError(f"path: no MRCLAM data directory given; pass one or set {DATA_ENV} to the "
                         f"directory holding the MRCLAM_Dataset* directories")
    return Path(path).expanduser()


def load(path, *, view_gap: float = DEFAULT_VIEW_GAP) -> MRCLAMDataset:
    """Read an MRCLAM dataset directory (files plain or ``.gz``) into an :class:`MRCLAMDataset`.

    Landmark rows whose stamps follow each other within ``view_gap`` seconds (default 10 ms; 0
    merges only equal stamps) form one view. Quirks of real files are handled and counted in
    ``dataset.report`` (:class:`LoadReport`): rows or records stamped out of order are sorted,
    duplicate ground-truth stamps dropped, robot and unknown-barcode rows set aside, split images
    merged. Malformed input raises :class:`DataFormatError` (a ValueError) naming the file and line:
    a missing ``Barcodes``/``Landmark_Groundtruth`` file, a 0-byte, corrupt or truncated file, a
    non-ASCII byte outside a ``#`` comment, a wrong number of columns, text or NaN/inf where numbers
    belong, a non-integer subject or barcode, a subject or barcode listed twice, a negative range or
    std-dev, a bearing outside [-pi, pi]. A directory that holds dataset directories instead of
    being one gets an error listing them. A robot is loaded for every ``RobotN_Measurement`` file;
    its odometry and ground truth are optional. When a file exists plain and compressed, the plain
    one is read.

    Example: ``ds = load(data_root() / "MRCLAM_Dataset1")``; then ``sorted(ds.robots)`` is
    ``[1, 2, 3, 4, 5]`` and ``ds.robot(1).view_times`` the robot's view time stamps.
    """
    directory = Path(path)
    gap = non_negative("view_gap", view_gap)
    if not directory.is_dir():
        raise DataFormatError(directory, None, "not a directory")
    bpath = find_file(directory, "Barcodes")
    if bpath is None:
        subs = sorted((p.name for p in directory.iterdir()
                       if p.is_dir() and find_file(p, "Barcodes") is not None),
                      key=lambda s: _natural_key(Path(s)))
        if subs:
            raise DataFormatError(directory, None, f"this directory holds MRCLAM datasets, it is not "
                                                   f"one: pass one of {', '.join(subs)}")
        raise DataFormatError(directory / "Barcodes.dat", None, "file not found (nor .dat.gz)")
    lpath = find_file(directory, "Landmark_Groundtruth")
    if lpath is None:
        raise DataFormatError(directory / "Landmark_Groundtruth.dat", None,
                              "file not found (nor .dat.gz): landmark ground truth is required")
    bc = read_table(bpath, _BARCODE_COLS, min_rows=1)
    check_unique(bc, 0, "subject")
    check_unique(bc, 1, "barcode")
    subj, code = bc.data[:, 0].astype(np.int64), bc.data[:, 1].astype(np.int64)
    b2s = dict(zip(code.tolist(), subj.tolist(), strict=True))
    lm = read_table(lpath, _LANDMARK_COLS, min_rows=3)
    check_unique(lm, 0, "subject")
    lid = lm.data[:, 0].astype(np.int64)
    order = np.argsort(lid, kind="stable")
    landmark_ids = lid[order]
    robots_m = _robot_numbers(directory, "Measurement")
    for kind in ("Odometry", "Groundtruth"):
        orphan = sorted(_robot_numbers(directory, kind) - robots_m)
        if orphan:
            raise DataFormatError(directory / f"Robot{orphan[0]}_Measurement.dat", None,
                                  f"file not found, but Robot{orphan[0]}_{kind} exists")
    robots = {n: _load_robot(directory, n, b2s, landmark_ids, gap) for n in sorted(robots_m)}
    files = tuple(sorted(p.name for p in directory.iterdir()
                         if p.is_file() and p.name.endswith((".dat", ".dat.gz"))))
    report = LoadReport(dataset=directory.name, view_gap=gap,
                        robots=tuple(rd.quirks for rd in robots.values()), files=files)
    return MRCLAMDataset(path=str(directory),
                         barcodes=dict(zip(subj.tolist(), code.tolist(), strict=True)),
                         landmark_ids=landmark_ids, landmark_xy=lm.data[order, 1:3],
                         landmark_std=lm.data[order, 3:5], robots=robots, report=report)
