"""Subcommands of the ``qfg`` console command.

Every module here with a ``register(subparsers)`` function adds one subcommand; :mod:`qfg.harness.cli`
discovers them, so a new command is a new file. Shared argument types live here.
"""

from __future__ import annotations

import argparse

FORMATS = ("png", "pdf", "svg")


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {v}")
    return v


def seed_int(text: str) -> int:
    """argparse type: a seed, an integer >= 0."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {v}")
    return v


def add_format(p) -> None:
    p.add_argument("--format", default="png", choices=FORMATS,
                   help="figure file format (default png)")
