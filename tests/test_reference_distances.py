"""The reference solver takes the odometry's distances (the factor on ratios of consecutive step
lengths, as the SIS solvers do): it once ignored them silently, so that "the exact posterior"
was the posterior of other measurements than the ones full was given."""

from dataclasses import replace

import numpy as np
import pytest

from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplets
from qfg.solvers.common import odometry as _odometry
from qfg.solvers.reference import staged as _reference

SB, SH = np.deg2rad(2), np.deg2rad(5)


def _kl(p, q):
    return np.sum(p * (np.log(np.maximum(p, 1e-12)) - np.log(np.maximum(q, 1e-12))), axis=1)


def _hists(seeds, n=4):
    return [random_triplet_history(np.random.default_rng(s), n, SB, SH, sigma_distance_ratio=0.05)
            for s in seeds]


def test_reference_agrees_with_full_when_distances_matter():
    # development geometries (seeds 900101, 900105) where the distances move the exact
    # posterior by KL 0.28-0.32: the reference with them lands where full (an independent
    # sampler of the same target) lands, within the samplers' error, and away from the
    # reference without them
    hs = _hists([900101, 900105])
    ref = np.array([e.landmark for e in solve_triplets(hs, method="reference", seed=3)])
    ref0 = np.array([e.landmark for e in solve_triplets(
        [replace(h, distances=None) for h in hs], method="reference", seed=3)])
    full = np.array([e.landmark for e in solve_triplets(hs, method="full", seed=3)])
    assert np.all(_kl(ref, ref0) > 0.1)
    assert np.all(_kl(ref, full) < 0.05)


def test_layout_factor_is_the_sis_factor():
    rng = np.random.default_rng(0)
    b = rng.uniform(-1, 1, (4, 3))
    d = np.array([0.3, 0.5, 0.2])
    L = _reference.Layout(b, np.zeros(3), 0.01, 0.02, d, 0.07)
    X = rng.normal(size=(5, 4, 2))
    s = np.hypot(*np.diff(X, axis=1).transpose(2, 0, 1))
    want = _odometry.log_distance_factor(s[:, 1:], s[:, :-1], d[1:], d[:-1], 0.07).sum(axis=1)
    np.testing.assert_allclose(L.log_distances(X), want, rtol=1e-12)
    # the first three views keep the first two distances
    np.testing.assert_allclose(L.first(3).log_distances(X[:, :3]), want - _odometry.log_distance_factor(
        s[:, 2], s[:, 1], d[2], d[1], 0.07), rtol=1e-12)


def test_bad_distances_and_the_conditional_sampler():
    h = _hists([900101])[0]
    args = (h.bearings, h.headings, h.sigma_bearing, h.sigma_heading)
    with pytest.raises(ValueError, match="sigma_distance_ratio: required"):
        _reference.solve_reference(*args, distances=h.distances, n_samples=64)
    with pytest.raises(ValueError, match="distances"):
        _reference.solve_reference(*args, distances=h.distances[:1], sigma_distance_ratio=0.05,
                                   n_samples=64)
    with pytest.raises(ValueError, match="distances: the conditional sampler"):
        _reference.solve_reference(*args, distances=h.distances, sigma_distance_ratio=0.05,
                                   sampler="conditional")
    # all distances unknown (0): no factor, the answer without distances
    a = _reference.solve_reference(*args, distances=np.zeros(3), sigma_distance_ratio=0.05,
                                   seed=1, n_samples=500, rounds=1, max_rounds=1)
    b = _reference.solve_reference(*args, seed=1, n_samples=500, rounds=1, max_rounds=1)
    np.testing.assert_array_equal(a["landmark"], b["landmark"])
