"""The console command: --version, --help, demo and partitions."""

import subprocess
import sys

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
    png = tmp_path / "scenario.png"
    assert png.exists() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_partitions_command(tmp_path, capsys):
    png = tmp_path / "tpcc.png"
    assert main(["partitions", "--name", "tpcc", "--output", str(png)]) == 0
    out = capsys.readouterr().out
    assert "TPCC: 16 states" in out and png.exists()
    assert main(["partitions", "--name", "nope", "--output", str(png)]) == 2
    assert "unknown name 'nope'" in capsys.readouterr().err


def test_demo_map_compares_propagated_exact_and_truth(tmp_path):
    import numpy as np

    from qfg.harness.demo import run

    lines = []
    res = run(seed=1, output=tmp_path, methods=("fast",), echo=lines.append)
    rows = res["map"]
    assert rows and any(line.startswith("qualitative map:") for line in lines)
    for r in rows:
        for key in ("propagated", "exact"):
            p = np.asarray(r[key])
            assert p.shape == (20,) and np.all(p >= 0) and abs(p.sum() - 1) < 1e-9
        assert 0 <= r["truth"] < 20
