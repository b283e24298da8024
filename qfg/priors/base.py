"""The base class of every prior (:class:`Prior`) and the argument checks the priors share:
AB-frame configurations ``[C, X_1, ..., X_n]`` as (..., k, 2) arrays, lengths in |AB| units
checked against :data:`LENGTH_RANGE`."""

from __future__ import annotations

import numpy as np

from .._validate import as_float_array, non_negative, positive_int

__all__ = ["Prior", "LENGTH_RANGE"]

# Accepted parameter ranges, checked at construction so that no solver meets an overflow later.
#: Lengths (box sides, the product prior's scale, window sides): squares and products of two of
#: them (W H, s^2, window areas) must be finite, non-zero normal floats with room left for sums
#: (s^2 + |P|^2) and powers taken in log space: 1e-100 <= length <= 1e100 keeps every such
#: product within [1e-200, 1e200] (float64 spans [2.2e-308, 1.8e308]).
LENGTH_RANGE = (1e-100, 1e100)


def _length(name: str, value, lo: float = LENGTH_RANGE[0]) -> float:
    """``value`` as a float in [lo, LENGTH_RANGE[1]], or a ValueError naming ``name`` and the
    range."""
    v = non_negative(name, value)
    hi = LENGTH_RANGE[1]
    if not lo <= v <= hi:
        raise ValueError(f"{name}: expected a length in [{lo:g}, {hi:g}] (products of lengths "
                         f"must stay finite and non-zero, points distinguishable), got {value!r}")
    return v


def _points(points) -> np.ndarray:
    p = as_float_array("points", points, min_ndim=2, last_dim=2)
    if p.shape[-2] < 1:
        raise ValueError(f"points: expected at least one point (shape (..., k, 2), k >= 1), "
                         f"got shape {p.shape}")
    return p


def _sample_args(n_cameras, size):
    return positive_int("n_cameras", n_cameras, minimum=0), positive_int("size", size, minimum=0)


class Prior:
    """Base class: a prior over AB-frame configurations ``[C, X_1, ..., X_n]``.

    Subclasses implement:

    * ``log_density(points)``: points (..., k, 2), k = n + 1 >= 1, AB-frame positions in the order
      [C, X_1, ..., X_n]; returns (...,) the log density up to an additive constant that depends
      only on k. Finite wherever the density is positive; -inf only where it is truly 0.
    * ``sample(seed, n_cameras, size)``: (size, 1 + n_cameras, 2) configurations drawn exactly from
      the prior.
    """

    name: str = "prior"

    def log_density(self, points) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def __repr__(self):
        return f"{type(self).__name__}(name={self.name!r})"
