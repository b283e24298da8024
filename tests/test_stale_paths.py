"""Every module path the repository mentions exists: ``qfg/...py`` file paths and dotted
``qfg.x.y`` names in code, docs, presets and tests resolve (a module, or an attribute of one), so
that a moved module leaves no stale pointer behind.

The places allowed to name former locations are CHANGELOG.md, which records the moves, and the
code that turns them into a pointer (its names are built at run time).
"""

import importlib
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

import qfg

REPO = Path(qfg.__file__).resolve().parent.parent
PATH = re.compile(r"(?<![\w/.-])qfg/[\w/]*\w\.py\b")
DOTTED = re.compile(r"(?<![\w/.-])qfg(?:\.[A-Za-z_]\w*)+")
SUFFIXES = (".py", ".md", ".toml", ".cfg", ".txt", ".rst")
#: the former top-level names, documented as moved (and refused with a pointer by qfg.__getattr__)
MOVED_NOTE = ("docs/modules.md", {f"qfg.{name}" for name in qfg._MOVED})


def _tracked_files():
    if shutil.which("git") is None or not (REPO / ".git").exists():
        pytest.skip("not a git checkout")
    out = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True)
    names = [n for n in out.stdout.decode().split("\0") if n]
    return [n for n in names if n.endswith(SUFFIXES) or n == "Makefile"]


def _resolves(name: str) -> bool:
    parts = name.split(".")
    if "__main__" in parts:  # importing it would run the command
        return (REPO / "qfg" / "__main__.py").exists()
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        for attr in parts[k:]:
            try:
                obj = getattr(obj, attr)
            except AttributeError:
                return False
        return True
    return False


def test_every_mentioned_module_path_exists(monkeypatch):
    monkeypatch.setenv("MPLBACKEND", os.environ.get("MPLBACKEND", "Agg"))
    stale, cache = [], {}
    for name in _tracked_files():
        path = REPO / name
        if not path.is_file() or path == Path(__file__).resolve():  # deleted; this file's examples
            continue
        if name == "CHANGELOG.md":  # the record of what moved and what was removed
            continue
        for n, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            for m in PATH.finditer(line):
                if not (REPO / m.group()).exists():
                    stale.append(f"{name}:{n}: {m.group()}")
            for m in DOTTED.finditer(line):
                dotted = m.group()
                if name == MOVED_NOTE[0] and dotted in MOVED_NOTE[1]:
                    continue
                if dotted not in cache:
                    cache[dotted] = _resolves(dotted)
                if not cache[dotted]:
                    stale.append(f"{name}:{n}: {dotted}")
    assert not stale, "stale module paths:\n" + "\n".join(stale)


def test_the_scan_sees_a_stale_path(tmp_path):
    # the patterns catch both forms the issue found
    line = "see qfg/studies/propagation.py and qfg.runner.run_study"
    assert [m.group() for m in PATH.finditer(line)] == ["qfg/studies/propagation.py"]
    assert [m.group() for m in DOTTED.finditer(line)] == ["qfg.runner.run_study"]
    assert not (REPO / "qfg/studies/propagation.py").exists()
    assert not _resolves("qfg.runner.run_study") and _resolves("qfg.harness.runner.run_study")
