"""``qfg experiment NAME``: run a study through the experiment runner."""

from __future__ import annotations

import shlex
import sys


def register(sub):
    p = sub.add_parser("experiment", help="run a study (qfg experiment list shows them)",
                       description="Run a study through the experiment runner. Presets come from "
                                   "experiments/<name>.toml.")
    p.add_argument("name", help="study name, or 'list'")
    p.add_argument("--preset", default="quick", help="preset in experiments/<name>.toml "
                                                     "(quick or paper; default quick)")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (default 1)")
    p.add_argument("--scheduler", default=None,
                   help="dask.distributed scheduler address (needs qfg[dask]); overrides --workers")
    p.add_argument("--output", default=None, help="output directory (default results/<name>-<preset>)")
    p.add_argument("--seed", type=int, default=0, help="experiment seed (default 0)")
    p.add_argument("--resume", action="store_true", help="continue a run in --output")
    p.add_argument("--overwrite", action="store_true", help="start again in a used --output")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a preset parameter (TOML value), may repeat")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_main)


def parse_overrides(items):
    """``["a=1", "b='x'", "c=[1, 2]"]`` -> dict, values read as TOML (bare words as strings)."""
    from ..runner import tomllib

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
    from .. import runner

    if args.name == "list":
        for name, st in sorted(runner.studies().items()):
            print(f"{name:20s} {st.description}")
        return 0
    study = runner.get_study(args.name)
    presets = runner.load_presets(study.name)
    if args.preset not in presets:
        raise ValueError(f"--preset: {args.preset!r} not in experiments/"
                         f"{study.name.replace('-', '_')}.toml (has {', '.join(presets)})")
    params = {**presets[args.preset], **parse_overrides(args.set)}
    output = args.output or f"results/{study.name}-{args.preset}"
    executor = runner.make_executor(args.workers, args.scheduler) if args.scheduler else None
    command = "qfg " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    rows = runner.run_study(study, params, output, seed=args.seed, workers=args.workers,
                            resume=args.resume, overwrite=args.overwrite, executor=executor,
                            progress=not args.no_progress, command=command)
    print(f"{study.name}: {len(rows)} rows in {output}")
    return 0
