"""qfg.joint.start: the starts of the joint solve, and runs without odometry solved with the
kinematic prior and checked against each other (against loops, closed forms and the truth of
simulated worlds)."""

import dataclasses
import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from qfg import joint
from qfg.geometry import to_frame, wrap_angle
from qfg.joint import start as joint_start
from qfg.metrics import log_score
from qfg.partitions import get as get_partition
from qfg.simulation import random_trajectory_run

EDC = get_partition("edc")
#: the simulator's motion (0.3 m per pose, 1 s apart, turns of 20 degrees sd) as a prior
SIM = joint_start.KinematicPrior(speed=0.3, sigma_speed=0.05, sigma_lateral=0.02,
                                 sigma_turn=0.4)


def _loop_visual_steps(r, prior):
    """The definition, one image pair at a time (a landmark's last bearing in an image)."""
    by_pose = {}
    for p, lm, b in zip(r.bearing_pose.tolist(), r.bearing_landmark.tolist(),
                        r.bearing.tolist(), strict=True):
        by_pose.setdefault(p, {})[lm] = b
    dth = np.zeros(r.n_poses - 1)
    for i in range(r.n_poses - 1):
        a, b = by_pose.get(i, {}), by_pose.get(i + 1, {})
        common = set(a) & set(b)
        if common:
            dth[i] = -np.median([wrap_angle(b[k] - a[k]) for k in common])
    z = prior.steps(np.diff(r.times))[0]
    z[:, 2] = dth
    return z


@pytest.mark.parametrize("seed", range(4))
def test_visual_steps_equal_the_loop_over_image_pairs(seed):
    rng = np.random.default_rng(seed)
    n = 60
    pose = np.sort(rng.integers(0, n, 400))
    lm = rng.choice([3, 7, 11, 40, 41], 400)      # repeats within an image, gaps between
    r = joint.RobotRun(robot=1, times=np.cumsum(rng.uniform(0.1, 2, n)), bearing_pose=pose,
                       bearing_landmark=lm, bearing=rng.uniform(-np.pi, np.pi, 400),
                       sigma_bearing=0.01)
    np.testing.assert_allclose(joint_start.visual_steps(r), _loop_visual_steps(r, joint_start.KINEMATIC),
                               atol=1e-12)


def test_visual_steps_recover_a_pure_rotation():
    # a camera turning on the spot: every bearing turns by minus the turn
    L = np.array([[3.0, 0], [0, 4], [-2, -1]])
    th = np.cumsum(np.r_[0, np.deg2rad([5, -3, 10])])
    b = wrap_angle(np.arctan2(L[:, 1], L[:, 0])[None, :] - th[:, None])
    r = joint.RobotRun(robot=0, times=np.arange(4.0), bearing_pose=np.repeat(np.arange(4), 3),
                       bearing_landmark=np.tile([0, 1, 2], 4), bearing=b.ravel(),
                       sigma_bearing=0.01)
    np.testing.assert_allclose(joint_start.visual_steps(r)[:, 2], np.diff(th), atol=1e-12)


@given(st.floats(0.1, 10), st.floats(-np.pi, np.pi), st.floats(-5, 5), st.floats(-5, 5),
       st.integers(0, 2 ** 32 - 1))
def test_similarity_recovers_the_transform_and_misfit_is_invariant(s, a, tx, ty, seed):
    A = np.random.default_rng(seed).normal(size=(6, 2))
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    B = s * A @ R.T + [tx, ty]
    s2, R2, t2 = joint_start.similarity(A, B)
    assert s2 == pytest.approx(s, rel=1e-9)
    np.testing.assert_allclose(R2, R, atol=1e-9)
    np.testing.assert_allclose(t2, [tx, ty], atol=1e-8 * max(1, s))
    assert joint_start.shape_misfit(A, B) < 1e-9 and joint_start.shape_misfit(B, A) < 1e-9
    # rigid: no scale
    assert joint_start.similarity(A, B, scale=False)[0] == 1.0


def test_similarity_of_a_stack_is_each_fit_and_recovers_each_transform():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(5, 7, 2))
    a, s = rng.uniform(-np.pi, np.pi, 5), rng.uniform(0.2, 5, 5)
    R = np.stack([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]).transpose(2, 0, 1)
    B = s[:, None, None] * np.einsum("kij,knj->kni", R, A) + rng.normal(size=(5, 1, 2))
    B += rng.normal(0, 0.05, B.shape)              # not exact: each fit is a least squares
    s2, R2, t2 = joint_start.similarity(A, B)
    for k in range(5):
        sk, Rk, tk = joint_start.similarity(A[k], B[k])
        assert s2[k] == pytest.approx(sk, rel=1e-12)
        np.testing.assert_allclose(R2[k], Rk, atol=1e-12)
        np.testing.assert_allclose(t2[k], tk, atol=1e-12)
    # exact copies: the transforms themselves; one target broadcast against the stack
    s3, R3, _ = joint_start.similarity(np.stack([A[0] * 3, A[0] @ R[1].T]), A[0])
    np.testing.assert_allclose(s3, [1 / 3, 1.0], rtol=1e-12)
    np.testing.assert_allclose(R3[1], R[1].T, atol=1e-12)


def test_a_mirror_image_or_a_moved_landmark_does_not_fit():
    A = np.random.default_rng(0).normal(size=(8, 2))
    assert joint_start.shape_misfit(A * [1, -1], A) > 0.1      # no reflections
    B = A.copy()
    B[:5] += np.random.default_rng(1).normal(0, 0.5, (5, 2))    # most landmarks moved
    assert joint_start.shape_misfit(B, A) > joint_start.AGREE


@pytest.mark.parametrize("seed", range(6))
def test_agreeing_group_is_the_largest_pairwise_agreeing_set(seed):
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(7, 2))
    maps = {}
    for k in range(6):
        a, s = rng.uniform(-np.pi, np.pi), rng.uniform(0.5, 2)
        R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        m = s * base @ R.T + rng.normal(size=2) + rng.normal(0, rng.choice([0.001, 0.3]), (7, 2))
        m[rng.random(7) < 0.15] = np.nan          # landmarks a robot did not place
        maps[k + 1] = m

    def agree(i, j):
        m = np.isfinite(maps[i]).all(1) & np.isfinite(maps[j]).all(1)
        return m.sum() >= 4 and max(joint_start.shape_misfit(maps[i][m], maps[j][m]),
                                    joint_start.shape_misfit(maps[j][m], maps[i][m])) <= 0.05
    brute = ()
    for k in range(len(maps), 1, -1):
        for g in itertools.combinations(sorted(maps), k):
            if all(agree(i, j) for i, j in itertools.combinations(g, 2)):
                brute = g
                break
        if brute:
            break
    assert joint_start.agreeing_group(maps, 0.05) == brute


def _world(seed, n_robots, n_poses=150):
    rng = np.random.default_rng(seed)
    first = random_trajectory_run(rng, n_landmarks=6, n_poses=n_poses, fov_deg=360,
                                  sigma_bearing=np.deg2rad(1))
    runs = [first] + [random_trajectory_run(rng, n_poses=n_poses, fov_deg=360,
                                            sigma_bearing=np.deg2rad(1),
                                            landmarks=first.landmarks)
                      for _ in range(n_robots - 1)]
    meas = [joint.simulated_measurements(r, odometry=False, robot=k).runs[0]
            for k, r in enumerate(runs)]
    return meas, first.landmarks


def _truth_score(post, L):
    res = joint.triplet_marginals(post, samples=500, seed=0)
    tri = np.array(res.triplets)
    s = EDC.state_of(to_frame(L[tri[:, 2]], L[tri[:, 0]], L[tri[:, 1]]))
    return log_score(np.asarray(res.probabilities), s)


def test_robots_without_odometry_make_a_map_with_the_kinematic_prior():
    meas, L = _world(0, 2)
    post = joint.solve(joint.JointMeasurements(tuple(meas), tuple(range(6))),
                       joint.SolveParams(kinematic=SIM, kinematic_chunks=(10, 20, 40)))
    assert post.method == "joint" and "kinematic_prior" in post.flags
    assert post.robot_flags == {0: "kinematic", 1: "kinematic"}
    assert set(post.info["kinematic_starts"]) == {0, 1}
    ls = _truth_score(post, L)
    # every triplet far sharper than the prior (-3.0 uniform) and none confidently wrong
    assert ls.mean() > -0.2 and np.mean(ls < np.log(0.01)) == 0


def test_a_robot_whose_map_disagrees_is_left_out_unverified():
    meas, L = _world(1, 3)
    # robot 2 misreads two landmarks' ids for the whole run: its map has another shape
    r = meas[2]
    lm = r.bearing_landmark.copy()
    lm[r.bearing_landmark == 0], lm[r.bearing_landmark == 3] = 3, 0
    lm[r.bearing_landmark == 1], lm[r.bearing_landmark == 4] = 4, 1
    meas[2] = dataclasses.replace(r, bearing_landmark=lm)
    post = joint.solve(joint.JointMeasurements(tuple(meas), tuple(range(6))),
                       joint.SolveParams(kinematic=SIM, kinematic_chunks=(10, 20, 40)))
    assert post.robot_flags == {0: "kinematic", 1: "kinematic", 2: "unverified"}
    assert "unverified" in post.flags and post.method == "joint"
    assert _truth_score(post, L).mean() > -0.2
    # without the check the robot enters the joint solve, whose residual check drops it here
    # (a wrong minimum of the whole run does not always show in the residuals: docs/joint.md)
    loose = joint.solve(joint.JointMeasurements(tuple(meas), tuple(range(6))),
                        joint.SolveParams(kinematic=SIM, kinematic_chunks=(10, 20, 40),
                                          agree=None))
    assert loose.robot_flags[2] == "local_minimum"


def test_the_kinematic_covariance_factor_scales_only_maps_with_a_run_without_odometry():
    meas, _ = _world(0, 2)
    m = joint.JointMeasurements(tuple(meas), tuple(range(6)))
    kw = dict(kinematic=SIM, kinematic_chunks=(20,))
    one = joint.solve(m, joint.SolveParams(inflate_kinematic=1.0, **kw))
    four = joint.solve(m, joint.SolveParams(inflate_kinematic=4.0, **kw))
    # the same fit (deterministic), its covariance times the factor
    np.testing.assert_array_equal(one.points, four.points)
    np.testing.assert_allclose(four.modes[0].covariance, 4.0 * one.modes[0].covariance,
                               rtol=1e-12)
    assert (one.info["covariance_scale"], four.info["covariance_scale"]) == (1.0, 4.0)
    # a map from runs with odometry is left as it is
    rng = np.random.default_rng(3)
    run = random_trajectory_run(rng, n_landmarks=5, n_poses=30, fov_deg=360)
    odo = joint.simulated_measurements(run)
    a, b = joint.solve(odo, seed=0), joint.solve(odo, joint.SolveParams(inflate_kinematic=4.0), seed=0)
    np.testing.assert_array_equal(a.modes[0].covariance, b.modes[0].covariance)
    assert b.info["covariance_scale"] == 1.0


def _posterior_with_robot_maps(seed, c, K=3, L=7, sigma=0.01):
    """A Gaussian joint map (iid landmark covariance sigma^2) and K robots' own maps drawn
    about it with covariance (K - 1) (c sigma)^2: the scatter a calibrated map of K equal robots
    would show, times c^2 in variance."""
    rng = np.random.default_rng(seed)
    P = rng.uniform(0.0, 5.0, (L, 2))
    maps = {r: P + rng.normal(0.0, c * sigma * np.sqrt(K - 1), (L, 2)) for r in range(K)}
    mode = joint.Mode(1.0, P, sigma ** 2 * np.eye(2 * L), 0.0)
    return joint.JointPosterior(tuple(range(L)), (mode,), np.ones(L, bool), ("ok",) * L,
                                dict.fromkeys(range(K), "kinematic"), (), "joint", {},
                                {"robot_maps": maps})


@pytest.mark.parametrize("c", [1.0, 3.0])
def test_overdispersion_measures_the_scatter_the_covariance_leaves_out(c):
    # with the scatter injected by hand, kappa is c^2 (the AB frame linear at this sigma);
    # the median over 3 x 210 triplets of correlated draws: within 35 %
    ks = [joint.overdispersion(_posterior_with_robot_maps(s, c), samples=2000, seed=s)
          for s in range(4)]
    assert 0.65 * c * c < np.median(ks) < 1.35 * c * c
    # one robot, or robots with no landmark placed: nothing to compare
    post = _posterior_with_robot_maps(0, c)
    assert np.isnan(joint.overdispersion(post, robots=[0]))
    empty = dataclasses.replace(post, info={"robot_maps": {
        r: np.full((7, 2), np.nan) for r in range(3)}})
    assert np.isnan(joint.overdispersion(empty))
    # scale_covariance: every covariance times the factor, nothing else
    big = joint.scale_covariance(post, 9.0)
    np.testing.assert_array_equal(big.modes[0].covariance, 9.0 * post.modes[0].covariance)
    np.testing.assert_array_equal(big.points, post.points)
    with pytest.raises(ValueError, match="factor"):
        joint.scale_covariance(post, 0.0)


def test_ab_frame_moments_are_the_linearised_gaussian_at_small_covariance():
    post = _posterior_with_robot_maps(0, 1.0, sigma=1e-3)
    P = post.points
    tri = [(0, 1, 2), (3, 5, 6), (6, 2, 0)]
    mu, cov = joint.ab_frame_moments(post, tri, samples=4000, seed=1)
    for t, m, c in zip(tri, mu, cov, strict=True):
        # the Jacobian of C's AB-frame position in the three points, by central differences
        x0 = P[list(t)].ravel()
        f = lambda x: to_frame(x[4:6], x[0:2], x[2:4])  # noqa: E731
        Jac = np.column_stack([(f(x0 + h) - f(x0 - h)) / 2e-7
                               for h in 1e-7 * np.eye(6)])
        lin = Jac @ (1e-6 * np.eye(6)) @ Jac.T
        np.testing.assert_allclose(m, f(x0), atol=5 * np.sqrt(np.trace(lin) / 4000))
        np.testing.assert_allclose(c, lin, rtol=0.15, atol=0.15 * np.abs(lin).max())
    # an unconstrained landmark: NaN, not a guess
    keep = np.arange(7) != 2
    m = post.modes[0]
    cols = np.repeat(keep, 2)
    loose = dataclasses.replace(post, constrained=keep, modes=(dataclasses.replace(
        m, covariance=m.covariance[np.ix_(cols, cols)]),))
    mu2, _ = joint.ab_frame_moments(loose, tri, samples=50, seed=1)
    assert np.isnan(mu2[[0, 2]]).all() and np.isfinite(mu2[1]).all()
    with pytest.raises(ValueError, match="triplets"):
        joint.ab_frame_moments(post, [(0, 0, 1)])


def test_landmark_moments_remove_the_gauge_and_keep_the_shape():
    # a Gaussian map whose covariance is iid sigma^2 plus a large gauge part (moves of the
    # whole map: translations, and (x, y) -> (1 + b + i a)(x, y), exact similarities). Aligned
    # by similarity (4 dof) the shape's total variance is (2 L - 4) sigma^2 (the iid noise
    # projected off the similarities' tangent space), whatever the gauge adds (its scale kept
    # near 1: a map drawn at scale k has its noise at k sigma in the aligned frame).
    L, sigma = 7, 1e-3
    post = _posterior_with_robot_maps(2, 1.0, L=L, sigma=sigma)
    P = post.points
    X = P - P.mean(0)
    G = np.column_stack([np.tile([1.0, 0.0], L), np.tile([0.0, 1.0], L),
                         np.column_stack([-X[:, 1], X[:, 0]]).ravel(), X.ravel()])
    gauge = G @ np.diag([0.5, 0.5, 0.02, 0.02]) ** 2 @ G.T
    m = post.modes[0]
    post = dataclasses.replace(post, modes=(dataclasses.replace(
        m, covariance=m.covariance + gauge),))
    mu, cov = joint.landmark_moments(post, samples=4000, seed=1)
    raw = joint.sample_landmarks(post, 4000, seed=1)
    raw_total = sum(np.trace(np.cov(raw[:, k].T)) for k in range(L))
    total = np.trace(cov, axis1=1, axis2=2).sum()
    assert total == pytest.approx((2 * L - 4) * sigma ** 2, rel=0.06)
    assert raw_total > 1e3 * total
    np.testing.assert_allclose(mu, P, atol=5 * sigma / np.sqrt(4000))
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    # an unconstrained landmark: NaN; a map of two landmarks: no shape at all
    keep = np.arange(L) != 4
    cols = np.repeat(keep, 2)
    loose = dataclasses.replace(post, constrained=keep, modes=(dataclasses.replace(
        m, covariance=m.covariance[np.ix_(cols, cols)]),))
    mu2, cov2 = joint.landmark_moments(loose, samples=50, seed=1)
    assert np.isnan(mu2[4]).all() and np.isnan(cov2[4]).all() and np.isfinite(mu2[keep]).all()
    two = np.arange(L) < 2
    cols = np.repeat(two, 2)
    pair = dataclasses.replace(post, constrained=two, modes=(dataclasses.replace(
        m, covariance=m.covariance[np.ix_(cols, cols)]),))
    assert np.isnan(joint.landmark_moments(pair, samples=50)[0]).all()
    # against a truth: the map's own gauge (x2, turned, moved) is not an error
    truth = P + rng_err(L)
    Q = np.array([[0.0, -1.0], [1.0, 0.0]])
    err, C, z2, (s, R, t) = joint.aligned_errors(2 * mu @ Q.T + 7,
                                                 4 * np.einsum("ij,kjl,ml->kim", Q, cov, Q), truth)
    np.testing.assert_allclose(err, joint.aligned_errors(mu, cov, truth)[0], atol=1e-12)
    np.testing.assert_allclose(z2, joint.aligned_errors(mu, cov, truth)[2], rtol=1e-9)
    assert s == pytest.approx(0.5 * joint.aligned_errors(mu, cov, truth)[3][0], rel=1e-12)
    with pytest.raises(ValueError, match="at least 3"):
        joint.aligned_errors(mu[:2], cov[:2], truth[:2])
    with pytest.raises(ValueError, match="covariance, truth"):
        joint.aligned_errors(mu, cov[:3], truth)


def rng_err(L):
    return np.random.default_rng(5).normal(0, 1e-3, (L, 2))


def test_auto_inflation_widens_by_the_measured_overdispersion():
    meas, _ = _world(0, 2)
    m = joint.JointMeasurements(tuple(meas), tuple(range(6)))
    kw = dict(kinematic=SIM, kinematic_chunks=(20,))
    one = joint.solve(m, joint.SolveParams(inflate_kinematic=1.0, **kw))
    auto = joint.solve(m, joint.SolveParams(inflate_kinematic="auto", **kw))
    kappa = auto.info["overdispersion"]
    assert kappa == joint.overdispersion(one, [0, 1], seed=0)
    assert auto.info["covariance_scale"] == max(1.0, kappa)
    np.testing.assert_allclose(auto.modes[0].covariance,
                               max(1.0, kappa) * one.modes[0].covariance, rtol=1e-12)
    assert ("overdispersed" in auto.flags) == (kappa > joint.OVERDISPERSED)
    with pytest.raises(ValueError, match="inflate_kinematic"):
        joint.SolveParams(inflate_kinematic="twice", **kw)


def test_bad_options_are_refused_by_name():
    meas, _ = _world(2, 1, n_poses=10)
    with pytest.raises(ValueError, match="without_odometry"):
        joint.SolveParams(without_odometry="ignore")
    with pytest.raises(ValueError, match="kinematic"):
        joint.SolveParams(kinematic={"speed": 1})
    with pytest.raises(ValueError, match="inflate_kinematic"):
        joint.SolveParams(inflate_kinematic=-1.0)
    with pytest.raises(ValueError, match="kinematic_chunks"):
        joint.SolveParams(kinematic_chunks=(1,))
    with pytest.raises(ValueError, match="sigma_turn"):
        joint_start.KinematicPrior(sigma_turn=-1)
    with pytest.raises(ValueError, match="c_xy"):
        joint_start.KinematicPrior(c_xy=0)
    with pytest.raises(ValueError, match="kinematic prior"):
        joint_start.kinematic_start(meas[0], {i: i for i in range(6)})


def test_ab_frame_z2_is_chi_square_for_a_draw_from_the_posterior():
    # positions drawn from the (linear, at this sigma) posterior itself: z^2 ~ chi-square(2),
    # median 1.39; the same z^2 as e' C^-1 e with numpy's inverse; another frame changes nothing
    post = _posterior_with_robot_maps(0, 1.0, sigma=1e-3)
    tri = [tuple(int(x) for x in t) for t in
           np.random.default_rng(1).permutation(np.array(list(itertools.permutations(range(7), 3)))
                                                )[:60]]
    z = np.concatenate([joint.ab_frame_z2(
        post, post.points + np.random.default_rng(s).normal(0, 1e-3, (7, 2)), tri, 4000, 0)
        for s in range(6)])
    assert 1.0 < np.median(z) < 1.9
    X = post.points + np.random.default_rng(9).normal(0, 1e-3, (7, 2))
    mu, cov = joint.ab_frame_moments(post, tri, 4000, 0)
    t = np.array(tri)
    e = to_frame(X[t[:, 2]], X[t[:, 0]], X[t[:, 1]]) - mu
    want = np.einsum("ti,tij,tj->t", e, np.linalg.inv(cov), e)
    np.testing.assert_allclose(joint.ab_frame_z2(post, X, tri, 4000, 0), want, rtol=1e-9)
    R = np.array([[0.6, -0.8], [0.8, 0.6]])
    np.testing.assert_allclose(joint.ab_frame_z2(post, 3.0 * X @ R.T + 1.0, tri, 4000, 0), want,
                               rtol=1e-6)
    with np.errstate(invalid="ignore"):
        missing = X.copy()
        missing[4] = np.nan
        zm = joint.ab_frame_z2(post, missing, [(0, 1, 4), (0, 1, 2)], 500, 0)
    assert np.isnan(zm[0]) and np.isfinite(zm[1])
    with pytest.raises(ValueError, match="positions"):
        joint.ab_frame_z2(post, X[:5], tri)


def test_landmark_ellipses_hold_the_truth_as_often_as_they_claim_in_simulation():
    # one robot with odometry, paper noise, 40 drawn runs: every truth's squared Mahalanobis
    # distance under the gauge-free covariance, both aligned over the same landmarks
    # (aligned_errors). Calibrated: chi-square with 2 dof (median 1.39, 95 % under 5.99).
    # Measured: 68 landmarks, median 1.15, 95.6 % inside; a covariance of half or twice the
    # variance it should have would put the median at 2.3 or 0.58 (z^2 scales inversely).
    z = []
    for seed in range(40):
        run = random_trajectory_run(np.random.default_rng(seed), n_landmarks=8, n_poses=40,
                                    fov_deg=150)
        post = joint.solve(joint.simulated_measurements(run), seed=0)
        mu, cov = joint.landmark_moments(post, 1000, seed)
        f = np.isfinite(mu).all(axis=1)
        if f.sum() < 3:
            continue
        _, _, z2, _ = joint.aligned_errors(mu[f], cov[f], run.landmarks[f])
        z += z2[np.array([x == "ok" for x in post.landmark_flags])[f]].tolist()
    z = np.array(z)
    assert z.size >= 50
    assert 0.9 < np.median(z) < 2.0
    assert 0.88 <= np.mean(z <= 5.991) <= 0.995
