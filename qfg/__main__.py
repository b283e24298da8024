"""``python -m qfg``: the ``qfg`` command."""

import sys

from qfg.harness.cli import main

sys.exit(main())
