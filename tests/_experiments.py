"""Load a script of ``experiments/`` as a module (the scripts are not a package), for the tests
that check them."""

from __future__ import annotations

import importlib.util
from pathlib import Path

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def load_experiment(path: str):
    """The module of ``experiments/<path>.py``, ``path`` naming its topic folder and script, e.g.
    ``"mrclam/mrclam_heading_steps"``."""
    file = EXPERIMENTS / f"{path}.py"
    spec = importlib.util.spec_from_file_location(file.stem, file)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
