"""The joint map method (qfg.joint) and the nonlinear module under it (qfg.nonlinear).

Checked against things computed independently: a long-run Metropolis sampler of the exact robust
posterior (numpy, not GTSAM's linearisation), geometry (ray intersections, noise-free
configurations), GTSAM's own graph error against the numpy cost, and data corrupted on purpose.
"""

import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest

from qfg import joint
from qfg import nonlinear as nl
from qfg.datasets.mrclam.joint_map import mrclam_marginals, mrclam_reference, mrclam_runs
from qfg.geometry import wrap_angle
from qfg.inference.results import Marginals
from qfg.joint import start as joint_start
from qfg.joint import states as joint_states
from qfg.partitions import get as get_partition
from qfg.simulation import random_trajectory_run

EDC = get_partition("edc")


def _truth(run, triplets):
    t = np.array(triplets)
    L = run.landmarks
    return joint_states._safe_frame(L[t[:, 2]], L[t[:, 0]], L[t[:, 1]])


def _run(seed, **kw):
    opts = dict(n_landmarks=6, n_poses=14, fov_deg=360.0)
    opts.update(kw)
    return random_trajectory_run(np.random.default_rng(seed), **opts)


# ----------------------------------------------------------------------------- nonlinear
def test_intersect_rays_is_the_exact_intersection_and_measures_parallax():
    rng = np.random.default_rng(0)
    p = np.array([0.3, 1.7])
    o = rng.uniform(-3, 3, size=(5, 2))
    ang = np.arctan2(p[1] - o[:, 1], p[0] - o[:, 0])
    q, ok, par = nl.intersect_rays(o, ang, 0.01)
    assert ok and np.allclose(q, p, atol=1e-9)
    d = np.abs(wrap_angle(ang[:, None] - ang[None, :]))
    assert par == pytest.approx(np.max(np.minimum(d, np.pi - d)))
    _, ok, par = nl.intersect_rays([[0, 0], [1, 0]], [0.0, 0.0], 0.01)  # collinear rays
    assert not ok


def test_robust_cost_equals_gtsams_graph_error():
    run = _run(1)
    meas = joint.simulated_measurements(run)
    post = joint.solve(meas, joint.SolveParams(starts=1))
    pr, fit = post._problem, post._fit
    rng = np.random.default_rng(2)
    for scale in (0.0, 0.01, 0.05):
        X = fit.poses + rng.normal(0, scale, fit.poses.shape)
        L = fit.points + rng.normal(0, scale, fit.points.shape)
        g = nl._graph(pr).error(nl._values(pr, X, L))
        assert float(nl.robust_cost(pr, X, L)) == pytest.approx(g, rel=1e-3, abs=1e-6)


def test_covariance_without_a_gauge_is_a_clear_error():
    pr = nl.BearingProblem(n_poses=2, n_points=1, bearing_pose=[0, 1], bearing_point=[0, 0],
                           bearing=[0.5, 2.0], sigma_bearing=0.01)
    f = nl.fit(pr, [[0, 0, 0], [2, 0, 0]], [[1, 1]])
    with pytest.raises(ValueError, match="problem"):
        nl.covariance(pr, f, points=[0])


def _pose_on_a_landmark():
    """Five poses, four landmarks seen from every pose, the last 20 micrometres from pose 3:
    that bearing's information is ~1e13 and GTSAM's Cholesky gives up."""
    P = np.array([[0, 0, 0], [0.5, 0, 0.1], [1.0, 0.1, 0.2], [1.5, 0.2, 0.3], [2.0, 0.3, 0.3]])
    L = np.array([[1, 2], [2, -1], [3, 1.5], [1.5 + 2e-5, 0.2]])
    bp, bl = np.repeat(np.arange(5), 4), np.tile(np.arange(4), 5)
    d = L[bl] - P[bp, :2]
    kw = dict(n_poses=5, n_points=4, bearing_pose=bp, bearing_point=bl,
              bearing=np.arctan2(d[:, 1], d[:, 0]) - P[bp, 2], sigma_bearing=0.01,
              between_from=range(4), between_to=range(1, 5), between=nl._relative(P[:-1], P[1:]),
              between_sigma=[0.05, 0.05, 0.1])
    return kw, P, L


def _qr_covariance(pr, f, keys):
    """The reference: GTSAM's multifrontal QR and the joint of ``keys`` by QR, inverted."""
    import gtsam
    import scipy.linalg as sl

    gfg = nl._graph(pr).linearize(nl._values(pr, f.poses, f.points))
    bt = gfg.eliminateMultifrontal(gtsam.Ordering.ColamdGaussianFactorGraph(gfg),
                                   gtsam.EliminateQR)
    A, _ = bt.joint(keys, gtsam.EliminateQR).jacobian(gtsam.Ordering(keys))
    Ri = sl.solve_triangular(np.linalg.qr(np.asarray(A), mode="r"), np.eye(len(A[0])))
    return Ri @ Ri.T


def test_laplace_sparse_solve_equals_gtsam_where_gtsam_answers():
    run = _run(3, n_poses=30)
    post = joint.solve(joint.simulated_measurements(run))
    a = nl.Laplace(post._problem, post._fit)
    s = nl.Laplace(post._problem, post._fit, solver="sparse")
    assert (a.method, s.method) == ("gtsam", "sparse")
    Ca, Cs = a.joint(range(6), [0, 7, 29]), s.joint(range(6), [0, 7, 29])
    assert np.abs(Ca - Cs).max() <= 1e-9 * np.abs(Ca).max()


def test_laplace_answers_an_ill_conditioned_fit_gtsam_cannot():
    kw, P, L = _pose_on_a_landmark()
    pr = nl.BearingProblem(**kw, pose_prior_index=[0], pose_prior=[[0, 0, 0]],
                           pose_prior_sigma=1e-6)
    f = nl.fit(pr, P, L)
    lap = nl.Laplace(pr, f)
    assert lap.method == "sparse" and "near variable" in lap.error
    C = lap.joint(range(4), [1, 3])
    ref = _qr_covariance(pr, f, [5, 6, 7, 8, 1, 3])
    assert np.abs(C - ref).max() <= 1e-8 * np.abs(ref).max()
    assert np.linalg.eigvalsh(C)[0] > 0


def test_a_pose_fitted_onto_a_landmark_it_sees_is_moved_off():
    """The trap of MRCLAM without odometry: started 20 micrometres from a landmark it sees (on
    its line of sight), Levenberg-Marquardt keeps the pose there (that bearing fits at any
    angle) at a cost far above the true minimum's; escape_close leaves the bearing out, refits,
    puts it back and lands on the true minimum with every bearing kept."""
    P = np.array([[0, 0, 0], [0.5, 0, 0.1], [1.0, 0.1, 0.2], [1.5, 0.2, 0.3], [2.0, 0.3, 0.3]])
    L = np.array([[1, 2], [2, -1], [3, 1.5], [2.5, 0.9]])
    bp, bl = np.repeat(np.arange(5), 4), np.tile(np.arange(4), 5)
    d = L[bl] - P[bp, :2]
    pr = nl.BearingProblem(n_poses=5, n_points=4, bearing_pose=bp, bearing_point=bl,
                           bearing=np.arctan2(d[:, 1], d[:, 0]) - P[bp, 2], sigma_bearing=0.01,
                           between_from=range(4), between_to=range(1, 5),
                           between=nl._relative(P[:-1], P[1:]), between_sigma=[0.05, 0.05, 0.1],
                           pose_prior_index=[0], pose_prior=[[0, 0, 0]], pose_prior_sigma=1e-6)
    Q = P.astype(float).copy()
    u = (L[3] - P[3, :2]) / np.linalg.norm(L[3] - P[3, :2])
    Q[3, :2] = L[3] - 2e-5 * u
    trapped = nl.fit(pr, Q, L)
    assert trapped.cost > 100 and np.linalg.norm(trapped.poses[3, :2] - L[3]) < 1e-4
    pr2, f, dropped, close = joint_start.escape_close(pr, trapped, joint_start.TOO_CLOSE, 100)
    assert (dropped, close) == (0, 1) and pr2 is pr
    assert f.cost < 1e-9 and np.allclose(f.poses, P, atol=1e-6)
    # a fit clear of every landmark is returned as it is
    assert joint_start.escape_close(pr, f, joint_start.TOO_CLOSE, 100)[1:] == (f, 0, 0)


def test_a_landmark_the_data_put_on_a_pose_loses_that_bearing():
    """Bearings that place a landmark 20 micrometres from a pose (no robot stands on a
    landmark): the one bearing from that pose is left out, the others kept, and the
    covariance no longer needs the sparse fallback."""
    kw, P, L = _pose_on_a_landmark()
    pr = nl.BearingProblem(**kw, pose_prior_index=[0], pose_prior=[[0, 0, 0]],
                           pose_prior_sigma=1e-6)
    f = nl.fit(pr, P, L)
    pr2, f2, dropped, close = joint_start.escape_close(pr, f, joint_start.TOO_CLOSE, 100)
    assert (dropped, close) == (1, 1) and pr2.bearing.size == pr.bearing.size - 1
    gone = ~np.isin(np.arange(pr.bearing.size), [15])          # pose 3's bearing to point 3
    assert np.array_equal(pr2.bearing, pr.bearing[gone])
    assert nl.Laplace(pr2, f2).method == "gtsam"
    with pytest.raises(ValueError, match="too_close"):
        joint.SolveParams(too_close=1.5)


def test_solve_params_hold_every_option_checked_once():
    p = joint.SolveParams()
    assert (p.chunk, p.min_rays, p.min_parallax_deg, p.starts, p.robust, p.outlier) == (
        100, 3, 10.0, 3, nl.HUBER_K, joint.OUTLIER)
    assert (p.inflate_kinematic, p.agree, p.too_close) == (
        joint.KINEMATIC_INFLATE, joint_start.AGREE, joint_start.TOO_CLOSE)
    assert p.kinematic is joint_start.KINEMATIC and p.kinematic_chunks == (25, 50, 100)
    assert joint.SolveParams(kinematic_chunks=np.array([10, 20])).kinematic_chunks == (10, 20)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.starts = 1
    assert dataclasses.replace(p, starts=1).starts == 1
    for name, bad in [("chunk", 1), ("min_rays", 1.5), ("min_parallax_deg", -1), ("starts", 0),
                      ("robust", np.nan), ("outlier", -1), ("residual_limit", "x"),
                      ("landmark_limit", -1), ("mode_cost", -1), ("inflate", -1),
                      ("inflate_kinematic", "twice"), ("sir_rays", -1), ("max_iterations", 0),
                      ("without_odometry", "ignore"), ("kinematic", {"speed": 1}),
                      ("kinematic_chunks", (1,)), ("agree", -1), ("too_close", 1.0)]:
        with pytest.raises(ValueError, match=f"^{name}: "):
            joint.SolveParams(**{name: bad})
        with pytest.raises(ValueError, match=f"^{name}: "):
            dataclasses.replace(p, **{name: bad})


def test_an_option_passed_as_its_own_keyword_names_solve_params():
    meas = joint.simulated_measurements(_run(1))
    with pytest.raises(TypeError, match=r"starts.*SolveParams\(starts=\.\.\.\).*CHANGELOG"):
        joint.solve(meas, starts=1)
    with pytest.raises(TypeError, match="unexpected keyword argument 'stars'"):
        joint.solve(meas, stars=1)
    with pytest.raises(ValueError, match="params"):
        joint.solve(meas, {"starts": 1})
    with pytest.raises(TypeError, match="mrclam_marginals.*SolveParams"):
        mrclam_marginals(None, without_odometry="skip")


def test_a_long_solve_tells_its_phases():
    said = []
    post = joint.solve(joint.simulated_measurements(_run(1)), joint.SolveParams(starts=1),
                       progress=said.append)
    assert post.method == "joint" and said[0].startswith("joint: robot 0 (1 of 1)")
    assert any("the joint solve of robot 0" in m for m in said)
    assert any("covariance" in m for m in said)
    with pytest.raises(ValueError, match="progress"):
        joint.solve(joint.simulated_measurements(_run(1)), progress="loud")


def test_laplace_reports_a_singular_system_instead_of_filling_it():
    kw, P, L = _pose_on_a_landmark()
    pr = nl.BearingProblem(**kw)                   # no anchor: a free gauge
    f = nl.fit(pr, P, L)
    with pytest.raises(nl.SingularInformation, match="singular"):
        nl.Laplace(pr, f).joint([0, 1])
    with pytest.raises(ValueError, match="solver"):
        nl.Laplace(pr, f, solver="qr")


@pytest.mark.parametrize("kw, name", [
    (dict(bearing_pose=[0, 5], bearing_point=[0, 0], bearing=[0, 0]), "bearing_pose"),
    (dict(bearing_pose=[0], bearing_point=[0], bearing=[np.nan]), "bearing"),
    (dict(bearing_pose=[0], bearing_point=[0], bearing=[0.1], sigma_bearing=0.0),
     "sigma_bearing"),
    (dict(between_from=[0], between_to=[1], between=[[1, 0]]), "between"),
])
def test_bearing_problem_bad_input_names_the_argument(kw, name):
    with pytest.raises(ValueError, match=name):
        nl.BearingProblem(n_poses=2, n_points=1, **kw)


# ----------------------------------------------------------------------------- simulator
def test_trajectory_run_noise_free_odometry_is_the_true_motion():
    r = random_trajectory_run(np.random.default_rng(3), n_landmarks=7, n_poses=12,
                              sigma_bearing=0, sigma_heading=0, sigma_step=0, sigma_turn=0,
                              fov_deg=90)
    rel = nl._relative(r.poses[:-1], r.poses[1:])
    assert np.allclose(r.odometry, rel, atol=1e-12)
    true = wrap_angle(np.arctan2(r.landmarks[None, :, 1] - r.poses[:, None, 1],
                                       r.landmarks[None, :, 0] - r.poses[:, None, 0])
                            - r.poses[:, None, 2])
    assert np.all(np.abs(true[r.visible]) <= np.deg2rad(45) + 1e-12)
    assert np.allclose(r.bearings[r.visible], true[r.visible])
    assert np.all(r.bearings[~r.visible] == 0)


# ----------------------------------------------------------------------------- joint
def test_states_of_a_known_configuration():
    """Nearly noise-free measurements: every triplet's most likely state is the true one, with
    near certainty wherever C is not within 2 cm of a state boundary."""
    run = _run(4, sigma_bearing=np.deg2rad(0.02), sigma_heading=np.deg2rad(0.05),
               sigma_step=0.001, sigma_turn=np.deg2rad(0.05), n_poses=16)
    post = joint.solve(joint.simulated_measurements(run))
    assert post.method == "joint" and all(f in ("ok", "weak") for f in post.landmark_flags)
    res = joint.triplet_marginals(post, samples=400, seed=0)
    assert isinstance(res, Marginals) and res.partition == "edc"
    c = _truth(run, res.triplets)
    g = EDC.state_of(c)
    P = res.probabilities
    assert np.all(P.argmax(1) == g)
    # distance of C (AB frame) to the nearest boundary, by perturbation
    eps = 0.02
    stable = np.ones(len(g), bool)
    for d in ([eps, 0], [-eps, 0], [0, eps], [0, -eps]):
        stable &= EDC.state_of(c + np.array(d)) == g
    assert np.all(P[np.arange(len(g)), g][stable] > 0.98)
    assert res[res.triplets[0]].shape == (20,)


def test_joint_matches_long_run_sampling_of_the_exact_posterior():
    """The state distributions from the joint method's samples against those of a long
    Metropolis run on the exact robust posterior (few views, paper's noise)."""
    run = _run(5, n_poses=8, n_landmarks=5)
    meas = joint.simulated_measurements(run)
    post = joint.solve(meas)
    ok = post.constrained
    assert ok.all() and set(post.landmark_flags) == {"weak"}
    tri = np.array(joint_states._all_triplets(5))
    n = 300

    def states(S):
        return joint_states.state_counts(S, tri, EDC) / len(S)

    def tv(a, b):
        return 0.5 * np.abs(a - b).sum(1).mean()

    ref = states(joint.reference_samples(post, n, steps=800, seed=1))
    sir = states(joint.sample_landmarks(post, n, seed=2))
    gauss = states(joint.sample_landmarks(joint.solve(meas, joint.SolveParams(sir_rays=0)), n, seed=2))
    # the posterior is far from Gaussian here (8 views): the conditional resampling of the weak
    # landmarks is much closer to the exact posterior than one Laplace approximation
    assert tv(sir, ref) < 0.25 and tv(sir, ref) < tv(gauss, ref) - 0.1, (tv(sir, ref),
                                                                         tv(gauss, ref))
    # and both are far from what an uninformed answer gives
    assert tv(np.full_like(ref, 1 / 20), ref) > 0.5


def test_a_robot_in_a_wrong_minimum_is_flagged_and_dropped():
    """Three runs of one world; the third's barcodes are misassigned (landmark ids permuted),
    so that its map cannot agree with the others: it must be flagged, left out, and the answer
    stay right."""
    rng = np.random.default_rng(6)
    L = rng.uniform([-3, -3], [3, 4], size=(6, 2))
    runs = []
    for k in range(3):
        r = random_trajectory_run(np.random.default_rng(60 + k), n_landmarks=6, n_poses=16,
                                  fov_deg=360)
        # same landmarks for every robot: recompute the bearings
        phi = wrap_angle(np.arctan2(L[None, :, 1] - r.poses[:, None, 1],
                                          L[None, :, 0] - r.poses[:, None, 0])
                               - r.poses[:, None, 2])
        phi = phi + np.random.default_rng(70 + k).normal(0, r.sigma_bearing, phi.shape)
        vi, col = np.nonzero(r.visible)
        ids = col if k < 2 else np.array([1, 0, 3, 2, 5, 4])[col]
        runs.append(joint.RobotRun(k, np.arange(r.n_poses, dtype=float), vi, ids, phi[vi, col],
                                   r.sigma_bearing, r.odometry, r.odometry_sigma))
    post = joint.solve(joint.JointMeasurements(tuple(runs)))
    assert post.robot_flags[2] == "local_minimum"
    assert "local_minimum" in post.flags
    assert post.robot_flags[0] == post.robot_flags[1] == "ok"
    res = joint.triplet_marginals(post, samples=400, seed=0)
    g = EDC.state_of(joint_states._safe_frame(*(L[np.array(res.triplets)[:, i]] for i in (2, 0, 1))))
    assert np.mean(res.probabilities[np.arange(len(g)), g] > 0.5) > 0.8


def test_a_fit_that_fails_its_residual_check_is_widened_not_confident():
    """One robot whose bearings are far noisier than it claims (5 deg told 0.1 deg): no start
    passes the residual check, the answer is flagged and every triplet is the prior."""
    run = _run(7, sigma_bearing=np.deg2rad(5.0))
    meas = joint.simulated_measurements(run)
    r = meas.runs[0]
    bad = joint.JointMeasurements((joint.RobotRun(0, r.times, r.bearing_pose, r.bearing_landmark,
                                                  r.bearing, np.deg2rad(0.1), r.odometry,
                                                  r.odometry_sigma),))
    post = joint.solve(bad)
    assert "local_minimum" in post.flags and post.robot_flags[0] == "local_minimum"
    q = np.linspace(1, 2, 20)
    q /= q.sum()
    res = joint.triplet_marginals(post, samples=200, prior_states=q)
    assert np.allclose(res.probabilities, q) and np.all(res.info["flagged"])


def test_unconstrained_landmark_gets_the_prior():
    run = _run(8, n_landmarks=6)
    meas = joint.simulated_measurements(run)
    r = meas.runs[0]
    keep = ~((r.bearing_landmark == 5) & (r.bearing_pose > 0))  # landmark 5: one ray
    r2 = joint.RobotRun(0, r.times, r.bearing_pose[keep], r.bearing_landmark[keep],
                        r.bearing[keep], r.sigma_bearing, r.odometry, r.odometry_sigma)
    post = joint.solve(joint.JointMeasurements((r2,), meas.landmark_ids))
    assert post.landmark_flags[5] == "unconstrained" and "unconstrained_landmark" in post.flags
    q = np.full(20, 0.05)
    res = joint.triplet_marginals(post, [(0, 1, 5), (5, 0, 1), (0, 1, 2)], samples=200,
                                  prior_states=q)
    assert np.allclose(res[(0, 1, 5)], q) and np.allclose(res[(5, 0, 1)], q)
    assert list(res.info["flagged"]) == [True, True, False]
    assert res[(0, 1, 2)].max() > 0.5


def test_a_lone_run_without_odometry_is_unverified_and_skip_leaves_it_out():
    run = _run(9)
    # a fit without odometry can pass every residual check in a wrong minimum: alone, with no
    # other robot's map to check it against, it is not used
    post = joint.solve(joint.simulated_measurements(run, odometry=False))
    assert post.method == "none" and "unverified" in post.flags
    assert post.robot_flags[0] == "unverified"
    res = joint.triplet_marginals(post, samples=100)
    assert res.method == "joint" and np.allclose(res.probabilities, 1 / 20)
    assert res.info["flagged"].all()
    cam = joint.camera_marginals(post, 0, [0, 1], [(0, 1, 2), (1, 2, 3)])
    assert isinstance(cam, Marginals) and cam.method == "joint" and cam.info["robot"] == 0
    assert np.allclose(cam.probabilities, 1 / 20) and np.allclose(cam[(1, 2, 3)], 1 / 20)
    skip = joint.SolveParams(without_odometry="skip")
    post = joint.solve(joint.simulated_measurements(run, odometry=False), skip)
    assert post.method == "none" and post.robot_flags[0] == "no_odometry"
    # with another robot that has odometry, skip leaves the one without out, flagged
    m1 = joint.simulated_measurements(run, odometry=False, robot=1).runs[0]
    m0 = joint.simulated_measurements(run).runs[0]
    post = joint.solve(joint.JointMeasurements((m0, m1)), skip)
    assert post.method == "joint" and post.robot_flags == {0: "ok", 1: "no_odometry"}


def test_floor_mixes_every_row_toward_the_prior():
    run = _run(10)
    post = joint.solve(joint.simulated_measurements(run))
    a = joint.triplet_marginals(post, samples=300, seed=0, floor=0.0)
    b = joint.triplet_marginals(post, samples=300, seed=0, floor=0.01)
    assert np.allclose(b.probabilities, 0.99 * a.probabilities + 0.01 / 20)
    assert np.allclose(a.probabilities.sum(1), 1)


def test_same_seed_same_answer():
    run = _run(11)
    meas = joint.simulated_measurements(run)
    a = joint.triplet_marginals(joint.solve(meas), samples=200, seed=5)
    b = joint.triplet_marginals(joint.solve(meas), samples=200, seed=5)
    assert np.array_equal(a.probabilities, b.probabilities)


@pytest.mark.parametrize("kw, err, name", [
    (dict(times=[1.0, 0.0]), ValueError, "times"),
    (dict(bearing_pose=[0, 3]), ValueError, "bearing_pose"),
    (dict(bearing=[0.1]), ValueError, "bearing"),
    (dict(odometry=[[0.1, 0, 0], [0, 0, 0]]), ValueError, "odometry"),
    (dict(odometry_sigma=None), ValueError, "odometry_sigma"),
    (dict(sigma_bearing=0.0), ValueError, "sigma_bearing"),
])
def test_robot_run_bad_input(kw, err, name):
    base = dict(robot=0, times=[0.0, 1.0], bearing_pose=[0, 1], bearing_landmark=[3, 4],
                bearing=[0.1, 0.2], sigma_bearing=0.01, odometry=[[0.1, 0, 0]],
                odometry_sigma=[[0.01, 0.01, 0.01]])
    base.update(kw)
    with pytest.raises(err, match=name):
        joint.RobotRun(**base)


def test_bad_measurements_and_queries():
    r = joint.RobotRun(0, [0.0, 1.0], [0, 1], [3, 4], [0.1, 0.2], 0.01)
    with pytest.raises(ValueError, match="at least 3 landmarks"):
        joint.JointMeasurements((r,))
    with pytest.raises(ValueError, match="distinct"):
        joint.JointMeasurements((r, r), (3, 4, 5))
    with pytest.raises(ValueError, match="not in the list"):
        joint.JointMeasurements((r,), (3, 5, 6))
    with pytest.raises(ValueError, match="measurements"):
        joint.solve([r])
    post = joint.solve(joint.simulated_measurements(_run(12)))
    with pytest.raises(KeyError, match="99"):
        joint.triplet_marginals(post, [(0, 1, 99)])
    with pytest.raises(ValueError, match="triplets"):
        joint.triplet_marginals(post, [(0, 0, 1)])
    with pytest.raises(ValueError, match="prior_states"):
        joint.triplet_marginals(post, prior_states=np.ones(20))
    with pytest.raises(KeyError, match="robot"):
        joint.camera_marginals(post, 7, [0], [(0, 1, 2)])


def test_camera_states_of_a_known_configuration():
    run = _run(13, sigma_bearing=np.deg2rad(0.02), sigma_heading=np.deg2rad(0.05),
               sigma_step=0.001, sigma_turn=np.deg2rad(0.05))
    post = joint.solve(joint.simulated_measurements(run))
    tri = [(0, 1, 2)] * run.n_poses
    res = joint.camera_marginals(post, 0, np.arange(run.n_poses), tri, samples=200, seed=0)
    assert (res.method, res.partition, res.info["robot"]) == ("joint", "edc", 0)
    assert res.triplets == tuple(tri) and np.array_equal(res.info["pose_index"],
                                                         np.arange(run.n_poses))
    P = res.probabilities
    A, B = run.landmarks[0], run.landmarks[1]
    g = EDC.state_of(joint_states._safe_frame(run.poses[:, :2], A, B))
    assert np.mean(P.argmax(1) == g) >= 0.9


# ----------------------------------------------------------------------------- MRCLAM
def _mrclam_dir():
    root = os.environ.get("QFG_MRCLAM_DIR") or str(Path(__file__).resolve().parents[2]
                                                     / "shared" / "data" / "mrclam")
    d = Path(root) / "MRCLAM_Dataset6"
    return d if d.is_dir() else None


@pytest.mark.skipif(_mrclam_dir() is None, reason="MRCLAM dataset 6 not present")
def test_mrclam_runs_keep_requested_views_and_odometry_matches_dead_reckoning():
    from qfg.datasets import mrclam

    ds = mrclam.load(_mrclam_dir())
    rd = ds.robot(2)
    want = rd.view_times[np.flatnonzero(rd.visible.any(1))[[10, 11, 12]]]
    meas = mrclam_runs(ds, [2, 3], keep_times={2: set(want.tolist())})
    run = meas.run(2)
    assert set(want.tolist()) <= set(run.times.tolist())
    P, _ = mrclam.view_poses(rd)
    idx = np.searchsorted(rd.view_times, run.times)
    chain = joint_start.chain(P[idx[0]], run.odometry)
    assert np.allclose(chain[:, :2], P[idx, :2], atol=1e-9)
    assert meas.landmark_ids == tuple(int(x) for x in ds.landmark_ids)
    with pytest.raises(KeyError, match="robot"):
        meas.run(9)


@pytest.mark.skipif(_mrclam_dir() is None, reason="MRCLAM dataset 6 not present")
def test_mrclam_runs_min_interval_thins_the_images_in_time():
    from qfg.datasets import mrclam

    ds = mrclam.load(_mrclam_dir())
    full = mrclam_runs(ds, [2]).run(2)
    thin = mrclam_runs(ds, [2], min_interval=24.0).run(2)
    assert np.diff(thin.times).min() >= 24.0
    assert set(thin.times.tolist()) <= set(ds.robot(2).view_times.tolist())
    # about one image per 24 s of the run, far fewer than the motion keyframes
    span = full.times[-1] - full.times[0]
    assert span / 24.0 / 2 <= thin.n_poses <= span / 24.0 + 1 < full.n_poses / 10
    # the odometry still chains the kept poses as dead reckoning does
    P, _ = mrclam.view_poses(ds.robot(2))
    idx = np.searchsorted(ds.robot(2).view_times, thin.times)
    assert np.allclose(joint_start.chain(P[idx[0]], thin.odometry)[:, :2], P[idx, :2], atol=1e-9)
    # a view to be scored is kept however close it is
    want = float(full.times[5])
    kept = mrclam_runs(ds, [2], min_interval=24.0, keep_times={2: {want}}).run(2)
    assert want in set(kept.times.tolist())
    with pytest.raises(ValueError, match="min_interval"):
        mrclam_runs(ds, [2], min_interval=-1)


@pytest.mark.skipif(_mrclam_dir() is None or not (_mrclam_dir().parent / "MRCLAM_Dataset5").is_dir(),
                    reason="MRCLAM dataset 5 not present")
def test_mrclam_dataset_without_odometry_skipped_says_the_pipeline_must_answer():
    from qfg.datasets import mrclam

    ds = mrclam.load(_mrclam_dir().parent / "MRCLAM_Dataset5")
    q = np.full(20, 0.05)
    res = mrclam_marginals(ds, [(6, 7, 8)], prior_states=q, samples=50,
                           params=joint.SolveParams(without_odometry="skip"))
    assert res.method == "none" and "no_odometry" in res.posterior.flags
    assert set(res.posterior.robot_flags.values()) == {"no_odometry"}
    assert res.triplets.method == "joint" and np.allclose(res.triplets[(6, 7, 8)], q)


@pytest.mark.skipif(_mrclam_dir() is None or not (_mrclam_dir().parent / "MRCLAM_Dataset5").is_dir(),
                    reason="MRCLAM dataset 5 not present")
def test_mrclam_runs_min_interval_without_odometry():
    from qfg.datasets import mrclam

    ds = mrclam.load(_mrclam_dir().parent / "MRCLAM_Dataset5")
    every = mrclam_runs(ds, [1]).run(1)
    thin = mrclam_runs(ds, [1], min_interval=10.0).run(1)
    assert thin.odometry is None and np.diff(thin.times).min() >= 10.0
    assert set(thin.times.tolist()) <= set(every.times.tolist())
    # greedy in time: the next image of the full set 10 s or more after a kept one is kept
    nxt = every.times[np.searchsorted(every.times, thin.times[:-1] + 10.0)]
    assert np.array_equal(nxt, thin.times[1:])



@pytest.mark.skipif(_mrclam_dir() is None, reason="MRCLAM dataset 6 not present")
def test_mrclam_runs_odometry_noise_grows_with_the_path_between_keyframes():
    from qfg.datasets import mrclam

    ds = mrclam.load(_mrclam_dir())
    rd = ds.robot(3)
    ratio = {}
    for gap in (0.0, 40.0):
        net = mrclam_runs(ds, [3], min_interval=gap).run(3)
        path = mrclam_runs(ds, [3], min_interval=gap, noise_by_path=True).run(3)
        assert np.array_equal(net.times, path.times) and np.allclose(net.odometry, path.odometry)
        # the net-step model is what odometry_steps gives without the path
        P, _ = mrclam.view_poses(rd)
        idx = np.searchsorted(rd.view_times, net.times)
        assert np.allclose(net.odometry_sigma, joint.odometry_steps(P[idx])[1])
        # never below the net step's noise; the path's length from the velocity log
        assert (path.odometry_sigma >= net.odometry_sigma - 1e-12).all()
        tr = np.diff(rd.odometry.travelled(net.times - mrclam.DEFAULT_ODOMETRY_LEAD), axis=0)
        c = joint.ODOMETRY_NOISE
        want = c["c0"][0] + c["c_turn"][0] * np.maximum(tr[:, 1], np.abs(net.odometry[:, 2])) \
            + c["c_dist"][0] * np.maximum(tr[:, 0], np.hypot(*net.odometry[:, :2].T))
        assert np.allclose(path.odometry_sigma[:, 0], want)
        ratio[gap] = path.odometry_sigma[:, 0] / net.odometry_sigma[:, 0]
    # keyframes every 2 cm or 1 deg: path and step agree; 40 s apart the robot wanders between
    assert np.percentile(ratio[0.0], 99) < 1.1
    assert np.median(ratio[40.0]) > 1.15 and np.percentile(ratio[40.0], 90) > 2


def test_overdispersion_is_reported_not_acted_on_when_every_run_has_odometry():
    rng = np.random.default_rng(3)
    a = random_trajectory_run(rng, n_landmarks=6, n_poses=40, fov_deg=360)
    b = random_trajectory_run(rng, n_poses=40, fov_deg=360, landmarks=a.landmarks)
    runs = tuple(joint.simulated_measurements(r, robot=k).runs[0] for k, r in enumerate((a, b)))
    post = joint.solve(joint.JointMeasurements(runs, tuple(range(6))))
    kappa = post.info["overdispersion"]
    assert np.isfinite(kappa) and kappa == joint.overdispersion(post, [0, 1], seed=0)
    # the covariance is the Laplace approximation as is, whatever the scatter
    assert post.info["covariance_scale"] == 1.0 and "overdispersed" not in post.flags
    widened = joint.scale_covariance(post, 3.0)
    assert joint.overdispersion(widened, [0, 1], seed=0) == pytest.approx(kappa / 3.0, rel=0.05)
    lone = joint.solve(joint.JointMeasurements(runs[:1], tuple(range(6))))
    assert "overdispersion" not in lone.info


@pytest.mark.skipif(_mrclam_dir() is None, reason="MRCLAM dataset 6 not present")
def test_mrclam_reference_puts_the_ground_truth_at_the_maps_poses_and_points():
    from qfg.datasets import mrclam
    from qfg.geometry import bearing, wrap_angle

    ds = mrclam.load(_mrclam_dir())
    meas = mrclam_runs(ds, [2, 3], min_interval=24.0)
    post = joint.solve(meas, seed=0)
    ref = mrclam_reference(ds, post, meas)
    with pytest.raises(ValueError, match="robot 2 has .* poses"):
        mrclam_reference(ds, post, mrclam_runs(ds, [2, 3]))
    assert ref.robot(1).groundtruth is None and ds.robot(1).groundtruth is not None
    placed = np.isfinite(post.points).all(1)
    cols = ds.landmark_index(np.array(post.landmark_ids)[placed])
    assert np.allclose(ref.landmark_xy[cols], post.points[placed])
    for n in (2, 3):
        run = meas.run(n)
        P, ok = ref.robot(n).groundtruth_poses(run.times)
        assert ok.all() and np.allclose(P, post.poses[n])
        # the measured bearings against the reference are the map's own residuals, computed
        # here from the posterior directly
        k = placed[post.index(run.bearing_landmark)]
        pose, lm = run.bearing_pose[k], run.bearing_landmark[k]
        own = wrap_angle(run.bearing[k] - bearing(post.poses[n][pose],
                                                  post.points[post.index(lm)]))
        rd = ref.robot(n)
        v = np.searchsorted(rd.view_times, run.times)[pose]
        col = ref.landmark_index(lm)
        got = wrap_angle(rd.view_bearings[v, col] - bearing(P[pose], ref.landmark_xy[col]))
        assert k.sum() > 20 and np.allclose(got, own, atol=1e-9) and rd.visible[v, col].all()
    unplaced = ds.landmark_index(np.array(post.landmark_ids)[~placed])
    assert unplaced.size and not any(r.visible[:, unplaced].any() for r in ref.robots.values())
    m = mrclam.measure_noise(ref, offsets=[0.0])
    assert set(m.robots) == {2, 3} and m.bearing.n > 0
    # aligned onto the landmarks' ground truth: the least-squares similarity's normal
    # equations hold (errors sum to zero, and are orthogonal to the centred map points and to
    # their quarter-turns: translation, scale and rotation optimal); the same bearing
    # residuals (a similarity keeps every angle)
    al = mrclam_reference(ds, post, meas, align=True)
    X = al.landmark_xy[cols]
    e, X0 = X - ds.landmark_xy[cols], X - X.mean(0)
    assert np.allclose(e.sum(0), 0, atol=1e-9) and abs(np.sum(X0 * e)) < 1e-9
    assert abs(np.sum(X0[:, 0] * e[:, 1] - X0[:, 1] * e[:, 0])) < 1e-9
    ma = mrclam.measure_noise(al, offsets=[0.0])
    assert ma.bearing.n == m.bearing.n and np.isclose(ma.bearing.robust_std, m.bearing.robust_std)
    assert np.isclose(ma.heading_step.sigma90, m.heading_step.sigma90)
