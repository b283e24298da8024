"""MRCLAM study: a synthetic MRCLAM-format directory (tests/test_mrclam.py's writer, known geometry)
through ``qfg mrclam`` and :func:`qfg.studies.mrclam.run_dataset`, with a small composition tensor
built here (16 samples per state) or a uniform one, never the shipped EDC tensor."""

from __future__ import annotations

import csv
import itertools
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_mrclam import LANDMARKS, write_dataset

from qfg import metrics
from qfg.datasets import mrclam
from qfg.harness.cli import main as qfg_main
from qfg.harness.studies import mrclam as study
from qfg.partitions import get as get_partition
from qfg.solvers import solve_triplets

EDC = get_partition("edc")
M = EDC.n_states
KEYS = ("dmse", "gmd", "entropy", "gt_rating")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("mrclam_study")
    write_dataset(root / "MRCLAM_Dataset1")
    write_dataset(root / "MRCLAM_Dataset2", robot2_odometry=False, truth_swap=(8, 9))
    return root


@pytest.fixture(scope="module")
def small_tensor(tmp_path_factory):
    from qfg.composition import save
    from qfg.composition.build import build

    path = tmp_path_factory.mktemp("tensor") / "edc.npz"
    save(path, build("edc", samples=16, seed=0, progress=False))
    return path


@pytest.fixture(scope="module")
def cli_run(data, small_tensor, tmp_path_factory):
    out = tmp_path_factory.mktemp("out") / "ds1"
    rc = qfg_main(["mrclam", str(data / "MRCLAM_Dataset1"), "--tensor", str(small_tensor),
                   "--output", str(out), "--seed", "3"])
    assert rc in (0, None)
    with open(out / "triplets.csv") as fh:
        rows = list(csv.DictReader(fh))
    return out, rows, json.loads((out / "summary.json").read_text())


def _truth_state(a, b, c):
    """EDC state of C in the AB frame from the synthetic geometry, independent of the study."""
    A, B, C = (np.array(LANDMARKS[x], dtype=float) for x in (a, b, c))
    u = B - A
    s = np.hypot(*u)
    ex, ey = np.array([u[1], -u[0]]) / s, u / s     # +y along AB, +x to the right of AB
    return int(EDC.state_of((C - A) @ np.stack([ex, ey], axis=1) / s))


def test_cli_summary_shape_and_percentiles_of_rows(cli_run):
    out, rows, summ = cli_run
    assert summ["n_triplets"] == 5 * 4 * 3 == len(rows)
    for kind in ("seen", "propagated", "uniform_seen", "uniform_propagated"):
        assert set(summ[kind]) >= set(KEYS)
        assert all(len(v) == 3 for v in summ[kind].values())
    for kind in ("seen", "propagated"):
        sel = [r for r in rows if r["kind"] == kind]
        assert len(sel) == summ[f"n_{kind}"] > 0
        for k in KEYS:
            want = np.percentile([float(r[k]) for r in sel], [25, 50, 75])
            assert np.allclose(summ[kind][k], want)
    assert summ["datasets"]["MRCLAM_Dataset1"]["n_triplets"] == 60
    figs = sorted(p.name for p in (out / "figures").iterdir())
    assert any("robot" in f for f in figs) and any("triplet" in f for f in figs)


def test_seen_rows_match_an_independent_solve_and_score(cli_run, data):
    _, rows, _ = cli_run
    ds = mrclam.load(data / "MRCLAM_Dataset1")
    hs = [h for r in sorted(ds.robots) for h in mrclam.triplet_histories(ds, r)]
    est = solve_triplets(hs, method="fast", seed=3)
    by: dict = {}
    for h, e in zip(hs, est, strict=True):
        by.setdefault(tuple(h.landmarks), []).append(e.landmark)
    seen = {(int(r["A"]), int(r["B"]), int(r["C"])): r for r in rows if r["kind"] == "seen"}
    assert set(seen) == set(by)
    assert {(8, 9, 10), (6, 7, 8)} <= {tuple(sorted(t)) for t in seen}
    for t, r in seen.items():
        p = np.prod(by[t], axis=0)
        p = p / p.sum() if p.sum() > 0 else np.mean(by[t], axis=0)
        g = _truth_state(*t)
        assert int(r["truth_state"]) == g
        assert np.isclose(float(r["dmse"]), metrics.dmse(p, g), atol=1e-9)
        assert np.isclose(float(r["gmd"]), metrics.gmd(p, g, EDC.centroids), atol=1e-9)
        assert np.isclose(float(r["entropy"]), metrics.entropy(p), atol=1e-9)
        assert int(r["gt_rating"]) == metrics.gt_rating(p, g)
        assert int(r["n_histories"]) == len(by[t])
        assert np.isclose(float(r["uniform_dmse"]), np.sqrt((1 - 1 / M) ** 2 + (M - 1) / M**2))
        assert np.isclose(float(r["uniform_entropy"]), np.log(M))
    assert all(r["method"] == "fast" for r in seen.values())
    # every ordered triplet of the five landmarks is in the map exactly once
    got = sorted((int(r["A"]), int(r["B"]), int(r["C"])) for r in rows)
    assert got == sorted(itertools.permutations(sorted(LANDMARKS), 3))


def test_uniform_tensor_propagates_nothing_and_baseline_and_swap_are_reported(data):
    # a uniform tensor carries no information: every propagated triplet stays uniform
    T = np.full((M, M, M), 1.0 / M**3)
    rows = study.run_dataset(data / "MRCLAM_Dataset2", tensor=T, seed=0)
    prop = [r for r in rows if r["kind"] == "propagated"]
    assert prop and all(np.isclose(r["dmse"], r["uniform_dmse"]) for r in prop)
    assert all(np.isclose(r["entropy"], np.log(M)) for r in prop)
    # robot 2 of this dataset has no odometry: its triplets are solved by the baseline
    r2 = [r for r in rows if r["robots"] == "2"]
    assert r2 and all(r["method"] == "baseline" for r in r2)
    assert all(r["method"] == "fast" for r in rows if r["robots"] == "1")
    # the ground truth of 8 and 9 is swapped in the file: detected, swapped back, reported
    assert {r["gt_swaps"] for r in rows} == {"8-9"}
    for r in rows:
        assert r["truth_state"] == _truth_state(r["A"], r["B"], r["C"])
    summ = study.summary(rows)
    assert summ["gt_swaps"] == ["8-9"] and summ["n_baseline"] == len(r2)
    # without the fix the states of triplets using 8 or 9 are scored against the wrong positions
    raw = study.run_dataset(data / "MRCLAM_Dataset2", tensor=T, seed=0, fix_landmarks=False)
    assert any(a["truth_state"] != b["truth_state"] for a, b in zip(rows, raw, strict=True))


def test_robot_subset_and_bad_arguments(data):
    T = np.full((M, M, M), 1.0 / M**3)
    rows = study.run_dataset(data / "MRCLAM_Dataset1", robots=[2], tensor=T, seed=0)
    seen = [r for r in rows if r["kind"] == "seen"]
    assert len(seen) == 6 and {r["robots"] for r in seen} == {"2"}
    with pytest.raises(ValueError, match="method"):
        study.run_dataset(data / "MRCLAM_Dataset1", method="slow", tensor=T)
    with pytest.raises(ValueError, match="combine"):
        study.run_dataset(data / "MRCLAM_Dataset1", combine="max", tensor=T)
    with pytest.raises(ValueError, match="robot"):
        study.run_dataset(data / "MRCLAM_Dataset1", robots=[9], tensor=T)


def test_runner_tasks_one_per_dataset(data, tmp_path):
    ts = study.tasks({"data": str(data)})
    assert [t["path"].rsplit("/", 1)[-1] for t in ts] == ["MRCLAM_Dataset1", "MRCLAM_Dataset2"]
    assert len(study.tasks({"data": str(data), "datasets": [2]})) == 1
    with pytest.raises(ValueError, match="datasets"):
        study.tasks({"data": str(data), "datasets": [7]})
    with pytest.raises(ValueError, match="unknown"):
        study.tasks({"data": str(data), "colour": 1})
    from qfg.harness.runner import load_presets

    presets = load_presets("mrclam")
    assert {"quick", "paper"} <= set(presets)
    for p in presets.values():
        study._params(p)
        assert "data" not in p   # no machine path in the presets


def test_runner_data_directory_from_the_environment(data, monkeypatch):
    monkeypatch.setenv(mrclam.DATA_ENV, str(data))
    assert [t["path"].rsplit("/", 1)[-1] for t in study.tasks({})] == [
        "MRCLAM_Dataset1", "MRCLAM_Dataset2"]
    monkeypatch.delenv(mrclam.DATA_ENV)
    with pytest.raises(ValueError, match=mrclam.DATA_ENV):
        study.tasks({})


# ------------------------------------------------------------------------- combining estimates
probs = st.lists(st.floats(0.0, 1.0), min_size=4, max_size=4).filter(lambda v: sum(v) > 1e-3)


def _norm(v):
    v = np.asarray(v, dtype=float)
    return v / v.sum()


@settings(max_examples=60, deadline=None)
@given(st.lists(probs, min_size=1, max_size=4))
def test_product_combination_is_bayes_for_independent_evidence(vs):
    P = np.array([_norm(v) for v in vs])
    p, fb = study.combine_estimates(P, "product")
    assert np.isclose(p.sum(), 1.0) and np.all(p >= 0)
    prod = P.prod(axis=0)
    if prod.sum() > 1e-300:
        assert not fb and np.allclose(p, prod / prod.sum(), atol=1e-9)
    # order does not matter, and a uniform estimate adds nothing
    assert np.allclose(study.combine_estimates(P[::-1], "product")[0], p)
    assert np.allclose(study.combine_estimates(np.vstack([P, np.full(4, 0.25)]), "product")[0], p)


def test_combination_fallback_and_other_rules():
    a, b = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.5, 0.5])
    p, fb = study.combine_estimates([a, b], "product")
    assert fb and np.allclose(p, [0.5, 0.25, 0.25])
    assert np.allclose(study.combine_estimates([a, b], "best")[0], a)
    assert np.allclose(study.combine_estimates([a, b], "mean")[0], [0.5, 0.25, 0.25])
    with pytest.raises(ValueError, match="combine"):
        study.combine_estimates([a], "vote")
    with pytest.raises(ValueError, match="p"):
        study.combine_estimates([[0.5, 0.6]])


def test_study_runs_through_the_runner(data, small_tensor, tmp_path):
    from qfg.harness.runner import run_study

    out = tmp_path / "run"
    rows = run_study(study.STUDY, {"data": str(data), "datasets": [1], "robots": [2],
                                   "tensor": str(small_tensor)}, out, progress=False)
    assert len(rows) == 60 and {r["dataset"] for r in rows} == {"MRCLAM_Dataset1"}
    summ = json.loads((out / "summary.json").read_text())
    assert summ["n_triplets"] == 60 and summ["n_seen"] == 6
    assert set(summ["datasets"]) == {"MRCLAM_Dataset1"}
    assert (out / "triplets.csv").exists() and any((out / "figures").iterdir())


def test_chunked_solving_gives_the_same_fast_rows(data, monkeypatch):
    T = np.full((M, M, M), 1.0 / M**3)
    whole = study.run_dataset(data / "MRCLAM_Dataset1", tensor=T, seed=0)
    monkeypatch.setattr(study, "CHUNK", 7)      # 66 histories -> 10 chunks
    parts = study.run_dataset(data / "MRCLAM_Dataset1", tensor=T, seed=0)
    keys = ("A", "B", "C", "dmse", "entropy", "gt_rating", "n_histories", "method")
    assert [[r[k] for k in keys] for r in whole] == [[r[k] for k in keys] for r in parts]
