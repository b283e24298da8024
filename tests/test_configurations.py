"""Configuration inference (qfg.configurations): checked against the prior, brute-force importance
sampling from the prior, a closed form for one seen triplet, and its own Monte Carlo error."""

from __future__ import annotations

import json

import numpy as np
import pytest

from qfg.combine import temper
from qfg.configurations import (
    TEMPER,
    UNSETTLED_ERROR,
    UNSETTLED_SHARE,
    ConfigurationPosterior,
    NotSettledWarning,
    PositionSummary,
    configuration_marginals,
    infer_configurations,
    prior_states,
    summarize_position,
)
from qfg.geometry import to_frame
from qfg.graph import QualitativeFactorGraph
from qfg.priors import WorldBoxPrior

M = 20
FLOOR = 0.01


def _vec(state, p=0.9):
    v = np.full(M, (1 - p) / (M - 1))
    v[state] = p
    return v


# two overlapping seen triplets on four landmarks: a moderate and a sharp estimate
EVIDENCE = {(0, 1, 2): _vec(1, 0.7), (1, 2, 3): _vec(12, 0.95)}


def _all_triplets(n):
    return [(a, b, c) for a in range(n) for b in range(n) for c in range(n)
            if len({a, b, c}) == 3]


def _brute_force(evidence, triplets, n, draws, floor=FLOOR, seed=0, tau=TEMPER["config-state"]):
    """Importance sampling from the prior: weights prod_t ((1 - eps) P'_t(s_t) / q(s_t) + eps),
    P'_t = q (P_t / q)^tau normalized (the default tempering of state likelihoods)."""
    from qfg.combine import temper
    from qfg.partitions import get

    pr, part = WorldBoxPrior(), get("edc")
    q = prior_states(pr, "edc")
    X = pr.sample_world(np.random.default_rng(seed), n, draws)

    def states(ts):
        ts = np.array(ts)
        return part.state_of(to_frame(X[:, ts[:, 2]], X[:, ts[:, 0]], X[:, ts[:, 1]]))

    logw = np.zeros(draws)
    for t, v in evidence.items():
        s = states([t])[:, 0]
        vt = temper(v, q, tau)
        logw += np.log((1 - floor) * vt[s] / q[s] + floor)
    w = np.exp(logw - logw.max())
    w /= w.sum()
    S = states(triplets)
    out = np.stack([np.bincount(S[:, r], weights=w, minlength=M) for r in range(len(triplets))])
    return out, 1.0 / np.sum(w * w)


@pytest.fixture(scope="module")
def posterior():
    return infer_configurations(EVIDENCE, seed=3, n_particles=2000, n_groups=4, floor=FLOOR)


def test_no_evidence_gives_the_prior_state_marginals():
    post = infer_configurations({}, landmarks=(0, 1, 2, 3), seed=0, n_particles=2000)
    res = post.marginals()
    q = prior_states("world", "edc")
    assert post.diagnostics["n_stages"] == 0
    # every triplet's marginal is q: pooled over the 24 triplets, within a few standard errors
    P = res.probabilities
    assert np.allclose(P.sum(axis=1), 1.0)
    se = np.sqrt(q * (1 - q) / (2000 * len(P)))
    assert np.all(np.abs(P.mean(axis=0) - q) < 5 * se + 1e-3)


@pytest.mark.parametrize("tau", [1.0, 0.6])
def test_one_seen_triplet_closed_form(tau):
    # with one seen triplet its marginal is q (L / E_q L) = (1 - eps) P' + eps q exactly (P' the
    # tempered estimate, P itself at tau = 1): the floor keeps eps q(s) for the states the
    # estimate rules out (it cannot veto the truth)
    v = np.zeros(M)
    v[[1, 3]] = [0.8, 0.2]
    post = infer_configurations({(0, 1, 2): v}, seed=1, n_particles=4000, n_groups=8,
                                floor=0.05, pseudo_count=0.0, temper=tau)
    res = post.marginals([(0, 1, 2)])
    q = prior_states("world", "edc")
    want = 0.95 * (v if tau == 1 else temper(v, q, tau)) + 0.05 * q
    se = res.info["mc_error"][0]
    assert np.all(np.abs(res[(0, 1, 2)] - want) < 5 * se + 0.01)
    assert np.all(res[(0, 1, 2)][v == 0] > 0)      # ruled-out states keep mass


def test_floor_is_required():
    with pytest.raises(ValueError, match="floor"):
        infer_configurations(EVIDENCE, floor=0.0)


def test_agrees_with_brute_force_importance_sampling(posterior):
    ts = _all_triplets(4)
    res = posterior.marginals(ts, pseudo_count=0.0)
    bf, ess = _brute_force(EVIDENCE, ts, 4, 300_000)
    assert ess > 2000
    se = np.sqrt(np.asarray(res.info["mc_error"]) ** 2 + bf * (1 - bf) / ess)
    diff = np.abs(res.probabilities - bf)
    assert np.max(diff) < 0.06
    assert np.mean((diff / (se + 1e-3)) ** 2) < 4.0


def test_update_tempers_in_new_evidence(posterior):
    # start from the first triplet only, add the second: the brute-force answer of both
    first = dict(list(EVIDENCE.items())[:1])
    post = infer_configurations(first, landmarks=(3,), seed=5, n_particles=2000, floor=FLOOR)
    up = post.update(dict(list(EVIDENCE.items())[1:]), seed=6)
    ts = _all_triplets(4)
    bf, ess = _brute_force(EVIDENCE, ts, 4, 300_000, seed=1)
    diff = np.abs(up.marginals(ts, pseudo_count=0.0).probabilities - bf)
    assert np.max(diff) < 0.07
    assert set(up.evidence) == set(EVIDENCE)
    # replacing a triplet's evidence: the old likelihood is tempered out
    rep = up.update({(1, 2, 3): _vec(5, 0.95)}, seed=7)
    assert rep.evidence[(1, 2, 3)][5] == pytest.approx(0.95)
    assert np.argmax(rep.marginals([(1, 2, 3)])[(1, 2, 3)]) == 5
    # a landmark new to the map: placed from the prior, then constrained by its evidence
    new = rep.update({(1, 2, 9): _vec(12, 0.95)}, seed=8)
    assert sorted(new.landmarks) == [0, 1, 2, 3, 9] and new.positions.shape == (2000, 5, 2)
    assert np.argmax(new.marginals([(1, 2, 9)])[(1, 2, 9)]) == 12


def test_same_seed_same_answer():
    a = infer_configurations(EVIDENCE, seed=11, n_particles=400).marginals()
    b = infer_configurations(EVIDENCE, seed=11, n_particles=400).marginals()
    assert np.array_equal(a.probabilities, b.probabilities)


def test_two_seeds_agree_within_the_reported_error():
    ts = _all_triplets(4)
    r = [infer_configurations(EVIDENCE, seed=s, n_particles=2400, n_groups=8).marginals(ts)
         for s in (21, 22)]
    se = np.sqrt(np.asarray(r[0].info["mc_error"]) ** 2 + np.asarray(r[1].info["mc_error"]) ** 2)
    z2 = (r[0].probabilities - r[1].probabilities) ** 2 / (se ** 2 + 1e-8)
    assert np.mean(z2) < 3.0          # t with 7 dof: E z^2 = 1.4 per population pair
    assert np.max(np.abs(r[0].probabilities - r[1].probabilities)) < 0.08


def test_widen_mixes_each_row_toward_the_prior_by_its_monte_carlo_error(posterior):
    ts = _all_triplets(4)
    raw = posterior.marginals(ts)
    q = prior_states("world", "edc")
    se = np.asarray(raw.info["mc_error"]).max(axis=1)
    for scale in (1e-12, float(np.median(se)), 10.0):
        r = posterior.marginals(ts, widen=scale)
        w = np.minimum(1.0, se / scale)
        assert np.allclose(r.info["widened"], w)
        assert np.allclose(r.probabilities, (1 - w[:, None]) * raw.probabilities + w[:, None] * q)
        assert np.allclose(r.probabilities.sum(axis=1), 1.0)
    # a tiny scale leaves nothing the populations disagree on: the prior wherever se > 0
    assert np.allclose(posterior.marginals(ts, widen=1e-12).probabilities[se > 0], q)
    with pytest.raises(ValueError, match="widen"):
        posterior.marginals(ts, widen=0.0)
    one = infer_configurations(EVIDENCE, seed=3, n_particles=200, n_groups=1)
    with pytest.raises(ValueError, match="n_groups"):
        one.marginals(ts, widen=0.1)


def test_unsettled_rows_are_the_ones_the_populations_disagree_on_and_warned_about():
    """``info["unsettled"]`` is the rows whose largest Monte Carlo error is above the threshold,
    and the warning comes exactly when they are more than the threshold share; a few particles
    per population leave most rows unsettled, many particles none."""
    import warnings

    ts = _all_triplets(4)
    for n, seed in ((40, 5), (4000, 6)):
        post = infer_configurations(EVIDENCE, seed=seed, n_particles=n, n_groups=4)
        with warnings.catch_warnings(record=True) as got:
            warnings.simplefilter("always")
            r = post.marginals(ts)
        se = np.asarray(r.info["mc_error"]).max(axis=1)
        assert np.array_equal(r.info["unsettled"], se > UNSETTLED_ERROR)
        warned = [w for w in got if issubclass(w.category, NotSettledWarning)]
        assert len(warned) == int(np.mean(se > UNSETTLED_ERROR) > UNSETTLED_SHARE)
        if n == 40:
            assert warned and "n_particles" in str(warned[0].message)
        else:
            assert not warned
    with pytest.warns(NotSettledWarning, match="mixed toward the prior"):
        infer_configurations(EVIDENCE, seed=5, n_particles=40).marginals(ts, widen=0.05)


def test_labelled_result_for_every_triplet(posterior):
    res = posterior.marginals()
    assert list(res.triplets) == _all_triplets(4)
    assert res.partition == "edc" and res.method == "config-state"
    assert res.info["seen"].sum() == 2
    assert res.info["seen"][list(res.triplets).index((1, 2, 3))]
    assert np.allclose(res.probabilities.sum(axis=1), 1.0)
    assert np.all(res.probabilities > 0)
    for k in ("n_stages", "ess", "acceptance_landmark", "acceptance_similarity", "mc_error",
              "log_evidence"):
        assert k in res.info
    assert res.info["n_stages"] >= 1
    assert isinstance(res.info["configurations"], ConfigurationPosterior)
    X = posterior.positions
    assert X.shape == (2000, 4, 2) and np.isclose(posterior.weights.sum(), 1.0)
    box = np.array([posterior.prior.width, posterior.prior.height])
    assert np.all((X >= 0) & (X <= box))
    # the samples answer other questions: the states of any triplet in every configuration
    assert posterior.states([(3, 2, 1)]).shape == (2000, 1)


def test_graph_input_and_its_triplets():
    g = QualitativeFactorGraph("edc")
    g.add_triplet((0, 1, 2), EVIDENCE[(0, 1, 2)])
    g.add_triplet((1, 2, 3), EVIDENCE[(1, 2, 3)])
    g.add_triplet((0, 1, 3))
    res = configuration_marginals(g, seed=2, n_particles=400)
    assert res.triplets == ((0, 1, 2), (1, 2, 3), (0, 1, 3))
    assert res.info["seen"].tolist() == [True, True, False]


def test_bad_input():
    post = infer_configurations(EVIDENCE, seed=0, n_particles=200)
    with pytest.raises(KeyError, match="landmark 7"):
        post.marginals([(0, 1, 7)])
    with pytest.raises(ValueError, match="triplet"):
        post.marginals([(0, 0, 1)])
    with pytest.raises(ValueError, match=r"\(1, 2, 3\).*20 state"):
        infer_configurations({(1, 2, 3): np.full(6, 1 / 6)})
    with pytest.raises(ValueError, match="prior"):
        infer_configurations(EVIDENCE, prior="uniform")

    class Est:  # a TripletEstimate-like answer made under another prior
        landmark, partition, prior = _vec(1), "edc", "uniform"

    with pytest.raises(ValueError, match="prior 'uniform'"):
        infer_configurations({(0, 1, 2): Est()})
    with pytest.raises(ValueError, match="n_particles"):
        infer_configurations(EVIDENCE, n_particles=1001, n_groups=4)
    with pytest.raises(ValueError, match="method"):
        infer_configurations(EVIDENCE, method="exact")
    with pytest.raises(ValueError, match="PositionSummary"):
        infer_configurations(EVIDENCE, method="config-metric")
    with pytest.raises(ValueError, match="options"):
        infer_configurations(EVIDENCE, particles=10)
    lr = summarize_position((np.array([[0.5, 0.5]]), np.ones(1)), partition="lr")
    with pytest.raises(ValueError, match="partition 'lr'"):
        infer_configurations({(0, 1, 2): lr}, method="config-metric")


# ----------------------------------------------------------------------------- metric evidence
def test_position_summary_is_a_likelihood_ratio_and_serialisable():
    rng = np.random.default_rng(0)
    pr = WorldBoxPrior()
    # a "posterior" that is the prior itself: the ratio must be about 1 where the prior is
    c = pr.sample(rng, 0, 20_000)[:, 0]
    s = summarize_position((c, np.full(len(c), 1 / len(c))), n_components=256, seed=1)
    assert not s.low_ess
    probe = pr.sample(rng, 0, 4000)[:, 0]
    assert 0.8 < np.mean(s.ratio(probe)) < 1.2
    back = PositionSummary.from_dict(json.loads(json.dumps(s.to_dict())))
    assert np.allclose(back.ratio(probe[:50]), s.ratio(probe[:50]))
    few = summarize_position((c[:5], np.full(5, 0.2)))
    assert few.low_ess
    with pytest.raises(ValueError, match="weights"):
        summarize_position((c[:5], np.ones(4)))


def test_metric_evidence_places_c_where_the_solver_did():
    rng = np.random.default_rng(2)
    where = np.array([0.6, 2.0])
    xy = where + 0.05 * rng.standard_normal((2000, 2))
    s = summarize_position((xy, np.full(2000, 1 / 2000)), seed=0)
    post = infer_configurations({(0, 1, 2): s}, method="config-metric", seed=4, n_particles=2000,
                                floor=1e-3)
    X = post.positions
    c = to_frame(X[:, 2], X[:, 0], X[:, 1])
    assert np.linalg.norm(np.median(c, axis=0) - where) < 0.05
    # the state-only likelihood of the same evidence knows only the state
    st = infer_configurations({(0, 1, 2): s.states}, seed=4, n_particles=2000, floor=1e-3)
    cs = to_frame(st.positions[:, 2], st.positions[:, 0], st.positions[:, 1])
    assert np.mean(np.linalg.norm(c - where, axis=1)) < np.mean(np.linalg.norm(cs - where, axis=1))


def test_log_likelihoods_are_the_floored_tempered_ratio_at_any_configuration():
    """log_likelihoods(X) against the formula computed here from the partition's own lookup:
    log((1 - eps) P'_t(s_t) / q(s_t) + eps), P' the tempered estimate; unchanged by a similarity
    transform of X; the default scores the particles."""
    from qfg.partitions import get

    post = infer_configurations(EVIDENCE, n_particles=200, n_sweeps=1, seed=3)
    rng = np.random.default_rng(7)
    X = rng.uniform(0, 1, size=(50, 4, 2))
    got = post.log_likelihoods(X)
    q = prior_states(WorldBoxPrior(), "edc")
    part = get("edc")
    for r, (t, v) in enumerate(post.evidence.items()):
        s = part.state_of(to_frame(X[:, t[2]], X[:, t[0]], X[:, t[1]]))
        want = np.log((1 - FLOOR) * (temper(v, q, TEMPER["config-state"]) / q)[s] + FLOOR)
        np.testing.assert_allclose(got[r], want, rtol=1e-12)
    th = 0.7
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    np.testing.assert_allclose(post.log_likelihoods(2.5 * X @ R.T + [3.0, -1.0]), got,
                               atol=1e-9)
    np.testing.assert_array_equal(post.log_likelihoods(), post.log_likelihoods(post.positions))
    assert post.log_likelihoods(X[0]).shape == (2, 1)
    with pytest.raises(ValueError, match="positions: expected shape"):
        post.log_likelihoods(X[:, :3])
