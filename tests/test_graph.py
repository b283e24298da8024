"""Tests of qfg.graph: building, key scheme, discovery, GTSAM/networkx export."""

import itertools

import gtsam
import networkx as nx
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qfg.graph import (
    QualitativeFactorGraph,
    brute_force_compositions,
    full_map,
    map_from_triplets,
    triplet_key,
)


def rand_T(rng, m):
    return rng.random((m, m, m)) * (rng.random((m, m, m)) < 0.7) + 1e-3 * (rng.random((m, m, m)) < .5)


def test_key_scheme_injective_and_independent_of_map():
    keys = {triplet_key(*t) for t in itertools.permutations(range(7), 3)}
    assert len(keys) == 7 * 6 * 5
    g1 = full_map(4, partition=None, tensor=np.ones((2, 2, 2)))
    g2 = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)))
    g2.add_triplet((3, 2, 1))
    g2.add_triplet((0, 1, 2))
    assert g1.key((0, 1, 2)) == g2.key((0, 1, 2)) == triplet_key(0, 1, 2)
    assert triplet_key(1, 0, 2) > triplet_key(0, 2**20 - 1, 2**20 - 2)


def test_full_map_counts_and_speed_scale():
    g = full_map(15, partition=None, tensor=np.ones((2, 2, 2)))
    assert g.n_triplets == 2730 and g.n_factors == 32760
    # every factor's triplets are in the documented roles
    fv = g.factor_vars
    ts = g.triplets
    for f in (0, 100, 32759):
        i, j, k, s = g.factors[f]
        assert [ts[v] for v in fv[f]] == [(i, j, k), (j, k, s), (i, j, s)]


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(4, 6), st.floats(0.1, 0.9))
def test_discovery_equals_brute_force_scan(seed, n_land, frac):
    rng = np.random.default_rng(seed)
    all_t = list(itertools.permutations(range(n_land), 3))
    chosen = [t for t in all_t if rng.random() < frac]
    g = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)))
    for t in chosen:
        g.add_triplet(t)
    g.discover_compositions()
    assert g.factors == brute_force_compositions(chosen)
    # idempotent
    assert g.discover_compositions() == 0


def test_brute_force_scan_is_itself_right_on_the_full_map():
    # independent count: 4 distinct ordered landmarks per factor
    assert len(brute_force_compositions(itertools.permutations(range(5), 3))) == 5 * 4 * 3 * 2


def test_table_order_matches_numpy_product():
    """gtsam marginals of prior x T x priors equal a brute-force numpy product (C-order table)."""
    rng = np.random.default_rng(1)
    m = 3
    T = rand_T(rng, m)
    g = QualitativeFactorGraph(None, tensor=T)
    ps = [rng.dirichlet(np.ones(m)) for _ in range(3)]
    for t, p in zip([(0, 1, 2), (1, 2, 3), (0, 1, 3)], ps, strict=True):
        g.add_triplet(t, p)
    assert g.discover_compositions() == 1
    joint = ps[0][:, None, None] * ps[1][None, :, None] * ps[2][None, None, :] * T
    joint /= joint.sum()
    expect = [joint.sum(axis=(1, 2)), joint.sum(axis=(0, 2)), joint.sum(axis=(0, 1))]
    fg = g.to_gtsam()
    assert fg.size() == 4
    marg = gtsam.DiscreteMarginals(fg)
    for v, t in enumerate(g.triplets):
        got = np.asarray(marg.marginalProbabilities((triplet_key(*t), m)))
        np.testing.assert_allclose(got, expect[v], atol=1e-12)
    # and the factor's value at each assignment is T[a, b, c]
    comp = fg.at(3)
    keys = [triplet_key(*t) for t in g.triplets]
    for a, b, c in itertools.product(range(m), repeat=3):
        vals = gtsam.DiscreteValues()
        vals[keys[0]], vals[keys[1]], vals[keys[2]] = a, b, c
        assert comp(vals) == pytest.approx(T[a, b, c], abs=1e-15)


def test_to_networkx_bipartite_with_attributes():
    g = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)))
    g.add_triplet((0, 1, 2), [1.0, 0.0])
    g.add_triplet((1, 2, 3), [1.0, 1.0])
    g.add_triplet((0, 1, 3))
    g.discover_compositions()
    G = g.to_networkx()
    assert nx.is_bipartite(G)
    assert G.number_of_nodes() == 3 + 2 + 1 and G.number_of_edges() == 2 + 3
    a = G.nodes[("v", 0, 1, 2)]
    assert a["seen"] and a["isc"] == pytest.approx(1.0) and a["prior"].tolist() == [1.0, 0.0]
    assert G.nodes[("v", 1, 2, 3)]["isc"] == pytest.approx(0.0)
    assert G.nodes[("v", 0, 1, 3)]["prior"] is None and not G.nodes[("v", 0, 1, 3)]["seen"]
    assert G.edges[("c", 0, 1, 2, 3), ("v", 0, 1, 3)]["role"] == 3


def test_prior_accepts_estimate_like_object_and_normalizes():
    class Est:
        landmark = np.array([2.0, 6.0])

    g = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)))
    v = g.add_triplet((0, 1, 2), Est())
    np.testing.assert_allclose(g.priors[v], [0.25, 0.75])
    assert g.add_triplet((0, 1, 2), None, replace=True) == v and g.priors[v] is None


def test_map_from_triplets_seen_plus_unseen():
    seen = {(0, 1, 2): [0.5, 0.5], (1, 2, 3): [0.2, 0.8]}
    g = map_from_triplets(seen, unseen=[(0, 1, 3), (1, 2, 3)], partition=None,
                          tensor=np.ones((2, 2, 2)))
    assert g.triplets == [(0, 1, 2), (1, 2, 3), (0, 1, 3)]
    assert g.seen.tolist() == [True, True, False] and g.factors == [(0, 1, 2, 3)]


@pytest.mark.parametrize("triplet, prior, match", [
    ((0, 0, 1), None, "triplet: landmark ids must be distinct"),
    ((0, 1), None, "triplet"),
    ((0, 1, 2.5), None, "triplet: landmark ids must be integers"),
    ((0, 1, -1), None, "triplet: landmark ids must be in"),
    ((0, 1, 2), [0.5, 0.5, 0.0], "prior: expected shape"),
    ((0, 1, 2), [-0.1, 1.1], "prior: expected non-negative"),
    ((0, 1, 2), [np.nan, 1], "prior: non-finite"),
    ((0, 1, 2), [0.0, 0.0], "prior: all zero"),
    ((0, 1, 2), "ab", "prior"),
])
def test_bad_input(triplet, prior, match):
    g = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)))
    with pytest.raises(ValueError, match=match):
        g.add_triplet(triplet, prior)


def test_bad_constructor_and_composition():
    with pytest.raises(ValueError, match="tensor"):
        QualitativeFactorGraph(None, tensor=np.ones((2, 3, 2)))
    with pytest.raises(ValueError, match="partition"):
        QualitativeFactorGraph("")
    g = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)))
    g.add_triplet((0, 1, 2))
    with pytest.raises(ValueError, match="ijks: triplet"):
        g.add_composition((0, 1, 2, 3))
    with pytest.raises(ValueError, match="triplet: .* not in the map"):
        g.index((5, 6, 7))
    with pytest.raises(ValueError, match="n_landmarks"):
        full_map(2, partition=None, tensor=np.ones((2, 2, 2)))


def test_tensor_none_loads_the_shipped_tensor_lazily(tmp_path, monkeypatch):
    from qfg import composition, partitions

    rng = np.random.default_rng(4)
    T = rng.random((2, 2, 2))
    T /= T.sum()
    ct = composition.CompositionTensor(
        partition="lr", T=T, support=T > 0, window=tuple(partitions.get("lr").window), samples_per_state=1,
        seed=0, quad_segs=8, version="test", sha256=composition.checksum(T), meta={})
    monkeypatch.setenv(composition.ENV_VAR, str(tmp_path))
    g = QualitativeFactorGraph("lr")
    g.add_triplet((0, 1, 2))          # unseen: no tensor needed yet
    assert g._table is None
    composition.save(composition.tensor_path("lr"), ct)
    g.add_triplet((0, 1, 3), [0.3, 0.7])
    np.testing.assert_allclose(g.table, T)
    assert g.m == 2


def test_map_from_histories_uses_solver_estimates():
    from qfg.graph import map_from_histories
    from qfg.simulation import random_scenario, triplet_histories
    from qfg.solvers import solve_triplets

    sc = random_scenario(np.random.default_rng(3), n_landmarks=5, n_poses=3, landmarks_per_view=4,
                         sigma_bearing=0.02, sigma_heading=0.05)
    hs = triplet_histories(sc)
    T = np.random.default_rng(0).random((20, 20, 20))
    seen_ts = {h.landmarks for h in hs}
    unseen = [t for t in itertools.permutations(range(5), 3) if t not in seen_ts][:4]
    g = map_from_histories(hs, unseen=unseen, tensor=T, seed=7)
    assert g.seen.sum() == len(hs) and g.n_triplets == len(hs) + len(unseen)
    ests = solve_triplets(hs, method="fast", seed=7)
    for h, e in zip(hs, ests, strict=True):
        np.testing.assert_allclose(g.priors[g.index(h.landmarks)], e.landmark / e.landmark.sum())
    assert g.factors == brute_force_compositions(g.triplets)


# ------------------------------------------------------------------ validation (issues 11, 12)
def test_partition_name_is_checked():
    """Issue 11 item 4: an unknown partition name was accepted."""
    with pytest.raises(ValueError, match="partition: unknown name 'nonsense'"):
        QualitativeFactorGraph("nonsense")
    with pytest.raises(ValueError, match="partition"):
        QualitativeFactorGraph(None)          # unlabelled needs a tensor
    assert QualitativeFactorGraph("EDC").partition == "edc"


def test_tensor_must_match_the_partition():
    """Issue 11 item 4: ("lr", tensor=<20x20x20>) was accepted."""
    with pytest.raises(ValueError, match="tensor: shape .*'lr' has 2 states"):
        QualitativeFactorGraph("lr", tensor=np.ones((20, 20, 20)))
    with pytest.raises(ValueError, match="tensor"):
        QualitativeFactorGraph("lr", tensor=-np.ones((2, 2, 2)))

    class Fake:                                 # a CompositionTensor of another partition
        partition = "fdc"
        T = np.ones((2, 2, 2))

    with pytest.raises(ValueError, match="tensor: a 'fdc' composition tensor"):
        QualitativeFactorGraph("lr", tensor=Fake())
    g = QualitativeFactorGraph(None, tensor=np.ones((3, 3, 3)))
    assert g.partition is None and g.m == 3


@pytest.mark.parametrize("ids", [(0, 1, 2**20), (-1, 1, 2), (0, 0, 1), (0, 1, 2.0), (True, 1, 2)])
def test_triplet_key_validates_ids(ids):
    """Issue 12 item 5: triplet_key(0, 1, 2**20) == triplet_key(0, 1, 0); negative keys."""
    with pytest.raises(ValueError, match="triplet"):
        triplet_key(*ids)


def test_triplet_key_injective_at_the_edges_of_the_range():
    top = 2**20 - 1
    ts = [(0, 1, top), (top, 0, 1), (1, top, 0), (top - 1, top, 0), (0, 1, 2)]
    keys = [triplet_key(*t) for t in ts]
    assert len(set(keys)) == len(ts) and min(keys) >= 0
    for t, k in zip(ts, keys, strict=True):               # decodes back to the ids
        assert (k >> 40, (k >> 20) & top, k & top) == t


@pytest.mark.parametrize("prior, expect", [
    ([1e308, 1e308], [0.5, 0.5]),                  # the sum overflows to inf
    ([1e308, 0.5e308], [2 / 3, 1 / 3]),
    ([1e200, 3e200], [0.25, 0.75]),
    ([1e-300, 3e-300], [0.25, 0.75]),
    ([0.0, 5e-324], [0.0, 1.0]),                   # subnormal
])
def test_prior_normalizes_without_overflow(prior, expect):
    """Issue 12 item 6: a prior of 1e308 entries was stored as all zeros."""
    g = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)))
    v = g.add_triplet((0, 1, 2), prior)
    p = g.priors[v]
    assert np.all(np.isfinite(p)) and p.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(p, expect, rtol=1e-12)


def test_graph_module_does_not_import_inference():
    """The graph -> propagation -> graph cycle is gone: graph.py imports no inference module."""
    import ast
    import inspect

    import qfg.graph

    tree = ast.parse(inspect.getsource(qfg.graph))
    mods = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    mods |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert not any("propagation" in m or "inference" in m for m in mods), mods


# ------------------------------------------------------------------ order-of-call mistakes
def test_propagate_before_any_composition_is_refused_and_after_discovery_answers():
    from qfg.propagation import propagate

    T = np.zeros((2, 2, 2))
    T[0, 0, 0] = T[1, 1, 1] = 1
    g = QualitativeFactorGraph("lr", tensor=T)
    for t, p in [((0, 1, 2), [0.9, 0.1]), ((1, 2, 3), [0.9, 0.1]), ((0, 1, 3), None)]:
        g.add_triplet(t, p)
    for method in ("best", "pooled"):
        with pytest.raises(ValueError, match=r"^g: .*discover_compositions"):
            propagate(g, method=method)
    assert not g.compositions_asked
    assert g.discover_compositions() == 1 and g.compositions_asked
    # the unseen triplet is composed from the two seen ones (all three equal under T)
    assert propagate(g)[(0, 1, 3)].argmax() == 0


def test_a_map_with_nothing_to_compose_answers_once_discovery_ran():
    from qfg.propagation import propagate

    g = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)))
    g.add_triplet((0, 1, 2), [0.9, 0.1])
    g.add_triplet((3, 4, 5))                            # shares no pair: no factor can exist
    assert g.discover_compositions() == 0
    assert propagate(g)[(3, 4, 5)].tolist() == [0.5, 0.5]


def test_a_map_of_seen_triplets_only_needs_no_composition():
    from qfg.propagation import propagate

    g = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)))
    g.add_triplet((0, 1, 2), [0.9, 0.1])
    np.testing.assert_allclose(propagate(g)[(0, 1, 2)], [0.9, 0.1])
