"""The SIS engine's few-views budget (option ``few_views_budget``): used while a triplet has at
most ``_engine.FEW_VIEWS`` views, never seen in an answer with more views, and the same answer
whether the views come one at a time or together."""

import numpy as np
import pytest

from qfg.simulation import random_triplet_history
from qfg.solvers import TripletSolver, solve_triplet, solve_triplets
from qfg.solvers.sis import engine as _engine

_SMALL = {"n_samples": 48, "motion_samples": 3, "max_hypotheses": 120, "posterior_samples": 24,
          "landmark_samples": 2}
_BUDGET = {"n_samples": 96, "motion_samples": 4, "max_hypotheses": 240, "posterior_samples": 48}


def _hist(seed, n, **kw):
    return random_triplet_history(np.random.default_rng(seed), n, np.deg2rad(2.0),
                                  np.deg2rad(5.0), **kw)


def _incremental(h, n, seed, **opts):
    s = TripletSolver("full", sigma_bearing=h.sigma_bearing, sigma_heading=h.sigma_heading,
                      seed=seed, sigma_distance_ratio=h.sigma_distance_ratio, **opts)
    out = []
    for i in range(n):
        d = None if i == 0 or h.distances is None else h.distances[i - 1]
        s.add_view(h.bearings[i], None if i == 0 else h.headings[i - 1], d)
        out.append(s.estimate())
    return out


@pytest.mark.parametrize("distances", [False, True])
def test_incremental_equals_batch_and_later_views_ignore_the_small_budget(distances):
    kw = {"sigma_distance_ratio": 0.074} if distances else {}
    h = _hist(41, 5, **kw)
    opts = dict(_BUDGET, few_views_budget=_SMALL, rejuvenate=1)
    inc = _incremental(h, 5, 9, **opts)
    for n in range(1, 6):
        batch = solve_triplet(**_first(h, n), method="full", seed=9, **opts)
        np.testing.assert_array_equal(inc[n - 1].landmark, batch.landmark)
        np.testing.assert_array_equal(inc[n - 1].cameras, batch.cameras)
        plain = solve_triplet(**_first(h, n), method="full", seed=9, **_BUDGET, rejuvenate=1,
                              few_views_budget=None)
        small = solve_triplet(**_first(h, n), method="full", seed=9,
                              **{**_BUDGET, **_SMALL}, rejuvenate=1, few_views_budget=None)
        if n <= _engine.FEW_VIEWS:
            # the small budget's answer: exactly the engine with those options
            np.testing.assert_array_equal(batch.landmark, small.landmark)
        else:
            # beyond FEW_VIEWS the answer is the caller's budget's, to the bit
            np.testing.assert_array_equal(batch.landmark, plain.landmark)
            np.testing.assert_array_equal(batch.cameras, plain.cameras)
        assert batch.options["few_views_budget"] == _SMALL


def _first(h, n):
    """The first n views of a history, as solve_triplet's arguments."""
    kw = {} if h.distances is None else {"distances": h.distances[:n - 1],
                                          "sigma_distance_ratio": h.sigma_distance_ratio}
    return dict(bearings=h.bearings[:n], headings=h.headings[:n - 1] if n > 1 else None,
                sigma_bearing=h.sigma_bearing, sigma_heading=h.sigma_heading, **kw)


def test_batches_of_3_and_4_views_match_their_incremental_solves():
    # solve_triplets tells the engine the number of views (no rebuild at 4 views); the
    # incremental solver does not know it and rebuilds: the same answers
    opts = dict(_BUDGET, few_views_budget=_SMALL)
    for n in (3, 4):
        hs = [_hist(50 + i, 4) for i in range(2)]
        b = np.stack([h.bearings[:n] for h in hs])
        es = solve_triplets(b, np.stack([h.headings[:n - 1] for h in hs]), method="full",
                            sigma_bearing=hs[0].sigma_bearing, sigma_heading=hs[0].sigma_heading,
                            seed=4, **opts)
        for t, (h, e) in enumerate(zip(hs, es, strict=True)):
            root = np.random.SeedSequence(np.random.SeedSequence(4).entropy, spawn_key=(t,))
            inc = _incremental(h, n, root, **opts)[-1]
            np.testing.assert_array_equal(inc.landmark, e.landmark)


def test_bad_few_views_budget_is_refused():
    h = _hist(60, 3)
    with pytest.raises(ValueError, match="few_views_budget"):
        solve_triplet(h, method="full", few_views_budget={"bearing_floor": 0.1})
    with pytest.raises(ValueError, match="few_views_budget"):
        solve_triplet(h, method="full", few_views_budget={"n_samples": 0})
    with pytest.raises(ValueError, match="few_views_budget"):
        solve_triplet(h, method="full", few_views_budget=[("n_samples", 10)])


def test_budget_options_a_call_sets_are_not_overridden():
    """The few-views defaults are one package (budget, two populations, escalation): a call that
    sets a budget option, a population count or any few-views option gets the package off with
    its own settings on top, the same answers as saying so."""
    from qfg.solvers import DEFAULTS
    from qfg.solvers.common.options import FEW_VIEWS_OFF

    assert DEFAULTS["full"]["few_views_budget"] and DEFAULTS["full"]["few_views_escalate"]
    h = _hist(61, 3)
    mine = {"n_samples": 64, "motion_samples": 3, "max_hypotheses": 150, "posterior_samples": 32}
    a = solve_triplet(h, method="full", seed=2, **mine)
    b = solve_triplet(h, method="full", seed=2, **FEW_VIEWS_OFF, **mine)
    np.testing.assert_array_equal(a.landmark, b.landmark)
    assert {k: a.options[k] for k in FEW_VIEWS_OFF} == FEW_VIEWS_OFF
    # one budget option is enough; the call's other options keep their defaults
    c = solve_triplet(h, method="full", seed=2, n_samples=64, posterior_samples=32)
    assert {k: c.options[k] for k in FEW_VIEWS_OFF} == FEW_VIEWS_OFF
    d = solve_triplet(h, method="full", seed=2, n_samples=64, posterior_samples=32,
                      few_views_budget=None)
    np.testing.assert_array_equal(c.landmark, d.landmark)
    # a few-views option alone: the others off, not at their defaults
    e = solve_triplet(h, method="full", seed=2, few_views_budget={"n_samples": 200}, **mine)
    assert e.options["few_views_populations"] == 1 and e.options["few_views_escalate"] is None
    # no option: the package
    f = solve_triplet(h, method="full", seed=2)
    assert f.options["few_views_populations"] == 2 and f.options["few_views_escalate"] == 0.15
