"""The heavy-tailed step-length-ratio factor (``distance_tail``) of the SIS motion model: the
factor is the closed-form normal mixture, the weights carry it, the mixture proposal (which
draws the circle children from the core normal) still targets the same posterior, the move
target carries it, a ratio off by a factor of 2 no longer vetoes the truth, and bad input."""

from dataclasses import replace

import numpy as np
import pytest

from qfg import metrics
from qfg.simulation import random_triplet_history
from qfg.solvers import TripletSolver, _likelihood, _sis, solve_triplet, solve_triplets

SB, SH = np.deg2rad(2), np.deg2rad(5)
TAIL = (0.1, 7.0)


def _hist(seed, n=3, sd=0.05):
    return random_triplet_history(np.random.default_rng(seed), n, SB, SH, sigma_distance_ratio=sd)


def _steps(poses):
    return np.hypot(*np.diff(poses[..., :2], axis=-2).T).T


def test_factor_is_the_normal_mixture_of_the_log_ratio():
    rng = np.random.default_rng(0)
    s, sp, d, dp = rng.uniform(0.1, 3.0, (4, 50))
    sig = rng.uniform(0.05, 0.3, 50)
    r = np.log(s / sp) - np.log(d / dp)
    share, scale = TAIL

    def normal(x, w):
        return np.exp(-0.5 * (x / w) ** 2) / (w * np.sqrt(2 * np.pi))

    direct = np.log((1 - share) * normal(r, sig) + share * normal(r, scale * sig))
    tail = _likelihood.as_distance_tail(TAIL)
    np.testing.assert_allclose(_sis.log_distance_factor(s, sp, d, dp, sig, tail), direct,
                               rtol=1e-10)
    # a density in r: integrates to 1 over the log ratio
    x = np.linspace(-5, 5, 200001)
    f = np.exp(_sis.log_distance_factor(np.exp(x), 1.0, 1.0, 1.0, 0.1, tail))
    assert abs(np.sum(f) * (x[1] - x[0]) - 1.0) < 1e-6
    # no factor where a distance or a step is 0, as without the tail
    zero = _sis.log_distance_factor([1.0, 1.0, 0.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0],
                                    [1.0, 0.0, 1.0], 0.1, tail)
    assert zero.tolist() == [0.0, 0.0, 0.0]


def test_intermediate_weights_carry_the_tail_factor(monkeypatch):
    # ray proposal only, nothing pruned: the same children with the normal and the tail, whose
    # weights differ by exactly the two factors' difference
    monkeypatch.setattr(_sis, "_MIX_DISTANCE_PROPOSAL", False)
    h = _hist(11, 4)
    kw = dict(method="full", seed=2, n_samples=100, motion_samples=4, max_hypotheses=10**6,
              prune_ratio=0.0, rejuvenate=0, sigma_distance_ratio=0.2)
    a = TripletSolver.solve(h, **kw)._state
    b = TripletSolver.solve(h, distance_tail=TAIL, **kw)._state
    np.testing.assert_array_equal(a.poses, b.poses)
    st = _steps(b.poses)
    args = (st[:, 1:], st[:, :-1], h.distances[1:], h.distances[:-1], 0.2)
    f = _sis.log_distance_factor(*args, _likelihood.as_distance_tail(TAIL)) \
        - _sis.log_distance_factor(*args)
    np.testing.assert_allclose(b.lw_base - a.lw_base, f.sum(axis=1), rtol=1e-9, atol=1e-9)


def test_mixture_proposal_with_tail_targets_the_same_posterior(monkeypatch):
    # The circle children come from the core normal while the target's factor is the mixture:
    # the weighted means of the step-length log ratio and of the new camera agree with the ray
    # proposal alone (both unbiased for the same target). A history whose second step is
    # measured 1.6x too long puts weight in the tail.
    h = _hist(900038, 3, 0.02)
    h = replace(h, distances=h.distances * np.array([1.0, 1.6]))
    kw = dict(method="full", n_samples=1000, motion_samples=16, max_hypotheses=10**6,
              prune_ratio=0.0, sigma_distance_ratio=0.02, distance_tail=(0.2, 10.0))
    out = {}
    for mix in (False, True):
        monkeypatch.setattr(_sis, "_MIX_DISTANCE_PROPOSAL", mix)
        vals = []
        for seed in range(2):
            st = TripletSolver.solve(h, seed=seed, **kw)._state
            w = np.exp(st.lw_base - st.lw_base.max())
            w /= w.sum()
            s = _steps(st.poses)
            vals.append([np.sum(w * np.log(s[:, 1] / s[:, 0])), np.sum(w * st.poses[:, 2, 0]),
                         np.sum(w * st.poses[:, 2, 1])])
        out[mix] = np.mean(vals, axis=0)
    np.testing.assert_allclose(out[True], out[False], atol=0.02)


def test_move_target_includes_the_tail_factor():
    h = _hist(13, 4, 0.1)
    st = TripletSolver.solve(h, method="fast", seed=0, distance_tail=TAIL)._state
    tid = np.zeros(1, dtype=int)
    true = np.asarray(h.truth.poses_ab, dtype=float)[None]
    lt, _ = _sis._log_pose_target(st, tid, true)
    lt0, _ = _sis._log_pose_target(replace(st, distances=np.zeros_like(st.distances)), tid, true)
    stp = _steps(true)
    f = _sis.log_distance_factor(stp[:, 1:], stp[:, :-1], h.distances[1:], h.distances[:-1], 0.1,
                                 _likelihood.as_distance_tail(TAIL))
    np.testing.assert_allclose(lt - lt0, f.sum(axis=1), rtol=1e-9)


def test_a_ratio_off_by_two_no_longer_vetoes_the_truth():
    # Simulated misfit: the second step's measured length doubled. Under the normal (sigma
    # 0.05) the truth's ratio is 14 sigma off; with the tail it is an ordinary tail event.
    hs = [_hist(s, 4, 0.05) for s in range(100, 112)]
    bad = [replace(h, distances=h.distances * np.array([1.0, 2.0, 2.0])) for h in hs]
    kw = dict(method="full", seed=0)
    score = {}
    for name, extra in (("normal", {}), ("tail", {"distance_tail": TAIL})):
        est = solve_triplets(bad, **kw, **extra)
        score[name] = np.array([metrics.log_score(e.landmark, h.truth.state, clip=1e-4)
                                for e, h in zip(est, bad, strict=True)])
    assert score["tail"].mean() > score["normal"].mean() + 0.3
    assert np.mean(score["tail"] < np.log(0.01)) < np.mean(score["normal"] < np.log(0.01))


@pytest.mark.parametrize("bad", [(0.1,), (1.2, 3.0), (0.1, 0.5), "x",
                                 {"share": 0.1, "scale": 2.0, "outlier": 0.1}])
def test_bad_distance_tail(bad):
    with pytest.raises(ValueError, match="distance_tail"):
        solve_triplet(_hist(1), method="full", seed=0, distance_tail=bad)


def test_methods_without_distances_refuse_the_option():
    with pytest.raises(ValueError, match="distance_tail: not an option of method 'baseline'"):
        solve_triplet(_hist(1), method="baseline", seed=0, distance_tail=TAIL)
