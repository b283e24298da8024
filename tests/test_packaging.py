"""The package installs anywhere: a wheel built from the checkout carries the shipped tensors, the
study presets and the licence, and a non-editable install used from another directory finds
them; an editable install of a clone named ``qfg`` also works from the folder holding the clone.

Everything is installed without downloads: ``--no-deps --no-build-isolation`` with this
environment's setuptools and wheel, into virtual environments that see this environment's
packages through a ``.pth`` file.
"""

import os
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

import qfg

pytestmark = pytest.mark.skipif(os.name != "posix", reason="virtual environments laid out as bin/")

REPO = Path(qfg.__file__).resolve().parent.parent
SKIP = {".git", ".venv", "out", "results", "build", "dist", ".hypothesis", ".pytest_cache",
        ".ruff_cache", "__pycache__"}


def _copy_checkout(dest: Path) -> Path:
    shutil.copytree(REPO, dest, symlinks=True,
                    ignore=lambda d, names: [n for n in names if n in SKIP or n.endswith(".egg-info")])
    return dest


def _venv(path: Path) -> Path:
    """A virtual environment at ``path`` seeing this environment's packages (not its qfg)."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(path)], check=True)
    py = path / "bin" / "python"
    site = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    Path(site, "_qfg_test_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return py


def _run(args, cwd, **kw):
    env = {k: v for k, v in os.environ.items()
           if k not in ("QFG_TENSORS", "QFG_EXPERIMENTS", "PYTHONPATH")}
    env["MPLBACKEND"] = "Agg"
    r = subprocess.run(args, cwd=cwd, capture_output=True, text=True, env=env, timeout=600, **kw)
    assert r.returncode == 0, f"{args}\n{r.stdout}\n{r.stderr}"
    return r.stdout


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    src = _copy_checkout(tmp_path_factory.mktemp("src") / "qfg")
    dist = tmp_path_factory.mktemp("dist")
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
          "-w", str(dist), str(src)], cwd=dist)
    (whl,) = dist.glob("qfg-*.whl")
    return whl


def test_wheel_carries_tensors_presets_and_licence(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    for part in ("edc", "fdc", "lr", "tpcc"):
        assert f"qfg/_tensors/{part}.npz" in names
    shipped = sorted(p.name for p in (REPO / "experiments" / "presets").glob("*.toml"))
    assert shipped and all(f"qfg/_presets/{n}" in names for n in shipped)
    # the presets only: the investigation scripts of experiments/ are no package code
    assert not any(n.startswith("qfg/_presets/") and not n.endswith(".toml") for n in names)
    # setuptools >= 69 files it under licenses/
    assert any(re.search(r"\.dist-info/(licenses/)?LICENSE$", n) for n in names)
    assert not any(n.startswith(("tests/", "benchmarks/", "tensors/", "experiments/")) for n in names)


def test_installed_wheel_works_from_another_directory(wheel, tmp_path):
    py = _venv(tmp_path / "venv")
    _run([str(py), "-m", "pip", "install", "--no-deps", "--no-index", "-q", str(wheel)], cwd=tmp_path)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    out = _run([str(py), "-c",
                "import qfg, numpy as np\n"
                "from qfg.composition import tensor, tensors_dir\n"
                "from qfg.harness.runner import load_presets, presets_dir\n"
                "t = tensor('edc'); assert np.asarray(t).shape == (20, 20, 20)\n"
                "assert load_presets('composition')['quick']\n"
                "print(qfg.__file__); print(tensors_dir()); print(presets_dir())"], cwd=elsewhere)
    site = str(tmp_path / "venv")
    assert all(line.startswith(site) for line in out.split()), out  # nothing from the checkout
    qfg_cmd = str(tmp_path / "venv" / "bin" / "qfg")
    _run([qfg_cmd, "tensors", "info"], cwd=elsewhere)
    out = _run([qfg_cmd, "experiment", "composition", "--preset", "quick", "--no-progress",
                "--set", "n_per_level=1", "--set", "sigma_bearing_deg=[2.0]"], cwd=elsewhere)
    assert "composition: 1 rows in out/composition-quick" in out
    assert (elsewhere / "out" / "composition-quick" / "figures" / "composition_dmse.png").exists()


def test_editable_install_of_a_clone_named_qfg_works_from_its_parent(tmp_path):
    clone = _copy_checkout(tmp_path / "holder" / "qfg")
    py = _venv(tmp_path / "venv")
    _run([str(py), "-m", "pip", "install", "--no-deps", "--no-build-isolation", "-q", "-e",
          str(clone)], cwd=tmp_path)
    # the folder holding the clone has a directory called qfg: it must not shadow the package
    out = _run([str(py), "-c",
                "import qfg\nfrom qfg.composition import tensor, tensors_dir\n"
                "from qfg.harness.runner import presets_dir\ntensor('lr')\n"
                "print(qfg.__file__); print(tensors_dir()); print(presets_dir())"],
               cwd=clone.parent)
    f, t, p = out.split()
    assert Path(f) == clone / "qfg" / "__init__.py"
    assert Path(t) == (clone / "tensors").resolve()
    assert Path(p) == (clone / "experiments" / "presets").resolve()
    assert not list(Path(p).rglob("*.py"))  # no script reachable as qfg._presets.<name>
