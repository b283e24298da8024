"""Figures: the run's figure format (``--format``: :func:`figure_format`,
:func:`use_figure_format`) and :func:`save_figure`, which every study's figures go through."""

from __future__ import annotations

import contextlib
import contextvars
from pathlib import Path

from qfg.harness.runner.errors import RunnerError
from qfg.harness.runner.records import _replacing

#: Figure formats ``--format`` accepts.
FIGURE_FORMATS = ("png", "pdf", "svg")


_FORMAT: contextvars.ContextVar[str] = contextvars.ContextVar("qfg_figure_format", default="png")


def figure_format() -> str:
    """The figure format of the run in progress (``--format``; default png)."""
    return _FORMAT.get()


@contextlib.contextmanager
def use_figure_format(fmt: str):
    """Within the block, :func:`save_figure` writes ``fmt`` (png, pdf or svg)."""
    if fmt not in FIGURE_FORMATS:
        raise RunnerError(f"format: expected one of {', '.join(FIGURE_FORMATS)}, got {fmt!r}")
    token = _FORMAT.set(fmt)
    try:
        yield fmt
    finally:
        _FORMAT.reset(token)


def save_figure(fig, outdir, name: str, *, dpi: int = 130, fmt: str | None = None) -> Path:
    """Write ``fig`` as ``<outdir>/figures/<name>.<format>`` (the run's format unless ``fmt``),
    creating the folder; close it; return the path. Every study's figures go through here."""
    fmt = fmt or figure_format()
    if fmt not in FIGURE_FORMATS:
        raise RunnerError(f"format: expected one of {', '.join(FIGURE_FORMATS)}, got {fmt!r}")
    figdir = Path(outdir) / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    path = figdir / f"{name}.{fmt}"
    import matplotlib.pyplot as plt

    try:
        with _replacing(path) as fh:
            fig.savefig(fh, dpi=dpi, format=fmt)
    finally:
        plt.close(fig)
    return path
