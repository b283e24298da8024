"""``qfg mrclam`` as a user meets it (issue 18 items 1-4): options, the folder and the data files
checked before anything runs (exit 2, one line naming the option or the file and line, nothing
written, no solver call); progress per phase; the solving recorded in pieces, so that an
interrupted run resumed writes the same triplets.csv as one that ran through; the map a named,
pluggable step; the table's key and why no camera view was scored.

The datasets are the synthetic ones of tests/test_mrclam.py (known geometry, motion capture for
robot 1 only), written here; the fast solver and no figures keep each run to seconds.
"""

from __future__ import annotations

import gzip
import json

import numpy as np
import pytest
from test_mrclam import write_dataset

from qfg.harness.cli import main
from qfg.harness.studies import mrclam as study

FAST = ["--method", "fast", "--no-figures", "--max-gap", "10", "--spread-views", "0"]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    r = tmp_path_factory.mktemp("mrclam_cli")
    write_dataset(r / "MRCLAM_Dataset1")
    write_dataset(r / "MRCLAM_Dataset2", gz=True)
    return r


@pytest.fixture
def no_solving(monkeypatch):
    """Any solve is a test failure: a refused command must refuse before any work."""
    def boom(*a, **k):
        raise AssertionError("the solver ran before the input was refused")

    monkeypatch.setattr("qfg.solvers.solve_triplets", boom)


def _refused(capsys, argv, *words):
    """Exit 2, one line on stderr holding ``words``, nothing on stdout."""
    try:
        rc = main(argv)
    except SystemExit as exc:   # argparse's own errors
        rc = exc.code
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert rc == 2, cap.err
    assert len(lines) == 1, cap.err
    for w in words:
        assert w in lines[0], lines[0]
    assert "Traceback" not in cap.err and not cap.out.strip()
    return lines[0]


# ------------------------------------------------------------------------------ item 1: options
@pytest.mark.parametrize("bad, name", [
    (["--temper", "2"], "--temper"), (["--temper", "nan"], "--temper"),
    (["--temper", "-0.5"], "--temper"), (["--temper", "banana"], "--temper"),
    (["--model-check", "0.9"], "--model-check"), (["--model-check", "-1"], "--model-check"),
    (["--bearing-tail", "cauchy"], "--bearing-tail"),
    (["--robots", "9"], "--robots"), (["--robots", "0"], "--robots"),
    (["--robots", "1,x"], "--robots"), (["--robots", "1,1"], "--robots"),
    (["--max-gap", "-1"], "--max-gap"), (["--max-gap", "0"], "--max-gap"),
    (["--max-gap", "inf"], "--max-gap"), (["--max-gap", "abc"], "--max-gap"),
    (["--min-travel", "-0.1"], "--min-travel"),
    (["--max-views", "1"], "--max-views"), (["--max-views", "-2"], "--max-views"),
    (["--spread-views", "1"], "--spread-views"),
    (["--sigma-distance-ratio", "-1"], "--sigma-distance-ratio"),
    (["--sigma-bearing-deg", "-0.5"], "--sigma-bearing-deg"),
    (["--sigma-heading-deg", "nan"], "--sigma-heading-deg"),
    (["--curve", "3,x"], "--curve"), (["--curve", "3,-1"], "--curve"),
    (["--piece-size", "0"], "--piece-size"),
    (["--tensor", "/no/such/tensor.npz"], "--tensor"),
    (["--robots", "2", "--mode", "paper"], "--mode"),
    (["--propagation", "pooled", "--map", "best"], "--propagation"),
    (["--propagation", "mean"], "'pooled'"),
    (["--map", "nope"], "--map"), (["--method", "slow"], "--method"),
    (["--seed", "-1"], "--seed"), (["--resume", "--overwrite"], "--resume"),
    (["--heading-walk", "-1"], "--heading-walk"), (["--heading-walk", "fast"], "--heading-walk"),
    (["--distance-tail", "wide"], "--distance-tail"),
    (["--camera-prior", "pairs"], "--camera-prior"),
    (["--budget", "0"], "--budget"), (["--budget", "nan"], "--budget"),
    (["--budget", "2", "--method", "baseline"], "--budget"),
    (["--populations", "0"], "--populations"), (["--populations", "two"], "--populations"),
    (["--populations", "2", "--method", "baseline"], "--populations"),
    (["--prior", "arena-logscale", "--map", "config-state"], "--prior"),
])
def test_bad_option_is_one_line_naming_it_and_nothing_is_written(root, tmp_path, capsys,
                                                                 no_solving, bad, name):
    out = tmp_path / "out"
    _refused(capsys, ["mrclam", str(root / "MRCLAM_Dataset1"), "--output", str(out), *bad], name)
    assert not out.exists()


@pytest.mark.parametrize("which", ["parent", "not a dataset", "missing", "a file"])
def test_bad_dataset_folder_is_one_line_naming_it(root, tmp_path, capsys, no_solving, which):
    out = tmp_path / "out"
    if which == "parent":
        path, words = root, [str(root), "MRCLAM_Dataset1, MRCLAM_Dataset2"]
    elif which == "not a dataset":
        path = tmp_path / "notes"
        path.mkdir()
        (path / "readme.txt").write_text("hello")
        words = [str(path / "Barcodes.dat"), "not found"]
    elif which == "missing":
        path, words = tmp_path / "nowhere", [str(tmp_path / "nowhere")]
    else:
        path = tmp_path / "file.dat"
        path.write_text("1 2\n")
        words = [str(path), "not a directory"]
    _refused(capsys, ["mrclam", str(path), "--output", str(out), *FAST], *words)
    assert not out.exists()


def test_resume_with_other_options_is_refused_before_loading(root, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["mrclam", str(root / "MRCLAM_Dataset1"), "--output", str(out), "--robots", "2",
                 "--no-progress", *FAST]) == 0
    capsys.readouterr()
    before = sorted(p.name for p in out.iterdir())
    _refused(capsys, ["mrclam", str(root / "MRCLAM_Dataset1"), "--output", str(out), "--robots",
                      "2", "--seed", "5", "--resume", *FAST], "--resume", "seed")
    _refused(capsys, ["mrclam", str(root / "MRCLAM_Dataset1"), "--output", str(out), *FAST],
             "already holds a run")
    assert sorted(p.name for p in out.iterdir()) == before



def test_run_recorded_with_later_options_at_their_defaults_resumes(root, tmp_path, capsys):
    """Some runs wrote the later options (``study.LATER_KEYS``) into run.json at their defaults;
    a run at those defaults leaves them out of its identity. Resuming such a run must work,
    and a recorded non-default value must still be refused."""
    out = tmp_path / "out"
    argv = ["mrclam", str(root / "MRCLAM_Dataset1"), "--output", str(out), "--robots", "2",
            "--no-progress", *FAST]
    assert main(argv) == 0
    meta = json.loads((out / "run.json").read_text())
    assert not set(study.LATER_KEYS) & set(meta["params"])
    meta["params"].update({k: study.DEFAULTS[k] for k in study.LATER_KEYS})
    (out / "run.json").write_text(json.dumps(meta))
    capsys.readouterr()
    assert main([*argv, "--resume"]) == 0
    capsys.readouterr()
    meta["params"]["heading_drift"] = True
    (out / "run.json").write_text(json.dumps(meta))
    _refused(capsys, [*argv, "--resume"], "--resume", "heading_drift")


def test_temper_rules_run_from_the_command_line_and_record_their_choice(root, tmp_path, capsys):
    """``--temper auto`` and ``auto-1se`` (a later phase: --resume makes only the combination
    again): each records the power it chose; the one-standard-error rule never a larger one."""
    out = tmp_path / "out"
    argv = ["mrclam", str(root / "MRCLAM_Dataset1"), "--output", str(out), "--robots", "1,2",
            "--no-progress", "--map", "seen", *FAST]
    chosen = {}
    for rule in ("auto", "auto-1se"):
        assert main([*argv, "--temper", rule, *(["--resume"] if chosen else [])]) == 0
        summary = json.loads((out / "summary.json").read_text())["options"]
        chosen[rule] = summary["temper_chosen"]
        assert chosen[rule] in study.AUTO_TEMPERS
        assert len(summary["temper_check"]) == len(study.AUTO_TEMPERS)
    assert chosen["auto-1se"] <= chosen["auto"]
    capsys.readouterr()
    _refused(capsys, [*argv, "--temper", "auto-2se", "--resume"], "--temper")

# ------------------------------------------------------------------------------ item 2: data files
def _damage(d, how):
    """Damage robot 1's measurement file of dataset ``d`` (plain or .gz): returns the file and
    the line the error must name (None: no line)."""
    gz = (d / "Robot1_Measurement.dat.gz").exists()
    p = d / ("Robot1_Measurement.dat.gz" if gz else "Robot1_Measurement.dat")
    raw = p.read_bytes()
    text = gzip.decompress(raw) if gz else raw
    lines = text.split(b"\n")
    if how == "flipped byte":
        assert gz
        b = bytearray(raw)
        b[len(b) // 2] ^= 0x55
        p.write_bytes(bytes(b))
        return p, "line"
    if how == "empty":
        p.write_bytes(b"")
        return p, None
    if how == "negative range":
        k = 10
        f = lines[k].split(b"\t")
        f[2] = b" -1.5 "
        lines[k] = b"\t".join(f)
        line = k + 1
    else:  # a malformed line
        k = 12
        lines[k] = b"1248272275.000 \t 72 \t"
        line = k + 1
    new = b"\n".join(lines)
    p.write_bytes(gzip.compress(new) if gz else new)
    return p, f"line {line}"


@pytest.mark.parametrize("how", ["flipped byte", "empty", "negative range", "malformed line"])
def test_damaged_data_file_is_one_line_naming_file_and_line(tmp_path, capsys, no_solving, how):
    d = write_dataset(tmp_path / "MRCLAM_Dataset7", gz=(how == "flipped byte"))
    p, where = _damage(d, how)
    out = tmp_path / "out"
    line = _refused(capsys, ["mrclam", str(d), "--output", str(out), *FAST], str(p))
    if where:
        assert where in line
    assert not out.exists()


# ------------------------------------------------------------------------------ item 3: pieces
def _run(path, out, *extra):
    # the solvers' pipeline (the pooled map), whatever the default map is
    return main(["mrclam", str(path), "--output", str(out), "--piece-size", "8", "--seed", "4",
                 "--map", "pooled", *FAST, *extra])


def test_interrupted_and_resumed_run_writes_the_same_triplets_as_one_run(root, tmp_path,
                                                                         monkeypatch, capsys):
    d = root / "MRCLAM_Dataset1"
    whole = tmp_path / "whole"
    assert _run(d, whole) == 0
    err = capsys.readouterr().err
    for phase in ("loaded MRCLAM_Dataset1", "histories:", "pieces", "combined:", "map pooled:",
                  "scores:"):
        assert phase in err, err
    n_pieces = len((whole / "records.jsonl").read_text().splitlines())
    assert n_pieces >= 4

    # the run stops after 3 pieces, as Ctrl-C would: the runner records what finished
    calls = []
    real = study.run_piece

    def stop_after_three(task, rng):
        if len(calls) == 3:
            raise KeyboardInterrupt
        calls.append(task["index"])
        return real(task, rng)

    part = tmp_path / "part"
    monkeypatch.setattr(study, "run_piece", stop_after_three)
    assert _run(d, part) == 130
    assert "interrupted after 3 of" in capsys.readouterr().err
    assert len((part / "records.jsonl").read_text().splitlines()) == 3
    assert not (part / "triplets.csv").exists()

    # resumed: only the other pieces are solved, and the outputs are those of the whole run
    calls.clear()
    monkeypatch.setattr(study, "run_piece", lambda task, rng: (calls.append(task["index"]),
                                                                real(task, rng))[1])
    assert _run(d, part, "--resume") == 0
    assert sorted(calls) == list(range(3, n_pieces))
    for name in ("triplets.csv", "cameras.csv", "rows.csv"):
        assert (part / name).read_bytes() == (whole / name).read_bytes(), name


def test_pieces_give_the_in_memory_run(root, tmp_path):
    # the command's recorded pieces and run_dataset solve the same histories with the same seeds
    d = root / "MRCLAM_Dataset1"
    out = tmp_path / "o"
    assert _run(d, out, "--robots", "2", "--no-progress") == 0
    rows = study.run_dataset(d, study.MrclamParams(robots=[2], method="fast", max_gap=10.0,
                                                   spread_views=0, piece=8), seed=4)
    import csv

    with open(out / "triplets.csv") as fh:
        got = {(r["A"], r["B"], r["C"]): r for r in csv.DictReader(fh)}
    want = [r for r in rows if r["kind"] != "camera"]
    assert len(got) == len(want) > 0
    for r in want:
        g = got[(str(r["A"]), str(r["B"]), str(r["C"]))]
        assert g["kind"] == r["kind"] and g["probabilities"] == r["probabilities"]


# ------------------------------------------------------------------------------ the map step
def test_map_method_is_pluggable_recorded_and_resume_reuses_the_pieces(root, tmp_path,
                                                                       monkeypatch, capsys):
    from qfg.harness.studies.mrclam import maps as mrclam_maps

    made = []

    def flat(seen):
        made.append(len(seen.triplets))
        # every seen triplet, uniform: scored by the same code as any map
        s, m = seen.probabilities.shape
        assert seen.estimates.shape[1] == m and len(seen.histories()) == len(seen.estimates)
        return mrclam_maps.MapResult(seen.triplets, np.full((s, m), 1.0 / m), np.ones(s, bool),
                                     np.zeros(s, bool))

    monkeypatch.setitem(mrclam_maps.MAP_METHODS, "flat",
                        mrclam_maps.MapMethod("flat", flat, "uniform, for the test"))
    d = root / "MRCLAM_Dataset1"
    out = tmp_path / "o"
    assert _run(d, out, "--robots", "2", "--no-progress") == 0
    solved = (out / "records.jsonl").read_bytes()
    calls = []
    real = study.run_piece
    monkeypatch.setattr(study, "run_piece", lambda t, r: (calls.append(1), real(t, r))[1])
    # another map over the same solved pieces: nothing solved again
    assert main(["mrclam", str(d), "--output", str(out), "--piece-size", "8", "--seed", "4",
                 "--robots", "2", "--map", "flat", "--resume", "--no-progress", *FAST]) == 0
    assert not calls and made and (out / "records.jsonl").read_bytes() == solved
    import csv

    with open(out / "triplets.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert rows and {r["map"] for r in rows} == {"flat"}
    assert all(np.isclose(float(r["log_score"]), float(r["uniform_log_score"])) for r in rows)
    assert (out / "maps" / "flat.npz").exists() and (out / "maps" / "pooled.npz").exists()
    # the seen estimates, for work outside the pipeline: each seen triplet's estimate
    with np.load(out / "seen.npz") as z:
        seen_rows = {tuple(t): p for t, p in zip(z["triplet_ids"].tolist(), z["probabilities"],
                                                 strict=True)}
        assert (z["history_row"] >= 0).all() and len(z["estimates"]) == len(z["history_row"])
    with open(out / "triplets.csv") as fh:
        pooled_free = [r for r in csv.DictReader(fh) if r["kind"] == "seen"]
    assert set(seen_rows) == {(int(r["A"]), int(r["B"]), int(r["C"])) for r in pooled_free}
    # the recorded map is used again while its inputs are the same
    n = len(made)
    assert main(["mrclam", str(d), "--output", str(out), "--piece-size", "8", "--seed", "4",
                 "--robots", "2", "--map", "flat", "--resume", *FAST]) == 0
    assert len(made) == n and "as recorded" in capsys.readouterr().err
    # --overwrite starts again: the recorded maps too, not only the solved pieces
    assert main(["mrclam", str(d), "--output", str(out), "--piece-size", "8", "--seed", "4",
                 "--robots", "2", "--map", "flat", "--overwrite", *FAST]) == 0
    assert len(made) == n + 1 and "as recorded" not in capsys.readouterr().err
    assert not (out / "maps" / "pooled.npz").exists()
    # the former option names the same map
    assert study.map_name(True, "pooled") == "pooled" and study.map_name(False) == "seen"
    assert study.MrclamParams(propagation="best").map_method == "best"
    with pytest.raises(ValueError, match="'pooled'.*CHANGELOG.md"):
        study.map_name(True, "mean")


# ------------------------------------------------------------------------------ item 4: the table
def test_table_has_a_key_and_no_camera_view_says_why(root, tmp_path, capsys):
    out = tmp_path / "o"
    assert _run(root / "MRCLAM_Dataset1", out, "--robots", "2", "--no-progress") == 0
    printed = capsys.readouterr().out
    head = printed.splitlines()[0]
    for col in ("log score est.", "uniform", "prior", "Brier est.", "truth < 1% est."):
        assert col in head
    assert " / " not in printed.split("Key:")[0]
    assert "Key:" in printed and "prior alone" in printed
    assert "0 camera views scored (no motion capture (RobotN_Groundtruth) in MRCLAM_Dataset1 " \
           "for robot 2)" in printed
    assert "Key:" in (out / "table.md").read_text()
    summ = json.loads((out / "summary.json").read_text())
    assert summ["options"]["map"] == "pooled" and summ["options"]["robots"] == [2]


def test_ctrl_c_in_a_real_process_keeps_the_pieces_and_resume_finishes(root, tmp_path):
    """A ``qfg mrclam`` process sent SIGINT (to its group, as a terminal's Ctrl-C) once its first
    piece is recorded: one line, exit 130, the piece kept; resumed, the outputs of a run that
    went through. The child's second piece waits (a sleep the signal interrupts), so the signal
    always lands mid-run."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    d = root / "MRCLAM_Dataset1"
    part = tmp_path / "part"
    args = ["mrclam", str(d), "--output", str(part), "--piece-size", "8", "--seed", "4",
            "--map", "pooled", *FAST]
    code = ("import signal, sys, time\n"
            "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
            "from qfg.harness.studies import mrclam as study\n"
            "real = study.run_piece\n"
            "def slow(task, rng):\n"
            "    if task['index'] >= 1:\n"
            "        time.sleep(120)\n"
            "    return real(task, rng)\n"
            "study.run_piece = slow\n"
            "from qfg.harness.cli import main\n"
            f"sys.exit(main({args!r}))\n")
    here = str(Path(__file__).parent)
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, "PYTHONPATH": here})
    rec = part / "records.jsonl"
    deadline = time.time() + 120
    while time.time() < deadline and not (rec.exists() and rec.read_bytes().count(b"\n") >= 1):
        if proc.poll() is not None:
            break
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    last = stderr.strip().splitlines()[-1]
    assert "interrupted after 1 of" in last and "--resume" in last, stderr
    assert rec.read_bytes().count(b"\n") == 1 and not (part / "run.lock").exists()
    assert _run(d, part, "--resume", "--no-progress") == 0
    whole = tmp_path / "whole"
    assert _run(d, whole, "--no-progress") == 0
    assert (part / "triplets.csv").read_bytes() == (whole / "triplets.csv").read_bytes()
