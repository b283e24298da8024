"""qfg.harness.mrclam_runs.dataset_row and ``qfg mrclam-runs table``: the row
it makes for a dataset agrees with what
``qfg mrclam`` itself summarised (``summary.json``, computed by the study from the same rows), and
pairs of runs that are not one run's solving are refused by name."""

from __future__ import annotations

import json
import shutil

import pytest
from test_mrclam import write_dataset

from qfg.harness.cli import main

FAST = ["--method", "fast", "--no-figures", "--no-progress", "--max-gap", "10", "--spread-views",
        "0", "--piece-size", "8", "--seed", "4"]


def _module():
    from qfg.harness import mrclam_runs

    return mrclam_runs


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    r = tmp_path_factory.mktemp("whole")
    d = r / "MRCLAM_Dataset1"
    write_dataset(d)
    seen, mapped = r / "seen", r / "mapped"
    # robot 1 alone leaves some triplets unseen
    one = ["--robots", "1", *FAST]
    assert main(["mrclam", str(d), "--output", str(seen), "--map", "seen", *one]) == 0
    shutil.copytree(seen, mapped)
    assert main(["mrclam", str(d), "--output", str(mapped), "--map", "seen-prior", "--resume",
                 *one]) == 0
    other = r / "other"
    assert main(["mrclam", str(d), "--output", str(other), "--map", "seen", *FAST]) == 0
    return seen, mapped, other


def _cells(row: str) -> list[str]:
    return [c.strip() for c in row.strip().strip("|").split("|")]


def test_row_agrees_with_the_runs_own_summaries(runs):
    seen, mapped, _ = runs
    cells = _cells(_module().dataset_row(seen, mapped))
    header = _cells(_module().TABLE_HEADER.splitlines()[0])
    got = dict(zip(header, cells, strict=True))
    s = json.loads((seen / "summary.json").read_text())["honest"]
    m = json.loads((mapped / "summary.json").read_text())["honest"]
    assert got["dataset"] == "MRCLAM_Dataset1"
    assert int(got["seen n"]) == s["seen"]["n"] == m["seen"]["n"]
    assert int(got["unseen n"]) == m["propagated"]["n"] > 0
    solvers, under = got["seen: solvers (under 1 %)"].split(" (")
    assert float(solvers) == pytest.approx(s["seen"]["log_score"], abs=0.005)
    assert float(under.rstrip(" %)")) == pytest.approx(100 * s["seen"]["truth_under_1pct"],
                                                         abs=0.05)
    assert float(got["seen: prior alone"]) == pytest.approx(s["seen"]["prior_log_score"],
                                                            abs=0.005)
    assert float(got["unseen: prior alone"]) == pytest.approx(
        m["propagated"]["prior_log_score"], abs=0.005)
    # seen-prior answers the unseen triplets by the prior's state distribution: no gain
    unseen_map = float(got["unseen: map"].split(" (")[0])
    assert unseen_map == pytest.approx(m["propagated"]["prior_log_score"], abs=0.005)
    assert got["unseen gain over the prior (SE)"].startswith(("+0.00", "-0.00"))
    # seen-prior keeps the solvers' seen rows
    assert got["seen: map"] == got["seen: solvers (under 1 %)"]


def test_runs_of_other_solving_are_refused(runs, tmp_path):
    seen, mapped, other = runs
    mod = _module()
    with pytest.raises(ValueError, match="not the same seen triplets"):
        mod.dataset_row(other, mapped)
    with pytest.raises(ValueError, match="no summary.json"):
        mod.dataset_row(seen, tmp_path)


def test_table_command_prints_writes_and_refuses_bad_input(runs, tmp_path, capsys):
    seen, mapped, _ = runs
    out = tmp_path / "t"
    assert main(["mrclam-runs", "table", str(seen), str(mapped), "--output", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith(_module().TABLE_HEADER)
    assert (out / "whole_datasets.md").read_text().startswith(_module().TABLE_HEADER)
    assert main(["mrclam-runs", "table", str(seen)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pairs" in err[0], err
    assert main(["mrclam-runs", "table", str(seen), str(tmp_path)]) == 2
    assert "no summary.json" in capsys.readouterr().err
