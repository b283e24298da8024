"""Measurements simulated from a prior (:func:`sample_measurements`): configurations drawn
from the prior and the solvers' bearings and headings made from them, for calibration checks."""

from __future__ import annotations

import numpy as np

from .._validate import as_rng, non_negative, positive_int
from .names import get

__all__ = ["sample_measurements"]


def sample_measurements(prior, seed, n_views: int, sigma_bearing: float, sigma_heading: float,
                        size: int):
    """Configurations drawn from ``prior`` and measurements made from them by the solvers' model
    (calibration checks: a correct posterior is calibrated on these).

    Configurations ``[C, X_1..X_n]`` from ``prior.sample``, headings uniform, bearings
    ``phi_{j,L} = wrap(f(L, X_j, alpha_j) + sigma_bearing N(0, 1))`` for L in (A, B, C), headings
    ``psi_j = wrap(g(X_j, alpha_j, X_{j+1}) + sigma_heading N(0, 1))``.

    Returns ``(bearings (size, n, 3), headings (size, n - 1), configs (size, n + 1, 2),
    alphas (size, n))``; radians, AB frame.

    >>> b, h, x, a = sample_measurements("world", np.random.default_rng(0), 3, 0.01, 0.02, 5)
    >>> b.shape, h.shape, x.shape, a.shape
    ((5, 3, 3), (5, 2), (5, 4, 2), (5, 3))
    """
    from ..geometry import bearing, motion_heading, wrap_angle

    pr = get(prior)
    rng = as_rng(seed)
    n = positive_int("n_views", n_views)
    size = positive_int("size", size)
    sb = non_negative("sigma_bearing", sigma_bearing)
    sh = non_negative("sigma_heading", sigma_heading)
    conf = pr.sample(rng, n, size)
    alpha = rng.uniform(-np.pi, np.pi, size=(size, n))
    poses = np.concatenate([conf[:, 1:], alpha[..., None]], axis=-1)          # (size, n, 3)
    L = np.concatenate([np.zeros((size, 1, 2)), np.tile([[[0.0, 1.0]]], (size, 1, 1)),
                        conf[:, :1]], axis=1)                                  # (size, 3, 2)
    phi = bearing(poses[:, :, None, :], L[:, None, :, :])
    phi = wrap_angle(phi + sb * rng.standard_normal(phi.shape))
    psi = motion_heading(poses[:, :-1], poses[:, 1:, :2])
    psi = wrap_angle(psi + sh * rng.standard_normal(psi.shape))
    return phi, psi, conf, alpha
