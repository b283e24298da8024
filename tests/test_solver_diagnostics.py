"""The Pareto k-hat diagnostic against tails of known shape, and on solver estimates."""

import numpy as np
import pytest

from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplet
from qfg.solvers.common.diagnostics import pareto_k


@pytest.mark.parametrize("xi", [0.1, 0.5, 0.9])
def test_pareto_k_recovers_a_known_tail_shape(xi):
    """Weights U^-xi (U uniform) have an exact Pareto tail of shape xi: the mean k-hat over 20
    samples of 4000 is within 0.08 of it (measured bias: +0.03, +0.015, -0.04)."""
    rng = np.random.default_rng(7)
    ks = [pareto_k(-xi * np.log(rng.random(4000))) for _ in range(20)]
    assert abs(np.mean(ks) - xi) < 0.08, np.mean(ks)


def test_pareto_k_light_tails_and_edge_cases():
    rng = np.random.default_rng(3)
    # log-normal weights with a small spread: a light tail
    assert pareto_k(0.3 * rng.standard_normal(4000)) < 0.3
    # proposal N(0, 1) for target N(0, 4): the weights have infinite variance (k > 1/2)
    x = rng.standard_normal(20000)
    assert pareto_k(x * x * (0.5 - 0.125)) > 0.6
    assert np.isnan(pareto_k(np.zeros(10)))                 # too few
    assert np.isnan(pareto_k(np.full(500, -np.inf)))         # no positive weight
    assert np.isnan(pareto_k(np.zeros(500)))                 # flat: no tail


def test_estimates_carry_pareto_k():
    h = random_triplet_history(np.random.default_rng(900001), 3, np.deg2rad(2), np.deg2rad(5))
    e = solve_triplet(h, method="full", seed=0)
    assert np.isfinite(e.pareto_k)
    assert np.isnan(solve_triplet(h, method="fast-paper").pareto_k)
