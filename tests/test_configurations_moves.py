"""The sampler's moves of qfg.configurations keep the right distribution (issue 21 (b)): with
flat evidence every move must leave the world prior itself invariant, including in the landmarks'
scale, which no state marginal sees; the per-estimate widening by effective sample size matches
its closed form; blocks of landmarks are the evidence's components and rigid clusters."""

from __future__ import annotations

import numpy as np
import pytest

from qfg.configurations import infer_configurations, prior_states
from qfg.configurations.sampler import _landmark_blocks
from qfg.priors import WorldBoxPrior

M = 20


def _spread(X):
    """(P,) RMS distance of each configuration's landmarks from their centroid."""
    d = X - X.mean(axis=1, keepdims=True)
    return np.sqrt(np.mean(np.sum(d * d, axis=-1), axis=1))


@pytest.mark.parametrize("evidence", [
    {(0, 1, 2): None},                          # one component of 3 landmarks in 5
    {(0, 1, 2): None, (2, 3, 4): None},         # two rigid clusters sharing landmark 2
])
def test_moves_keep_the_prior_with_flat_evidence(evidence):
    pr = WorldBoxPrior()
    q = prior_states(pr, "edc")
    ev = {t: q for t in evidence}               # P_t = q: a likelihood of 1 everywhere
    post = infer_configurations(ev, pr, landmarks=range(5), n_particles=4000, n_sweeps=6,
                                seed=3)
    assert post.diagnostics["n_stages"] == 1
    assert post.diagnostics["acceptance_similarity"] > 0.05
    if len(evidence) > 1:
        assert post.diagnostics["n_blocks"] >= 2 and post.diagnostics["acceptance_block"] > 0.05
    ref = pr.sample_world(np.random.default_rng(0), 5, 40000)
    a, b = _spread(post.positions), _spread(ref)
    # the particles start as independent prior draws; moves that keep the prior keep them so
    se = np.sqrt(a.var() / a.size + b.var() / b.size)
    assert abs(a.mean() - b.mean()) < 4 * se
    # and the positions' spread in the box (not only the shape's scale)
    xa, xb = post.positions[..., 0].ravel(), ref[..., 0].ravel()
    assert abs(xa.std() - xb.std()) < 0.02 * xb.std()


def test_ess_widening_closed_form():
    """One seen triplet, estimate P from n effective draws: its marginal is the estimate read as
    (n P + a q) / (n + a) with the floor on top, ``(1 - e) P + e q``, e = 1 - (1 - eps) n / (n + a)
    (tempering off)."""
    pr = WorldBoxPrior()
    q = prior_states(pr, "edc")
    v = np.full(M, 0.1 / (M - 1))
    v[3] = 0.9
    eps, a, n = 0.01, 3.0, 6.0
    post = infer_configurations({(0, 1, 2): v}, pr, n_particles=8000, seed=1, temper=1.0,
                                floor=eps, ess_prior=a, ess={(0, 1, 2): n})
    got = post.marginals([(0, 1, 2)], pseudo_count=0)
    e = 1 - (1 - eps) * n / (n + a)
    want = (1 - e) * v + e * q
    err = got.info["mc_error"][0]
    z = (got.probabilities[0] - want) / np.maximum(err, 1e-3)
    assert np.mean(z ** 2) < 4
    assert abs(got.probabilities[0, 3] - want[3]) < 0.05
    # without the ESS (a plain vector is taken as exact) the answer is the floor alone
    post0 = infer_configurations({(0, 1, 2): v}, pr, n_particles=8000, seed=1, temper=1.0,
                                 floor=eps, ess_prior=a)
    p0 = post0.marginals([(0, 1, 2)], pseudo_count=0).probabilities[0, 3]
    assert abs(p0 - ((1 - eps) * 0.9 + eps * q[3])) < 0.05
    assert p0 - got.probabilities[0, 3] > 0.15       # the two differ by far more than the error


def test_ess_bad_input():
    v = np.full(M, 1 / M)
    with pytest.raises(ValueError, match="ess"):
        infer_configurations({(0, 1, 2): v}, ess={(0, 1, 2): 0}, n_particles=40)
    with pytest.raises(ValueError, match="ess"):
        infer_configurations({(0, 1, 2): v}, ess={(0, 1, 3): 5}, n_particles=40)
    with pytest.raises(ValueError, match="ess"):
        infer_configurations({(0, 1, 2): v}, ess=[5], n_particles=40)
    with pytest.raises(ValueError, match="ess_prior"):
        infer_configurations({(0, 1, 2): v}, ess_prior=-1, n_particles=40)


def test_blocks_are_components_and_rigid_clusters():
    ijk = np.array([[0, 1, 2], [1, 2, 3], [3, 4, 5], [6, 7, 8]])
    blocks = {tuple(b.tolist()) for b in _landmark_blocks(ijk, 10)}
    # rigid clusters {0..3} (two triplets sharing 1, 2), {3, 4, 5}, {6, 7, 8} (also a component),
    # component {0..5}
    assert blocks == {(0, 1, 2, 3), (3, 4, 5), (6, 7, 8), (0, 1, 2, 3, 4, 5)}
    # all landmarks in one block: nothing (the whole-configuration move does it)
    assert _landmark_blocks(np.array([[0, 1, 2]]), 3) == []


def test_unlinked_triplets_can_answer_the_prior():
    """Two groups of landmarks no seen triplet links: ``unlinked="prior"`` answers the prior's
    states for every triplet across them and leaves the others as sampled."""
    pr = WorldBoxPrior()
    q = prior_states(pr, "edc")
    v = np.full(M, 0.1 / (M - 1))
    v[5] = 0.9
    post = infer_configurations({(0, 1, 2): v, (3, 4, 5): v}, pr, n_particles=400, seed=0)
    assert post.components().tolist() == [0, 0, 0, 1, 1, 1]
    ts = [(0, 1, 2), (0, 1, 3), (3, 4, 0), (4, 5, 3)]
    a = post.marginals(ts)
    b = post.marginals(ts, unlinked="prior")
    assert a.info["unlinked"].tolist() == [False, True, True, False]
    np.testing.assert_allclose(b.probabilities[1], q)
    np.testing.assert_allclose(b.probabilities[2], q)
    np.testing.assert_allclose(b.probabilities[[0, 3]], a.probabilities[[0, 3]])
    assert np.abs(a.probabilities[1] - q).max() > 1e-3       # the samples' own answer differs
    # rows answered by the prior are not counted as unsettled, whatever the populations say
    few = infer_configurations({(0, 1, 2): v, (3, 4, 5): v}, pr, n_particles=40, seed=0)
    with pytest.warns(UserWarning):
        fa = few.marginals(ts)
    fb = few.marginals(ts, unlinked="prior")
    assert fa.info["unsettled"][[1, 2]].all() and not fb.info["unsettled"][[1, 2]].any()
    np.testing.assert_array_equal(fb.info["unsettled"][[0, 3]], fa.info["unsettled"][[0, 3]])
    with pytest.raises(ValueError, match="unlinked"):
        post.marginals(ts, unlinked="yes")
