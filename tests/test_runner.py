"""The experiment runner: determinism across workers, resume after a kill, recorded failures."""

import contextlib
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


def _child(code: str, **kw) -> subprocess.Popen:
    """A Python child with the tests folder importable, in its own session (killable as a group)."""
    pre = (f"import sys; sys.path.insert(0, {str(HERE)!r}); import toy_study; "
           "from qfg.harness import runner; ")
    return subprocess.Popen([sys.executable, "-c", pre + code], start_new_session=True, **kw)


def _wait_records(rec: Path, n: int, timeout: float = 60):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if rec.exists() and rec.read_bytes().count(b"\n") >= n:
            return
        time.sleep(0.02)
    raise AssertionError(f"{rec}: fewer than {n} records after {timeout} s")




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
    proc = _child(f"runner.run_study(toy_study.SLOW, {params!r}, {str(out)!r}, seed=5, workers=2, "
                  "progress=False)")
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


# ------------------------------------------------------------------ one run per output directory
def test_a_second_run_on_a_running_output_is_refused(tmp_path):
    out = tmp_path / "o"
    params = {"n": 200, "sleep": 0.05}
    proc = _child(f"runner.run_study(toy_study.SLOW, {params!r}, {str(out)!r}, progress=False)")
    try:
        _wait_records(out / "records.jsonl", 2)
        lock = json.loads((out / runner.LOCK_NAME).read_text())
        assert lock["pid"] == proc.pid and lock["host"]
        for resume in (True, False):
            with pytest.raises(runner.OutputInUse, match=f"in use by pid {proc.pid}"):
                runner.run_study(toy_study.SLOW, params, out, resume=resume, progress=False)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    # the holder is dead: its lock is stale and a resume takes it over, then releases it
    rows = runner.run_study(toy_study.SLOW, {"n": 200, "sleep": 0.0}, out, resume=False,
                            overwrite=True, progress=False)
    assert len({r["scenario"] for r in rows}) == 200
    assert not (out / runner.LOCK_NAME).exists()


def test_stale_lock_of_a_dead_process_is_taken_over(tmp_path, capsys):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (tmp_path / runner.LOCK_NAME).write_text(json.dumps({"pid": dead.pid, "host": runner.this_host()}))
    runner.run_study(toy_study.STUDY, {"n": 3}, tmp_path, progress=False)
    assert f"took over the lock of pid {dead.pid}" in capsys.readouterr().err
    # a lock naming another host is never broken automatically
    other = {"pid": os.getpid(), "host": "elsewhere.example"}
    (tmp_path / runner.LOCK_NAME).write_text(json.dumps(other))
    with pytest.raises(runner.OutputInUse, match="elsewhere.example"):
        runner.run_study(toy_study.STUDY, {"n": 3}, tmp_path, resume=True, progress=False)


def test_lock_without_flock_uses_the_pid(tmp_path, monkeypatch):
    monkeypatch.setattr(runner.lock, "fcntl", None)
    with runner.OutputLock(tmp_path) as lk:
        assert json.loads(lk.path.read_text())["pid"] == os.getpid()
        with pytest.raises(runner.OutputInUse):
            runner.OutputLock(tmp_path).acquire()  # this (live) process holds it
    assert not (tmp_path / runner.LOCK_NAME).exists()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (tmp_path / runner.LOCK_NAME).write_text(json.dumps({"pid": dead.pid, "host": runner.this_host()}))
    with runner.OutputLock(tmp_path) as lk:
        assert lk.took_over["pid"] == dead.pid


def test_duplicate_records_are_read_once(tmp_path):
    params = {"n": 6}
    ref = runner.run_study(toy_study.STUDY, params, tmp_path / "ref", seed=2, progress=False)
    out = tmp_path / "dup"
    runner.run_study(toy_study.STUDY, params, out, seed=2, progress=False)
    rec = out / "records.jsonl"
    lines = rec.read_bytes().splitlines(keepends=True)
    # what two concurrent resumes used to leave: every scenario twice, one failure in between
    fail = json.dumps({"index": 1, "seed": [2, 1], "error": "RuntimeError: x"}).encode() + b"\n"
    rec.write_bytes(b"".join(lines) + fail + b"".join(lines[::-1]))
    ok, failed = runner.dedupe_records(runner.read_records(rec)[0])
    assert [r["index"] for r in ok] == list(range(6)) and failed == []
    rows = runner.run_study(toy_study.STUDY, params, out, seed=2, resume=True, progress=False)
    assert len(rows) == len(ref) == 18
    assert (out / "rows.csv").read_bytes() == (tmp_path / "ref" / "rows.csv").read_bytes()
    assert not (out / "errors.json").exists()


def test_fresh_starts_released_together_exactly_one_proceeds(tmp_path):
    go = tmp_path / "go"
    for trial in range(3):
        out = tmp_path / f"run{trial}"
        code = (f"import os, time\nwhile not os.path.exists({str(go)!r}): time.sleep(0.001)\n"
                f"try:\n    runner.run_study(toy_study.SLOW, {{'n': 4, 'sleep': 0.05}}, "
                f"{str(out)!r}, progress=False)\nexcept runner.RunnerError as e:\n"
                "    print(type(e).__name__, e); sys.exit(2)")
        procs = [subprocess.Popen([sys.executable, "-c",
                                   f"import sys; sys.path.insert(0, {str(HERE)!r}); import toy_study;"
                                   f" from qfg.harness import runner\n" + code],
                                  stdout=subprocess.PIPE, text=True) for _ in range(3)]
        time.sleep(1.5)  # every child imported and waiting
        go.touch()
        codes = [p.wait(60) for p in procs]
        go.unlink()
        assert sorted(codes) == [0, 2, 2], (codes, [p.stdout.read() for p in procs])
        assert len(runner.read_records(out / "records.jsonl")[0]) == 4


def _proc_children(pid: int) -> list[int]:
    kids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                kids.append(int(d.name))
    return kids


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"  # a zombie has exited; only its exit status is left


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_sigkill_of_the_main_process_leaves_no_worker(tmp_path):
    out = tmp_path / "o"
    proc = _child(f"runner.run_study(toy_study.SLOW, {{'n': 400, 'sleep': 0.05}}, {str(out)!r}, "
                  "workers=2, progress=False)")
    try:
        _wait_records(out / "records.jsonl", 4)
        workers = _proc_children(proc.pid)
        assert len(workers) >= 2, workers  # the pool (and its resource tracker, if any)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        deadline = time.time() + 5
        while time.time() < deadline and any(_alive(w) for w in workers):
            time.sleep(0.05)
        assert not [w for w in workers if _alive(w)], "a worker outlived the main process"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)


# ------------------------------------------------------------------ arguments checked up front
def test_bad_seed_workers_and_output_are_rejected_before_running(tmp_path):
    for seed in (-1, 1.5, "3", True):
        with pytest.raises(runner.RunnerError, match="seed"):
            runner.run_study(toy_study.STUDY, {"n": 2}, tmp_path / "s", seed=seed, progress=False)
    for workers in (0, -3, 2.0):
        with pytest.raises(runner.RunnerError, match="workers"):
            runner.run_study(toy_study.STUDY, {"n": 2}, tmp_path / "w", workers=workers,
                             progress=False)
    f = tmp_path / "a_file"
    f.write_text("x")
    with pytest.raises(runner.RunnerError, match="is a file"):
        runner.run_study(toy_study.STUDY, {"n": 2}, f, progress=False)
    with pytest.raises(runner.RunnerError, match="which is a file"):
        runner.run_study(toy_study.STUDY, {"n": 2}, f / "sub", progress=False)
    with pytest.raises(runner.RunnerError, match="no scenarios"):
        runner.run_study(toy_study.STUDY, {"n": 0}, tmp_path / "z", progress=False)
    assert not any((tmp_path / d).exists() for d in ("s", "w", "z"))


def test_every_scenario_failing_is_an_error(tmp_path):
    with pytest.raises(runner.ScenariosFailed, match="every scenario failed"):
        runner.run_study(toy_study.FAILING, {"n": 3}, tmp_path, progress=False)
    assert len(json.loads((tmp_path / "errors.json").read_text())) == 3


def test_param_spec_names_the_parameter():
    spec = runner.param_spec({"n": 10, "xs": [1.0], "mode": "a", "flag": False},
                             n={"min": 1}, xs={"min": 0.0, "nonempty": True},
                             mode={"choices": ("a", "b")})
    assert runner.validate_params(spec, {"n": 2, "xs": [0, 2.5]}) == \
        {"n": 2, "xs": [0.0, 2.5], "mode": "a", "flag": False}
    bad = [({"n": -1}, "n: expected an integer >= 1"), ({"n": "abc"}, "n: expected an integer"),
           ({"n": 2.0}, "n: expected an integer"), ({"n": True}, "n: expected an integer"),
           ({"xs": []}, "xs: expected a non-empty"), ({"xs": [1, -2]}, r"xs\[1\]"),
           ({"xs": 3}, "xs: expected a list"), ({"mode": "c"}, "mode: expected one of"),
           ({"flag": "yes"}, "flag: expected true or false"), ({"zz": 1}, "unknown zz"),
           ({"xs": [float("nan")]}, "finite")]
    for params, msg in bad:
        with pytest.raises(runner.RunnerError, match=msg):
            runner.validate_params(spec, params)


def test_every_preset_satisfies_its_study_spec():
    from qfg.harness.studies import studies

    found = studies()
    assert found and all(st.params is not None for st in found.values())
    for name, st in found.items():
        for preset, params in runner.load_presets(name).items():
            runner.validate_params(st.params, params), (name, preset)


def test_tables_and_figures_have_one_writer(tmp_path):
    path = runner.write_table(tmp_path / "t.csv", [{"a": 1.23456789, "b": "x"}, {"a": None, "c": True}])
    assert path.read_text() == "a,b,c\n1.23457,x,\n,,True\n"
    runner.write_table(tmp_path / "u.csv", [{"a": 1.23456789}], digits=None)
    assert (tmp_path / "u.csv").read_text() == "a\n1.23456789\n"
    import matplotlib.pyplot as plt

    magic = {"png": b"\x89PNG", "pdf": b"%PDF", "svg": b"<?xml"}
    for fmt, head in magic.items():
        with runner.use_figure_format(fmt):
            fig, ax = plt.subplots()
            p = runner.save_figure(fig, tmp_path / "new" / "dir", "f")
        assert p == tmp_path / "new" / "dir" / "figures" / f"f.{fmt}"
        assert p.read_bytes()[:len(head)] == head
    with pytest.raises(runner.RunnerError, match="format"):
        runner.run_study(toy_study.STUDY, {"n": 1}, tmp_path / "f", figure_format="jpg",
                         progress=False)


# ------------------------------------------------------------------ issue 18: nothing lost
def _no_time(rows):
    return [{k: v for k, v in r.items() if k != "time_s"} for r in rows]


def test_a_worker_killed_by_a_signal_is_replaced_and_its_scenarios_rerun(tmp_path):
    import toy_faults

    flags = tmp_path / "flags"
    flags.mkdir()
    params = {"n": 12, "kill": [3, 7], "mode": "once", "flags": str(flags)}
    ref = runner.run_study(toy_study.STUDY, {"n": 12}, tmp_path / "ref", seed=4, progress=False)
    ex = runner.ProcessExecutor(2)
    try:
        rows = runner.run_study(toy_faults.KILLING, params, tmp_path / "o", seed=4, executor=ex,
                                progress=False)
    finally:
        ex.close()
    assert (flags / "killed-3").exists() and (flags / "killed-7").exists()
    assert ex.restarts >= 1
    assert rows == _no_time(ref)
    assert not (tmp_path / "o" / "errors.json").exists()
    # with the runner's own pool (no executor given) as well
    for f in flags.iterdir():
        f.unlink()
    rows2 = runner.run_study(toy_faults.KILLING, params, tmp_path / "o2", seed=4, workers=2,
                             progress=False)
    assert rows2 == rows and (flags / "killed-3").exists()


def test_a_scenario_that_always_kills_its_worker_stops_with_one_line_and_resumes(tmp_path):
    import toy_faults

    flags = tmp_path / "flags"
    flags.mkdir()
    params = {"n": 10, "kill": [4], "mode": "until-healed", "flags": str(flags)}
    out = tmp_path / "o"
    with pytest.raises(runner.RunAborted) as info:
        runner.run_study(toy_faults.KILLING, params, out, seed=2, workers=2, progress=False)
    msg = str(info.value)
    assert "\n" not in msg and "scenario 4" in msg and "SIGKILL" in msg and "--resume" in msg
    # alone in the pool 1 + retries times, then blamed; the other scenarios are all recorded
    assert (flags / "killed-4").read_text().count("x") >= 3
    recs = runner.read_records(out / "records.jsonl")[0]
    assert 4 not in {r["index"] for r in recs} and len(recs) >= 1
    (flags / "healed").touch()
    rows = runner.run_study(toy_faults.KILLING, params, out, seed=2, resume=True, workers=2,
                            progress=False)
    ref = runner.run_study(toy_study.STUDY, {"n": 10}, tmp_path / "ref", seed=2, progress=False)
    assert rows == _no_time(ref)


def _mount(target: Path, *opts: str) -> bool:
    """Mount (root only); False when this test process cannot."""
    if not sys.platform.startswith("linux") or os.geteuid() != 0:
        return False
    r = subprocess.run(["mount", *opts, str(target)], capture_output=True)
    return r.returncode == 0


def _umount(target: Path):
    subprocess.run(["umount", "-l", str(target)], capture_output=True)


def test_a_full_disk_stops_with_one_line_and_loses_nothing(tmp_path):
    disk = tmp_path / "disk"
    disk.mkdir()
    if not _mount(disk, "-t", "tmpfs", "-o", "size=64k", "tmpfs"):
        pytest.skip("cannot mount a small tmpfs here (needs root on Linux)")
    try:
        out = disk / "o"
        params = {"n": 600}  # about 170 kB of records: the disk fills mid-run
        with pytest.raises(runner.RunAborted) as info:
            runner.run_study(toy_study.STUDY, params, out, seed=6, progress=False)
        msg = str(info.value)
        assert "\n" not in msg and "No space left on device" in msg and "--resume" in msg
        rec = out / "records.jsonl"
        recs, good = runner.read_records(rec)
        assert good == rec.stat().st_size, "the file must end at its last complete record"
        assert 10 < len(recs) < 600
        assert f"{len(recs)} of 600 scenarios" in msg
        assert not (out / runner.LOCK_NAME).exists()
        # room again: the resume completes it, identical to an uninterrupted run
        assert _mount(disk, "-o", "remount,size=4m")
        rows = runner.run_study(toy_study.STUDY, params, out, seed=6, resume=True,
                                progress=False)
        ref = runner.run_study(toy_study.STUDY, params, tmp_path / "ref", seed=6, progress=False)
        assert [(r["scenario"], r["x"]) for r in rows] == [(r["scenario"], r["x"]) for r in ref]
        assert (out / "rows.csv").read_bytes() == (tmp_path / "ref" / "rows.csv").read_bytes()
    finally:
        _umount(disk)


def test_a_disk_full_while_writing_the_outputs_keeps_every_record(tmp_path):
    import toy_faults

    disk = tmp_path / "disk"
    disk.mkdir()
    if not _mount(disk, "-t", "tmpfs", "-o", "size=64k", "tmpfs"):
        pytest.skip("cannot mount a small tmpfs here (needs root on Linux)")
    try:
        out = disk / "o"
        params = {"n": 5, "bytes": 200_000}
        with pytest.raises(runner.RunAborted) as info:
            runner.run_study(toy_faults.BIG_SUMMARY, params, out, seed=1, progress=False)
        msg = str(info.value)
        assert "\n" not in msg and "No space left on device" in msg and "--resume" in msg
        assert len(runner.read_records(out / "records.jsonl")[0]) == 5
        assert not list(out.glob(".*.tmp")), "the temporary file is removed"
        assert not (out / "big.txt").exists()
        assert _mount(disk, "-o", "remount,size=1m")
        runner.run_study(toy_faults.BIG_SUMMARY, params, out, seed=1, resume=True,
                         progress=False)
        assert (out / "big.txt").stat().st_size == 200_000
    finally:
        _umount(disk)


def test_an_unwritable_records_file_is_one_line(tmp_path):
    out = tmp_path / "o"
    runner.run_study(toy_study.STUDY, {"n": 4}, out, seed=1, progress=False)
    rec = out / "records.jsonl"
    rec.write_bytes(b"".join(rec.read_bytes().splitlines(keepends=True)[:2]))  # 2 still to run
    before = rec.read_bytes()
    # read-only: a read-only bind mount of the file (chmod does not stop root)
    if _mount(rec, "--bind", str(rec)):
        try:
            if not _mount(rec, "-o", "remount,ro,bind"):
                pytest.skip("cannot remount read-only here")
            with pytest.raises(runner.RunnerError, match=r"cannot write .*records\.jsonl.*"
                                                         r"Read-only file system"):
                runner.run_study(toy_study.STUDY, {"n": 4}, out, seed=1, resume=True,
                                 progress=False)
        finally:
            _umount(rec)
        assert rec.read_bytes() == before
    # a folder where the records file should be
    rec.unlink()
    rec.mkdir()
    for kw in ({"resume": True}, {"overwrite": True}):
        with pytest.raises(runner.RunnerError, match="records.jsonl") as info:
            runner.run_study(toy_study.STUDY, {"n": 4}, out, seed=1, progress=False, **kw)
        assert "\n" not in str(info.value)


def test_resume_with_another_seed_is_refused_even_without_run_json(tmp_path):
    out = tmp_path / "o"
    runner.run_study(toy_study.STUDY, {"n": 4}, out, seed=3, progress=False)
    (out / "run.json").unlink()
    with pytest.raises(runner.RunnerError, match=r"records\.jsonl:1: scenario 0 was recorded "
                                                 r"with seed \[3, 0\], not \[4, 0\]"):
        runner.run_study(toy_study.STUDY, {"n": 4}, out, seed=4, resume=True, progress=False)
    # the same seed, but the study and params can no longer be checked
    with pytest.raises(runner.RunnerError, match="run.json is missing"):
        runner.run_study(toy_study.STUDY, {"n": 4}, out, seed=3, resume=True, progress=False)
    recs = runner.read_records(out / "records.jsonl")[0]
    assert [r["seed"] for r in recs] == [[3, r["index"]] for r in recs] and len(recs) == 4
    assert not (out / "run.json").exists()  # refused before writing anything


@pytest.mark.parametrize("text", ["[1, 2]\n", "{not json\n", "\"a string\"\n", "\xff\n"])
def test_a_damaged_run_json_is_one_line_naming_it(tmp_path, text):
    out = tmp_path / "o"
    runner.run_study(toy_study.STUDY, {"n": 2}, out, seed=0, progress=False)
    (out / "run.json").write_bytes(text.encode("latin-1"))
    with pytest.raises(runner.RunnerError, match=r"run\.json: ") as info:
        runner.run_study(toy_study.STUDY, {"n": 2}, out, seed=0, resume=True, progress=False)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("bad", ['{"index": -1, "seed": [0, -1], "rows": []}',
                                 '{"index": true, "seed": [0, 1], "rows": []}',
                                 '{"index": 1.0, "seed": [0, 1], "rows": []}',
                                 '{"index": 1, "seed": [0, 1], "rows": 5}',
                                 '{"index": 1, "seed": [0, 1], "rows": [5]}',
                                 '{"index": 1, "seed": [0, 1]}',
                                 '[1]'])
def test_records_that_are_not_records_are_rejected_with_file_and_line(tmp_path, bad):
    out = tmp_path / "o"
    runner.run_study(toy_study.STUDY, {"n": 3}, out, seed=0, progress=False)
    rec = out / "records.jsonl"
    lines = rec.read_text().splitlines(keepends=True)
    rec.write_text(lines[0] + bad + "\n" + "".join(lines[1:]))
    with pytest.raises(runner.RunnerError, match=r"records\.jsonl:2: not a runner record"):
        runner.run_study(toy_study.STUDY, {"n": 3}, out, seed=0, resume=True, progress=False)


def test_outputs_replace_planted_links_instead_of_writing_through_them(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    out = tmp_path / "o"
    out.mkdir()
    for name in ("rows.csv", "timings.csv", "run.json"):
        (out / name).symlink_to(victim)
    runner.run_study(toy_study.STUDY, {"n": 3, "fail": [1]}, out, seed=0, progress=False)
    assert victim.read_text() == "precious\n"
    for name in ("rows.csv", "timings.csv", "run.json", "errors.json"):
        assert (out / name).is_file() and not (out / name).is_symlink()
    assert (out / "rows.csv").read_text().startswith("scenario,")
    # errors.json, a figure, a table: the same writer
    (out / "errors.json").unlink()
    (out / "errors.json").symlink_to(victim)
    (out / "figures").mkdir()
    (out / "figures" / "f.png").symlink_to(victim)
    runner.run_study(toy_study.STUDY, {"n": 3, "fail": [1]}, out, seed=0, progress=False,
                     overwrite=True)
    import matplotlib.pyplot as plt

    runner.save_figure(plt.figure(), out, "f")
    assert victim.read_text() == "precious\n"
    assert (out / "figures" / "f.png").read_bytes()[:4] == b"\x89PNG"
    # the records file and the lock are never written through a link either
    for name in ("records.jsonl", runner.LOCK_NAME):
        o = tmp_path / name
        o.mkdir()
        (o / name).symlink_to(victim)
        with pytest.raises(runner.RunnerError, match=name.replace(".", r"\.")):
            runner.run_study(toy_study.STUDY, {"n": 2}, o, resume=True, progress=False)
        assert victim.read_text() == "precious\n"


def test_resume_of_a_run_recorded_by_another_version_says_so(tmp_path, capsys):
    """Solver defaults change between versions: a resumed run keeps its records and says which
    version made them; a run of this version resumes silently."""
    params = {"n": 4}
    first = runner.run_study(toy_study.STUDY, params, tmp_path, seed=1, progress=False)
    meta = json.loads((tmp_path / "run.json").read_text())
    assert meta["version"] == runner.__version__
    capsys.readouterr()
    runner.run_study(toy_study.STUDY, params, tmp_path, seed=1, resume=True, progress=False)
    assert "recorded by qfg" not in capsys.readouterr().err
    (tmp_path / "run.json").write_text(json.dumps({**meta, "version": "0.0.1"}))
    rows = runner.run_study(toy_study.STUDY, params, tmp_path, seed=1, resume=True,
                            progress=False)
    err = capsys.readouterr().err
    assert "recorded by qfg 0.0.1" in err and runner.__version__ in err
    assert rows == first
