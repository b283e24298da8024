"""MRCLAM files as they come: split images merged into one view, quirks handled and counted,
malformed files rejected with file and line (issue 12 item 10), the data directory, motion capture.

Small datasets are written here in the MRCLAM format; expected views and counts are worked out by
hand from what was written. Tests on the real data skip when ``../shared/data/mrclam`` is absent.
"""

from __future__ import annotations

import gzip
import itertools
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data_dir
from hypothesis import given, settings
from hypothesis import strategies as st

from qfg.datasets import mrclam
from qfg.datasets.mrclam import DataFormatError
from qfg.datasets.mrclam import _noise as noise
from qfg.geometry import bearing as geo_bearing
from qfg.geometry import wrap_angle

HEADER = "# UTIAS Multi-Robot Cooperative Localization and Mapping Dataset\n# written by a test\n"
# dataset 2's split image: barcode 9 at .774, barcodes 81, 18, 14, 61, 7 at .775
SPLIT = (9, 81, 18, 14, 61, 7)
BARCODES = {1: 5, 2: 14 + 100, **{6 + i: b for i, b in enumerate(SPLIT)}, 12: 72}
LANDMARKS = {s: (float(s), float(s % 3)) for s in range(6, 13)}


def _write(path: Path, lines, gz=False):
    text = HEADER + "".join(line + "\n" for line in lines)
    if gz:
        with gzip.open(str(path) + ".gz", "wt") as fh:
            fh.write(text)
    else:
        path.write_text(text)


def small_dataset(d: Path, meas_rows, *, odometry=None, groundtruth=None, gz=False) -> Path:
    """A one-robot dataset: ``meas_rows`` (time, barcode, range, bearing) for robot 1."""
    d.mkdir(parents=True, exist_ok=True)
    _write(d / "Barcodes.dat", [f"{s} \t {b}" for s, b in sorted(BARCODES.items())])
    _write(d / "Landmark_Groundtruth.dat",
           [f"{s} \t {x} \t {y} \t 0.0001 \t 0.0001" for s, (x, y) in sorted(LANDMARKS.items())])
    _write(d / "Robot1_Measurement.dat", ["%.3f \t %d \t %.3f \t %.3f" % tuple(r) for r in meas_rows],
           gz)
    if odometry is not None:
        _write(d / "Robot1_Odometry.dat", ["%.3f \t %.3f \t %.3f" % tuple(r) for r in odometry], gz)
    if groundtruth is not None:
        _write(d / "Robot1_Groundtruth.dat", ["%.3f \t %.6f \t %.6f \t %.6f" % tuple(r)
                                              for r in groundtruth], gz)
    return d


def split_images(t0=1000.774, n=3, dt=1.0):
    """``n`` images, each logged as barcode 9 at t and the five others 1 ms later."""
    rows = []
    for k in range(n):
        t = t0 + k * dt
        rows.append((t, SPLIT[0], 2.0, 0.01 * k))
        rows += [(t + 0.001, b, 3.0 + j, -0.1 + 0.02 * j) for j, b in enumerate(SPLIT[1:])]
    return rows


# ----------------------------------------------------------------------------------------------
# one image logged row by row is one view

def test_rows_one_ms_apart_form_one_view(tmp_path):
    ds = mrclam.load(small_dataset(tmp_path / "D", split_images()))
    rd = ds.robot(1)
    assert rd.n_views == 3
    assert np.allclose(rd.view_times, 1000.774 + np.arange(3), atol=1e-6)   # first row's stamp
    assert rd.visible.sum(axis=1).tolist() == [6, 6, 6]
    q = ds.report.robot(1)
    assert q.merged_stamps == 3 and np.isclose(q.max_view_span, 0.001, atol=1e-6)
    # the bearings stay with their landmarks
    col = ds.landmark_index([6, 7])
    assert np.allclose(rd.view_bearings[2, col], [0.02, -0.1])
    # exact stamps only: the same rows make six views of 1 and 5 landmarks
    exact = mrclam.load(tmp_path / "D", view_gap=0.0).robot(1)
    assert exact.n_views == 6 and exact.visible.sum(axis=1).tolist() == [1, 5] * 3


def test_merging_recovers_the_triplets_of_the_whole_image(tmp_path):
    d = small_dataset(tmp_path / "D", split_images())
    merged = mrclam.history_counts(mrclam.load(d), min_views=3, min_interval=0.5)
    split = mrclam.history_counts(mrclam.load(d, view_gap=0.0), min_views=3, min_interval=0.5)
    # six landmarks in every image: C(6, 3) = 20 triplets; split, the five give C(5, 3) = 10
    assert merged["all"]["distinct_triplets"] == 20 and split["all"]["distinct_triplets"] == 10


def test_rows_further_apart_than_the_gap_are_separate_views(tmp_path):
    rows = [(1000.0, 9, 2.0, 0.0), (1000.009, 81, 2.0, 0.0), (1000.018, 18, 2.0, 0.0),
            (1000.040, 14, 2.0, 0.0)]
    rd = mrclam.load(small_dataset(tmp_path / "D", rows)).robot(1)
    # 9 ms steps chain into one view; 22 ms later is a new image
    assert rd.visible.sum(axis=1).tolist() == [3, 1]
    rd = mrclam.load(tmp_path / "D", view_gap=0.005).robot(1)
    assert rd.visible.sum(axis=1).tolist() == [1, 1, 1, 1]
    with pytest.raises(ValueError, match="view_gap"):
        mrclam.load(tmp_path / "D", view_gap=-0.001)


def test_duplicate_landmark_within_a_merged_view_keeps_the_first_row(tmp_path):
    rows = [(1000.0, 9, 2.0, 0.1), (1000.001, 9, 2.5, 0.3), (1000.001, 81, 2.0, 0.2)]
    ds = mrclam.load(small_dataset(tmp_path / "D", rows))
    rd = ds.robot(1)
    assert rd.n_views == 1 and ds.report.robot(1).duplicate_landmarks == 1
    assert rd.view_bearings[0, ds.landmark_index([6])[0]] == 0.1


# ----------------------------------------------------------------------------------------------
# quirks: handled, counted, and the result equals the clean file's

def test_measurements_out_of_order_are_sorted_and_counted(tmp_path):
    rows = split_images(n=4)
    clean = mrclam.load(small_dataset(tmp_path / "Clean", rows))
    swapped = list(rows)
    swapped[6], swapped[8] = swapped[8], swapped[6]   # an image's row written after the next's
    moved = swapped[:12] + [swapped[-1]] + swapped[12:-1]   # and the last image's row, much earlier
    ds = mrclam.load(small_dataset(tmp_path / "Quirky", moved))
    q = ds.report.robot(1)
    # row 6 (t1) after rows 8 and 7 (t1 + 1 ms); the last row (t3 + 1 ms) before row 12 (t2)
    assert q.measurements_out_of_order == 2
    assert np.isclose(q.measurements_max_backstep, 1.001, atol=1e-6)
    assert np.all(np.diff(ds.robot(1).time) >= 0)
    a, b = clean.robot(1), ds.robot(1)
    assert np.array_equal(a.view_times, b.view_times) and np.array_equal(a.visible, b.visible)
    assert np.array_equal(a.view_bearings, b.view_bearings)


def test_odometry_and_groundtruth_out_of_order_are_sorted_and_counted(tmp_path):
    t = np.round(np.arange(999.0, 1004.0, 0.05), 3)
    odo = [(x, 0.1, 0.2) for x in t]
    gt = [(x, 0.1 * (x - 999), 0.0, 0.0) for x in t]
    clean = mrclam.load(small_dataset(tmp_path / "Clean", split_images(), odometry=odo, groundtruth=gt))
    odo_q = odo[:10] + [odo[12], odo[10], odo[11]] + odo[13:]   # one record 0.1 s early
    odo_q.insert(20, odo[19])                                       # one repeated stamp
    gt_q = gt[:30] + [gt[31], gt[30]] + gt[32:]
    gt_q.insert(40, (gt[39][0], 7.0, 7.0, 0.0))                     # two poses at one stamp
    ds = mrclam.load(small_dataset(tmp_path / "Quirky", split_images(), odometry=odo_q,
                                   groundtruth=gt_q))
    q = ds.report.robot(1)
    assert (q.odometry_out_of_order, q.odometry_duplicate_stamps) == (1, 1)
    assert np.isclose(q.odometry_max_backstep, 0.1, atol=1e-6)
    assert (q.groundtruth_out_of_order, q.groundtruth_duplicate_stamps) == (1, 1)
    assert q.groundtruth_rows == len(gt_q)
    a, b = clean.robot(1), ds.robot(1)
    assert np.allclose(a.odometry.poses(a.view_times), b.odometry.poses(b.view_times), atol=1e-12)
    assert np.array_equal(a.groundtruth, b.groundtruth)   # the later duplicate is dropped
    assert "sorted 0 measurement rows and 1 odometry records" in ds.report.describe()


def test_robot_and_unknown_barcodes_are_set_aside_and_counted(tmp_path):
    rows = split_images(n=1) + [(1001.5, 5, 2.0, 0.0), (1001.6, 33, 2.0, 0.0), (1001.7, 33, 1.0, 0.0)]
    ds = mrclam.load(small_dataset(tmp_path / "D", rows))
    q = ds.report.robot(1)
    assert (q.landmark_rows, q.robot_rows, q.unknown_rows, q.unknown_barcodes) == (6, 1, 2, (33,))
    assert ds.robot(1).n_views == 1
    assert ds.report.totals()["unknown_barcodes"] == (33,)


# ----------------------------------------------------------------------------------------------
# malformed files: DataFormatError naming file and line (issue 12 item 10)

def _raises(d, path, line, fragment):
    with pytest.raises(DataFormatError) as exc:
        mrclam.load(d)
    err = exc.value
    assert isinstance(err, ValueError)
    assert err.path == str(path) and err.line == line, str(err)
    assert fragment in str(err)
    return err


def test_corrupt_gz_is_a_data_format_error_not_zlib_error(tmp_path):
    d = small_dataset(tmp_path / "D", split_images(n=40), gz=True)
    p = d / "Robot1_Measurement.dat.gz"
    raw = bytearray(p.read_bytes())
    raw[40] ^= 0xFF
    p.write_bytes(bytes(raw))
    with pytest.raises(DataFormatError) as exc:
        mrclam.load(d)
    err = exc.value
    assert err.path == str(p) and isinstance(err.line, int) and err.line >= 1
    assert "gzip" in str(err) and f"line {err.line}" in str(err)


def test_gz_with_a_bad_checksum_or_cut_short_is_named(tmp_path):
    d = small_dataset(tmp_path / "D", split_images(n=40), gz=True)
    p = d / "Robot1_Measurement.dat.gz"
    good = p.read_bytes()
    n_lines = gzip.decompress(good).count(b"\n")
    bad = bytearray(good)
    bad[-8] ^= 0x01                                   # the CRC32 of the trailer
    p.write_bytes(bytes(bad))
    err = _raises(d, p, n_lines + 1, "corrupt gzip data")
    assert "check" in str(err)
    p.write_bytes(good[: len(good) // 2])             # a download cut in half
    with pytest.raises(DataFormatError, match="truncated gzip file"):
        mrclam.load(d)
    p.write_bytes(b"this is not gzip\n")
    _raises(d, p, 1, "corrupt gzip data")


@pytest.mark.parametrize("name", ["Robot1_Measurement.dat.gz", "Robot1_Measurement.dat",
                                  "Robot1_Odometry.dat.gz", "Barcodes.dat"])
def test_zero_byte_file_is_an_error_not_an_empty_robot(tmp_path, name):
    gz = name.endswith(".gz")
    d = small_dataset(tmp_path / "D", split_images(), odometry=[(999.0, 0.1, 0.0), (1005.0, 0.1, 0.0)],
                      gz=gz)
    p = d / name
    p.write_bytes(b"")
    _raises(d, p, None, "empty file (0 bytes)")


def test_non_utf8_byte_in_a_comment_is_fine(tmp_path):
    d = small_dataset(tmp_path / "D", split_images())
    want = mrclam.load(d).robot(1)
    p = d / "Robot1_Measurement.dat"
    lines = p.read_bytes().split(b"\n")
    lines.insert(1, b"# produced by Jos\xe9 \xff\xfe (latin-1, not UTF-8)")
    lines[5] = lines[5] + b"  # trailing comment \xe9"
    p.write_bytes(b"\n".join(lines))
    got = mrclam.load(d).robot(1)
    assert np.array_equal(got.view_times, want.view_times)
    assert np.array_equal(got.view_bearings, want.view_bearings)
    # the same in a .gz
    with gzip.open(str(p) + ".gz", "wb") as fh:
        fh.write(b"\n".join(lines))
    os.remove(p)
    assert np.array_equal(mrclam.load(d).robot(1).view_bearings, want.view_bearings)


@pytest.mark.parametrize("gz", [False, True], ids=["plain", "gz"])
def test_undecodable_byte_in_a_data_line_names_the_line(tmp_path, gz):
    d = small_dataset(tmp_path / "D", split_images())
    p = d / "Robot1_Measurement.dat"
    lines = p.read_bytes().split(b"\n")
    lines[4] = lines[4].replace(b"\t", b"\t\xe9", 1)   # file line 5
    data = b"\n".join(lines)
    if gz:
        os.remove(p)
        p = d / "Robot1_Measurement.dat.gz"
        p.write_bytes(gzip.compress(data))
    else:
        p.write_bytes(data)
    err = _raises(d, p, 5, "byte 0xe9")
    assert "not ASCII" in str(err)


IMPOSSIBLE = [
    # (file, data row index, new text, message fragment)
    ("Robot1_Measurement.dat", 2, "1000.775 \t 81 \t -0.5 \t 0.1", "column 'range': -0.5 is below 0"),
    ("Robot1_Measurement.dat", 3, "1000.775 \t 18 \t 1.0 \t 10000000000.0", "column 'bearing'"),
    ("Robot1_Measurement.dat", 3, "1000.775 \t 18 \t 1.0 \t -3.2", "column 'bearing': -3.2 is below"),
    ("Robot1_Measurement.dat", 4, "1000.775 \t 14 \t nan \t 0.1", "column 'range': expected a finite"),
    ("Robot1_Measurement.dat", 0, "1000.774 \t 9 \t 2.0 \t 0.1 \t 7", "expected 4 columns"),
    ("Landmark_Groundtruth.dat", 1, "7 \t 7.0 \t 1.0 \t -0.0001 \t 0.0001", "column 'x std-dev'"),
    ("Landmark_Groundtruth.dat", 2, "8 \t 8.0 \t inf \t 0.0001 \t 0.0001", "column 'y'"),
    ("Barcodes.dat", 2, "3 \t 41.5", "column 'barcode': expected an integer"),
]


@pytest.mark.parametrize("gz", [False, True], ids=["plain", "gz"])
@pytest.mark.parametrize("case", IMPOSSIBLE, ids=[c[3] for c in IMPOSSIBLE])
def test_impossible_values_name_file_and_line(tmp_path, case, gz):
    fname, row, new, fragment = case
    d = small_dataset(tmp_path / "D", split_images())
    p = d / fname
    lines = p.read_text().split("\n")
    n_head = HEADER.count("\n")
    lines[n_head + row] = new
    if gz:
        os.remove(p)
        p = d / (fname + ".gz")
        p.write_bytes(gzip.compress("\n".join(lines).encode()))
    else:
        p.write_text("\n".join(lines))
    _raises(d, p, n_head + row + 1, fragment)


def test_bearing_of_rounded_pi_is_accepted(tmp_path):
    rows = [(1000.0, 9, 2.0, 3.142), (1000.0, 81, 2.0, -3.142)]
    rd = mrclam.load(small_dataset(tmp_path / "D", rows)).robot(1)
    assert rd.view_bearings[0, :2].tolist() == [3.142, -3.142]


# ----------------------------------------------------------------------------------------------
# where the data are

def test_folder_above_the_datasets_lists_them(tmp_path):
    for k in (10, 2, 1):
        small_dataset(tmp_path / f"MRCLAM_Dataset{k}", split_images(n=1))
    (tmp_path / "notes").mkdir()
    with pytest.raises(DataFormatError) as exc:
        mrclam.load(tmp_path)
    msg = str(exc.value)
    assert "MRCLAM_Dataset1, MRCLAM_Dataset2, MRCLAM_Dataset10" in msg and "notes" not in msg
    assert [p.name for p in mrclam.find_datasets(tmp_path)] == [
        "MRCLAM_Dataset1", "MRCLAM_Dataset2", "MRCLAM_Dataset10"]
    assert mrclam.find_datasets(tmp_path / "MRCLAM_Dataset2") == [tmp_path / "MRCLAM_Dataset2"]
    with pytest.raises(DataFormatError, match="no MRCLAM dataset here"):
        mrclam.find_datasets(tmp_path / "notes")


def test_data_root_comes_from_the_argument_or_the_environment(tmp_path, monkeypatch):
    monkeypatch.delenv(mrclam.DATA_ENV, raising=False)
    with pytest.raises(ValueError, match=mrclam.DATA_ENV):
        mrclam.data_root()
    assert mrclam.data_root(tmp_path) == tmp_path
    monkeypatch.setenv(mrclam.DATA_ENV, str(tmp_path / "elsewhere"))
    assert mrclam.data_root() == tmp_path / "elsewhere"
    assert mrclam.data_root(tmp_path) == tmp_path


def test_command_line_reports_a_bad_file_in_one_line(tmp_path, capsys):
    d = small_dataset(tmp_path / "MRCLAM_Dataset1", split_images(), gz=True)
    (d / "Robot1_Measurement.dat.gz").write_bytes(b"")
    assert mrclam._cli._main([str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Robot1_Measurement.dat.gz" in err and "Traceback" not in err


def test_command_line_quirks_table(tmp_path, capsys):
    small_dataset(tmp_path / "MRCLAM_Dataset1", split_images())
    assert mrclam._cli._main([str(tmp_path), "--quirks"]) == 0
    out = capsys.readouterr().out
    assert "| MRCLAM_Dataset1 | 18 | 3 | 3 | 1 |" in out   # rows, views, merged stamps, span (ms)


# ----------------------------------------------------------------------------------------------
# motion capture and measured noise on known geometry

def _drive(t):
    """Commands: forward 0.1 m/s, turn rate varying (so a clock offset is identifiable)."""
    return np.full_like(t, 0.1), 0.3 * np.sin(2 * np.pi * t / 7.0) + 0.1 * np.sign(np.sin(t / 3.0))


ORIGIN = np.array([0.0, -4.0])   # the robot's start in the world, metres from the landmarks


def noisy_dataset(d: Path, *, sigma, lead, seed=0, tau=0.0):
    """Robot 1 driven by :func:`_drive`; capture poses every 16 ms by exact integration of the
    commands; bearings from the capture poses plus N(0, sigma); odometry stamps ``lead`` s early
    (a command stamped t moves the robot at t + lead). ``tau`` > 0: each landmark's bearing
    error is a stationary AR(1) process over the views instead (correlation exp(-lag / tau))."""
    rng = np.random.default_rng(seed)
    t_cmd = np.round(np.arange(0.0, 70.0, 0.01), 3)
    v, w = np.round(_drive(t_cmd), 3)   # as written to the file
    t_gt = np.round(np.arange(1.0, 69.0, 0.016), 3)
    P = mrclam.integrate_odometry(t_cmd, v, w, t_gt)
    gt = np.column_stack([t_gt + 1000, P[:, :2] + ORIGIN, P[:, 2]])
    t_view = np.round(np.arange(3.0, 66.0, 0.25), 3)
    V = mrclam.integrate_odometry(t_cmd, v, w, t_view)
    rows = []
    a = np.exp(-0.25 / tau) if tau else 0.0   # views every 0.25 s
    err = rng.normal(0, sigma, 6)
    for tv, pose in zip(t_view, V, strict=True):
        err = a * err + np.sqrt(1 - a * a) * rng.normal(0, sigma, 6)
        for s, b in zip(range(6, 12), SPLIT, strict=True):
            L = np.array(LANDMARKS[s]) - ORIGIN
            phi = wrap_angle(geo_bearing(pose, L) + err[s - 6])
            rows.append((tv + 1000, b, float(np.hypot(*(L - pose[:2]))), float(phi)))
    odo = np.column_stack([t_cmd + 1000 - lead, v, w])
    d = small_dataset(d, [], odometry=odo.tolist(), groundtruth=gt.tolist())
    # bearings need more than the writer's 3 decimals to carry a 0.01 rad noise faithfully
    _write(d / "Robot1_Measurement.dat", ["%.3f \t %d \t %.6f \t %.6f" % r for r in rows])
    return d


def test_measure_noise_recovers_injected_noise_and_offsets(tmp_path):
    sigma, lead = 0.005, 0.2
    ds = mrclam.load(noisy_dataset(tmp_path / "N", sigma=sigma, lead=lead))
    assert ds.robot(1).has_groundtruth and ds.report.robot(1).views_outside_groundtruth == 0
    m = mrclam.measure_noise(ds, odometry_lead=lead, offsets=np.arange(-0.4, 0.41, 0.02),
                             min_travel=0.2)
    assert abs(m.measurement_offset) <= 0.02 + 1e-9
    assert abs(m.odometry_lead - lead) <= 0.02 + 1e-9
    assert abs(m.bearing.robust_std - sigma) < 0.15 * sigma and abs(m.bearing.median) < 0.2 * sigma
    assert abs(m.bearing.sigma90 - sigma) < 0.15 * sigma
    # within one view the noise is the same independent noise (scaled for the view mean)
    assert abs(m.bearing_within_view.robust_std - sigma) < 0.15 * sigma
    # odometry read at the right lead is exact: headings and distances agree with the capture
    assert m.heading_step.n > 20 and m.heading_step.p90_abs < 1e-4
    assert m.distance_step.p90_abs < 5e-3 and m.distance_ratio.p90_abs < 5e-3
    # read without the lead, the direction of travel is off: the measurement can tell
    m0 = mrclam.measure_noise(ds, odometry_lead=0.0, offsets=[0.0, lead])
    assert m0.heading_step.p90_abs > 5 * m.heading_step.p90_abs
    table = mrclam.noise_table(m)
    assert "| bearing (measured - captured) |" in table and "sigma90" in table


def test_bearing_lag_correlation_recovers_persistence(tmp_path):
    """Independent errors: every separation's correlation near 0; AR(1) errors with time constant
    tau: near exp(-lag / tau) at the first lag of each bin (the within-view mean removes nothing:
    the landmarks' processes are independent and alike). The six landmarks seen are refitted
    onto their truth from noiseless bearings, the seventh (never seen) not."""
    sigma, tau = 0.005, 5.0
    m0 = mrclam.measure_noise(mrclam.load(noisy_dataset(tmp_path / "I", sigma=sigma, lead=0.0)),
                              offsets=[0.0])
    m1 = mrclam.measure_noise(mrclam.load(noisy_dataset(tmp_path / "A", sigma=sigma, lead=0.0,
                                                        tau=tau)), offsets=[0.0])
    for m in (m0, m1):
        shift = np.array(m.landmark_shift)
        assert shift.size == 7 and np.isnan(shift).sum() == 1
        assert [(lo, hi) for lo, hi, *_ in m.bearing_lag_correlation] == list(noise.LAG_BINS)
    for (lo, _, n, p, r), (_, _, _, p1, r1) in zip(m0.bearing_lag_correlation,
                                                    m1.bearing_lag_correlation, strict=True):
        if lo > 63:   # the run is 63 s of views: no pairs that far apart
            assert n == 0 and np.isnan(p)
            continue
        assert n > 50 and abs(p) < 0.2 and abs(r) < 0.2
        if lo < 30:
            assert abs(p1 - np.exp(-lo / tau)) < 0.15 and abs(r1 - np.exp(-lo / tau)) < 0.2, lo
    table = mrclam.noise_table(m1)
    assert "| 0.5-3 s |" in table and "Persistence of bearing errors" in table
    exact = mrclam.measure_noise(mrclam.load(noisy_dataset(tmp_path / "E", sigma=1e-7, lead=0.0)),
                                 offsets=[0.0])
    assert np.nanmax(exact.landmark_shift) < 1e-3


def test_lag_pairs_brute_force():
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0, 50, 200))
    x = rng.normal(size=200)
    a, b = noise.lag_pairs(t, x, 2.0, 7.0)
    want = [(x[i], x[j]) for i in range(200)
            for j in [next((j for j in range(i + 1, 200) if 2.0 <= t[j] - t[i] < 7.0), None)]
            if j is not None and t[j] - t[i] < 7.0]
    assert a.tolist() == [w[0] for w in want] and b.tolist() == [w[1] for w in want]


def test_measure_noise_needs_ground_truth(tmp_path):
    ds = mrclam.load(small_dataset(tmp_path / "D", split_images()))
    with pytest.raises(ValueError, match="dataset"):
        mrclam.measure_noise(ds)


def test_histories_carry_distances_and_captured_poses(tmp_path):
    lead = 0.2
    ds = mrclam.load(noisy_dataset(tmp_path / "N", sigma=0.0, lead=lead))
    hs = mrclam.triplet_histories(ds, 1, odometry_lead=lead, min_travel=0.3)
    assert hs and all(isinstance(h, mrclam.MRCLAMHistory) for h in hs)
    for h in hs[:12]:
        P = h.truth.poses_world
        assert P.shape == (h.n_views, 3) and h.groundtruth_valid.all() and h.robot == 1
        # the odometry's distances between views equal the captured ones (same commands)
        assert np.allclose(h.distances, np.hypot(*np.diff(P[:, :2], axis=0).T), atol=1e-3)
        assert h.truth.camera_states.shape == (h.n_views,)
    # every view of a pass when min_travel = 0, none repeated
    all_views = mrclam.triplet_histories(ds, 1, odometry_lead=lead, min_travel=0.0)
    assert max(h.n_views for h in all_views) == ds.robot(1).n_views


# ----------------------------------------------------------------------------------------------
# the real data, when present

REAL = Path(os.environ.get(mrclam.DATA_ENV) or shared_data_dir() / "mrclam")


def _real(k):
    d = REAL / f"MRCLAM_Dataset{k}"
    if not d.is_dir():
        pytest.skip(f"MRCLAM dataset {k} not found at {d} (set {mrclam.DATA_ENV})")
    return d


def test_real_dataset2_split_image_is_one_view():
    d = _real(2)
    ds = mrclam.load(d)
    rd = ds.robot(5)
    v = int(np.argmin(np.abs(rd.view_times - 1248275413.774)))
    assert abs(rd.view_times[v] - 1248275413.774) < 1e-6
    seen = ds.landmark_ids[rd.visible[v]].tolist()
    # in dataset 2 barcode 14 is robot 2 (subject 2): the image holds five landmarks and a robot
    assert ds.barcodes[2] == 14
    want = sorted(s for s, b in ds.barcodes.items() if b in SPLIT and s in ds.landmark_ids)
    assert seen == want == [6, 8, 12, 13, 14]
    split = mrclam.load(d, view_gap=0.0).robot(5)
    k = np.flatnonzero(np.abs(split.view_times - 1248275413.7745) < 0.001)
    assert split.visible[k].sum(axis=1).tolist() == [1, 4]


def test_real_dataset6_ground_truth_explains_the_bearings():
    ds = mrclam.load(_real(6))
    assert sorted(ds.robots) == [1, 2, 3, 4, 5]
    for n, rd in ds.robots.items():
        assert rd.has_groundtruth and rd.groundtruth.shape[0] > 40000
        v, col = np.nonzero(rd.visible)
        P, ok = rd.groundtruth_poses(rd.view_times[v])
        assert ok.mean() > 0.99
        res = wrap_angle(rd.view_bearings[v, col] - geo_bearing(P, ds.landmark_xy[col]))[ok]
        # motion capture and landmark ground truth predict the measured bearings to about a degree
        assert np.degrees(np.median(np.abs(res))) < 1.5, n
    hs = mrclam.triplet_histories(ds, 3)
    assert hs and all(h.truth.poses_world is not None and h.truth.camera_states is not None
                      for h in hs)
    assert np.mean(np.concatenate([h.groundtruth_valid for h in hs])) > 0.95


def test_real_datasets_report_quirks_without_refusing():
    for k in range(1, 7):
        d = REAL / f"MRCLAM_Dataset{k}"
        if not d.is_dir():
            continue
        ds = mrclam.load(d)
        t = ds.report.totals()
        assert t["merged_stamps"] > 0 and t["max_view_span"] <= 0.010
        assert t["views"] == sum(rd.n_views for rd in ds.robots.values())
        assert t["robot_rows"] > 0


def test_triplet_counts_over_all_combinations_are_consistent(tmp_path):
    # history_counts' raw distinct triplets against a brute-force count over views
    ds = mrclam.load(small_dataset(tmp_path / "D", split_images()))
    rd = ds.robot(1)
    brute = {c for c in itertools.combinations(range(ds.landmark_ids.size), 3)
             if sum(rd.visible[:, list(c)].all(axis=1)) >= 3}
    assert mrclam.history_counts(ds)["all"]["distinct_triplets_raw"] == len(brute) == 20


# ----------------------------------------------------------------------------------------------
# damaged files: whatever the damage, a dataset or a DataFormatError naming a file of it

FILES = ("Barcodes.dat", "Landmark_Groundtruth.dat", "Robot1_Measurement.dat", "Robot1_Odometry.dat",
         "Robot1_Groundtruth.dat")


@settings(max_examples=60, deadline=None)
@given(which=st.sampled_from(FILES), gz=st.booleans(),
       flips=st.lists(st.tuples(st.floats(0.0, 1.0, exclude_max=True), st.integers(1, 255)),
                      min_size=1, max_size=3))
def test_damaged_file_loads_or_names_the_file(tmp_path_factory, which, gz, flips):
    d = tmp_path_factory.mktemp("fuzz")
    t = np.round(np.arange(999.0, 1004.0, 0.05), 3)
    small_dataset(d, split_images(), odometry=[(x, 0.1, 0.2) for x in t],
                  groundtruth=[(x, 0.1 * (x - 999), 0.0, 0.0) for x in t], gz=gz)
    p = d / which
    if gz and which.startswith("Robot"):
        p = d / (which + ".gz")
    raw = bytearray(p.read_bytes())
    for pos, xor in flips:
        raw[int(pos * len(raw))] ^= xor
    p.write_bytes(bytes(raw))
    try:
        ds = mrclam.load(d)
    except DataFormatError as err:
        assert Path(err.path).parent == d and (err.line is None or err.line >= 1), str(err)
        assert err.path in str(err)
    else:
        assert ds.report.robot(1).views == ds.robot(1).n_views


# ----------------------------------------------------------------------------------------------
# files a user may be handed: streamed, bounded, named (issue 18 item 9)

def _fifo(p):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    os.mkfifo(p)


@pytest.mark.parametrize("make, fragment", [
    (lambda p: p.mkdir(), "a directory"),
    (_fifo, "FIFO"),
    (lambda p: os.symlink(p.name, p), "symbolic link loop"),
    (lambda p: os.symlink("nowhere.dat", p), "could not read"),
])
@pytest.mark.parametrize("name", ["Robot2_Measurement.dat", "Robot1_Odometry.dat.gz",
                                  "Barcodes.dat"])
def test_a_data_file_name_on_something_else_is_named(tmp_path, make, fragment, name):
    d = small_dataset(tmp_path / "D", split_images(), odometry=[(999.0, 0.1, 0.0), (1005.0, 0.1, 0.0)])
    if name == "Barcodes.dat":
        (d / name).unlink()
    elif name.endswith(".gz"):
        (d / name[:-3]).unlink()
    p = d / name
    make(p)
    # a FIFO is never opened (that would wait for a writer): the test would hang, not fail
    _raises(d, p, None, fragment)


def test_zero_padded_robot_number_is_named(tmp_path):
    d = small_dataset(tmp_path / "D", split_images())
    (d / "Robot1_Measurement.dat").rename(d / "Robot01_Measurement.dat")
    _raises(d, d / "Robot01_Measurement.dat", None, "Robot1_Measurement.dat")


def test_rows_keep_their_line_numbers_across_blocks_comments_and_blank_lines(tmp_path):
    # > 64 KiB, so the file is read in several blocks; comments and blank lines in between
    rows = [(t, b, r, phi % 1.0) for t, b, r, phi in split_images(n=2000)]
    lines = ["%.3f \t %d \t %.3f \t %.3f" % r for r in rows]
    for k in (5, 3000, 9000):
        lines.insert(k, "# a comment" if k != 3000 else "   ")
    bad = 11000
    lines[bad] = lines[bad].rsplit("\t", 2)[0] + "\t -1.000 \t 0.100"   # a negative range
    d = small_dataset(tmp_path / "D", [])
    _write(d / "Robot1_Measurement.dat", lines)
    assert (d / "Robot1_Measurement.dat").stat().st_size > 3 * 2**16
    _raises(d, d / "Robot1_Measurement.dat", HEADER.count("\n") + bad + 1, "range")
    for gz in (False, True):
        lines[bad] = lines[bad - 1]
        if gz:
            (d / "Robot1_Measurement.dat").unlink()
        _write(d / "Robot1_Measurement.dat", lines, gz=gz)
        tab = mrclam._io.read_table(mrclam._io.find_file(d, "Robot1_Measurement"),
                                    mrclam._load._MEAS_COLS)
        text = (gzip.decompress if gz else bytes)(mrclam._io.find_file(
            d, "Robot1_Measurement").read_bytes()).decode().split("\n")
        want = [i + 1 for i, t in enumerate(text) if t.split("#")[0].strip()]
        assert tab.lines.tolist() == want and len(want) == tab.data.shape[0] == len(rows)


def test_too_many_lines_and_too_long_a_line_are_named(tmp_path, monkeypatch):
    from qfg.datasets.mrclam import _constants

    d = small_dataset(tmp_path / "D", split_images(n=10))
    p = d / "Robot1_Measurement.dat"
    monkeypatch.setattr(_constants, "MAX_LINES", 30)
    _raises(d, p, 31, "more than 30 lines")
    monkeypatch.undo()
    p.write_bytes(HEADER.encode() + b"1000.0 \t 9 \t 2.0 " + b"7" * (3 * 2**20))   # no newline
    _raises(d, p, HEADER.count("\n") + 1, "line longer than")


def _bomb(path: Path, inflated: int):
    """A .gz file of valid measurement lines inflating to ``inflated`` bytes, written in a
    moment: one 1 MiB member repeated (gzip allows members one after another)."""
    block = b"1000.000 \t 9 \t 2.000 \t 0.100\n" * (2**20 // 30)
    member = gzip.compress(block, compresslevel=9)
    with open(path, "wb") as fh:
        fh.write(gzip.compress(HEADER.encode()))
        for _ in range(inflated // len(block)):
            fh.write(member)


_MEMORY_CHILD = """
import resource, sys, time
resource.setrlimit(resource.RLIMIT_AS, (CAP, CAP))
from qfg.datasets import mrclam
t = time.perf_counter()
try:
    mrclam.load(sys.argv[1])
    print("loaded")
except mrclam.DataFormatError as exc:
    print("error", exc)
except MemoryError:
    print("MemoryError")
print(time.perf_counter() - t)
def peak_kb():
    # VmHWM: this process's own peak RSS; ru_maxrss would also count the forked parent's RSS
    # from before exec (a large pytest process made these checks fail in the full suite)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
print(peak_kb())
"""


@pytest.mark.skipif(not hasattr(os, "fork") or sys.platform != "linux",
                    reason="RLIMIT_AS and /proc/self/status: Linux")
@pytest.mark.parametrize("kind", ["sparse 2 GB file", "gzip bomb 1.5 GB"])
def test_oversize_file_and_gzip_bomb_are_refused_in_bounded_memory(tmp_path, kind):
    import subprocess

    d = small_dataset(tmp_path / "D", split_images())
    if kind.startswith("sparse"):
        p = d / "Robot1_Measurement.dat"
        with open(p, "r+b") as fh:
            fh.truncate(2 * 2**30)          # a hole: no disk used, 2 GB to read
    else:
        (d / "Robot1_Measurement.dat").unlink()
        p = d / "Robot1_Measurement.dat.gz"
        _bomb(p, int(1.5 * 2**30))
        assert p.stat().st_size < 8 * 2**20
    cap = 1536 * 2**20                      # a regression fails with MemoryError, not the machine
    proc = subprocess.run([sys.executable, "-c", _MEMORY_CHILD.replace("CAP", str(cap)), str(d)],
                          capture_output=True, text=True, timeout=120)
    what, secs, rss_kb = proc.stdout.strip().split("\n")
    assert what.startswith("error") and str(p) in what, proc.stdout + proc.stderr
    assert "plausibly" in what
    assert int(rss_kb) < 400 * 1024, f"{kind}: peak RSS {int(rss_kb) // 1024} MB"
