"""Geometry: frames, bearings, locus circles, intersections, triangulation."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qfg import geometry as g

seeds = st.integers(0, 2**32 - 1)


def _similarity(rng):
    theta = rng.uniform(-np.pi, np.pi)
    s = rng.uniform(0.2, 5.0)
    t = rng.uniform(-10, 10, 2)
    R = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    return theta, s, t, R


@given(seeds)
@settings(max_examples=50, deadline=None)
def test_bearings_and_headings_invariant_under_similarity(seed):
    rng = np.random.default_rng(seed)
    L = rng.uniform(-3, 3, (5, 2))
    P = np.column_stack([rng.uniform(-3, 3, (4, 2)), rng.uniform(-np.pi, np.pi, 4)])
    phi = g.bearing(P[:, None, :], L[None])
    psi = g.motion_heading(P[:-1], P[1:, :2])
    theta, s, t, R = _similarity(rng)
    L2 = s * L @ R.T + t
    P2 = np.column_stack([s * P[:, :2] @ R.T + t, P[:, 2] + theta])
    np.testing.assert_allclose(g.wrap_angle(g.bearing(P2[:, None, :], L2[None]) - phi), 0, atol=1e-9)
    np.testing.assert_allclose(g.wrap_angle(g.motion_heading(P2[:-1], P2[1:, :2]) - psi), 0,
                               atol=1e-9)


@given(seeds)
@settings(max_examples=50, deadline=None)
def test_frame_round_trip_and_definition(seed):
    rng = np.random.default_rng(seed)
    A, B = rng.uniform(-3, 3, (2, 2))
    if np.linalg.norm(A - B) < 1e-3:
        return
    np.testing.assert_allclose(g.to_frame(A, A, B), [0, 0], atol=1e-9)
    np.testing.assert_allclose(g.to_frame(B, A, B), [0, 1], atol=1e-9)
    pts = rng.uniform(-5, 5, (10, 2))
    np.testing.assert_allclose(g.from_frame(g.to_frame(pts, A, B), A, B), pts, atol=1e-9)
    poses = np.column_stack([pts, rng.uniform(-np.pi, np.pi, 10)])
    back = g.poses_from_frame(g.poses_to_frame(poses, A, B), A, B)
    np.testing.assert_allclose(back[:, :2], pts, atol=1e-9)
    np.testing.assert_allclose(g.wrap_angle(back[:, 2] - poses[:, 2]), 0, atol=1e-9)
    # distances scale by 1/|AB| and the frame is not mirrored (left stays left)
    d = np.linalg.norm(B - A)
    q = g.to_frame(pts, A, B)
    np.testing.assert_allclose(np.linalg.norm(q[0] - q[1]), np.linalg.norm(pts[0] - pts[1]) / d)
    d_ = B - A
    cross_world = d_[0] * (pts - A)[:, 1] - d_[1] * (pts - A)[:, 0]
    assert np.all(np.sign(cross_world) == -np.sign(q[:, 0]))  # left of AB (ccw) is x < 0


@given(seeds)
@settings(max_examples=50, deadline=None)
def test_bearings_same_in_world_and_frame(seed):
    rng = np.random.default_rng(seed)
    A, B, C = rng.uniform(-3, 3, (3, 2))
    if np.linalg.norm(A - B) < 1e-2:
        return
    P = np.array([*rng.uniform(-3, 3, 2), rng.uniform(-np.pi, np.pi)])
    Pab = g.poses_to_frame(P, A, B)
    for Lw in (A, B, C):
        np.testing.assert_allclose(
            g.wrap_angle(g.bearing(Pab, g.to_frame(Lw, A, B)) - g.bearing(P, Lw)), 0, atol=1e-9)


@given(seeds)
@settings(max_examples=100, deadline=None)
def test_noiseless_locus_circle_passes_through_camera(seed):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-3, 3, 2)
    if min(np.linalg.norm(X), np.abs(X[0])) < 1e-2:
        return  # camera on line AB: degenerate, tested separately
    alpha = rng.uniform(-np.pi, np.pi)
    pose = np.array([*X, alpha])
    phia = g.bearing(pose, [0.0, 0.0])
    phib = g.bearing(pose, [0.0, 1.0])
    c = g.locus_circle(phia, phib)
    assert not c.degenerate
    assert np.linalg.norm(X - c.center) == pytest.approx(float(c.radius), rel=1e-7)
    assert c.side == (1 if X[0] < 0 else -1)
    assert float(g.wrap_angle(g.heading_on_locus(X, phia) - alpha)) == pytest.approx(0, abs=1e-9)
    # the closed-form arc parametrization reaches X at the angle XAB
    a = np.arccos(np.clip(X[1] / np.linalg.norm(X), -1, 1))
    np.testing.assert_allclose(g.locus_point(c.gamma, a), X, atol=1e-7)


def test_locus_point_stays_on_circle_and_arc():
    gam = np.array([0.3, -0.3, 2.5, -2.9])
    c = g.locus_circle(np.zeros(4), gam)
    u = np.linspace(0.01, 0.99, 50)[:, None] * (np.pi - np.abs(gam))[None]
    p = g.locus_point(gam[None], u)
    r = np.linalg.norm(p - c.center[None], axis=-1)
    np.testing.assert_allclose(r, np.broadcast_to(c.radius, r.shape), rtol=1e-9)
    assert np.all(np.sign(p[..., 0]) == -np.sign(gam)[None])


def test_degenerate_locus():
    c = g.locus_circle([0.3, 0.3], [0.3, 0.3 + np.pi])  # equal bearings; opposite bearings
    assert c.degenerate.tolist() == [True, True]
    assert np.all(np.isfinite(c.center)) and np.all(c.side == 0)


@given(seeds)
@settings(max_examples=100, deadline=None)
def test_ray_circle_intersection_points_are_on_circle_and_ray(seed):
    rng = np.random.default_rng(seed)
    o = rng.uniform(-3, 3, 2)
    th = rng.uniform(-np.pi, np.pi)
    c = rng.uniform(-2, 2, 2)
    r = rng.uniform(0.1, 3)
    pts, valid = g.ray_circle_intersection(o, th, c, r)
    u = np.array([np.cos(th), np.sin(th)])
    for k in range(2):
        if valid[k]:
            assert np.linalg.norm(pts[k] - c) == pytest.approx(r, rel=1e-7, abs=1e-9)
            assert np.dot(pts[k] - o, u) > 0
            w_ = pts[k] - o
            assert abs(u[0] * w_[1] - u[1] * w_[0]) < 1e-7
    # brute force: sample the ray densely; a crossing of the circle exists iff some hit is valid
    t = np.linspace(1e-6, 20, 200001)
    ray = o + t[:, None] * u
    dist = np.linalg.norm(ray - c, axis=1) - r
    crosses = np.any(np.sign(dist[1:]) != np.sign(dist[:-1]))
    if crosses:
        assert valid.any()


def test_ray_circle_side_filter_and_misses():
    # circle of radius 1 at origin, horizontal ray through the middle from the left
    pts, valid = g.ray_circle_intersection([-3.0, 0.0], 0.0, [0.0, 0.0], 1.0)
    assert valid.tolist() == [True, True]
    np.testing.assert_allclose(pts, [[-1, 0], [1, 0]], atol=1e-12)
    pts, valid = g.ray_circle_intersection([-3.0, 0.0], 0.0, [0.0, 0.0], 1.0, side=1)
    assert valid.tolist() == [True, False]  # side +1 keeps x < 0
    pts, valid = g.ray_circle_intersection([-3.0, 0.0], np.pi, [0.0, 0.0], 1.0)  # pointing away
    assert not valid.any() and np.all(np.isfinite(pts))
    pts, valid = g.ray_circle_intersection([-3.0, 5.0], 0.0, [0.0, 0.0], 1.0)  # misses
    assert not valid.any()
    pts, valid = g.ray_circle_intersection([0.0, 0.0], 0.0, [0.0, 0.0], np.inf)
    assert not valid.any() and np.all(np.isfinite(pts))


@given(seeds)
@settings(max_examples=100, deadline=None)
def test_triangulation_recovers_point_from_exact_rays(seed):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-3, 3, 2)
    o = rng.uniform(-3, 3, (3, 2))
    ang = np.arctan2(p[1] - o[:, 1], p[0] - o[:, 0])
    if np.min(np.abs(np.sin(ang[:, None] - ang[None]))[np.triu_indices(3, 1)]) < 1e-2:
        return  # near-parallel rays: ill-conditioned
    q, ok = g.triangulate_lsq(o, ang)
    assert ok
    np.testing.assert_allclose(q, p, atol=1e-6)
    q2, ok2, ahead = g.triangulate_pairwise_centroid(o, ang)
    assert ok2 and ahead
    np.testing.assert_allclose(q2, p, atol=1e-6)


def test_triangulation_parallel_rays_flagged():
    o = np.array([[0.0, 0.0], [0.0, 1.0]])
    q, ok = g.triangulate_lsq(o, [0.0, 0.0])
    assert not ok and np.all(np.isfinite(q))
    q2, ok2, ahead = g.triangulate_pairwise_centroid(o, [0.0, 0.0])
    assert not ok2 and not ahead and np.all(np.isfinite(q2))
    # intersection behind a camera
    _, ok3, ahead3 = g.triangulate_pairwise_centroid(o, [np.pi / 4, -np.pi / 4 + np.pi])
    assert ok3 and not ahead3


def test_geometry_bad_input():
    with pytest.raises(ValueError, match="A, B"):
        g.to_frame([1.0, 1.0], [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="poses"):
        g.bearing([0.0, 0.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="non-finite"):
        g.bearing([0.0, np.inf, 0.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="angles"):
        g.triangulate_lsq(np.zeros((3, 2)), np.zeros(2))


def test_wrap_angle_range():
    a = np.linspace(-20, 20, 10001)
    w = g.wrap_angle(a)
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-9)
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-9)
    assert float(g.wrap_angle(-np.pi)) == pytest.approx(np.pi)


def test_to_frame_with_huge_coordinates_and_its_overflow():
    # Scale-invariant: 1e200-sized and 1.7e308-wide inputs give the unit-scale answer.
    np.testing.assert_array_equal(g.to_frame([0.0, 5e199], [1e200, 0.0], [1e200, 1e200]),
                                  [-1.0, 0.5])
    # p - A = (3.4e308, 0) overflows as written; d = (0, 1.7e308): x = 2, y = 0.
    np.testing.assert_allclose(g.to_frame([1.7e308, 0.0], [-1.7e308, 0.0], [-1.7e308, 1.7e308]),
                               [2.0, 0.0], rtol=1e-15)
    # A point 1e300 / 1e-8 = 1e308 units of |B - A| away still fits; 3.4e308 does not: named.
    np.testing.assert_allclose(g.to_frame([1e300, 0.0], [0.0, 0.0], [0.0, 1e-8]), [1e308, 0.0])
    with pytest.raises(ValueError, match="points: .*overflow"):
        g.to_frame([1.7e308, 0.0], [-1.7e308, 0.0], [-1.7e308, 1.0])
    with pytest.raises(ValueError, match="coincide"):
        g.to_frame([1e300, 0.0], [1e300, 1e300], [1e300, 1e300])
