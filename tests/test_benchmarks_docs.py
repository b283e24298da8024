"""``python -m benchmarks --docs-only``: the recorded results' descriptions follow the benchmarks'
docstrings and docs/benchmarks.md is rebuilt from them, with nothing run and no recorded row,
machine or command changed; a benchmark whose data are absent is skipped and records nothing."""

import json
import shutil
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))   # benchmarks/ is the checkout's, not an installed package

from benchmarks.__main__ import docstring, refresh_docs, render, run_topic  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"


def test_docs_only_rewrites_descriptions_and_keeps_the_measurements(tmp_path):
    res = shutil.copytree(RESULTS, tmp_path / "results")
    stale = res / "partitions.json"
    rec = json.loads(stale.read_text())
    stale.write_text(json.dumps(dict(rec, doc="stale"), indent=2) + "\n")
    page = tmp_path / "benchmarks.md"
    # only the stale record is rewritten: the recorded ones already follow their docstrings
    assert refresh_docs(res, page) == [stale, page]
    for f in sorted(RESULTS.glob("*.json")):
        old = json.loads(f.read_text())
        assert json.loads((res / f.name).read_text()) == dict(old, doc=docstring(old["topic"]))
    assert page.read_text() == render(res)


def test_the_recorded_page_is_the_one_the_recorded_results_give():
    assert (REPO / "docs" / "benchmarks.md").read_text() == render(RESULTS)


def test_a_benchmark_without_its_data_is_skipped_and_records_nothing(tmp_path, monkeypatch):
    monkeypatch.delenv("QFG_UAI_DIR", raising=False)
    assert run_topic("uai", tmp_path) is None
    assert not list(tmp_path.iterdir())
