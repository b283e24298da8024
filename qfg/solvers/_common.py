"""Pieces shared by the single-triplet solvers: the result type, input checks, random streams,
likelihood kernels, priors, locus sampling and the weighted state histograms.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians; lengths in |AB|.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import partitions as _partitions
from .. import priors as _priors
from .._validate import as_float_array, non_negative, positive_int
from ..geometry import LOCUS_EPS, heading_on_locus, locus_point, wrap_angle

#: Methods :func:`qfg.solvers.solve_triplet` knows.
METHODS = ("full", "fast", "fast-paper", "baseline", "reference")

#: Prior names the solvers accept (besides any :class:`qfg.priors.Prior` object): see
#: :func:`qfg.priors.get`. ``"world"`` (default) is the exact prior of the simulator's world.
PRIORS = _priors.NAMES

#: Triangulation used in the resection step.
RESECTIONS = ("centroid", "lsq")

_NEG_INF = -np.inf


# ---------------------------------------------------------------------------------------------
# result type


@dataclass(frozen=True, eq=False, repr=False)
class TripletEstimate:
    """Qualitative estimate of one triplet AB:C from its history: the answer only (a few KB).

    Attributes:
        landmark: (m,) P(S^{AB:C} = s | H), sums to 1.
        cameras: (n, m) P(S^{AB:X}_i = s | H) for every view i, each row sums to 1.
        n_hypotheses: number of weighted hypotheses behind the estimate (trajectory hypotheses
            for ``full``/``fast``, landmark candidates with non-zero weight for ``baseline``).
        ess: effective sample size of the landmark weights, ``1 / sum w^2`` (normalized w).
        mc_error: Monte Carlo standard error of ``landmark`` where the method estimates it
            (largest over states), else NaN.
        degenerate: True when the input was degenerate or nothing survived; the distributions are
            then as spread as the geometry allows, uniform wherever nothing is known (never NaN).
        reason: why ``degenerate`` is set ("" otherwise).
        method: the model actually solved (``"full"``, ``"fast"``, ``"baseline"``, ...).
        partition: partition name the states refer to.
        n_views: number of views n.
        prior: name of the prior over AB-frame configurations.
        options: the solver options used (defaults filled in; the prior by name).

    The weighted hypotheses behind an estimate (for figures) are kept by the solver object,
    :meth:`qfg.solvers.TripletSolver.hypotheses`, not here.

    >>> import numpy as np
    >>> from qfg.simulation import random_triplet_history
    >>> from qfg.solvers import solve_triplet
    >>> h = random_triplet_history(np.random.default_rng(0), n_views=3)
    >>> est = solve_triplet(h, method="fast")
    >>> est.landmark.shape, est.cameras.shape, bool(np.isclose(est.landmark.sum(), 1.0))
    ((20,), (3, 20), True)
    """

    landmark: np.ndarray
    cameras: np.ndarray
    n_hypotheses: int
    degenerate: bool
    reason: str
    method: str
    partition: str
    n_views: int
    ess: float = float("nan")
    mc_error: float = float("nan")
    prior: str = ""
    options: dict = field(default_factory=dict)

    @property
    def most_likely(self) -> tuple[int, float]:
        """(0-based state, probability) of the most probable landmark state."""
        s = int(np.argmax(self.landmark))
        return s, float(self.landmark[s])

    def __repr__(self) -> str:
        s, p = self.most_likely
        flag = f", degenerate: {self.reason}" if self.degenerate else ""
        return (f"TripletEstimate(method={self.method!r}, partition={self.partition!r}, "
                f"n_views={self.n_views}, prior={self.prior!r}, most_likely=({s}, {p:.3f}), "
                f"n_hypotheses={self.n_hypotheses}, ess={self.ess:.1f}{flag})")

    def add_view(self, bearings, heading=None):
        """Not here: an estimate holds only the answer. Raises ValueError naming the
        replacement, :class:`qfg.solvers.TripletSolver`."""
        raise ValueError(ADD_VIEW_MOVED)


#: Message of the former estimate-based incremental API.
ADD_VIEW_MOVED = ("estimate: a TripletEstimate holds only the answer and cannot be updated; solve "
                  "incrementally with qfg.solvers.TripletSolver(method=..., sigma_bearing=..., "
                  "sigma_heading=..., seed=...).add_view(bearings, heading) and .estimate()")


@dataclass(frozen=True, eq=False, repr=False)
class Hypotheses:
    """The weighted hypotheses behind an estimate (for figures and diagnostics).

    Attributes:
        landmark_samples: (J, 2) AB-frame positions of C behind ``landmark``.
        landmark_weights: (J,) normalized weights (sum 1, or all 0 when J = 0).
        camera_samples: (n, K, 3) AB-frame camera poses (x, y, alpha).
        camera_weights: (n, K) their normalized weights per view.
        joint: True when hypothesis j is the trajectory ``camera_samples[:, j]`` with landmark
            ``landmark_samples[j]``.
    """

    landmark_samples: np.ndarray
    landmark_weights: np.ndarray
    camera_samples: np.ndarray
    camera_weights: np.ndarray
    joint: bool

    def __repr__(self) -> str:
        return (f"Hypotheses(landmark_samples={self.landmark_samples.shape}, "
                f"camera_samples={self.camera_samples.shape}, joint={self.joint})")


class TripletBatchSizes:
    """Sizes of a solver state holding ``bearings`` (T, i, 3): T triplets after i views."""

    @property
    def n_triplets(self) -> int:
        return self.bearings.shape[0]

    @property
    def n_views(self) -> int:
        return self.bearings.shape[1]


def ess(weights) -> float:
    """Effective sample size ``1 / sum w^2`` of normalized weights (0 when all are 0)."""
    w = np.asarray(weights, dtype=float)
    s2 = float(np.sum(w * w))
    return 1.0 / s2 if s2 > 0 else 0.0


# ---------------------------------------------------------------------------------------------
# options


#: Documented defaults (chosen by measurement: docs/solvers.md). Angles in radians.
DEFAULTS = {
    "full": {
        "n_samples": 600,            # first-view camera samples per triplet (x motion_samples
                                     # when both sigmas are 0)
        "motion_samples": 8,         # noise draws per hypothesis and view (motion step)
        "motion_spread": 1.0,        # noise drawn this many times wider (weights corrected)
        "max_hypotheses": 3000,      # cap after pruning (systematic resampling down to it)
        "prune_ratio": 1e-6,         # drop hypotheses lighter than this x the heaviest
        "landmark_samples": 4,       # C samples per trajectory (intermediate and final weights)
        "ray_fraction": 0.25,        # share of C samples drawn along a line of sight
        "posterior_samples": 512,    # trajectories resampled for the exact-prior final weights
        "one_view_samples": 16,      # C samples per trajectory with a single view
        "bearing_floor": np.deg2rad(0.05),
        "move_steps": 0,             # Metropolis-Hastings moves per hypothesis after resampling
                                     # (resample-move; measured not to help: docs/solvers.md)
        "mc_shrinkage": 1.0,         # pseudo-draws of the uniform added to the ESS draws
                                     # (shrink_to_uniform)
        "prior": "world",
    },
    "fast": {
        "n_samples": 64,
        "motion_samples": 4,
        "motion_spread": 1.0,
        "max_hypotheses": 256,
        "prune_ratio": 1e-6,
        "landmark_samples": 2,
        "ray_fraction": 0.5,
        "posterior_samples": 32,
        "one_view_samples": 8,
        "bearing_floor": np.deg2rad(0.5),   # wider than full's: with its small budget the
                                            # noiseless posterior's narrow peaks are missed
        "move_steps": 0,
        "mc_shrinkage": 1.0,
        "prior": "world",
    },
    "fast-paper": {
        "n_samples": 128,            # camera positions on the first view's arc (coarse grid)
        "refine_levels": 1,          # adaptive refinement of the first camera's arc parameter:
        "refine_cells": 16,          #   the heaviest cells, split into
        "refine_factor": 8,          #   this many sub-cells, this many times
        "jacobian": True,            # weight positions by the motion step's change of variables
        "kernel": "bearing",         # C-bearing likelihood width: "bearing" = sigma_v,
                                     # "combined" = hypot(sigma_v, sigma_w)
        "max_hypotheses": 8192,
        "bearing_floor": np.deg2rad(0.05),
        "one_view_samples": 16,
        "resection": "lsq",
        "landmark_volume": False,
        "prior": "world",
    },
    "baseline": {
        "n_landmark_samples": 4096,  # C candidates drawn from the prior (stratified)
        "noise_samples": 16,         # measurement-noise draws per view (1 when sigma = 0)
        "jacobian_cap": 30.0,        # cap on 1/|det J| relative to the median candidate
        "prior": "world",
    },
}


def resolve_options(method: str, options: dict, defaults: dict | None = None) -> dict:
    """Defaults of ``method`` (or ``defaults``, e.g. the reference solver's) updated with
    ``options``; unknown or bad options raise ValueError."""
    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    opts = dict(DEFAULTS[method] if defaults is None else defaults)
    unknown = sorted(set(options) - set(opts))
    if unknown:
        raise ValueError(f"{unknown[0]}: not an option of method {method!r}; "
                         f"known: {', '.join(sorted(opts))}")
    opts.update(options)
    if "motion" in opts and opts["motion"] not in ("sample", "match"):
        raise ValueError(f"motion: expected 'sample' or 'match', got {opts['motion']!r}")
    for k in ("n_samples", "max_hypotheses", "one_view_samples", "n_landmark_samples",
              "motion_samples", "noise_samples", "refine_cells", "refine_factor",
              "posterior_samples", "landmark_samples"):
        if k in opts:
            opts[k] = positive_int(k, opts[k])
    if "move_steps" in opts:
        opts["move_steps"] = positive_int("move_steps", opts["move_steps"], minimum=0)
    if "refine_levels" in opts:
        opts["refine_levels"] = positive_int("refine_levels", opts["refine_levels"], minimum=0)
    if "motion_spread" in opts:
        ms = non_negative("motion_spread", opts["motion_spread"])
        if ms < 1:
            raise ValueError(f"motion_spread: expected a number >= 1, got {ms}")
        opts["motion_spread"] = ms
    for k in ("bearing_floor", "heading_floor", "match_sigmas", "jacobian_cap", "mc_shrinkage"):
        if k in opts:
            opts[k] = non_negative(k, opts[k])
            if k in ("match_sigmas", "jacobian_cap") and opts[k] == 0:
                raise ValueError(f"{k}: expected a number > 0, got 0")
    for k in ("jacobian", "landmark_volume"):
        if k in opts and not isinstance(opts[k], (bool, np.bool_)):
            raise ValueError(f"{k}: expected True or False, got {opts[k]!r}")
    if "prune_ratio" in opts:
        pr = non_negative("prune_ratio", opts["prune_ratio"])
        if pr >= 1:
            raise ValueError(f"prune_ratio: expected a number in [0, 1), got {pr}")
        opts["prune_ratio"] = pr
    if opts.get("kernel", "bearing") not in ("bearing", "combined"):
        raise ValueError(f"kernel: expected 'bearing' or 'combined', got {opts['kernel']!r}")
    if opts.get("resection", "centroid") not in RESECTIONS:
        raise ValueError(f"resection: expected one of {RESECTIONS}, got {opts['resection']!r}")
    opts["prior"] = resolve_prior(opts["prior"])
    if "ray_fraction" in opts:
        rf = non_negative("ray_fraction", opts["ray_fraction"])
        if rf > 1:
            raise ValueError(f"ray_fraction: expected a number in [0, 1], got {rf}")
        opts["ray_fraction"] = rf
    return opts


def effective_sigma(sigma, floor):
    """Likelihood width actually used: ``max(sigma, floor)`` (so that zero noise still works)."""
    return np.maximum(np.asarray(sigma, dtype=float), floor)


# ---------------------------------------------------------------------------------------------
# input


@dataclass(frozen=True)
class Measurements:
    """Validated measurements of one triplet: bearings (n, 3), headings (n - 1,) or None, and
    the odometry's travelled distances (n - 1,) (0 = unknown) with the noise of their log
    ratios, or None (used by the SIS methods only)."""

    bearings: np.ndarray
    headings: np.ndarray | None
    sigma_bearing: float
    sigma_heading: float
    distances: np.ndarray | None = None
    sigma_distance_ratio: float | None = None

    @property
    def n_views(self) -> int:
        return self.bearings.shape[0]


def check_bearings(bearings) -> np.ndarray:
    b = as_float_array("bearings", bearings, last_dim=3)
    if b.ndim == 1:
        b = b[None, :]
    if b.ndim != 2 or b.shape[0] < 1:
        raise ValueError(f"bearings: expected shape (n, 3) with n >= 1, got {b.shape}")
    return wrap_angle(b)


def check_headings(headings, n_views: int) -> np.ndarray | None:
    if headings is None:
        return None
    h = as_float_array("headings", headings)
    h = np.atleast_1d(h)
    if h.ndim != 1 or h.shape[0] != n_views - 1:
        raise ValueError(f"headings: expected {n_views - 1} value(s) for {n_views} view(s) "
                         f"(shape ({n_views - 1},)), got shape {h.shape}")
    return wrap_angle(h)


#: Largest noise sigma used (radians). A wrapped normal with sigma >= 10 rad is uniform on the
#: circle to within ``2 exp(-50)``, so larger sigmas are the same model; capping them keeps the
#: solvers' arithmetic finite (sigma^2 and its inverse) for any finite input up to 1e308.
SIGMA_CAP = 10.0


def check_sigma(name: str, value) -> float:
    """A noise sigma (radians): a finite number >= 0 (ValueError naming ``name`` otherwise),
    capped at :data:`SIGMA_CAP`.

    >>> check_sigma("sigma_bearing", 1e300), check_sigma("sigma_bearing", 0.02)
    (10.0, 0.02)
    """
    return min(non_negative(name, value), SIGMA_CAP)


def check_heading(heading) -> float:
    """One heading psi (radians, a finite scalar) for an incremental view, wrapped to (-pi, pi];
    ValueError naming ``heading`` otherwise (the checks of :func:`check_headings`)."""
    h = as_float_array("heading", heading)
    if h.ndim != 0:
        raise ValueError(f"heading: expected one number (radians), got shape {h.shape}")
    return float(wrap_angle(h))


def check_distances(distances, n_views: int) -> np.ndarray | None:
    """Travelled distances (n - 1,) between consecutive views: finite, >= 0 (ValueError naming
    ``distances`` otherwise); None stays None.

    >>> check_distances([0.3, 0.0], 3).tolist()
    [0.3, 0.0]
    """
    if distances is None:
        return None
    d = np.atleast_1d(as_float_array("distances", distances))
    if d.ndim != 1 or d.shape[0] != n_views - 1:
        raise ValueError(f"distances: expected {n_views - 1} value(s) for {n_views} view(s) "
                         f"(shape ({n_views - 1},)), got shape {d.shape}")
    if np.any(d < 0):
        raise ValueError(f"distances: expected values >= 0, got {d.min()!r}")
    return d


def check_distance(distance) -> float:
    """One travelled distance for an incremental view: a finite number >= 0 (ValueError naming
    ``distance`` otherwise)."""
    d = as_float_array("distance", distance)
    if d.ndim != 0:
        raise ValueError(f"distance: expected one number, got shape {d.shape}")
    return non_negative("distance", d)


#: Least width of the step-length-ratio factor (noise of log(d_i / d_(i-1))): with
#: ``sigma_distance_ratio = 0`` the ratio is matched to within about 1 %, like ``bearing_floor``.
DISTANCE_RATIO_FLOOR = 0.01


def check_distance_sigma(value, distances) -> float | None:
    """``sigma_distance_ratio`` for ``distances``: required (finite, >= 0, capped at
    :data:`SIGMA_CAP`) when there are distances; None without them."""
    if distances is None:
        return None if value is None else check_sigma("sigma_distance_ratio", value)
    if value is None:
        raise ValueError("sigma_distance_ratio: required when distances are given (noise of "
                         "the log ratio of consecutive distances)")
    return check_sigma("sigma_distance_ratio", value)


def measurements(bearings, headings, sigma_bearing, sigma_heading, distances=None,
                 sigma_distance_ratio=None) -> Measurements:
    """Validate one triplet's input. ``bearings`` may be a TripletHistory (then ``headings``,
    ``distances`` and unset sigmas come from it)."""
    from ..simulation import TripletHistory

    if isinstance(bearings, TripletHistory):
        hist = bearings
        if headings is not None:
            raise ValueError("headings: pass either a TripletHistory or bearings and headings, "
                             "not both")
        if distances is not None:
            raise ValueError("distances: pass either a TripletHistory or bearings and "
                             "distances, not both")
        b = check_bearings(hist.bearings)
        h = check_headings(hist.headings, b.shape[0]) if hist.has_motion else None
        sb = hist.sigma_bearing if sigma_bearing is None else sigma_bearing
        sh = hist.sigma_heading if sigma_heading is None else sigma_heading
        distances = getattr(hist, "distances", None) if hist.has_motion else None
        if sigma_distance_ratio is None:
            sigma_distance_ratio = getattr(hist, "sigma_distance_ratio", None)
    else:
        b = check_bearings(bearings)
        h = check_headings(headings, b.shape[0])
        if sigma_bearing is None:
            raise ValueError("sigma_bearing: required (radians) unless a TripletHistory is given")
        if sigma_heading is None:
            if h is not None and h.size:
                raise ValueError("sigma_heading: required (radians) when headings are given")
            sigma_heading = 0.0
        sb, sh = sigma_bearing, sigma_heading
    d = check_distances(distances, b.shape[0])
    return Measurements(bearings=b, headings=h, sigma_bearing=check_sigma("sigma_bearing", sb),
                        sigma_heading=check_sigma("sigma_heading", sh), distances=d,
                        sigma_distance_ratio=check_distance_sigma(sigma_distance_ratio, d))


def get_partition(partition):
    return _partitions.get(partition)


# ---------------------------------------------------------------------------------------------
# random streams: one per (view, purpose), so that adding a view draws exactly what a batch solve
# of all views draws for it.

#: spawn-key purposes
STREAM_CAMERAS, STREAM_RESAMPLE, STREAM_LANDMARKS, STREAM_POSTERIOR, STREAM_RETRY = 0, 1, 3, 4, 5
STREAM_MOVE = 6


def root_seed(seed) -> np.random.SeedSequence:
    """A SeedSequence from None, an int, a SeedSequence or a Generator (one draw is consumed)."""
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if isinstance(seed, np.random.Generator):
        return np.random.SeedSequence(int(seed.integers(0, 2**63)))
    if seed is None:
        return np.random.SeedSequence()
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: expected None, an int >= 0, a SeedSequence or a numpy Generator, "
                         f"got {seed!r}")
    return np.random.SeedSequence(int(seed))


def child_seed(root: np.random.SeedSequence, *key: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(root.entropy, spawn_key=tuple(root.spawn_key) + tuple(key))


def stream(root: np.random.SeedSequence, *key: int) -> np.random.Generator:
    """The generator of stream ``key`` under ``root`` (e.g. ``(view, STREAM_CAMERAS)``)."""
    return np.random.default_rng(child_seed(root, *key))


# ---------------------------------------------------------------------------------------------
# kernels and priors


def log_gauss(residual, sigma):
    """Log of a Gaussian likelihood up to a constant: ``-r^2 / (2 sigma^2) - log(sigma)``."""
    r = np.asarray(residual) / sigma
    return -0.5 * r * r - np.log(sigma)


#: Cap of the Laplace volume of C (log of an area in |AB|^2): near-parallel rays leave C
#: unconstrained along them, and the prior, not the volume, then bounds it.
LOG_VOLUME_CAP = np.log(100.0)


def log_landmark_volume(cameras, L, sigma) -> np.ndarray:
    """Log of the Laplace volume of C about a triangulated point: the integral over L of
    ``prod_t N(phi_C,t - f(L, X_t); sigma)`` is about ``exp(-r^2 / 2 sigma^2) 2 pi sigma^2 /
    sqrt(det H)`` with ``H = sum_t g_t g_t^T``, ``g_t = grad_L f(L, X_t)`` (``|g_t| = 1 / d_t``),
    so ``det H = sum_{s<t} sin^2(angle between rays s, t) / (d_s d_t)^2``. Capped at
    :data:`LOG_VOLUME_CAP`.

    ``cameras`` (..., n, 2), ``L`` (..., 2), ``sigma`` broadcastable to (...).
    """
    d = L[..., None, :] - cameras
    r2 = np.maximum(np.sum(d * d, axis=-1), 1e-300)
    g = np.stack([-d[..., 1], d[..., 0]], axis=-1) / r2[..., None]
    n = cameras.shape[-2]
    ii, jj = np.triu_indices(n, k=1)
    cr = g[..., ii, 0] * g[..., jj, 1] - g[..., ii, 1] * g[..., jj, 0]
    det = np.sum(cr * cr, axis=-1)
    with np.errstate(divide="ignore"):
        lv = np.log(2 * np.pi * np.asarray(sigma) ** 2) - 0.5 * np.log(np.maximum(det, 1e-300))
    return np.minimum(lv, LOG_VOLUME_CAP)


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


#: Scale of the heavy-tailed distance proposal along lines of sight (|AB| units).
RAY_CENTRE = np.array([0.0, 0.5])


def _ray_points(origins, angles, eps, v, sigma):
    """C along lines of sight: ``L = O + r u(theta + eps)`` with ``r = tau v / (1 - v)`` (v in
    (0, 1)) and ``tau = max(1, |O - (0, 1/2)|)`` (the distance scale of the world). ``origins``
    (..., 2), ``angles`` (...), ``eps`` and ``v`` (..., k) -> ``(L (..., k, 2), log q (..., k))``
    with q the density over positions when ``eps ~ N(0, sigma^2)`` and v is uniform:
    ``N(eps; sigma) tau / (tau + r)^2 / r`` (polar coordinates about O)."""
    tau = np.maximum(1.0, np.linalg.norm(origins - RAY_CENTRE, axis=-1))[..., None]
    v = np.clip(v, 1e-12, 1 - 1e-12)
    r = tau * v / (1.0 - v)
    th = np.asarray(angles)[..., None] + eps
    L = origins[..., None, :] + r[..., None] * np.stack([np.cos(th), np.sin(th)], axis=-1)
    return L, ray_log_density_polar(eps, r, tau, sigma)


def ray_log_density_polar(eps, r, tau, sigma):
    """log q of :func:`_ray_points` at angular offset ``eps`` and distance ``r``."""
    return (log_gauss(eps, sigma) - 0.5 * np.log(2 * np.pi) + np.log(tau)
            - 2.0 * np.log(tau + r) - np.log(np.maximum(r, 1e-300)))


def arc_parameter(gamma, w):
    """Angle at A of arc points for parameters ``w`` in (0, 1), and ``log(da/dw)``.

    ``a = span (1 - cos(pi w)) / 2`` with ``span = pi - |gamma|``: denser near both ends of the arc
    (cameras close to A or B, or near line AB on a large circle), where the position moves
    fastest with ``a``; ``da/dw = span pi sin(pi w) / 2``.
    """
    span = np.pi - np.abs(gamma)
    a = span * 0.5 * (1.0 - np.cos(np.pi * w))
    dadw = span * 0.5 * np.pi * np.sin(np.pi * w)
    with np.errstate(divide="ignore"):
        return a, np.where(dadw > 0, np.log(np.where(dadw > 0, dadw, 1.0)), _NEG_INF)


def log_arc_jacobian(points, gamma, log_dadw) -> np.ndarray:
    """Log importance weight of arc samples under a uniform prior over positions.

    With ``X = locus_point(gamma, a)``, ``dx dy = |AX| sin(a) / sin^2(gamma) d gamma d a`` and
    ``|AX| sin(a) = |x|``; a sample drawn at parameter w (``a = a(w)``, w uniform) therefore
    carries ``|x| (da/dw) / sin^2(gamma)``. Degenerate gammas and points on line AB get -inf.
    """
    s2 = np.sin(gamma) ** 2
    ax = np.abs(points[..., 0])
    ok = (s2 >= LOCUS_EPS**2) & (ax > 0) & np.isfinite(log_dadw)
    with np.errstate(divide="ignore"):
        out = np.log(np.where(ok, ax, 1.0)) + np.where(ok, log_dadw, 0.0) - np.log(
            np.where(ok, s2, 1.0))
    return np.where(ok, out, _NEG_INF)


def log_ray_jacobian(points, origins, angles) -> np.ndarray:
    """Log of the area element of positions reached along rays, for points ``X`` (..., 2) where
    rays from ``origins`` at ``angles`` (the heading) meet locus circles of subtended angle gamma.

    ``X = O + t u(theta)`` with ``Gamma(X) = gamma``, so ``|d(x, y) / d(theta, gamma)| =
    t / |grad Gamma(X) . u|`` where ``Gamma(X) = dir(B - X) - dir(A - X)`` is the angle AB
    subtends at X. It turns the heading and bearing likelihoods, sampled or taken as exact, into
    a density over positions (the motion step's change of variables). -inf where the ray grazes
    the circle or starts on it.
    """
    X = np.asarray(points, dtype=float)
    O = np.asarray(origins, dtype=float)
    ux, uy = np.cos(angles), np.sin(angles)
    t = (X[..., 0] - O[..., 0]) * ux + (X[..., 1] - O[..., 1]) * uy
    ax, ay = -X[..., 0], -X[..., 1]
    bx, by = -X[..., 0], 1.0 - X[..., 1]
    ra, rb = ax * ax + ay * ay, bx * bx + by * by
    ok = (ra > 0) & (rb > 0)
    ra, rb = np.where(ok, ra, 1.0), np.where(ok, rb, 1.0)
    gx = by / rb - ay / ra
    gy = -bx / rb + ax / ra
    dot = np.abs(gx * ux + gy * uy)
    ok &= (dot > 1e-300) & (t > 0)
    with np.errstate(divide="ignore"):
        out = np.log(np.where(ok, t, 1.0)) - np.log(np.where(ok, dot, 1.0))
    return np.where(ok, out, _NEG_INF)


def log_camera_prior(points, gamma, log_dadw, prior) -> np.ndarray:
    """Intermediate importance log-weight of arc samples: the arc's change of variables times
    the per-point prior (:func:`point_log_prior`)."""
    return log_arc_jacobian(points, gamma, log_dadw) + point_log_prior(prior, points)


# ---------------------------------------------------------------------------------------------
# the sampling step


def arc_poses(phi_a, phi_b, w, prior):
    """Camera poses on the exact locus arcs of bearings ``phi_a``, ``phi_b`` (T,) at arc
    parameters ``w`` (T, K) in (0, 1) (:func:`arc_parameter`). Returns ``(poses (T, K, 3),
    logw (T, K))`` with logw the prior importance weight per unit of w."""
    pa = np.asarray(phi_a, dtype=float)[..., None]
    gamma = wrap_angle(np.asarray(phi_b, dtype=float)[..., None] - pa)
    a, log_dadw = arc_parameter(gamma, w)
    X = locus_point(gamma, a)
    alpha = heading_on_locus(X, pa)
    logw = log_camera_prior(X, gamma, log_dadw, prior)
    return np.concatenate([X, alpha[..., None]], axis=-1), logw


#: Rows (trajectories) per block of the batched C computations: the (views, rows) temporaries
#: of a block stay in the core's cache (about 1.5x faster than whole-batch arrays of a million
#: rows); results do not depend on it.
CHUNK_ROWS = 16384


def _laplace(X, theta, parts=False):
    """Least-squares triangulation of lines of sight (J, n) and ``H = sum_t g_t g_t^T`` there
    (``g_t = grad_L f(L, X_t)``, ``|g_t| = 1 / d_t``), with a tiny ridge so that H is always
    invertible. Returns (L* (J, 2), ok, h00, h01, h11, det H, least squared camera distance),
    and with ``parts`` also ``(dx, dy, th)`` (n, J): L* - X_t and the line angles per view."""
    # views along the first axis (n, J): the sums over views are then adds of contiguous rows,
    # several times faster than reductions along a short last axis
    x = np.ascontiguousarray(X[..., 0].T)
    y = np.ascontiguousarray(X[..., 1].T)
    th = np.ascontiguousarray(np.asarray(theta, dtype=float).T)
    # least squares over lines with unit normals nv = (-sin, cos): (sum nv nv^T) L = sum nv nv^T o
    sn, cs = np.sin(th), np.cos(th)
    tmp = sn * sn
    a = _vsum(tmp)
    np.multiply(sn, cs, out=tmp)
    b = -_vsum(tmp)
    np.multiply(cs, cs, out=tmp)
    c = _vsum(tmp)
    proj = cs * y
    proj -= sn * x                                         # nv . o per line
    np.multiply(sn, proj, out=tmp)
    v0 = -_vsum(tmp)
    np.multiply(cs, proj, out=tmp)
    v1 = _vsum(tmp)
    dm = a * c - b * b
    ok = np.abs(dm) > 1e-12
    sd = np.where(ok, dm, 1.0)
    L0, L1 = (c * v0 - b * v1) / sd, (a * v1 - b * v0) / sd
    # a triangulation far beyond the world (near-parallel lines) is no better than none
    ok &= (np.abs(L0) < 1e6) & (np.abs(L1) < 1e6)
    L0 = np.where(ok, L0, _vsum(x) / x.shape[0])
    L1 = np.where(ok, L1, _vsum(y) / y.shape[0])
    dx, dy = np.subtract(L0, x, out=x), np.subtract(L1, y, out=y)
    r2 = dx * dx
    r2 += dy * dy
    np.maximum(r2, 1e-150, out=r2)
    np.minimum(r2, 1e150, out=r2)
    r2min = np.min(r2, axis=0)
    r4 = np.multiply(r2, r2, out=r2)
    ux = np.minimum(np.maximum(dx, -1e75, out=sn), 1e75, out=sn)
    uy = np.minimum(np.maximum(dy, -1e75, out=cs), 1e75, out=cs)
    np.multiply(uy, uy, out=tmp)
    tmp /= r4
    h00 = _vsum(tmp)
    np.multiply(ux, ux, out=tmp)
    tmp /= r4
    h11 = _vsum(tmp)
    np.multiply(ux, uy, out=tmp)
    tmp /= r4
    h01 = -_vsum(tmp)
    ridge = 1e-9 * (h00 + h11) + 1e-12
    h00, h11 = h00 + ridge, h11 + ridge
    det = h00 * h11 - h01 * h01
    out = (np.stack([L0, L1], axis=-1), ok, h00, h01, h11, det, r2min)
    return out + ((dx, dy, th),) if parts else out


def _vsum(a):
    """Sum over the first axis (views) of an (n, J) array, row by row."""
    out = a[0].copy()
    for r in a[1:]:
        out += r
    return out


def depth_spread(ok, h00, h01, h11, det, r2min, sig):
    """Standard deviation of C along its least constrained direction (``sigma^2 H^-1``) over its
    distance from the nearest camera; inf without a triangulation."""
    tr = (h00 + h11) / det
    lam = 0.5 * tr + np.sqrt(np.maximum(0.25 * tr * tr - 1.0 / det, 0.0))
    return np.where(ok, np.sqrt(lam) * sig / np.sqrt(r2min), np.inf)


def laplace_landmark(poses, phi_c, sigma, parts=False):
    """Laplace approximation of C's integral ``log ∫ prod_t N(phi_C,t - f(L, X_t); sigma) dL``
    (normalized Gaussians) about the least-squares triangulation, without the prior:
    ``sum_t log N(r_t) + log(2 pi sigma^2 / sqrt(det H))``. Good where C's depth is resolved;
    returns (log Z (J,), L* (J, 2), depth spread (J,)) so that callers can fall back to sampling
    (:func:`sample_landmarks`) where it is not; with ``parts`` also the triangulation and ``H``
    as :func:`sample_landmarks` takes them (``laplace=``): (L*, ok, h00, h01, h11, det H,
    least squared camera distance)."""
    J, n = poses.shape[:2]
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), (J,))
    phi_c = np.broadcast_to(np.asarray(phi_c, dtype=float), (J, n))
    lz, Ls, spread = np.empty(J), np.empty((J, 2)), np.empty(J)
    if parts:
        ok_all, H = np.empty(J, dtype=bool), np.empty((5, J))
    for i in range(0, J, CHUNK_ROWS):
        sl = slice(i, i + CHUNK_ROWS)
        P = poses[sl]
        Ls[sl], ok, h00, h01, h11, det, r2min, (dx, dy, th) = _laplace(
            P[..., :2], P[..., 2] + phi_c[sl], parts=True)
        res = np.arctan2(dy, dx, out=dx)
        res -= th
        res = wrap_angle(res)
        res *= res
        s = sig[sl]
        lz[sl] = (-0.5 * _vsum(res) / (s * s) - n * (np.log(s) + 0.5 * np.log(2 * np.pi))
                  + np.log(2 * np.pi * s * s) - 0.5 * np.log(det))
        spread[sl] = depth_spread(ok, h00, h01, h11, det, r2min, s)
        if parts:
            ok_all[sl] = ok
            H[0, sl], H[1, sl], H[2, sl], H[3, sl], H[4, sl] = h00, h01, h11, det, r2min
    if parts:
        return lz, Ls, spread, (Ls, ok_all, *H)
    return lz, Ls, spread


def sample_landmarks(rng, poses, phi_c, sigma, k: int, ray_fraction: float, draws=None,
                     laplace=None):
    """C samples for each camera trajectory, from a defensive mixture: a Gaussian about the
    least-squares triangulation with covariance ``(1.5 sigma)^2 H^-1`` (``H = sum_t g_t g_t^T``,
    ``g_t = grad_L f(L, X_t)``; the Laplace approximation of C's conditional, inflated) and, for
    a share ``ray_fraction`` of the samples (all of them with one view), :func:`_ray_points` along
    the line of sight of a view chosen uniformly. The mixture density is evaluated exactly, so
    ``exp(log prior + log lik - log q)`` is an unbiased estimate of C's integral for every
    geometry, including lines of sight that coincide (C's depth then comes from the prior).

    ``poses`` (J, n, 3), ``phi_c`` (n,) or (J, n), ``sigma`` > 0 (scalar or (J,)); the random
    numbers come from ``rng`` or, if given, ``draws`` (dict: ``z`` (J, kg, 2) and ``eps`` (J, kr)
    standard normals, ``t`` (J, kr) views, ``u`` (J, kr) uniforms); ``laplace``: the
    triangulation and ``H`` of these rows if already computed (:func:`laplace_landmark` with
    ``parts``). Returns ``L (J, k, 2)``, ``log q
    (J, k)``, ``log lik (J, k)`` (sum over views of the normalized Gaussian C-bearing
    likelihood) and the depth spread ``(J,)``: the standard deviation of C along its least
    constrained direction over its distance from the nearest camera (inf without a
    triangulation).
    """
    J, n = poses.shape[:2]
    kr = k if n == 1 else min(k, int(round(k * ray_fraction)))
    kg = k - kr
    if draws is None:
        draws = {"z": rng.standard_normal((J, kg, 2)), "t": rng.integers(0, n, size=(J, kr)),
                 "eps": rng.standard_normal((J, kr)), "u": rng.random((J, kr))}
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), (J,))
    phi_c = np.broadcast_to(np.asarray(phi_c, dtype=float), (J, n))
    L, log_q, log_lik, spread = np.empty((J, k, 2)), np.empty((J, k)), np.empty((J, k)), \
        np.empty(J)
    chunk = max(1, CHUNK_ROWS // k)
    for i in range(0, J, chunk):
        sl = slice(i, i + chunk)
        L[sl], log_q[sl], log_lik[sl], spread[sl] = _sample_landmarks_rows(
            poses[sl], phi_c[sl], sig[sl], kg, kr, {key: v[sl] for key, v in draws.items()},
            None if laplace is None else tuple(v[sl] for v in laplace))
    return L, log_q, log_lik, spread


def _sample_landmarks_rows(poses, phi_c, sig, kg, kr, draws, laplace=None):
    """:func:`sample_landmarks` on one block of rows."""
    J, n = poses.shape[:2]
    k = kg + kr
    X = poses[..., :2]
    theta = poses[..., 2] + phi_c
    L = np.empty((J, k, 2))
    spread = np.full(J, np.inf)
    c2 = (1.5 * sig) ** 2
    if kg:
        Ls, ok, h00, h01, h11, det, r2min = _laplace(X, theta) if laplace is None else laplace
        # covariance c2 H^-1 and its Cholesky factor
        s00, s11, s01 = c2 * h11 / det, c2 * h00 / det, -c2 * h01 / det
        l11 = np.sqrt(s00)
        l21 = s01 / l11
        l22 = np.sqrt(np.maximum(s11 - l21 * l21, 1e-300))
        z = draws["z"]
        L[:, :kg, 0] = Ls[:, None, 0] + l11[:, None] * z[..., 0]
        L[:, :kg, 1] = Ls[:, None, 1] + l21[:, None] * z[..., 0] + l22[:, None] * z[..., 1]
        spread = depth_spread(ok, h00, h01, h11, det, r2min, sig)
    if kr:
        t = draws["t"]
        jj = np.arange(J)[:, None]
        eps = sig[:, None] * draws["eps"]
        v = (np.arange(kr) + draws["u"]) / kr
        Lr, _ = _ray_points(X[jj, t], theta[jj, t], eps[..., None], v[..., None],
                            sig[:, None, None])
        L[:, kg:] = Lr[..., 0, :]
    # per view: distance and angular residual of every sample, views along the first axis
    # (n, J, k) so that the sums over views are adds of contiguous blocks
    ddx = L[:, :, 0][None] - X[..., 0].T[:, :, None]
    ddy = L[:, :, 1][None] - X[..., 1].T[:, :, None]
    res = np.arctan2(ddy, ddx)
    res -= theta.T[:, :, None]
    res = wrap_angle(res)
    log_lik = -0.5 * _vsum(res * res) / (sig * sig)[:, None] - n * (
        np.log(sig) + 0.5 * np.log(2 * np.pi))[:, None]
    logs = []
    if kg:
        ex = L[..., 0] - Ls[:, None, 0]
        ey = L[..., 1] - Ls[:, None, 1]
        m = (h00[:, None] * ex * ex + 2 * h01[:, None] * ex * ey + h11[:, None] * ey * ey) / \
            c2[:, None]
        logs.append(np.log(kg / k) - 0.5 * m - np.log(2 * np.pi)
                    + 0.5 * np.log(det / (c2 * c2))[:, None])
    if kr:
        tau = np.maximum(1.0, np.hypot(X[..., 0] - RAY_CENTRE[0], X[..., 1] - RAY_CENTRE[1]))
        ddx *= ddx
        ddy *= ddy
        ddx += ddy
        r = np.sqrt(ddx, out=ddx)
        lr = ray_log_density_polar(res, r, tau.T[:, :, None], sig[None, :, None])
        logs.append(np.log(kr / k) + _logsumexp_rows(lr) - np.log(n))
    log_q = logs[0] if len(logs) == 1 else np.logaddexp(logs[0], logs[1])
    return L, log_q, log_lik, spread


def weighted_state_error(part, points, weights) -> float:
    """Monte Carlo standard error of a self-normalized weighted state histogram (delta method:
    ``sqrt(sum_i w_i^2 (1[s_i = s] - p_s)^2)``), the largest over states. ``weights`` sum to 1."""
    w = np.asarray(weights, dtype=float)
    if w.size == 0 or not np.any(w > 0):
        return float("nan")
    s = part.state_of(points)
    m = part.n_states
    p = np.bincount(s, weights=w, minlength=m)
    w2 = w * w
    a = np.bincount(s, weights=w2, minlength=m)           # sum over i in s of w_i^2
    tot = w2.sum()
    var = a * (1 - p) ** 2 + (tot - a) * p**2
    return float(np.sqrt(var.max()))


# ---------------------------------------------------------------------------------------------
# output


def normalize_log(logw: np.ndarray) -> np.ndarray:
    """exp(logw) normalized to sum 1 along the last axis; all -inf rows give all zeros."""
    logw = np.asarray(logw, dtype=float)
    if logw.size == 0:
        return np.zeros_like(logw)
    mx = np.max(logw, axis=-1, keepdims=True)
    ok = np.isfinite(mx)
    w = np.exp(logw - np.where(ok, mx, 0.0))
    w = np.where(ok, w, 0.0)
    s = w.sum(axis=-1, keepdims=True)
    return np.where(s > 0, w / np.where(s > 0, s, 1.0), 0.0)


def state_histogram(part, points, weights) -> tuple[np.ndarray, bool]:
    """Weighted histogram of the states of AB-frame ``points`` (J, 2) -> ((m,), ok). Uniform and
    ok = False when the weights are all zero."""
    m = part.n_states
    w = np.asarray(weights, dtype=float)
    if w.size == 0 or not np.any(w > 0):
        return np.full(m, 1.0 / m), False
    keep = w > 0
    s = part.state_of(points[keep])
    h = np.bincount(s, weights=w[keep], minlength=m)[:m]
    return h / h.sum(), True


def prior_name(opts) -> str:
    p = opts.get("prior", "")
    return p if isinstance(p, str) else getattr(p, "name", type(p).__name__)


def public_options(opts) -> dict:
    """Options as an estimate reports them: plain values, the prior by name."""
    out = dict(opts)
    if "prior" in out:
        out["prior"] = prior_name(opts)
    return out


def shrink_to_uniform(p, n_eff, alpha):
    """State probabilities estimated from ``n_eff`` effective posterior draws, shrunk toward the
    uniform distribution by ``alpha`` pseudo-draws: ``(n_eff p + alpha / m) / (n_eff + alpha)``.

    This is the posterior mean of a state distribution under a symmetric Dirichlet(alpha / m)
    prior after observing ``n_eff p`` draws in each state: a Monte Carlo estimate from a handful
    of effective draws cannot support probabilities near 0 or 1, and the shrinkage keeps it from
    claiming them (``p`` (..., m); the rows still sum to 1). ``alpha = 0`` returns ``p``.

    >>> shrink_to_uniform(np.array([1.0, 0.0, 0.0, 0.0]), 3.0, 1.0).round(4).tolist()
    [0.8125, 0.0625, 0.0625, 0.0625]
    """
    p = np.asarray(p, dtype=float)
    if alpha <= 0 or not np.isfinite(n_eff):
        return p
    m = p.shape[-1]
    return (n_eff * p + alpha / m) / (n_eff + alpha)


def make_estimate(method, part, n_views, landmark, cameras, *, hypotheses: Hypotheses,
                  reasons=(), mc_error=float("nan"), opts) -> tuple[TripletEstimate, Hypotheses]:
    """The (answer, hypotheses) pair every solver's ``finish`` returns. With the option
    ``mc_shrinkage`` = alpha > 0 the landmark and camera distributions are shrunk toward the
    uniform by alpha pseudo-draws against the final sample's ESS (:func:`shrink_to_uniform`)."""
    lw = hypotheses.landmark_weights
    e = ess(lw)
    a = float(opts.get("mc_shrinkage", 0.0) or 0.0)
    landmark = shrink_to_uniform(landmark, e, a)
    cameras = shrink_to_uniform(cameras, e, a)
    est = TripletEstimate(
        landmark=np.asarray(landmark, dtype=float), cameras=np.asarray(cameras, dtype=float),
        n_hypotheses=int(np.count_nonzero(lw > 0)), degenerate=bool(reasons),
        reason="; ".join(reasons), method=method, partition=part.name, n_views=int(n_views),
        ess=e, mc_error=float(mc_error), prior=prior_name(opts),
        options=public_options(opts))
    return est, hypotheses


def empty_hypotheses(n_views) -> Hypotheses:
    return Hypotheses(landmark_samples=np.zeros((0, 2)), landmark_weights=np.zeros(0),
                      camera_samples=np.zeros((n_views, 0, 3)),
                      camera_weights=np.zeros((n_views, 0)), joint=False)


def uniform_estimate(method, part, n_views, reason, opts) -> tuple[TripletEstimate, Hypotheses]:
    m = part.n_states
    return make_estimate(method, part, n_views, np.full(m, 1.0 / m),
                         np.full((n_views, m), 1.0 / m), hypotheses=empty_hypotheses(n_views),
                         reasons=(reason,), opts=opts)


#: Bearings of consecutive views equal within this (radians, all three): the camera is taken as
#: not having moved.
SAME_POSE_TOL = 1e-9

#: C's depth is called unresolved when its standard deviation along the least constrained
#: direction exceeds this fraction of its distance from the nearest camera.
DEPTH_SPREAD = 0.5


def geometry_reasons(bearings, sigma_bearing=0.0, headings=None, sigma_heading=0.0
                     ) -> list[str]:
    """Flags from the measurements alone: cameras on (or within a tenth of the bearing noise of)
    line AB; travel along the line of sight to C between every pair of views (``psi_i`` equal to
    ``phi_C,i`` or opposite, within ``hypot(sigma_v, sigma_w)``): the lines of sight to C may
    then coincide, leaving C's depth to the prior."""
    out = []
    g = wrap_angle(bearings[:, 1] - bearings[:, 0])
    # within a tenth of the bearing noise: the arc is then not known to be finite
    tol = max(LOCUS_EPS, float(np.sin(min(0.1 * float(sigma_bearing), np.pi / 2))))
    bad = [int(i) for i in np.flatnonzero(np.abs(np.sin(g)) < tol)]
    if bad:
        out.append("camera on line AB (phi_A = phi_B or opposite, within the bearing noise) in "
                   "view(s) " + ", ".join(str(b + 1) for b in bad))
    if headings is not None and len(headings) >= 1:
        d = wrap_angle(np.asarray(headings) - bearings[:-1, 2])
        off = np.minimum(np.abs(d), np.pi - np.abs(d))
        if np.all(off <= max(1e-6, float(np.hypot(sigma_bearing, sigma_heading)))):
            out.append("lines of sight to C may coincide: the camera travels along its line of "
                       "sight to C between every pair of views")
    return out


def _logsumexp_rows(a) -> np.ndarray:
    """:func:`logsumexp` over the first axis of a float array (n, ...) (same values), on whole
    rows: numpy's reductions over a short axis are several times slower."""
    mx = a[0].copy()
    for r in a[1:]:
        np.maximum(mx, r, out=mx)
    ok = np.isfinite(mx)
    m0 = np.where(ok, mx, 0.0)
    s = np.exp(a[0] - m0)
    for r in a[1:]:
        s += np.exp(r - m0)
    with np.errstate(divide="ignore"):
        return np.where(ok, mx + np.log(np.where(ok, s, 1.0)), -np.inf)


def logsumexp(a, axis=-1) -> np.ndarray:
    """``log(sum(exp(a)))`` along ``axis``; -inf where every entry is -inf (no warning)."""
    a = np.asarray(a, dtype=float)
    mx = np.max(a, axis=axis, keepdims=True, initial=-np.inf)
    ok = np.isfinite(mx)
    s = np.sum(np.exp(a - np.where(ok, mx, 0.0)), axis=axis, keepdims=True)
    with np.errstate(divide="ignore"):
        out = np.where(ok, mx + np.log(np.where(ok, s, 1.0)), -np.inf)
    return np.squeeze(out, axis=axis)
