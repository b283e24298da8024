"""The console command: --version, --help, demo, partitions, messages and exit codes."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from qfg import __version__
from qfg.harness.cli import main


def test_version_and_help(capsys):
    try:
        main(["--version"])
    except SystemExit as e:
        assert e.code == 0
    assert __version__ in capsys.readouterr().out
    main([])
    out = capsys.readouterr().out
    assert "demo" in out and "partitions" in out and "experiment" in out


def test_installed_console_script():
    r = subprocess.run([sys.executable, "-m", "qfg.harness.cli", "--version"], capture_output=True, text=True)
    assert r.returncode == 0 and __version__ in r.stdout


def test_demo_writes_figure_and_prints_map(tmp_path, capsys):
    assert main(["demo", "--output", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "ground-truth EDC states" in out
    png = tmp_path / "figures" / "scenario.png"
    assert png.exists() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_partitions_command(tmp_path, capsys):
    assert main(["partitions", "--name", "tpcc", "--output", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    png = tmp_path / "figures" / "tpcc.png"
    assert "TPCC: 16 states" in out and png.exists()
    assert main(["partitions", "--name", "nope", "--output", str(tmp_path)]) == 2
    assert "unknown name 'nope'" in capsys.readouterr().err


def test_demo_map_compares_propagated_exact_and_truth(tmp_path):
    import numpy as np

    from qfg.harness.demo import run

    lines = []
    res = run(seed=1, output=tmp_path, methods=("fast",), echo=lines.append, fmt="svg")
    assert res["figure"] == tmp_path / "figures" / "scenario.svg"
    assert res["figure"].read_bytes()[:5] == b"<?xml"
    rows = res["map"]
    assert rows and any(line.startswith("qualitative map:") for line in lines)
    for r in rows:
        for key in ("propagated", "exact", "configurations"):
            p = np.asarray(r[key])
            assert p.shape == (20,) and np.all(p >= 0) and abs(p.sum() - 1) < 1e-9
        assert 0 <= r["truth"] < 20


HERE = Path(__file__).resolve().parent
MAGIC = {"png": b"\x89PNG", "pdf": b"%PDF", "svg": b"<?xml"}


def test_partitions_output_is_a_folder_like_every_command(tmp_path, capsys, monkeypatch):
    deep = tmp_path / "new" / "dir"
    assert main(["partitions", "--output", str(deep)]) == 0
    assert (deep / "figures" / "edc.png").read_bytes()[:4] == MAGIC["png"]
    for fmt in ("pdf", "svg"):
        assert main(["partitions", "--name", "lr", "--format", fmt, "--output",
                     str(tmp_path / "f")]) == 0
        got = tmp_path / "f" / "figures" / f"lr.{fmt}"
        assert got.read_bytes()[:len(MAGIC[fmt])] == MAGIC[fmt]
    # the former file-name form is refused with one line saying where the figure goes now
    assert main(["partitions", "--output", str(tmp_path / "y.png")]) == 2
    _one_error_line(capsys, "--output", "figures/edc.<format>")
    assert not (tmp_path / "y.png").exists()
    monkeypatch.chdir(tmp_path)  # the default goes under out/
    assert main(["partitions", "--name", "fdc", "--format", "pdf"]) == 0
    assert (tmp_path / "out" / "partitions" / "figures" / "fdc.pdf").read_bytes()[:4] == MAGIC["pdf"]


def _one_error_line(capsys, *words):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    for w in words:
        assert w in err[0], err[0]
    return err[0]


def test_experiment_input_errors_are_one_line_and_exit_2(tmp_path, capsys):
    f = tmp_path / "a_file"
    f.write_text("")
    base = ["experiment", "composition", "--no-progress"]
    assert main([*base, "--output", str(f)]) == 2
    _one_error_line(capsys, "is a file")
    assert main([*base, "--output", str(f / "sub")]) == 2
    _one_error_line(capsys, "which is a file")
    out = str(tmp_path / "o")
    for bad, name in ((["--set", "n_per_level=-1"], "n_per_level"),
                      (["--set", "n_per_level=abc"], "n_per_level"),
                      (["--set", "sigma_bearing_deg=[1, -2]"], "sigma_bearing_deg[1]"),
                      (["--set", "prior=magic"], "prior"), (["--set", "nope=1"], "nope")):
        assert main([*base, "--output", out, *bad]) == 2
        _one_error_line(capsys, name)
    for bad in (["--seed", "-1"], ["--workers", "0"], ["--workers", "-3"], ["--format", "jpg"]):
        with pytest.raises(SystemExit) as e:
            main([*base, "--output", out, *bad])
        assert e.value.code == 2
        assert bad[0] in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # nothing ran


def _toy_cli(args, out, **kw):
    """``qfg experiment toy-slow ...`` in a child process (its own session, so a SIGINT to the
    group is what Ctrl-C in a terminal sends), the toy studies registered."""
    # a shell started in the background hands its jobs SIGINT ignored; a terminal does not
    code = ("import signal; signal.signal(signal.SIGINT, signal.default_int_handler)\n"
            f"import sys; sys.path.insert(0, {str(HERE)!r}); import toy_study\n"
            "import qfg.harness.studies as S\n"
            "S.studies = lambda: {s.name: s for s in (toy_study.SLOW, toy_study.FAILING)}\n"
            "from qfg.harness.cli import main\n"
            f"sys.exit(main({['experiment', *args, '--no-progress', '--output', str(out)]!r}))")
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True, **kw)


def _presets(tmp_path):
    exp = tmp_path / "exp"
    exp.mkdir(exist_ok=True)
    (exp / "toy_slow.toml").write_text("[quick]\nn = 60\nsleep = 0.1\n")
    (exp / "toy_failing.toml").write_text("[quick]\nn = 3\n")
    return {**os.environ, "QFG_EXPERIMENTS": str(exp)}


@pytest.mark.parametrize("workers", ["1", "2"])
def test_ctrl_c_prints_one_line_exits_130_and_resume_finishes(tmp_path, workers):
    env = _presets(tmp_path)
    out = tmp_path / "o"
    proc = _toy_cli(["toy-slow", "--workers", workers], out, env=env)
    rec = out / "records.jsonl"
    deadline = time.time() + 60
    while time.time() < deadline and not (rec.exists() and rec.read_bytes().count(b"\n") >= 3):
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C in a terminal does: the whole group
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert "interrupted after" in lines[0] and "of 60 scenarios; continue with --resume" in lines[0]
    done = int(lines[0].split("interrupted after ")[1].split()[0])
    assert 3 <= done < 60
    assert not (out / "run.lock").exists()
    proc = _toy_cli(["toy-slow", "--resume", "--workers", workers], out, env=env)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 0, stderr
    assert sorted({json.loads(x)["index"] for x in rec.read_text().splitlines()}) == list(range(60))


def test_every_scenario_failing_exits_1(tmp_path):
    proc = _toy_cli(["toy-failing"], tmp_path / "o", env=_presets(tmp_path))
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 1
    assert "every scenario failed (3 of 3)" in stderr


def test_mrclam_follows_the_experiment_overwrite_rules(tmp_path, capsys):
    used = tmp_path / "used"
    used.mkdir()
    (used / "records.jsonl").write_text("")
    data = tmp_path / "MRCLAM_Dataset9"
    data.mkdir()
    assert main(["mrclam", str(data), "--output", str(used)]) == 2
    _one_error_line(capsys, "already holds a run", "--resume", "--overwrite")
    f = tmp_path / "file"
    f.write_text("")
    assert main(["mrclam", str(data), "--output", str(f / "x")]) == 2
    _one_error_line(capsys, "which is a file")


def test_tensors_build_refuses_to_overwrite_without_force(tmp_path, capsys):
    from qfg.composition import tensors_dir

    assert main(["tensors", "build", "--partition", "lr", "--output", str(tensors_dir())]) == 2
    line = _one_error_line(capsys, "shipped", "--force")
    assert "lr.npz" in line


def test_scheduler_without_dask_is_one_line(tmp_path, capsys, monkeypatch):
    # dask hidden: importing dask.distributed raises ImportError, as without the extra
    monkeypatch.setitem(sys.modules, "dask", None)
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    for name in ("composition", "all"):
        assert main(["experiment", name, "--scheduler", "tcp://127.0.0.1:1", "--no-progress",
                     "--output", str(tmp_path / "o")]) == 2
        _one_error_line(capsys, "pip install qfg[dask]")
    assert not (tmp_path / "o").exists()


def test_run_aborted_is_one_line_and_exit_1(tmp_path, capsys, monkeypatch):
    from qfg.harness import runner

    def stop(*a, **k):
        raise runner.RunAborted("cannot write x: No space left on device; continue with --resume")

    monkeypatch.setattr(runner, "run_study", stop)
    assert main(["experiment", "composition", "--no-progress", "--output",
                 str(tmp_path / "o")]) == 1
    _one_error_line(capsys, "No space left on device")


def test_an_unknown_preset_names_a_file_that_exists(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # wherever the user is, e.g. a pip install without a checkout
    assert main(["experiment", "single-triplet", "--preset", "nope", "--output",
                 str(tmp_path / "o")]) == 2
    line = _one_error_line(capsys, "--preset", "'nope'", "quick")
    named = line.split("(", 1)[1].split(" has ")[0]
    assert Path(named).is_absolute() and Path(named).is_file(), line


@pytest.mark.parametrize("argv", [["demo", "--bogus"], ["partitions", "--bogus=1"],
                                  ["mrclam-runs", "table", "x", "y", "--bogus"], ["--bogus"]])
def test_unknown_arguments_are_one_line_naming_them_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    _one_error_line(capsys, argv[-1], "unrecognized arguments")
