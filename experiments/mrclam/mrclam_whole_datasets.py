"""The whole-dataset MRCLAM rows from recorded ``qfg mrclam`` runs: per dataset, the solvers'
own seen triplets and a configuration map's seen and unseen ones, each beside the prior alone.

Each dataset is given as two finished run folders of the same solved histories: the first made
with ``--map seen`` (the solvers' combined estimates), the second with a configuration map
(``--map config-state`` or ``config-metric``; ``--resume`` on a copy of the first folder reuses
its solving). For each it prints, from the folders' ``triplets.csv`` and ``summary.json``: the
power the check over histories chose, the seen triplets' mean log p(truth) (clip 1e-4) and share
of truths under 1 % as the solvers combined them and as the map gives them, the prior alone's
score on the same rows, the map's unseen triplets against the prior alone, and the unseen gain
over the prior alone with its standard error clustered by landmark set (the orderings of one set
share their evidence)::

    python experiments/mrclam/mrclam_whole_datasets.py out/d1-seen out/d1-config \\
        [out/d2-seen out/d2-config ...]

No ground truth enters the maps; it enters here only to score, as in ``qfg mrclam``.

Backs docs/results/mrclam.md, "The tail model and the model checks", and docs/configurations.md,
"On MRCLAM". Run from the repository root as above.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

from qfg.metrics import clustered_se


def _rows(run: Path) -> tuple[dict, list[dict]]:
    """``(summary.json, triplets.csv rows)`` of a finished run folder; exits naming what is
    missing."""
    summ, trip = run / "summary.json", run / "triplets.csv"
    for p in (summ, trip):
        if not p.is_file():
            raise SystemExit(f"{run}: no {p.name} (not a finished qfg mrclam run)")
    with open(trip, newline="") as fh:
        return json.loads(summ.read_text()), list(csv.DictReader(fh))


def _scores(rows: list[dict], key: str, where: Path) -> np.ndarray:
    try:
        return np.array([float(r[key]) for r in rows])
    except (KeyError, ValueError) as e:
        raise SystemExit(f"{where}/triplets.csv: column {key!r}: {e!r}") from None


def _mean(rows: list[dict], where: Path, key: str) -> str:
    return f"{_scores(rows, key, where).mean():.2f}"


def _cell(rows: list[dict], where: Path) -> str:
    """Mean log p(truth) (share of truths under 1 %)."""
    return (f"{_mean(rows, where, 'log_score')} "
            f"({100 * _scores(rows, 'truth_under_1pct', where).mean():.1f} %)")


def _sets(rows: list[dict]) -> np.ndarray:
    """Cluster index of each row: its unordered landmark set."""
    names = ["-".join(sorted((r["A"], r["B"], r["C"]))) for r in rows]
    return np.unique(names, return_inverse=True)[1]


def _n_histories(run: Path) -> int:
    """How many histories the run solved (one row of ``records.jsonl`` each)."""
    with open(run / "records.jsonl") as fh:
        return sum(len(json.loads(line)["rows"]) for line in fh)


def dataset_row(seen_run: Path, map_run: Path) -> str:
    """One markdown row (see :data:`HEADER`) for a dataset's pair of runs."""
    s_summ, s_rows = _rows(seen_run)
    m_summ, m_rows = _rows(map_run)
    solved = [r for r in s_rows if r["kind"] == "seen"]
    m_seen = [r for r in m_rows if r["kind"] == "seen"]
    unseen = [r for r in m_rows if r["kind"] == "propagated"]
    key = lambda r: (r["A"], r["B"], r["C"])                                   # noqa: E731
    if {key(r) for r in solved} != {key(r) for r in m_seen}:
        raise SystemExit(f"{seen_run} and {map_run}: not the same seen triplets "
                         f"({len(solved)} and {len(m_seen)}): not one run's solving")
    names = {r["dataset"] for r in s_rows + m_rows}
    if len(names) != 1:
        raise SystemExit(f"{seen_run} and {map_run}: more than one dataset ({sorted(names)})")
    taus = {s_summ.get("options", {}).get("temper_chosen"),
            m_summ.get("options", {}).get("temper_chosen")}
    if unseen:
        gain = (_scores(unseen, "log_score", map_run)
                - _scores(unseen, "prior_log_score", map_run))
        u = (f"{_mean(unseen, map_run, 'prior_log_score')} | {_cell(unseen, map_run)} | "
             f"{round(gain.mean(), 2) + 0.0:+.2f} ± {clustered_se(gain, _sets(unseen)):.2f}")
    else:
        u = "- | - | -"
    tau = "/".join(str(t) for t in sorted(taus, key=str))
    return (f"| {names.pop()} | {_n_histories(seen_run)} | {tau} | "
            f"{len(solved)} | {_mean(solved, seen_run, 'prior_log_score')} | {_cell(solved, seen_run)} | "
            f"{_cell(m_seen, map_run)} | {len(unseen)} | {u} |")


HEADER = ("| dataset | histories | temper chosen | seen n | seen: prior alone | seen: solvers "
          "(under 1 %) | seen: map | unseen n | unseen: prior alone | unseen: map | unseen gain "
          "over the prior (SE) |\n|---|---|---|---|---|---|---|---|---|---|---|")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", type=Path, nargs="+",
                    help="run folders in pairs: --map seen, then the configuration map")
    a = ap.parse_args(argv)
    if len(a.runs) % 2:
        ap.error(f"runs come in pairs (seen, map); got {len(a.runs)} folders")
    print(HEADER)
    for i in range(0, len(a.runs), 2):
        print(dataset_row(a.runs[i], a.runs[i + 1]))


if __name__ == "__main__":
    main()
