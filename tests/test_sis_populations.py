"""Independent populations of the SIS engine (``populations``, ``few_views_populations``).

Checked against what must hold: K = 1 is the engine unchanged; K populations average exactly
the K single-population solves with the split budget and the populations' seeds; batch and
incremental solves agree when K changes after FEW_VIEWS views; the pooled ESS, the
between-population error and the hypotheses follow their formulas; bad values are refused.
"""

import numpy as np
import pytest

from qfg.simulation import random_triplet_history
from qfg.solvers import TripletSolver, solve_triplet, solve_triplets
from qfg.solvers.common import seeds as _seeds
from qfg.solvers.sis import populations as _populations
from qfg.solvers.sis.engine import FEW_VIEWS

SV, SW = np.deg2rad(2.0), np.deg2rad(5.0)


def _history(seed, n):
    return random_triplet_history(np.random.default_rng(seed), n, SV, SW)


def _first(h, k):
    from qfg.harness.studies.single_triplet import first_views

    return first_views(h, k)


SMALL = {"n_samples": 120, "max_hypotheses": 600, "posterior_samples": 128}


def test_one_population_is_the_engine_unchanged():
    h = _history(1, 4)
    a = solve_triplet(h, method="full", seed=5, **SMALL)
    b = solve_triplet(h, method="full", seed=5, populations=1, **SMALL)
    assert np.array_equal(a.landmark, b.landmark)
    assert np.array_equal(a.cameras, b.cameras)


def test_populations_average_the_split_solves():
    """The answer is the mean of K solves, each with 1/K of the budget and its own seed."""
    h = _history(2, 4)
    K = 2
    got = solve_triplet(h, method="full", seed=7, populations=K, **SMALL)
    root = _seeds.root_seed(7)
    split = _populations.split_options({**SMALL, "populations": K}, K)
    assert split["n_samples"] == 60 and split["max_hypotheses"] == 300
    singles = [solve_triplet(h, method="full", seed=r, **{k: split[k] for k in SMALL})
               for r in _populations.roots(root, K)]
    want = np.mean([e.landmark for e in singles], axis=0)
    assert np.allclose(got.landmark, want / want.sum(), atol=1e-12)
    assert np.allclose(got.cameras, np.mean([e.cameras for e in singles], axis=0), atol=1e-12)
    # pooled ESS of weights w_kj / K: K^2 / sum_k 1 / ess_k
    assert got.ess == pytest.approx(K * K / sum(1 / e.ess for e in singles))
    # the error is at least the between-population standard error of the mean
    L = np.stack([e.landmark for e in singles])
    assert got.mc_error >= np.max(L.std(axis=0, ddof=1)) / np.sqrt(K) - 1e-15
    assert got.options["populations"] == K and got.options["n_samples"] == SMALL["n_samples"]


def test_batch_and_incremental_agree_when_k_changes():
    h = _history(3, FEW_VIEWS + 2)
    opts = dict(SMALL, populations=3, few_views_populations=1)
    s = TripletSolver("full", sigma_bearing=SV, sigma_heading=SW, seed=11, **opts)
    for i in range(h.n_views):
        s.add_view(h.bearings[i], None if i == 0 else h.headings[i - 1])
        b = solve_triplet(_first(h, i + 1), method="full", seed=11, **opts)
        assert np.array_equal(s.estimate().landmark, b.landmark), i + 1
        assert s._populations == (1 if i + 1 <= FEW_VIEWS else 3)
    # a batch of several triplets gives each the answer it gets alone
    hs = [_first(h, FEW_VIEWS + 1), _first(_history(4, FEW_VIEWS + 1), FEW_VIEWS + 1)]
    batch = solve_triplets(hs, method="full", seed=11, **opts)
    root = _seeds.root_seed(11)
    for t, (hh, e) in enumerate(zip(hs, batch, strict=True)):
        alone = solve_triplet(hh, method="full", seed=_seeds.child_seed(root, t), **opts)
        assert np.array_equal(e.landmark, alone.landmark)


def test_hypotheses_are_the_populations_pooled():
    h = _history(5, 4)
    s = TripletSolver.solve(h.bearings, h.headings, sigma_bearing=SV, sigma_heading=SW, seed=2,
                            populations=2, **SMALL)
    hyp = s.hypotheses()
    assert hyp.landmark_weights.sum() == pytest.approx(1.0)
    assert np.allclose(hyp.camera_weights.sum(axis=1), 1.0)
    assert hyp.camera_samples.shape[0] == 4
    # the landmark answer is the pooled weights' state histogram up to the engine's shrinkage:
    # each population's answer is, so their mean is
    assert hyp.landmark_samples.shape[0] == hyp.landmark_weights.shape[0]


def test_disagreeing_populations_are_flagged():
    """Two populations certain of different states: the average keeps both and is flagged."""
    from qfg.solvers.common.estimate import TripletEstimate

    def est(s):
        p = np.full(20, 1e-6)
        p[s] = 1.0
        p /= p.sum()
        return TripletEstimate(landmark=p, cameras=np.tile(p, (3, 1)), n_hypotheses=10,
                               degenerate=False, reason="", method="full", partition="edc",
                               n_views=3, ess=100.0, mc_error=0.01, pareto_k=0.2,
                               model_check=0.5)

    e, hyp = _populations.merge([(est(3), None), (est(7), None)], {"populations": 2})
    assert hyp is None
    assert e.degenerate and "disagree" in e.reason
    assert e.landmark[3] == pytest.approx(0.5, abs=1e-4) and e.landmark[7] == pytest.approx(0.5, abs=1e-4)
    assert e.mc_error == pytest.approx(np.std([1.0, 0.0], ddof=1) / np.sqrt(2), abs=1e-4)
    same, _ = _populations.merge([(est(3), None), (est(3), None)], {"populations": 2})
    assert not same.degenerate


@pytest.mark.parametrize("bad", [0, -1, 1.5, "two"])
def test_bad_population_counts_are_refused(bad):
    h = _history(6, 3)
    with pytest.raises(ValueError, match="populations"):
        solve_triplet(h, method="full", populations=bad)
    with pytest.raises(ValueError, match="few_views_populations"):
        solve_triplet(h, method="fast", few_views_populations=bad)


def test_pooled_flags_decide_the_sampled_tests_for_the_pool():
    """A union of per-population tests would flag more the more populations there are: the
    flags read off the samples are decided again for the pool (the mean share of unresolved
    depth against UNRESOLVED_SHARE, the pooled ESS against min_ess); measurement flags are
    kept as they are."""
    import dataclasses

    from qfg.solvers.common.degenerate import UNRESOLVED_REASON, UNRESOLVED_SHARE
    from qfg.solvers.common.estimate import ess_reason, pooled_reasons

    h = _history(3, 3)
    base = solve_triplet(h, method="full", seed=1, few_views_budget=None)

    def pop(share, *reasons):
        return dataclasses.replace(base, depth_unresolved=share, reason="; ".join(reasons),
                                   degenerate=bool(reasons))

    geo = "the camera stands on line AB in views 1, 2"
    lo, hi = UNRESOLVED_SHARE - 0.2, UNRESOLVED_SHARE + 0.1
    # one population over the line, the mean under it: not flagged; the measurement flag kept
    got = pooled_reasons([pop(hi, geo, UNRESOLVED_REASON), pop(lo, geo)], [0.5, 0.5], 500.0,
                         {"min_ess": 2.0})
    assert got == [geo]
    # both over it: flagged once
    got = pooled_reasons([pop(hi, UNRESOLVED_REASON), pop(hi + 0.05, UNRESOLVED_REASON)],
                         [0.5, 0.5], 500.0, {"min_ess": 2.0})
    assert got == [UNRESOLVED_REASON]
    # weights count: 0.9 on the high share
    assert pooled_reasons([pop(hi), pop(lo)], [0.9, 0.1], 500.0, {}) == [UNRESOLVED_REASON]
    # the ESS flag by the pooled ESS, not by either population's
    low = pop(lo, ess_reason(1.5, 2.0))
    assert pooled_reasons([low, pop(lo)], [0.5, 0.5], 3.0, {"min_ess": 2.0}) == []
    assert pooled_reasons([low, pop(lo)], [0.5, 0.5], 1.8, {"min_ess": 2.0}) == [
        ess_reason(1.8, 2.0)]
    # a share a method does not compute: its flag is kept as raised
    assert pooled_reasons([pop(float("nan"), UNRESOLVED_REASON), pop(lo)], [0.5, 0.5], 500.0,
                          {}) == [UNRESOLVED_REASON]
