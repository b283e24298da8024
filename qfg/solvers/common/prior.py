"""Priors over AB-frame configurations as the solvers use them: the named prior resolved, the
cheap per-point prior of intermediate weights, the exact joint prior of final weights.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians; lengths in |AB|.
"""

from __future__ import annotations

import numpy as np

from ... import priors as _priors

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
    """Per-point log density (..., 2) -> (...): the prior of one point of the configuration.

    The SIS solvers use it in their *intermediate* weights only (pruning, resampling, ranking;
    their final weights use ``prior.log_density`` of the whole configuration,
    :func:`log_joint_prior`, so there it affects efficiency, never the target); ``fast-paper`` and
    ``baseline`` build their answers from it (a product of per-point priors, their model).

    For a :class:`qfg.priors.WorldBoxPrior` of the simulator's shape (:func:`is_simulator_world`)
    it is the cheap product fit :class:`qfg.priors.ProductPrior` (fitted to that box); for any
    other box the exact one-point marginal ``prior.log_density`` of one point (the marginal up to
    O(d_min^2), :class:`qfg.priors.WorldBoxPrior`), so that the box's parameters are honoured;
    any other prior: its density of a single point.

    >>> from qfg.priors import WorldBoxPrior
    >>> p = np.array([[3.0, 0.5]])          # 3 |AB| across the line AB
    >>> bool(point_log_prior(WorldBoxPrior(width=20.0, height=1.0), p)[0]   # a long thin box
    ...      < point_log_prior(WorldBoxPrior(), p)[0] - 2)
    True
    """
    pts = np.asarray(points, dtype=float)
    if isinstance(prior, _priors.WorldBoxPrior) and is_simulator_world(prior):
        prior = _PRODUCT
    if isinstance(prior, _priors.ProductPrior):
        dx, dy = pts[..., 0] - prior.CENTRE[0], pts[..., 1] - prior.CENTRE[1]
        s2 = prior.scale**2
        return np.log(s2 / np.pi) - 2.0 * np.log(s2 + (dx * dx + dy * dy))
    if pts.size == 0:
        return np.zeros(pts.shape[:-1])
    return prior.log_density(pts[..., None, :])


def is_simulator_world(prior) -> bool:
    """True for a :class:`qfg.priors.WorldBoxPrior` with the simulator's box up to scale (the
    AB-frame prior is scale-free: the same ``width / height`` and ``d_min / width``), the box
    :class:`qfg.priors.ProductPrior` was fitted to."""
    if not isinstance(prior, _priors.WorldBoxPrior) or prior.scale_power:
        return False
    ref = _SIMULATOR_WORLD
    return bool(np.isclose(prior.width / prior.height, ref.width / ref.height, rtol=1e-9)
                and np.isclose(prior.d_min / prior.width, ref.d_min / ref.width, rtol=1e-9,
                               atol=1e-12))


_SIMULATOR_WORLD = _priors.WorldBoxPrior(n_rho=4)
_PRODUCT = _priors.ProductPrior()


def log_joint_prior_draws(prior, landmarks, cameras) -> np.ndarray:
    """:func:`log_joint_prior` of ``[L_jr, X_j]`` for r draws of C per camera trajectory:
    landmarks (J, r, 2), cameras (J, n, 2) -> (J, r). A world-box prior computes each
    trajectory's part once (:meth:`qfg.priors.WorldBoxPrior.log_density_extended`)."""
    L = np.asarray(landmarks, dtype=float)
    X = np.asarray(cameras, dtype=float)
    J, r = L.shape[:2]
    if isinstance(prior, _priors.WorldBoxPrior) and L.size:
        return prior.log_density_extended(X, L)
    return log_joint_prior(prior, L, np.broadcast_to(X[:, None], (J, r) + X.shape[1:]))


def log_joint_prior(prior, landmark, cameras) -> np.ndarray:
    """``prior.log_density`` of configurations ``[C, X_1..X_n]``: landmark (..., 2), cameras
    (..., n, 2) -> (...)."""
    L = np.asarray(landmark, dtype=float)
    X = np.asarray(cameras, dtype=float)
    cfg = np.concatenate([L[..., None, :], X], axis=-2)
    if cfg.size == 0:
        return np.zeros(cfg.shape[:-2])
    return prior.log_density(cfg)
