"""Argument checks shared by every public function.

Each check raises ``ValueError`` whose message names the argument and what is wrong, so that bad
input never turns into a NaN or a traceback from deep inside numpy, shapely or gtsam.
"""

from __future__ import annotations

import numpy as np


def as_float_array(name: str, value, *, last_dim: int | None = None, ndim: int | None = None,
                   min_ndim: int = 0) -> np.ndarray:
    """Return ``value`` as a finite float64 array, checking its shape.

    ``last_dim``: required size of the last axis; ``ndim``: required number of axes;
    ``min_ndim``: least number of axes.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected numbers, got {type(value).__name__} ({exc})") from None
    if ndim is not None and arr.ndim != ndim:
        raise ValueError(f"{name}: expected {ndim} axes, got shape {arr.shape}")
    if arr.ndim < min_ndim:
        raise ValueError(f"{name}: expected at least {min_ndim} axes, got shape {arr.shape}")
    if last_dim is not None and (arr.ndim == 0 or arr.shape[-1] != last_dim):
        raise ValueError(f"{name}: expected last axis of size {last_dim}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise ValueError(f"{name}: {bad} non-finite value(s) (NaN or inf)")
    return arr


def non_negative(name: str, value) -> float:
    """Return ``value`` as a finite float that is >= 0."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(v) or v < 0:
        raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")
    return v


def per_step_sigma(name: str, value, n_steps: int):
    """A noise sigma that is one number (a float >= 0) or one per step of a history: (n_steps,)
    finite values, every one > 0 or every one 0 (a noiseless step among noisy ones is not a
    model the solvers take), returned as an array. ValueError naming ``name`` otherwise.

    >>> per_step_sigma("sigma_heading", 0.1, 2), per_step_sigma("sigma_heading", [0.1, 0.2], 2)
    (0.1, array([0.1, 0.2]))
    """
    if np.ndim(value) == 0:
        return non_negative(name, value)
    arr = as_float_array(name, value, ndim=1)
    if arr.shape[0] != n_steps:
        raise ValueError(f"{name}: expected one number or {n_steps} (one per step between "
                         f"{n_steps + 1} views), got shape {arr.shape}")
    if np.any(arr < 0):
        raise ValueError(f"{name}: expected values >= 0, got {arr.min()!r}")
    if arr.size and np.any(arr == 0) and np.any(arr > 0):
        raise ValueError(f"{name}: expected every step's sigma > 0 or every one 0, got "
                         f"{arr.tolist()}")
    return arr


def positive_int(name: str, value, *, minimum: int = 1) -> int:
    """Return ``value`` as an int that is >= ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name}: expected an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value}")
    return int(value)


def _check_seed(seed):
    if isinstance(seed, (np.random.Generator, np.random.SeedSequence)) or seed is None:
        return seed
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: expected an int >= 0, a numpy SeedSequence, a numpy Generator or "
                         f"None, got {seed!r}")
    return int(seed)


def as_rng(seed) -> np.random.Generator:
    """The project's one seed rule (docs/conventions.md): ``seed`` is an int >= 0, a numpy
    ``SeedSequence``, a numpy ``Generator`` (used as it is: draws advance the caller's stream) or
    None (fresh entropy). Returns a ``numpy.random.Generator``.

    >>> bool(as_rng(3).random() == np.random.default_rng(3).random())
    True
    """
    seed = _check_seed(seed)
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


def as_seed_sequence(seed) -> np.random.SeedSequence:
    """The same rule as :func:`as_rng`, for code that spawns independent streams: an int or None
    becomes ``SeedSequence(seed)``; a Generator gives one draw (advancing it) as the entropy."""
    seed = _check_seed(seed)
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if isinstance(seed, np.random.Generator):
        return np.random.SeedSequence(int(seed.integers(0, 2**63)))
    return np.random.SeedSequence(seed)
