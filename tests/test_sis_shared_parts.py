"""Computations the SIS engine's final weights share across the C draws of one trajectory give
the values of the unshared formulas: the joint prior with the cameras' part computed once per
trajectory (``Prior.log_density_shared``) against ``log_density`` of the whole configurations,
and the model check with the cameras' residuals computed once (``per_pose``) against the check
of the repeated poses."""

import numpy as np
import pytest

from qfg.priors import CallablePrior, ProductPrior, WindowPrior, WorldBoxPrior
from qfg.solvers import _model_check


def _configs(seed, N=300, K=4, n=3, spread=2.0):
    rng = np.random.default_rng(seed)
    X = WorldBoxPrior().sample(rng, n, N)[:, 1:]
    L = X[:, :1, None, :] + rng.normal(scale=spread, size=(N, K, 1, 2))
    return L, X


@pytest.mark.parametrize("prior", [WorldBoxPrior(n_rho=32), WorldBoxPrior(n_rho=4),
                                   WorldBoxPrior(width=20.0, height=1.0, d_min=0.5, n_rho=16),
                                   WorldBoxPrior(d_min=0.0, n_rho=8), WindowPrior(),
                                   ProductPrior(),
                                   CallablePrior(lambda p: -np.sum((p[..., 0, :] - p[..., 1, :])
                                                                   ** 2, axis=-1))])
def test_joint_prior_shared_equals_whole_configurations(prior):
    L, X = _configs(1)
    # coinciding points (density 0 where d_min > 0), far points, points on the line AB
    L[:5, 0, 0] = X[:5, 1]
    X[5:10] *= 40.0
    L[10:15, :, 0] = [0.0, 0.5]
    whole = np.concatenate([L, np.broadcast_to(X[:, None], (X.shape[0], L.shape[1]) + X.shape[1:])],
                           axis=2)
    want = prior.log_density(whole)
    got = prior.log_density_shared(L, X)
    assert got.shape == want.shape
    # the same arithmetic on the same numbers: equal to the bit
    np.testing.assert_array_equal(got, want)


def test_joint_prior_shared_several_leading_points_and_huge_inputs():
    p = WorldBoxPrior(n_rho=16)
    rng = np.random.default_rng(2)
    P, S = rng.normal(size=(50, 3, 2, 2)) * 3, rng.normal(size=(50, 2, 2)) * 3
    S[:3] *= 1e120                                   # leading points farther out than the shared ones too
    whole = np.concatenate([P, np.broadcast_to(S[:, None], (50, 3, 2, 2))], axis=2)
    want, got = p.log_density(whole), p.log_density_shared(P, S)
    np.testing.assert_array_equal(got, want)
    with pytest.raises(ValueError, match="points"):
        p.log_density_shared(P[:, :, 0], S)


@pytest.mark.parametrize("tail", [None, (0.1, 5.0, 0.01)])
def test_model_check_per_pose_equals_repeated_poses(tail):
    from qfg.solvers._likelihood import as_tail

    rng = np.random.default_rng(3)
    n, J, r = 3, 40, 4
    P = np.concatenate([rng.normal(size=(n, J, 2)) * 2, rng.uniform(-3, 3, (n, J, 1))], axis=2)
    L = rng.normal(size=(J * r, 2)) * 2
    b = rng.uniform(-np.pi, np.pi, (n, 3)) * 0.3
    w = rng.random(J * r)
    w[::7] = 0.0
    w /= w.sum()
    t = as_tail(tail)
    want = _model_check.posterior_predictive_p(b, [0.3, -0.2], np.repeat(P, r, axis=1), L, w,
                                               0.5, 0.4, t)
    got = _model_check.posterior_predictive_p(b, [0.3, -0.2], P, L, w, 0.5, 0.4, t, per_pose=r)
    assert 0 < want < 1
    assert got == pytest.approx(want, abs=1e-12)
