"""A study and its parameters: :class:`Study` (the three functions the runner calls) and the
parameter spec (:class:`Param`, :func:`param_spec`) that :func:`validate_params` checks before
anything runs."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from qfg.harness.runner.errors import RunnerError


@dataclass(frozen=True)
class Param:
    """What one study parameter accepts.

    Attributes:
        default: the value when the preset and ``--set`` do not give one; its type is the
            parameter's type (int, float, str, bool, list of those, dict).
        min, max: inclusive bounds for numbers (each element for a list of numbers).
        choices: the allowed values of a string (each element for a list of strings).
        nonempty: a list must have at least one element.
    """

    default: object
    min: float | None = None
    max: float | None = None
    choices: tuple | None = None
    nonempty: bool = False

    def check(self, name: str, value):
        """``value`` converted to the parameter's type (int -> float), or RunnerError naming it."""
        d = self.default
        if isinstance(d, list):
            if not isinstance(value, (list, tuple)):
                raise RunnerError(f"{name}: expected a list, got {value!r}")
            if self.nonempty and not value:
                raise RunnerError(f"{name}: expected a non-empty list")
            elem = Param(d[0] if d else None, self.min, self.max, self.choices)
            if not d:  # no element type to check against
                return list(value)
            return [elem.check(f"{name}[{i}]", v) for i, v in enumerate(value)]
        if isinstance(d, bool):
            if not isinstance(value, bool):
                raise RunnerError(f"{name}: expected true or false, got {value!r}")
            return value
        if isinstance(d, int):
            if isinstance(value, bool) or not isinstance(value, int):
                raise RunnerError(f"{name}: expected an integer{self._range()}, got {value!r}")
            self._bounds(name, value, "an integer")
            return value
        if isinstance(d, float):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise RunnerError(f"{name}: expected a number{self._range()}, got {value!r}")
            if not np.isfinite(value):
                raise RunnerError(f"{name}: expected a finite number, got {value!r}")
            self._bounds(name, value, "a number")
            return float(value)
        if isinstance(d, str):
            if not isinstance(value, str):
                raise RunnerError(f"{name}: expected a string, got {value!r}")
            if self.choices is not None and value not in self.choices:
                raise RunnerError(f"{name}: expected one of {', '.join(map(repr, self.choices))}, "
                                  f"got {value!r}")
            return value
        if isinstance(d, dict):
            if not isinstance(value, dict):
                raise RunnerError(f"{name}: expected a table (dict), got {value!r}")
            return value
        return value  # None default: anything

    def _range(self):
        lo = f" >= {self.min:g}" if self.min is not None else ""
        hi = f" <= {self.max:g}" if self.max is not None else ""
        return lo + ("," if lo and hi else "") + hi

    def _bounds(self, name, value, what):
        if (self.min is not None and value < self.min) or (self.max is not None and value > self.max):
            raise RunnerError(f"{name}: expected {what}{self._range()}, got {value!r}")


def param_spec(defaults: Mapping, **constraints) -> dict[str, Param]:
    """A parameter spec from a study's defaults: each parameter's type is its default's;
    ``constraints`` add bounds or choices, e.g. ``n_per_level={"min": 1}``."""
    unknown = set(constraints) - set(defaults)
    if unknown:
        raise ValueError(f"constraints: not parameters: {sorted(unknown)}")
    return {k: Param(v, **constraints.get(k, {})) for k, v in defaults.items()}


def validate_params(spec: Mapping[str, Param], params: Mapping) -> dict:
    """``params`` merged over the spec's defaults, every value checked; RunnerError naming the
    first bad or unknown parameter."""
    unknown = sorted(set(params) - set(spec))
    if unknown:
        raise RunnerError(f"params: unknown {', '.join(unknown)}; known: {', '.join(sorted(spec))}")
    out = {}
    for name, p in spec.items():
        out[name] = p.check(name, params[name]) if name in params else p.default
    return out


@dataclass(frozen=True)
class Study:
    """A study: what its scenarios are, how one runs, and how results are summarized.

    Attributes:
        name: command-line name (``"single-triplet"``).
        tasks: ``params -> list[dict]``: one JSON-serializable description per scenario.
        run_task: ``(task, rng) -> list[dict]``: rows of scalars (str, int, float, bool) for one
            scenario. Must be a module-level function (it is pickled to worker processes).
        summarize: ``(outdir, rows, params) -> None``: tables, figures, summary.json, and the
            headline table printed (:func:`print_table`).
        description: one line for ``qfg experiment list``.
        params: the parameter spec (:func:`param_spec`); given, parameters are checked before the
            run (:func:`validate_params`) and ``tasks`` receives them as given.
    """

    name: str
    tasks: Callable[[dict], list]
    run_task: Callable[[dict, np.random.Generator], list]
    summarize: Callable[[Path, list, dict], None] | None = None
    description: str = ""
    params: Mapping[str, Param] | None = None

    def check_params(self, params: Mapping) -> None:
        """RunnerError naming the first bad parameter (nothing without a spec)."""
        if self.params is not None:
            validate_params(self.params, params)
