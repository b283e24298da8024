"""One heading sigma per step (full and fast): equal steps are the one-sigma model to the bit,
batch equals incremental, the move target is the closed form, the right per-step model beats
one sigma on histories simulated with it, and bad input gets a clear error."""

from dataclasses import replace

import numpy as np
import pytest

from qfg import metrics
from qfg.simulation import random_triplet_history
from qfg.solvers import TripletSolver, solve_triplet, solve_triplets
from qfg.solvers.sis import target as _target

SB = np.deg2rad(1.0)
STEPS = np.deg2rad([1.0, 20.0, 1.0])


def _noisy(seed, steps=STEPS):
    """A 4-view history with exact headings plus N(0, steps[i]) noise on step i."""
    h = random_triplet_history(np.random.default_rng(1000 + seed), len(steps) + 1, SB, 0.0)
    noise = steps * np.random.default_rng(5000 + seed).standard_normal(len(steps))
    return replace(h, headings=h.headings + noise, sigma_heading=steps)


@pytest.mark.parametrize("method", ["full", "fast"])
def test_equal_steps_are_the_one_sigma_model(method):
    h = _noisy(0)
    a = solve_triplet(replace(h, sigma_heading=0.05), method=method, seed=3)
    b = solve_triplet(replace(h, sigma_heading=np.full(3, 0.05)), method=method, seed=3)
    np.testing.assert_array_equal(a.landmark, b.landmark)
    np.testing.assert_array_equal(a.cameras, b.cameras)


@pytest.mark.parametrize("method", ["full", "fast"])
def test_batch_equals_incremental_with_step_sigmas(method):
    hs = [_noisy(s) for s in range(3)]
    batch = solve_triplets(hs, method=method, seed=7)
    single = [solve_triplet(h, method=method, seed=s) for h, s in
              zip(hs, np.random.SeedSequence(7).spawn(3), strict=True)]
    solver = TripletSolver(method, sigma_bearing=SB, sigma_heading=STEPS.max(),
                           seed=np.random.SeedSequence(7).spawn(3)[0])
    for i in range(4):
        solver.add_view(hs[0].bearings[i], None if i == 0 else hs[0].headings[i - 1],
                        sigma_heading=None if i == 0 else STEPS[i - 1])
    for e, f in zip(batch, single, strict=True):
        np.testing.assert_array_equal(e.landmark, f.landmark)
    np.testing.assert_array_equal(solver.estimate().landmark, single[0].landmark)


def test_move_target_is_the_per_step_closed_form():
    h = _noisy(4)
    st = TripletSolver.solve(h, method="fast", seed=0)._state
    true = np.asarray(h.truth.poses_ab, dtype=float)[None]
    tid = np.zeros(1, dtype=int)
    lt, _ = _target.log_pose_target(st, tid, true)
    flat, _ = _target.log_pose_target(replace(st, step_sigma=np.ones_like(st.step_sigma)), tid,
                                    true)
    X, al = true[0, :, :2], true[0, :, 2]
    d = np.diff(X, axis=0)
    rh = np.angle(np.exp(1j * (h.headings - (np.arctan2(d[:, 1], d[:, 0]) - al[:-1]))))
    # only the heading part differs: -rh^2 / (2 s^2) against -rh^2 / 2
    np.testing.assert_allclose(lt - flat, -0.5 * np.sum(rh ** 2 / STEPS ** 2 - rh ** 2),
                               rtol=1e-9, atol=1e-9)


def test_the_right_per_step_model_scores_best():
    # Simulated with a 20-deg middle step among 1-deg ones: the per-step model against one
    # sigma for every step (the largest: too wide elsewhere; the smallest: over-confident)
    hs = [_noisy(s) for s in range(24)]
    score = {}
    for name, sh in (("steps", STEPS), ("max", STEPS.max()), ("min", STEPS.min())):
        est = solve_triplets([replace(h, sigma_heading=sh) for h in hs], method="full", seed=0)
        score[name] = np.mean([metrics.log_score(e.landmark, h.truth.state)
                               for e, h in zip(est, hs, strict=True)])
    assert score["steps"] > score["max"] + 0.05
    assert score["steps"] > score["min"] + 0.3


@pytest.mark.parametrize("bad, match", [
    ([0.1, 0.2], "expected one number or 3"),
    ([0.1, -0.2, 0.1], "values >= 0"),
    ([0.1, 0.0, 0.1], "every step's sigma > 0 or every one 0"),
    ([0.1, np.nan, 0.1], "sigma_heading"),
])
def test_bad_step_sigmas(bad, match):
    with pytest.raises(ValueError, match=match):
        solve_triplet(replace(_noisy(1), sigma_heading=np.deg2rad(1.0)), method="full",
                      sigma_heading=bad)


@pytest.mark.parametrize("method", ["reference", "fast-paper"])
def test_methods_with_one_sigma_refuse_step_sigmas(method):
    with pytest.raises(ValueError, match="one sigma per step is taken by 'full' and 'fast'"):
        solve_triplet(_noisy(1), method=method, seed=0)


def test_incremental_step_sigma_checks():
    s = TripletSolver("full", sigma_bearing=SB, sigma_heading=0.05)
    with pytest.raises(ValueError, match="first view has no step"):
        s.add_view([0.1, 0.5, 0.3], sigma_heading=0.1)
    s.add_view([0.1, 0.5, 0.3])
    with pytest.raises(ValueError, match="> 0 exactly when the solver's is"):
        s.add_view([0.1, 0.5, 0.3], 0.2, sigma_heading=0.0)


def test_baseline_ignores_step_sigmas():
    h = _noisy(2)
    a = solve_triplet(h, method="baseline", seed=0)
    b = solve_triplet(replace(h, sigma_heading=0.1), method="baseline", seed=0)
    np.testing.assert_array_equal(a.landmark, b.landmark)


# ------------------------------------------------------------------ the headings' tail
HTAIL = (0.1, 8.0)


def test_move_target_with_a_heading_tail_is_the_mixture():
    from qfg.solvers.common import likelihood as _likelihood

    h = _noisy(4)
    st = TripletSolver.solve(h, method="fast", seed=0, heading_tail=HTAIL)._state
    true = np.asarray(h.truth.poses_ab, dtype=float)[None]
    tid = np.zeros(1, dtype=int)
    lt, _ = _target.log_pose_target(st, tid, true)
    plain = replace(st, opts={**st.opts, "heading_tail": None})
    l0, _ = _target.log_pose_target(plain, tid, true)
    X, al = true[0, :, :2], true[0, :, 2]
    d = np.diff(X, axis=0)
    rh = np.angle(np.exp(1j * (h.headings - (np.arctan2(d[:, 1], d[:, 0]) - al[:-1]))))
    share, scale = HTAIL

    def normal(x, s):
        return np.exp(-0.5 * (x / s) ** 2) / (s * np.sqrt(2 * np.pi))

    mix = np.sum(np.log((1 - share) * normal(rh, STEPS) + share * normal(rh, scale * STEPS)))
    # the one-sigma target leaves out the normal's constants: -rh^2 / (2 s^2) per step
    np.testing.assert_allclose(lt - l0, mix + 0.5 * np.sum(rh ** 2 / STEPS ** 2), rtol=1e-9)
    assert _likelihood.as_normal_tail(HTAIL, "heading_tail").share == share


def test_a_heading_tail_keeps_an_outlier_step_from_vetoing_the_truth():
    # Simulated misfit: every history's second step off by 25 deg while the model says 1 deg
    # per step; with the tail (10% of steps 8x wider) the truth is no longer ruled out
    steps = np.deg2rad([1.0, 1.0, 1.0])
    hs = []
    for s in range(16):
        h = _noisy(s, steps)
        hs.append(replace(h, headings=h.headings + np.deg2rad([0.0, 25.0, 0.0])))
    score = {}
    for name, extra in (("normal", {}), ("tail", {"heading_tail": HTAIL})):
        est = solve_triplets(hs, method="full", seed=0, **extra)
        score[name] = np.array([metrics.log_score(e.landmark, h.truth.state)
                                for e, h in zip(est, hs, strict=True)])
    assert score["tail"].mean() > score["normal"].mean() + 0.3
    assert np.mean(score["tail"] < np.log(0.01)) < np.mean(score["normal"] < np.log(0.01))


def test_bad_heading_tail_and_methods_without_it():
    with pytest.raises(ValueError, match="heading_tail: expected None or"):
        solve_triplet(_noisy(1), method="full", seed=0, heading_tail=(0.1,))
    with pytest.raises(ValueError, match="heading_tail: not an option of method 'reference'"):
        solve_triplet(replace(_noisy(1), sigma_heading=0.02), method="reference", seed=0,
                      heading_tail=HTAIL)
