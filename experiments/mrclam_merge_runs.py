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

    python experiments/mrclam_merge_runs.py out/d5-r1 out/d5-r2 [auto-1se,auto,1] [--map NAME]

``--map`` (default ``seen``): another map method of ``qfg mrclam`` (e.g. ``config-state``); its
unseen triplets are then scored too.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from qfg.harness.studies import mrclam as study

#: Options the runs must share (``robots`` differs; ``piece`` and ``seed`` only set the work's
#: split and seeds).
SHARED = ("path", "mode", "prior", "partition", "fix_landmarks", "min_travel", "max_gap",
          "max_views", "spread_views", "sigma_bearing_deg", "sigma_heading_deg", "distances",
          "sigma_distance_ratio", "bearing_tail", "model_check", "heading_drift")


def merged_estimates(runs):
    """``(prep, estimates)`` of recorded runs (folders) merged as one run of all their robots:
    the histories prepared as ``qfg mrclam --robots R1,R2,...`` prepares them, each with its
    recorded estimate. ValueError when the runs' options differ (but for ``robots``), a robot
    is in two runs, or the records do not match the histories."""
    runs = [Path(r) for r in runs]
    params = [json.loads((r / "run.json").read_text())["params"] for r in runs]
    for r, p in zip(runs[1:], params[1:], strict=True):
        bad = [k for k in SHARED if p.get(k) != params[0].get(k)]
        if bad:
            raise ValueError(f"{r}: its options {bad} differ from {runs[0]}'s")
    robots = [int(x) for p in params for x in p["robots"]]
    if len(set(robots)) != len(robots):
        raise ValueError(f"runs: a robot is in more than one run ({robots})")
    kw = {k: params[0][k] for k in SHARED if k in params[0] and k != "path"}
    ests, hist = [], []
    for r, p in zip(runs, params, strict=True):
        prep = study.prepare_run(p["path"], robots=p["robots"], **kw)
        rows = [row for line in open(r / "records.jsonl") for row in json.loads(line)["rows"]]
        ests += study.estimates_from_rows(prep, rows)
        hist += prep.histories
    merged = study.prepare_run(params[0]["path"], robots=robots, **kw)

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
    sys.exit(main())
