"""``qfg mrclam-runs merge|table``: recorded ``qfg mrclam`` runs read again (nothing solved).

* ``qfg mrclam-runs merge RUN RUN... [--temper RULE,...] [--map NAME] [--output DIR]``: runs of
  different robots of one dataset scored as one run of all their robots
  (:func:`qfg.harness.mrclam_runs.merged_estimates`); printed per temper rule. With ``--output``
  the printed lines go to ``DIR/merge.txt`` and each rule's merged rows to
  ``DIR/triplets_<rule>.csv`` (the columns of a run's ``triplets.csv``).
* ``qfg mrclam-runs table SEEN_RUN MAP_RUN [SEEN_RUN MAP_RUN ...] [--output DIR]``: the
  per-dataset markdown table of the solvers' seen triplets and a configuration map's seen and
  unseen ones beside the prior alone (:func:`qfg.harness.mrclam_runs.whole_datasets_table`);
  with ``--output``, also written to ``DIR/whole_datasets.md``.

A command of its own, not a subcommand of ``qfg mrclam``: that one takes a dataset folder as its
positional argument, so ``qfg mrclam merge`` could be a folder called ``merge``.

Bad input ends the command with one line naming the argument or the file, exit status 2. Files
are replaced whole (:mod:`qfg.files`).
"""

from __future__ import annotations

from pathlib import Path

from qfg.harness.commands import one_line_error


def register(sub):
    p = sub.add_parser("mrclam-runs", help="merge or table recorded qfg mrclam runs",
                       description="Recorded qfg mrclam run folders read again, nothing solved: "
                                   "runs of different robots merged as one run (merge), or the "
                                   "per-dataset table of seen and map runs (table).")
    p.error = one_line_error(p)
    subs = p.add_subparsers(dest="runs_command", metavar="ACTION", required=True)

    m = subs.add_parser("merge", help="score runs of different robots of one dataset as one run",
                        description="Runs of different robots of one dataset (the same options "
                                    "but --robots) scored as one run of all their robots: the "
                                    "histories prepared as --robots R1,R2,... prepares them, "
                                    "then tempered, combined, mapped and scored by the study. "
                                    "Only the seeds differ from solving the robots together.")
    m.error = one_line_error(m)
    m.add_argument("runs", nargs="+", metavar="RUN", help="finished qfg mrclam run folders, "
                                                          "two or more")
    m.add_argument("--temper", default="auto-1se",
                   help="comma-separated temper rules, each auto, auto-1se or a power in [0, 1] "
                        "(default auto-1se)")
    m.add_argument("--map", default="seen",
                   help="map method of qfg mrclam --map (default seen); a map that propagates "
                        "(e.g. config-state) scores the unseen triplets too")
    m.add_argument("--output", default=None,
                   help="folder (created if missing) for merge.txt and triplets_<rule>.csv")
    m.set_defaults(func=_merge)

    t = subs.add_parser("table", help="the per-dataset table of seen and map runs",
                        description="Per dataset, from two finished runs of the same solving "
                                    "(--map seen, then a configuration map, e.g. --resume on a "
                                    "copy with --map config-state): the solvers' seen triplets "
                                    "and the map's seen and unseen ones, each beside the prior "
                                    "alone, as a markdown table.")
    t.error = one_line_error(t)
    t.add_argument("runs", nargs="+", metavar="RUN",
                   help="run folders in pairs: SEEN_RUN (--map seen) MAP_RUN (the map)")
    t.add_argument("--output", default=None,
                   help="folder (created if missing) for whole_datasets.md")
    t.set_defaults(func=_table)


def _rules(text: str) -> list:
    from qfg.harness.studies.mrclam import TEMPER_RULES

    out = []
    for item in (x.strip().lower() for x in str(text).split(",")):
        if item in TEMPER_RULES:
            out.append(item)
            continue
        try:
            v = float(item)
        except ValueError:
            v = float("nan")
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"--temper: expected auto, auto-1se or a power in [0, 1], got "
                             f"{item!r}")
        out.append(item)
    return out


def _folders(runs, name="RUN") -> list[Path]:
    out = [Path(r) for r in runs]
    for r in out:
        if not r.is_dir():
            raise ValueError(f"{name}: {r} is not a folder (give qfg mrclam run folders)")
    return out


def _output(text):
    """``--output``: the folder, created when missing; ValueError when it cannot be."""
    out = Path(text)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"--output: cannot make the folder {out}: {exc.strerror or exc}") from None
    return out


def _write(path: Path, text: str) -> None:
    from qfg.files import atomic_write_text

    try:
        atomic_write_text(path, text)
    except OSError as exc:
        raise ValueError(f"--output: cannot write {path}: {exc.strerror or exc}") from None


def _csv(rows: list[dict]) -> str:
    import csv
    import io

    cols = list(dict.fromkeys(k for r in rows for k in r if not k.startswith("time_")))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in rows:
        w.writerow(["" if r.get(k) is None else str(r.get(k)) for k in cols])
    return buf.getvalue()


def _merge(args):
    from qfg.harness import mrclam_runs
    from qfg.harness.studies.mrclam.maps import MAP_METHODS

    rules = _rules(args.temper)
    if args.map not in MAP_METHODS:
        raise ValueError(f"--map: unknown {args.map!r}; known: {', '.join(MAP_METHODS)}")
    runs = _folders(args.runs)
    if len(runs) < 2:
        raise ValueError(f"RUN: give two or more run folders to merge, got {len(runs)}")
    out = _output(args.output) if args.output else None
    prep, ests = mrclam_runs.merged_estimates(runs)
    by_rule = {}
    lines = mrclam_runs.merge_lines(prep, ests, rules, args.map, rows_by_rule=by_rule)
    print("\n".join(lines))
    if out is not None:
        _write(out / "merge.txt", "\n".join(lines) + "\n")
        for rule, rows in by_rule.items():
            _write(out / f"triplets_{rule}.csv",
                   _csv([r for r in rows if r["kind"] != "camera"]))
        print(f"-> {out}")
    return 0


def _table(args):
    from qfg.harness import mrclam_runs

    runs = _folders(args.runs)
    if len(runs) % 2:
        raise ValueError(f"RUN: runs come in pairs (SEEN_RUN MAP_RUN); got {len(runs)} folders")
    out = _output(args.output) if args.output else None
    text = mrclam_runs.whole_datasets_table(list(zip(runs[::2], runs[1::2], strict=True)))
    print(text)
    if out is not None:
        _write(out / "whole_datasets.md", text + "\n")
        print(f"-> {out / 'whole_datasets.md'}")
    return 0
