"""The scripts of experiments/ and benchmarks/ use qfg's public names only, and pytest collects
none of them (they are investigations and benchmarks, not tests or package code).

A private name is a module path component or an imported or attribute name that starts with one
underscore (dunders are public). Checked by reading every script's imports with ``ast``: ``from
<qfg module> import b``, ``import <qfg module> as m``, and ``m._x`` on a name bound to a qfg
module.
"""

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPTS = sorted(p for d in ("experiments", "benchmarks") for p in (REPO / d).rglob("*.py"))


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _offences(path: Path):
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    bound = set()  # local names bound to qfg modules or objects
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 \
                and node.module.split(".")[0] == "qfg":
            parts = node.module.split(".")
            if any(_private(x) for x in parts):
                yield f"{node.lineno}: from {node.module} import ..."
            for a in node.names:
                if _private(a.name):
                    yield f"{node.lineno}: from {node.module} import {a.name}"
                bound.add(a.asname or a.name)
        elif isinstance(node, ast.Import):
            for a in node.names:
                parts = a.name.split(".")
                if parts[0] == "qfg":
                    if any(_private(x) for x in parts):
                        yield f"{node.lineno}: import {a.name}"
                    bound.add(a.asname or parts[0])
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr) \
                and isinstance(node.value, ast.Name) and node.value.id in bound:
            yield f"{node.lineno}: {node.value.id}.{node.attr}"


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: str(p.relative_to(REPO)))
def test_script_uses_public_names_only(path):
    bad = list(_offences(path))
    assert not bad, f"{path.relative_to(REPO)} reaches private names of qfg:\n" + "\n".join(bad)


def test_the_checker_sees_private_names(tmp_path):
    f = tmp_path / "s.py"
    f.write_text("from qfg.solvers." + "_options import x\n"
                 "from qfg import joint\njoint._hidden\n"
                 "import qfg.inference.exact as ex\nex._clique_sizes\nfrom qfg.joint import _y\n")
    assert len(list(_offences(f))) == 4


def test_pytest_collects_nothing_from_experiments_or_benchmarks():
    out = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q",
                          "-p", "no:cacheprovider"], cwd=REPO, capture_output=True, text=True,
                         timeout=600).stdout
    # "path::test" or, at -qq (the project's addopts has -q), "path: count"
    paths = [x.split("::")[0].split(": ")[0] for x in out.splitlines() if ".py" in x]
    assert "tests/test_scripts.py" in paths, "the collection was not read: the check would pass empty"
    assert not [x for x in paths if x.startswith(("experiments/", "benchmarks/", "qfg/_presets"))]


SCRIPT_PATH = re.compile(r"(?<![\w/.])((?:experiments|benchmarks)/[\w/]+\.(?:py|toml))")


def test_every_script_path_the_repository_names_exists():
    out = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True)
    if out.returncode:
        pytest.skip("not a git checkout")
    bad = []
    for name in out.stdout.split():
        if not name.endswith((".py", ".md", ".toml", ".cff")) and name != "Makefile":
            continue
        path = REPO / name
        if not path.is_file():
            continue
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            bad += [f"{name}:{i}: {m}" for m in SCRIPT_PATH.findall(line) if not (REPO / m).exists()]
    assert not bad, "paths of scripts that do not exist:\n" + "\n".join(bad)
