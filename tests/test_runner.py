"""The experiment runner: determinism across workers, resume after a kill, recorded failures."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import toy_study

from qfg.harness import runner

HERE = Path(__file__).resolve().parent


def test_same_seed_same_rows_with_1_and_2_workers(tmp_path):
    params = {"n": 12}
    r1 = runner.run_study(toy_study.STUDY, params, tmp_path / "w1", seed=7, workers=1, progress=False)
    r2 = runner.run_study(toy_study.STUDY, params, tmp_path / "w2", seed=7, workers=2, progress=False)
    assert (tmp_path / "w1" / "rows.csv").read_bytes() == (tmp_path / "w2" / "rows.csv").read_bytes()
    assert [r["x"] for r in r1] == [r["x"] for r in r2]
    assert [r["scenario"] for r in r1] == sorted(r["scenario"] for r in r1)
    r3 = runner.run_study(toy_study.STUDY, params, tmp_path / "s8", seed=8, progress=False)
    assert [r["x"] for r in r3] != [r["x"] for r in r1]
    # timing columns go to timings.csv, not rows.csv
    assert "time_s" not in (tmp_path / "w1" / "rows.csv").read_text().splitlines()[0]
    assert (tmp_path / "w1" / "timings.csv").exists()


def test_failures_are_recorded_and_the_run_goes_on(tmp_path, capsys):
    rows = runner.run_study(toy_study.STUDY, {"n": 6, "fail": [2, 4]}, tmp_path, seed=1,
                            progress=False)
    assert sorted({r["scenario"] for r in rows}) == [0, 1, 3, 5]
    errs = json.loads((tmp_path / "errors.json").read_text())
    assert [e["index"] for e in errs] == [2, 4]
    assert errs[0]["seed"] == [1, 2] and "fails on purpose" in errs[0]["error"]
    assert "Traceback" in errs[0]["traceback"]
    assert "2 scenario(s) failed" in capsys.readouterr().err


def test_partial_last_line_is_detected_and_dropped(tmp_path):
    params = {"n": 5}
    full = runner.run_study(toy_study.STUDY, params, tmp_path / "a", seed=3, progress=False)
    rec = tmp_path / "a" / "records.jsonl"
    lines = rec.read_bytes().splitlines(keepends=True)
    # keep two complete records and half of the third, as a kill mid-write would leave it
    rec.write_bytes(b"".join(lines[:2]) + lines[2][: len(lines[2]) // 2])
    done, good = runner.read_records(rec)
    assert len(done) == 2 and good == len(b"".join(lines[:2]))
    resumed = runner.run_study(toy_study.STUDY, params, tmp_path / "a", seed=3, resume=True,
                               progress=False)
    assert [r["x"] for r in resumed] == [r["x"] for r in full]
    assert len(runner.read_records(rec)[0]) == 5


def test_used_output_needs_resume_or_overwrite(tmp_path):
    runner.run_study(toy_study.STUDY, {"n": 2}, tmp_path, progress=False)
    with pytest.raises(runner.RunnerError, match="--resume"):
        runner.run_study(toy_study.STUDY, {"n": 2}, tmp_path, progress=False)
    with pytest.raises(runner.RunnerError, match="different"):
        runner.run_study(toy_study.STUDY, {"n": 3}, tmp_path, resume=True, progress=False)
    runner.run_study(toy_study.STUDY, {"n": 3}, tmp_path, overwrite=True, progress=False)


def test_killed_run_resumes_to_the_uninterrupted_result(tmp_path):
    params = {"n": 40, "sleep": 0.05}
    ref = runner.run_study(toy_study.SLOW, params, tmp_path / "ref", seed=5, progress=False)
    out = tmp_path / "killed"
    code = (f"import sys; sys.path.insert(0, {str(HERE)!r}); import toy_study; from qfg.harness import runner;"
            f"runner.run_study(toy_study.SLOW, {params!r}, {str(out)!r}, seed=5, workers=2, "
            "progress=False)")
    proc = subprocess.Popen([sys.executable, "-c", code], start_new_session=True)
    rec = out / "records.jsonl"
    deadline = time.time() + 60
    while time.time() < deadline:
        if rec.exists() and rec.read_bytes().count(b"\n") >= 5:
            break
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    n_before = len(runner.read_records(rec)[0])
    assert 5 <= n_before < 40, "the kill should land mid-run"
    resumed = runner.run_study(toy_study.SLOW, params, out, seed=5, resume=True, workers=2,
                               progress=False)
    assert [(r["scenario"], r["k"], r["x"]) for r in resumed] == \
        [(r["scenario"], r["k"], r["x"]) for r in ref]
    assert (out / "rows.csv").read_bytes() == (tmp_path / "ref" / "rows.csv").read_bytes()


def test_presets_and_overrides(tmp_path, monkeypatch):
    (tmp_path / "toy.toml").write_text("[quick]\nn = 3\n[paper]\nn = 300\nname = 'x'\n")
    monkeypatch.setenv("QFG_EXPERIMENTS", str(tmp_path))
    assert runner.load_presets("toy") == {"quick": {"n": 3}, "paper": {"n": 300, "name": "x"}}
    from qfg.harness.commands.experiment import parse_overrides

    assert parse_overrides(["n=5", "s=abc", "l=[1, 2]"]) == {"n": 5, "s": "abc", "l": [1, 2]}
    with pytest.raises(ValueError, match="KEY=VALUE"):
        parse_overrides(["oops"])
    (tmp_path / "bad.toml").write_text("[quick\n")
    with pytest.raises(runner.RunnerError, match="bad.toml"):
        runner.load_presets("bad")
