"""Subcommands of the ``qfg`` console command.

Every module here with a ``register(subparsers)`` function adds one subcommand; :mod:`qfg.cli`
discovers them, so a new command is a new file.
"""
