"""Recorded ``qfg mrclam`` runs, read again: merged as one run, or tabled per dataset.

Two jobs on finished run folders (``run.json``, ``records.jsonl``, ``triplets.csv``,
``summary.json``), nothing solved again; the command is ``qfg mrclam-runs``
(:mod:`qfg.harness.commands.mrclam_runs`):

* :func:`merged_estimates` and :func:`merge_lines` combine runs of different robots of one
  dataset (e.g. robots solved one at a time, on different machines) as one run of all their
  robots. The runs must share every option but ``robots`` (:data:`SHARED_OPTIONS`). The
  histories of the merged robots are prepared as ``qfg mrclam --robots R1,R2,...`` would prepare
  them (checked one by one against the records), then the study's own
  :func:`qfg.harness.studies.mrclam.finish` tempers (the check over histories now compares the
  robots' passes of a triplet too), combines and scores them. Only the seeds differ from solving
  the robots together (the pieces of a run are seeded by their position in it).
* :func:`dataset_row` and :func:`whole_datasets_table`: per dataset, the solvers' own seen
  triplets (a ``--map seen`` run) and a configuration map's seen and unseen ones (a run of the
  same solving with ``--map config-state``, say), each beside the prior alone, as a markdown
  table (:data:`TABLE_HEADER`). No ground truth enters the maps; it enters here only to score,
  as in ``qfg mrclam``.

Bad input (a folder that is not a finished run, runs that do not go together) raises
ValueError naming the folder or file.

Example (two runs of robots 1 and 2 of one dataset, then the table of a seen run and a map run)::

    from qfg.harness import mrclam_runs
    prep, ests = mrclam_runs.merged_estimates(["out/d5-r1", "out/d5-r2"])
    print("\\n".join(mrclam_runs.merge_lines(prep, ests, ["auto-1se", 1.0])))
    print(mrclam_runs.whole_datasets_table([("out/d1-seen", "out/d1")]))
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from qfg.harness.studies import mrclam as study
from qfg.metrics import clustered_se

__all__ = ["SHARED_OPTIONS", "TABLE_HEADER", "dataset_row", "merge_lines", "merged_estimates",
           "merged_rows", "whole_datasets_table"]

#: Options the merged runs must share: the study's solve options but the robots and the work's
#: split (``piece`` only sets how the histories are split into recorded pieces).
SHARED_OPTIONS = tuple(k for k in study.SOLVE_KEYS if k not in ("robots", "piece"))


# ------------------------------------------------------------------------------ merge
def _options(params: dict) -> dict:
    return {k: params.get(k, study.DEFAULTS.get(k)) for k in SHARED_OPTIONS}


def _run_params(run: Path) -> dict:
    """The recorded params of a run folder; ValueError naming what is missing."""
    if not run.is_dir():
        raise ValueError(f"{run}: not a folder (give a run folder of qfg mrclam)")
    f = run / "run.json"
    try:
        meta = json.loads(f.read_text())
        params = meta["params"]
    except FileNotFoundError:
        raise ValueError(f"{f}: missing (not a qfg mrclam run folder)") from None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{f}: not a run record ({exc})") from None
    if meta.get("study") not in (None, "mrclam") or not isinstance(params, dict):
        raise ValueError(f"{f}: not a qfg mrclam run (study {meta.get('study')!r})")
    return params


def _recorded_rows(run: Path) -> list[dict]:
    f = run / "records.jsonl"
    try:
        with open(f) as fh:
            return [row for line in fh for row in json.loads(line)["rows"]]
    except FileNotFoundError:
        raise ValueError(f"{f}: missing (nothing solved in this run folder)") from None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{f}: not a run's records ({exc})") from None


def merged_estimates(runs) -> tuple:
    """``(prep, estimates)`` of recorded runs (folders) merged as one run of all their robots:
    the histories prepared as ``qfg mrclam --robots R1,R2,...`` prepares them
    (:class:`qfg.harness.studies.mrclam.Prepared`), each with its recorded estimate (a list of
    :class:`~qfg.harness.studies.mrclam.LightEstimate`, one per history, in ``prep``'s order).
    ValueError when the runs' options differ (but for ``robots``), a robot is in two runs, or the
    records do not match the histories."""
    runs = [Path(r) for r in runs]
    params = [_run_params(r) for r in runs]
    for r, p in zip(runs[1:], params[1:], strict=True):
        bad = [k for k in SHARED_OPTIONS if _options(p)[k] != _options(params[0])[k]]
        if bad:
            raise ValueError(f"{r}: its options {bad} differ from {runs[0]}'s")
    robots = [int(x) for p in params for x in p["robots"]]
    if len(set(robots)) != len(robots):
        raise ValueError(f"runs: a robot is in more than one run ({robots})")
    ests, hist = [], []
    for r, p in zip(runs, params, strict=True):
        prep = study.prepared(p)
        rows = _recorded_rows(r)
        try:
            ests += study.estimates_from_rows(prep, rows)
        except ValueError as exc:
            raise ValueError(f"{r}: {exc}") from None
        hist += prep.histories
    merged = study.prepared({**params[0], "robots": robots})

    def key(rb, h):
        return int(rb), tuple(int(x) for x in h.landmarks), tuple(np.round(h.views, 6))

    mine = {key(rb, h): k for k, (rb, h) in enumerate(hist)}
    order = [mine.get(key(rb, h)) for rb, h in merged.histories]
    if None in order or len(order) != len(hist):
        raise ValueError("runs: their histories are not those of the merged robots "
                         "(recorded with other data or options)")
    return merged, [ests[k] for k in order]


def merged_rows(prep, ests, rule, map_method: str = "seen") -> tuple[list[dict], dict]:
    """``(rows, details)`` of merged estimates under one temper rule (``"auto"``,
    ``"auto-1se"`` or a power in [0, 1]) and map method: :func:`qfg.harness.studies.mrclam.finish`
    on them (rows as in a run's ``triplets.csv``; ``details["temper"]`` the power used)."""
    rule = rule if str(rule).startswith("auto") else float(rule)
    return study.finish(prep, ests, temper=rule, map_method=map_method)


def merge_lines(prep, ests, rules=("auto-1se",), map_method: str = "seen", *,
                rows_by_rule: dict | None = None) -> list[str]:
    """The merged run's scores, per temper rule: the seen triplets' mean log p(truth) (clip
    1e-4), the prior alone's, the share of truths under 1 %, overall and by which robots saw the
    triplet; with a map that propagates (not ``seen``), its unseen triplets too. Each rule's rows
    (:func:`merged_rows`) are put in ``rows_by_rule`` when given."""
    out = []
    for rule in rules:
        rows, det = merged_rows(prep, ests, rule, map_method)
        if rows_by_rule is not None:
            rows_by_rule[str(rule)] = rows
        seen = [r for r in rows if r["kind"] == "seen"]
        ls = np.array([r["log_score"] for r in seen])
        pr = np.array([r["prior_log_score"] for r in seen])
        u = np.array([r["truth_under_1pct"] for r in seen], float)
        by = np.array([str(r["robots"]) for r in seen])
        out.append(f"temper {rule} (power {det['temper']:g}): {len(seen)} seen triplets, mean log "
                   f"p(truth) {ls.mean():.2f} (the prior alone {pr.mean():.2f}), truth under 1% "
                   f"{100 * u.mean():.1f}%")
        for key in sorted(set(by)):
            s = by == key
            out.append(f"    seen by robots {key.replace(';', ',')}: {s.sum()}, "
                       f"{ls[s].mean():.2f}, truth under 1% {100 * u[s].mean():.1f}%")
        prop = [r for r in rows if r["kind"] == "propagated"]
        if prop:
            lp = np.array([r["log_score"] for r in prop])
            pp = np.array([r["prior_log_score"] for r in prop])
            up = np.array([r["truth_under_1pct"] for r in prop], float)
            out.append(f"    unseen ({map_method}): {len(prop)}, {lp.mean():.2f} (the prior "
                       f"alone {pp.mean():.2f}), truth under 1% {100 * up.mean():.1f}%")
    return out


# ------------------------------------------------------------------------------ table
def _rows(run: Path) -> tuple[dict, list[dict]]:
    """``(summary.json, triplets.csv rows)`` of a finished run folder; ValueError naming what
    is missing."""
    run = Path(run)
    summ, trip = run / "summary.json", run / "triplets.csv"
    for p in (summ, trip):
        if not p.is_file():
            raise ValueError(f"{run}: no {p.name} (not a finished qfg mrclam run)")
    try:
        with open(trip, newline="") as fh:
            return json.loads(summ.read_text()), list(csv.DictReader(fh))
    except (OSError, ValueError) as exc:
        raise ValueError(f"{run}: cannot read summary.json or triplets.csv ({exc})") from None


def _scores(rows: list[dict], key: str, where: Path) -> np.ndarray:
    try:
        return np.array([float(r[key]) for r in rows])
    except (KeyError, ValueError) as e:
        raise ValueError(f"{where}/triplets.csv: column {key!r}: {e!r}") from None


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
    return len(_recorded_rows(Path(run)))


def dataset_row(seen_run, map_run) -> str:
    """One markdown row (see :data:`TABLE_HEADER`) for a dataset's pair of finished runs of the
    same solving: ``seen_run`` made with ``--map seen`` (the solvers' combined estimates),
    ``map_run`` with a configuration map (``--resume`` on a copy of the first folder reuses its
    solving). Scores: mean log p(truth) (clip 1e-4) and share of truths under 1 %; the unseen
    gain over the prior alone with its standard error clustered by landmark set (the orderings
    of one set share their evidence). ValueError when a folder is not a finished run or the
    pair is not one run's solving of one dataset."""
    seen_run, map_run = Path(seen_run), Path(map_run)
    s_summ, s_rows = _rows(seen_run)
    m_summ, m_rows = _rows(map_run)
    solved = [r for r in s_rows if r["kind"] == "seen"]
    m_seen = [r for r in m_rows if r["kind"] == "seen"]
    unseen = [r for r in m_rows if r["kind"] == "propagated"]
    key = lambda r: (r["A"], r["B"], r["C"])                                   # noqa: E731
    if {key(r) for r in solved} != {key(r) for r in m_seen}:
        raise ValueError(f"{seen_run} and {map_run}: not the same seen triplets "
                         f"({len(solved)} and {len(m_seen)}): not one run's solving")
    names = {r["dataset"] for r in s_rows + m_rows}
    if len(names) != 1:
        raise ValueError(f"{seen_run} and {map_run}: more than one dataset ({sorted(names)})")
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
            f"{len(solved)} | {_mean(solved, seen_run, 'prior_log_score')} | "
            f"{_cell(solved, seen_run)} | "
            f"{_cell(m_seen, map_run)} | {len(unseen)} | {u} |")


#: The header of :func:`whole_datasets_table` (two markdown lines).
TABLE_HEADER = ("| dataset | histories | temper chosen | seen n | seen: prior alone | seen: "
                "solvers (under 1 %) | seen: map | unseen n | unseen: prior alone | unseen: map "
                "| unseen gain over the prior (SE) |\n|---|---|---|---|---|---|---|---|---|---|---|")


def whole_datasets_table(pairs) -> str:
    """The markdown table (:data:`TABLE_HEADER`, then one :func:`dataset_row` per
    ``(seen_run, map_run)`` pair), without a final newline."""
    return "\n".join([TABLE_HEADER, *(dataset_row(s, m) for s, m in pairs)])
