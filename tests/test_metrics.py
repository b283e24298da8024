"""Metrics against hand-computed values and properties."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from qfg import metrics, partitions

U20 = np.full(20, 1 / 20)


def test_uniform_edc_values():
    assert metrics.dmse(U20, 0) == pytest.approx(np.sqrt(19 / 400 + (19 / 20) ** 2))
    assert round(float(metrics.dmse(U20, 7)), 3) == 0.975
    assert metrics.entropy(U20) == pytest.approx(np.log(20))
    assert metrics.information_score(U20) == pytest.approx(0.0, abs=1e-12)
    assert metrics.gt_rating(U20, 5) == 10.5  # ties split evenly: the mean rank (20 + 1) / 2
    assert metrics.likelihood_ratio(U20) == pytest.approx(1.0)
    assert metrics.gt_likelihood_ratio(U20, 3) == pytest.approx(1.0)


def test_hand_computed_small_example():
    p = np.array([0.5, 0.3, 0.2, 0.0])
    c = np.array([[0, 0], [3, 4], [0, 1], [10, 10]], dtype=float)
    g = 1
    assert metrics.dmse(p, g) == pytest.approx(np.sqrt(0.25 + 0.49 + 0.04))
    assert metrics.gt_rating(p, g) == 2
    assert metrics.gmd(p, g, c) == pytest.approx(0.5 * 5 + 0.2 * np.hypot(3, 3))
    assert metrics.gt_likelihood(p, g) == pytest.approx(0.3)
    assert metrics.gt_likelihood_ratio(p, g) == pytest.approx(0.6)
    H = -(0.5 * np.log(0.5) + 0.3 * np.log(0.3) + 0.2 * np.log(0.2))
    assert metrics.entropy(p) == pytest.approx(H)
    assert metrics.likelihood_ratio(p) == pytest.approx(0.6)
    assert metrics.information_score(p) == pytest.approx((np.log(4) - H) / np.log(4))


def test_one_hot_truth_is_perfect():
    p = np.eye(20)[4]
    cents = partitions.get("edc").centroids
    r = metrics.evaluate(p, 4, cents)
    assert r["dmse"] == 0 and r["gt_rating"] == 1 and r["gmd"] == 0
    assert r["log_score"] == 0 and r["brier"] == 0 and r["truth_under_1pct"] == 0
    assert r["entropy"] == 0 and r["information_score"] == 1 and r["likelihood_ratio"] == 0
    assert metrics.dmse(p, 5) == pytest.approx(np.sqrt(2))


def _simplex(m):
    return arrays(float, m, elements=st.floats(0, 1)).filter(lambda a: a.sum() > 1e-3).map(
        lambda a: a / a.sum())


@given(_simplex(20), st.integers(0, 19))
@settings(max_examples=200, deadline=None)
def test_metric_ranges(p, g):
    cents = partitions.get("edc").centroids
    r = metrics.evaluate(p, g, cents)
    assert 0 <= r["dmse"] <= np.sqrt(2) + 1e-9
    assert 1 <= r["gt_rating"] <= 20
    assert np.log(1e-4) <= r["log_score"] <= 0 and 0 <= r["brier"] <= 2
    assert r["gmd"] >= 0
    assert 0 <= r["information_score"] <= 1
    assert 0 <= r["entropy"] <= np.log(20) + 1e-9
    assert 0 <= r["likelihood_ratio"] <= 1
    assert 0 <= r["gt_likelihood_ratio"] <= 1 + 1e-12
    # rating 1 exactly when the truth is the unique most likely state
    unique_top = np.sum(p >= p[g] - 1e-12) == 1
    assert (r["gt_rating"] == 1) == (bool(unique_top) and r["gt_likelihood_ratio"] >= 1 - 1e-12)


def test_batched_equals_loop():
    rng = np.random.default_rng(0)
    P = rng.dirichlet(np.ones(20), size=(3, 4))
    G = rng.integers(0, 20, size=(3, 4))
    cents = partitions.get("edc").centroids
    batch = metrics.evaluate(P, G, cents)
    for i in range(3):
        for j in range(4):
            single = metrics.evaluate(P[i, j], G[i, j], cents)
            for k, v in single.items():
                assert batch[k][i, j] == pytest.approx(float(v))


def test_bad_input():
    with pytest.raises(ValueError, match="sum to 1"):
        metrics.dmse([0.5, 0.6], 0)
    with pytest.raises(ValueError, match="negative"):
        metrics.entropy([1.5, -0.5])
    with pytest.raises(ValueError, match="g: states"):
        metrics.dmse([0.5, 0.5], 2)
    with pytest.raises(ValueError, match="integer"):
        metrics.dmse([0.5, 0.5], 0.5)
    with pytest.raises(ValueError, match="non-finite"):
        metrics.entropy([np.nan, 1.0])
    with pytest.raises(ValueError, match="centroids"):
        metrics.gmd([0.5, 0.5], 0, np.zeros((3, 2)))


def _rating_by_permutations(p, g):
    """Mean rank of the truth over every order of the tied states (brute force)."""
    import itertools

    ranks = []
    vals = sorted(set(p.tolist()), reverse=True)
    groups = [[i for i in range(len(p)) if p[i] == v] for v in vals]
    for perm in itertools.product(*[list(itertools.permutations(gr)) for gr in groups]):
        order = [i for grp in perm for i in grp]
        ranks.append(order.index(g) + 1)
    return np.mean(ranks)


def test_gt_rating_ties_split_evenly_brute_force():
    rng = np.random.default_rng(0)
    for _ in range(30):
        counts = rng.integers(0, 4, size=5)
        counts[0] += 1
        p = counts / counts.sum()          # equal counts give bit-identical probabilities
        for g in range(5):
            bf = _rating_by_permutations(p, g)
            assert metrics.gt_rating(p, g) == pytest.approx(bf)
    # a zero-probability truth among zeros no longer rates well
    assert metrics.gt_rating([1.0, 0, 0, 0], 2) == pytest.approx(3.0)


def test_log_score_brier_truth_under_closed_forms():
    p = np.array([[0.7, 0.2, 0.1, 0.0], [0.25, 0.25, 0.25, 0.25]])
    g = np.array([3, 1])
    np.testing.assert_allclose(metrics.log_score(p, g), [np.log(1e-4), np.log(0.25)])
    np.testing.assert_allclose(metrics.log_score(p, g, clip=1e-2), [np.log(1e-2), np.log(0.25)])
    np.testing.assert_allclose(metrics.brier(p, g), [0.49 + 0.04 + 0.01 + 1.0, 3 / 16 + 0.75**2])
    np.testing.assert_allclose(metrics.brier(p, g), metrics.dmse(p, g) ** 2)
    assert metrics.truth_under(p, g).tolist() == [True, False]
    assert metrics.truth_under(p, g, 0.3).tolist() == [True, True]
    with pytest.raises(ValueError, match="clip"):
        metrics.log_score(p, g, clip=0)


def test_scores_are_proper():
    # the expected score under q is best at p = q (log and Brier are strictly proper)
    rng = np.random.default_rng(1)
    q = rng.dirichlet(np.ones(5))
    states = np.arange(5)

    def expected(f, p):
        return float(np.sum(q * f(np.tile(p, (5, 1)), states)))

    for _ in range(50):
        p = rng.dirichlet(np.ones(5))
        assert expected(metrics.log_score, p) <= expected(metrics.log_score, q) + 1e-12
        assert expected(metrics.brier, p) >= expected(metrics.brier, q) - 1e-12


def test_self_expected_scores_are_the_scores_averaged_over_truths_drawn_from_the_estimate():
    # the definition, by enumeration over the truth, and by simulation: a calibrated forecaster
    # (truths drawn from its own estimates) scores its self-expected mean, an over-confident one less
    rng = np.random.default_rng(3)
    P = rng.dirichlet(np.full(6, 0.3), size=40)
    P[0] = [0.995, 0.005, 0, 0, 0, 0]
    states = np.arange(6)
    for p in P:
        tiled = np.tile(p, (6, 1))
        assert metrics.expected_log_score(p) == pytest.approx(
            np.sum(p * metrics.log_score(tiled, states)), abs=1e-12)
        assert metrics.expected_log_score(p, clip=0.05) == pytest.approx(
            np.sum(p * metrics.log_score(tiled, states, clip=0.05)), abs=1e-12)
        assert metrics.expected_truth_under(p, 0.02) == pytest.approx(
            np.sum(p * metrics.truth_under(tiled, states, 0.02)), abs=1e-12)
    Q = rng.dirichlet(np.ones(6), size=20000)
    g = (Q.cumsum(1) < rng.random((20000, 1))).sum(1)
    se = metrics.log_score(Q, g).std() / np.sqrt(len(g))
    assert abs(metrics.log_score(Q, g).mean() - metrics.expected_log_score(Q).mean()) < 4 * se
    sharp = Q ** 3 / np.sum(Q ** 3, axis=1, keepdims=True)
    assert metrics.log_score(sharp, g).mean() < metrics.expected_log_score(sharp).mean() - 10 * se
    assert metrics.expected_truth_under([0.995, 0.005]) == pytest.approx(0.005)
    with pytest.raises(ValueError, match="clip"):
        metrics.expected_log_score(P, clip=0)


def test_reliability_against_brute_force():
    rng = np.random.default_rng(2)
    P = rng.dirichlet(np.full(4, 0.5), size=300)
    g = rng.integers(0, 4, size=300)
    r = metrics.reliability(P, g, bins=5)
    top, conf = P.argmax(1), P.max(1)
    for b in range(5):
        lo, hi = b / 5, (b + 1) / 5
        inb = (conf >= lo) & ((conf < hi) if b < 4 else (conf <= hi))
        assert r.top_count[b] == inb.sum()
        if inb.any():
            assert r.top_confidence[b] == pytest.approx(conf[inb].mean())
            assert r.top_accuracy[b] == pytest.approx(np.mean(top[inb] == g[inb]))
        pairs = (P >= lo) & ((P < hi) if b < 4 else (P <= hi))
        assert r.all_count[b] == pairs.sum()
        if pairs.any():
            hit = np.arange(4)[None, :] == g[:, None]
            assert r.all_confidence[b] == pytest.approx(P[pairs].mean())
            assert r.all_frequency[b] == pytest.approx(hit[pairs].mean())
    assert r.all_count.sum() == P.size and r.top_count.sum() == 300
    ece = sum(r.top_count[b] * abs(r.top_accuracy[b] - r.top_confidence[b])
              for b in range(5) if r.top_count[b]) / 300
    assert metrics.expected_calibration_error(P, g, bins=5) == pytest.approx(ece)


def test_calibrated_forecaster_has_small_ece():
    # truths drawn from the forecasts themselves: ECE shrinks like 1/sqrt(n); a sharpened copy
    # of the same forecasts is miscalibrated
    rng = np.random.default_rng(3)
    P = rng.dirichlet(np.ones(6), size=20000)
    g = np.array([rng.choice(6, p=p) for p in P])
    assert metrics.expected_calibration_error(P, g) < 0.02
    assert metrics.expected_calibration_error(P, g, kind="all") < 0.01
    S = P**3 / np.sum(P**3, axis=1, keepdims=True)
    assert metrics.expected_calibration_error(S, g) > 0.05
    with pytest.raises(ValueError, match="kind"):
        metrics.expected_calibration_error(P, g, kind="nope")


def test_clustered_se_takes_any_labels_and_refuses_a_length_mismatch():
    clustered_se = metrics.clustered_se
    rng = np.random.default_rng(5)
    v = rng.standard_normal(60)
    ints = np.repeat(np.arange(20), 3)
    names = [f"set-{i}" for i in ints]
    assert clustered_se(v, names) == pytest.approx(clustered_se(v, ints))
    # one cluster's members moved together: the sum of residuals per cluster, by hand
    res = np.array([np.sum(v[ints == c] - v.mean()) for c in range(20)])
    assert clustered_se(v, ints) == pytest.approx(np.sqrt(np.sum(res ** 2)) / v.size)
    assert clustered_se([1.0], [0]) == 0.0
    with pytest.raises(ValueError, match="60 values but 59 cluster labels"):
        clustered_se(v, ints[:-1])
