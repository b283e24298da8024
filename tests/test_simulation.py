"""Simulator: reproducibility, minimum distance, consistency of measurements with the truth."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qfg import geometry as g
from qfg import partitions
from qfg.simulation import (
    SimulationConfig,
    TripletHistory,
    random_scenario,
    random_triplet_history,
    sample_positions,
    triplet_histories,
)


def test_same_seed_same_history_and_different_seed_differs():
    a = random_triplet_history(np.random.default_rng(5), 3, 0.01, 0.02)
    b = random_triplet_history(np.random.default_rng(5), 3, 0.01, 0.02)
    c = random_triplet_history(np.random.default_rng(6), 3, 0.01, 0.02)
    assert np.array_equal(a.bearings, b.bearings) and np.array_equal(a.headings, b.headings)
    assert np.array_equal(a.truth.poses_world, b.truth.poses_world)
    assert not np.array_equal(a.bearings, c.bearings)
    s1 = random_scenario(np.random.default_rng(3), 7, 10, sigma_bearing=0.1, sigma_heading=0.1)
    s2 = random_scenario(np.random.default_rng(3), 7, 10, sigma_bearing=0.1, sigma_heading=0.1)
    for f in ("landmarks", "poses", "visible", "bearings", "heading_noise"):
        assert np.array_equal(getattr(s1, f), getattr(s2, f))


@given(st.integers(0, 2**32 - 1), st.floats(0.01, 1.0))
@settings(max_examples=30, deadline=None)
def test_minimum_distance_respected(seed, dmin):
    cfg = SimulationConfig(xlim=(0, 3), ylim=(0, 3), min_distance=dmin * 0.3)
    pts = sample_positions(np.random.default_rng(seed), 25, cfg)
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    assert np.min(d[np.triu_indices(25, 1)]) >= cfg.min_distance
    assert np.all((pts >= 0) & (pts <= 3))


def test_min_distance_impossible_raises():
    cfg = SimulationConfig(xlim=(0, 0.1), ylim=(0, 0.1), min_distance=1.0, max_tries=20)
    with pytest.raises(ValueError, match="could not place"):
        sample_positions(np.random.default_rng(0), 5, cfg)


def test_noiseless_history_matches_truth():
    h = random_triplet_history(np.random.default_rng(11), n_views=4)
    L, P = h.truth.landmarks_world, h.truth.poses_world
    np.testing.assert_allclose(h.bearings, g.bearing(P[:, None, :], L[None]), atol=1e-12)
    np.testing.assert_allclose(h.headings, g.motion_heading(P[:-1], P[1:, :2]), atol=1e-12)
    # truth in the AB frame agrees with the frame transform and the partition
    A, B, C = L
    np.testing.assert_allclose(h.truth.C_ab, g.to_frame(C, A, B))
    assert h.truth.state == partitions.get("edc").state_of(h.truth.C_ab)
    # bearings measured in the AB frame equal the world ones
    Pab = h.truth.poses_ab
    Lab = g.to_frame(L, A, B)
    np.testing.assert_allclose(g.wrap_angle(g.bearing(Pab[:, None, :], Lab[None]) - h.bearings), 0,
                               atol=1e-9)


def test_noise_has_requested_scale():
    rng = np.random.default_rng(2)
    errs = []
    for _ in range(300):
        h = random_triplet_history(rng, 3, sigma_bearing=0.05)
        P, L = h.truth.poses_world, h.truth.landmarks_world
        errs.append(g.wrap_angle(h.bearings - g.bearing(P[:, None], L[None])).ravel())
    assert np.std(np.concatenate(errs)) == pytest.approx(0.05, rel=0.1)


def test_scenario_triplet_histories_are_complete_and_consistent():
    sc = random_scenario(np.random.default_rng(4), 6, 15, 4, sigma_bearing=0.0)
    hist = triplet_histories(sc)
    # brute force: every ordered triple of distinct landmarks co-visible at >= 1 pose
    expected = set()
    for a in range(6):
        for b in range(6):
            for c in range(6):
                if len({a, b, c}) == 3 and np.any(sc.visible[:, [a, b, c]].all(axis=1)):
                    expected.add((a, b, c))
    assert {h.landmarks for h in hist} == expected
    for h in hist[:20]:
        poses = np.flatnonzero(sc.visible[:, list(h.landmarks)].all(axis=1))
        assert h.views.tolist() == poses.tolist()  # time order
        assert h.headings.shape == (len(poses) - 1,)
        np.testing.assert_allclose(
            h.bearings, g.bearing(sc.poses[poses][:, None], sc.landmarks[list(h.landmarks)][None]),
            atol=1e-12)
    multi = triplet_histories(sc, min_views=3)
    assert all(h.n_views >= 3 for h in multi)
    assert len(multi) < len(hist)


def test_scenario_headings_between_non_consecutive_views():
    sc = random_scenario(np.random.default_rng(9), 5, 12, 3, sigma_heading=0.0)
    for h in triplet_histories(sc, min_views=2):
        v = h.views
        np.testing.assert_allclose(h.headings, g.motion_heading(sc.poses[v[:-1]], sc.poses[v[1:], :2]))


def test_bad_input():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="sigma_bearing"):
        random_triplet_history(rng, 3, sigma_bearing=-1)
    with pytest.raises(ValueError, match="n_views"):
        random_triplet_history(rng, 0)
    with pytest.raises(ValueError, match="landmarks_per_view"):
        random_scenario(rng, 3, 5, landmarks_per_view=4)
    with pytest.raises(ValueError, match="headings"):
        TripletHistory((0, 1, 2), np.zeros((3, 3)), np.zeros(3), 0.0, 0.0)
    with pytest.raises(ValueError, match="bearings"):
        TripletHistory((0, 1, 2), np.full((3, 3), np.nan), np.zeros(2), 0.0, 0.0)
    with pytest.raises(ValueError, match="xlim"):
        SimulationConfig(xlim=(1, 0))
