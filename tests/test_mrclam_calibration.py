"""Each robot's bearing calibration against motion capture: recovered from bearings distorted by a
known bias and scale (the synthetic dataset of test_mrclam, exact bearings), undone by
calibrate_bearings, carried into the histories; the shipped constants re-measured on dataset 6."""

from __future__ import annotations

import numpy as np
import pytest
from test_mrclam import OPTS, REAL, write_dataset

from qfg.datasets import mrclam
from qfg.geometry import wrap_angle


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    return mrclam.load(write_dataset(tmp_path_factory.mktemp("mrclam_cal") / "Synth"))


def _distort(ds, robot, bias, scale):
    """The dataset whose robot measured ``bias + (1 + scale) phi``: calibrate_bearings with the
    inverse map (m - b') / (1 + s') = bias + (1 + scale) m."""
    s_inv = 1.0 / (1.0 + scale) - 1.0
    return mrclam.calibrate_bearings(ds, {robot: (-bias * (1.0 + s_inv), s_inv)})


def test_exact_bearings_need_no_calibration(synth):
    cal = mrclam.measure_bearing_calibration(synth, offset=0.0, min_rows=10)
    assert set(cal) == {1}                                    # robot 2 has no motion capture
    bias, scale, rows = cal[1]
    assert rows > 50
    # (the capture is sampled every 0.05 s and interpolated: 4e-5 rad off on the circle)
    assert abs(bias) < 1e-4 and abs(scale) < 1e-4


def test_a_known_bias_and_scale_are_recovered_and_undone(synth):
    bias, scale = np.deg2rad(-1.3), 0.04
    bent = _distort(synth, 1, bias, scale)
    rd, rb = synth.robot(1), bent.robot(1)
    np.testing.assert_allclose(rb.view_bearings[rd.visible],
                               wrap_angle(bias + (1 + scale) * rd.view_bearings[rd.visible]),
                               atol=1e-12)
    np.testing.assert_array_equal(rb.view_bearings[~rd.visible], rd.view_bearings[~rd.visible])
    got = mrclam.measure_bearing_calibration(bent, offset=0.0, min_rows=10)[1]
    assert got[0] == pytest.approx(bias, abs=2e-4) and got[1] == pytest.approx(scale, abs=2e-4)
    fixed = mrclam.calibrate_bearings(bent, {1: got})
    np.testing.assert_allclose(fixed.robot(1).view_bearings, rd.view_bearings, atol=5e-4)
    np.testing.assert_allclose(fixed.robot(1).bearing, rd.bearing, atol=5e-4)
    # robots left out of the calibration keep their bearings
    np.testing.assert_array_equal(fixed.robot(2).view_bearings, synth.robot(2).view_bearings)


def test_histories_carry_the_calibrated_bearings(synth):
    b, s = 0.01, -0.02
    raw = mrclam.triplet_histories(synth, 1, **OPTS)
    cal = mrclam.triplet_histories(mrclam.calibrate_bearings(synth, {1: (b, s)}), 1, **OPTS)
    assert len(raw) == len(cal) > 0
    for h0, h1 in zip(raw, cal, strict=True):
        np.testing.assert_allclose(h1.bearings, wrap_angle((h0.bearings - b) / (1 + s)),
                                   atol=1e-12)
        np.testing.assert_array_equal(h1.headings, h0.headings)


def test_forward_axis_of_rotated_markers():
    """Captured headings 0.9 deg off the direction the robot drives (straight segments joined
    by turns in place): the forward axis is found at +0.9 deg, and turns are left out."""
    t = np.arange(0.0, 200.0, 0.05)
    seg = (t // 20).astype(int)
    heading = np.deg2rad(40.0) * seg                               # 20 s straight, then turn
    step = np.where((t % 20) < 15, 0.1 * 0.05, 0.0)               # the last 5 s: turn in place
    x = np.cumsum(step * np.cos(heading))
    y = np.cumsum(step * np.sin(heading))
    turn = np.where((t % 20) >= 15, np.deg2rad(40.0) * ((t % 20) - 15) / 5 - np.deg2rad(40), 0.0)
    captured = heading + turn * (seg > 0) - np.deg2rad(0.9)
    g = np.c_[t, x, y, captured]
    assert mrclam.forward_axis(g) == pytest.approx(np.deg2rad(0.9), abs=np.deg2rad(0.02))


def test_bad_calibration(synth):
    with pytest.raises(ValueError, match="robot 1"):
        mrclam.calibrate_bearings(synth, {1: (0.0, 0.9)})
    with pytest.raises(ValueError, match="robot 1"):
        mrclam.calibrate_bearings(synth, {1: (np.nan, 0.0)})
    no_gt = mrclam.calibrate_bearings(synth, {})
    no_gt = no_gt.__class__(**{**no_gt.__dict__, "robots": {2: synth.robot(2)}})
    with pytest.raises(ValueError, match="no robot ground truth"):
        mrclam.measure_bearing_calibration(no_gt)


def test_shipped_calibration_is_dataset_6s():
    d6 = REAL / "MRCLAM_Dataset6"
    if not d6.is_dir():
        pytest.skip(f"MRCLAM dataset 6 not found at {REAL} (set QFG_MRCLAM_DIR)")
    got = mrclam.measure_bearing_calibration(mrclam.load(d6))
    assert set(got) == set(mrclam.DEFAULT_BEARING_CALIBRATION)
    for n, (b, s) in mrclam.DEFAULT_BEARING_CALIBRATION.items():
        assert got[n][0] == pytest.approx(b, abs=np.deg2rad(0.001))
        assert got[n][1] == pytest.approx(s, abs=1e-4)
