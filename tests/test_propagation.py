"""Tests of qfg.propagation: exact engines, Algorithm 2/3, composition levels, loopy BP."""

import itertools
import string

import networkx as nx
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qfg.graph import QualitativeFactorGraph, full_map
from qfg.inference import loopy_bp
from qfg.metrics import information_score
from qfg.propagation import (
    GraphTooLargeError,
    composition_levels,
    exact_marginals,
    propagate,
    topology_scores,
)


def rand_T(rng, m, density=0.7):
    T = rng.random((m, m, m)) * (rng.random((m, m, m)) < density)
    T[tuple(rng.integers(0, m, 3))] += 0.5  # some mass
    return T


def brute_marginals(g):
    """Marginals by enumerating every joint state (independent of both engines)."""
    n, m = g.n_triplets, g.m
    letters = string.ascii_letters
    terms, ops = [], []
    P = g.prior_matrix()
    for v in np.flatnonzero(g.seen):
        terms.append(letters[v])
        ops.append(P[v])
    for f in g.factor_vars:
        terms.append("".join(letters[v] for v in f))
        ops.append(g.table)
    full = np.ones((m,) * n)
    idx = letters[:n]
    for t, op in zip(terms, ops, strict=True):
        srt = "".join(sorted(t, key=idx.index))
        full = full * np.einsum(f"{t}->{srt}", op).reshape([m if c in t else 1 for c in idx])
    full /= full.sum()
    return np.stack([full.sum(axis=tuple(a for a in range(n) if a != v)) for v in range(n)])


def one_factor_graph(T, p1, p2, p3=None):
    g = QualitativeFactorGraph(None, tensor=T)
    g.add_triplet((0, 1, 2), p1)
    g.add_triplet((1, 2, 3), p2)
    g.add_triplet((0, 1, 3), p3)
    g.discover_compositions()
    return g


def random_graph(rng, T, n_land=5, frac=0.3, seen_frac=0.5):
    g = QualitativeFactorGraph(None, tensor=T)
    m = T.shape[0]
    for t in itertools.permutations(range(n_land), 3):
        if rng.random() < frac:
            g.add_triplet(t, rng.dirichlet(np.ones(m)) if rng.random() < seen_frac else None)
    g.discover_compositions()
    return g


# ------------------------------------------------------------------ exact engines
@pytest.mark.parametrize("seed", range(6))
def test_gtsam_and_contract_agree_on_random_loopy_graphs(seed):
    rng = np.random.default_rng(seed)
    T = rand_T(rng, 3)
    g = QualitativeFactorGraph(None, tensor=T)
    # triplets of landmarks 0..3, enough to form loops; a random subset of them seen
    # factors (0,1,2,3) and (0,1,3,2) share (0,1,2) and (0,1,3): a loop
    core = [(0, 1, 2), (0, 1, 3), (0, 2, 1), (1, 2, 3), (1, 3, 2)]
    rest = [t for t in itertools.permutations(range(4), 3) if t not in core]
    extra = [rest[i] for i in rng.choice(len(rest), 3, replace=False)]
    for t in core + extra:
        g.add_triplet(t, rng.dirichlet(np.ones(3)) if rng.random() < 0.5 else None)
    g.discover_compositions()
    assert g.n_triplets <= 10
    G = g.to_networkx()
    has_loop = len(nx.cycle_basis(G)) > 0
    a = exact_marginals(g, method="gtsam")
    b = exact_marginals(g, method="contract")
    np.testing.assert_allclose(a, b, atol=1e-9)
    np.testing.assert_allclose(b, brute_marginals(g), atol=1e-9)
    assert has_loop


def test_brute_force_helper_on_one_factor():
    rng = np.random.default_rng(3)
    T = rand_T(rng, 3)
    p1, p2 = rng.dirichlet(np.ones(3)), rng.dirichlet(np.ones(3))
    g = one_factor_graph(T, p1, p2)
    joint = p1[:, None, None] * p2[None, :, None] * T
    np.testing.assert_allclose(brute_marginals(g)[2], joint.sum((0, 1)) / joint.sum(), atol=1e-12)


def test_exact_unreachable_and_isolated_are_uniform_and_seen_isolated_keeps_prior():
    T = rand_T(np.random.default_rng(0), 3)
    g = one_factor_graph(T, [0.2, 0.3, 0.5], None)  # no seen triplet touches (1,2,3)/(0,1,3) but f
    g.add_triplet((7, 8, 9))                          # isolated unseen
    g.add_triplet((7, 9, 8), [0.1, 0.1, 0.8])         # isolated seen
    for engine in ("junction", "gtsam", "contract"):
        M = exact_marginals(g, method=engine)
        np.testing.assert_allclose(M[3], np.full(3, 1 / 3))
        np.testing.assert_allclose(M[4], [0.1, 0.1, 0.8])


def test_exact_too_big_raises_with_size():
    g = full_map(6, tensor=np.ones((20, 20, 20)))
    for engine in ("junction", "gtsam", "contract"):
        with pytest.raises(GraphTooLargeError, match="entries"):
            exact_marginals(g, method=engine)
    with pytest.raises(GraphTooLargeError, match="entries"):
        exact_marginals(g, method="contract", max_table=10**4)
    with pytest.raises(ValueError, match="method"):
        exact_marginals(g, method="magic")


# ------------------------------------------------------------------ Algorithm 2
@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 4))
def test_one_factor_two_seen_label_correcting_equals_exact(seed, m):
    rng = np.random.default_rng(seed)
    T = rand_T(rng, m)
    p1 = rng.dirichlet(np.ones(m))
    p2 = rng.dirichlet(np.ones(m))
    for order in ((p1, p2, None), (p1, None, p2), (None, p1, p2)):
        g = one_factor_graph(T, *order)
        target = [k for k, p in enumerate(order) if p is None][0]
        joint = T.copy()
        for k, p in enumerate(order):
            if p is not None:
                joint = joint * np.expand_dims(p, [a for a in range(3) if a != k])
        if joint.sum() <= 0:
            continue
        exact = joint.sum(axis=tuple(a for a in range(3) if a != target)) / joint.sum()
        r = propagate(g)
        np.testing.assert_allclose(r.probabilities[target], exact, atol=1e-12)
        np.testing.assert_allclose(exact_marginals(g)[target], exact, atol=1e-12)
        assert r.order.tolist() == [target] and r.updated_by[target] == 0


def naive_algorithm2(g):
    """Algorithm 2 as written: every step, every open factor proposes; best ISC kept."""
    T = g.table
    m = g.m
    fv = g.factor_vars
    vals = [None if p is None else p for p in g.priors]
    upd = g.seen.copy()
    order, by = [], {}
    while True:
        best = None
        for f, vs in enumerate(fv):
            u = upd[vs]
            if u.all() or not u.any():
                continue
            for r in np.flatnonzero(~u):
                V = [vals[v] if upd[v] else np.ones(m) for v in vs]
                V[r] = np.ones(m)
                x = np.einsum("abc,a,b,c->" + "abc"[r], T, *V)
                p = x / x.sum() if x.sum() > np.finfo(float).tiny else np.full(m, 1 / m)
                key = (-information_score(p), vs[r], f)
                if best is None or key < best[0]:
                    best = (key, vs[r], f, p)
        if best is None:
            break
        _, v, f, p = best
        upd[v] = True
        vals[v] = p
        order.append(v)
        by[v] = f
    return vals, order, by


@pytest.mark.parametrize("seed", range(8))
def test_priority_queue_equals_naive_algorithm2(seed):
    rng = np.random.default_rng(100 + seed)
    T = rand_T(rng, 3)
    g = random_graph(rng, T, n_land=5, frac=0.35, seen_frac=0.3)
    vals, order, by = naive_algorithm2(g)
    r = propagate(g)
    assert r.order.tolist() == order
    assert all(r.updated_by[v] == f for v, f in by.items())
    for v, p in enumerate(vals):
        expect = np.full(3, 1 / 3) if p is None else p
        np.testing.assert_allclose(r.probabilities[v], expect, atol=1e-12)
    np.testing.assert_allclose(r.isc, information_score(r.probabilities))


def test_unreachable_triplets_are_uniform():
    rng = np.random.default_rng(5)
    T = rand_T(rng, 3)
    g = one_factor_graph(T, rng.dirichlet(np.ones(3)), None)
    # a second component with no seen triplet, and an isolated triplet
    for t in [(4, 5, 6), (5, 6, 7), (4, 5, 7), (8, 9, 10)]:
        g.add_triplet(t)
    g.discover_compositions()
    r = propagate(g)
    for v in (3, 4, 5, 6):
        np.testing.assert_allclose(r.probabilities[v], np.full(3, 1 / 3))
        assert not r.reached[v] and r.updated_by[v] == -1
        assert r.isc[v] == pytest.approx(0.0, abs=1e-12)
    assert r.reached[:3].all()
    # a triplet without any factor is uniform for every method (the unseen component is not:
    # under the exact model it carries the tensor's own marginals)
    np.testing.assert_allclose(loopy_bp(g).probabilities[6], np.full(3, 1 / 3), atol=1e-12)
    np.testing.assert_allclose(exact_marginals(g)[6], np.full(3, 1 / 3), atol=1e-12)


def test_propagate_deterministic_and_seen_kept():
    rng = np.random.default_rng(9)
    T = rand_T(rng, 4)
    g = random_graph(rng, T, n_land=6, frac=0.3)
    r1, r2 = propagate(g), propagate(g)
    np.testing.assert_array_equal(r1.probabilities, r2.probabilities)
    np.testing.assert_array_equal(r1.order, r2.order)
    P = g.prior_matrix()
    np.testing.assert_allclose(r1.probabilities[g.seen], P[g.seen])
    assert set(r1.order.tolist()).isdisjoint(np.flatnonzero(g.seen).tolist())


# ------------------------------------------------------------------ Algorithm 3 / CL
def chain_graph():
    """Hand-worked graph: seen a=(0,1,2); f0 = (0,1,2,3): (0,1,2), (1,2,3), (0,1,3);
    f1 = (1,2,3,4): (1,2,3), (2,3,4), (1,2,4)."""
    g = QualitativeFactorGraph(None, tensor=np.ones((2, 2, 2)))
    g.add_triplet((0, 1, 2), [0.9, 0.1])
    for t in [(1, 2, 3), (0, 1, 3), (2, 3, 4), (1, 2, 4)]:
        g.add_triplet(t)
    g.add_composition((0, 1, 2, 3))
    g.add_composition((1, 2, 3, 4))
    return g


def test_topology_scores_hand_worked():
    g = chain_graph()
    isc0 = float(information_score(np.array([0.9, 0.1])))
    a = 0.5
    r = topology_scores(g, alpha=a)
    # step 1: f0 proposes 0.5*isc0 to (1,2,3) and (0,1,3): tie -> smaller index (1,2,3) = v1
    # step 2: f0 now has two updated -> (0,1,3) gets 0.75*(isc0+0.5 isc0)/2 = 0.5625 isc0;
    #         f1 proposes 0.5*0.5 isc0 = 0.25 isc0 to v3, v4 -> v2 first
    # step 3, 4: f1 -> v3 and v4: 0.25 isc0, then v4 from two: 0.75*(0.5+0.25)/2 = 0.28125 isc0
    expect = np.array([1.0, 0.5, 0.5625, 0.25, 0.28125]) * isc0
    np.testing.assert_allclose(r.scores, expect)
    assert r.order.tolist() == [1, 2, 3, 4]
    assert r.updated_by.tolist() == [-1, 0, 0, 1, 1]
    r1 = topology_scores(g, alpha=a, seen_score=1.0)
    np.testing.assert_allclose(r1.scores, expect / isc0)
    r2 = topology_scores(g, alpha=0.2, seen_score=1.0)
    np.testing.assert_allclose(r2.scores[:3], [1.0, 0.8, 0.96 * 1.8 / 2])


def test_composition_levels_hand_worked():
    g = chain_graph()
    g.add_triplet((7, 8, 9))
    r = composition_levels(g)
    np.testing.assert_array_equal(r.levels, [0, 1, 1, 2, 2, np.inf])
    np.testing.assert_allclose(r.normalized, [1, 0.5, 0.5, 0, 0, 0])
    assert not r.reached[5]


def test_scores_bad_input():
    g = chain_graph()
    with pytest.raises(ValueError, match="alpha"):
        topology_scores(g, alpha=1.0)
    with pytest.raises(ValueError, match="seen_score"):
        topology_scores(g, seen_score=2.0)
    with pytest.raises(ValueError, match="damping"):
        loopy_bp(g, damping=1.0)
    with pytest.raises(ValueError, match="max_iters"):
        loopy_bp(g, max_iters=0)
    with pytest.raises(ValueError, match="tol"):
        loopy_bp(g, tol=0)


# ------------------------------------------------------------------ loopy BP
@pytest.mark.parametrize("seed", range(4))
def test_loopy_bp_exact_on_trees(seed):
    rng = np.random.default_rng(20 + seed)
    m = 3
    T = rand_T(rng, m)
    g = QualitativeFactorGraph(None, tensor=T)
    for t in [(0, 1, 2), (1, 2, 3), (0, 1, 3), (2, 3, 4), (1, 2, 4), (1, 3, 4), (0, 1, 4)]:
        g.add_triplet(t, rng.dirichlet(np.ones(m)) if rng.random() < 0.6 else None)
    # f0 and f1 share (1,2,3); f2 = (0,1,3,4) shares only (0,1,3) with f0: a tree
    for ijks in [(0, 1, 2, 3), (1, 2, 3, 4), (0, 1, 3, 4)]:
        g.add_composition(ijks)
    assert nx.is_forest(g.to_networkx())
    r = loopy_bp(g, max_iters=50, tol=1e-13)
    assert r.converged and r.iterations < 50
    np.testing.assert_allclose(r.probabilities, brute_marginals(g), atol=1e-9)


def test_loopy_bp_reports_non_convergence_and_damping_runs():
    rng = np.random.default_rng(2)
    T = rand_T(rng, 3)
    g = random_graph(rng, T, n_land=5, frac=0.5)
    with pytest.warns(UserWarning, match="not converged after 1 iterations"):
        r = loopy_bp(g, max_iters=1)
    assert r.iterations == 1 and not r.converged
    d = loopy_bp(g, damping=0.5, max_iters=500, tol=1e-8)
    assert d.iterations <= 500
    np.testing.assert_allclose(d.probabilities.sum(axis=1), 1.0)
    assert np.all(d.probabilities >= 0)


def test_isc_hand_worked_on_copy_tensor():
    """T[a, b, c] = 1 iff a = b = c: composition copies the state. Prior (0.9, 0.1) on (0,1,2):
    (1,2,3) gets (0.9, 0.1) from one known (ISC = 1 - H(0.9)/ln 2 = 0.531004...), then (0,1,3)
    from two known: (0.81, 0.01) / 0.82."""
    T = np.zeros((2, 2, 2))
    T[0, 0, 0] = T[1, 1, 1] = 1.0
    g = one_factor_graph(T, [0.9, 0.1], None)
    r = propagate(g)
    h = -(0.9 * np.log(0.9) + 0.1 * np.log(0.1))
    assert r.isc[1] == pytest.approx(1 - h / np.log(2), abs=1e-12)
    assert r.isc[1] == pytest.approx(0.5310044064107189, abs=1e-12)
    np.testing.assert_allclose(r.probabilities[2], [0.81 / 0.82, 0.01 / 0.82], atol=1e-12)
    np.testing.assert_allclose(exact_marginals(g, method="gtsam")[2], [0.9, 0.1], atol=1e-12)


def test_compare_unseen_and_truth_states():
    from qfg.graph import truth_states
    from qfg.propagation import compare_unseen

    L = np.array([[0.0, 0.0], [0.0, 1.0], [-1.0, 0.5], [1.0, 0.5]])
    g = QualitativeFactorGraph("lr", tensor=rand_T(np.random.default_rng(0), 2))
    for t, p in [((0, 1, 2), [0.9, 0.1]), ((1, 2, 3), None), ((0, 1, 3), None)]:
        g.add_triplet(t, p)
    g.discover_compositions()
    truth = truth_states(g.triplets, L, "lr")
    # independent check: C left of the directed line A->B iff cross(B - A, C - A) > 0
    from qfg import partitions
    lr = partitions.get("lr")
    for (i, j, k), s in zip(g.triplets, truth, strict=True):
        d, e = L[j] - L[i], L[k] - L[i]
        cross = d[0] * e[1] - d[1] * e[0]
        left_state = int(lr.state_of(np.array([[-0.5, 0.5]]))[0])  # x < 0 in the AB frame
        assert (s == left_state) == (cross > 0)
    rows = compare_unseen(g, truth=truth)
    assert [r["triplet"] for r in rows] == [(1, 2, 3), (0, 1, 3)]
    ex = exact_marginals(g)
    r = propagate(g)
    for row, v in zip(rows, (1, 2), strict=True):
        np.testing.assert_allclose(row["exact"], ex[v])
        np.testing.assert_allclose(row["propagated"], r.probabilities[v])
        assert row["truth"] == truth[v]
    big = full_map(6, tensor=np.ones((20, 20, 20)))
    rows = compare_unseen(big, method="gtsam")
    assert rows[0]["exact"] is None and "entries" in rows[0]["exact_error"]
    with pytest.raises(ValueError, match="truth"):
        compare_unseen(g, truth=[0, 1])


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 4), st.floats(0.2, 0.6))
def test_outputs_are_distributions_and_scores_bounded(seed, m, frac):
    rng = np.random.default_rng(seed)
    g = random_graph(rng, rand_T(rng, m), n_land=5, frac=frac)
    r = propagate(g)
    b = loopy_bp(g, max_iters=30, warn=False)
    for M in (r.probabilities, b.probabilities):
        assert np.all(np.isfinite(M)) and np.all(M >= 0)
        np.testing.assert_allclose(M.sum(axis=1), 1.0, atol=1e-12)
    assert np.all((r.isc >= 0) & (r.isc <= 1))
    t = topology_scores(g)
    assert np.all((t.scores >= 0) & (t.scores <= 1))
    # a triplet is reached by Alg. 2 iff Alg. 3 and the composition levels reach it
    np.testing.assert_array_equal(r.reached, t.reached)
    np.testing.assert_array_equal(r.reached, np.isfinite(composition_levels(g).levels))
    # topology score never exceeds the best seen start (decay only loses information)
    if g.seen.any():
        assert t.scores.max() <= information_score(g.prior_matrix()[g.seen]).max() + 1e-12


def test_contradictory_priors_zero_mass():
    from qfg.propagation import ZeroMassError

    T = np.zeros((2, 2, 2))
    T[0, 0, 0] = T[1, 1, 1] = 1.0
    g = one_factor_graph(T, [1.0, 0.0], [0.0, 1.0])
    with pytest.raises(ZeroMassError):
        exact_marginals(g)
    r = propagate(g)
    np.testing.assert_allclose(r.probabilities[2], [0.5, 0.5])
    b = loopy_bp(g)
    assert np.all(np.isfinite(b.probabilities))
    np.testing.assert_allclose(b.probabilities.sum(axis=1), 1.0)


def test_close_used_reading_closes_the_factor_after_one_update():
    g = chain_graph()
    r = propagate(g, close_used=True)
    # f0 updates (1,2,3) and closes, so (0,1,3) is unreachable; f1 then updates (2,3,4) and closes
    assert r.order.tolist() == [1, 3]
    assert r.reached.tolist() == [True, True, False, True, False]
    np.testing.assert_allclose(r.probabilities[[2, 4]], 0.5)
    t = topology_scores(g, seen_score=1.0, close_used=True)
    np.testing.assert_allclose(t.scores, [1.0, 0.5, 0.0, 0.25, 0.0])
    c = composition_levels(g, close_used=True)
    np.testing.assert_array_equal(c.levels, [0, 1, np.inf, 2, np.inf])


@pytest.mark.parametrize("seed", range(30))
def test_best_first_engine_makes_the_choices_of_the_proposal_heap(seed):
    """Issue 19: Algorithm 2 keeps one best proposal per triplet (memory O(F)); it must pick
    the same triplet, factor and value at every step as the engine that heaps every proposal."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(2, 6))
    g = random_graph(rng, rand_T(rng, m), n_land=int(rng.integers(4, 8)),
                     frac=float(rng.uniform(0.1, 0.7)))
    for close_used in (False, True):
        a = propagate(g, close_used=close_used)
        b = propagate(g, close_used=close_used, _reference=True)
        np.testing.assert_array_equal(a.order, b.order)
        np.testing.assert_array_equal(a.updated_by, b.updated_by)
        np.testing.assert_array_equal(a.reached, b.reached)
        np.testing.assert_allclose(a.probabilities, b.probabilities, atol=1e-12)


def test_unchecked_information_score_is_the_metric():
    from qfg.metrics import information_score
    from qfg.propagation import _isc

    rng = np.random.default_rng(3)
    p = rng.dirichlet(np.full(20, 0.3), size=200)
    p[:5, :10] = 0.0
    p[:5] /= p[:5].sum(axis=1, keepdims=True)
    p[5] = np.eye(20)[3]
    p[6] = 1 / 20
    np.testing.assert_array_equal(_isc(p, np.log(20)), information_score(p))


def test_loopy_bp_memory_estimate_bounds_its_allocations():
    import tracemalloc

    from qfg.inference import loopy_bp_memory

    rng = np.random.default_rng(0)
    for L, m in ((9, 20), (8, 6)):
        g = full_map(L, partition=None, tensor=rng.random((m, m, m)))
        for t in g.triplets[::7]:
            g.add_triplet(t, rng.random(m))
        tracemalloc.start()
        loopy_bp(g, max_iters=2, warn=False)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        est = loopy_bp_memory(g.n_triplets, g.n_factors, m)
        assert peak <= est <= 3 * peak + 1e6
