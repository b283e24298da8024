"""``qfg experiment NAME``: run a study through the experiment runner."""

from __future__ import annotations

import shlex
import sys


def register(sub):
    p = sub.add_parser("experiment", help="run a study (qfg experiment list shows them)",
                       description="Run a study through the experiment runner. Presets come from "
                                   "experiments/<name>.toml.")
    p.add_argument("name", help="study name, 'list', or 'all' (every study, then docs/results.md)")
    p.add_argument("--preset", default="quick", help="preset in experiments/<name>.toml "
                                                     "(quick or paper; default quick)")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (default 1)")
    p.add_argument("--scheduler", default=None,
                   help="dask.distributed scheduler address (needs qfg[dask]); overrides --workers")
    p.add_argument("--output", default=None, help="output directory (default results/<name>-<preset>;"
                                                  " with 'all': the root, default results)")
    p.add_argument("--seed", type=int, default=0, help="experiment seed (default 0)")
    p.add_argument("--resume", action="store_true", help="continue a run in --output")
    p.add_argument("--overwrite", action="store_true", help="start again in a used --output")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a preset parameter (TOML value), may repeat")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--doc-only", action="store_true",
                   help="with 'all': only rebuild docs/results.md from docs/results/*.md")
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
    study = get_study(args.name)
    presets = runner.load_presets(study.name)
    if args.preset not in presets:
        raise ValueError(f"--preset: {args.preset!r} not in experiments/"
                         f"{study.name.replace('-', '_')}.toml (has {', '.join(presets)})")
    params = {**presets[args.preset], **parse_overrides(args.set)}
    output = args.output or f"results/{study.name}-{args.preset}"
    executor = runner.make_executor(args.workers, args.scheduler) if args.scheduler else None
    command = "qfg " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    try:
        rows = runner.run_study(study, params, output, seed=args.seed, workers=args.workers,
                                resume=args.resume, overwrite=args.overwrite, executor=executor,
                                progress=not args.no_progress, command=command)
    finally:
        if executor is not None:  # the cluster client made for --scheduler
            executor.close()
    print(f"{study.name}: {len(rows)} rows in {output}")
    return 0


def _main_all(args):
    """``qfg experiment all``: every study with ``--preset`` into ``<--output or results>/
    <name>-<preset>``, then docs/results.md rebuilt (qfg/studies/_all.py)."""
    from qfg.harness import runner
    from qfg.harness.studies._all import run_all

    if args.doc_only:
        from qfg.harness.results_doc import write

        print(f"rebuilt {write()}")
        return 0
    if args.set:
        raise ValueError("--set: not accepted with 'all' (parameters differ between studies)")
    extra = "".join([f" --workers {args.workers}" if args.workers > 1 else "",
                     f" --scheduler {shlex.quote(args.scheduler)}" if args.scheduler else ""])
    executor = runner.make_executor(args.workers, args.scheduler) if args.scheduler else None
    try:
        runs = run_all(args.preset, root=args.output or "results", seed=args.seed,
                       workers=args.workers, executor=executor, resume=args.resume,
                       overwrite=args.overwrite, progress=not args.no_progress, extra_args=extra)
    finally:
        if executor is not None:
            executor.close()
    return 1 if any(r.get("error") for r in runs) else 0
