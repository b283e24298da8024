"""The reference solver against a brute-force integral, against itself (seeds), and calibrated on
data drawn from its own prior; degenerate inputs flagged."""

import numpy as np
import pytest

from qfg import partitions, priors
from qfg.geometry import (
    bearing,
    heading_on_locus,
    locus_circle,
    locus_point,
    motion_heading,
    ray_circle_intersection,
    wrap_angle,
)
from qfg.solvers.reference.staged import solve_reference

EDC = partitions.get("edc")
A, B = np.zeros(2), np.array([0.0, 1.0])


def _measure(theta):
    """Noise-free measurements h(theta) of two views: 6 bearings and the heading.
    theta (..., 8) = (X1, alpha1, X2, alpha2, C)."""
    P1, P2, C = theta[..., 0:3], theta[..., 3:6], theta[..., 6:8]
    return np.stack([bearing(P1, A), bearing(P1, B), bearing(P1, C), bearing(P2, A),
                     bearing(P2, B), bearing(P2, C), motion_heading(P1, P2[..., :2])], -1)


def _brute_force_two_views(phi, psi, prior, n_grid=20000):
    """State probabilities of C in the zero-noise limit, by the co-area formula: the posterior
    lives on the curve h(theta) = measurements, parametrized by the first camera's angle a at A,
    with density prior(theta) / sqrt(det(J J^T)) |dtheta/da| (J = dh/dtheta by central
    differences): independent of the solver's Jacobians."""
    g1 = wrap_angle(phi[0, 1] - phi[0, 0])
    a = (np.arange(n_grid) + 0.5) / n_grid * (np.pi - abs(g1))
    circ = locus_circle(phi[1, 0], phi[1, 1])
    out = np.zeros(EDC.n_states)
    for root in (0, 1):
        def theta_of(a, root=root):
            X1 = locus_point(g1, a)
            al1 = heading_on_locus(X1, phi[0, 0])
            pts, ok = ray_circle_intersection(X1, al1 + psi[0], circ.center, circ.radius,
                                              circ.side)
            X2, ok = pts[:, root], ok[:, root]
            al2 = heading_on_locus(X2, phi[1, 0])
            b1, b2 = al1 + phi[0, 2], al2 + phi[1, 2]
            u1 = np.stack([np.cos(b1), np.sin(b1)], -1)
            u2 = np.stack([np.cos(b2), np.sin(b2)], -1)
            cr = u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0]
            w = X2 - X1
            t1 = (w[:, 0] * u2[:, 1] - w[:, 1] * u2[:, 0]) / cr
            t2 = (w[:, 0] * u1[:, 1] - w[:, 1] * u1[:, 0]) / cr
            ok &= (t1 > 0) & (t2 > 0)                 # C in front of both cameras
            C = X1 + t1[:, None] * u1
            return np.concatenate([X1, al1[:, None], X2, al2[:, None], C], -1), ok

        th, ok = theta_of(a)
        e = 1e-7
        tp, okp = theta_of(a + e)
        tm, okm = theta_of(a - e)
        ok &= okp & okm
        dth = (tp - tm) / (2 * e)
        dth[:, [2, 5]] = wrap_angle(tp[:, [2, 5]] - tm[:, [2, 5]]) / (2 * e)
        J = np.zeros((n_grid, 7, 8))
        for k in range(8):
            d = np.zeros(8)
            d[k] = e
            J[:, :, k] = wrap_angle(_measure(th + d) - _measure(th - d)) / (2 * e)
        G = np.einsum("nik,njk->nij", J, J)
        pts = np.stack([th[:, 6:8], th[:, 0:2], th[:, 3:5]], 1)
        dens = np.exp(prior.log_density(pts[ok])) / np.sqrt(np.linalg.det(G[ok])) * \
            np.linalg.norm(dth[ok], axis=-1)
        out += np.bincount(EDC.state_of(th[ok, 6:8]), weights=dens, minlength=EDC.n_states)
    return out / out.sum()


@pytest.mark.parametrize("seed", [0, 4])
def test_matches_brute_force_integral_two_views(seed):
    # seeds whose posterior spreads over several states (0: six states, 4: two)
    prior = priors.get("world")
    phi, psi, conf, _ = priors.sample_measurements(prior, np.random.default_rng(seed), 2, 0.0,
                                                   0.0, 1)
    bf = _brute_force_two_views(phi[0], psi[0], prior)
    assert np.sum(bf > 0.01) >= 2
    out = solve_reference(phi[0], psi[0], 1e-5, 1e-5, seed=np.random.default_rng(1),
                          bearing_floor=1e-6, heading_floor=1e-6)
    tol = 4 * out["mc_error"] + 0.005          # MC error + the grid's error
    assert np.all(np.abs(out["landmark"] - bf) <= tol), (out["landmark"], bf, out["mc_error"])
    assert out["ess"] > 1000 and not out["degenerate"]


def test_two_seeds_agree_within_reported_error():
    phi, psi, _, _ = priors.sample_measurements("world", np.random.default_rng(21), 3,
                                                np.deg2rad(2), np.deg2rad(5), 1)
    a = solve_reference(phi[0], psi[0], np.deg2rad(2), np.deg2rad(5), seed=1, n_samples=6000)
    b = solve_reference(phi[0], psi[0], np.deg2rad(2), np.deg2rad(5), seed=2, n_samples=6000)
    sd = np.sqrt(a["mc_error"] ** 2 + b["mc_error"] ** 2)
    assert np.all(np.abs(a["landmark"] - b["landmark"]) <= 4.5 * sd + 2e-3)
    assert np.all(np.abs(a["cameras"] - b["cameras"]) <= 4.5 * np.sqrt(
        a["cameras_mc_error"] ** 2 + b["cameras_mc_error"] ** 2) + 2e-3)
    c = solve_reference(phi[0], psi[0], np.deg2rad(2), np.deg2rad(5), seed=1, n_samples=6000)
    np.testing.assert_array_equal(a["landmark"], c["landmark"])      # same seed, same answer


def test_calibrated_on_data_from_its_own_prior():
    # 60 triplets, 3 views, 2/5 deg, drawn from the world prior with the solver's noise model.
    # For a calibrated posterior, sum(1[top = truth] - p_top) has mean 0 and variance
    # sum p_top (1 - p_top); likewise the truth's mass in each probability bin. |z| < 3.5.
    n, sb, sh = 60, np.deg2rad(2), np.deg2rad(5)
    phi, psi, conf, _ = priors.sample_measurements("world", np.random.default_rng(5), 3, sb, sh, n)
    truth = EDC.state_of(conf[:, 0])
    P = np.array([solve_reference(phi[i], psi[i], sb, sh, seed=i, n_samples=3000)["landmark"]
                  for i in range(n)])
    top, pt = P.argmax(1), P.max(1)
    z = np.sum((top == truth) - pt) / np.sqrt(np.sum(pt * (1 - pt)))
    assert abs(z) < 3.5, z
    onehot = np.arange(20)[None, :] == truth[:, None]
    for lo, hi in ((0.0, 0.1), (0.1, 0.9), (0.9, 1.01)):
        inb = (P >= lo) & (P < hi)
        pb = np.sum(P * inb, 1)
        var = np.sum(pb * (1 - pb))
        if var > 0.5:
            zb = np.sum(np.sum(onehot & inb, 1) - pb) / np.sqrt(var)
            assert abs(zb) < 3.5, (lo, hi, zb)
    # and it is informative: far better than the uniform answer's log score log(1/20)
    assert np.mean(np.log(np.maximum(P[np.arange(n), truth], 1e-4))) > np.log(1 / 20) + 1.5


def test_coinciding_lines_of_sight_flagged_and_spread():
    # issue 10's example: the fast solver put probability 1 on state 13; the truth is state 3
    b = [[-2.3433983565, 0.842300949939, 0.267824910126],
         [-2.57720998567, 1.144027291146, 0.267824910126],
         [-2.670018674713, 1.717907968331, 0.267824910126]]
    out = solve_reference(b, [0.267824910126, 0.267824910126], 0.0, 0.0, seed=0, n_samples=6000)
    assert out["degenerate"] and "lines of sight" in out["reason"]
    assert out["landmark"][3] > 0.1 and out["landmark"].max() < 0.9
    assert np.isclose(out["landmark"].sum(), 1.0) and np.all(np.isfinite(out["landmark"]))


def test_all_views_at_one_pose_and_camera_on_ab():
    b = [[-2.3433983565, 0.842300949939, 0.267824910126]] * 3
    out = solve_reference(b, [0.0, 0.0], 0.0, 0.0, seed=0, n_samples=4000)
    assert out["degenerate"] and np.isclose(out["landmark"].sum(), 1.0)
    assert out["landmark"].max() < 0.9
    # camera between A and B: gamma = pi
    out = solve_reference([[np.pi / 2, -np.pi / 2, 0.3]], None, 0.01, 0.0, seed=0, n_samples=4000)
    assert out["degenerate"] and "line AB" in out["reason"]
    assert np.isclose(out["landmark"].sum(), 1.0) and out["cameras"].shape == (1, 20)


def test_one_view_and_no_motion():
    phi, psi, conf, _ = priors.sample_measurements("world", np.random.default_rng(8), 2,
                                                   np.deg2rad(1), np.deg2rad(2), 1)
    one = solve_reference(phi[0, :1], None, np.deg2rad(1), 0.0, seed=0, n_samples=4000)
    assert one["ess"] > 500 and one["cameras"].shape == (1, 20)
    assert one["landmark"].max() < 0.99                 # one view leaves C along a ray
    two = solve_reference(phi[0], None, np.deg2rad(1), np.deg2rad(2), partition="lr", seed=0,
                          n_samples=4000)
    assert two["landmark"].shape == (2,) and two["cameras"].shape == (2, 2)


def test_bad_input():
    b = [[0.1, 0.5, 0.3]]
    with pytest.raises(ValueError, match="nope"):
        solve_reference(b, None, 0.01, 0.0, nope=1)
    with pytest.raises(ValueError, match="sigma_bearing"):
        solve_reference(b, None, -1.0, 0.0)
    with pytest.raises(ValueError, match="headings"):
        solve_reference([[0.1, 0.5, 0.3]] * 2, [0.1, 0.2], 0.01, 0.01)
    with pytest.raises(ValueError, match="prior"):
        solve_reference(b, None, 0.01, 0.0, prior="arc")


def test_far_negative_arc_logit_gives_w_zero_without_overflow():
    # the arc parameter w = 1 / (1 + exp(-logit)) of a view's camera; a t component or a Newton
    # step can put the logit below -709.78, where exp overflows (pytest makes the warning an
    # error). w is then 0 to double precision (the camera sits at A: no valid draw), and draws
    # with ordinary logits are untouched.
    from qfg.solvers.reference.staged import Layout, _construct

    L = Layout(np.array([[0.3, 0.9, 0.5]]), None, 0.01, 0.0)
    logits = np.array([-1e4, -800.0, -5.0, -1.0, 0.4, 4.0])
    v = np.zeros((logits.size, 3))
    v[:, 0] = logits
    X, _, logjac, _, valid, _ = _construct(L, v)
    assert not valid[:2].any() and valid[2:].all() and np.isfinite(logjac[2:]).all()
    w = np.r_[0.0, 0.0, 1.0 / (1.0 + np.exp(-logits[2:]))]
    gamma = wrap_angle(np.full(logits.size, 0.9 - 0.3))
    span = np.pi - np.abs(gamma)
    want = locus_point(gamma, span * 0.5 * (1.0 - np.cos(np.pi * w)))
    assert np.allclose(X[:, 0], want, rtol=1e-12, atol=0.0)
