"""Escalation of few-views answers (option ``few_views_escalate``, :mod:`qfg.solvers.sis.escalation`):
the answers equal the small budget's where its populations agree and the budget-weighted mean of
the small and the whole budget's answers (the latter from the escalation seed) where they do
not; incremental and batch solves agree after every view; bad values are refused."""

import numpy as np
import pytest

from qfg.simulation import random_triplet_history
from qfg.solvers import TripletSolver, solve_triplet, solve_triplets
from qfg.solvers.sis import engine as _engine

_WHOLE = {"n_samples": 96, "motion_samples": 4, "max_hypotheses": 240, "posterior_samples": 48}
_SMALL = {"n_samples": 48, "motion_samples": 3, "max_hypotheses": 120, "posterior_samples": 24,
          "landmark_samples": 2}
_FEW = dict(_WHOLE, few_views_populations=2, few_views_budget=_SMALL)
#: the spawn key of the escalated solve's seed under a triplet's seed (documented)
_KEY = 2_000_003
#: the small answer's share: n_samples x motion_samples of each budget
_W = 48 * 3 / (48 * 3 + 96 * 4)


def _hist(seed, n, **kw):
    return random_triplet_history(np.random.default_rng(seed), n, np.deg2rad(2.0),
                                  np.deg2rad(5.0), **kw)


def _first(h, n):
    kw = {} if h.distances is None else {"distances": h.distances[:n - 1],
                                          "sigma_distance_ratio": h.sigma_distance_ratio}
    return dict(bearings=h.bearings[:n], headings=h.headings[:n - 1] if n > 1 else None,
                sigma_bearing=h.sigma_bearing, sigma_heading=h.sigma_heading, **kw)


def test_answers_are_the_small_ones_or_pooled_with_the_whole_budget():
    hs = [_hist(70 + i, 3) for i in range(8)]
    small = solve_triplets(hs, method="full", seed=5, **_FEW)
    err = np.sort([e.mc_error for e in small])
    # a threshold with answers on both sides of it
    thr = float(0.5 * (err[3] + err[4]))
    assert 0 < thr < 1
    got = solve_triplets(hs, method="full", seed=5, few_views_escalate=thr, **_FEW)
    n_escalated = 0
    for t, (h, s, g) in enumerate(zip(hs, small, got, strict=True)):
        if s.mc_error <= thr:
            np.testing.assert_array_equal(g.landmark, s.landmark)
            np.testing.assert_array_equal(g.cameras, s.cameras)
            assert g.n_hypotheses == s.n_hypotheses
            continue
        n_escalated += 1
        # the whole budget alone, from the triplet's seed's escalation child
        whole = solve_triplet(h, method="full", seed=np.random.SeedSequence(5, spawn_key=(t, _KEY)),
                              **_WHOLE)
        np.testing.assert_allclose(g.landmark, _W * s.landmark + (1 - _W) * whole.landmark,
                                   rtol=0, atol=1e-12)
        np.testing.assert_allclose(g.cameras, _W * s.cameras + (1 - _W) * whole.cameras,
                                   rtol=0, atol=1e-12)
        assert g.n_hypotheses == s.n_hypotheses + whole.n_hypotheses
        assert np.isclose(g.mc_error, np.hypot(_W * s.mc_error, (1 - _W) * whole.mc_error))
        assert g.options["few_views_escalate"] == thr
    assert n_escalated == 4


@pytest.mark.parametrize("distances", [False, True])
def test_incremental_equals_batch_after_every_view(distances):
    kw = {"sigma_distance_ratio": 0.074} if distances else {}
    h = _hist(43, 5, **kw)
    # every answer of up to FEW_VIEWS views escalates at this threshold
    opts = dict(_FEW, few_views_escalate=1e-9)
    s = TripletSolver("full", sigma_bearing=h.sigma_bearing, sigma_heading=h.sigma_heading,
                      seed=9, sigma_distance_ratio=h.sigma_distance_ratio, **opts)
    for n in range(1, 6):
        d = None if n == 1 or h.distances is None else h.distances[n - 2]
        s.add_view(h.bearings[n - 1], None if n == 1 else h.headings[n - 2], d)
        inc = s.estimate()
        batch = solve_triplet(**_first(h, n), method="full", seed=9, **opts)
        np.testing.assert_array_equal(inc.landmark, batch.landmark)
        np.testing.assert_array_equal(inc.cameras, batch.cameras)
        assert inc.mc_error == batch.mc_error and inc.ess == batch.ess
        plain = solve_triplet(**_first(h, n), method="full", seed=9, **_FEW)
        if n <= _engine.FEW_VIEWS:
            assert batch.n_hypotheses > plain.n_hypotheses      # escalated
        else:
            # beyond FEW_VIEWS the option changes nothing
            np.testing.assert_array_equal(batch.landmark, plain.landmark)
            np.testing.assert_array_equal(batch.cameras, plain.cameras)


def test_pooled_hypotheses_are_both_sets_with_weights_summing_to_one():
    h = _hist(44, 3)
    s = TripletSolver.solve(h, method="full", seed=2, few_views_escalate=1e-9, **_FEW)
    small = TripletSolver.solve(h, method="full", seed=2, **_FEW).hypotheses()
    hyp = s.hypotheses()
    assert hyp.landmark_weights.sum() == pytest.approx(1.0)
    assert hyp.landmark_samples.shape[0] > small.landmark_samples.shape[0]
    np.testing.assert_allclose(hyp.landmark_weights[:small.landmark_weights.size],
                               _W * small.landmark_weights)
    np.testing.assert_allclose(hyp.camera_weights.sum(axis=1), 1.0)


@pytest.mark.parametrize("value", [0, 1, 1.5, -0.1, "0.1", True, [0.1]])
def test_bad_thresholds_are_refused(value):
    h = _hist(45, 3)
    with pytest.raises(ValueError, match="few_views_escalate"):
        solve_triplet(h, method="full", few_views_escalate=value, **_FEW)


def test_escalation_needs_two_populations_and_the_full_method():
    h = _hist(46, 3)
    with pytest.raises(ValueError, match="few_views_populations >= 2"):
        solve_triplet(h, method="full", few_views_escalate=0.15, few_views_budget=_SMALL)
    with pytest.raises(ValueError, match="few_views_escalate: not an option of method 'fast'"):
        solve_triplet(h, method="fast", few_views_escalate=0.15)
    with pytest.raises(ValueError, match="few_views_escalate"):
        TripletSolver("full", few_views_escalate=2.0, few_views_populations=2)
