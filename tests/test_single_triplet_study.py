"""The single-triplet study runs end to end at a tiny size through the runner, reproducibly."""

import csv
import json

import numpy as np

from qfg.harness import runner
from qfg.harness.studies import get_study
from qfg.harness.studies import single_triplet as st

TINY = {"n_scenarios": 2, "sigma_v_deg": [0.0, 2.0], "sigma_w_deg": [0.0, 5.0],
        "headline": [2.0, 5.0], "reference_noise": [[2.0, 5.0]],
        "options": {"reference": {"n_samples": 1500, "rounds": 1}, "full": {"n_samples": 200}},
        "views_sweep": [2, 4]}


def test_presets_and_tasks():
    presets = runner.load_presets("single-triplet")
    paper = presets["paper"]
    assert len(paper["sigma_v_deg"]) * len(paper["sigma_w_deg"]) == 36
    assert paper["n_scenarios"] == 300
    assert max(paper["sigma_v_deg"]) == 10 and max(paper["sigma_w_deg"]) == 20
    # the headline combination of Table 1 is in the grid, and the diagonal is sigma_w ~ 2 sigma_v
    assert 2.0 in paper["sigma_v_deg"] and 5.0 in paper["sigma_w_deg"]
    for sv, sw in zip(paper["sigma_v_deg"], paper["sigma_w_deg"], strict=True):
        assert sv == sw == 0 or 2 <= sw / sv <= 2.5
    tasks = st.tasks(presets["quick"])
    assert len(tasks) == presets["quick"]["n_scenarios"]
    assert get_study("single-triplet") is st.STUDY


def test_tiny_run(tmp_path):
    rows = runner.run_study(st.STUDY, TINY, tmp_path / "a", seed=3, progress=False)
    methods = st.DEFAULTS["methods"]
    main = [r for r in rows if not r["sweep"]]
    # every combination and method, plus the reference at its one combination
    assert len(main) == 2 * (4 * len(methods) + 1)
    assert sum(r["method"] == "reference" for r in main) == 2
    assert all((r["sigma_v_deg"], r["sigma_w_deg"]) == (2.0, 5.0)
               for r in main if r["method"] == "reference")
    sweep = [r for r in rows if r["sweep"]]
    assert sorted({r["n_views"] for r in sweep}) == [2, 4] and len(sweep) == 2 * 2 * len(methods)
    for r in rows:
        assert r["method"] in st.METHODS
        assert 0 <= r["dmse"] <= np.sqrt(2) + 1e-9 and r["gt_rating"] >= 1
        assert r["time_s"] > 0
        p = np.array([float(v) for v in r["p"].split()])
        assert abs(p.sum() - 1) < 1e-4
        # the scores in a row are those of its probabilities
        assert abs(r["log_score"] - np.log(max(p[r["gt_state"]], 1e-4))) < 1e-4
        assert abs(r["brier"] - (np.sum(p**2) - 2 * p[r["gt_state"]] + 1)) < 1e-4
    # the noise grid shares one geometry per scenario
    by = {(r["scenario"], r["method"]): r["gt_state"] for r in main}
    for r in main:
        assert r["gt_state"] == by[(r["scenario"], r["method"])]
    assert (tmp_path / "a" / "table1.md").exists()
    for name in ("dmse_vs_noise", "gmd_vs_noise", "entropy_vs_noise", "gt_rating_vs_noise",
                 "fast_motion_noise", "fast_measurement_noise", "dmse_grid", "views_sweep",
                 *(f"reliability_{m}" for m in methods + ["reference"])):
        assert (tmp_path / "a" / "figures" / f"{name}.png").exists(), name
    for name in ("scores.md", "views.md", "views.csv", "reference.md"):
        assert (tmp_path / "a" / name).exists()
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert set(summary["headline_dmse_p50"]) == set(methods) | {"reference"}
    b = summary["calibration_bound"]
    assert b["n"] == 2 and 0 <= b["median_entropy_5e-3"]["bound"] <= 1 / 0.9
    assert {v["n_views"] for v in summary["views"]} == {2, 4}
    agree = {r["method"]: r for r in summary["against_reference"]}
    assert set(agree) == set(methods) and all(r["n"] == 2 and r["kl_mean"] >= -1e-9
                                              for r in agree.values())
    # same seed, same rows (timings excluded), whatever the worker count
    runner.run_study(st.STUDY, TINY, tmp_path / "b", seed=3, workers=2, progress=False)
    a = list(csv.DictReader(open(tmp_path / "a" / "rows.csv")))
    b = list(csv.DictReader(open(tmp_path / "b" / "rows.csv")))
    assert a == b


def test_table_numbers_have_no_negative_zero():
    # rounding leaves percentiles of non-negative quantities at -0.0 or -1e-17; they print as 0,
    # while genuinely small and ordinary values keep their digits
    assert st._fmt(-0.0) == "0" and st._fmt(-1e-17) == "0" and st._fmt(3e-125) == "0"
    assert st._fmt(2e-5) == "2e-05" and st._fmt(0.456) == "0.46" and st._fmt(-0.25) == "-0.25"
    row = {"sigma_v_deg": 0.0, "sigma_w_deg": 0.0, "method": "full", "n": 3,
           "log_score_mean": -0.08, "log_score_se": 0.03, "brier_mean": 0.05, "top1": 0.96,
           "confidently_wrong": 0.0, "p_max_mean": 0.97, "ece_top": 0.04, "dmse_p50": -0.0,
           "entropy_p50": -0.0}
    last = st.scores_table([row], [(0.0, 0.0)]).splitlines()[-1]
    assert last.endswith("| 0.000 | 0 |"), last
    assert "-0" not in last.split("|")[-3] + last.split("|")[-2]
    row["entropy_p50"] = 0.0123
    assert st.scores_table([row], [(0.0, 0.0)]).splitlines()[-1].endswith("| 0.0123 |")
