"""The ``qfg`` console command. Subcommands live in :mod:`qfg.harness.commands`, one module each.

Exit status: 0 done; 1 the work failed (every scenario of a run failed, a study of ``qfg
experiment all`` failed, a check found problems, a run stopped by a full disk or a worker that
kept dying: ``--resume`` continues it); 2 bad input (arguments, parameters, an output
that is a file or in use by another run) with one line on stderr; 130 interrupted by Ctrl-C
(one line saying how far the run got; ``--resume`` continues it).
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys

from qfg._version import __version__
from qfg.harness import commands


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="qfg", description="Probabilistic qualitative localization and mapping.")
    parser.add_argument("--version", action="version", version=f"qfg {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        mod = importlib.import_module(f"{commands.__name__}.{info.name}")
        if hasattr(mod, "register"):
            mod.register(sub)
    return parser


def _command_parser(parser: argparse.ArgumentParser, args) -> argparse.ArgumentParser:
    """The (sub)parser that parsed ``args``: the deepest subcommand named in them."""
    while True:
        chosen = [a.choices[getattr(args, a.dest)] for a in parser._actions
                  if isinstance(a, argparse._SubParsersAction)
                  and getattr(args, a.dest, None) in a.choices]
        if not chosen:
            return parser
        parser = chosen[0]


def main(argv=None) -> int:
    # Figures are written to files: a non-interactive backend unless the user chose one. Set
    # here, at the entry point, so that importing qfg in a notebook changes nothing.
    os.environ.setdefault("MPLBACKEND", "Agg")
    from qfg.harness.runner import RunAborted, RunInterrupted, ScenariosFailed

    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        # the command's own error, as one line naming the arguments (argparse's top-level
        # parser would print its usage line and its name instead)
        commands.one_line_error(_command_parser(parser, args))(
            f"unrecognized arguments: {' '.join(unknown)}")
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except RunInterrupted as exc:
        print(f"qfg {args.command}: {exc}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print(f"qfg {args.command}: interrupted", file=sys.stderr)
        return 130
    except (ScenariosFailed, RunAborted) as exc:
        print(f"qfg {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except ValueError as exc:  # bad input: one clear line, not a traceback
        print(f"qfg {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
