"""Combine recorded ``qfg mrclam`` runs of different robots of one dataset as one run of all
their robots (e.g. robots solved one at a time, on different machines).

Each run's folder holds its solved estimates (``records.jsonl``); the runs must share every
option but ``robots``. The histories of the merged robots are prepared as ``qfg mrclam --robots
R1,R2,...`` would prepare them (checked one by one against the records), then the study's own
:func:`qfg.harness.studies.mrclam.finish` tempers (the check over histories now compares the
robots' passes of a triplet too), combines and scores them with the seen-triplet map. Printed
per temper rule: the seen triplets' mean log p(truth) (clip 1e-4), the prior alone's, the share
of truths under 1 %, overall and by which robots saw the triplet. Only the seeds differ from
solving the robots together (the pieces of a run are seeded by their position in it).

    python experiments/mrclam/mrclam_merge_runs.py out/d5-r1 out/d5-r2 [auto-1se,auto,1] [--map NAME]

``--map`` (default ``seen``): another map method of ``qfg mrclam`` (e.g. ``config-state``); its
unseen triplets are then scored too.

Backs docs/configurations.md, "On MRCLAM", and docs/results/mrclam.md, "The tail model and the
model checks". Run from the repository root as above, on run folders made by ``qfg mrclam``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from qfg.harness.studies import mrclam as study

#: Options the runs must share: the study's solve options but the robots and the work's split
#: (``piece`` only sets how the histories are split into recorded pieces).
SHARED = tuple(k for k in study.SOLVE_KEYS if k not in ("robots", "piece"))


def _options(params: dict) -> dict:
    return {k: params.get(k, study.DEFAULTS.get(k)) for k in SHARED}


def merged_estimates(runs):
    """``(prep, estimates)`` of recorded runs (folders) merged as one run of all their robots:
    the histories prepared as ``qfg mrclam --robots R1,R2,...`` prepares them, each with its
    recorded estimate. ValueError when the runs' options differ (but for ``robots``), a robot
    is in two runs, or the records do not match the histories."""
    runs = [Path(r) for r in runs]
    params = [json.loads((r / "run.json").read_text())["params"] for r in runs]
    for r, p in zip(runs[1:], params[1:], strict=True):
        bad = [k for k in SHARED if _options(p)[k] != _options(params[0])[k]]
        if bad:
            raise ValueError(f"{r}: its options {bad} differ from {runs[0]}'s")
    robots = [int(x) for p in params for x in p["robots"]]
    if len(set(robots)) != len(robots):
        raise ValueError(f"runs: a robot is in more than one run ({robots})")
    ests, hist = [], []
    for r, p in zip(runs, params, strict=True):
        prep = study.prepared(p)
        rows = [row for line in open(r / "records.jsonl") for row in json.loads(line)["rows"]]
        ests += study.estimates_from_rows(prep, rows)
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


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    map_method = "seen"
    if "--map" in argv:
        i = argv.index("--map")
        map_method = argv[i + 1]
        del argv[i:i + 2]
    runs = [Path(a) for a in argv if Path(a).is_dir()]
    rules = [a for a in argv if not Path(a).is_dir()]
    rules = rules[0].split(",") if rules else ["auto-1se"]
    if len(runs) < 2:
        print(__doc__)
        return 2
    merged, ests = merged_estimates(runs)
    for rule in rules:
        rows, det = study.finish(merged, ests, temper=rule if rule.startswith("auto")
                                 else float(rule), map_method=map_method)
        seen = [r for r in rows if r["kind"] == "seen"]
        ls = np.array([r["log_score"] for r in seen])
        pr = np.array([r["prior_log_score"] for r in seen])
        u = np.array([r["truth_under_1pct"] for r in seen], float)
        by = np.array([str(r["robots"]) for r in seen])
        print(f"temper {rule} (power {det['temper']:g}): {len(seen)} seen triplets, mean log "
              f"p(truth) {ls.mean():.2f} (the prior alone {pr.mean():.2f}), truth under 1% "
              f"{100 * u.mean():.1f}%")
        for key in sorted(set(by)):
            s = by == key
            print(f"    seen by robots {key.replace(';', ',')}: {s.sum()}, {ls[s].mean():.2f}, "
                  f"truth under 1% {100 * u[s].mean():.1f}%")
        prop = [r for r in rows if r["kind"] == "propagated"]
        if prop:
            lp = np.array([r["log_score"] for r in prop])
            pp = np.array([r["prior_log_score"] for r in prop])
            up = np.array([r["truth_under_1pct"] for r in prop], float)
            print(f"    unseen ({map_method}): {len(prop)}, {lp.mean():.2f} (the prior alone "
                  f"{pp.mean():.2f}), truth under 1% {100 * up.mean():.1f}%")
    return 0


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    sys.exit(main())
