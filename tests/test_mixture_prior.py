"""MixturePrior: a weighted mixture of priors, against its components and Bayes' rule."""

import numpy as np
import pytest
from scipy import stats

from qfg.priors import MixturePrior, TrajectoryPrior, WindowPrior, WorldBoxPrior
from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplet


def test_density_is_the_weighted_sum():
    box, win = WorldBoxPrior(), WindowPrior()
    m = MixturePrior([box, win], weights=[3.0, 1.0])
    q = box.sample(0, 2, 50)
    want = np.log(0.75 * np.exp(box.log_density(q)) + 0.25 * np.exp(win.log_density(q)))
    np.testing.assert_allclose(m.log_density(q), want, rtol=1e-10)
    # a zero weight drops its component, even where that component has no density
    far = np.array([[[40.0, 40.0], [0.5, 0.5], [1.0, 1.0]]])
    assert np.isfinite(MixturePrior([box, win], [1.0, 0.0]).log_density(far)).all()


def test_sampler_draws_each_component_by_its_weight():
    box, win = WorldBoxPrior(), WindowPrior()
    x = MixturePrior([box, win], weights=[0.2, 0.8]).sample(1, 1, 6000)
    ref = np.concatenate([box.sample(2, 1, 1200), win.sample(3, 1, 4800)])
    assert stats.ks_2samp(np.hypot(*x[:, 0].T), np.hypot(*ref[:, 0].T)).pvalue > 1e-3
    assert stats.ks_2samp(np.hypot(*x[:, 1].T), np.hypot(*ref[:, 1].T)).pvalue > 1e-3


def test_its_posterior_is_the_evidence_weighted_average():
    # Bayes: p(s | y, mixture) = sum_i w_i Z_i p_i(s | y) / sum_i w_i Z_i, each Z_i and p_i from
    # the reference solver under one component; the mixture solved directly must agree
    box = WorldBoxPrior()
    path = TrajectoryPrior(box)
    h = random_triplet_history(np.random.default_rng(720001), 3, np.deg2rad(2), np.deg2rad(5))
    ests = [solve_triplet(h, method="reference", seed=s, prior=p, n_samples=8000)
            for s, p in ((1, box), (2, path))]
    z = np.array([e.log_evidence for e in ests])
    w = np.exp(z - z.max()) / np.exp(z - z.max()).sum()
    want = w[0] * ests[0].landmark + w[1] * ests[1].landmark
    got = solve_triplet(h, method="reference", seed=3, prior=MixturePrior([box, path]),
                        n_samples=8000)
    assert 0.5 * np.abs(got.landmark - want).sum() < 0.06
    assert got.log_evidence == pytest.approx(np.log(np.exp(z - z.max()).mean()) + z.max(),
                                             abs=0.3)


@pytest.mark.parametrize("kw, match", [
    (dict(components=[]), "components"), (dict(components=["world"]), "components"),
    (dict(weights=[1.0]), "weights"), (dict(weights=[-1.0, 2.0]), "weights"),
    (dict(weights=[0.0, 0.0]), "weights"), (dict(weights=[np.nan, 1.0]), "weights")])
def test_bad_parameters_are_named(kw, match):
    args = {"components": [WorldBoxPrior(), WindowPrior()], **kw}
    with pytest.raises(ValueError, match=match):
        MixturePrior(args.pop("components"), **args)
