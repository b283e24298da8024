"""TrajectoryPrior: one robot's later cameras by scale-free steps, against closed forms and its
own sampler."""

import numpy as np
import pytest
from scipy import stats

from qfg.priors import TrajectoryPrior, TravelPrior, WindowPrior, WorldBoxPrior
from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplet


def test_a_step_integrates_to_one_over_the_plane():
    # the density of X_2 given (C, X_1) integrates to 1 (log-polar grid about X_1), so the
    # prior's marginal of (C, X_1) is the first prior's
    first = WindowPrior()
    p = TrajectoryPrior(first, steps=(1e-3, 10.0))
    head = np.array([[0.3, 0.4], [1.5, -0.5]])
    u = np.linspace(np.log(1e-3), np.log(10.0), 4001)
    th = np.linspace(-np.pi, np.pi, 65)[:-1]
    U, T = np.meshgrid(u, th, indexing="ij")
    b = np.exp(U)
    x2 = head[1] + np.stack([b * np.cos(T), b * np.sin(T)], axis=-1)
    q = np.concatenate([np.broadcast_to(head, U.shape + (2, 2)), x2[..., None, :]], axis=-2)
    dens = np.exp(p.log_density(q) - first.log_density(head))
    # dX = b^2 du dtheta on the log-polar grid
    total = np.trapezoid((dens * b * b).mean(axis=1) * 2 * np.pi, u)
    assert total == pytest.approx(1.0, abs=1e-3)


def test_its_sampler_draws_log_uniform_steps_after_the_first_prior():
    box = WorldBoxPrior(width=6.0, height=11.0)
    p = TrajectoryPrior(box, n_first=1, steps=(1e-2, 5.0))
    x = p.sample(0, 4, 4000)
    assert x.shape == (4000, 5, 2)
    b = np.hypot(*np.diff(x[:, 1:], axis=1).T).ravel()
    z = (np.log(b) - np.log(1e-2)) / (np.log(5.0) - np.log(1e-2))
    assert stats.kstest(z, "uniform").pvalue > 1e-3
    # C and the first camera as the box draws them: C's distance from A, two-sample KS
    ref = box.sample(1, 1, 4000)
    assert stats.ks_2samp(np.hypot(*x[:, 0].T), np.hypot(*ref[:, 0].T)).pvalue > 1e-3
    assert stats.ks_2samp(np.hypot(*x[:, 1].T), np.hypot(*ref[:, 1].T)).pvalue > 1e-3
    assert np.all(np.isfinite(p.log_density(x)))


def test_more_views_do_not_pull_the_path_longer():
    # a path of one shape and scale lambda, its first camera fixed: the density of lambda is
    # p(configuration) lambda^(2(k - 1) - 1) (the k - 1 later cameras' positions scale with it).
    # The box's points are uniform, so that density rises as lambda^(2k - 3): every view added
    # pulls the path longer. The trajectory's steps (density b^-2 each) cancel it: lambda is
    # log-uniform whatever k
    box = WorldBoxPrior(width=6.0, height=11.0)
    traj = TrajectoryPrior(box)
    shape = np.array([[0.0, 0.0], [0.1, 0.05], [0.2, 0.0], [0.3, 0.05], [0.4, 0.0]])
    C, X0 = np.array([0.5, 0.5]), np.array([2.0, 0.5])

    def slope(prior, k):
        lp = [prior.log_density(np.concatenate([C[None], X0 + lam * shape[:k]]))
              + (2 * (k - 1) - 1) * np.log(lam) for lam in (0.05, 0.1)]
        return (lp[1] - lp[0]) / np.log(2.0)

    assert slope(box, 5) - slope(box, 2) == pytest.approx(6.0, abs=0.5)
    assert slope(traj, 2) == pytest.approx(-1.0, abs=1e-9)
    assert slope(traj, 5) == pytest.approx(-1.0, abs=1e-9)


def test_the_solvers_take_it_with_a_travel_prior_first():
    h = random_triplet_history(np.random.default_rng(3), 4, np.deg2rad(2), np.deg2rad(5))
    first = TravelPrior(WorldBoxPrior(), 0.5)
    est = solve_triplet(h, method="full", seed=0, prior=TrajectoryPrior(first, n_first=2))
    assert np.isclose(est.landmark.sum(), 1.0) and np.all(np.isfinite(est.landmark))
    with pytest.raises(ValueError, match="sampler"):
        TrajectoryPrior(first, n_first=2).sample(0, 3, 2)


@pytest.mark.parametrize("kw, match", [
    (dict(first="world"), "first"), (dict(n_first=-1), "n_first"),
    (dict(steps=(0.0, 1.0)), "steps"), (dict(steps=(2.0, 1.0)), "steps"), (dict(steps=3), "steps")])
def test_bad_parameters_are_named(kw, match):
    args = {"first": WorldBoxPrior(), **kw}
    with pytest.raises(ValueError, match=match):
        TrajectoryPrior(args.pop("first"), **args)
