"""The map methods of ``qfg mrclam`` beyond the paper's (configuration inference, the joint GTSAM
map), the fallback without odometry, and the one rule for the default map.

The dataset is the synthetic one of tests/test_mrclam.py (known geometry, exact bearings, robot 1
with motion capture), so the joint map has a right answer to find.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from test_mrclam import write_dataset

from qfg.harness.cli import main
from qfg.harness.studies.mrclam import compare as mrclam_compare
from qfg.harness.studies.mrclam import maps as mrclam_maps

FAST = ["--no-figures", "--no-progress", "--max-gap", "10", "--spread-views", "0"]
TABLE = Path(__file__).resolve().parents[1] / "docs" / "results" / "mrclam_maps.csv"


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    r = tmp_path_factory.mktemp("mrclam_maps")
    write_dataset(r / "MRCLAM_Dataset1")
    write_dataset(r / "MRCLAM_Dataset2", robot2_odometry=False)
    write_dataset(r / "MRCLAM_Dataset3", robot2_odometry=False, robot1_odometry=False)
    return r


def _rows(out, name="triplets.csv"):
    with open(out / name) as fh:
        return list(csv.DictReader(fh))


def _exit_code(argv) -> int:
    """main's exit status, whether it returns it or argparse raises SystemExit."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def _map_info(out, name):
    with np.load(out / "maps" / f"{name}.npz", allow_pickle=False) as z:
        return json.loads(str(z["info"]))


def test_joint_map_needs_no_solver_and_beats_the_prior(root, tmp_path, monkeypatch):
    def boom(*a, **k):
        raise AssertionError("the joint map needs no single-triplet solver")

    monkeypatch.setattr("qfg.solvers.solve_triplets", boom)
    out = tmp_path / "o"
    assert main(["mrclam", str(root / "MRCLAM_Dataset1"), "--map", "joint", "--output",
                 str(out), *FAST]) == 0
    rows = _rows(out)
    n = len({r["A"] for r in rows} | {r["C"] for r in rows})
    assert len(rows) == n * (n - 1) * (n - 2)          # every ordered triplet, each once
    assert {r["map"] for r in rows} == {"joint"}
    seen = [r for r in rows if r["kind"] == "seen"]
    assert seen and _map_info(out, "joint")["answered_by"] == "joint"
    # exact bearings of a known geometry: the joint posterior beats the prior alone
    for kind in ("seen", "propagated"):
        rs = [r for r in rows if r["kind"] == kind]
        if not rs:  # the synthetic robots see every triplet of its few landmarks
            continue
        est = np.mean([float(r["log_score"]) for r in rs])
        assert est > np.mean([float(r["prior_log_score"]) for r in rs]) + 1.0, kind
    cams = _rows(out, "cameras.csv")
    assert cams and {r["method"] for r in cams} == {"joint"}
    assert json.loads((out / "run.json").read_text())["params"]["method"] == "none"


def test_joint_map_uses_every_robot_and_a_robot_without_odometry_must_agree(root, tmp_path):
    # robot 2 has no odometry: the joint map still answers from robot 1's run (it fits every
    # robot of the dataset); robot 2 drives 2 m straight past 3 landmarks, too little parallax
    # for its start to place them, so it is left out, flagged
    out = tmp_path / "o"
    assert main(["mrclam", str(root / "MRCLAM_Dataset2"), "--robots", "2", "--map", "joint",
                 "--method", "none", "--output", str(out), *FAST]) == 0
    info = _map_info(out, "joint")
    assert info["answered_by"] == "joint"
    assert info["robot_flags"] == {"1": "ok", "2": "unconstrained"}


def test_joint_map_without_odometry_falls_back_and_says_which_map_answered(root, tmp_path,
                                                                          capsys):
    d = root / "MRCLAM_Dataset3"        # no robot has odometry; neither start places 3 landmarks
    # asked for no solver: the joint map tries (two robots might agree), and when it cannot
    # answer it says why, in one line, naming the way out
    assert _exit_code(["mrclam", str(d), "--map", "joint", "--method", "none",
                       "--output", str(tmp_path / "refused"), *FAST]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--method full" in err[0] and "could not answer" in err[0]
    # by default the solvers answer too and the map falls back to JOINT_FALLBACK, which it
    # records with the reason
    out = tmp_path / "o"
    assert main(["mrclam", str(d), "--robots", "2", "--map", "joint", "--output", str(out),
                 *FAST]) == 0
    info = _map_info(out, "joint")
    assert info["answered_by"] == mrclam_maps.JOINT_FALLBACK
    assert "could not answer" in info["why"] and "2 unconstrained" in info["why"]
    assert json.loads((out / "run.json").read_text())["params"]["method"] == "full"
    # and it resumes as recorded, the solver not given again
    assert main(["mrclam", str(d), "--robots", "2", "--map", "joint", "--output", str(out),
                 "--resume", *FAST]) == 0


def test_without_odometry_the_joint_map_is_solved_first_and_once(root, tmp_path, monkeypatch,
                                                                  capsys):
    """On a dataset without odometry the default solver is decided by the joint solve, done
    before any piece: the solvers run only when it cannot answer, and the map step uses that
    same answer (one joint solve per run)."""
    import dataclasses

    from qfg.datasets.mrclam import joint_map

    d = root / "MRCLAM_Dataset3"        # no robot has odometry; the joint solve cannot answer
    real = joint_map.mrclam_marginals
    calls = []

    def counted(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(joint_map, "mrclam_marginals", counted)
    out = tmp_path / "fallback"
    assert main(["mrclam", str(d), "--robots", "2", "--output", str(out),
                 *FAST[:1], *FAST[2:]]) == 0
    assert len(calls) == 1
    err = capsys.readouterr().err     # the joint solve's phases are told as it goes
    assert "joint: robot 1 (1 of 2): its own map, a kinematic motion prior" in err
    assert err.index("joint: robot") < err.index("cannot answer") < err.index("solving")
    assert json.loads((out / "run.json").read_text())["params"]["method"] == "full"
    assert _map_info(out, "joint")["answered_by"] == mrclam_maps.JOINT_FALLBACK
    assert {r["method"] for r in _rows(out) if r["kind"] == "seen"} == {"baseline"}

    # when it answers, no solver runs: the recorded method is none, the map the joint one
    def answering(*a, **k):
        calls.append(1)
        return dataclasses.replace(real(*a, **k), method="joint")

    monkeypatch.setattr(joint_map, "mrclam_marginals", answering)
    calls.clear()
    out = tmp_path / "answers"
    assert main(["mrclam", str(d), "--robots", "2", "--output", str(out), *FAST]) == 0
    assert len(calls) == 1
    assert json.loads((out / "run.json").read_text())["params"]["method"] == "none"
    assert _map_info(out, "joint")["answered_by"] == "joint"
    assert {r["method"] for r in _rows(out) if r["kind"] == "seen"} == {"none"}
    # resumed as recorded: neither decided nor solved again (the map is recorded)
    calls.clear()
    assert main(["mrclam", str(d), "--robots", "2", "--output", str(out), "--resume",
                 *FAST]) == 0
    assert not calls
    # ground truth corrected first (a new dataset object): still one solve
    from qfg.datasets import mrclam as data

    check = data.check_landmarks
    monkeypatch.setattr(data, "check_landmarks", lambda ds, **k: check(ds, min_landmarks=2))
    sw = write_dataset(tmp_path / "MRCLAM_Dataset3", robot2_odometry=False,
                       robot1_odometry=False, truth_swap=(6, 8))
    assert main(["mrclam", str(sw), "--robots", "2", "--output", str(tmp_path / "sw"),
                 *FAST]) == 0
    assert len(calls) == 1 and _rows(tmp_path / "sw")[0]["gt_swaps"] == "6-8"


def test_the_joint_answer_is_remembered_for_the_same_inputs(root):
    from qfg.datasets import mrclam as data
    from qfg.harness.studies import mrclam as study

    prep = study.prepare_run(root / "MRCLAM_Dataset1")
    hs = [h for _, h in prep.histories]
    kw = dict(prior_states=prep.prior_states, camera_prior_states=prep.prior_camera_states,
              partition="edc")
    a = mrclam_maps.joint_answer(prep.dataset, hs, seed=0, **kw)
    assert mrclam_maps.joint_answer(prep.dataset, hs, seed=0, **kw) is a
    assert a.method == "joint"
    # another seed, other histories or another dataset object: solved again
    b = mrclam_maps.joint_answer(prep.dataset, hs, seed=1, **kw)
    assert b is not a
    assert mrclam_maps.joint_answer(prep.dataset, hs[:-1], seed=1, **kw) is not b
    other = data.load(root / "MRCLAM_Dataset1")
    c = mrclam_maps.joint_answer(other, hs[:-1], seed=1, **kw)
    assert c is not b and mrclam_maps.joint_answer(other, hs[:-1], seed=1, **kw) is c


def test_the_user_is_told_which_map_answered_and_what_it_flagged():
    from qfg.harness.studies.mrclam import say_map_info

    said = []
    say_map_info("joint", {"answered_by": "seen-prior", "why": "robots disagree"}, said.append)
    say_map_info("joint", {"answered_by": "joint", "flags": ["kinematic_prior", "overdispersed"],
                           "overdispersion": 4.08, "covariance_scale": 4.08}, said.append)
    say_map_info("joint", {"answered_by": "joint", "flags": []}, said.append)
    say_map_info("joint", {"answered_by": "joint", "flags": [], "too_close": 5.0,
                           "too_close_dropped": 5.0}, said.append)
    say_map_info("pooled", {}, said.append)
    say_map_info("joint", {"answered_by": "joint", "flags": [], "overdispersion": 1.4},
                 said.append)
    say_map_info("joint", {"answered_by": "joint", "flags": ["kinematic_prior"],
                           "overdispersion": 0.8, "covariance_scale": 1.0}, said.append)
    assert said == ["map joint: answered by seen-prior: robots disagree",
                    "map joint: flags kinematic_prior, overdispersed; the robots' own maps "
                    "scatter 4.08x what its covariance allows (covariance x4.08)",
                    "map joint: 5 bearings from poses the fit had put on the landmark seen (5 "
                    "left out, the others kept once the poses moved off)",
                    "map joint: the robots' own maps scatter 1.40x what its covariance allows "
                    "(not widened: every run has odometry)",
                    "map joint: flags kinematic_prior; the robots' own maps scatter 0.80x what "
                    "its covariance allows (not widened: no more than it allows)"]


def test_configuration_map_answers_every_ordered_triplet_and_is_drawn(root, tmp_path):
    out = tmp_path / "o"
    assert main(["mrclam", str(root / "MRCLAM_Dataset1"), "--map", "config-state", "--method",
                 "fast", "--output", str(out), *[a for a in FAST if a != "--no-figures"]]) == 0
    rows = _rows(out)
    keys = {(r["A"], r["B"], r["C"]) for r in rows}
    assert len(keys) == len(rows) and {r["map"] for r in rows} == {"config-state"}
    P = np.array([[float(x) for x in r["probabilities"].split(";")] for r in rows])
    assert np.all(np.isfinite(P)) and np.allclose(P.sum(axis=1), 1.0)
    assert all(np.isfinite(float(r["log_score"])) for r in rows)
    assert (out / "figures" / "configuration_map.png").stat().st_size > 10_000
    geom = _map_info(out, "config-state")["map_geometry"]
    ids = {int(r[k]) for r in rows for k in ("A", "B", "C")}
    assert geom["kind"] == "configurations" and set(geom["landmark_ids"]) == ids
    S = np.asarray(geom["samples"])
    assert S.shape[1:] == (len(ids), 2) and 0 < len(S) <= 300
    assert len(geom["components"]) == len(ids)


def test_configuration_geometry_draws_distinct_particles_or_by_weight():
    """Equal weights: distinct particles, ids through the posterior's landmark indices; all the
    weight on one particle: every sample is that particle."""
    import types

    X = np.arange(50 * 3 * 2, dtype=float).reshape(50, 3, 2)
    post = types.SimpleNamespace(positions=X, weights=np.full(50, 0.02), landmarks=(2, 0, 1),
                                 components=lambda: np.array([0, 0, 1]))
    g = mrclam_maps.configuration_geometry(post, np.array([11, 12, 13]), samples=20, seed=3)
    S = np.asarray(g["samples"])
    assert S.shape == (20, 3, 2) and len({tuple(x.ravel()) for x in S}) == 20
    assert g["landmark_ids"] == [13, 11, 12] and g["components"] == [0, 0, 1]
    w = np.zeros(50)
    w[7] = 1.0
    g = mrclam_maps.configuration_geometry(types.SimpleNamespace(**{**vars(post), "weights": w}),
                                           np.array([11, 12, 13]), samples=20, seed=3)
    assert np.array_equal(np.asarray(g["samples"]), np.repeat(X[7:8], 20, axis=0))


def _random_similarity(rng, X):
    """``X`` (n, 2) turned, scaled and moved at random (a configuration's gauge)."""
    a, s, t = rng.uniform(-np.pi, np.pi), rng.uniform(0.1, 3), rng.normal(0, 2, 2)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return s * X @ R.T + t


def test_the_configuration_map_figure_aligns_each_sample_onto_the_truth():
    """By hand: every sample a random similarity of the truth, so aligned it is the truth
    (distance 0), except landmark 5, which no seen triplet links to the others (its own
    component) and which every sample puts 0.5 m from its truth in the truth's frame: it is left
    out of the alignment, drawn exactly 0.5 m off and named."""
    import types

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from qfg.harness.plotting_mrclam import configuration_map_figure

    rng = np.random.default_rng(1)
    truth = rng.uniform(0, 5, (8, 2))
    off = truth.copy()
    off[5] += [0.3, 0.4]
    samples = [_random_similarity(rng, off) for _ in range(40)]
    ds = types.SimpleNamespace(name="by hand", robots={},
                               landmark_position=lambda ids: truth[np.asarray(ids)])
    geom = {"kind": "configurations", "landmark_ids": list(range(8)),
            "samples": np.array(samples).tolist(), "components": [0] * 5 + [1] + [0] * 2}
    fig = configuration_map_figure(geom, ds)
    note = " ".join(t.get_text() for t in fig.texts).replace("\n", " ")
    assert "over the 7 landmarks of the largest linked group" in note
    assert "median distance of a landmark's dots from its truth: 0.00 m" in note
    assert "largest 5 (0.50 m)" in note and "(the prior alone places them): 5" in note
    dots = [ln for ln in fig.axes[0].lines if ln.get_marker() == "." and len(ln.get_xdata())]
    assert len(dots) == 8 and all(len(ln.get_xdata()) == 40 for ln in dots)
    plt.close(fig)
    # samples that scatter about the truth (sd 0.3 of its rms radius, then a random similarity)
    # are drawn about the truth, not shrunk toward its centre: each cloud's mean within 0.1 of
    # the radius of its truth, and the clouds as wide as the truth (a least-squares scale would
    # shrink them by about 1 / (1 + 2 x 0.3^2) = 0.85)
    T = truth[:7]
    rad = np.sqrt(np.mean(np.sum((T - T.mean(0)) ** 2, axis=1)))
    samples = [_random_similarity(rng, T + rng.normal(0, 0.3 * rad, T.shape))
               for _ in range(400)]
    ds7 = types.SimpleNamespace(name="by hand", robots={},
                                landmark_position=lambda ids: T[np.asarray(ids)])
    fig = configuration_map_figure({"kind": "configurations", "landmark_ids": list(range(7)),
                                    "samples": np.array(samples).tolist()}, ds7)
    dots = [ln for ln in fig.axes[0].lines if ln.get_marker() == "." and len(ln.get_xdata())]
    centre = np.array([[np.mean(ln.get_xdata()), np.mean(ln.get_ydata())] for ln in dots])
    assert np.max(np.hypot(*(centre - T).T)) < 0.1 * rad
    plt.close(fig)


def test_method_none_with_a_map_made_from_estimates_is_refused(root, tmp_path, capsys):
    assert _exit_code(["mrclam", str(root / "MRCLAM_Dataset1"), "--map", "pooled", "--method",
                       "none", "--output", str(tmp_path / "o"), *FAST]) == 2
    assert "--method none" in capsys.readouterr().err


# ------------------------------------------------------------------------------ the default rule
def _row(d, m, kind, n, score):
    return {"dataset": d, "map": m, "kind": kind, "n": n, "log_score": score}


def test_best_map_weights_by_triplets_and_needs_every_dataset():
    rows = [_row(1, "a", "seen", 10, -1.0), _row(1, "a", "propagated", 90, -3.0),
            _row(2, "a", "seen", 100, -2.0),
            _row(1, "b", "seen", 10, -0.5), _row(1, "b", "propagated", 90, -2.9),
            _row(2, "b", "seen", 100, -2.4),
            _row(1, "c", "seen", 100, 0.0),                       # dataset 2 missing
            _row(1, "a", "camera", 1000, 0.0), _row(1, "b", "camera", 1000, -9.0)]
    s = mrclam_compare.map_scores([r for r in rows if r["map"] != "c"])
    assert s["a"] == pytest.approx(((-10 - 270 - 200) / 200, 200))   # cameras do not count
    assert s["b"] == pytest.approx(((-5 - 261 - 240) / 200, 200))
    assert mrclam_compare.best_map(rows, datasets=(1, 2)) == "a"     # c is not on dataset 2
    assert mrclam_compare.best_map(rows, datasets=(1,)) == "c"
    with pytest.raises(ValueError, match="every one of datasets"):
        mrclam_compare.best_map(rows, datasets=(3,))


def test_merged_rows_replace_each_rerun_dataset_and_map_in_place():
    recorded = [_row(1, "a", "seen", 10, -1.0), _row(1, "a", "propagated", 90, -3.0),
                _row(5, "a", "seen", 10, -2.0), _row(5, "a", "propagated", 90, -2.9),
                _row(5, "b", "seen", 10, -1.5)]
    new = [_row(5, "a", "seen", 30, -0.2), _row(5, "a", "propagated", 70, -0.3),
           _row(6, "a", "seen", 1, -0.1)]
    out = mrclam_compare.merge_rows(recorded, new)
    assert out == recorded[:2] + new[:2] + [recorded[4], new[2]]
    assert mrclam_compare.merge_rows(recorded, []) == recorded


def test_an_unknown_map_name_is_refused_by_name(capsys):
    with pytest.raises(SystemExit):
        mrclam_compare.main(["--from-csv", str(TABLE), "--maps", "joint,jiont"])
    assert "jiont" in capsys.readouterr().err


def test_the_default_map_is_the_rule_applied_to_the_recorded_comparison():
    rows = mrclam_compare.read_table(TABLE)
    assert {int(r["dataset"]) for r in rows} == {1, 2, 3, 4, 5, 6}
    assert mrclam_maps.DEFAULT_MAP == mrclam_compare.best_map(rows)
    assert mrclam_maps.DEFAULT_MAP in mrclam_maps.MAP_METHODS


def test_seen_config_keeps_the_solvers_seen_rows_and_answers_the_rest(root, tmp_path):
    d, out = root / "MRCLAM_Dataset1", tmp_path / "o"
    args = ["mrclam", str(d), "--method", "fast", "--output", str(out), *FAST]
    assert main([*args, "--map", "pooled"]) == 0
    pooled = {(r["A"], r["B"], r["C"]): r["probabilities"] for r in _rows(out)
              if r["kind"] == "seen"}
    assert main([*args, "--map", "seen-config", "--resume"]) == 0
    rows = _rows(out)
    seen = {(r["A"], r["B"], r["C"]): r["probabilities"] for r in rows if r["kind"] == "seen"}
    assert seen == pooled                     # the solvers' combined estimates, as written
    assert {r["map"] for r in rows} == {"seen-config"}


def test_config_metric_map_uses_the_position_summaries_each_pass_kept(root, tmp_path, capsys):
    d, out = root / "MRCLAM_Dataset1", tmp_path / "o"
    args = ["mrclam", str(d), "--method", "fast", "--output", str(out), *FAST]
    assert main([*args, "--map", "config-metric"]) == 0
    rows = _rows(out)
    assert {r["map"] for r in rows} == {"config-metric"}
    assert len({(r["A"], r["B"], r["C"]) for r in rows}) == len(rows)
    info = _map_info(out, "config-metric")
    # a pass whose solver kept no sample (degenerate) weighs by its states alone
    assert info["likelihood"] == "metric" and 0 < info["n_metric"] <= info["n_seen"]
    # the records keep one summary per set and pass (the ascending ordering's histories)
    recs = [r for line in open(out / "records.jsonl") for r in json.loads(line)["rows"]]
    kept = [r for r in recs if r["position"]]
    assert kept and all(int(r["A"]) < int(r["B"]) < int(r["C"]) for r in kept)
    assert len(kept) == sum(int(r["A"]) < int(r["B"]) < int(r["C"]) for r in recs)
    # records made before summaries were kept: a clear refusal, not a map of nothing
    lines = []
    for line in open(out / "records.jsonl"):
        rec = json.loads(line)
        for r in rec["rows"]:
            r["position"] = ""
        lines.append(json.dumps(rec))
    (out / "records.jsonl").write_text("\n".join(lines) + "\n")
    (out / "maps" / "config-metric.npz").unlink()
    capsys.readouterr()
    assert _exit_code([*args, "--map", "config-metric", "--resume"]) != 0
    assert "keep no summaries of C's position" in capsys.readouterr().err


def test_maps_figure_draws_each_row_from_the_prior_to_its_score(tmp_path, capsys):
    """The comparison figure from the recorded table (nothing run): one panel per kind, one bar
    per row, each from the prior alone's score to the map's, hatched where the fallback
    answered; the command writes it where it is told and prints the table."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from qfg.harness.plotting_mrclam import maps_figure

    rows = mrclam_compare.read_table(TABLE)
    fig = maps_figure(rows)
    kinds = list(dict.fromkeys(r["kind"] for r in rows))
    axes = [a for a in fig.axes if a.get_title()]
    assert len(axes) == len(kinds)
    for ax, kind in zip(axes, sorted(kinds, key=("seen", "propagated", "camera").index),
                        strict=True):
        bars = sorted(((p.get_y(), p.get_height(), bool(p.get_hatch())) for p in ax.patches
                       if isinstance(p, Rectangle)), key=lambda b: (round(b[0], 6), b[1]))
        want = sorted(((float(r["prior_log_score"]),
                        float(r["log_score"]) - float(r["prior_log_score"]),
                        r["answered_by"] != r["map"]) for r in rows if r["kind"] == kind),
                      key=lambda b: (round(b[0], 6), b[1]))
        assert len(bars) == len(want)
        for (y, h, hatched), (wy, wh, fb) in zip(bars, want, strict=True):
            assert y == pytest.approx(wy) and h == pytest.approx(wh) and hatched == fb
    plt.close(fig)
    out = tmp_path / "o"
    assert mrclam_compare.main(["--from-csv", str(TABLE), "--output", str(out)]) == 0
    assert (out / "mrclam_maps.png").stat().st_size > 10_000
    assert "best (the default rule): " + mrclam_maps.DEFAULT_MAP in capsys.readouterr().out


def test_the_joint_map_figure_is_drawn_and_counts_the_truths_inside_their_ellipses(root,
                                                                                   tmp_path):
    """``qfg mrclam`` with the joint map draws the map against the ground truth
    (figures/joint_map.png) from a geometry recorded with the map; the figure's count of true
    landmarks inside their 95 % ellipses is the chi-square count of errors drawn by hand."""
    import types

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Ellipse

    from qfg.harness.plotting_mrclam import joint_map_figure

    out = tmp_path / "o"
    assert main(["mrclam", str(root / "MRCLAM_Dataset1"), "--map", "joint", "--output",
                 str(out), *[a for a in FAST if a != "--no-figures"]]) == 0
    assert (out / "figures" / "joint_map.png").stat().st_size > 10_000
    geom = _map_info(out, "joint")["map_geometry"]
    assert set(geom) >= {"landmark_ids", "mean", "covariance", "paths", "landmark_flags"}
    assert len(geom["mean"]) == len(geom["landmark_ids"]) and geom["paths"]

    # by hand: 12 landmarks, the map a similarity of the truth plus known errors, each landmark
    # 0.01 m iid. The errors are made orthogonal to the similarities' tangent space at the
    # truth, so the best similarity leaves them as they are (to first order): the count is
    # then the chi-square count of the errors themselves.
    rng = np.random.default_rng(0)
    truth = rng.uniform(0, 5, (12, 2))
    X = truth - truth.mean(0)
    G = np.column_stack([np.tile([1.0, 0.0], 12), np.tile([0.0, 1.0], 12),
                         np.column_stack([-X[:, 1], X[:, 0]]).ravel(), X.ravel()])
    e = rng.normal(0, 0.01, 24) * np.repeat([1.0] * 6 + [4.0] * 6, 2)
    e = (e - G @ np.linalg.lstsq(G, e, rcond=None)[0]).reshape(12, 2)
    z2 = (e ** 2).sum(1) / 0.01 ** 2
    want, want_wide = int((z2 <= 5.991).sum()), int((z2 <= 5.991 * 20).sum())
    assert 0 < want < 12
    a, s = 0.7, 0.3
    Rm = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    mu = ((truth + e) * s) @ Rm.T + [3.0, -1.0]
    ds = types.SimpleNamespace(name="by hand", robots={},
                               landmark_position=lambda ids: truth[np.asarray(ids)])
    geom = {"landmark_ids": list(range(12)), "landmark_flags": ["ok"] * 12,
            "mean": mu.tolist(), "covariance": np.tile((0.01 * s) ** 2 * np.eye(2),
                                                       (12, 1, 1)).tolist(),
            "paths": {"1": (mu[:3]).tolist()}, "overdispersion": 20.0,
            "covariance_scale": 1.0}
    fig = joint_map_figure(geom, ds)
    note = " ".join(t.get_text() for t in fig.texts).replace("\n", " ")
    assert f"{want} of 12 true landmarks inside their 95 % ellipse" in note
    assert f"{want_wide} inside the dashed one (the covariance x20.00" in note
    ells = [p for p in fig.axes[0].patches if isinstance(p, Ellipse)]
    assert len(ells) == 24 and sum(p.get_linestyle() == "--" for p in ells) == 12
    plt.close(fig)
    # a map already widened by its scatter gets no dashed ellipses, and says so; robots left
    # out are named
    fig = joint_map_figure({**geom, "covariance_scale": 20.0,
                            "robot_flags": {"1": "ok", "2": "local_minimum"}}, ds)
    assert len([p for p in fig.axes[0].patches if isinstance(p, Ellipse)]) == 12
    note = " ".join(t.get_text() for t in fig.texts).replace("\n", " ")
    assert "already widened x20.00" in note and "left out of the map: 2 (local_minimum)" in note
    plt.close(fig)
