"""Priors of independent points in the AB frame (|AB| = 1): uniform in a window
(:class:`WindowPrior`, ``"uniform"``) and the heavy-tailed product fit of the world's marginal
(:class:`ProductPrior`, ``"world-product"``, approximate)."""

from __future__ import annotations

import numpy as np

from .._validate import as_float_array, as_rng
from .base import LENGTH_RANGE, Prior, _length, _points, _sample_args

__all__ = ["WindowPrior", "ProductPrior", "DEFAULT_WINDOW", "COORD_LIMIT", "MAX_WINDOW_ASPECT"]

#: Default AB-frame window of :class:`WindowPrior` (the solvers' former ``prior_window``).
DEFAULT_WINDOW = (-6.0, 6.0, -5.5, 6.5)

#: Window coordinates: |v| <= 1e100, so that xmax - xmin is finite (<= 2e100).
COORD_LIMIT = 1e100
#: Window aspect ratio (long side / short side): the baseline solver lays candidates on a grid of
#: about sqrt(n * aspect) by n / that cells, which for a more elongated window has more cells
#: than candidates asked for; an AB-frame window that elongated (|AB| = 1) is not a region the
#: solvers reason in.
MAX_WINDOW_ASPECT = 1e3


class WindowPrior(Prior):
    """Independent points uniform in an AB-frame window ``(xmin, xmax, ymin, ymax)``.

    ``log_density = -k log(area)`` inside (every point in the window), -inf outside.

    >>> p = WindowPrior((-1.0, 1.0, 0.0, 2.0))
    >>> p.log_density([[[0.0, 0.5]], [[3.0, 0.5]]]).tolist() == [-np.log(4.0), -np.inf]
    True
    """

    name = "uniform"

    def __init__(self, window=DEFAULT_WINDOW):
        w = tuple(float(v) for v in as_float_array("window", window).ravel())
        if len(w) != 4 or not (w[0] < w[1] and w[2] < w[3]):
            raise ValueError(f"window: expected (xmin, xmax, ymin, ymax) with xmin < xmax and "
                             f"ymin < ymax, got {window!r}")
        if max(abs(v) for v in w) > COORD_LIMIT:
            raise ValueError(f"window: expected coordinates within ±{COORD_LIMIT:g} (the sides "
                             f"must be finite), got {window!r}")
        sides = (w[1] - w[0], w[3] - w[2])
        lo = LENGTH_RANGE[0]
        if min(sides) < lo:
            raise ValueError(f"window: expected sides >= {lo:g} (the area must stay a non-zero "
                             f"float), got sides {sides[0]:g} x {sides[1]:g}")
        if max(sides) / min(sides) > MAX_WINDOW_ASPECT:
            raise ValueError(f"window: expected an aspect ratio (long side / short side) <= "
                             f"{MAX_WINDOW_ASPECT:g}, got sides {sides[0]:g} x {sides[1]:g}")
        self.window = w
        self.area = (w[1] - w[0]) * (w[3] - w[2])

    def __repr__(self):
        return f"WindowPrior(window={self.window})"

    def log_density(self, points) -> np.ndarray:
        p = _points(points)
        xmin, xmax, ymin, ymax = self.window
        inside = np.all((p[..., 0] >= xmin) & (p[..., 0] <= xmax) & (p[..., 1] >= ymin)
                        & (p[..., 1] <= ymax), axis=-1)
        return np.where(inside, -p.shape[-2] * np.log(self.area), -np.inf)

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        n_cameras, size = _sample_args(n_cameras, size)
        xmin, xmax, ymin, ymax = self.window
        return as_rng(seed).uniform((xmin, ymin), (xmax, ymax), size=(size, n_cameras + 1, 2))


class ProductPrior(Prior):
    """APPROXIMATE world prior: independent points, each with the heavy-tailed density

        p(P) = (s^2 / π) (s^2 + |P - (0, 1/2)|^2)^-2,  i.e.  P(|P - (0, 1/2)| <= R) = R^2 / (s^2 + R^2),

    fitted (s = 0.85) to the AB-frame marginal of one uniformly placed object. The exact joint
    (:class:`WorldBoxPrior`) couples the points through AB's unknown scale and rotation; this
    product ignores that and is kept only to reproduce earlier results.

    >>> p = ProductPrior()
    >>> bool(np.isclose(p.log_density([[[0.0, 0.5]]])[()], np.log(1 / (np.pi * 0.85**2))))
    True
    """

    name = "world-product"
    CENTRE = np.array([0.0, 0.5])

    def __init__(self, scale: float = 0.85):
        self.scale = _length("scale", scale)

    def __repr__(self):
        return f"ProductPrior(scale={self.scale:g})"

    def log_density(self, points) -> np.ndarray:
        p = _points(points)
        d = p - self.CENTRE
        s2 = self.scale ** 2
        return np.sum(np.log(s2 / np.pi) - 2.0 * np.log(s2 + np.sum(d * d, axis=-1)), axis=-1)

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        n_cameras, size = _sample_args(n_cameras, size)
        rng = as_rng(seed)
        u = rng.random((size, n_cameras + 1))
        r = self.scale * np.sqrt(u / (1.0 - u))          # inverse of R^2 / (s^2 + R^2)
        th = rng.uniform(-np.pi, np.pi, size=u.shape)
        return self.CENTRE + np.stack([r * np.cos(th), r * np.sin(th)], axis=-1)
