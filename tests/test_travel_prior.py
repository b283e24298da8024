"""TravelPrior: the world box joined with one measured step length, against the box itself."""

import numpy as np
import pytest

from qfg.priors import TravelPrior, WorldBoxPrior


@pytest.mark.parametrize("box", [WorldBoxPrior(width=6.0, height=11.0),
                                 WorldBoxPrior(width=4.0, height=9.0, d_min=0.05, scale_power=-2)])
@pytest.mark.parametrize("tail", [(0.0, 1.0), (0.1, 5.0)])
def test_integrated_over_the_measurement_it_is_the_box(box, tail):
    # a joint density of (configuration, log d): its marginal over log d is the box's density,
    # which WorldBoxPrior computes in closed form (tests/test_priors.py checks it against sampling)
    q = box.sample(3, 4, 6)                      # C and four cameras
    for step in (0, 2):
        ld = np.linspace(np.log(1e-5), np.log(60.0), 2000)
        vals = np.array([TravelPrior(box, np.exp(x), step=step, tail=tail).log_density(q)
                         for x in ld])
        m = vals.max(0)
        integ = m + np.log(np.trapezoid(np.exp(vals - m), ld, axis=0))
        np.testing.assert_allclose(integ, box.log_density(q), atol=2e-3)


def test_prefers_the_step_length_the_distance_says():
    box = WorldBoxPrior(width=6.0, height=11.0)
    base = np.array([[0.5, 0.5], [2.0, 0.5]])
    b = np.exp(np.linspace(np.log(0.005), np.log(5.0), 60))
    q = np.concatenate([np.broadcast_to(base, (60, 2, 2)),
                        (base[1] + np.stack([np.zeros(60), b], 1))[:, None]], 1)
    gain = TravelPrior(box, 0.3, sigma=0.05, tail=(0.0, 1.0)).log_density(q) - box.log_density(q)
    # the pair's length s is metres in this box (at most its diagonal, with C and the cameras
    # 2 |AB| away about 5 m), so d = 0.3 m says b = d / s: about 0.06-0.3 |AB|; a step too short
    # needs an AB too long for the box (no density), a step of 1 |AB| a pair of 0.3 m
    top = b[np.argmax(gain)]
    assert 0.03 < top < 0.3
    assert np.all(gain[b < 0.3 / np.hypot(6.0, 11.0)] == -np.inf)
    assert gain[b > 3 * top].max() < gain.max() - 2
    assert gain[(b > 0.8) & (b < 1.25)].max() < gain.max() - 8


def test_fewer_points_than_the_step_needs_is_the_box():
    box = WorldBoxPrior()
    q = box.sample(1, 1, 4)                      # C and one camera: step 0 needs two
    np.testing.assert_array_equal(TravelPrior(box, 1.0).log_density(q), box.log_density(q))


def test_coinciding_cameras_have_no_density_not_nan():
    box = WorldBoxPrior()
    q = np.array([[0.5, 0.5], [2.0, 0.5], [2.0, 0.5]])
    assert TravelPrior(box, 1.0).log_density(q) == -np.inf


@pytest.mark.parametrize("kw, match", [
    (dict(box="world"), "box"), (dict(distance=0.0), "distance"), (dict(distance=np.nan), "distance"),
    (dict(step=-1), "step"), (dict(sigma=0.0), "sigma"), (dict(tail=(1.0, 2.0)), "tail"),
    (dict(tail=3), "tail"), (dict(nodes=2), "nodes"), (dict(detection=(2.0, 1.0, 0.1, 0.1)),
                                                        "detection"),
    (dict(detection=(1.0, 6.0, 0.0, 0.4)), "detection"), (dict(detection=(1.0, 6.0)), "detection")])
def test_bad_parameters_are_named(kw, match):
    args = {"box": WorldBoxPrior(), "distance": 1.0, **kw}
    with pytest.raises(ValueError, match=match):
        TravelPrior(args.pop("box"), args.pop("distance"), **args)
    with pytest.raises(ValueError, match="sampler"):
        TravelPrior(WorldBoxPrior(), 1.0).sample(0, 2, 3)


def test_detection_weighs_each_range_at_the_scale_the_step_fixes():
    # with the step's error tiny the integral over s collapses to s* = d / b, so the detection
    # factor adds exactly sum over cameras and landmarks of log D(s* r) (D written out here)
    box = WorldBoxPrior(width=6.0, height=11.0)
    q = box.sample(5, 3, 8)                                      # C and three cameras
    det = (1.2, 6.0, 0.1, 0.5)
    plain = TravelPrior(box, 0.4, sigma=1e-5, tail=(0.0, 1.0))
    seen = TravelPrior(box, 0.4, sigma=1e-5, tail=(0.0, 1.0), detection=det)
    s = 0.4 / np.hypot(*(q[:, 2] - q[:, 1]).T)
    marks = np.array([[0.0, 0.0], [0.0, 1.0]])
    want = np.zeros(len(q))
    for i in range(len(q)):
        for cam in q[i, 1:]:
            for lm in (marks[0], marks[1], q[i, 0]):
                r = s[i] * np.hypot(*(cam - lm))
                want[i] += np.log(1 / (1 + np.exp(-(r - det[0]) / det[2]))
                                  / (1 + np.exp(-(det[1] - r) / det[3])))
    got = seen.log_density(q) - plain.log_density(q)
    ok = np.isfinite(plain.log_density(q))
    assert ok.sum() >= 4
    np.testing.assert_allclose(got[ok], want[ok], atol=1e-6)


def test_detection_prefers_landmarks_in_range():
    # one camera step of 0.5 m; the cameras 2 |AB| from A: at |AB| = s the range is 2 s, and
    # the step of 0.25 |AB| fixes s = 2 m, so the landmarks stand about 4 m away; a step of
    # 0.05 |AB| makes s = 10 m and the landmarks 20 m away, out of the camera's range
    box = WorldBoxPrior(width=30.0, height=30.0)
    near = np.array([[0.5, 0.5], [2.0, 0.5], [2.0, 0.75]])
    far = np.array([[0.5, 0.5], [2.0, 0.5], [2.0, 0.55]])
    det = TravelPrior(box, 0.5, detection=(1.0, 8.0, 0.1, 0.5))
    plain = TravelPrior(box, 0.5)
    # the box alone favours the far pair (its density grows as s^(2k+1)); detection reverses it
    assert plain.log_density(near) < plain.log_density(far) - 5
    assert det.log_density(near) > det.log_density(far) + 3
