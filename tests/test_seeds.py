"""One seed rule across the API (docs/conventions.md): an int >= 0, a SeedSequence, a Generator or
None; same int, same result; a Generator continues its stream; bad seeds are a ValueError naming
``seed``."""

import numpy as np
import pytest

from qfg import priors, simulation
from qfg._validate import as_rng, as_seed_sequence
from qfg.composition.build import random_configurations, sample_state
from qfg.solvers import solve_triplet

CALLS = {
    "sample_positions": lambda s: simulation.sample_positions(s, 5),
    "random_triplet_history": lambda s: simulation.random_triplet_history(s, 3, 0.01, 0.02).bearings,
    "random_scenario": lambda s: simulation.random_scenario(s, 5, 4).poses,
    "prior.sample": lambda s: priors.get("world").sample(s, 2, 3),
    "WindowPrior.sample": lambda s: priors.WindowPrior((-1, 1, -1, 2)).sample(s, 2, 3),
    "sample_measurements": lambda s: priors.sample_measurements("world", s, 3, 0.01, 0.02, 4)[0],
    "sample_state": lambda s: sample_state("lr", 1, 8, s),
    "random_configurations": lambda s: random_configurations("lr", 100, s),
    "solve_triplet": lambda s: solve_triplet(
        simulation.random_triplet_history(0, 3, 0.02, 0.05), method="fast-paper",
        seed=s).landmark,
}


@pytest.mark.parametrize("name", sorted(CALLS))
def test_every_seed_kind_is_accepted_and_deterministic(name):
    f = CALLS[name]
    a, b = f(7), f(7)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(f(np.random.SeedSequence(7)), f(np.random.SeedSequence(7)))
    np.testing.assert_array_equal(f(np.random.default_rng(7)), f(np.random.default_rng(7)))
    assert np.shape(f(None)) == np.shape(a)


@pytest.mark.parametrize("name", sorted(CALLS))
@pytest.mark.parametrize("bad", [-1, 1.5, True, "3", [1, 2]])
def test_bad_seeds_name_the_argument(name, bad):
    with pytest.raises(ValueError, match="seed"):
        CALLS[name](bad)


def test_a_generator_continues_its_stream():
    g = np.random.default_rng(5)
    first = simulation.sample_positions(g, 4)
    second = simulation.sample_positions(g, 4)
    assert not np.array_equal(first, second)
    np.testing.assert_array_equal(first, simulation.sample_positions(5, 4))


def test_the_rule_is_implemented_once():
    assert as_rng(3).random() == np.random.default_rng(3).random()
    assert as_seed_sequence(3).entropy == np.random.SeedSequence(3).entropy
    g = np.random.default_rng(1)
    assert as_rng(g) is g
    s = np.random.SeedSequence(9)
    assert as_seed_sequence(s) is s
