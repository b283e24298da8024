"""The model check of many triplets at once (the SIS engine's final step) against the check
built from its pieces one triplet at a time (residuals, discrepancy, reference distribution),
and the p-value each full-solver estimate reports against the check of the sample it returns."""

import numpy as np
import pytest

from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplets
from qfg.solvers.common.likelihood import as_tail
from qfg.solvers.sis import model_check as mc


def _one(b, h, P, L, w, sv, sh, tail):
    """p of one triplet from the module's pieces: P (n, K, 3) poses, one landmark per pose."""
    if not sv > 0 or not np.any(w > 0):
        return np.nan
    rb, rh = mc.residuals(b, h, P, L)
    use_h = bool(np.all(np.asarray(sh) > 0))
    D = mc.discrepancy(rb, rh, sv, sh if use_h else 0.0, tail)
    sf = mc.reference_sf(D, 3 * b.shape[0], rh.shape[0] if use_h else 0, tail, sv)
    return float(np.sum(w * sf) / np.sum(w))


@pytest.mark.parametrize("tail", [None, (0.1, 5.0, 0.01)])
def test_batch_equals_one_triplet_at_a_time(tail):
    t = as_tail(tail)
    rng = np.random.default_rng(11)
    T, n, r = 5, 4, 3
    J = rng.integers(0, 6, T)                       # trajectories per triplet (one has none)
    J[2] = 0
    tid = np.repeat(np.arange(T), J)
    P = np.concatenate([rng.normal(size=(tid.size, n, 2)) * 2,
                        rng.uniform(-3, 3, (tid.size, n, 1))], axis=2)
    L = rng.normal(size=(tid.size * r, 2)) * 2
    b = rng.uniform(-1, 1, (T, n, 3)) * 0.5
    h = rng.uniform(-1, 1, (T, n - 1)) * 0.5
    w = rng.random(tid.size * r)
    w[::5] = 0.0
    sv = np.array([0.3, 0.5, 0.5, 0.0, 0.3])         # triplet 3: noiseless, no check
    sh = np.array([[0.4, 0.4, 0.2], [0.0, 0.4, 0.4], [0.4] * 3, [0.4] * 3, [0.3] * 3])
    got = mc.posterior_predictive_batch(b, h, P, tid, L, w, sv, sh, t, per_pose=r)
    tr = np.repeat(tid, r)
    for k in range(T):
        rows = tr == k
        Pk = np.repeat(P[tid == k], r, axis=0).transpose(1, 0, 2)
        want = _one(b[k], h[k], Pk, L[rows], w[rows], sv[k], sh[k], t)
        if np.isnan(want):
            assert np.isnan(got[k])
        else:
            assert 0 < want < 1
            assert got[k] == pytest.approx(want, abs=1e-12)
    assert np.isnan(got[2]) and np.isnan(got[3])
    # C's deviances from the draws' log likelihoods (as the SIS engine hands them over)
    from qfg.geometry import bearing, wrap_angle
    from qfg.solvers.common.likelihood import log_bearing

    rc = wrap_angle(b[tr, :, 2] - bearing(np.repeat(P, r, axis=0), L[:, None, :]))
    svc = np.where(sv > 0, sv, 1.0)[tr][:, None]
    ll = np.sum(log_bearing(rc, svc, t), axis=1)
    via = mc.posterior_predictive_batch(b, h, P, tid, L, w, sv, sh, t, per_pose=r, c_loglik=ll)
    np.testing.assert_allclose(via, got, rtol=0, atol=1e-10)


def test_each_estimate_reports_the_check_of_its_own_sample():
    """``TripletEstimate.model_check`` of a batched solve is the check of the weighted sample
    the same solve returns for that triplet (a triplet's share of the batch, not another's)."""
    hs = [random_triplet_history(np.random.default_rng(40 + i), 4, np.deg2rad(2.0),
                                 np.deg2rad(5.0)) for i in range(4)]
    out = solve_triplets(hs, method="full", seed=3, hypotheses=True)
    for h, (est, hyp) in zip(hs, out, strict=True):
        sv = max(h.sigma_bearing, est.options["bearing_floor"])
        sh = max(h.sigma_heading, est.options["bearing_floor"])
        want = _one(np.asarray(h.bearings), np.asarray(h.headings), hyp.camera_samples,
                    hyp.landmark_samples, hyp.landmark_weights, sv, sh,
                    est.options.get("bearing_tail"))
        assert est.model_check == pytest.approx(want, abs=1e-9)
