"""MRCLAM study: a synthetic MRCLAM-format directory (tests/test_mrclam.py's writer, known geometry,
motion capture for robot 1) through ``qfg mrclam`` and :func:`run_dataset`, with a small
composition tensor built here (16 samples per state) or a uniform one, never the shipped tensor;
and the real dataset 6 (skipped when the data are absent)."""

from __future__ import annotations

import csv
import dataclasses
import itertools
import json

import numpy as np
import pytest
from test_mrclam import LANDMARKS, T0, pose1, write_dataset

from qfg import metrics
from qfg.combine import combine_posteriors, prior_state_distribution
from qfg.datasets import mrclam
from qfg.geometry import bearing, wrap_angle
from qfg.harness.cli import main as qfg_main
from qfg.harness.studies import mrclam as study
from qfg.harness.studies.mrclam import MrclamParams as P
from qfg.partitions import get as get_partition
from qfg.solvers import solve_triplets

EDC = get_partition("edc")
M = EDC.n_states
UNIFORM_T = np.full((M, M, M), 1.0 / M**3)


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
                   "--output", str(out), "--seed", "3", "--curve", "3,0", "--method", "fast",
                   "--combine", "prior-once", "--max-gap", "10", "--spread-views", "0", "--no-distances",
                   "--map", "pooled"])
    assert rc in (0, None)
    with open(out / "triplets.csv") as fh:
        rows = list(csv.DictReader(fh))
    with open(out / "cameras.csv") as fh:
        cams = list(csv.DictReader(fh))
    return out, rows, cams, json.loads((out / "summary.json").read_text())


def _truth_state(a, b, c):
    """EDC state of C in the AB frame from the synthetic geometry, independent of the study."""
    A, B, C = (np.array(LANDMARKS[x], dtype=float) for x in (a, b, c))
    u = B - A
    s = np.hypot(*u)
    ex, ey = np.array([u[1], -u[0]]) / s, u / s     # +y along AB, +x to the right of AB
    return int(EDC.state_of((C - A) @ np.stack([ex, ey], axis=1) / s))


def test_cli_writes_every_row_score_and_summary(cli_run):
    out, rows, cams, summ = cli_run
    assert len(rows) == 5 * 4 * 3 and {r["kind"] for r in rows} <= {"seen", "propagated"}
    assert cams and {r["kind"] for r in cams} == {"camera"}
    for r in rows + cams:
        p = study.decode(r["probabilities"])
        g = int(r["truth_state"])
        assert np.isclose(float(r["p_truth"]), p[g], atol=1e-5)
        assert np.isclose(float(r["log_score"]), np.log(max(p[g], 1e-4)), atol=1e-4)
        assert np.isclose(float(r["brier"]), metrics.brier(p, g), atol=1e-5)
        assert np.isclose(float(r["uniform_log_score"]), -np.log(M))
        assert float(r["uniform_gt_rating"]) == (M + 1) / 2          # ties split, not 1
    for kind, sel in (("seen", [r for r in rows if r["kind"] == "seen"]),
                      ("propagated", [r for r in rows if r["kind"] == "propagated"]),
                      ("camera", cams)):
        s = summ["honest"][kind]
        assert s["n"] == len(sel)
        if not sel:
            continue
        for k in ("log_score", "brier", "gt_rating", "truth_under_1pct", "prior_log_score",
                  "uniform_brier", "flagged"):
            assert np.isclose(s[k], np.mean([float(r[k]) for r in sel]))
    figs = sorted(p.name for p in (out / "figures").iterdir())
    assert "reliability_honest.png" in figs and "views_curve.png" in figs
    assert any("robot" in f for f in figs)
    curve = list(csv.DictReader(open(out / "curve.csv")))
    assert {int(r["max_views"]) for r in curve} == {3, 0}
    three = [float(r["views_median"]) for r in curve if r["max_views"] == "3"]
    assert three and max(three) <= 3


def test_seen_rows_are_the_combined_independent_solves(cli_run, data):
    _, rows, _, _ = cli_run
    ds = mrclam.load(data / "MRCLAM_Dataset1")
    pr = study.make_prior(ds, "arena")
    # without the odometry's distances, as the study solves by default
    hs = [dataclasses.replace(h, distances=None) for r in sorted(ds.robots)
          for h in mrclam.triplet_histories(ds, r, min_travel=0.02)]
    est = solve_triplets(hs, method="fast", seed=np.random.SeedSequence(3).spawn(1)[0], prior=pr)
    q = prior_state_distribution(pr, samples=study.PRIOR_SAMPLES, seed=1)
    by: dict = {}
    for h, e in zip(hs, est, strict=True):
        by.setdefault(tuple(h.landmarks), []).append(e.landmark)
    seen = {(int(r["A"]), int(r["B"]), int(r["C"])): r for r in rows if r["kind"] == "seen"}
    assert set(seen) == set(by)
    for t, r in seen.items():
        # the prior counted once: prod p_i / q^(k - 1), written out here
        lp = np.log(np.maximum(by[t], 1e-300)).sum(axis=0) - (len(by[t]) - 1) * np.log(q)
        p = np.exp(lp - lp.max())
        p /= p.sum()
        assert np.allclose(p, combine_posteriors(by[t], q).probabilities, atol=1e-9)
        g = _truth_state(*t)
        assert int(r["truth_state"]) == g
        assert np.isclose(float(r["p_truth"]), p[g], atol=1e-5)
        assert np.isclose(float(r["prior_log_score"]), np.log(max(q[g], 1e-4)), atol=1e-9)
        assert int(r["n_histories"]) == len(by[t])
    got = sorted((int(r["A"]), int(r["B"]), int(r["C"])) for r in rows)
    assert got == sorted(itertools.permutations(sorted(LANDMARKS), 3))


def test_camera_rows_score_against_the_captured_poses(cli_run, data):
    _, _, cams, _ = cli_run
    assert {r["robot"] for r in cams} == {"1"}                 # only robot 1 has a capture
    for r in cams[::7]:
        A, B = (np.array(LANDMARKS[int(r[k])], float) for k in ("A", "B"))
        X = pose1(float(r["time"]) - T0)[:2]
        u = B - A
        s = np.hypot(*u)
        ex, ey = np.array([u[1], -u[0]]) / s, u / s
        assert int(r["truth_state"]) == int(EDC.state_of((X - A) @ np.stack([ex, ey], 1) / s))


def test_paper_mode_recomputes_inputs_from_the_capture(data):
    ds = mrclam.load(data / "MRCLAM_Dataset1")
    hp = study.histories(ds, mode="paper", min_travel=0.02)
    hm = {(tuple(h.landmarks), h.views[0]): h for _, h in study.histories(ds, min_travel=0.02)}
    assert hp and {r for r, _ in hp} == {1}
    for _, h in hp:
        m = hm[(tuple(h.landmarks), h.views[0])]
        # the synthetic measurements are exact (3-decimal stamps): clean inputs agree with them
        assert np.abs(wrap_angle(h.bearings - m.bearings)).max() < 2e-3
        P = h.truth.poses_world
        assert np.allclose(h.bearings, bearing(P[:, None], h.truth.landmarks_world[None]))
        # distances from the capture too, not the odometry's
        assert np.allclose(h.distances, np.hypot(*np.diff(P[:, :2], axis=0).T))
    with pytest.raises(ValueError, match="mode"):
        study.histories(ds, robots=[2], mode="paper")
    with pytest.raises(ValueError, match="mode"):
        study.histories(ds, mode="clean")


def test_truncate_and_arena(data):
    ds = mrclam.load(data / "MRCLAM_Dataset1")
    h = max((h for _, h in study.histories(ds, robots=[1], min_travel=0.02)),
            key=lambda h: h.n_views)
    t = study.truncate(h, 3)
    assert t.n_views == 3 and t.headings.shape == (2,) and t.distances.shape == (2,)
    assert np.array_equal(t.truth.camera_states, h.truth.camera_states[:3])
    assert study.truncate(h, 0) is h
    e = study.arena_extent(ds)
    L = np.array(list(LANDMARKS.values()))
    gt = ds.robot(1).groundtruth[:, 1:3]
    assert e["robots_from"] == "motion capture"
    assert e["x"][0] <= L[:, 0].min() and e["x"][1] >= L[:, 0].max()
    assert e["y"][0] <= L[:, 1].min() and e["y"][1] >= L[:, 1].max()
    assert e["x"][0] >= min(L[:, 0].min(), gt[:, 0].min()) - 1e-9
    assert e["y"][1] <= max(L[:, 1].max(), gt[:, 1].max()) + 1e-9
    pr = study.make_prior(ds, "arena")
    assert np.isclose(pr.width, e["width"]) and np.isclose(pr.height, e["height"])
    with pytest.raises(ValueError, match="prior"):
        study.make_prior(ds, "flat")


def test_uniform_tensor_propagates_nothing_baseline_and_swap_reported(data):
    # robot 2 alone sees one triplet (landmarks 8, 9, 10): the rest of the map is propagated
    rows = study.run_dataset(data / "MRCLAM_Dataset2", P(robots=[2]), tensor=UNIFORM_T, seed=0)
    prop = [r for r in rows if r["kind"] == "propagated"]
    assert prop and all(np.isclose(r["log_score"], r["uniform_log_score"]) for r in prop)
    r2 = [r for r in rows if r["kind"] == "seen" and r["robots"] == "2"]
    assert r2 and all(r["method"] == "baseline" for r in r2)
    assert {r["gt_swaps"] for r in rows} == {"8-9"}
    for r in rows:
        if r["kind"] != "camera":
            assert r["truth_state"] == _truth_state(r["A"], r["B"], r["C"])
    summ = study.summary(rows)
    assert summ["gt_swaps"] == ["8-9"]
    assert summ["honest"]["n_baseline"] == len(r2)


def test_bad_arguments_and_product_rule(data):
    with pytest.raises(ValueError, match="method"):
        study.run_dataset(data / "MRCLAM_Dataset1", P(method="slow"), tensor=UNIFORM_T)
    with pytest.raises(ValueError, match="combine"):
        study.run_dataset(data / "MRCLAM_Dataset1", P(combine="max"), tensor=UNIFORM_T)
    with pytest.raises(ValueError, match="robot"):
        study.run_dataset(data / "MRCLAM_Dataset1", P(robots=[9]), tensor=UNIFORM_T)
    # the options of the run are the params object's, not keywords of run_dataset
    with pytest.raises(TypeError, match="MrclamParams"):
        study.run_dataset(data / "MRCLAM_Dataset1", robots=[1])
    # the rules are about combining: the fast solver's estimates serve as well as the full one's
    opts = P(robots=[1], propagate=False, max_gap=10.0, spread_views=0, method="fast")
    a = study.run_dataset(data / "MRCLAM_Dataset1", opts.replace(combine="prior-once"), seed=0)
    b = study.run_dataset(data / "MRCLAM_Dataset1", opts.replace(combine="product"), seed=0)
    c = study.run_dataset(data / "MRCLAM_Dataset1", opts.replace(combine="geometric"), seed=0)
    assert all(r["kind"] in ("seen", "camera") for r in a)
    multi = [(x, y) for x, y in zip(a, b, strict=True)
             if x["kind"] == "seen" and x["n_histories"] > 1]
    single = [(x, y) for x, y in zip(a, b, strict=True)
              if x["kind"] == "seen" and x["n_histories"] == 1]
    assert all(np.isclose(x["p_truth"], y["p_truth"]) for x, y in single)
    assert multi and any(not np.isclose(x["p_truth"], y["p_truth"]) for x, y in multi)
    # one history: every rule returns its estimate
    for x, z in zip(a, c, strict=True):
        if x["kind"] == "seen" and x["n_histories"] == 1:
            assert np.isclose(x["p_truth"], z["p_truth"])


def test_runner_tasks_presets_and_environment(data, monkeypatch):
    ts = study.tasks({"data": str(data)})
    assert [t["path"].rsplit("/", 1)[-1] for t in ts] == ["MRCLAM_Dataset1", "MRCLAM_Dataset2"]
    with pytest.raises(ValueError, match="datasets"):
        study.tasks({"data": str(data), "datasets": [7]})
    with pytest.raises(ValueError, match="unknown"):
        study.tasks({"data": str(data), "colour": 1})
    with pytest.raises(ValueError, match="mode"):
        study.tasks({"data": str(data), "mode": "clean"})
    from qfg.harness.runner import load_presets

    presets = load_presets("mrclam")
    assert {"quick", "paper"} <= set(presets)
    for p in presets.values():
        study.experiment_params(p)
        assert "data" not in p   # no machine path in the presets
    monkeypatch.setenv(mrclam.DATA_ENV, str(data))
    assert len(study.tasks({})) == 2
    monkeypatch.delenv(mrclam.DATA_ENV)
    with pytest.raises(ValueError, match=mrclam.DATA_ENV):
        study.tasks({})


def test_study_runs_through_the_runner(data, small_tensor, tmp_path):
    from qfg.harness.runner import run_study

    out = tmp_path / "run"
    rows = run_study(study.STUDY, {"data": str(data), "datasets": [1], "robots": [2],
                                   "tensor": str(small_tensor)}, out, progress=False)
    assert {r["dataset"] for r in rows} == {"MRCLAM_Dataset1"}
    summ = json.loads((out / "summary.json").read_text())
    assert summ["honest"]["seen"]["n"] == 6 and summ["honest"]["camera"]["n"] == 0
    assert (out / "triplets.csv").exists() and any((out / "figures").iterdir())


# ------------------------------------------------------------------------- the real dataset 6
def _real6():
    import os
    from pathlib import Path

    root = os.environ.get(mrclam.DATA_ENV) or str(Path(__file__).parents[2] / "shared/data/mrclam")
    d = Path(root) / "MRCLAM_Dataset6"
    if not d.is_dir():
        pytest.skip("MRCLAM dataset 6 not available")
    return d


def test_real_dataset6_camera_states_and_paper_mode_score():
    d = _real6()
    opts = P(robots=[4], propagate=False, max_views=4, method="fast")
    rows = study.run_dataset(d, opts, seed=0)
    cams = [r for r in rows if r["kind"] == "camera"]
    assert cams and all(0 <= r["truth_state"] < M for r in cams)
    assert all(np.isfinite(r["log_score"]) and r["log_score"] >= np.log(1e-4) for r in cams)
    paper = study.run_dataset(d, opts.replace(mode="paper"), seed=0)
    assert {r["mode"] for r in paper} == {"paper"} and any(r["kind"] == "seen" for r in paper)


def test_spread_views_get_headings_of_their_own_steps(data):
    # robot 1 drives a circle at omega = W: the chord between views dt apart turns by W dt / 2,
    # whichever views are kept (tests/test_mrclam.py checks the loader's headings the same way)
    from test_mrclam import W

    ds = mrclam.load(data / "MRCLAM_Dataset1")
    long = [h for _, h in study.histories(ds, robots=[1], min_travel=0.02) if h.n_views >= 7]
    sp = {(tuple(h.landmarks), h.views[0]): h
          for _, h in study.histories(ds, robots=[1], min_travel=0.02, spread_views=3)}
    assert long
    for h in long:
        s = sp[(tuple(h.landmarks), h.views[0])]
        assert s.n_views == 3 and s.views[0] == h.views[0] and s.views[-1] == h.views[-1]
        assert np.allclose(s.headings, W * np.diff(s.views) / 2, atol=1e-6)
        assert np.allclose(s.bearings, h.bearings[np.searchsorted(h.views, s.views)])
        assert np.all(s.distances > h.distances.max())


def test_noise_model_options_reach_the_histories_and_the_solver(data):
    # --heading-walk: each step's sigma b sqrt(dt) from the views' times (never below the
    # loader's); --distance-tail measured: the core sigma on the histories, the tail for the
    # solvers (not for the baseline, which has no distances)
    p = data / "MRCLAM_Dataset1"
    plain = study.prepare_run(p, P(robots=[1], spread_views=4))
    prep = study.prepare_run(p, P(robots=[1], spread_views=4, heading_walk=2.0,
                             distance_tail="measured"))
    sd, tail = study.DISTANCE_TAILS["measured"]
    assert prep.solver_options["distance_tail"] == tail
    for (_, h0), (_, h) in zip(plain.histories, prep.histories, strict=True):
        want = np.maximum(h0.sigma_heading, np.deg2rad(2.0) * np.sqrt(np.diff(h0.views)))
        np.testing.assert_allclose(np.broadcast_to(h.sigma_heading, want.shape), want)
        assert h.sigma_distance_ratio == sd
    assert any(np.ndim(h.sigma_heading) == 1 for _, h in prep.histories)
    est = study.solve_piece(prep, 0, method="fast", seed=0, piece=4)
    assert len(est) == 4
    assert study.solve_piece(prep, 0, method="baseline", seed=0, piece=2)
    with pytest.raises(ValueError, match="heading_walk: one heading model at a time"):
        study.prepare_run(p, P(robots=[1], heading_walk=1.0, heading_drift=True))
    with pytest.raises(ValueError, match="distance_tail: expected one of"):
        study.prepare_run(p, P(robots=[1], distance_tail="wide"))
    # --camera-prior joint: to the full/fast solvers (the baseline has no such option), absent
    # at its default so that older runs solve as before
    assert plain.solver_options["camera_prior"] is None
    joint = study.prepare_run(p, P(robots=[1], spread_views=4, camera_prior="joint"))
    assert joint.solver_options["camera_prior"] == "joint"
    a = study.solve_piece(joint, 0, method="fast", seed=0, piece=4)
    b = study.solve_piece(plain, 0, method="fast", seed=0, piece=4)
    assert any(not np.array_equal(x.landmark, y.landmark) for x, y in zip(a, b, strict=True))
    assert study.solve_piece(joint, 0, method="baseline", seed=0, piece=2)
    with pytest.raises(ValueError, match="camera_prior: expected one of"):
        study.prepare_run(p, P(robots=[1], camera_prior="pairs"))
    # --budget F: the full/fast solvers' budget keys at F times their defaults, absent at 1;
    # the solver then gets exactly that budget (the answers differ from the default's)
    assert plain.solver_options["budget"] is None
    big = study.prepare_run(p, P(robots=[1], spread_views=4, budget=0.5))
    assert big.solver_options["budget"] == 0.5
    seen = {}
    import qfg.solvers as solvers

    def spy(*args, **kw):
        seen.update(kw)
        return orig(*args, **kw)

    orig = solvers.solve_triplets
    solvers.solve_triplets = spy
    try:
        study.solve_piece(big, 0, method="fast", seed=0, piece=2)
    finally:
        solvers.solve_triplets = orig
    from qfg.solvers.common.options import DEFAULTS

    assert seen["n_samples"] == round(DEFAULTS["fast"]["n_samples"] * 0.5)
    assert seen["max_hypotheses"] == round(DEFAULTS["fast"]["max_hypotheses"] * 0.5)
    assert "budget" not in seen
    with pytest.raises(ValueError, match="budget: the baseline solver has no budget factor"):
        study.solve_piece(big, 0, method="baseline", seed=0, piece=2)
    with pytest.raises(ValueError, match="budget: expected a factor > 0"):
        study.prepare_run(p, P(robots=[1], budget=0.0))
    # --populations K: the solvers' populations option, absent at 1; the baseline runs none
    assert plain.solver_options["populations"] is None
    two = study.prepare_run(p, P(robots=[1], spread_views=4, populations=2))
    assert two.solver_options["populations"] == 2
    seen.clear()
    solvers.solve_triplets = spy
    try:
        study.solve_piece(two, 0, method="fast", seed=0, piece=2)
        assert seen["populations"] == 2
        seen.clear()
        study.solve_piece(two, 0, method="baseline", seed=0, piece=2)
        assert "populations" not in seen
    finally:
        solvers.solve_triplets = orig
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="populations: expected a whole number"):
            study.prepare_run(p, P(robots=[1], populations=bad))


def test_bearing_calibration_reaches_the_histories_and_the_map(data):
    # --bearing-calibration measured: every robot's bearings corrected by dataset 6's constants
    # before the histories are made (the joint map reads the same dataset), headings unchanged
    from qfg.datasets import mrclam
    from qfg.geometry import wrap_angle

    p = data / "MRCLAM_Dataset1"
    plain = study.prepare_run(p, P(robots=[1], spread_views=4))
    cal = study.prepare_run(p, P(robots=[1], spread_views=4, bearing_calibration="measured"))
    b, s = mrclam.DEFAULT_BEARING_CALIBRATION[1]
    assert len(plain.histories) == len(cal.histories) > 0
    for (_, h0), (_, h) in zip(plain.histories, cal.histories, strict=True):
        np.testing.assert_allclose(h.bearings, wrap_angle((h0.bearings - b) / (1 + s)),
                                   atol=1e-12)
        np.testing.assert_array_equal(h.headings, h0.headings)
    rd0, rd = plain.dataset.robot(1), cal.dataset.robot(1)
    assert not np.allclose(rd.view_bearings[rd0.visible], rd0.view_bearings[rd0.visible])
    with pytest.raises(ValueError, match="bearing_calibration: expected one of"):
        study.prepare_run(p, P(robots=[1], bearing_calibration="fitted"))


def test_sigma_options_reach_the_histories_from_the_command_line(data):
    # `qfg mrclam --sigma-bearing-deg / --sigma-heading-deg` -> the run's parameters -> every
    # history's sigmas (the bearing tail's core would otherwise set the bearing sigma)
    import argparse

    from qfg.harness.commands import mrclam as cmd

    p = data / "MRCLAM_Dataset1"
    ap = argparse.ArgumentParser()
    cmd.register(ap.add_subparsers())
    args = ap.parse_args(["mrclam", str(p), "--robots", "1", "--bearing-tail", "measured",
                          "--sigma-bearing-deg", "0.5", "--sigma-heading-deg", "2.2"])
    params, _ = cmd.check_options(args)
    assert (params.sigma_bearing_deg, params.sigma_heading_deg) == (0.5, 2.2)
    assert params.bearing_tail == "measured" and params.robots == (1,)
    prep = study.prepare_run(p, params)
    assert prep.histories
    for _, h in prep.histories:
        assert np.isclose(h.sigma_bearing, np.deg2rad(0.5))
        assert np.allclose(h.sigma_heading, np.deg2rad(2.2))


def test_params_object_checks_each_field_and_derives_the_option_lists():
    # every option in one frozen object: checked when made, the error one line naming the field
    p = P(robots=[2, 1], max_gap=10)
    assert p.robots == (2, 1) and p.max_gap == 10.0 and isinstance(p.max_gap, float)
    assert p.map_method == "pooled" and P(propagate=False).map_method == "seen"
    assert P(map="best", propagate=False).map_method == "best"
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.method = "fast"
    for bad, name in [({"max_gap": 0}, "max_gap"), ({"temper": 2}, "temper"),
                      ({"temper": "auto-2se"}, "temper"), ({"max_views": 1}, "max_views"),
                      ({"robots": [0]}, "robots"), ({"robots": [1, 1]}, "robots"),
                      ({"piece": 0}, "piece"), ({"model_check": 0.9}, "model_check"),
                      ({"map": "nope"}, "map"), ({"mode": "clean"}, "mode"),
                      ({"propagation": "mean"}, "propagation")]:
        with pytest.raises(study.ParamError, match=f"^{name}: ") as exc:
            P(**bad)
        assert exc.value.field == name and "\n" not in str(exc.value)
    with pytest.raises(study.ParamError, match="'pooled'.*CHANGELOG.md"):
        P(propagation="mean")
    with pytest.raises(study.ParamError, match="colour: unknown option"):
        P.from_dict({"colour": 1})
    assert P.from_dict(p.to_dict()) == p
    # the study's parameters, the solve keys and the later keys come from the fields
    assert set(study.DEFAULTS) == {"data", "datasets", *study.FIELDS}
    assert set(study.SOLVE_KEYS) < {"path", *study.FIELDS} and "combine" not in study.SOLVE_KEYS
    assert set(study.LATER_KEYS) < set(study.SOLVE_KEYS)
    for f in dataclasses.fields(P):
        assert f.metadata["doc"] and f.name in P.__doc__
