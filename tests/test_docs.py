"""Every ```python block of README.md and docs/**/*.md runs (issue 18 item 12): one case per
block, in a fresh namespace and a temporary working directory, so that the examples a user copies
cannot drift from the code. Shell blocks stay documentation (they run studies for minutes).

A block that reads the MRCLAM data (``mrclam.data_root()``) is skipped when ../shared/data is not
there, as every test using that data is.
"""

import os
import re
from pathlib import Path

import pytest
from conftest import shared_data_dir

REPO = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.S | re.M)


def _blocks():
    files = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
    out = []
    for f in files:
        text = f.read_text(encoding="utf-8")
        for m in FENCE.finditer(text):
            line = text.count("\n", 0, m.start()) + 2  # the first line of code
            out.append(pytest.param(f, line, m.group(1), id=f"{f.relative_to(REPO)}:{line}"))
    return out


BLOCKS = _blocks()


def test_the_docs_have_python_blocks():
    # the extraction itself: a fence pattern that found nothing would make this file pass empty
    names = {p.values[0].name for p in BLOCKS}
    assert {"README.md", "composition.md", "graph.md", "solvers.md"} <= names


@pytest.mark.parametrize("path, line, code", BLOCKS)
def test_python_block_runs(path, line, code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # blocks may write files (write_uai(g, "map.uai"))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    if "mrclam.data_root()" in code and not os.environ.get("QFG_MRCLAM_DIR"):
        root = shared_data_dir() / "mrclam"
        if not root.is_dir():
            pytest.skip(f"MRCLAM data not found at {root}")
        monkeypatch.setenv("QFG_MRCLAM_DIR", str(root))
    # line numbers of a failure point into the markdown file
    compiled = compile("\n" * (line - 1) + code, str(path), "exec")
    exec(compiled, {"__name__": "__docs__"})
