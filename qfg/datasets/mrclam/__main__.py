"""``python -m qfg.datasets.mrclam``: see :func:`qfg.datasets.mrclam._cli._main`."""

from ._cli import _main

raise SystemExit(_main())
