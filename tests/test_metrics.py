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
    assert metrics.gt_rating(U20, 5) == 1  # ties favour the truth
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
    assert r["gmd"] >= 0
    assert 0 <= r["information_score"] <= 1
    assert 0 <= r["entropy"] <= np.log(20) + 1e-9
    assert 0 <= r["likelihood_ratio"] <= 1
    assert 0 <= r["gt_likelihood_ratio"] <= 1 + 1e-12
    assert (r["gt_rating"] == 1) == (r["gt_likelihood_ratio"] >= 1 - 1e-12)


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
