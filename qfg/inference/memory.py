"""The memory budget of the exact engines: what they may allocate, checked before any work.

Every engine call estimates the peak bytes it will allocate (tables it builds, messages it keeps,
the largest intermediate of each contraction it runs, see
:meth:`~qfg.inference.junction.JunctionTree.memory_estimate`) and compares it with a budget:

* ``memory=`` on the call, else
* the environment variable ``QFG_MEMORY_BUDGET``, else
* :data:`DEFAULT_FRACTION` of the machine's physical memory (``os.sysconf``; 8 GiB when the
  system does not say).

A budget is bytes, a size (``512M``, ``2G``, ``2GiB``), a percentage of the machine's memory
(``50%``) or unlimited (``inf``, ``1e400``): :func:`qfg.budget.parse_bytes`, the one parser of
the library, which this module re-exports with :func:`memory_budget` and
:data:`DEFAULT_FRACTION`.

Over budget -> :class:`MemoryBudgetError` (a :class:`~qfg.inference.results.GraphTooLargeError`,
so a ValueError) naming the estimate, the budget and where the bytes go, before any table is built.

>>> parse_bytes("1.5G") == int(1.5 * 2 ** 30)
True
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from .. import budget as _budget
from ..budget import DEFAULT_FRACTION, memory_budget, parse_bytes
from .results import GraphTooLargeError

__all__ = ["MemoryBudgetError", "MemoryEstimate", "memory_budget", "parse_bytes",
           "DEFAULT_FRACTION", "check_memory"]


class MemoryBudgetError(GraphTooLargeError, _budget.MemoryBudgetError):
    """Raised before any work when an engine's estimated peak allocation exceeds the budget.

    Both a :class:`~qfg.inference.results.GraphTooLargeError` and a
    :class:`qfg.budget.MemoryBudgetError` (so a ValueError). Attributes: ``estimate`` (bytes, a
    float), ``budget`` (bytes), ``task``, and those of
    :class:`~qfg.inference.results.GraphTooLargeError` (``entries``, ``width``)."""

    def __init__(self, message: str, *, estimate: float, budget: int, task: str = "",
                 entries: float = float("nan"), width: int = 0):
        # both bases take other keywords: set every attribute here, once
        ValueError.__init__(self, message)
        self.entries = entries
        self.width = width
        self.max_table = 0
        self.estimate = float(estimate)
        self.budget = int(budget)
        self.task = task


def check_memory(estimate: float, budget: int, task: str, detail: str = "", *,
                 entries: float = float("nan"), width: int = 0) -> None:
    """Raise :class:`MemoryBudgetError` when ``estimate`` bytes exceed ``budget`` (bytes):
    :func:`qfg.budget.check_memory` with the exact engines' error and advice."""
    _budget.check_memory(estimate, budget, task, detail, name="g",
                         hint="use propagate() or loopy_bp(), evidence, or a smaller model",
                         error=MemoryBudgetError, entries=entries, width=width)


@dataclass(frozen=True)
class MemoryEstimate:
    """Estimated peak bytes of one engine call: ``bytes`` (the total checked against the
    budget), ``task``, ``parts`` (bytes per component, e.g. ``tables``, ``linear_pass``)."""

    bytes: float
    task: str
    parts: Mapping = field(default_factory=dict)
