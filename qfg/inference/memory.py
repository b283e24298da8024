"""The memory budget of the exact engines: what they may allocate, checked before any work.

Every engine call estimates the peak bytes it will allocate (tables it builds, messages it keeps,
the largest intermediate of each contraction it runs, see
:meth:`~qfg.inference.junction.JunctionTree.memory_estimate`) and compares it with a budget:

* ``memory=`` on the call (bytes, an int >= 1), else
* the environment variable ``QFG_MEMORY_BUDGET`` (bytes; suffixes ``K``, ``M``, ``G`` allowed), else
* :data:`DEFAULT_FRACTION` of the machine's physical memory (``os.sysconf``; 4 GiB when the
  system does not say).

Over budget -> :class:`MemoryBudgetError` (a :class:`~qfg.inference.results.GraphTooLargeError`,
so a ValueError) naming the estimate, the budget and where the bytes go, before any table is built.

>>> parse_bytes("1.5G") == int(1.5 * 2 ** 30)
True
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field

from .results import GraphTooLargeError

__all__ = ["MemoryBudgetError", "MemoryEstimate", "memory_budget", "parse_bytes",
           "DEFAULT_FRACTION", "check_memory"]

#: Share of the physical memory the exact engines may use by default.
DEFAULT_FRACTION = 0.5

_UNITS = {"": 1, "B": 1, "K": 2 ** 10, "M": 2 ** 20, "G": 2 ** 30, "T": 2 ** 40}


class MemoryBudgetError(GraphTooLargeError):
    """Raised before any work when an engine's estimated peak allocation exceeds the budget.

    Attributes: ``estimate`` (bytes, a float), ``budget`` (bytes), ``task``, and those of
    :class:`~qfg.inference.results.GraphTooLargeError` (``entries``, ``width``)."""

    def __init__(self, message: str, *, estimate: float, budget: int, task: str = "",
                 entries: float = float("nan"), width: int = 0):
        super().__init__(message, entries=entries, width=width)
        self.estimate = float(estimate)
        self.budget = int(budget)
        self.task = task


def parse_bytes(text) -> int:
    """``"2G"``, ``"512M"``, ``"1e9"`` or an int -> bytes (ValueError naming it otherwise)."""
    if isinstance(text, bool):
        raise ValueError(f"memory: expected bytes (an int or e.g. '2G'), got {text!r}")
    if isinstance(text, int):
        v = text
    else:
        s = str(text).strip().upper().removesuffix("IB").removesuffix("B")
        unit = s[-1:] if s[-1:] in _UNITS and s[-1:] != "" else ""
        try:
            v = int(float(s[:-1] if unit else s) * _UNITS[unit])
        except ValueError:
            raise ValueError(f"memory: expected bytes (an int or e.g. '2G'), got {text!r}") from None
    if v < 1:
        raise ValueError(f"memory: expected a positive number of bytes, got {text!r}")
    return v


def _physical_memory() -> int:
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return 8 * 2 ** 30


def memory_budget(memory=None) -> int:
    """The budget in bytes: ``memory`` if given, else ``$QFG_MEMORY_BUDGET``, else
    :data:`DEFAULT_FRACTION` of the physical memory."""
    if memory is not None:
        return parse_bytes(memory)
    env = os.environ.get("QFG_MEMORY_BUDGET")
    if env:
        return parse_bytes(env)
    return int(DEFAULT_FRACTION * _physical_memory())


def _fmt(b: float) -> str:
    for unit, size in (("TiB", 2 ** 40), ("GiB", 2 ** 30), ("MiB", 2 ** 20), ("KiB", 2 ** 10)):
        if b >= size:
            return f"{b / size:.3g} {unit}"
    return f"{b:.0f} B"


def check_memory(estimate: float, budget: int, task: str, detail: str = "", *,
                 entries: float = float("nan"), width: int = 0) -> None:
    """Raise :class:`MemoryBudgetError` when ``estimate`` bytes exceed ``budget``."""
    if estimate > budget:
        raise MemoryBudgetError(
            f"g: {task} refused before any work: it would allocate about {_fmt(estimate)} "
            f"({estimate:.3g} bytes{'; ' + detail if detail else ''}) > the memory budget "
            f"{_fmt(budget)} (memory=, or $QFG_MEMORY_BUDGET); use propagate() or loopy_bp(), "
            f"evidence, or a smaller model", estimate=estimate, budget=budget, task=task,
            entries=entries, width=width)


@dataclass(frozen=True)
class MemoryEstimate:
    """Estimated peak bytes of one engine call: ``bytes`` (the total checked against the
    budget), ``task``, ``parts`` (bytes per component, e.g. ``tables``, ``linear_pass``)."""

    bytes: float
    task: str
    parts: Mapping = field(default_factory=dict)
