"""A weighted mixture of priors over the same configurations (:class:`MixturePrior`):
Bayesian model averaging over its components for any solver that takes a prior."""

from __future__ import annotations

import numpy as np

from .._validate import as_rng
from .base import Prior, _points, _sample_args

__all__ = ["MixturePrior"]


class MixturePrior(Prior):
    """A weighted mixture of priors over the same configurations:

        prior(q) = sum_i w_i prior_i(q),   w_i >= 0, sum_i w_i = 1.

    The posterior under it is the posterior under each component weighted by its evidence,
    ``w_i Z_i / sum_j w_j Z_j`` (Bayesian model averaging), so any solver that takes a prior
    averages over the components without computing any evidence. That holds only when every
    component is a normalized density of the configurations (:class:`WorldBoxPrior` with
    ``scale_power=0``, :class:`TrajectoryPrior` over one, :class:`WindowPrior`); a component
    known only up to a constant would carry an arbitrary weight.

    >>> from qfg.priors import TrajectoryPrior, WorldBoxPrior
    >>> box = WorldBoxPrior()
    >>> m = MixturePrior([box, TrajectoryPrior(box)])
    >>> q = np.array([[0.5, 0.5], [2.0, 0.5], [2.1, 0.5]])
    >>> want = np.logaddexp(box.log_density(q), TrajectoryPrior(box).log_density(q)) - np.log(2)
    >>> bool(np.isclose(m.log_density(q), want))
    True
    """

    name = "mixture"

    def __init__(self, components, weights=None):
        comps = list(components)
        if len(comps) < 1 or not all(isinstance(c, Prior) for c in comps):
            raise ValueError(f"components: expected one or more qfg.priors.Prior, got "
                             f"{components!r}")
        w = np.full(len(comps), 1.0 / len(comps)) if weights is None else \
            np.asarray(weights, dtype=float)
        if w.shape != (len(comps),) or not np.all(np.isfinite(w)) or np.any(w < 0) \
                or w.sum() <= 0:
            raise ValueError(f"weights: expected {len(comps)} finite weights >= 0 with a "
                             f"positive sum, got {weights!r}")
        self.components, self.weights = comps, w / w.sum()

    def __repr__(self):
        return f"MixturePrior({self.components!r}, weights={np.round(self.weights, 6).tolist()})"

    def log_density(self, points) -> np.ndarray:
        p = _points(points)
        with np.errstate(divide="ignore"):
            terms = [np.log(w) + np.asarray(c.log_density(p), dtype=float)
                     for c, w in zip(self.components, self.weights, strict=True) if w > 0]
        return np.logaddexp.reduce(np.stack(terms), axis=0)

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        n_cameras, size = _sample_args(n_cameras, size)
        rng = as_rng(seed)
        pick = rng.choice(len(self.components), size=size, p=self.weights)
        out = np.empty((size, n_cameras + 1, 2))
        for i, c in enumerate(self.components):
            rows = np.flatnonzero(pick == i)
            if rows.size:
                out[rows] = c.sample(rng, n_cameras, rows.size)
        return out
