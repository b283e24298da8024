"""What a user meets before any science: the install's metadata and the top-level namespace."""

import subprocess
import sys
import warnings
from pathlib import Path

import pytest

import qfg

REPO = Path(qfg.__file__).resolve().parent.parent


def test_pyproject_licence_is_an_spdx_expression_and_the_build_does_not_warn(monkeypatch):
    setuptools = pytest.importorskip("setuptools")
    if int(setuptools.__version__.split(".")[0]) < 77:
        pytest.skip("setuptools < 77 (the test extra asks for >= 77) reads no SPDX licence")
    from setuptools.config.pyprojecttoml import apply_configuration
    from setuptools.dist import Distribution

    monkeypatch.chdir(REPO)  # license-files and readme are relative to the project
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dist = apply_configuration(Distribution(), REPO / "pyproject.toml")
    assert [str(w.message).splitlines()[0] for w in caught] == []
    assert dist.metadata.license_expression == "BSD-3-Clause"


def test_dir_of_qfg_lists_only_its_own_names():
    # a fresh interpreter: what `import qfg; dir(qfg)` shows a user
    out = subprocess.run([sys.executable, "-c", "import qfg; print(' '.join(dir(qfg)))"],
                         capture_output=True, text=True, check=True).stdout.split()
    public = [n for n in out if not n.startswith("_")]
    assert "annotations" not in public and "importlib" not in public
    assert set(public) == set(qfg.__all__) - {"__version__"}
