"""The memory budget: how many bytes a call may allocate, read from an argument, the environment
or the machine, and the check made before any allocation.

A budget is given as

* bytes: an int >= 1, or a float or a string of one (``1e9``; a fraction of a byte is dropped);
* a size with a binary unit: ``512K``, ``512M``, ``2G``, ``1T``, with or without ``B`` / ``iB``
  (``2G``, ``2GB`` and ``2GiB`` are all 2 * 2**30 bytes), any case, spaces allowed;
* a percentage of the machine's physical memory: ``50%`` (above 0, at most 100);
* unlimited: ``inf``, ``infinity``, ``unlimited``, a number too large for a float (``1e400``)
  or ``math.inf``.

A budget is always an int from 1 to :data:`UNLIMITED` (2**63 - 1 bytes, 8 EiB, more than any
machine can address): an unlimited one, or any larger number, is :data:`UNLIMITED`. So a budget
can be divided, compared with a float estimate or handed to numpy as an int64 without overflow,
and an "unlimited" call is still refused, with the usual message, when it would need more than
a 64-bit machine could ever give it.

Anything else (zero, a negative number, NaN, a bool, text that is none of the above) is a
ValueError whose message starts with the name of the argument it came from (``memory=``,
``--memory``, ``$QFG_MEMORY_BUDGET``).

Where a budget comes from, first match wins (:func:`memory_budget`): the call's own argument,
else the environment variable :data:`ENV` (``QFG_MEMORY_BUDGET``), else
:data:`DEFAULT_FRACTION` of the physical memory (``os.sysconf``; 8 GiB when the system does not
say).

>>> parse_bytes("1.5G") == int(1.5 * 2 ** 30), parse_bytes("512MiB") == 512 * 2 ** 20
(True, True)
>>> parse_bytes("1e400") == parse_bytes(float("inf")) == UNLIMITED == 2 ** 63 - 1
True
>>> format_bytes(parse_bytes("inf")), format_bytes(3 * 2 ** 30)
('unlimited', '3 GiB')
>>> parse_bytes("-2G", name="--memory")
Traceback (most recent call last):
...
ValueError: --memory: expected a positive number of bytes, got '-2G'
"""

from __future__ import annotations

import math
import os

__all__ = ["UNLIMITED", "DEFAULT_FRACTION", "ENV", "MemoryBudgetError", "parse_bytes",
           "memory_budget", "physical_memory", "format_bytes", "check_memory"]

#: The unlimited budget, and the largest: 2**63 - 1 bytes (numpy's largest int64), printed as
#: ``unlimited``.
UNLIMITED = 2 ** 63 - 1

#: Share of the physical memory a call may use when no budget is given.
DEFAULT_FRACTION = 0.5

#: The environment variable read when a call is given no budget.
ENV = "QFG_MEMORY_BUDGET"

_UNITS = {"": 1, "K": 2 ** 10, "M": 2 ** 20, "G": 2 ** 30, "T": 2 ** 40, "P": 2 ** 50}
_WORDS = {"INF", "INFINITY", "UNLIMITED"}


class MemoryBudgetError(ValueError):
    """Raised before any work when a call's estimated peak allocation exceeds the budget.

    Attributes: ``estimate`` (bytes, a float), ``budget`` (bytes, an int) and ``task`` (what
    was refused)."""

    def __init__(self, message: str, *, estimate: float, budget: int, task: str = ""):
        super().__init__(message)
        self.estimate = float(estimate)
        self.budget = int(budget)
        self.task = task


def _expected(name: str, value) -> ValueError:
    return ValueError(f"{name}: expected a positive number of bytes (e.g. 2000000000), a size "
                      f"(512M, 2G, 2GiB), a percentage of the machine's memory (50%) or inf, "
                      f"got {value!r}")


def parse_bytes(value, *, name: str = "memory"):
    """A budget (see the module docstring) -> bytes: an int from 1 to :data:`UNLIMITED`.

    ``name`` is the argument the value came from; a bad value is a ValueError starting with it.
    """
    if isinstance(value, bool) or value is None:
        raise _expected(name, value)
    if isinstance(value, int):          # exact: no round trip through a float
        v = value
    elif isinstance(value, float):
        v = _from_float(value, value, name)
    else:
        s = str(value).strip().upper()
        if not s:
            raise _expected(name, value)
        if s in _WORDS or s in ("+INF", "+INFINITY"):
            return UNLIMITED
        if s.endswith("%"):
            pct = _number(s[:-1], value, name)
            if not 0 < pct <= 100:
                raise ValueError(f"{name}: a percentage of the machine's memory must be above 0 "
                                 f"and at most 100, got {value!r}")
            v = int(pct / 100 * physical_memory())
        else:
            num, unit = _split_unit(s)
            if num is None:
                raise _expected(name, value)
            v = _from_float(_number(num, value, name) * _UNITS[unit], value, name)
    if v < 1:
        raise ValueError(f"{name}: expected a positive number of bytes, got {value!r}")
    return min(v, UNLIMITED)


def _split_unit(s: str):
    """``"2GIB"`` -> ``("2", "G")``, ``"512B"`` -> ``("512", "")``; (None, "") when a unit has
    no number or ``IB`` has no unit."""
    binary = s.endswith("IB")
    s = s[:-2] if binary else s.removesuffix("B")
    unit = s[-1:] if s[-1:] in _UNITS and s[-1:] else ""
    if binary and not unit:
        return None, ""
    num = s[:-1] if unit else s
    return (num if num.strip() else None), unit


def _number(text: str, value, name: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise _expected(name, value) from None
    if math.isnan(x):
        raise ValueError(f"{name}: expected a positive number of bytes, got {value!r} (NaN)")
    return x


def _from_float(x: float, value, name: str):
    if math.isnan(x):
        raise ValueError(f"{name}: expected a positive number of bytes, got {value!r} (NaN)")
    if x < 0:
        raise ValueError(f"{name}: expected a positive number of bytes, got {value!r}")
    return UNLIMITED if x >= UNLIMITED else int(x)


def physical_memory() -> int:
    """The machine's physical memory in bytes (8 GiB when the system does not say)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return 8 * 2 ** 30


def memory_budget(memory=None, *, name: str = "memory="):
    """The budget in bytes (an int from 1 to :data:`UNLIMITED`): ``memory`` if given (a bad one is a
    ValueError naming ``name``), else ``$QFG_MEMORY_BUDGET`` (naming it), else
    :data:`DEFAULT_FRACTION` of the physical memory."""
    if memory is not None:
        return parse_bytes(memory, name=name)
    env = os.environ.get(ENV)
    if env is not None and env.strip():
        return parse_bytes(env, name=f"${ENV}")
    return int(DEFAULT_FRACTION * physical_memory())


def format_bytes(b) -> str:
    """Bytes as a short readable size (``3 GiB``, ``512 B``); :data:`UNLIMITED` as
    ``unlimited``."""
    if b >= UNLIMITED:
        return "unlimited"
    b = float(b)
    for unit, size in (("TiB", 2 ** 40), ("GiB", 2 ** 30), ("MiB", 2 ** 20), ("KiB", 2 ** 10)):
        if b >= size:
            return f"{b / size:.3g} {unit}"
    return f"{b:.0f} B"


def check_memory(estimate: float, budget: int, task: str, detail: str = "", *, name: str = "",
                 hint: str = "", error=None, **attributes) -> None:
    """Raise ``error`` (:class:`MemoryBudgetError` by default) when ``estimate`` bytes exceed
    ``budget`` (bytes). ``task`` names what is refused, ``detail`` where the bytes go, ``name``
    the argument the message starts with, ``hint`` what to do instead; ``attributes`` go to the
    error with ``estimate``, ``budget`` and ``task``."""
    if estimate > budget:
        raise (error or MemoryBudgetError)(
            f"{name + ': ' if name else ''}{task} refused before any work: it would allocate about "
            f"{format_bytes(estimate)} ({estimate:.3g} bytes{'; ' + detail if detail else ''}) > "
            f"the memory budget {format_bytes(budget)} (memory=, or ${ENV})"
            f"{'; ' + hint if hint else ''}", estimate=estimate, budget=budget, task=task,
            **attributes)
