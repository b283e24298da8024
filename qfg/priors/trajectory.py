"""One robot's cameras as a path (:class:`TrajectoryPrior`): a first prior places C and the
first cameras, every later camera is one scale-free step (log-uniform length in |AB| units) from
the one before it."""

from __future__ import annotations

import numpy as np

from .._validate import as_rng, positive_int
from .base import Prior, _points, _sample_args

__all__ = ["TrajectoryPrior"]


class TrajectoryPrior(Prior):
    """One robot's cameras: ``first`` places C and the first ``n_first`` cameras, and every
    later camera is one step from the camera before it, in a uniform direction, its length
    ``b`` (|AB| units) log-uniform on ``steps = (lo, hi)``:

        prior(q_1..q_k) = first(q_1..q_(1+n_first)) prod_(j > n_first) 1[lo <= b_j <= hi] /
                          (2 π b_j^2 log(hi / lo)),   b_j = |X_j - X_(j-1)|.

    A box prior (:class:`WorldBoxPrior`) makes every camera an independent point of the box, so
    for k cameras on a path of one shape, the first fixed, the density of the path's scale λ
    grows as λ^(2k - 3) (the later cameras' area element) until the path nears the box's size:
    the more views, the longer it expects the robot's path, however short it was. Scale-free
    steps add views without that pull; the odometry's ratios and headings (the solvers'
    likelihood) give the path its shape. With ``first`` a :class:`TravelPrior`
    (``n_first=2``: its step 0 joins the box with the first step's metres) the path has a
    scale too.

    >>> from qfg.priors import WorldBoxPrior
    >>> box = WorldBoxPrior(width=6.0, height=11.0)
    >>> p = TrajectoryPrior(box)
    >>> q = np.array([[0.5, 0.5], [2.0, 0.5], [2.0, 0.6], [2.0, 0.8]])  # C, X_1, X_2, X_3
    >>> step = -np.log(2 * np.pi * np.log(1e6))                # each step's normalizer
    >>> want = box.log_density(q[:2]) + step - 2 * np.log(0.1) + step - 2 * np.log(0.2)
    >>> bool(np.isclose(p.log_density(q), want))
    True
    """

    name = "trajectory"

    def __init__(self, first: Prior, *, n_first: int = 1, steps: tuple = (1e-4, 1e2)):
        if not isinstance(first, Prior):
            raise ValueError(f"first: expected a qfg.priors.Prior, got {first!r}")
        self.first = first
        self.n_first = positive_int("n_first", n_first, minimum=0)
        try:
            lo, hi = (float(x) for x in steps)
        except (TypeError, ValueError):
            raise ValueError(f"steps: expected (lo, hi) in |AB| units, got {steps!r}") from None
        if not (np.isfinite([lo, hi]).all() and 0 < lo < hi):
            raise ValueError(f"steps: expected 0 < lo < hi (|AB| units), got {steps!r}")
        self.steps = (lo, hi)
        self._c = -np.log(2.0 * np.pi * np.log(hi / lo))

    def __repr__(self):
        return f"TrajectoryPrior({self.first!r}, n_first={self.n_first}, steps={self.steps})"

    def log_density(self, points) -> np.ndarray:
        p = _points(points)
        m = 1 + min(p.shape[-2] - 1, self.n_first)
        out = np.asarray(self.first.log_density(p[..., :m, :]), dtype=float)
        if p.shape[-2] > m:
            v = np.diff(p[..., m - 1:, :], axis=-2)
            b2 = np.sum(v * v, axis=-1)
            lo, hi = self.steps
            with np.errstate(divide="ignore"):
                lp = np.where((b2 >= lo * lo) & (b2 <= hi * hi), self._c - np.log(b2), -np.inf)
            out = out + lp.sum(axis=-1)
        return out

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        n_cameras, size = _sample_args(n_cameras, size)
        rng = as_rng(seed)
        m = min(n_cameras, self.n_first)
        head = np.asarray(self.first.sample(rng, m, size), dtype=float)
        n = n_cameras - m
        lo, hi = self.steps
        b = np.exp(rng.uniform(np.log(lo), np.log(hi), (size, n)))
        th = rng.uniform(-np.pi, np.pi, (size, n))
        walk = head[:, -1:, :] + np.cumsum(b[..., None] * np.stack([np.cos(th), np.sin(th)],
                                                                   axis=-1), axis=1)
        return np.concatenate([head, walk], axis=1)
