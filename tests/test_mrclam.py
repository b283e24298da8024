"""MRCLAM loader, odometry integration and triplet histories.

The synthetic dataset is written here in the MRCLAM file format from known geometry: robot 1 drives
a circle (v = 0.1 m/s, omega = 0.01 rad/s) from the world origin, robot 2 a straight line; bearings
and ranges are the exact ones from the true poses. Expected views, headings and states are worked
out by hand from that geometry (not with the code under test).
"""

from __future__ import annotations

import gzip
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data_dir
from hypothesis import given, settings
from hypothesis import strategies as st

from qfg.datasets import mrclam
from qfg.datasets.mrclam import DataFormatError, integrate_odometry

T0 = 1248272270.0
LANDMARKS = {6: (4.0, 4.0), 7: (4.0, 6.0), 8: (3.0, 7.0), 9: (6.0, 5.0), 10: (8.0, 9.0)}
BARCODES = {1: 5, 2: 14, 6: 72, 7: 27, 8: 54, 9: 70, 10: 36}
V, W = 0.1, 0.01
HEADER = ["# UTIAS Multi-Robot Cooperative Localization and Mapping Dataset",
          "# produced by a test", "# Data Fomat:", "# columns"]
NHEAD = len(HEADER)
# test grouping: views are 1 s apart and the robots move 0.1 m/s, so min_travel = 0.15 m keeps
# every second view (chord after 2 s: 2 R sin(0.01) = 0.19999 m; after 1 s: 0.09999 m).
OPTS = dict(min_travel=0.15, max_gap=10.0, min_interval=2.0)


def pose1(tau):
    """Robot 1: circle of radius V / W from (0, 0, 0) at tau = 0 (closed form)."""
    tau = np.asarray(tau, dtype=float)
    R = V / W
    return np.stack([R * np.sin(W * tau), R * (1 - np.cos(W * tau)), W * tau], axis=-1)


def pose2(tau):
    """Robot 2: straight up the line x = 7 from (7, 0), heading +y."""
    tau = np.asarray(tau, dtype=float)
    return np.stack([np.full_like(tau, 7.0), V * tau, np.full_like(tau, np.pi / 2)], axis=-1)


def r1_schedule():
    out = [(t, (6, 7, 8)) for t in range(0, 16)] + [(t, (6, 7)) for t in range(16, 30)]
    out += [(t, (6, 7, 8, 9)) for t in range(30, 41)] + [(t, (6, 7, 8, 10)) for t in range(41, 46)]
    out += [(t, (6, 7, 9, 10)) for t in range(46, 51)]
    return out


def _rb(pose, lid):
    L = np.array(LANDMARKS[lid])
    d = L - pose[:2]
    phi = np.arctan2(d[1], d[0]) - pose[2]
    return float(np.hypot(*d)), float(np.arctan2(np.sin(phi), np.cos(phi)))


def _write(path: Path, rows, fmt, gz=False):
    text = "\n".join(HEADER + [fmt % tuple(r) for r in rows]) + "\n"
    if gz:
        with gzip.open(str(path) + ".gz", "wt") as fh:
            fh.write(text)
    else:
        path.write_text(text)


def write_dataset(d: Path, *, gz=False, robot2_odometry=True, truth_swap=None,
                  robot1_odometry=True):
    """Write the synthetic dataset into directory ``d``; ``truth_swap``: a landmark pair whose
    ground-truth lines exchange positions."""
    d.mkdir(parents=True, exist_ok=True)
    _write(d / "Barcodes.dat", sorted(BARCODES.items()), "%3d \t %3d", gz)
    lm = {k: v for k, v in LANDMARKS.items()}
    if truth_swap:
        a, b = truth_swap
        lm[a], lm[b] = lm[b], lm[a]
    _write(d / "Landmark_Groundtruth.dat", [(k, x, y, 1e-4, 1e-4) for k, (x, y) in sorted(lm.items())],
           "%3d \t %.8f \t %.8f \t %.8f \t %.8f", gz)
    # robot 1 measurements
    rows = []
    for tau, lids in r1_schedule():
        p = pose1(tau)
        for lid in lids:
            rows.append((T0 + tau, BARCODES[lid], *_rb(p, lid)))
        if tau == 3:
            rows.append((T0 + tau, BARCODES[2], 2.0, 0.1))   # robot 2 seen in a view
        if tau == 7:
            rows.append((T0 + tau, 99, 3.0, 0.2))            # unknown barcode
        if tau == 8:
            rows.append((T0 + tau, BARCODES[6], 1.0, 0.3))   # duplicate landmark in one view
        if tau == 3:
            rows.append((T0 + 3.5, BARCODES[2], 2.0, 0.1))   # a robot alone: no view
        if tau == 5:
            rep = [r for r in rows if r[0] == T0 + 5]
            rows += [(T0 + 5.3, *r[1:]) for r in rep]        # logger repeats the frame
    _write(d / "Robot1_Measurement.dat", rows, "%.3f \t %d \t %.9f \t %.9f", gz)
    rows = []
    for tau in range(0, 21):
        p = pose2(tau)
        for lid in (8, 9, 10):
            rows.append((T0 + tau, BARCODES[lid], *_rb(p, lid)))
        if tau == 10:
            rows.append((T0 + tau, BARCODES[1], 4.0, -0.1))
    _write(d / "Robot2_Measurement.dat", rows, "%.3f \t %d \t %.9f \t %.9f", gz)
    # odometry: constant commands at irregular record times covering the measurements
    rng = np.random.default_rng(7)
    for n, w, span in ((1, W, (-2.0, 55.0)), (2, 0.0, (-1.0, 22.0))):
        if (n == 2 and not robot2_odometry) or (n == 1 and not robot1_odometry):
            continue
        t = np.sort(np.concatenate([span, rng.uniform(*span, size=400)]))
        _write(d / f"Robot{n}_Odometry.dat", [(T0 + x, V, w) for x in t], "%.6f \t %.3f \t %.3f", gz)
    taus = np.arange(-2.0, 55.0, 0.05)
    _write(d / "Robot1_Groundtruth.dat", [(T0 + t, *pose1(t)) for t in taus],
           "%.3f \t %.9f \t %.9f \t %.9f", gz)
    return d


@pytest.fixture(scope="module")
def synth_dir(tmp_path_factory):
    return write_dataset(tmp_path_factory.mktemp("mrclam") / "Synth")


@pytest.fixture(scope="module")
def synth(synth_dir):
    return mrclam.load(synth_dir)


# ----------------------------------------------------------------------------------------------
# odometry integration against closed forms

@settings(max_examples=40, deadline=None)
@given(v=st.floats(0.0, 2.0), w=st.floats(-1.5, 1.5), seed=st.integers(0, 2**31))
def test_integrate_odometry_constant_command_is_a_circle(v, w, seed):
    rng = np.random.default_rng(seed)
    t = np.sort(np.concatenate([[0.0, 10.0], rng.uniform(0, 10, 30)]))
    q = rng.uniform(0, 10, 25)
    P = integrate_odometry(t, np.full_like(t, v), np.full_like(t, w), q, start=(1.0, -2.0, 0.5))
    th = 0.5 + w * q
    if abs(w) > 1e-9:
        x = 1.0 + v / w * (np.sin(th) - np.sin(0.5))
        y = -2.0 + v / w * (np.cos(0.5) - np.cos(th))
    else:
        x, y = 1.0 + v * q * np.cos(0.5), -2.0 + v * q * np.sin(0.5)
    assert np.allclose(P[:, 0], x, atol=1e-9) and np.allclose(P[:, 1], y, atol=1e-9)
    assert np.allclose(np.angle(np.exp(1j * (P[:, 2] - th))), 0.0, atol=1e-9)


def test_integrate_odometry_omega_near_zero_is_continuous():
    t = np.array([0.0, 5.0])
    q = np.array([5.0])
    straight = integrate_odometry(t, [1.0, 1.0], [0.0, 0.0], q)
    tiny = integrate_odometry(t, [1.0, 1.0], [1e-13, 1e-13], q)
    assert np.allclose(straight, [[5.0, 0.0, 0.0]])
    assert np.allclose(tiny, straight, atol=1e-10)
    assert np.all(np.isfinite(tiny))


def test_integrate_odometry_piecewise_commands_match_fine_euler():
    rng = np.random.default_rng(3)
    t = np.sort(np.concatenate([[0.0, 20.0], rng.uniform(0, 20, 15)]))
    v, w = rng.uniform(0, 0.5, t.size), rng.uniform(-0.8, 0.8, t.size)
    q = np.array([0.0, 3.3, 7.1, 12.9, 20.0])
    P = integrate_odometry(t, v, w, q)
    # independent reference: forward Euler with 2e6 tiny steps (the records and queries on the grid)
    ts = np.unique(np.concatenate([np.linspace(0.0, 20.0, 2_000_001), t, q]))
    k = np.clip(np.searchsorted(t, ts[:-1], side="right") - 1, 0, t.size - 2)
    dt = np.diff(ts)
    th = np.concatenate([[0.0], np.cumsum(w[k] * dt)])
    x = np.concatenate([[0.0], np.cumsum(v[k] * np.cos(th[:-1]) * dt)])
    y = np.concatenate([[0.0], np.cumsum(v[k] * np.sin(th[:-1]) * dt)])
    idx = np.searchsorted(ts, q)
    assert np.allclose(P[:, 0], x[idx], atol=1e-4) and np.allclose(P[:, 1], y[idx], atol=1e-4)
    assert np.allclose(np.angle(np.exp(1j * (P[:, 2] - th[idx]))), 0.0, atol=1e-6)


def test_travelled_is_the_dead_reckoned_path_length_and_turning():
    rng = np.random.default_rng(4)
    t = np.sort(np.concatenate([[0.0, 20.0], rng.uniform(0, 20, 15)]))
    v, w = rng.uniform(-0.3, 0.5, t.size), rng.uniform(-0.8, 0.8, t.size)
    od = mrclam.Odometry(t, v, w)
    q = np.array([0.0, 3.3, 7.1, 12.9, 20.0])
    got = od.travelled(q)
    # independent reference: the dead-reckoned poses on a fine grid, chords and turns summed
    fine = np.unique(np.concatenate([np.linspace(0.0, 20.0, 200_001), t, q]))
    P = integrate_odometry(t, v, w, fine)
    step = np.hypot(*np.diff(P[:, :2], axis=0).T)
    turn = np.abs(np.angle(np.exp(1j * np.diff(P[:, 2]))))
    idx = np.searchsorted(fine, q)
    length = np.concatenate([[0.0], np.cumsum(step)])[idx]
    turned = np.concatenate([[0.0], np.cumsum(turn)])[idx]
    assert np.allclose(got[:, 0], length, atol=1e-6) and np.allclose(got[:, 1], turned, atol=1e-9)
    # there and back: the path, not the net step
    back = mrclam.Odometry(np.array([0.0, 1.0, 2.0]), np.array([1.0, -1.0, 0.0]), np.zeros(3))
    assert np.allclose(back.travelled([2.0]), [[2.0, 0.0]])
    assert np.allclose(integrate_odometry(back.time, back.v, back.omega, [2.0])[0], 0.0)
    with pytest.raises(ValueError, match="times"):
        od.travelled([21.0])


@settings(max_examples=30, deadline=None)
@given(split=st.floats(0.01, 9.99), seed=st.integers(0, 2**31))
def test_integrate_odometry_extra_record_with_same_command_changes_nothing(split, seed):
    rng = np.random.default_rng(seed)
    t = np.array([0.0, 2.0, 5.0, 10.0])
    v, w = rng.uniform(0, 1, 4), rng.uniform(-1, 1, 4)
    k = np.searchsorted(t, split, side="right") - 1
    t2 = np.insert(t, k + 1, split)
    v2, w2 = np.insert(v, k + 1, v[k]), np.insert(w, k + 1, w[k])
    q = np.linspace(0, 10, 23)
    assert np.allclose(integrate_odometry(t, v, w, q), integrate_odometry(t2, v2, w2, q), atol=1e-12)


@pytest.mark.parametrize("kw, msg", [
    (dict(query_times=[11.0]), "query_times"),
    (dict(v=[1.0, 1.0]), "equal lengths"),
    (dict(time=[0.0, 5.0, 4.0]), "non-decreasing"),
])
def test_integrate_odometry_bad_input(kw, msg):
    args = dict(time=[0.0, 5.0, 10.0], v=[1.0, 1.0, 1.0], omega=[0.0, 0.0, 0.0], query_times=[1.0])
    args.update(kw)
    with pytest.raises(ValueError, match=msg):
        integrate_odometry(**args)


# ----------------------------------------------------------------------------------------------
# loading the synthetic dataset

def test_load_maps_barcodes_and_counts_non_landmarks(synth):
    assert sorted(synth.robots) == [1, 2]
    assert synth.landmark_ids.tolist() == [6, 7, 8, 9, 10]
    assert np.allclose(synth.landmark_position([8, 6]), [[3.0, 7.0], [4.0, 4.0]])
    r1 = synth.robot(1)
    # hand count: 160 scheduled landmark rows + 3 repeated + 1 duplicate; robot 2 at tau 3, 3.5
    assert (r1.n_landmark, r1.n_robot, r1.n_unknown) == (164, 2, 1)
    assert r1.unknown_barcodes == (99,)
    assert r1.n_duplicate == 1 and r1.n_repeated_views == 1
    # views: integer tau 0..50 and the repeated frame at 5.3 (tau 3.5 saw a robot only)
    expected = np.sort(np.concatenate([np.arange(51.0), [5.3]]))
    assert np.allclose(r1.view_times - T0, expected, atol=1e-6)
    cols = {lid: i for i, lid in enumerate(synth.landmark_ids)}
    v30 = np.argmin(np.abs(r1.view_times - (T0 + 30)))
    assert set(synth.landmark_ids[r1.visible[v30]].tolist()) == {6, 7, 8, 9}
    # the duplicate at tau 8 (bearing 0.3) is dropped in favour of the first, true, one
    v8 = np.argmin(np.abs(r1.view_times - (T0 + 8)))
    assert np.isclose(r1.view_bearings[v8, cols[6]], _rb(pose1(8), 6)[1], atol=1e-8)
    r2 = synth.robot(2)
    assert (r2.n_landmark, r2.n_robot, r2.n_unknown) == (63, 1, 0)
    assert r1.has_odometry and r2.has_odometry and r1.groundtruth is not None


def test_landmark_fixes_recover_true_poses(synth):
    f = mrclam.landmark_fixes(synth, 1)
    taus = f.times - T0
    ok = np.abs(taus - 5.3) > 1e-6  # the repeated frame carries tau 5's measurements
    assert np.allclose(f.poses[ok], pose1(taus[ok]), atol=1e-6)
    assert np.all(f.residual[ok] < 1e-6)
    P, t_anchor = mrclam.anchored_dead_reckoning(synth, 1, T0 + np.array([10.0, 33.3, 50.0]))
    assert np.isclose(t_anchor, T0) and np.allclose(P, pose1([10.0, 33.3, 50.0]), atol=1e-6)


def test_bearing_residuals_and_odometry_check_are_zero_on_exact_data(synth, tmp_path):
    res = mrclam.bearing_residuals(synth, 1)
    assert res.size == 4 * 21 and np.all(np.abs(res) < 1e-6)   # views tau 30..50 see 4 landmarks
    rows = mrclam.odometry_check(synth, 1, bins=((0.5, 3.0), (3.0, 10.0)))
    assert [r["n"] > 0 for r in rows] == [True, True]
    assert all(r["p90_abs_deg"] < 1e-4 for r in rows)
    no_odo = mrclam.load(write_dataset(tmp_path / "NoOdo", robot2_odometry=False))
    assert mrclam.odometry_check(no_odo, 2) == []


# ----------------------------------------------------------------------------------------------
# triplet histories: expected views, headings and states

EVEN = list(range(0, 15, 2))
EXPECTED_R1 = {
    (6, 7, 8): [EVEN, list(range(30, 45, 2))],        # unseen 15 s between tau 15 and 30: split
    (6, 7, 9): [[30, 32, 34, 36, 38, 40, 46, 48, 50]],  # unseen 6 s (41-45): one history
    (6, 7, 10): [[41, 43, 45, 47, 49]],
    (6, 8, 9): [list(range(30, 41, 2))],
    (6, 8, 10): [[41, 43, 45]],
    (6, 9, 10): [[46, 48, 50]],
    (7, 8, 9): [list(range(30, 41, 2))],
    (7, 8, 10): [[41, 43, 45]],
    (7, 9, 10): [[46, 48, 50]],
}


def test_segments_group_and_thin_views_as_worked_out(synth):
    segs = mrclam.triplet_segments(synth, 1, **OPTS)
    got = {}
    for s in segs:
        got.setdefault(s.landmarks, []).append(
            np.round(synth.robot(1).view_times[s.view_index] - T0, 6).tolist())
    assert got == {k: [[float(x) for x in v] for v in vs] for k, vs in EXPECTED_R1.items()}
    segs2 = mrclam.triplet_segments(synth, 2, **OPTS)
    assert [(s.landmarks, s.n_seen) for s in segs2] == [((8, 9, 10), 21)]
    assert np.allclose(synth.robot(2).view_times[segs2[0].view_index] - T0, np.arange(0, 21, 2))


def test_histories_bearings_headings_and_states(synth):
    hs = mrclam.triplet_histories(synth, 1, **OPTS)
    assert len(hs) == 6 * sum(len(v) for v in EXPECTED_R1.values())
    assert [h.landmarks for h in hs] == sorted(h.landmarks for h in hs)
    for h in hs:
        taus = h.views - T0
        assert np.all(np.diff(taus) > 0) and h.n_views >= 3 and h.has_motion
        P = pose1(taus)
        want = np.array([[_rb(p, lid)[1] for lid in h.landmarks] for p in P])
        ok = np.abs(taus - 5.3) > 1e-6
        assert np.allclose(h.bearings[ok], want[ok], atol=1e-8)
        # along a circle the chord turns by half the arc: psi = omega * dt / 2
        assert np.allclose(h.headings, W * np.diff(taus) / 2, atol=1e-8)
        assert np.allclose(h.truth.landmarks_world, [LANDMARKS[lid] for lid in h.landmarks])
        assert np.allclose(h.truth.poses_world, P, atol=1e-5)   # from Robot1_Groundtruth
        assert h.sigma_bearing == mrclam.DEFAULT_SIGMA_BEARING
    # EDC states worked out by hand in the AB frame (conventions.md table, 0-based)
    by = {h.landmarks: h for h in hs}
    assert np.allclose(by[(6, 7, 8)].truth.C_ab, [-0.5, 1.5])   # y >= 1, left, near B: label 3
    assert by[(6, 7, 8)].truth.state == 2
    assert np.allclose(by[(6, 7, 9)].truth.C_ab, [1.0, 0.5])    # middle band, right, far A far B
    assert by[(6, 7, 9)].truth.state == 9
    assert np.allclose(by[(7, 6, 8)].truth.C_ab, [0.5, -0.5])   # y < 0, near A, right: label 18
    assert by[(7, 6, 8)].truth.state == 17
    h2 = mrclam.triplet_histories(synth, 2, **OPTS)
    assert len(h2) == 6
    assert all(np.allclose(h.headings, 0.0, atol=1e-9) for h in h2)   # straight line
    assert h2[0].truth.poses_world is None                            # no Robot2_Groundtruth


def test_max_views_cuts_long_histories(synth):
    segs = mrclam.triplet_segments(synth, 1, max_views=4, **OPTS)
    got = [np.round(synth.robot(1).view_times[s.view_index] - T0).tolist()
           for s in segs if s.landmarks == (6, 7, 9)]
    assert got == [[30, 32, 34, 36], [38, 40, 46, 48, 50]]   # the 1-view tail joins its neighbour


def test_robot_without_odometry_has_no_motion(tmp_path):
    d = write_dataset(tmp_path / "NoOdo", robot2_odometry=False)
    ds = mrclam.load(d)
    assert ds.robot(2).odometry is None and ds.robot(1).odometry is not None
    hs = mrclam.triplet_histories(ds, 2, **OPTS)
    assert len(hs) == 6 and not any(h.has_motion for h in hs)
    assert np.allclose(hs[0].views - T0, np.arange(0, 21, 2))   # min_interval = 2 s
    assert np.all(hs[0].headings == 0.0)
    with pytest.raises(ValueError, match="no odometry"):
        mrclam.dead_reckon(ds.robot(2))


def test_history_counts(synth):
    c = mrclam.history_counts(synth, **OPTS)
    assert c[1]["segments"] == 10 and c[1]["histories"] == 60 and c[1]["triplets"] == 9
    assert c[2]["segments"] == 1 and c["all"]["distinct_triplets"] == 10


def test_bad_arguments(synth):
    with pytest.raises(ValueError, match="robot"):
        mrclam.triplet_histories(synth, 7)
    with pytest.raises(ValueError, match="max_gap"):
        mrclam.triplet_segments(synth, 1, max_gap=-1.0)
    with pytest.raises(ValueError, match="max_views"):
        mrclam.triplet_segments(synth, 1, max_views=2)
    with pytest.raises(ValueError, match="odometry_lead"):
        mrclam.triplet_histories(synth, 1, odometry_lead=float("nan"))


def test_check_landmarks_finds_a_swapped_ground_truth(tmp_path, synth):
    assert mrclam.check_landmarks(synth).swaps == ()
    bad = mrclam.load(write_dataset(tmp_path / "Swapped", truth_swap=(6, 8)))
    # 8 is only seen without 6 by robot 2, together with two other landmarks
    chk = mrclam.check_landmarks(bad, min_landmarks=2)
    assert chk.swaps == ((6, 8),)
    fixed = mrclam.swap_landmarks(bad, chk.swaps)
    assert np.allclose(fixed.landmark_xy, synth.landmark_xy)
    assert mrclam.check_landmarks(fixed, min_landmarks=2).swaps == ()


# ----------------------------------------------------------------------------------------------
# gz and plain

def _same_dataset(a, b):
    assert sorted(a.robots) == sorted(b.robots) and a.barcodes == b.barcodes
    for name in ("landmark_ids", "landmark_xy", "landmark_std"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
    for n in a.robots:
        ra, rb = a.robots[n], b.robots[n]
        for name in ("time", "barcode", "range", "bearing", "subject", "view_times", "visible",
                     "view_bearings", "view_ranges"):
            assert np.array_equal(getattr(ra, name), getattr(rb, name)), name
        assert (ra.odometry is None) == (rb.odometry is None)
        if ra.odometry is not None:
            assert np.array_equal(ra.odometry.time, rb.odometry.time)
            assert np.array_equal(ra.odometry.v, rb.odometry.v)
        ha, hb = mrclam.triplet_histories(a, n, **OPTS), mrclam.triplet_histories(b, n, **OPTS)
        assert len(ha) == len(hb)
        for x, y in zip(ha, hb, strict=True):
            assert x.landmarks == y.landmarks and np.array_equal(x.bearings, y.bearings)
            assert np.array_equal(x.headings, y.headings) and np.array_equal(x.views, y.views)


def test_gz_and_plain_give_the_same_dataset(tmp_path, synth):
    gz = mrclam.load(write_dataset(tmp_path / "Gz", gz=True))
    assert all(p.name.endswith(".gz") for p in (tmp_path / "Gz").iterdir())
    _same_dataset(synth, gz)
    # and a mix: some files compressed, some not
    mix = tmp_path / "Mix"
    shutil.copytree(tmp_path / "Gz", mix)
    with gzip.open(mix / "Robot1_Measurement.dat.gz", "rt") as fh:
        (mix / "Robot1_Measurement.dat").write_text(fh.read())
    os.remove(mix / "Robot1_Measurement.dat.gz")
    _same_dataset(synth, mrclam.load(mix))


# ----------------------------------------------------------------------------------------------
# malformed input: an error naming the file and the line

def _edit(path: Path, lineno: int, new: str | None, gz: bool = False):
    """Replace (or with None delete) 1-based line ``lineno`` of a plain or gzip file."""
    opener = gzip.open if gz else open
    with opener(path, "rt") as fh:
        lines = fh.read().splitlines()
    if new is None:
        del lines[lineno - 1]
    else:
        lines[lineno - 1] = new
    with opener(path, "wt") as fh:
        fh.write("\n".join(lines) + "\n")


CASES = [
    # (file, 1-based line to edit, new text, expected line in the message, message fragment)
    ("Robot1_Measurement.dat", NHEAD + 3, "%.3f \t 72 \t 1.0" % (T0 + 1), NHEAD + 3, "expected 4 columns"),
    ("Robot1_Measurement.dat", NHEAD + 5, "%.3f \t 72 \t abc \t 0.1" % (T0 + 1), NHEAD + 5,
     "column 'range'"),
    ("Robot1_Measurement.dat", NHEAD + 2, "%.3f \t 72.5 \t 1.0 \t 0.1" % T0, NHEAD + 2, "integer"),
    ("Robot1_Odometry.dat", NHEAD + 7, "%.6f \t 0.1 \t 0.01 \t 7" % (T0 - 2), NHEAD + 7,
     "expected 3 columns"),
    ("Robot2_Odometry.dat", NHEAD + 11, "%.6f \t nan \t 0.0" % (T0 - 0.9), NHEAD + 11, "finite"),
    # impossible values (issue 12 item 10; more in test_mrclam_files.py)
    ("Robot1_Measurement.dat", NHEAD + 6, "%.3f \t 72 \t -1.0 \t 0.1" % (T0 + 1), NHEAD + 6,
     "column 'range': -1.0 is below 0"),
    ("Robot1_Measurement.dat", NHEAD + 8, "%.3f \t 72 \t 1.0 \t 1e10" % (T0 + 1), NHEAD + 8,
     "column 'bearing'"),
    ("Robot2_Measurement.dat", NHEAD + 3, "%.3f \t 72 \t 1.0 \t inf" % T0, NHEAD + 3, "finite"),
    ("Landmark_Groundtruth.dat", NHEAD + 3, "  8 \t 3.0 \t 7.0 \t 0.0001 \t -0.0001", NHEAD + 3,
     "column 'y std-dev'"),
    ("Robot1_Groundtruth.dat", NHEAD + 20, "%.3f \t 0 \t nan \t 0" % (T0 - 1), NHEAD + 20, "finite"),
    ("Barcodes.dat", NHEAD + 4, "  7 \t 14", NHEAD + 4, "barcode 14 appears more than once"),
    ("Barcodes.dat", NHEAD + 1, "  1 \t five", NHEAD + 1, "column 'barcode'"),
    ("Landmark_Groundtruth.dat", NHEAD + 2, "  7 \t 4.0 \t 6.0 \t 0.0001", NHEAD + 2, "expected 5 columns"),
]


@pytest.mark.parametrize("gz", [False, True], ids=["plain", "gz"])
@pytest.mark.parametrize("case", CASES, ids=[f"{c[0]}:{c[4]}" for c in CASES])
def test_malformed_input_names_file_and_line(tmp_path, case, gz):
    fname, lineno, new, want_line, fragment = case
    d = write_dataset(tmp_path / "Bad", gz=gz)
    path = d / (fname + (".gz" if gz else ""))
    _edit(path, lineno, new, gz=gz)
    with pytest.raises(DataFormatError) as exc:
        mrclam.load(d)
    err = exc.value
    assert isinstance(err, ValueError)
    assert err.path == str(path) and err.line == want_line
    assert str(path) in str(err) and f"line {want_line}" in str(err) and fragment in str(err)


@pytest.mark.parametrize("missing", ["Landmark_Groundtruth.dat", "Barcodes.dat"])
def test_missing_required_file_is_named(tmp_path, missing):
    d = write_dataset(tmp_path / "Missing")
    os.remove(d / missing)
    with pytest.raises(DataFormatError, match=missing.replace(".", r"\.") + ".*not found"):
        mrclam.load(d)


def test_odometry_without_measurements_is_an_error(tmp_path):
    d = write_dataset(tmp_path / "Orphan")
    os.remove(d / "Robot2_Measurement.dat")
    with pytest.raises(DataFormatError, match="Robot2_Measurement"):
        mrclam.load(d)


def test_header_only_measurement_file_gives_a_robot_without_views(tmp_path):
    d = write_dataset(tmp_path / "Empty")
    (d / "Robot2_Measurement.dat").write_text("\n".join(HEADER) + "\n")
    ds = mrclam.load(d)
    assert ds.robot(2).n_views == 0 and mrclam.triplet_histories(ds, 2) == []
    assert ds.report.robot(2).empty_measurement_file and not ds.report.robot(1).empty_measurement_file
    assert ds.report.totals()["empty_measurement_files"] == 1


# ----------------------------------------------------------------------------------------------
# data flow and figures

def test_datasets_do_not_import_plotting():
    code = ("import sys, qfg.datasets.mrclam; "
            "print('qfg.harness.plotting' in sys.modules, 'qfg.harness.plotting_mrclam' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


def test_dataset_figure_is_written(tmp_path, synth):
    from qfg.harness.plotting_mrclam import dataset_figure

    h = mrclam.triplet_histories(synth, 1, **OPTS)[0]
    out = dataset_figure(synth, 1, tmp_path / "ds.png", history=h, time_range=(0, 30))
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ----------------------------------------------------------------------------------------------
# the real datasets, when present

def _real_root() -> Path:
    env = os.environ.get(mrclam.DATA_ENV)
    return Path(env) if env else shared_data_dir() / "mrclam"


REAL = _real_root()
NEEDS_REAL = pytest.mark.skipif(not (REAL / "MRCLAM_Dataset1").is_dir(),
                                reason=f"MRCLAM data not found at {REAL} (set QFG_MRCLAM_DIR)")


@pytest.fixture(scope="module")
def real():
    return {i: mrclam.load(REAL / f"MRCLAM_Dataset{i}") for i in range(1, 6)
            if (REAL / f"MRCLAM_Dataset{i}").is_dir()}


@NEEDS_REAL
def test_real_datasets_load(real):
    assert sorted(real) == [1, 2, 3, 4, 5]
    for i, ds in real.items():
        assert sorted(ds.robots) == [1, 2, 3, 4, 5]
        assert ds.landmark_ids.tolist() == list(range(6, 21))
        no_odo = sorted(n for n, rd in ds.robots.items() if not rd.has_odometry)
        assert no_odo == {3: [4], 5: [1, 2, 3, 4, 5]}.get(i, [])   # as the data README says
        for rd in ds.robots.values():
            assert rd.n_views > 1000 and rd.n_robot > 0
            assert np.all(np.diff(rd.view_times) > 0)
            assert np.all(np.abs(rd.bearing) < 0.7)   # the cameras' field of view is about +-33 deg


@NEEDS_REAL
def test_real_histories_and_odometry_agree_with_landmark_fixes(real):
    ds = real[2]
    hs = mrclam.triplet_histories(ds, 5)
    assert len(hs) > 0 and all(h.n_views >= 3 and h.has_motion for h in hs)
    assert all(np.all(np.diff(h.views) > 0) for h in hs)
    # the integrated odometry's turn between fixes 3-10 s apart matches the fixes' turn
    f = mrclam.landmark_fixes(ds, 5, min_landmarks=3)
    good = f.residual < 0.1
    ft, fp = f.times[good], f.poses[good]
    odo = mrclam.dead_reckon(ds.robot(5), ft)
    i, j = np.nonzero(((ft[None] - ft[:, None]) > 3) & ((ft[None] - ft[:, None]) <= 10))
    err = np.angle(np.exp(1j * ((fp[j, 2] - fp[i, 2]) - (odo[j, 2] - odo[i, 2]))))
    assert i.size > 100 and np.degrees(np.median(np.abs(err))) < 5.0
    none = mrclam.triplet_histories(real[5], 1)
    assert len(none) > 0 and not any(h.has_motion for h in none)


@NEEDS_REAL
def test_real_dataset1_has_two_landmarks_swapped(real):
    # measured quirk (docs/mrclam.md): in dataset 1, landmarks 11 and 17 are each seen at the
    # other's ground-truth position; the other datasets are consistent.
    assert mrclam.check_landmarks(real[1]).swaps == ((11, 17),)
    for i in (2, 3, 4, 5):
        chk = mrclam.check_landmarks(real[i])
        assert chk.swaps == () and np.all(chk.error < 0.5)


@NEEDS_REAL
def test_real_gz_and_plain_copy_agree(tmp_path, real):
    src = REAL / "MRCLAM_Dataset4"
    dst = tmp_path / "MRCLAM_Dataset4"
    dst.mkdir()
    for p in src.iterdir():
        if p.name.endswith(".gz"):
            with gzip.open(p, "rb") as fi, open(dst / p.name[:-3], "wb") as fo:
                shutil.copyfileobj(fi, fo)
        else:
            shutil.copy(p, dst / p.name)
    plain = mrclam.load(dst)
    a, b = real[4], plain
    for n in a.robots:
        assert np.array_equal(a.robots[n].view_bearings, b.robots[n].view_bearings)
        assert np.array_equal(a.robots[n].odometry.omega, b.robots[n].odometry.omega)
    assert mrclam.history_counts(a) == mrclam.history_counts(b)
