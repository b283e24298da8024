"""The API reference builds (``make docs``): Sphinx with autodoc, autosummary and napoleon over
docs/api, from a copy of that directory into a temporary one, as the Makefile does.

Fails on real errors: a non-zero exit, a module or object autodoc cannot import, an ERROR or
CRITICAL message of Sphinx itself (a broken directive in docs/api, a toctree entry that names no
document), or a main page missing. Tolerated, and printed for the record: docstring-format
messages from docutils (tagged ``[docutils]``: indentation, block quotes, emphasis, and
"undefined substitution" where a plain-text docstring writes ``|x|`` for an absolute value),
duplicate object descriptions of names a package re-exports (``qfg.inference.Marginals`` is
also documented where it is defined) and ambiguous cross-references among them.
"""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("sphinx", reason="the docs extra (pip install -e '.[docs]'; make installs it)")

REPO = Path(__file__).resolve().parents[1]
MODULES = ("qfg.joint", "qfg.solvers", "qfg.graph", "qfg.propagation", "qfg.configurations",
           "qfg.inference", "qfg.metrics", "qfg.partitions", "qfg.simulation", "qfg.geometry")
REAL = re.compile(r"failed to import|Failed to import|no module named|\bERROR\b|\bCRITICAL\b"
                  r"|\bSEVERE\b|nonexisting document|toctree contains|Unknown directive"
                  r"|autosummary: stub file not found|Summarised items should not", re.I)


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("api")
    src, out, warn = tmp / "src", tmp / "html", tmp / "warnings.txt"
    shutil.copytree(REPO / "docs" / "api", src)
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-b", "html", "-q", "-w", str(warn),
                           str(src), str(out)], capture_output=True, text=True, timeout=600)
    return proc, out, warn.read_text(encoding="utf-8") if warn.exists() else ""


def test_the_reference_builds_without_real_errors(build):
    proc, out, warnings = build
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    real = [line for line in warnings.splitlines()
            if REAL.search(line) and not line.rstrip().endswith("[docutils]")]
    assert not real, "\n".join(real[:40])
    tolerated = [line for line in warnings.splitlines() if "WARNING" in line or "ERROR" in line]
    print(f"{len(tolerated)} tolerated warnings")
    print("\n".join(tolerated[:40]))


def test_the_reference_has_its_main_pages(build):
    _, out, _ = build
    assert (out / "index.html").is_file()
    index = (out / "index.html").read_text(encoding="utf-8")
    for mod in MODULES:
        page = out / "generated" / f"{mod}.html"
        assert page.is_file(), f"no page for {mod}"
        assert f"generated/{mod}.html" in index, f"{mod} is not linked from the index"
    joint = (out / "generated" / ("qfg.joint" + ".html")).read_text(encoding="utf-8")
    for name in ("RobotRun", "JointMeasurements", "solve", "triplet_marginals",
                 "camera_marginals"):
        assert name in joint
    # a class page carries its docstring's fields (napoleon read the Attributes section)
    run = (out / "generated" / ("qfg.joint.RobotRun" + ".html")).read_text(encoding="utf-8")
    assert "bearing_landmark" in run and "odometry_sigma" in run
