"""Single-triplet solvers: accuracy on noiseless scenarios, the baseline's independence of the
headings, incremental = batch, valid distributions on random and degenerate input, bad input."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qfg import geometry, metrics, partitions
from qfg.simulation import TripletHistory, random_triplet_history
from qfg.solvers import TripletSolver, add_view, solve_triplet, solve_triplets
from qfg.solvers.baseline import resect
from qfg.solvers.common import arcs as _arcs
from qfg.solvers.common import estimate as _estimate
from qfg.solvers.common import input as _input
from qfg.solvers.common import laplace as _laplace
from qfg.solvers.common import options as _options
from qfg.solvers.common import prior as _prior
from qfg.solvers.common import seeds as _seeds

METHODS = ("full", "fast", "fast-paper", "baseline")
EDC = partitions.get("edc")


def _noiseless(n, seed, n_views=3):
    ss = np.random.SeedSequence(seed)
    return [random_triplet_history(np.random.default_rng(c), n_views) for c in ss.spawn(n)]


# ---------------------------------------------------------------------------------------------
# accuracy (acceptance): noiseless 3-view scenarios


@pytest.fixture(scope="module")
def noiseless200():
    return _noiseless(200, 20240)


@pytest.mark.parametrize("method, least", [("full", 0.95), ("fast-paper", 0.95), ("fast", 0.92)])
def test_noiseless_truth_is_most_probable(noiseless200, method, least):
    hs = noiseless200
    ests = solve_triplets(hs, method=method, seed=7)
    P = np.array([e.landmark for e in ests])
    g = np.array([h.truth.state for h in hs])
    top_c = np.mean(metrics.gt_rating(P, g) == 1)
    cams = np.array([e.cameras for e in ests])                 # (200, 3, 20)
    gc = np.array([h.truth.camera_states for h in hs])          # (200, 3)
    top_x = np.mean(metrics.gt_rating(cams, gc) == 1)
    assert top_c >= least, f"{method}: true C state most probable in {top_c:.1%}"
    assert top_x >= least, f"{method}: true camera states most probable in {top_x:.1%}"


# ---------------------------------------------------------------------------------------------
# baseline ignores headings; incremental equals batch; batch equals single


def test_baseline_ignores_headings():
    h = random_triplet_history(np.random.default_rng(5), 4, 0.03, 0.1)
    a = solve_triplet(h.bearings, h.headings, method="baseline", sigma_bearing=0.03,
                      sigma_heading=0.1, seed=11)
    other = np.random.default_rng(6).uniform(-np.pi, np.pi, 3)
    b = solve_triplet(h.bearings, other, method="baseline", sigma_bearing=0.03,
                      sigma_heading=1.5, seed=11)
    c = solve_triplet(h.bearings, None, method="baseline", sigma_bearing=0.03, seed=11)
    for e in (b, c):
        np.testing.assert_array_equal(a.landmark, e.landmark)
        np.testing.assert_array_equal(a.cameras, e.cameras)
    # while the motion-model solvers do read them
    f1 = solve_triplet(h, method="fast")
    f2 = solve_triplet(h.bearings, other, method="fast", sigma_bearing=0.03, sigma_heading=0.1)
    assert not np.allclose(f1.landmark, f2.landmark)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("sigmas", [(0.0, 0.0), (0.03, 0.08)])
def test_incremental_equals_batch(method, sigmas):
    h = random_triplet_history(np.random.default_rng(12), 4, *sigmas)
    solver = TripletSolver(method, sigma_bearing=sigmas[0], sigma_heading=sigmas[1], seed=99)
    for i in range(4):
        solver.add_view(h.bearings[i], None if i == 0 else h.headings[i - 1])
        inc = solver.estimate()
        batch = solve_triplet(h.bearings[:i + 1], h.headings[:i], method=method,
                              sigma_bearing=sigmas[0], sigma_heading=sigmas[1], seed=99)
        assert inc.n_views == batch.n_views == i + 1
        np.testing.assert_array_equal(inc.landmark, batch.landmark)
        np.testing.assert_array_equal(inc.cameras, batch.cameras)
        assert inc.n_hypotheses == batch.n_hypotheses and inc.reason == batch.reason
    # the old estimate-based entry point names its replacement
    with pytest.raises(ValueError, match="TripletSolver"):
        add_view(inc, h.bearings[0], 0.1)
    with pytest.raises(ValueError, match="TripletSolver"):
        inc.add_view(h.bearings[0], 0.1)
    assert add_view(solver, h.bearings[0], 0.1).n_views == 5


@pytest.mark.parametrize("method", METHODS)
def test_batch_equals_single_and_seeds(method):
    rng = np.random.default_rng(3)
    hs = [random_triplet_history(rng, 3, 0.02, 0.05) for _ in range(3)]
    hs.append(random_triplet_history(rng, 2, 0.02, 0.05))   # a different number of views
    batch = solve_triplets(hs, method=method, seed=17)
    root = np.random.SeedSequence(17)
    for t, h in enumerate(hs):
        single = solve_triplet(h, method=method, seed=_seeds.child_seed(root, t))
        np.testing.assert_allclose(batch[t].landmark, single.landmark, rtol=0, atol=1e-12)
        np.testing.assert_allclose(batch[t].cameras, single.cameras, rtol=0, atol=1e-12)
    # arrays in, same numbers out
    b = np.stack([h.bearings for h in hs[:3]])
    hd = np.stack([h.headings for h in hs[:3]])
    arr = solve_triplets(b, hd, method=method, sigma_bearing=0.02, sigma_heading=0.05, seed=17)
    for t in range(3):
        np.testing.assert_allclose(arr[t].landmark, batch[t].landmark, rtol=0, atol=1e-12)


def test_same_seed_same_result_and_seed_matters():
    h = random_triplet_history(np.random.default_rng(8), 3, 0.03, 0.08)
    a = solve_triplet(h, method="full", seed=4)
    b = solve_triplet(h, method="full", seed=4)
    np.testing.assert_array_equal(a.landmark, b.landmark)
    hc = [TripletSolver("full", sigma_bearing=0.03, sigma_heading=0.08, seed=s)
          .add_view(h.bearings[0]).add_view(h.bearings[1], h.headings[0]).hypotheses()
          for s in (5, 6)]
    assert not np.array_equal(hc[0].landmark_samples, hc[1].landmark_samples)
    g1 = solve_triplet(h, method="full", seed=np.random.default_rng(1))
    g2 = solve_triplet(h, method="full", seed=np.random.default_rng(1))
    np.testing.assert_array_equal(g1.landmark, g2.landmark)


# ---------------------------------------------------------------------------------------------
# outputs are valid distributions on random and degenerate input


def _check_valid(e, n_views):
    m = EDC.n_states
    assert e.landmark.shape == (m,) and e.cameras.shape == (n_views, m)
    for p in (e.landmark, e.cameras):
        assert np.all(np.isfinite(p)) and np.all(p >= 0)
        np.testing.assert_allclose(p.sum(axis=-1), 1.0, atol=1e-9)
    assert isinstance(e.degenerate, bool)
    if e.degenerate:
        assert e.reason


angles = st.floats(-np.pi, np.pi, allow_nan=False)


@given(st.integers(1, 4), st.integers(0, 2**31 - 1), st.sampled_from([0.0, 0.01, 0.1]),
       st.sampled_from([0.0, 0.05, 0.3]), st.sampled_from(METHODS))
@settings(max_examples=40, deadline=None)
def test_random_input_gives_valid_distributions(n, seed, sb, sh, method):
    rng = np.random.default_rng(seed)
    b = rng.uniform(-np.pi, np.pi, (n, 3))
    psi = rng.uniform(-np.pi, np.pi, n - 1)
    e = solve_triplet(b, psi, method=method, sigma_bearing=sb, sigma_heading=sh, seed=seed,
                      **({"n_landmark_samples": 1024} if method == "baseline" else {}))
    _check_valid(e, n)


@given(st.integers(1, 3), angles, angles, st.sampled_from(["equal", "opposite", "miss"]),
       st.sampled_from([0.0, 0.02]), st.sampled_from(METHODS))
@settings(max_examples=40, deadline=None)
def test_degenerate_input_gives_valid_flagged_distributions(n, phi_a, phi_c, kind, sb, method):
    if kind == "miss":
        # view 1 left of AB facing A, later views right of AB, travelling straight away from A:
        # (with zero noise) no ray meets a later arc
        b = np.tile([0.0, np.pi / 2, phi_c], (n, 1))
        b[1:, :2] = [np.pi / 2, 0.0]
        psi = np.full(n - 1, np.pi)
    else:
        gap = 0.0 if kind == "equal" else np.pi
        b = np.tile([phi_a, phi_a + gap, phi_c], (n, 1))
        psi = np.zeros(n - 1)
    e = solve_triplet(b, psi, method=method, sigma_bearing=sb, sigma_heading=0.0, seed=1,
                      **({"n_landmark_samples": 1024} if method == "baseline" else {}))
    _check_valid(e, n)
    if kind != "miss":
        assert e.degenerate and "line AB" in e.reason
        if sb == 0.0 and method != "baseline":
            np.testing.assert_allclose(e.landmark, 1.0 / 20)


def test_rays_that_miss_every_locus_give_uniform_flagged():
    # view 1 on the arc left of AB (x < 0) facing A (phi_A = 0), view 2 right of AB; travelling
    # along alpha + pi moves straight away from A, so x stays < 0 and no ray meets the view-2 arc
    b = np.array([[0.0, np.pi / 2, 0.3], [np.pi / 2, 0.0, 0.3]])
    for method in ("full", "fast"):
        e = solve_triplet(b, [np.pi], method=method, sigma_bearing=0.0, sigma_heading=0.0,
                          seed=2)
        _check_valid(e, 2)
        assert e.degenerate and e.n_hypotheses == 0
        np.testing.assert_allclose(e.landmark, 1.0 / 20)
        np.testing.assert_allclose(e.cameras, 1.0 / 20)


def test_zero_sigmas_work():
    h = random_triplet_history(np.random.default_rng(21), 3)
    for m in METHODS:
        e = solve_triplet(h.bearings, h.headings, method=m, sigma_bearing=0.0, sigma_heading=0.0,
                          seed=0)
        _check_valid(e, 3)
        assert not e.degenerate


# ---------------------------------------------------------------------------------------------
# bad input


@pytest.mark.parametrize("kwargs, arg", [
    (dict(bearings=np.zeros((3, 2)), headings=np.zeros(2)), "bearings"),
    (dict(bearings=np.zeros((0, 3)), headings=np.zeros(0)), "bearings"),
    (dict(bearings=np.zeros((2, 2, 3)), headings=np.zeros(1)), "bearings"),
    (dict(bearings=[[0.1, np.nan, 0.2]], headings=None), "bearings"),
    (dict(bearings=np.zeros((3, 3)), headings=np.zeros(3)), "headings"),
    (dict(bearings=np.zeros((3, 3)), headings=[0.0, np.inf]), "headings"),
    (dict(bearings=np.zeros((2, 3)), headings=[0.0], sigma_bearing=-0.1), "sigma_bearing"),
    (dict(bearings=np.zeros((2, 3)), headings=[0.0], sigma_heading=-1.0), "sigma_heading"),
    (dict(bearings=np.zeros((2, 3)), headings=[0.0], sigma_heading=np.nan), "sigma_heading"),
    (dict(bearings=np.zeros((2, 3)), headings=[0.0], method="exact"), "method"),
    (dict(bearings=np.zeros((2, 3)), headings=[0.0], n_samples=0), "n_samples"),
    (dict(bearings=np.zeros((2, 3)), headings=[0.0], warp=3), "warp"),
    (dict(bearings=np.zeros((2, 3)), headings=[0.0], prior="flat"), "prior"),
    (dict(bearings=np.zeros((2, 3)), headings=[0.0], seed=-3), "seed"),
    (dict(bearings=np.zeros((2, 3)), headings=[0.0], partition="nope"), "partition"),
])
def test_bad_input_names_the_argument(kwargs, arg):
    kw = dict(sigma_bearing=0.01, sigma_heading=0.02, method="full")
    kw.update(kwargs)
    b, h = kw.pop("bearings"), kw.pop("headings")
    with pytest.raises(ValueError, match=arg):
        solve_triplet(b, h, **kw)


def test_bad_input_other_entry_points():
    with pytest.raises(ValueError, match="sigma_bearing"):
        solve_triplet(np.zeros((2, 3)), [0.0])
    h = random_triplet_history(np.random.default_rng(0), 3)
    with pytest.raises(ValueError, match="headings"):
        solve_triplet(h, [0.0, 0.0])
    with pytest.raises(ValueError, match="headings"):
        solve_triplets(np.zeros((2, 3, 3)), np.zeros((2, 3)), sigma_bearing=0.0)
    with pytest.raises(ValueError, match="histories"):
        solve_triplets(np.zeros((2, 3)), sigma_bearing=0.0)
    s = TripletSolver("full", sigma_bearing=0.01, sigma_heading=0.02, seed=0)
    with pytest.raises(ValueError, match="bearings"):
        s.estimate()
    with pytest.raises(ValueError, match="heading"):
        s.add_view([0.1, 0.2, 0.3], 0.4)
    s.add_view([0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="heading"):
        s.add_view([0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="bearings"):
        s.add_view([0.1, 0.2], 0.1)
    with pytest.raises(ValueError, match="estimate"):
        add_view("nope", [0.1, 0.2, 0.3], 0.1)
    with pytest.raises(ValueError, match="method"):
        TripletSolver("exact", sigma_bearing=0.1)
    with pytest.raises(ValueError, match="sigma_bearing"):
        TripletSolver("full", sigma_bearing=-1)


def test_history_without_motion_uses_baseline_model():
    h = random_triplet_history(np.random.default_rng(4), 3, 0.02, 0.05)
    nm = TripletHistory(landmarks=h.landmarks, bearings=h.bearings, headings=h.headings,
                        sigma_bearing=0.02, sigma_heading=0.05, has_motion=False)
    e = solve_triplet(nm, method="full", seed=3)
    assert e.method == "baseline"
    b = solve_triplet(h, method="baseline", seed=3)
    np.testing.assert_array_equal(e.landmark, b.landmark)


# ---------------------------------------------------------------------------------------------
# geometry behind the weights, against independent computations


@given(st.integers(0, 2**31 - 1))
@settings(max_examples=30, deadline=None)
def test_resection_recovers_the_pose(seed):
    rng = np.random.default_rng(seed)
    X = np.append(rng.uniform(-3, 3, 2), rng.uniform(-np.pi, np.pi))
    L = rng.uniform(-3, 3, (1, 2))
    P = np.array([[0.0, 0.0], [0.0, 1.0], L[0]])
    phi = geometry.bearing(X[None, :], P)
    # away from the degenerate configurations (camera on the circle through A, B, L)
    poses, logdet, ok = resect(L, phi[None, :])
    if ok[0, 0]:
        np.testing.assert_allclose(poses[0, 0, :2], X[:2], atol=1e-6)
        assert abs(geometry.wrap_angle(poses[0, 0, 2] - X[2])) < 1e-6
        # |det J| by finite differences of the bearings
        J = np.empty((3, 3))
        for k in range(3):
            d = np.zeros(3)
            d[k] = 1e-6
            J[:, k] = geometry.wrap_angle(geometry.bearing((X + d)[None], P)
                                          - geometry.bearing((X - d)[None], P)) / 2e-6
        np.testing.assert_allclose(logdet[0, 0], np.log(abs(np.linalg.det(J))), atol=1e-4)


@given(st.integers(0, 2**31 - 1))
@settings(max_examples=30, deadline=None)
def test_ray_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    O = rng.uniform(-3, 3, 2)
    X = rng.uniform(-3, 3, 2)
    if min(np.linalg.norm(X), np.linalg.norm(X - [0, 1]), np.linalg.norm(X - O)) < 0.2:
        return
    theta = np.arctan2(*(X - O)[::-1])

    def point(th, gam):
        c = geometry.locus_circle(0.0, gam)
        pts, valid = geometry.ray_circle_intersection(O, th, c.center, c.radius)
        k = np.argmin(np.linalg.norm(pts - X, axis=-1) + 1e9 * ~valid)
        return pts[k]

    gam = geometry.wrap_angle(np.arctan2(1 - X[1], -X[0]) - np.arctan2(-X[1], -X[0]))
    h = 1e-6
    J = np.column_stack([(point(theta + h, gam) - point(theta - h, gam)) / (2 * h),
                         (point(theta, gam + h) - point(theta, gam - h)) / (2 * h)])
    det = abs(np.linalg.det(J))
    if not np.isfinite(det) or det > 1e3:    # near-grazing rays: finite differences unreliable
        return
    np.testing.assert_allclose(_arcs.log_ray_jacobian(X, O, theta), np.log(det), atol=1e-3)


def test_arc_jacobian_matches_finite_differences():
    rng = np.random.default_rng(0)
    for _ in range(20):
        gam = rng.choice([-1, 1]) * rng.uniform(0.1, 3.0)
        w = rng.uniform(0.05, 0.95)

        def point(g, ww):
            a, _ = _arcs.arc_parameter(g, ww)
            return geometry.locus_point(g, a)

        h = 1e-6
        J = np.column_stack([(point(gam + h, w) - point(gam - h, w)) / (2 * h),
                             (point(gam, w + h) - point(gam, w - h)) / (2 * h)])
        X = point(gam, w)
        _, ld = _arcs.arc_parameter(gam, w)
        np.testing.assert_allclose(_arcs.log_arc_jacobian(X, gam, ld),
                                   np.log(abs(np.linalg.det(J))), atol=1e-4)


def test_one_view_samples_lie_on_lines_of_sight_and_locus():
    phi = np.array([0.4, 1.3, -0.7])
    for method in ("full", "fast", "fast-paper"):
        s = TripletSolver(method, sigma_bearing=0.0, seed=1).add_view(phi)
        e, hy = s.estimate(), s.hypotheses()
        cams = hy.camera_samples[0]
        c = geometry.locus_circle(phi[0], phi[1])
        np.testing.assert_allclose(np.linalg.norm(cams[:, :2] - c.center, axis=1), c.radius,
                                   atol=1e-9)
        np.testing.assert_allclose(geometry.bearing(cams, [0.0, 1.0]), phi[1], atol=1e-9)
        if method != "fast-paper":
            # hypothesis j is (camera j, C j): C within a few bearing floors of the line of sight
            tol = 6 * e.options["bearing_floor"]
            err = geometry.wrap_angle(geometry.bearing(cams, hy.landmark_samples) - phi[2])
            assert np.all(np.abs(err) < tol)


def test_estimate_exposes_hypotheses():
    h = random_triplet_history(np.random.default_rng(2), 3, 0.02, 0.05)
    # one population (the few-views package off): the estimate is then the shrunk histogram of
    # these hypotheses; two populations average two such (tests/test_sis_populations.py)
    s = TripletSolver("full", sigma_bearing=0.02, sigma_heading=0.05, seed=0,
                      few_views_budget=None)
    for i in range(3):
        s.add_view(h.bearings[i], None if i == 0 else h.headings[i - 1])
    e, hy = s.estimate(), s.hypotheses()
    assert hy.joint
    J = e.n_hypotheses
    assert hy.camera_samples.shape[:2] == (3, hy.landmark_samples.shape[0])
    assert J == np.count_nonzero(hy.landmark_weights)
    np.testing.assert_allclose(hy.landmark_weights.sum(), 1.0)
    # the landmark estimate is the weighted histogram of the hypotheses (eq. slamapprox1),
    # shrunk toward the uniform by mc_shrinkage pseudo-draws against their ESS
    hist = np.bincount(EDC.state_of(hy.landmark_samples), hy.landmark_weights, minlength=20)
    assert e.ess == pytest.approx(_estimate.ess(hy.landmark_weights))
    alpha = _options.DEFAULTS["full"]["mc_shrinkage"]
    np.testing.assert_allclose(_estimate.shrink_to_uniform(hist, e.ess, alpha), e.landmark,
                               atol=1e-12)
    s, p = e.most_likely
    assert p == e.landmark.max() and 0 <= s < 20


def test_demo_estimates_every_seen_triplet(tmp_path):
    from qfg.harness.demo import run

    lines = []
    res = run(seed=1, output=tmp_path, methods=("fast",), echo=lines.append)
    assert len(res["estimates"]["fast"]) == len(res["histories"]) > 0
    assert 0 <= res["summary"]["fast"]["top1"] <= 1
    text = "\n".join(lines)
    assert "truth most likely for" in text
    assert any(p.name == "scenario.png" for p in tmp_path.rglob("*.png"))


@pytest.mark.parametrize("method", METHODS)
def test_estimate_is_small(method):
    import pickle

    h = random_triplet_history(np.random.default_rng(9), 3, 0.03, 0.08)
    e = solve_triplet(h, method=method, seed=0)
    assert len(pickle.dumps(e)) < 10_000
    assert len(repr(e)) < 300 and method in repr(e)
    assert e.ess > 0 and e.prior == "world"


def test_solver_quadrature_of_the_world_prior():
    # the solvers evaluate the world prior with SOLVER_N_RHO points in rho; against the prior's
    # own 128 points the log density differs by a constant per k plus at most 0.03
    from qfg.priors import WorldBoxPrior

    fine, coarse = WorldBoxPrior(), _prior.resolve_prior("world")
    assert isinstance(coarse, WorldBoxPrior) and coarse.n_rho == _prior.SOLVER_N_RHO
    rng = np.random.default_rng(0)
    for n_cameras in (1, 3):
        x = fine.sample(rng, n_cameras, 1500)
        d = coarse.log_density(x) - fine.log_density(x)
        assert np.max(np.abs(d - np.median(d))) < 0.03


def test_lsq_triangulation_matches_geometry():
    # the solvers' inline least-squares triangulation (speed) is geometry.triangulate_lsq
    rng = np.random.default_rng(1)
    X, th = rng.normal(size=(200, 3, 2)), rng.uniform(-np.pi, np.pi, (200, 3))
    L, ok = geometry.triangulate_lsq(X, th)
    L2, ok2 = _laplace.triangulate(X, th)[:2]
    np.testing.assert_allclose(L2[ok2], L[ok2], atol=1e-9)
    assert np.array_equal(ok, ok2)


def test_move_target_is_zero_residual_at_the_true_poses():
    # The MH moves' target (eqs. MsrLkl, MotionModel in x, y, alpha) against the simulator:
    # noiseless measurements of the true poses leave no residual; turning camera 1 by d adds d
    # to both A/B bearing residuals of view 1 and to the heading residual of the first move.
    from dataclasses import replace as _replace

    from qfg.solvers.sis import engine as _engine
    from qfg.solvers.sis import target as _target

    h = random_triplet_history(np.random.default_rng(21), 3, 0.0, 0.0)
    opts = _options.resolve_options("full", {})
    st = _engine.start(h.bearings[:1], np.array([0.02]), np.array([0.05]),
                    (np.random.SeedSequence(0),), opts, _input.get_partition("edc"), "full")
    st = _replace(st, bearings=h.bearings[None], headings=np.asarray(h.headings)[None],
                  same_pose=np.zeros((1, 3), dtype=bool))
    true = np.asarray(h.truth.poses_ab, dtype=float)[None]
    lt, lp = _target.log_pose_target(st, np.zeros(1, dtype=int), true)
    np.testing.assert_allclose(lt, lp, atol=1e-12)
    d = 0.01
    turned = true.copy()
    turned[0, 0, 2] += d
    lt2, lp2 = _target.log_pose_target(st, np.zeros(1, dtype=int), turned)
    np.testing.assert_allclose(lp2, lp)
    np.testing.assert_allclose(lt2 - lp2, -0.5 * (2 * d**2 / 0.02**2 + d**2 / 0.05**2),
                               rtol=1e-6)


def test_moves_spread_the_resampled_copies_and_keep_the_answer():
    # Resample-move: after 6 views the first camera is represented by many more distinct poses
    # (path degeneracy undone), while the answer stays that of the same sampler without moves
    # (the moves leave the posterior invariant).
    h = random_triplet_history(np.random.default_rng(900), 6, np.deg2rad(2), np.deg2rad(5))
    # (the rejuvenation, on by default, also spreads them: tests/test_sis_rejuvenation.py)
    kw = {"n_samples": 200, "motion_samples": 4, "max_hypotheses": 500, "rejuvenate": 0}
    s0 = TripletSolver.solve(h, method="full", seed=3, move_steps=0, **kw)
    s2 = TripletSolver.solve(h, method="full", seed=3, move_steps=2, **kw)
    n0 = np.unique(s0.hypotheses().camera_samples[0, :, 0]).size
    n2 = np.unique(s2.hypotheses().camera_samples[0, :, 0]).size
    assert n2 > 2 * n0
    ref = solve_triplet(h, method="full", seed=4, n_samples=600, motion_samples=8,
                        max_hypotheses=3000, move_steps=2)
    for s in (s0, s2):
        assert 0.5 * np.abs(s.estimate().landmark - ref.landmark).sum() < 0.25


@pytest.mark.parametrize("method", ["full", "fast"])
def test_mc_shrinkage_is_the_dirichlet_mean_of_the_raw_estimate(method):
    # the default answer is the raw Monte Carlo estimate (mc_shrinkage=0, same seed and draws)
    # shrunk toward the uniform by alpha pseudo-draws against the final sample's ESS
    h = random_triplet_history(np.random.default_rng(21), 4, np.deg2rad(2), np.deg2rad(5))
    alpha = _options.DEFAULTS[method]["mc_shrinkage"]
    assert alpha > 0
    raw = solve_triplet(h, method=method, seed=3, mc_shrinkage=0)
    est = solve_triplet(h, method=method, seed=3)
    assert est.ess == pytest.approx(raw.ess)
    m = raw.landmark.size
    want = (raw.ess * raw.landmark + alpha / m) / (raw.ess + alpha)
    np.testing.assert_allclose(est.landmark, want, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(est.cameras, (raw.ess * raw.cameras + alpha / m)
                               / (raw.ess + alpha), rtol=1e-12, atol=1e-15)
    # no state can be claimed impossible, nor certain, from finitely many effective draws
    assert est.landmark.min() >= alpha / m / (raw.ess + alpha) * (1 - 1e-12)
    assert est.landmark.max() <= 1 - alpha * (m - 1) / m / (raw.ess + alpha) * (1 - 1e-12)
    with pytest.raises(ValueError, match="mc_shrinkage"):
        solve_triplet(h, method=method, mc_shrinkage=-1)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.integers(1, 6), st.integers(1, 7), st.integers(0, 2), st.floats(0.0, 0.9))
def test_logsumexp_matches_scipy(n, k, axis, p_inf):
    """The solvers' logsumexp (kept for speed: benchmarks/bench_solvers.py --logsumexp) gives
    scipy.special.logsumexp's values on any axis, all -inf rows included (no warning)."""
    from scipy.special import logsumexp as scipy_lse

    from qfg.solvers.common.likelihood import logsumexp

    rng = np.random.default_rng(n * 100 + k * 10 + axis)
    a = rng.standard_normal((n, 5, k)) * 30
    a[rng.random(a.shape) < p_inf] = -np.inf
    with np.errstate(all="raise"):
        ours = logsumexp(a, axis=axis)
    with np.errstate(divide="ignore"):
        np.testing.assert_allclose(ours, scipy_lse(a, axis=axis), rtol=1e-12, atol=1e-12)
