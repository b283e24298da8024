"""propagate(method="pooled") against a plain loop over factors."""

import numpy as np
import pytest

from qfg.composition import marginal as compose
from qfg.graph import full_map
from qfg.propagation import propagate


def _loop_reference(g):
    """Rounds written out factor by factor (no batching): level-r triplets are the mean of the
    compositions of every factor with an updated and a non-updated member."""
    n, m = g.n_triplets, g.m
    vals = [None if p is None else np.asarray(p, float) / np.sum(p) for p in g.priors]
    while True:
        props = {}
        for f in g.factor_vars:
            f = [int(x) for x in f]
            upd = [vals[v] is not None for v in f]
            if not any(upd) or all(upd):
                continue
            for role in range(3):
                if upd[role]:
                    continue
                V = [vals[v] if (u and i != role) else (None if i == role else np.ones(m))
                     for i, (v, u) in enumerate(zip(f, upd, strict=True))]
                props.setdefault(f[role], []).append(
                    np.asarray(compose(g.table, V[0], V[1], V[2], role=role + 1).p))
        if not props:
            break
        for v, ps in props.items():
            vals[v] = np.mean(ps, axis=0)
    return np.array([np.full(m, 1.0 / m) if v is None else v for v in vals]).reshape(n, m)


@pytest.mark.parametrize("seed", [0, 1])
def test_pooled_equals_the_factor_loop(seed):
    rng = np.random.default_rng(seed)
    T = rng.random((4, 4, 4)) ** 3
    seen = {(0, 1, 2): rng.dirichlet(np.ones(4) * 0.5), (3, 1, 0): rng.dirichlet(np.ones(4))}
    g = full_map(5, partition=None, tensor=T, priors=seen)
    got = propagate(g, method="pooled")
    want = _loop_reference(g)
    np.testing.assert_allclose(np.asarray(got), want, atol=1e-12)
    assert np.all(got.info["level"][np.asarray(g.seen)] == 0)
    assert np.all(got.info["level"][~np.asarray(g.seen)] >= 1)
    assert got.method == "pooled"


def test_pooled_is_never_sharper_than_its_sharpest_proposal():
    # the mean of distributions has max probability <= the largest member's
    rng = np.random.default_rng(3)
    T = rng.random((4, 4, 4)) ** 4
    seen = {(0, 1, 2): np.array([0.97, 0.01, 0.01, 0.01]), (1, 2, 3): rng.dirichlet(np.ones(4))}
    g = full_map(4, partition=None, tensor=T, priors=seen)
    P = np.asarray(propagate(g, method="pooled"))
    best = np.asarray(propagate(g))
    assert P.max() <= max(best.max(), 0.97) + 1e-12


def test_unknown_method_is_named():
    g = full_map(4, partition=None, tensor=np.ones((2, 2, 2)), priors={(0, 1, 2): [0.5, 0.5]})
    with pytest.raises(ValueError, match="method"):
        propagate(g, method="sharpest")
    with pytest.raises(ValueError, match="close_used"):
        propagate(g, close_used=True, method="pooled")
