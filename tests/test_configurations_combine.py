"""Several passes of one triplet as one metric summary (:func:`qfg.configurations.
combine_positions`), checked against a brute-force grid of the same product of likelihood ratios,
and against properties the product must have."""

from __future__ import annotations

import numpy as np
import pytest

from qfg.configurations import combine_positions, summarize_position
from qfg.priors import WorldBoxPrior


def _pass(centre, sd, seed, n=3000):
    rng = np.random.default_rng(seed)
    xy = np.asarray(centre) + sd * rng.standard_normal((n, 2))
    return summarize_position((xy, np.full(n, 1.0 / n)), seed=seed)


def _grid_mean(summaries, tau=1.0, step=0.004):
    """The mean of prior(c) prod_h r_h(c)^tau on a fine grid (brute force)."""
    g = np.arange(-0.6, 2.0, step)
    xx, yy = np.meshgrid(g, g + 1.0)
    pts = np.stack([xx.ravel(), yy.ravel()], axis=1)
    logp = WorldBoxPrior().log_density(pts[:, None, :])
    for s in summaries:
        with np.errstate(divide="ignore"):
            logp = logp + tau * np.log(s.ratio(pts))
    w = np.exp(logp - logp[np.isfinite(logp)].max())
    w[~np.isfinite(w)] = 0.0
    w /= w.sum()
    mu = w @ pts
    return mu, np.sqrt(w @ np.sum((pts - mu) ** 2, axis=1))


@pytest.mark.parametrize("tau", [1.0, 0.5])
def test_two_agreeing_passes_give_the_grid_product(tau):
    a = _pass([0.50, 1.90], 0.08, 1)
    b = _pass([0.62, 1.95], 0.08, 2)
    ab = combine_positions([a, b], temper=tau, n_points=8000, n_components=256, seed=3)
    mu, spread = _grid_mean([a, b], tau)
    assert not ab.low_ess
    assert np.linalg.norm(ab.centres.mean(axis=0) - mu) < 0.2 * spread
    # its spread is the product's, not either pass's
    own = np.sqrt(np.mean(np.sum((ab.centres - ab.centres.mean(0)) ** 2, axis=1)))
    assert own == pytest.approx(spread, rel=0.25)


def test_tempering_one_pass_widens_it():
    a = _pass([0.4, 1.6], 0.05, 4)
    half = combine_positions([a], temper=0.5, n_points=8000, n_components=256, seed=5)
    assert combine_positions([a]) is a            # one pass, no tempering: itself
    sd = lambda s: np.sqrt(np.mean(np.sum((s.centres - s.centres.mean(0)) ** 2, axis=1)))  # noqa: E731
    _, grid_sd = _grid_mean([a], 0.5)
    assert sd(half) > 1.2 * sd(a)                 # r^0.5 is wider than r (about sqrt 2)
    assert sd(half) == pytest.approx(grid_sd, rel=0.25)


def test_passes_that_disagree_are_flagged():
    a = _pass([0.2, 1.5], 0.02, 6)
    b = _pass([1.2, 2.5], 0.02, 7)
    ab = combine_positions([a, b], seed=8)
    assert ab.low_ess                              # few draws carry the product, if any


def test_states_and_seeds():
    a, b = _pass([0.5, 1.9], 0.1, 9), _pass([0.55, 1.9], 0.1, 10)
    st = np.full(20, 0.05)
    one = combine_positions([a, b], states=st, seed=11)
    assert np.allclose(one.states, st)
    again = combine_positions([a, b], states=st, seed=11)
    assert np.array_equal(one.centres, again.centres)
    assert np.array_equal(combine_positions([a], states=st).centres, a.centres)


def test_bad_input():
    a = _pass([0.5, 1.9], 0.1, 12)
    lr = summarize_position((np.array([[0.5, 0.5], [0.6, 0.5]]), np.ones(2)), partition="lr")
    with pytest.raises(ValueError, match="PositionSummary"):
        combine_positions([])
    with pytest.raises(ValueError, match="partition 'lr'"):
        combine_positions([a, lr])
    with pytest.raises(ValueError, match="states"):
        combine_positions([a, a], states=np.ones(3))
    with pytest.raises(ValueError, match="temper"):
        combine_positions([a, a], temper=-1)
