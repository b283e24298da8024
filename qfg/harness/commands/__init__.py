"""Subcommands of the ``qfg`` console command.

Every module here with a ``register(subparsers)`` function adds one subcommand; :mod:`qfg.harness.cli`
discovers them, so a new command is a new file. Shared argument types live here.
"""

from __future__ import annotations

import argparse

FORMATS = ("png", "pdf", "svg")


def _int_at_least(text: str, minimum: int) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= {minimum}, got {text!r}") from None
    if v < minimum:
        raise argparse.ArgumentTypeError(f"expected an integer >= {minimum}, got {v}")
    return v


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    return _int_at_least(text, 1)


def seed_int(text: str) -> int:
    """argparse type: a seed, an integer >= 0."""
    return _int_at_least(text, 0)


def one_line_error(parser):
    """An ``error`` for ``parser`` that prints argparse's error as one line (``qfg CMD: error:
    MESSAGE (qfg CMD --help)``, exit 2), not usage + message: ``parser.error =
    one_line_error(parser)``."""

    def error(message):
        parser.exit(2, f"{parser.prog}: error: {message} ({parser.prog} --help)\n")

    return error


def add_format(p) -> None:
    p.add_argument("--format", default="png", choices=FORMATS,
                   help="figure file format (default png)")
