"""The ``qfg`` console command. Subcommands live in :mod:`qfg.commands`, one module each."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from qfg.harness import commands
from qfg._version import __version__


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


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except ValueError as exc:  # bad input: one clear line, not a traceback
        print(f"qfg {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
