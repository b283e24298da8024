"""Every map method of ``qfg mrclam`` on MRCLAM datasets 1-6, side by side, and the rule that picks
``qfg mrclam``'s default map (:data:`qfg.harness.studies.mrclam.maps.DEFAULT_MAP`).

Each (dataset, map) is one ``qfg mrclam`` run in ``<output>/<dataset>-<solver>``: the maps made
from the single-triplet solvers' estimates share one solved run per dataset (``--resume`` with
another ``--map`` reuses the solved pieces), the joint map runs without a solver
(``--method none``) and fits every robot of the dataset; when it cannot answer (robots without
odometry that cannot be checked against each other) it runs again beside the first solver's
estimates, to fall back on (its rows say which map answered).
The table has one row per (dataset, map, kind): the mean log p(truth) (clip 1e-4), Brier, truth
under 1%, beside uniform and the prior alone. Each run's wall time is printed as it finishes (a
resumed run reuses the solved pieces and any recorded map, so only a fresh run's time is the
method's).

The rule: the default map is the one with the best mean log score over every seen and unseen
(propagated) ordered triplet of the six datasets (:func:`best_map`).

Run (about 20 minutes on 2 cores; ``--update-docs`` writes docs/results/mrclam_maps.csv and
docs/figures/mrclam/maps.png)::

    python -m qfg.harness.studies.mrclam.compare $QFG_MRCLAM_DIR --output out/mrclam-maps

The table and figure again from a recorded table, without running anything::

    python -m qfg.harness.studies.mrclam.compare --from-csv docs/results/mrclam_maps.csv --output out/maps
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

#: the maps compared, and the solver each is made from (``none``: no single-triplet solver)
MAPS = (("joint", "none"), ("config-state", "fast"), ("config-metric", "fast"),
        ("seen-config", "fast"), ("seen-prior", "fast"), ("pooled", "fast"), ("best", "fast"))

COLUMNS = ("dataset", "robots", "map", "solver", "answered_by", "kind", "n", "log_score",
           "brier", "truth_under_1pct", "uniform_log_score", "prior_log_score")

#: robots per dataset where not all are run: dataset 5 has no odometry, so every map there is
#: made from the baseline model's estimates, whose 8,886 histories take about 75 minutes on this
#: machine; robot 1 (888 histories, the first robot, not chosen by any score) stands for it
ROBOTS = {5: "1"}


def _run(path: Path, out: Path, map_name: str, solver: str, resume: bool, seed: int,
         robots: str = "") -> float:
    cmd = [sys.executable, "-m", "qfg", "mrclam", str(path), "--map", map_name, "--no-figures",
           "--no-progress", "--output", str(out), "--seed", str(seed)]
    if robots:
        cmd += ["--robots", robots]
    cmd += ["--method", solver]      # given, so that none is not replaced by a solver
    cmd += ["--resume"] if resume else ["--overwrite"]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"{' '.join(cmd)} failed ({done.returncode}): "
                           f"{done.stderr.strip().splitlines()[-1:]}")
    return time.perf_counter() - t0


def compare(root, *, output, datasets=(1, 2, 3, 4, 5, 6), maps=MAPS, seed: int = 0,
            robots=None, say=print) -> list[dict]:
    """Run every map of ``maps`` on every dataset under ``root`` (``robots``: {dataset: "1,2"}
    where not every robot's histories are solved, default :data:`ROBOTS`); return the table's
    rows. A map made without a solver on a dataset without odometry may fall back (``qfg
    mrclam`` says which map answered): it then runs beside the first solver's estimates of the
    list."""
    robots = ROBOTS if robots is None else robots
    # the solver a map without one falls back on: the first of the list, or of the table's
    first_solver = next(s for _, s in (*maps, *MAPS) if s != "none")
    rows = []
    for d in datasets:
        path = Path(root) / f"MRCLAM_Dataset{d}"
        rs = robots.get(d, "")
        started = set()
        for name, solver in maps:
            out = Path(output) / f"d{d}-{solver}"
            try:
                wall = _run(path, out, name, solver, resume=out in started or
                            (out / "records.jsonl").exists(), seed=seed, robots=rs)
            except RuntimeError as exc:
                # without odometry the joint map may not answer; then it needs the solvers'
                # estimates to fall back on
                if solver != "none" or "could not answer" not in str(exc):
                    raise
                say(f"dataset {d}, {name}: {exc}; again beside {first_solver}'s estimates")
                solver = first_solver
                out = Path(output) / f"d{d}-{solver}"
                wall = _run(path, out, name, solver, resume=out in started or
                            (out / "records.jsonl").exists(), seed=seed, robots=rs)
            started.add(out)
            summ = json.loads((out / "summary.json").read_text())
            answered = name
            maps_info = out / "maps" / f"{name}.npz"
            if maps_info.is_file():
                with np.load(maps_info, allow_pickle=False) as z:
                    answered = json.loads(str(z["info"])).get("answered_by", name)
            for kind in ("seen", "propagated", "camera"):
                s = summ.get("honest", {}).get(kind)
                if not s or not s.get("n"):
                    continue
                rows.append({"dataset": d, "robots": rs or "all", "map": name, "solver": solver,
                             "answered_by": answered, "kind": kind, "n": int(s["n"]),
                             "log_score": s["log_score"], "brier": s["brier"],
                             "truth_under_1pct": s["truth_under_1pct"],
                             "uniform_log_score": s["uniform_log_score"],
                             "prior_log_score": s["prior_log_score"]})
            say(f"dataset {d}, {name} ({solver}): "
                + ", ".join(f"{r['kind']} {r['log_score']:.2f}" for r in rows
                            if r["dataset"] == d and r["map"] == name) + f" ({wall:.0f} s)")
    return rows


def map_scores(rows) -> dict:
    """Mean log score of each map over every seen and unseen (propagated) triplet of the rows'
    datasets (weighted by the number of triplets), ``{map: (score, n)}``."""
    acc: dict[str, list[float]] = {}
    for r in rows:
        if r["kind"] not in ("seen", "propagated"):
            continue
        a = acc.setdefault(r["map"], [0.0, 0])
        a[0] += float(r["log_score"]) * int(r["n"])
        a[1] += int(r["n"])
    return {m: (s / n, n) for m, (s, n) in acc.items() if n}


def best_map(rows, datasets=(1, 2, 3, 4, 5, 6)) -> str:
    """The rule for ``qfg mrclam``'s default: the map with the best mean log score over the seen
    and unseen triplets of ``datasets``; only maps scored on every one of them compete."""
    want = {int(d) for d in datasets}
    have: dict[str, set] = {}
    for r in rows:
        have.setdefault(r["map"], set()).add(int(r["dataset"]))
    scores = map_scores([r for r in rows if int(r["dataset"]) in want
                         and have[r["map"]] >= want])
    if not scores:
        raise ValueError(f"rows: no map scored on every one of datasets {sorted(want)}")
    return max(scores, key=lambda m: scores[m][0])


def markdown(rows) -> list[str]:
    """The comparison as a markdown table: one line per (dataset, kind), the maps side by side
    (mean log p(truth); truth under 1% in brackets), uniform and the prior alone last."""
    maps = list(dict.fromkeys(r["map"] for r in rows))
    solver = {r["map"]: r["solver"] for r in rows}
    solver = {m: ("none" if any(r["map"] == m and r["solver"] == "none" for r in rows)
                  else s) for m, s in solver.items()}
    head = ["dataset", "kind", "n", *(f"{m} ({solver[m]})" for m in maps), "uniform",
            "prior alone"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    by = {(str(r["dataset"]), r["kind"], r["map"]): r for r in rows}
    keys = list(dict.fromkeys((str(r["dataset"]), r["kind"]) for r in rows))
    for d, kind in keys:
        first = next(by[(d, kind, m)] for m in maps if (d, kind, m) in by)
        cells = []
        for m in maps:
            r = by.get((d, kind, m))
            if r is None:
                cells.append("")
                continue
            note = "" if r.get("answered_by", m) == m else f", by {r['answered_by']}"
            cells.append(f"{float(r['log_score']):.2f} ({100 * float(r['truth_under_1pct']):.1f}%"
                         f"{note})")
        if first.get("robots", "all") != "all":
            d = f"{d} (robot {first['robots']})"
        out.append("| " + " | ".join([d, "unseen" if kind == "propagated" else kind,
                                        str(first["n"]), *cells,
                                        f"{float(first['uniform_log_score']):.2f}",
                                        f"{float(first['prior_log_score']):.2f}"]) + " |")
    return out


def merge_rows(recorded, new) -> list[dict]:
    """``recorded`` rows with those of every (dataset, map) in ``new`` replaced by ``new``'s
    (in place, recorded order kept; pairs not recorded appended)."""
    def key(r):
        return int(r["dataset"]), r["map"]
    fresh: dict = {}
    for r in new:
        fresh.setdefault(key(r), []).append(r)
    out, done = [], set()
    for r in recorded:
        k = key(r)
        if k not in fresh:
            out.append(r)
        elif k not in done:
            out.extend(fresh[k])
            done.add(k)
    out.extend(r for k, rs in fresh.items() if k not in done for r in rs)
    return out


def read_table(path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def write_table(path, rows) -> None:
    from qfg.harness.runner import write_text

    lines = [",".join(COLUMNS)]
    for r in rows:
        lines.append(",".join(f"{r[c]:.4f}" if isinstance(r[c], float) else str(r[c])
                              for c in COLUMNS))
    write_text(Path(path), "\n".join(lines) + "\n")


def _figure(rows, paths) -> None:
    """:func:`qfg.harness.plotting_mrclam.maps_figure` of the rows, saved to each path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from qfg.harness.plotting_mrclam import maps_figure

    fig = maps_figure(rows)
    for path in paths:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
        print(f"figure: {path}", file=sys.stderr)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m qfg.harness.studies.mrclam.compare",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("root", nargs="?", help="the folder holding MRCLAM_Dataset1..6")
    p.add_argument("--from-csv", help="a recorded table (mrclam_maps.csv): print it and draw "
                   "its figure instead of running the maps")
    p.add_argument("--output", default="out/mrclam-maps")
    p.add_argument("--datasets", default="1,2,3,4,5,6")
    p.add_argument("--maps", default=",".join(m for m, _ in MAPS),
                   help="comma-separated map names of the table to run (with --update-docs, "
                        "their rows of the datasets run replace the recorded ones)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--update-docs", action="store_true",
                   help="write docs/results/mrclam_maps.csv (a tracked file)")
    a = p.parse_args(argv)
    ds = [int(x) for x in a.datasets.split(",")]
    names = [m.strip() for m in a.maps.split(",") if m.strip()]
    unknown = sorted(set(names) - {m for m, _ in MAPS})
    if unknown:
        p.error(f"--maps: {', '.join(unknown)} not in the table (maps: "
                f"{', '.join(m for m, _ in MAPS)})")
    maps = tuple(m for m in MAPS if m[0] in names)
    if a.from_csv:
        rows = read_table(a.from_csv)
        ds = [d for d in ds if any(int(r["dataset"]) == d for r in rows)]
    elif a.root:
        rows = compare(a.root, output=a.output, datasets=ds, maps=maps, seed=a.seed,
                       say=lambda m: print(m, file=sys.stderr, flush=True))
        write_table(Path(a.output) / "mrclam_maps.csv", rows)
    else:
        p.error("give the folder holding MRCLAM_Dataset1..6, or --from-csv")
    figures = [Path(a.output) / "mrclam_maps.png"]
    if a.update_docs:
        if not a.from_csv:
            recorded = Path("docs/results/mrclam_maps.csv")
            if recorded.is_file():
                rows = merge_rows(read_table(recorded), rows)
                ds = sorted({int(r["dataset"]) for r in rows})
            write_table(recorded, rows)
        figures.append(Path("docs/figures/mrclam/maps.png"))
    _figure(rows, figures)
    print("\n".join(markdown(rows)))
    for m, (s, n) in sorted(map_scores(rows).items(), key=lambda kv: -kv[1][0]):
        print(f"{m}: mean log p(truth) {s:.3f} over {n} seen and unseen triplets")
    print(f"best (the default rule): {best_map(rows, ds)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
