"""The propagation study (paper 6f): graph generation, selection, determinism, resume, summary."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from toy_study import PROPAGATION_SMALL

from qfg.graph import QualitativeFactorGraph
from qfg.harness import runner
from qfg.harness.studies import propagation as P
from qfg.propagation import topology_scores

PARAMS = {**PROPAGATION_SMALL, "config_particles": 200}


def _table():
    return P._tensor({"random_tensor": True, "partition": "edc"})


@pytest.fixture(scope="module")
def full_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("prop") / "full"
    rows = runner.run_study(P.STUDY, PARAMS, out, seed=5, progress=False)
    return out, rows


def test_same_seed_byte_identical_with_1_and_2_workers(tmp_path, full_run):
    out, _ = full_run
    runner.run_study(P.STUDY, PARAMS, tmp_path / "w2", seed=5, workers=2, progress=False)
    assert (tmp_path / "w2" / "rows.csv").read_bytes() == (out / "rows.csv").read_bytes()
    runner.run_study(P.STUDY, PARAMS, tmp_path / "s6", seed=6, progress=False)
    assert (tmp_path / "s6" / "rows.csv").read_bytes() != (out / "rows.csv").read_bytes()


def test_killed_mid_run_and_resumed_equals_uninterrupted(tmp_path, full_run):
    out, _ = full_run
    # what a kill leaves: two finished scenarios and half of the third one's record
    lines = (out / "records.jsonl").read_bytes().splitlines(keepends=True)
    killed = tmp_path / "killed"
    killed.mkdir()
    shutil.copy(out / "run.json", killed / "run.json")
    (killed / "records.jsonl").write_bytes(b"".join(lines[:2]) + lines[2][: len(lines[2]) // 2])
    runner.run_study(P.STUDY, PARAMS, killed, seed=5, resume=True, progress=False)
    assert (killed / "rows.csv").read_bytes() == (out / "rows.csv").read_bytes()
    assert (killed / "bins.csv").read_bytes() == (out / "bins.csv").read_bytes()


def test_summary_has_the_headline_keys_and_figures(full_run):
    out, rows = full_run
    s = json.loads((out / "summary.json").read_text())
    assert s["n_graphs"] == PARAMS["n_graphs"]
    assert s["n_triplets"] == len(rows)
    for k in ("spearman_tsc_isc", "spearman_cl_isc", "pearson_tsc_isc", "pearson_cl_isc"):
        assert s[k] is None or -1 <= s[k] <= 1
    assert s["seed"] == 5 and s["command"]
    for f in ("figures/decay_model_correlation.png", "figures/tsc_vs_cl.png",
              "figures/example_graphs.png", "bins.csv"):
        assert (out / f).stat().st_size > 0


def test_rows_respect_coverage_rate_and_model_definitions(full_run):
    _, rows = full_run
    by = {}
    for r in rows:
        by.setdefault(r["scenario"], []).append(r)
    for rs in by.values():
        n_v = rs[0]["n_v"]
        assert len(rs) == n_v
        assert sum(r["seen"] for r in rs) == rs[0]["n_seen"] == round(0.5 * n_v)
        # every triplet of the graph belongs to one of its factors
        fs = [tuple(map(int, f.split("-"))) for f in rs[0]["factors"].split(";")]
        assert len(fs) == rs[0]["n_fc"]
        assert {r["triplet"] for r in rs} == {"-".join(map(str, t))
                                              for f in fs for t in P.factor_triplets(f)}
        for r in rs:
            if r["seen"]:
                # seen: TSC starts at the prior's ISC, TSC1 at 1, level 0
                assert r["tsc"] == r["isc"] and r["tsc1"] == 1.0 and r["cl"] == 0.0
            else:
                # at most one two-known step from two seen: (1 - alpha^2) (1 + 1) / 2
                assert r["tsc1"] <= 0.75 + 1e-12


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), cov=st.floats(0.05, 0.95), n_fc=st.integers(1, 30))
def test_candidate_graph_coverage_rate(seed, cov, n_fc):
    factors, triplets, seen, g = P.candidate_graph(np.random.default_rng(seed), 6, n_fc, cov,
                                                   np.ones((20, 20, 20)))
    n_v = len(triplets)
    assert len(set(factors)) == n_fc
    assert int(seen.sum()) == min(max(round(cov * n_v), 1), n_v - 1)
    assert g.seen.tolist() == seen.tolist() and g.n_factors == n_fc


def _entropy_of_hist(scores, n_bins=10):
    counts = np.zeros(n_bins)
    for x in scores:
        counts[min(int(x * n_bins), n_bins - 1)] += 1
    p = counts[counts > 0] / counts.sum()
    return float(-(p * np.log(p)).sum())


def test_connectivity_score_hand_worked():
    g = QualitativeFactorGraph("edc", tensor=np.ones((20, 20, 20)))
    g.add_triplet((0, 1, 2), np.ones(20))
    g.add_triplet((1, 2, 3))
    g.add_triplet((0, 1, 3))
    g.add_composition((0, 1, 2, 3))
    # TSC = [1, 0.5, 0.5]: bins 9, 5, 5
    want = -(2 / 3 * np.log(2 / 3) + 1 / 3 * np.log(1 / 3))
    assert P.connectivity_score(g) == pytest.approx(want)


def test_kept_graph_has_the_max_connectivity_among_its_candidates(full_run):
    _, rows = full_run
    tasks = P.STUDY.tasks(PARAMS)
    table = _table()
    for idx in range(len(tasks)):
        task = tasks[idx]
        # replay the scenario's stream: the candidates are drawn first
        rng = runner.scenario_rng(5, idx)
        cands = []
        for _ in range(task["n_candidates"]):
            n_fc = int(rng.integers(task["n_fc_min"], task["n_fc_max"] + 1))
            factors, triplets, seen, g = P.candidate_graph(rng, task["n_landmarks"], n_fc,
                                                           task["coverage_rate"], table)
            tsc = topology_scores(g, seen_score=1.0).scores
            cands.append((_entropy_of_hist(tsc), triplets, seen))
        scores = [c[0] for c in cands]
        rs = [r for r in rows if r["scenario"] == idx]
        best = int(np.argmax(scores))
        assert rs[0]["kept_candidate"] == best
        assert rs[0]["connectivity"] == pytest.approx(max(scores))
        assert [r["triplet"] for r in rs] == ["-".join(map(str, t)) for t in cands[best][1]]
        assert [r["seen"] for r in rs] == cands[best][2].astype(int).tolist()


def test_binned_percentiles_brute_force():
    rng = np.random.default_rng(0)
    x, y = rng.random(500), rng.random(500)
    x[:3] = [0.0, 1.0, 0.1]
    out = P.binned_percentiles(x, y, 10)
    assert sum(b["count"] for b in out) == 500
    for k, b in enumerate(out):
        sel = [yy for xx, yy in zip(x, y, strict=True)
               if (k / 10 <= xx < (k + 1) / 10) or (k == 9 and xx == 1.0)]
        assert b["count"] == len(sel)
        assert b["p50"] == pytest.approx(np.median(sel))


def test_bad_params():
    with pytest.raises(ValueError, match="unknown"):
        P.tasks({"n_graph": 3})
    with pytest.raises(ValueError, match="coverage_rate"):
        P.tasks({"coverage_rate": 1.5})
    with pytest.raises(ValueError, match="n_fc"):
        P.tasks({"n_landmarks": 4, "n_fc_max": 100})


# ----------------------------------------------------------------- qfg experiment all, results doc
def test_experiment_all_runs_studies_and_rebuilds_results_doc(tmp_path, monkeypatch):
    from qfg.harness import results_doc
    from qfg.harness.studies import _all

    exp = tmp_path / "experiments"
    exp.mkdir()
    tiny = ", ".join(f"{k} = {str(v).lower() if isinstance(v, bool) else v}"
                     for k, v in PARAMS.items())
    (exp / "propagation.toml").write_text(f"[quick]\n{tiny.replace(', ', chr(10))}\n")
    monkeypatch.setenv("QFG_EXPERIMENTS", str(exp))
    secs = tmp_path / "sections"
    secs.mkdir()
    (secs / "propagation.md").write_text("## Propagation\n\n    qfg experiment propagation\n\n"
                                         "![f](../figures/propagation/x.png)\n")
    (secs / "composition.md").write_text("## Composition\n\nno command here\n")
    doc = tmp_path / "results.md"
    # composition has no preset file in exp: recorded as failed, propagation still runs
    runs = _all.run_all("quick", root=tmp_path / "res", seed=2, progress=False,
                        only=["composition", "propagation"])
    assert runs[0]["error"] and "preset" in runs[0]["error"]
    assert runs[1]["rows"] > 0 and not runs[1].get("error")
    assert (tmp_path / "res" / "propagation-quick" / "rows.csv").exists()
    results_doc.write(doc, runs, results_dir=secs)
    text = doc.read_text()
    # paper order: composition before propagation; figure links rebased from docs/results/ to docs/
    assert text.index("## Composition") < text.index("## Propagation")
    assert "](figures/propagation/x.png)" in text
    assert "qfg experiment propagation --preset quick --seed 2" in text
    assert "| n_graphs | 4 |" in text
    assert results_doc.missing_commands(results_doc.sections(secs)) == ["composition"]


def test_scheduler_executor_is_closed_after_the_run(tmp_path, monkeypatch):
    from qfg.harness import cli, runner

    closed = []

    class Fake(runner.SerialExecutor):
        def close(self):
            closed.append(True)

    monkeypatch.setattr(runner, "make_executor", lambda workers=1, scheduler=None: Fake())
    exp = tmp_path / "experiments"
    exp.mkdir()
    (exp / "propagation.toml").write_text("[quick]\nn_graphs = 1\nrandom_tensor = true\n"
                                          "n_landmarks = 5\nn_fc_min = 2\nn_fc_max = 4\nn_candidates = 1\n")
    monkeypatch.setenv("QFG_EXPERIMENTS", str(exp))
    argv = ["experiment", "propagation", "--scheduler", "tcp://fake:1", "--no-progress",
            "--output", str(tmp_path / "o")]
    assert cli.main(argv) == 0
    assert closed == [True]
    # closed also when the run fails (used output directory without --resume)
    assert cli.main(argv) == 2
    assert closed == [True, True]


def test_experiment_all_doc_only_rebuilds_without_running(tmp_path, monkeypatch):
    from qfg.harness import cli, results_doc, runner

    calls = []
    monkeypatch.setattr(results_doc, "write", lambda *a, **k: calls.append((a, k)) or tmp_path / "r.md")
    monkeypatch.setattr(runner, "run_study", lambda *a, **k: pytest.fail("ran a study"))
    monkeypatch.chdir(tmp_path)
    # outside a checkout (no docs/results/ here) there is no document to rebuild: a clear error
    assert cli.main(["experiment", "all", "--doc-only"]) == 2
    (tmp_path / "docs" / "results").mkdir(parents=True)
    assert cli.main(["experiment", "all", "--doc-only"]) == 0
    assert calls == [((Path("docs/results.md"),), {"results_dir": Path("docs/results")})]


def test_experiment_all_writes_no_tracked_file_without_update_docs(tmp_path, monkeypatch):
    from qfg.harness import cli, results_doc, runner

    monkeypatch.setattr(results_doc, "write", lambda *a, **k: pytest.fail("wrote the results doc"))
    monkeypatch.setattr(runner, "run_study", lambda *a, **k: [])
    monkeypatch.chdir(tmp_path)
    assert cli.main(["experiment", "all", "--no-progress"]) == 0
    assert not (tmp_path / "docs").exists()


def test_map_methods_scored_on_seen_and_unseen_triplets(full_run):
    out, rows = full_run
    for r in rows:
        for m in ("prior", "alg2", "pooled", "config-state", "config-metric"):
            assert r[f"{m}_ls"] <= 0 and 0 <= r[f"{m}_pit"] <= 1 and 0 <= r[f"{m}_brier"] <= 2
        assert (r["solver_ls"] is None) == (not r["seen"])
    s = json.loads((out / "summary.json").read_text())
    got = {(t["triplets"], t["method"]) for t in s["scores"]}
    assert ("seen", "solver") in got and ("unseen", "config-metric") in got
    assert ("unseen", "solver") not in got
    assert (out / "scores.md").exists()


def test_randomized_pit_is_uniform_for_calibrated_forecasts():
    from qfg.harness.studies._map_methods import randomized_pit

    rng = np.random.default_rng(0)
    P = rng.dirichlet(np.full(5, 0.5), size=20_000)
    truth = (rng.random(20_000)[:, None] > np.cumsum(P, axis=1)).sum(axis=1)   # drawn from P
    pit = randomized_pit(P, truth, rng.random(20_000))
    hist = np.histogram(pit, bins=10, range=(0, 1))[0] / 20_000
    assert np.all(np.abs(hist - 0.1) < 0.01)
    # over-confident forecasts (the same ones sharpened) pile up in the top decile
    sharp = P ** 3 / (P ** 3).sum(axis=1, keepdims=True)
    assert np.mean(randomized_pit(sharp, truth, rng.random(20_000)) >= 0.9) > 0.15
