"""The reference's conditional sampler (qfg.solvers.reference.conditional and .trajectory): its
pieces against geometry and dense linear algebra, and its answers against the staged sampler (an
independent importance sampler of the same exact posterior) at 3-4 views, within the Monte Carlo
errors both report."""

import numpy as np
import pytest

from qfg import partitions
from qfg.geometry import bearing, locus_point
from qfg.priors import CallablePrior
from qfg.simulation import random_triplet_history
from qfg.solvers.common.prior import resolve_prior
from qfg.solvers.reference import conditional as R
from qfg.solvers.reference import trajectory as RT
from qfg.solvers.reference.staged import REFERENCE_DEFAULTS, Layout, solve_reference

PRIOR = resolve_prior("world")


def _poses(rng, n):
    X = rng.uniform(-2, 2, (n, 2))
    return X, rng.uniform(-np.pi, np.pi, n)


def test_resection_recovers_noise_free_poses():
    rng = np.random.default_rng(0)
    C = rng.uniform(-2, 2, (200, 2))
    X, al = _poses(rng, 200)
    P = np.concatenate([X, al[:, None]], 1)
    phi = np.stack([bearing(P, np.zeros(2)), bearing(P, np.array([0.0, 1.0])),
                    bearing(P, C)], -1)
    for i in range(0, 200, 20):
        L = Layout(phi[i:i + 1], None, 0.01, 0.01)
        Xr, ar = RT.resect(L, C[i:i + 1])
        assert np.allclose(Xr[0, 0], X[i], atol=1e-8)
        assert np.isclose(np.cos(ar[0, 0] - al[i]), 1.0)


def test_arc_coordinates_invert_and_their_jacobian_matches_finite_differences():
    rng = np.random.default_rng(1)
    X = rng.uniform(-3, 3, (50, 2))
    a, g = RT.arc_coords(X)
    Y, dXda, dXdg, logdet, valid = RT.arc_position(a, g)
    assert valid.all() and np.allclose(Y, X) and np.allclose(locus_point(g, a), X)
    e = 1e-6
    fa = (RT.arc_position(a + e, g)[0] - RT.arc_position(a - e, g)[0]) / (2 * e)
    fg = (RT.arc_position(a, g + e)[0] - RT.arc_position(a, g - e)[0]) / (2 * e)
    assert np.allclose(fa, dXda, atol=1e-6) and np.allclose(fg, dXdg, atol=1e-6)
    det = np.abs(fa[:, 0] * fg[:, 1] - fa[:, 1] * fg[:, 0])
    assert np.allclose(np.log(det), logdet, atol=1e-6)


def test_block_cholesky_solves_and_samples_the_dense_system():
    rng = np.random.default_rng(2)
    N, n = 3, 5
    A = rng.standard_normal((N, 3 * n, 3 * n))
    band = np.abs(np.arange(3 * n)[:, None] // 3 - np.arange(3 * n)[None, :] // 3) <= 1
    P = np.einsum("nij,nkj->nik", A * band, A * band) + 3 * np.eye(3 * n)
    P = P * band
    P = P + 3 * n * np.eye(3 * n)                         # diagonally dominant: positive definite
    D = np.stack([P[:, 3 * j:3 * j + 3, 3 * j:3 * j + 3] for j in range(n)], 1)
    O = np.stack([P[:, 3 * j + 3:3 * j + 6, 3 * j:3 * j + 3] for j in range(n - 1)], 1)
    Ld, Lo = RT.block_cholesky(D, O)
    b = rng.standard_normal((N, n, 3))
    x = RT.block_solve(Ld, Lo, b)
    assert np.allclose(np.einsum("nij,nj->ni", P, x.reshape(N, -1)), b.reshape(N, -1))
    # log det P = 2 sum log diag(Ld); back substitution of z ~ N(0, I) has covariance P^-1
    assert np.allclose(2 * np.sum(np.log(np.diagonal(Ld, axis1=-2, axis2=-1)), axis=(1, 2)),
                       np.linalg.slogdet(P)[1])
    z = rng.standard_normal((N, n, 3))
    y = RT.back_substitute(Ld, Lo, z)
    Lfull = np.linalg.cholesky(P)
    assert np.allclose(y.reshape(N, -1), np.linalg.solve(np.swapaxes(Lfull, 1, 2),
                                                         z.reshape(N, -1)[..., None])[..., 0])


def test_particle_filter_log_z_agrees_with_the_laplace_integral():
    # given the true C of a 4-view history the trajectory's integral is nearly Gaussian: the
    # filter's unbiased estimate and the Laplace approximation agree to a few tenths of a nat
    h = random_triplet_history(np.random.default_rng(700000), 4, np.deg2rad(2), np.deg2rad(5))
    L = Layout(h.bearings, h.headings, h.sigma_bearing, h.sigma_heading)
    C = np.repeat(h.truth.C_ab[None], 400, 0)
    logz, X, al = R.particle_trajectories(L, C, np.random.default_rng(0), K=8)
    lw = logz + PRIOR.log_density(np.concatenate([C[:, None], X], 1))
    est = float(np.log(np.mean(np.exp(lw - lw.max()))) + lw.max())
    lap = float(RT.laplace_marginal(L, PRIOR, C[:1])[0])
    assert abs(est - lap) < 0.3, (est, lap)
    # the drawn trajectories sit near the truth's poses
    assert np.median(np.linalg.norm(X - h.truth.poses_ab[None, :, :2], axis=-1)) < 0.2


@pytest.mark.parametrize("i,n", [(0, 3), (2, 3), (1, 4)])
def test_agrees_with_the_staged_sampler(i, n):
    h = random_triplet_history(np.random.default_rng(700000 + i), n, np.deg2rad(2),
                               np.deg2rad(5))
    args = (h.bearings, h.headings, h.sigma_bearing, h.sigma_heading)
    a = solve_reference(*args, seed=1, sampler="conditional")
    b = solve_reference(*args, seed=1, sampler="staged")
    sd = np.sqrt(a["mc_error"] ** 2 + b["mc_error"] ** 2)
    assert np.all(np.abs(a["landmark"] - b["landmark"]) <= 4 * sd + 5e-3), (
        a["landmark"], b["landmark"], sd)
    assert 0.5 * np.abs(a["landmark"] - b["landmark"]).sum() < 0.05
    # the same evidence p(measurements): both are unbiased estimates of it
    assert abs(a["log_evidence"] - b["log_evidence"]) < 0.5
    assert a["ess"] >= 200 and np.isfinite(a["pareto_k"])


def test_starved_sampler_is_flagged_below_50():
    h = random_triplet_history(np.random.default_rng(700003), 8, np.deg2rad(2), np.deg2rad(5))
    out = solve_reference(h.bearings, h.headings, h.sigma_bearing, h.sigma_heading, seed=0,
                          sampler="conditional", rb_samples=16, particles=1, final_rounds=1,
                          tempering_rounds=1)
    assert out["ess"] < 50 and out["degenerate"] and "effective sample size" in out["reason"]
    assert np.isclose(out["landmark"].sum(), 1.0) and np.all(np.isfinite(out["landmark"]))


def test_bad_sampler_name():
    with pytest.raises(ValueError, match="sampler"):
        solve_reference([[0.1, 0.5, 0.3]], None, 0.01, 0.0, sampler="nope")


def test_conditional_sampler_one_view():
    # one view, no motion: answers sum to one, C spread along its line of sight
    out = solve_reference([[0.3, 1.2, 0.8]], None, np.deg2rad(2), 0.0, seed=0,
                          sampler="conditional", partition=partitions.get("edc"))
    assert np.isclose(out["landmark"].sum(), 1.0) and out["landmark"].max() < 0.99


@pytest.mark.parametrize("kind", ["world", "callable"])
def test_prior_inside_the_filter_estimates_the_same_integral(kind):
    # with the prior in the filter's targets (the world box's on every subset of the points, or,
    # for a user's prior, at the last step only) the filter's Z estimates the integral of the
    # whole target given C; the filter without it, weighted by the prior of one drawn
    # trajectory, is another unbiased estimator of the same integral
    h = random_triplet_history(np.random.default_rng(700203), 6, np.deg2rad(2), np.deg2rad(5))
    L = Layout(h.bearings, h.headings, h.sigma_bearing, h.sigma_heading)
    C = np.repeat(h.truth.C_ab[None], 500, 0)
    prior = PRIOR if kind == "world" else CallablePrior(PRIOR.log_density)
    assert (R.intermediate_prior(prior) is None) == (kind == "callable")
    lz, X, _ = R.particle_trajectories(L, C, np.random.default_rng(0), K=16)
    old = lz + PRIOR.log_density(np.concatenate([C[:, None], X], 1))
    new, _, _ = R.particle_trajectories(L, C, np.random.default_rng(1), K=16, prior=prior)

    def log_mean(lw):
        return float(np.log(np.mean(np.exp(lw - lw.max()))) + lw.max())

    assert abs(log_mean(new) - log_mean(old)) < 0.15, (log_mean(new), log_mean(old))


def test_c_proposal_matches_the_laplace_marginal_it_is_tempered_to():
    # C's proposal ends fitted to the Laplace marginal (its tempering's last target): a fresh
    # sample from it, weighted by that marginal, keeps a good share of effective draws. On this
    # history most of the product prior's draws of C have marginal 0 (no configuration in the
    # world box admits them); counted against all draws they once held the temperature at 0
    # for every round (ESS 5 of 1000)
    h = random_triplet_history(np.random.default_rng(700007), 8, np.deg2rad(2), np.deg2rad(5))
    L = Layout(h.bearings, h.headings, h.sigma_bearing, h.sigma_heading)
    mix, _ = R.adapt_c_proposal(L, PRIOR, np.random.default_rng(0), dict(REFERENCE_DEFAULTS))
    C = mix.draw(np.random.default_rng(1), 1000)
    lw = RT.laplace_marginal(L, PRIOR, C) - mix.log_density(C)
    w = np.exp(lw[np.isfinite(lw)] - np.max(lw[np.isfinite(lw)]))
    assert w.sum() ** 2 / np.sum(w * w) > 300


def test_the_estimate_carries_the_evidence_and_it_prefers_the_true_prior():
    # E over data from prior A of log Z_A - log Z_B is KL(p_A(data) || p_B(data)) >= 0: the
    # simulator's world box against a wide uniform window, on histories the box generated
    from qfg.priors import WindowPrior, WorldBoxPrior
    from qfg.solvers import solve_triplet

    diffs = []
    for i in range(12):
        h = random_triplet_history(np.random.default_rng(710000 + i), 3, np.deg2rad(2),
                                   np.deg2rad(5))
        z = [solve_triplet(h, method="reference", seed=i, prior=p, n_samples=2000).log_evidence
             for p in (WorldBoxPrior(), WindowPrior((-12.0, 12.0, -11.5, 12.5)))]
        assert np.all(np.isfinite(z))
        diffs.append(z[0] - z[1])
    assert np.mean(diffs) > 5.0 and np.mean(np.array(diffs) > 0) >= 0.9, diffs
    est = solve_triplet(h, method="full", seed=0)
    assert np.isnan(est.log_evidence)
