"""Partitions: lookup vs shapely geometry, areas, and the conventions table."""

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from qfg import partitions
from qfg.geometry import from_frame
from qfg.partitions import Partition, state_of_triplet

NAMES = ["edc", "fdc", "lr", "tpcc"]


@pytest.mark.parametrize("name", NAMES)
def test_state_of_agrees_with_shapely_containment(name):
    part = partitions.get(name)
    xmin, xmax, ymin, ymax = part.window
    rng = np.random.default_rng(1)
    pts = rng.uniform([xmin, ymin], [xmax, ymax], size=(20000, 2))
    polys = np.asarray(part.polygons, dtype=object)
    # keep points clearly away from every state boundary (circle polygons deviate by ~5e-6)
    bounds = shapely.boundary(polys)
    d = np.min(shapely.distance(bounds[None, :], shapely.points(pts)[:, None]), axis=1)
    pts = pts[d > 1e-4]
    inside = shapely.contains_xy(polys[None, :], pts[:, 0:1], pts[:, 1:2])  # (N, m)
    assert np.all(inside.sum(axis=1) == 1), "each point lies in exactly one polygon"
    assert np.array_equal(part.state_of(pts), np.argmax(inside, axis=1))


@pytest.mark.parametrize("name", NAMES)
def test_areas_sum_to_window_area(name):
    part = partitions.get(name)
    xmin, xmax, ymin, ymax = part.window
    assert part.areas.sum() == pytest.approx((xmax - xmin) * (ymax - ymin), rel=1e-9)
    assert part.centroids.shape == (part.n_states, 2)
    assert np.all(part.areas > 0)
    # centroids lie inside the window
    assert np.all(part.in_window(part.centroids))


def test_fdc_and_tpcc_windows_give_equal_areas():
    assert np.allclose(partitions.get("fdc").areas, 1.0)
    assert np.allclose(partitions.get("tpcc").areas, np.pi / 8, rtol=1e-4)
    assert np.allclose(partitions.get("lr").areas, 3.0)


# One hand-picked point per EDC state, read off the table in conventions.md (1-based labels).
EDC_POINTS = {
    1: (-0.5, 2.5), 2: (0.5, 2.5), 3: (-0.3, 1.3), 4: (0.3, 1.3),
    5: (-1.5, 0.75), 6: (-0.9, 0.8), 7: (-0.2, 0.75), 8: (0.2, 0.75), 9: (0.9, 0.8), 10: (1.5, 0.75),
    11: (-1.5, 0.25), 12: (-0.9, 0.2), 13: (-0.2, 0.25), 14: (0.2, 0.25), 15: (0.9, 0.2),
    16: (1.5, 0.25), 17: (-0.3, -0.3), 18: (0.3, -0.3), 19: (-1.5, -1.5), 20: (1.5, -1.5),
}


def test_edc_matches_conventions_table():
    edc = partitions.get("edc")
    labels = np.array(list(EDC_POINTS))
    pts = np.array([EDC_POINTS[k] for k in labels])
    assert edc.state_of(pts).tolist() == (labels - 1).tolist()


def test_edc_ties_follow_conventions():
    edc = partitions.get("edc")
    # x = 0 is right; |p - A| = 1 is near A; y = 1 is the top band; y = 0.5 the upper middle band
    assert edc.state_of([0.0, 2.5]) == 1
    assert edc.state_of([0.0, -1.0]) == 17  # near A (dA = 1), right
    assert edc.state_of([-0.3, 1.0]) == 2  # y = 1 -> top band, near B
    assert edc.state_of([1.2, 0.5]) == 9  # y = 0.5 -> upper middle, right, far A far B


def test_tpcc_sectors_and_distance():
    tp = partitions.get("tpcc")
    # straight ahead of B (away from A) slightly left: sector 0, near; far beyond radius 1
    assert tp.state_of([-0.01, 1.5]) == 0
    assert tp.state_of([-0.01, 2.5]) == 8
    # directly left of B: 90 degrees ccw -> sector 2 (lb); right of B: 270 -> sector 6
    assert tp.state_of([-0.5, 1.0]) == 2
    assert tp.state_of([0.5, 1.0 - 1e-9]) == 5
    # towards A, just left of the line: 180 - eps degrees -> sector 3
    assert tp.state_of([-1e-6, 0.5]) == 3


@given(st.floats(-5, 5), st.floats(-5, 5))
@settings(max_examples=200, deadline=None)
def test_state_of_is_a_valid_state(x, y):
    for name in NAMES:
        part = partitions.get(name)
        s = int(part.state_of([x, y]))
        assert 0 <= s < part.n_states


@given(st.integers(0, 2**32 - 1))
@settings(max_examples=30, deadline=None)
def test_state_of_triplet_is_similarity_invariant(seed):
    rng = np.random.default_rng(seed)
    A, B = rng.uniform(-3, 3, (2, 2))
    if np.linalg.norm(A - B) < 0.05:
        return
    C_ab = rng.uniform(-2, 3, (50, 2))
    C = from_frame(C_ab, A, B)
    assert np.array_equal(state_of_triplet(A, B, C), partitions.get("edc").state_of(C_ab))


def test_state_of_shapes_and_errors():
    edc = partitions.get("edc")
    assert edc.state_of(np.zeros((4, 5, 2))).shape == (4, 5)
    with pytest.raises(ValueError, match="points"):
        edc.state_of([[0.0, np.nan]])
    with pytest.raises(ValueError, match="points"):
        edc.state_of(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="unknown name 'foo'"):
        partitions.get("foo")
    with pytest.raises(ValueError, match="coincide"):
        state_of_triplet([1, 1], [1, 1], [0, 0])


def test_user_defined_partition_from_polygons():
    halves = [shapely.box(-10, 0.5, 10, 10), shapely.box(-10, -10, 10, 0.5)]
    part = Partition.from_polygons("updown", halves, (-1, 1, -1, 2), labels=("up", "down"))
    assert part.areas.tolist() == pytest.approx([3.0, 3.0])
    # no lookup given: shapely containment fallback
    assert part.state_of([[0.0, 1.0], [0.0, 0.0]]).tolist() == [0, 1]
    partitions.register(part)
    assert partitions.get("UPDOWN") is part
    with pytest.raises(ValueError, match="overlap"):
        Partition.from_polygons("bad", [shapely.box(-1, -1, 1, 1), shapely.box(0, 0, 1, 1)],
                                (-1, 1, -1, 1))
    with pytest.raises(ValueError, match="window"):
        Partition.from_polygons("bad2", halves, (1, -1, -1, 2))


def test_state_of_triplet_with_huge_finite_coordinates():
    # issue 12 item 4: |B - A|^2 overflowed to inf and the state was refused as "non-finite".
    # A = (1e200, 0), B = (1e200, 1e200), C = (0, 5e199): in the AB frame C = (1, 0.5) (see
    # geometry.to_frame's doctest), the same state as the unit-scale triplet.
    want = state_of_triplet([1, 0], [1, 1], [0, 0.5])
    assert state_of_triplet([1e200, 0], [1e200, 1e200], [0, 5e199]) == want
    assert state_of_triplet([1e300, 0], [1e300, 1e300], [0, 5e299]) == want


@given(st.integers(0, 2**32 - 1), st.integers(-900, 1000))
@settings(max_examples=40, deadline=None)
def test_state_of_triplet_is_invariant_under_any_power_of_two_scale(seed, exponent):
    # Scaling by 2^k is exact in float64, so the state must not change for any k whose scaled
    # points are still normal numbers and whose |B - A| is above the coincidence threshold.
    rng = np.random.default_rng(seed)
    A, B = rng.uniform(-3, 3, (2, 2))
    if np.linalg.norm(A - B) < 0.05:
        return
    C = rng.uniform(-6, 6, (30, 2))
    scale = 2.0 ** exponent
    # |B - A|^2 <= COINCIDENT_EPS (1e-18) at that scale: A and B coincide, refused (in logs, as
    # the scaled square may be out of range)
    if 2 * (np.log2(np.linalg.norm(A - B)) + exponent) <= np.log2(1e-18):
        with pytest.raises(ValueError, match="coincide"):
            state_of_triplet(A * scale, B * scale, C * scale)
        return
    np.testing.assert_array_equal(state_of_triplet(A * scale, B * scale, C * scale),
                                  state_of_triplet(A, B, C))


@pytest.mark.parametrize("name", NAMES)
def test_state_of_far_points_at_any_scale(name):
    # Points beyond |p| ~ 1e154 square to inf: same state as the same direction at a large but
    # ordinary distance, with no overflow warning (pytest turns RuntimeWarnings into errors).
    part = partitions.get(name)
    # directions away from the TPCC sector boundaries (multiples of 45 degrees)
    d = np.array([[1.0, 0.7], [-1.0, 0.3], [0.2, -1.0], [-0.5, 2.0], [1.7, -1.2]])
    d /= np.abs(d).max(axis=1, keepdims=True)
    want = part.state_of(d * 1e6)
    for scale in (1e160, 1e200, 1e300, 1.7e308):
        np.testing.assert_array_equal(part.state_of(d * scale), want)
