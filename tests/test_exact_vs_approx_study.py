"""The exact-vs-approximate study: same graphs as the propagation study, exact rows exact."""

import numpy as np
import pytest

from qfg.harness.runner import load_presets, run_study
from qfg.harness.studies import exact_vs_approx as eva
from qfg.harness.studies import propagation as prop

SMALL = {"n_graphs": 3, "random_tensor": True, "n_fc_min": 3, "n_fc_max": 8, "n_candidates": 3,
         "config_particles": 200}


def test_presets_use_the_propagation_study_graph_parameters():
    mine, theirs = load_presets("exact-vs-approx"), load_presets("propagation")
    for preset in ("quick", "paper"):
        for k, v in theirs[preset].items():
            assert mine[preset][k] == v, (preset, k)
    assert mine["paper"]["n_graphs"] == 5400


def test_same_graphs_as_the_propagation_study_and_exact_rows_exact(tmp_path):
    rows = run_study(eva.STUDY, SMALL, tmp_path / "e", seed=3, progress=False)
    prow = run_study(prop.STUDY, SMALL, tmp_path / "p", seed=3, progress=False)
    a = {(r["scenario"], r["triplet"]): r for r in rows if not r["seen"]}
    b = {(r["scenario"], r["triplet"]): r for r in prow if not r["seen"]}
    assert set(a) == set(b) and a
    for k, r in a.items():  # Algorithm 2 and Algorithm 3 on the same graph give the same numbers
        assert r["alg2_isc"] == pytest.approx(b[k]["isc"], abs=1e-12)
        assert r["tsc"] == pytest.approx(b[k]["tsc"], abs=1e-12)
        assert r["truth"] == b[k]["truth"]
        if not r["zero_mass"]:
            assert r["exact_tv"] == 0.0 and r["exact_kl"] == 0.0
            for m in eva.APPROX:
                assert 0.0 <= r[f"{m}_tv"] <= 1.0 + 1e-12 and r[f"{m}_kl"] >= 0.0
    # the map methods run on the same graphs with the same seeds: the same scores, seen and unseen
    a_all = {(r["scenario"], r["triplet"]): r for r in rows}
    b_all = {(r["scenario"], r["triplet"]): r for r in prow}
    assert set(a_all) == set(b_all)
    for k, r in a_all.items():
        for m in ("prior", "solver", "alg2", "pooled", "config-state", "config-metric"):
            assert r[f"{m}_ls"] == b_all[k][f"{m}_ls"] and r[f"{m}_pit"] == b_all[k][f"{m}_pit"]
    assert (tmp_path / "e" / "scores.md").exists()
    assert (tmp_path / "e" / "table.md").exists()
    assert (tmp_path / "e" / "figures" / "exact_vs_approx.png").exists()


def test_loopy_bp_is_exact_on_tree_graphs_of_the_study(tmp_path):
    rows = run_study(eva.STUDY, {**SMALL, "n_graphs": 4}, tmp_path, seed=5, progress=False)
    tree = [r for r in rows if not r["has_loop"] and not r["zero_mass"] and not r["seen"]]
    assert tree
    for r in tree:
        assert r["bp_tv"] < 1e-8


def test_bad_params():
    with pytest.raises(ValueError, match="n_graphs"):
        eva.tasks({"n_graphs": -1})
    with pytest.raises(ValueError, match="bp_damping"):
        eva.tasks({"bp_damping": 1.0})
    with pytest.raises(ValueError, match="params"):
        eva.tasks({"max_triplets": 3})


def test_tv_kl_against_hand_values():
    p = np.array([[0.5, 0.5]])
    q = np.array([[0.25, 0.75]])
    tv, kl = eva._tv_kl(p, q)
    assert tv[0] == pytest.approx(0.25)
    assert kl[0] == pytest.approx(0.5 * np.log(2) + 0.5 * np.log(0.5 / 0.75))


def test_propagation_graph_keeps_hypotheses_without_changing_the_graph():
    from qfg.random_graphs import propagation_graph

    T = eva._tensor({"random_tensor": True, "partition": "edc"})
    kw = {"n_fc_min": 3, "n_fc_max": 6, "n_candidates": 2}
    a = propagation_graph(np.random.default_rng(7), T, **kw)
    b = propagation_graph(np.random.default_rng(7), T, **kw, hypotheses=True)
    assert a.hypotheses is None
    assert a.graph.triplets == b.graph.triplets and np.array_equal(a.landmarks, b.landmarks)
    seen = [t for t, s in zip(b.graph.triplets, b.graph.seen, strict=True) if s]
    assert sorted(b.hypotheses) == sorted(seen)
    for pa, pb in zip(a.graph.priors, b.graph.priors, strict=True):
        assert (pa is None) == (pb is None)
        if pa is not None:
            assert np.array_equal(pa, pb)       # the same estimates as the batched solve
    h = b.hypotheses[seen[0]]
    assert h.landmark_samples.shape[1] == 2 and np.isclose(h.landmark_weights.sum(), 1.0)
