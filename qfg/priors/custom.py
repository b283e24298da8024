"""A user's own prior from callables (:class:`CallablePrior`): a log density over AB-frame
configurations (..., k, 2) -> (...,) and optionally a sampler."""

from __future__ import annotations

import numpy as np

from .._validate import as_float_array, as_rng
from .base import Prior, _points, _sample_args

__all__ = ["CallablePrior"]


class CallablePrior(Prior):
    """A user's prior: ``log_density_fn(points (..., k, 2)) -> (...,)`` and optionally
    ``sample_fn(rng, n_cameras, size) -> (size, 1 + n_cameras, 2)`` (``rng`` a numpy Generator).

    The log density may be unnormalized by a constant that depends only on k. Solvers need only
    ``log_density``; ``sample`` (calibration checks, baselines drawing from the prior) raises a
    ValueError naming ``sample_fn`` when none was given.

    >>> gauss = CallablePrior(lambda x: -0.5 * np.sum(x**2, axis=(-2, -1)), name="gauss")
    >>> float(gauss.log_density([[0.0, 1.0], [1.0, 1.0]]))
    -1.5
    """

    def __init__(self, log_density_fn, sample_fn=None, name: str = "custom"):
        if not callable(log_density_fn):
            raise ValueError(f"log_density_fn: expected a callable, got {log_density_fn!r}")
        if sample_fn is not None and not callable(sample_fn):
            raise ValueError(f"sample_fn: expected a callable or None, got {sample_fn!r}")
        self._ld, self._sample, self.name = log_density_fn, sample_fn, str(name)

    def log_density(self, points) -> np.ndarray:
        p = _points(points)
        out = np.asarray(self._ld(p), dtype=float)
        if out.shape != p.shape[:-2]:
            raise ValueError(f"log_density_fn: returned shape {out.shape}, expected {p.shape[:-2]}")
        if np.any(np.isnan(out)) or np.any(out == np.inf):
            raise ValueError("log_density_fn: returned NaN or +inf")
        return out

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        n_cameras, size = _sample_args(n_cameras, size)
        if self._sample is None:
            raise ValueError(f"sample_fn: prior {self.name!r} was built without a sampler")
        out = as_float_array("sample_fn", self._sample(as_rng(seed), n_cameras, size))
        if out.shape != (size, n_cameras + 1, 2):
            raise ValueError(f"sample_fn: returned shape {out.shape}, expected "
                             f"{(size, n_cameras + 1, 2)}")
        return out
