"""Readers for real data sets, turning their files into the package's measurement types.

``mrclam``: the UTIAS Multi-Robot Cooperative Localization and Mapping dataset (paper section 6d).
Submodules are imported on first use (``qfg.datasets.mrclam``), so that ``python -m
qfg.datasets.mrclam`` runs without a double import.
"""

import importlib

__all__ = ["mrclam"]


def __getattr__(name):
    if name in __all__:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
