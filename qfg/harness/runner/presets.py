"""Study presets: ``<presets_dir>/<name>.toml`` (package data ``qfg/_presets``, the top-level
``experiments/`` in a checkout; ``$QFG_EXPERIMENTS`` overrides), one table per preset."""

from __future__ import annotations

import os
from pathlib import Path

from qfg.harness.runner.errors import RunnerError

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - 3.10
    import tomli as tomllib


def presets_dir():
    """Where study presets live: ``$QFG_EXPERIMENTS`` if set, else the package data
    ``qfg/_presets`` (in a checkout: the top-level ``experiments/``)."""
    env = os.environ.get("QFG_EXPERIMENTS")
    if env:
        return Path(env)
    from importlib.resources import files

    return Path(str(files("qfg") / "_presets")).resolve()


#: Former name, kept importable.
experiments_dir = presets_dir


def preset_path(name: str) -> Path:
    """The preset file of study ``name``: ``<presets_dir>/<name>.toml`` (``-`` read as ``_``); an
    absolute path, so that messages name a file a pip user has."""
    return (presets_dir() / f"{name.replace('-', '_')}.toml").absolute()


def load_presets(name: str) -> dict[str, dict]:
    """Presets of a study from its preset file (:func:`preset_path`)."""
    path = preset_path(name)
    if not path.exists():
        raise RunnerError(f"study {name!r}: no preset file {path}")
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise RunnerError(f"{path}: {exc}") from None
    return {k: v for k, v in data.items() if isinstance(v, dict)}
