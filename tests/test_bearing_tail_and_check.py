"""The heavy-tailed bearing likelihood (``bearing_tail``) and the model check (``model_check``):
densities against numerical integration and their own draws, the solvers against the normal
model the tail reduces to, and the check on well-specified and misfit simulated histories."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.stats import chi2, kstest

from qfg.metrics import log_score
from qfg.simulation import random_triplet_history
from qfg.solvers import DEFAULTS, solve_triplets
from qfg.solvers.common.likelihood import (
    BearingTail,
    as_tail,
    bearing_noise,
    log_bearing,
    log_bearing_proposal,
)
from qfg.solvers.sis import model_check as mc

TAIL = BearingTail(share=0.27, scale=2.8, outlier=0.01)


@pytest.mark.parametrize("tail", [None, TAIL, BearingTail(0.0, 1.0, 0.2)])
@pytest.mark.parametrize("spread", [1.0, 4.0])
def test_bearing_density_integrates_to_one_and_matches_its_draws(tail, spread):
    sigma = 0.05
    x = np.linspace(-np.pi, np.pi, 400_001)
    dens = np.exp(log_bearing_proposal(x, sigma, tail, spread))
    # the wider normal components at spread 4 reach past pi (14 sigma): a little mass outside
    assert np.trapezoid(dens, x) == pytest.approx(1.0, abs=2e-3 if spread > 1 else 1e-6)
    rng = np.random.default_rng(3)
    n = 20_000
    d = bearing_noise(rng.standard_normal(n), rng.random(n), rng.random(n), sigma, tail, spread)
    cdf_x = np.cumsum(dens) * (x[1] - x[0])
    res = kstest(d[np.abs(d) < np.pi], lambda v: np.interp(v, x, cdf_x) / cdf_x[-1])
    assert res.pvalue > 1e-3


def test_tail_reduces_to_the_normal():
    r = np.linspace(-0.3, 0.3, 7)
    assert np.allclose(log_bearing(r, 0.1, None),
                       -0.5 * (r / 0.1) ** 2 - np.log(0.1 * np.sqrt(2 * np.pi)))
    assert as_tail((0.0, 3.0, 0.0)) is None
    assert as_tail(None) is None
    assert as_tail({"share": 0.1, "scale": 2.0, "outlier": 0.0}) == BearingTail(0.1, 2.0, 0.0)
    with pytest.raises(ValueError, match="bearing_tail"):
        as_tail((0.9, 2.0, 0.2))
    with pytest.raises(ValueError, match="bearing_tail"):
        solve_triplets(np.zeros((1, 2, 3)) + [0.1, 0.5, 0.3], np.zeros((1, 1)), method="fast",
                       sigma_bearing=0.01, sigma_heading=0.01, bearing_tail=(0.5, 0.5, 0.0))
    with pytest.raises(ValueError, match="model_check"):
        solve_triplets(np.zeros((1, 2, 3)) + [0.1, 0.5, 0.3], np.zeros((1, 1)), method="fast",
                       sigma_bearing=0.01, sigma_heading=0.01, model_check=1.5)


def _histories(seed, n, T, sb=np.deg2rad(2.0), sh=np.deg2rad(5.0), factor=1.0):
    rng = np.random.default_rng(seed)
    hs = [random_triplet_history(rng, n, factor * sb, factor * sh) for _ in range(T)]
    return [dataclasses.replace(h, sigma_bearing=sb, sigma_heading=sh) for h in hs]


def test_default_options_leave_the_answers_unchanged():
    # bearing_tail None and model_check 0 are the defaults: the same streams, the same answers
    hs = _histories(5, 3, 4)
    for method in ("fast", "full"):
        assert DEFAULTS[method]["bearing_tail"] is None and DEFAULTS[method]["model_check"] == 0
        a = solve_triplets(hs, method=method, seed=2)
        b = solve_triplets(hs, method=method, seed=2, bearing_tail=(0.0, 2.0, 0.0))
        assert all(np.array_equal(x.landmark, y.landmark) for x, y in zip(a, b, strict=True))


@pytest.mark.parametrize("method", ["fast", "full"])
def test_a_tail_that_is_all_wide_component_is_the_wider_normal(method):
    # share ~1 at scale 2: the mixture is N(0, 2 sigma); the tail path (mixture draws, tail C
    # weights and the tail's Laplace correction) must agree with the normal path at 2 sigma
    hs = _histories(7, 3, 12, sb=np.deg2rad(1.0), sh=np.deg2rad(3.0))
    wide = [dataclasses.replace(h, sigma_bearing=2 * h.sigma_bearing) for h in hs]
    a = solve_triplets(hs, method=method, seed=4, bearing_tail=(0.999999, 2.0, 0.0))
    b = solve_triplets(wide, method=method, seed=5)
    c = solve_triplets(wide, method=method, seed=4)

    def tv(u, v):
        return np.mean([0.5 * np.abs(x.landmark - y.landmark).sum()
                        for x, y in zip(u, v, strict=True)])

    # as close to the normal's answer as two seeds of the normal are to each other (Monte Carlo
    # noise; a C proposal as narrow as the core, not the mixture, gave twice that for full)
    assert tv(a, b) < 1.3 * tv(c, b) + 0.01


def test_the_tail_helps_when_a_bearing_is_an_outlier():
    sb = np.deg2rad(1.0)
    hs = _histories(9, 4, 24, sb=sb, sh=np.deg2rad(3.0))
    bad = []
    for h in hs:
        b = h.bearings.copy()
        b[2, 2] += np.deg2rad(15.0)     # C's bearing in view 3: a misread
        bad.append(dataclasses.replace(h, bearings=b))
    truth = np.array([h.truth.state for h in hs])
    plain = solve_triplets(bad, method="full", seed=1)
    tail = solve_triplets(bad, method="full", seed=1, bearing_tail=(0.2, 3.0, 0.01))
    s_plain = log_score(np.stack([e.landmark for e in plain]), truth).mean()
    s_tail = log_score(np.stack([e.landmark for e in tail]), truth).mean()
    assert s_tail > s_plain + 0.3


def test_reference_distribution_of_the_discrepancy():
    # the tabulated reference of a nearly normal tail is the chi-square
    D = np.array([3.0, 9.0, 15.0, 25.0])
    t = BearingTail(share=1e-9, scale=1.0, outlier=0.0)
    assert np.allclose(mc.reference_sf(D, 9, 2, t, 0.02), chi2.sf(D, 11), atol=0.012)
    # the discrepancy of replicated noise has that distribution: p uniform
    rng = np.random.default_rng(0)
    rb = rng.standard_normal((3, 3, 4000)) * 0.02
    rh = rng.standard_normal((2, 4000)) * 0.1
    p = mc.reference_sf(mc.discrepancy(rb, rh, 0.02, 0.1), 9, 2)
    assert kstest(p, "uniform").pvalue > 1e-3
    e = bearing_noise(rng.standard_normal((3, 3, 4000)), rng.random((3, 3, 4000)),
                      rng.random((3, 3, 4000)), 0.02, TAIL)
    p = mc.reference_sf(mc.discrepancy(e, rh, 0.02, 0.1, TAIL), 9, 2, TAIL, 0.02)
    assert kstest(p, "uniform").pvalue > 1e-3


def test_residuals_at_the_truth_are_the_noise():
    h = _histories(3, 3, 1, sb=0.0, sh=0.0)[0]     # noiseless: residuals 0 at the truth
    P = h.truth.poses_ab[:, None, :]
    L = h.truth.C_ab[None]
    rb, rh = mc.residuals(h.bearings, h.headings, P, L)
    assert np.allclose(rb, 0, atol=1e-9) and np.allclose(rh, 0, atol=1e-9)


def test_model_check_rarely_fires_on_well_specified_data_and_widens_misfits():
    level = 0.05
    T = 30
    clean = _histories(11, 4, T)
    est = solve_triplets(clean, method="full", seed=3, model_check=level)
    p = np.array([e.model_check for e in est])
    assert np.all(np.isfinite(p) | np.array([e.degenerate for e in est]))
    assert np.mean(p < level) <= 0.1
    # 5x the stated noise: the check fires on many, and those answers score at least as well
    # as the prior alone (what they are widened toward)
    bad = _histories(11, 4, T, factor=5.0)
    est = solve_triplets(bad, method="full", seed=3, model_check=level)
    p = np.array([e.model_check for e in est])
    fired = p < level
    assert fired.mean() >= 0.3
    assert all("model check" in e.reason for e, f in zip(est, fired, strict=True) if f)
    truth = np.array([h.truth.state for h in bad])[fired]
    from qfg.partitions import get as get_partition
    from qfg.priors import get as get_prior

    q_c, _ = mc.prior_states(get_prior("world"), get_partition("edc"))
    widened = log_score(np.stack([e.landmark for e, f in zip(est, fired, strict=True) if f]),
                        truth).mean()
    prior = log_score(np.tile(q_c, (truth.size, 1)), truth).mean()
    assert widened >= prior - 0.05


def test_widening_share():
    assert mc.widening(float("nan"), 0.05) == 0.0
    assert mc.widening(0.01, 0.0) == 0.0
    assert mc.widening(0.0, 0.05) == 1.0
    assert mc.widening(0.025, 0.05) == pytest.approx(0.5)


def test_a_per_image_offset_is_absorbed_by_the_camera_heading():
    # bearings f_k = atan2(P_k - X) - alpha: an offset o shared by A, B and C of one image is
    # the heading alpha - o; only the motion heading out of that view (relative to alpha) sees
    # it, as psi + o
    h = _histories(13, 4, 1, sb=0.0, sh=0.0)[0]
    o = np.array([0.01, -0.02, 0.015, 0.03])
    P = h.truth.poses_ab.copy()
    L = h.truth.C_ab[None]
    rb0, rh0 = mc.residuals(h.bearings, h.headings, P[:, None, :], L)
    P[:, 2] -= o
    rb, rh = mc.residuals(h.bearings + o[:, None], h.headings + o[:-1], P[:, None, :], L)
    assert np.allclose(rb, rb0, atol=1e-12) and np.allclose(rh, rh0, atol=1e-12)
