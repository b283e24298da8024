"""qfg.harness.mrclam_runs.merged_estimates and ``qfg mrclam-runs merge``: runs of
different robots merged as one run of all of them.
Checked against the runs themselves: every history of the merged robots gets its own run's
recorded estimate, and a triplet seen by one robot only is combined exactly as that robot's run
combined it (no temper: the same histories, the same rule)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from test_mrclam import write_dataset

from qfg.harness.cli import main
from qfg.harness.studies import mrclam as study

FAST = ["--method", "fast", "--no-figures", "--no-progress", "--max-gap", "10", "--spread-views",
        "0", "--map", "seen", "--piece-size", "8", "--seed", "4"]


def _merge_module():
    from qfg.harness import mrclam_runs

    return mrclam_runs


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    r = tmp_path_factory.mktemp("merge")
    d = r / "MRCLAM_Dataset1"
    write_dataset(d)
    out = {}
    for robot in (1, 2):
        out[robot] = r / f"r{robot}"
        assert main(["mrclam", str(d), "--output", str(out[robot]), "--robots", str(robot),
                     *FAST]) == 0
    return out


def _triplets(path):
    with open(path / "triplets.csv") as fh:
        return {(int(r["A"]), int(r["B"]), int(r["C"])): r for r in csv.DictReader(fh)
                if r["kind"] == "seen"}


def test_merged_run_keeps_each_runs_estimates_and_combinations(runs):
    mod = _merge_module()
    prep, ests = mod.merged_estimates([runs[1], runs[2]])
    assert sorted({int(r) for r, _ in prep.histories}) == [1, 2]
    assert len(ests) == len(prep.histories)
    rows, _ = study.finish(prep, ests, temper=1.0, map_method="seen")
    merged = {(r["A"], r["B"], r["C"]): r for r in rows if r["kind"] == "seen"}
    own = {1: _triplets(runs[1]), 2: _triplets(runs[2])}
    assert set(merged) == set(own[1]) | set(own[2])
    solo = 0
    for robot in (1, 2):
        for t, r in own[robot].items():
            if t in own[3 - robot]:
                continue
            solo += 1
            got = study.decode(merged[t]["probabilities"])
            assert np.allclose(got, study.decode(r["probabilities"]), atol=2e-6), t
    assert solo > 0


def test_merge_refuses_runs_with_other_options_or_the_same_robot(runs, tmp_path):
    mod = _merge_module()
    with pytest.raises(ValueError, match="more than one run"):
        mod.merged_estimates([runs[1], runs[1]])
    other = tmp_path / "other"
    d = Path(runs[1]).parent / "MRCLAM_Dataset1"
    assert main(["mrclam", str(d), "--output", str(other), "--robots", "2",
                 *FAST, "--max-views", "3"]) == 0
    with pytest.raises(ValueError, match="max_views"):
        mod.merged_estimates([runs[1], other])


def test_merge_command_prints_and_writes_and_refuses_bad_input(runs, tmp_path, capsys):
    out = tmp_path / "merged"
    assert main(["mrclam-runs", "merge", str(runs[1]), str(runs[2]), "--temper", "1",
                 "--output", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("temper 1 (power 1)")
    assert (out / "merge.txt").read_text().splitlines()[0] == printed.splitlines()[0]
    assert (out / "triplets_1.csv").is_file()
    for bad, word in ((["--temper", "2"], "--temper"), (["--map", "nope"], "--map")):
        assert main(["mrclam-runs", "merge", str(runs[1]), str(runs[2]), *bad]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and word in err[0], err
    assert main(["mrclam-runs", "merge", str(runs[1])]) == 2
    assert "two or more" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["mrclam-runs", "merge", str(runs[1]), str(runs[2]), "--bogus"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--bogus" in err[0] and "qfg mrclam-runs merge" in err[0], err
