"""What the MRCLAM study writes: the tables and summary of its rows (:func:`write_outputs`), its
figures (:func:`make_figures`), and the views curve (:func:`views_curve`, :func:`write_curve`)
with the scores under other tempering powers (:func:`temper_scores`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from qfg import metrics
from qfg.combine import temper
from qfg.datasets import mrclam as _mrclam
from qfg.harness.runner import figure_format, save_figure, write_table
from qfg.harness.studies.mrclam.history import prepare
from qfg.harness.studies.mrclam.params import KINDS, MODES, MrclamParams
from qfg.harness.studies.mrclam.pipeline import _combine, run_dataset
from qfg.harness.studies.mrclam.scoring import TABLE_KEY, _fmt, decode, summary, table_lines


def write_outputs(outdir, rows: list[dict], *, figures: bool = True, figure_robot=None,
                  details=None, options=None) -> dict:
    """``triplets.csv`` (seen and propagated rows), ``cameras.csv`` (camera rows, when any),
    ``summary.json`` (with ``options``, when given), ``table.md`` (the table and its key) and
    figures; returns the summary dict."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    # timings stay out of the tables (the runner's timings.csv has them), so that the same
    # inputs write the same bytes, however often the run was interrupted
    untimed = [{k: v for k, v in r.items() if not k.startswith("time_")} for r in rows]
    trip = [r for r in untimed if r["kind"] != "camera"]
    cams = [r for r in untimed if r["kind"] == "camera"]
    write_table(out / "triplets.csv", trip, digits=None)
    if cams:
        write_table(out / "cameras.csv", cams, digits=None)
    names = list(dict.fromkeys(r["dataset"] for r in rows))
    summ = summary(rows)
    summ["datasets"] = {n: summary([r for r in rows if r["dataset"] == n]) for n in names}
    if options is not None:
        summ["options"] = options
    (out / "summary.json").write_text(json.dumps(summ, indent=2) + "\n")
    (out / "table.md").write_text("\n".join(table_lines(summ)) + "\n\n" + TABLE_KEY + "\n")
    if figures and rows:
        make_figures(out, rows, details=details, robot=figure_robot)
    return summ


# ----------------------------------------------------------------------------- figures
def make_figures(outdir: Path, rows: list[dict], *, details=None, robot=None) -> list[Path]:
    """Reliability (calibration) figures of each mode's seen, propagated and camera rows, one
    robot's path with the views of the seen triplet with most views (first dataset) and, for a
    joint map or a configuration map, the map against the ground truth (``joint_map``,
    ``configuration_map``)."""
    from qfg.harness.plotting_mrclam import (
        configuration_map_figure,
        joint_map_figure,
        reliability_figure,
    )

    paths = []
    for mode in sorted({r["mode"] for r in rows}):
        groups = {}
        for kind in KINDS:
            sel = [r for r in rows if r["mode"] == mode and r["kind"] == kind]
            if sel:
                groups[kind] = (np.array([decode(r["probabilities"]) for r in sel]),
                                np.array([int(r["truth_state"]) for r in sel]))
        if groups:
            fig = reliability_figure(groups, title=f"{mode} mode: reliability")
            paths.append(save_figure(fig, outdir, f"reliability_{mode}"))
    paths += _path_figure(outdir, rows, details, robot)
    geom = dict(getattr((details or {}).get("map"), "info", None) or {}).get("map_geometry")
    if geom and geom.get("kind") == "configurations":
        paths.append(save_figure(configuration_map_figure(geom, details["dataset"]), outdir,
                                 "configuration_map"))
    elif geom:
        paths.append(save_figure(joint_map_figure(geom, details["dataset"]), outdir,
                                 "joint_map"))
    return paths


def _path_figure(outdir, rows, details, robot):
    from qfg.harness.plotting_mrclam import dataset_figure

    seen = [r for r in rows if r["kind"] == "seen" and r["mode"] == rows[0]["mode"]
            and r["dataset"] == rows[0]["dataset"]
            and (robot is None or str(robot) in str(r["robots"]).split(";"))]
    if not seen:
        return []
    row = max(seen, key=lambda r: (int(r["n_views"]), -int(r["A"]), -int(r["B"]), -int(r["C"])))
    if details is not None:
        ds = details["dataset"]
    else:
        ds, _ = prepare(row["path"], fix_landmarks=bool(row["gt_swaps"]))
    r = int(str(row["robots"]).split(";")[0]) if robot is None else int(robot)
    trip = (int(row["A"]), int(row["B"]), int(row["C"]))
    hs = [h for h in _mrclam.triplet_histories(ds, r, min_travel=0.02) if tuple(h.landmarks) == trip]
    h = max(hs, key=lambda x: x.n_views) if hs else None
    figdir = Path(outdir) / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    p = figdir / f"{ds.name}_robot{r}.{figure_format()}"
    return [Path(dataset_figure(ds, r, p, history=h))]


# ----------------------------------------------------------------------------- views curve
def views_curve(path, caps=(3, 5, 8, 13, 0), params=None, *, seed=0) -> list[dict]:
    """Seen-triplet scores against the views kept per pass: for each cap n (0: all), every pass
    truncated to its first n views, solved, combined and scored (no propagation), with the
    other options of ``params`` (:class:`MrclamParams`; None: the defaults). Returns one dict
    per (cap, mode, kind) with the :func:`kind_summary` entries and ``max_views``."""
    base = MrclamParams() if params is None else params
    out = []
    for n in caps:
        rows = run_dataset(path, base.replace(max_views=int(n), propagate=False, map=""),
                           seed=seed)
        for mode, d in summary(rows).items():
            if mode not in MODES:
                continue
            for kind in ("seen", "camera"):
                if d[kind]["n"]:
                    views = [int(r["n_views"]) / max(int(r.get("n_histories") or 1), 1)
                             for r in rows if r["kind"] == kind]
                    out.append({"dataset": rows[0]["dataset"], "max_views": int(n), "mode": mode,
                                "kind": kind, "views_median": float(np.median(views)),
                                **d[kind]})
    return out


def temper_scores(details, taus=(1.0, 0.5, 0.3, 0.2, 0.1, 0.05, 0.0), combine="prior-once"):
    """Mean scores of the seen triplets of one solved dataset (``run_dataset(...,
    return_details=True)`` with ``temper=1``) for each tempering exponent, without solving again:
    each history's estimate tempered, the histories of each ordered triplet combined, scored
    against the landmark ground truth. Returns a list of dicts (``temper``, ``n``, ``log_score``,
    ``brier``, ``truth_under_1pct``)."""
    ds, part, q = details["dataset"], details["partition"], details["prior_states"]
    from qfg.graph import truth_states

    hs = [h for _, h in details["histories"]]
    L = np.array([e.landmark for e in details["estimates"]])
    groups: dict[tuple, list[int]] = {}
    for k, h in enumerate(hs):
        groups.setdefault(tuple(ds.landmark_index(h.landmarks).tolist()), []).append(k)
    trip = np.array(sorted(groups), dtype=np.intp).reshape(-1, 3)
    g = truth_states(trip, ds.landmark_xy, part.name)
    out = []
    for tau in taus:
        Lt = temper(L, q, tau)
        P = np.array([_combine(Lt[groups[tuple(t)]], q, combine).probabilities
                      for t in trip.tolist()])
        out.append({"temper": float(tau), "n": int(len(trip)),
                    "log_score": float(metrics.log_score(P, g).mean()),
                    "brier": float(metrics.brier(P, g).mean()),
                    "truth_under_1pct": float(metrics.truth_under(P, g, 0.01).mean())})
    return out


def curve_lines(recs: list[dict]) -> list[str]:
    """Markdown rows of :func:`views_curve` records."""
    lines = ["| dataset | mode | kind | views per pass (cap) | median views | n | log score | "
             "Brier | GT rating | truth < 1% | flagged |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in recs:
        lines.append(f"| {r['dataset']} | {r['mode']} | {r['kind']} | "
                     f"{r['max_views'] or 'all'} | {r['views_median']:g} | {r['n']} | "
                     f"{_fmt(r['log_score'])} | {_fmt(r['brier'], 3)} | {_fmt(r['gt_rating'])} | "
                     f"{_fmt(r['truth_under_1pct'])} | {_fmt(r['flagged'])} |")
    return lines


def write_curve(outdir, recs: list[dict], *, figures: bool = True) -> None:
    """``curve.csv``, ``curve.md`` and (``figures``) ``figures/views_curve.<format>``."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    write_table(out / "curve.csv", recs, digits=None)
    (out / "curve.md").write_text("\n".join(curve_lines(recs)) + "\n")
    if figures and recs:
        from qfg.harness.plotting_mrclam import curve_figure

        save_figure(curve_figure(recs), out, "views_curve")
