"""Every ```python block of README.md and docs/**/*.md runs, so that the examples a user copies
cannot drift from the code. Shell blocks stay documentation (they run studies for minutes).

- A reference page (README.md, docs/*.md, ...): one case per block, each in a fresh namespace.
- A guide page (docs/guide/*.md, a tutorial told in steps): one case per page, its blocks run in
  order in one namespace, so a later block uses what an earlier one made; a failure names the
  block's line in the page.

Every case runs in a temporary working directory (blocks may write files) with matplotlib's Agg
backend. A block that reads the MRCLAM data (``mrclam.data_root()``) is skipped when the shared
data directory is not there, as every test using that data is.
"""

import os
import re
from pathlib import Path

import pytest
from conftest import shared_data_dir

REPO = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.S | re.M)


GUIDE = REPO / "docs" / "guide"


def _page_blocks(f):
    """(line of the first code line, code) of every python block of ``f``, in order."""
    text = f.read_text(encoding="utf-8")
    return [(text.count("\n", 0, m.start()) + 2, m.group(1)) for m in FENCE.finditer(text)]


def _blocks():
    files = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
    out = []
    for f in files:
        blocks = _page_blocks(f)
        if f.is_relative_to(GUIDE):
            if blocks:
                out.append(pytest.param(f, blocks, id=f"{f.relative_to(REPO)}"))
            continue
        for line, code in blocks:
            out.append(pytest.param(f, [(line, code)], id=f"{f.relative_to(REPO)}:{line}"))
    return out


BLOCKS = _blocks()


def test_the_docs_have_python_blocks():
    # the extraction itself: a fence pattern that found nothing would make this file pass empty
    names = {p.values[0].name for p in BLOCKS}
    assert {"README.md", "composition.md", "graph.md", "solvers.md", "own_robot.md",
            "paper_pipeline.md"} <= names


@pytest.mark.parametrize("path, blocks", BLOCKS)
def test_python_block_runs(path, blocks, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # blocks may write files (write_uai(g, "map.uai"))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    code = "".join(c for _, c in blocks)
    if "mrclam.data_root()" in code and not os.environ.get("QFG_MRCLAM_DIR"):
        root = shared_data_dir() / "mrclam"
        if not root.is_dir():
            pytest.skip(f"MRCLAM data not found at {root}")
        monkeypatch.setenv("QFG_MRCLAM_DIR", str(root))
    namespace = {"__name__": "__docs__"}
    for line, block in blocks:
        # line numbers of a failure point into the markdown file
        compiled = compile("\n" * (line - 1) + block, str(path), "exec")
        exec(compiled, namespace)
