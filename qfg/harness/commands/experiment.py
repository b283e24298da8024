"""``qfg experiment NAME``: run a study through the experiment runner."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from qfg.harness.commands import add_format, positive_int, seed_int


def register(sub):
    p = sub.add_parser("experiment", help="run a study (qfg experiment list shows them)",
                       description="Run a study through the experiment runner. Presets come from "
                                   "experiments/<name>.toml (shipped with the package).")
    p.add_argument("name", help="study name, 'list', or 'all' (every study)")
    p.add_argument("--preset", default="quick", help="preset in experiments/<name>.toml "
                                                     "(quick or paper; default quick)")
    p.add_argument("--workers", type=positive_int, default=1,
                   help="local worker processes (default 1)")
    p.add_argument("--scheduler", default=None,
                   help="dask.distributed scheduler address (needs qfg[dask]); overrides --workers")
    p.add_argument("--output", default=None, help="output directory (default out/<name>-<preset>;"
                                                  " with 'all': the root, default out)")
    p.add_argument("--seed", type=seed_int, default=0, help="experiment seed (default 0)")
    p.add_argument("--resume", action="store_true", help="continue a run in --output")
    p.add_argument("--overwrite", action="store_true", help="start again in a used --output")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a preset parameter (TOML value), may repeat")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_format(p)
    p.add_argument("--update-docs", nargs="?", const="docs/results.md", default=None,
                   metavar="PATH",
                   help="with 'all': also rebuild the results document (default docs/results.md, "
                        "from the section files docs/results/*.md next to it); without it no "
                        "tracked file is written")
    p.add_argument("--doc-only", action="store_true",
                   help="with 'all': only rebuild the results document (--update-docs PATH or "
                        "docs/results.md) from its section files, running nothing")
    p.set_defaults(func=_main)


def parse_overrides(items):
    """``["a=1", "b='x'", "c=[1, 2]"]`` -> dict, values read as TOML (bare words as strings)."""
    from qfg.harness.runner import tomllib

    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"--set: expected KEY=VALUE, got {item!r}")
        try:
            out[key.strip()] = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            out[key.strip()] = value
    return out


def _main(args):
    from qfg.harness import runner
    from qfg.harness.studies import get_study, studies

    if args.name == "list":
        for name, st in sorted(studies().items()):
            print(f"{name:20s} {st.description}")
        return 0
    if args.name == "all":
        return _main_all(args)
    if args.update_docs or args.doc_only:
        raise ValueError("--update-docs, --doc-only: only with 'all'")
    study = get_study(args.name)
    presets = runner.load_presets(study.name)
    if args.preset not in presets:
        raise ValueError(f"--preset: {args.preset!r} is not a preset of {study.name} "
                         f"({runner.preset_path(study.name)} has {', '.join(presets)})")
    params = {**presets[args.preset], **parse_overrides(args.set)}
    output = args.output or f"out/{study.name}-{args.preset}"
    executor = runner.make_executor(args.workers, args.scheduler) if args.scheduler else None
    command = "qfg " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    try:
        rows = runner.run_study(study, params, output, seed=args.seed, workers=args.workers,
                                resume=args.resume, overwrite=args.overwrite, executor=executor,
                                progress=not args.no_progress, command=command,
                                figure_format=args.format)
    finally:
        if executor is not None:  # the cluster client made for --scheduler
            executor.close()
    print(f"{study.name}: {len(rows)} rows in {output} (figures in {Path(output) / 'figures'})")
    return 0


def _docs_paths(args):
    """The results document to rebuild and its section folder; ValueError when absent."""
    doc = Path(args.update_docs or "docs/results.md")
    secs = doc.parent / "results"
    if not secs.is_dir():
        raise ValueError(f"--update-docs: no section folder {secs} next to {doc} (run from the "
                         "repository checkout, or give the path of its docs/results.md)")
    return doc, secs


def _main_all(args):
    """``qfg experiment all``: every study with ``--preset`` into ``<--output or out>/
    <name>-<preset>``; the results document rebuilt only with --update-docs."""
    from qfg.harness import runner
    from qfg.harness.studies._all import run_all

    if args.doc_only:
        from qfg.harness.results_doc import write

        doc, secs = _docs_paths(args)
        print(f"rebuilt {write(doc, results_dir=secs)}")
        return 0
    if args.set:
        raise ValueError("--set: not accepted with 'all' (parameters differ between studies)")
    doc = _docs_paths(args) if args.update_docs else None
    extra = "".join([f" --workers {args.workers}" if args.workers > 1 else "",
                     f" --scheduler {shlex.quote(args.scheduler)}" if args.scheduler else "",
                     f" --format {args.format}" if args.format != "png" else ""])
    executor = runner.make_executor(args.workers, args.scheduler) if args.scheduler else None
    try:
        runs = run_all(args.preset, root=args.output or "out", seed=args.seed,
                       workers=args.workers, executor=executor, resume=args.resume,
                       overwrite=args.overwrite, progress=not args.no_progress, extra_args=extra,
                       doc=doc, figure_format=args.format)
    finally:
        if executor is not None:
            executor.close()
    return 1 if any(r.get("error") for r in runs) else 0
