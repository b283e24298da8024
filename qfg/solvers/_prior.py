"""Priors over AB-frame configurations as the solvers use them: the named prior resolved, the
cheap per-point prior of intermediate weights, the exact joint prior of final weights.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians; lengths in |AB|.
"""

from __future__ import annotations

import numpy as np

from .. import priors as _priors

#: Quadrature points in rho of the world prior when the solvers are given its name (the prior
#: object's default is 128): the log density then differs by at most ~0.02 between
#: configurations (``tests/test_solvers.py``), far below the solvers' Monte Carlo error, at a
#: quarter of the cost.
SOLVER_N_RHO = 32


def resolve_prior(prior) -> "_priors.Prior":
    """A :class:`qfg.priors.Prior` from a name or a Prior (ValueError naming ``prior``); the name
    ``"world"`` gives the exact world-box prior with :data:`SOLVER_N_RHO` quadrature points. A
    Prior object is used as given."""
    if isinstance(prior, str) and prior == "world":
        return _priors.WorldBoxPrior(n_rho=SOLVER_N_RHO)
    return _priors.get(prior)


def point_log_prior(prior, points) -> np.ndarray:
    """Per-point log density (..., 2) -> (...) used in the solvers' *intermediate* weights only
    (pruning, resampling, ranking): the cheap product fit for the exact world prior, the prior of
    a single point otherwise. Final weights use ``prior.log_density`` of the whole configuration
    (:func:`log_joint_prior`), so this choice affects efficiency, never the target."""
    pts = np.asarray(points, dtype=float)
    if isinstance(prior, _priors.WorldBoxPrior):
        prior = _PRODUCT
    if isinstance(prior, _priors.ProductPrior):
        dx, dy = pts[..., 0] - prior.CENTRE[0], pts[..., 1] - prior.CENTRE[1]
        s2 = prior.scale**2
        return np.log(s2 / np.pi) - 2.0 * np.log(s2 + (dx * dx + dy * dy))
    if pts.size == 0:
        return np.zeros(pts.shape[:-1])
    return prior.log_density(pts[..., None, :])


_PRODUCT = _priors.ProductPrior()


def log_joint_prior(prior, landmark, cameras) -> np.ndarray:
    """``prior.log_density`` of configurations ``[C, X_1..X_n]``: landmark (..., 2), cameras
    (..., n, 2) -> (...)."""
    L = np.asarray(landmark, dtype=float)
    X = np.asarray(cameras, dtype=float)
    cfg = np.concatenate([L[..., None, :], X], axis=-2)
    if cfg.size == 0:
        return np.zeros(cfg.shape[:-2])
    return prior.log_density(cfg)
