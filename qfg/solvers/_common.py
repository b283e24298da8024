"""Pieces shared by the single-triplet solvers: the result type, input checks, random streams,
likelihood kernels, priors, locus sampling and the weighted state histograms.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians; lengths in |AB|.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import partitions as _partitions
from .._validate import as_float_array, non_negative, positive_int
from ..geometry import LOCUS_EPS, heading_on_locus, locus_point, wrap_angle

#: Methods :func:`qfg.solvers.solve_triplet` knows.
METHODS = ("full", "fast", "baseline")

#: Priors over positions (cameras and C) in the AB frame:
#:
#: * ``"world"``: the AB-frame density of a point placed uniformly in the world independently of A
#:   and B (the paper's prior, seen from the AB frame), measured to be close to
#:   ``p(P) = (s^2 / pi) (s^2 + |P - (0, 1/2)|^2)^-2`` with s = 0.85, i.e.
#:   ``P(|P - (0, 1/2)| <= R) = R^2 / (s^2 + R^2)`` (heavy-tailed, proper; docs/solvers.md);
#: * ``"uniform"``: uniform over positions in ``prior_window`` for cameras; C uniform in the window
#:   with one view and for the baseline (where the integral needs bounds), unrestricted with two
#:   or more views;
#: * ``"arc"``: uniform in the angle at A along each locus arc (the implicit prior of sampling
#:   the arc uniformly), no window; C as for ``"uniform"``.
PRIORS = ("world", "uniform", "arc")

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
        "n_samples": 600,            # camera samples on the first view's locus (sampling step);
                                     # x motion_samples when both sigmas are 0 (see _full)
        "motion": "sample",          # motion step: "sample" = each hypothesis' ray, heading noise
                                     # sampled, meets locus arcs drawn under bearing noise;
                                     # "match" = independent view samples matched by heading
        "motion_samples": 8,         # noise draws per hypothesis and view (motion="sample")
        "match_sigmas": 3.0,         # matching window in heading sigmas (motion="match")
        "max_hypotheses": 3000,      # cap after pruning (systematic resampling down to it)
        "prune_ratio": 1e-6,         # drop hypotheses lighter than this x the heaviest
        "bearing_floor": np.deg2rad(0.05),
        "heading_floor": np.deg2rad(1.0),
        "one_view_samples": 16,      # C samples per camera sample with a single view
        "resection": "lsq",          # "lsq" or the paper's "centroid" of pairwise intersections
        "landmark_volume": False,    # Laplace volume of C about the triangulated point
        "prior": "world",
        "prior_window": (-6.0, 6.0, -5.5, 6.5),
    },
    "fast": {
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
        "prior_window": (-6.0, 6.0, -5.5, 6.5),
    },
    "baseline": {
        "n_landmark_samples": 4096,  # C candidates drawn from the prior (stratified)
        "noise_samples": 16,         # measurement-noise draws per view (1 when sigma = 0)
        "jacobian_cap": 30.0,        # cap on 1/|det J| relative to the median candidate
        "prior": "world",
        "prior_window": (-6.0, 6.0, -5.5, 6.5),
    },
}


def resolve_options(method: str, options: dict) -> dict:
    """Defaults of ``method`` updated with ``options``; unknown or bad options raise ValueError."""
    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    opts = dict(DEFAULTS[method])
    unknown = sorted(set(options) - set(opts))
    if unknown:
        raise ValueError(f"{unknown[0]}: not an option of method {method!r}; "
                         f"known: {', '.join(sorted(opts))}")
    opts.update(options)
    if "motion" in opts and opts["motion"] not in ("sample", "match"):
        raise ValueError(f"motion: expected 'sample' or 'match', got {opts['motion']!r}")
    for k in ("n_samples", "max_hypotheses", "one_view_samples", "n_landmark_samples",
              "motion_samples", "noise_samples", "refine_cells", "refine_factor"):
        if k in opts:
            opts[k] = positive_int(k, opts[k])
    if "refine_levels" in opts:
        opts["refine_levels"] = positive_int("refine_levels", opts["refine_levels"], minimum=0)
    for k in ("bearing_floor", "heading_floor", "match_sigmas", "jacobian_cap"):
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
    if opts["prior"] not in PRIORS:
        raise ValueError(f"prior: expected one of {PRIORS}, got {opts['prior']!r}")
    w = tuple(float(v) for v in np.asarray(opts["prior_window"], dtype=float).ravel())
    if len(w) != 4 or not (np.all(np.isfinite(w)) and w[0] < w[1] and w[2] < w[3]):
        raise ValueError(f"prior_window: expected (xmin, xmax, ymin, ymax) with xmin < xmax and "
                         f"ymin < ymax, got {opts['prior_window']!r}")
    opts["prior_window"] = w
    if method == "baseline" and opts["prior"] == "arc":
        raise ValueError("prior: the baseline needs a prior over C positions ('world' or "
                         "'uniform'), not 'arc'")
    return opts


def effective_sigma(sigma, floor):
    """Likelihood width actually used: ``max(sigma, floor)`` (so that zero noise still works)."""
    return np.maximum(np.asarray(sigma, dtype=float), floor)


# ---------------------------------------------------------------------------------------------
# input


@dataclass(frozen=True)
class Measurements:
    """Validated measurements of one triplet: bearings (n, 3), headings (n - 1,) or None."""

    bearings: np.ndarray
    headings: np.ndarray | None
    sigma_bearing: float
    sigma_heading: float

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


def measurements(bearings, headings, sigma_bearing, sigma_heading) -> Measurements:
    """Validate one triplet's input. ``bearings`` may be a TripletHistory (then ``headings``
    and unset sigmas come from it)."""
    from ..simulation import TripletHistory

    if isinstance(bearings, TripletHistory):
        hist = bearings
        if headings is not None:
            raise ValueError("headings: pass either a TripletHistory or bearings and headings, "
                             "not both")
        b = check_bearings(hist.bearings)
        h = check_headings(hist.headings, b.shape[0]) if hist.has_motion else None
        sb = hist.sigma_bearing if sigma_bearing is None else sigma_bearing
        sh = hist.sigma_heading if sigma_heading is None else sigma_heading
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
    return Measurements(bearings=b, headings=h, sigma_bearing=non_negative("sigma_bearing", sb),
                        sigma_heading=non_negative("sigma_heading", sh))


def get_partition(partition):
    return _partitions.get(partition)


# ---------------------------------------------------------------------------------------------
# random streams: one per (view, purpose), so that adding a view draws exactly what a batch solve
# of all views draws for it.

#: spawn-key purposes
STREAM_CAMERAS, STREAM_RESAMPLE, STREAM_ONE_VIEW, STREAM_LANDMARKS = 0, 1, 2, 3


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


def log_landmark_volume(cameras, L, sigma, window) -> np.ndarray:
    """Log of the Laplace volume of C about a triangulated point: the integral over L of
    ``prod_t N(phi_C,t - f(L, X_t); sigma)`` is about ``exp(-r^2 / 2 sigma^2) 2 pi sigma^2 /
    sqrt(det H)`` with ``H = sum_t g_t g_t^T``, ``g_t = grad_L f(L, X_t)`` (``|g_t| = 1 / d_t``),
    so ``det H = sum_{s<t} sin^2(angle between rays s, t) / (d_s d_t)^2``. Capped at the prior
    window's area (near-parallel rays leave C unconstrained along them).

    ``cameras`` (..., n, 2), ``L`` (..., 2), ``sigma`` broadcastable to (...).
    """
    d = L[..., None, :] - cameras
    r2 = np.maximum(np.sum(d * d, axis=-1), 1e-300)
    g = np.stack([-d[..., 1], d[..., 0]], axis=-1) / r2[..., None]
    n = cameras.shape[-2]
    ii, jj = np.triu_indices(n, k=1)
    cr = g[..., ii, 0] * g[..., jj, 1] - g[..., ii, 1] * g[..., jj, 0]
    det = np.sum(cr * cr, axis=-1)
    xmin, xmax, ymin, ymax = window
    cap = np.log((xmax - xmin) * (ymax - ymin))
    with np.errstate(divide="ignore"):
        lv = np.log(2 * np.pi * np.asarray(sigma) ** 2) - 0.5 * np.log(np.maximum(det, 1e-300))
    return np.minimum(lv, cap)


def in_window(points, window) -> np.ndarray:
    xmin, xmax, ymin, ymax = window
    x, y = points[..., 0], points[..., 1]
    return (x >= xmin) & (x <= xmax) & (y >= ymin) & (y <= ymax)


#: Centre and scale of the ``"world"`` prior (the middle of AB; s fitted to the simulator's
#: AB-frame distribution of uniformly placed objects, within 0.015 in the CDF: docs/solvers.md).
WORLD_CENTRE = np.array([0.0, 0.5])
WORLD_SCALE = 0.85


def log_point_prior(points, prior: str, window) -> np.ndarray:
    """Log prior density of AB-frame positions (..., 2), up to a constant (see :data:`PRIORS`).
    For C with two or more views only ``"world"`` is informative (see :func:`log_c_prior`)."""
    if prior == "world":
        d = points - WORLD_CENTRE
        s2 = WORLD_SCALE**2
        return np.log(s2 / np.pi) - 2.0 * np.log(s2 + np.sum(d * d, axis=-1))
    return log_window(points, window, prior)


def log_c_prior(points, prior: str) -> np.ndarray:
    """Log prior of a triangulated C (two or more views): the ``"world"`` density, else flat."""
    if prior == "world":
        return log_point_prior(points, prior, None)
    return np.zeros(points.shape[:-1])


def log_window(points, window, prior: str) -> np.ndarray:
    """0 inside the prior window, -inf outside (``prior="uniform"``); 0 everywhere for ``"arc"``."""
    if prior != "uniform":
        return np.zeros(points.shape[:-1])
    return np.where(in_window(points, window), 0.0, _NEG_INF)


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
    u = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    t = np.sum((X - origins) * u, axis=-1)
    ax, ay = -X[..., 0], -X[..., 1]
    bx, by = -X[..., 0], 1.0 - X[..., 1]
    ra, rb = ax * ax + ay * ay, bx * bx + by * by
    ok = (ra > 0) & (rb > 0)
    ra, rb = np.where(ok, ra, 1.0), np.where(ok, rb, 1.0)
    gx = by / rb - ay / ra
    gy = -bx / rb + ax / ra
    dot = np.abs(gx * u[..., 0] + gy * u[..., 1])
    ok &= (dot > 1e-300) & (t > 0)
    with np.errstate(divide="ignore"):
        out = np.log(np.where(ok, t, 1.0)) - np.log(np.where(ok, dot, 1.0))
    return np.where(ok, out, _NEG_INF)


def log_camera_prior(points, gamma, log_dadw, prior, window) -> np.ndarray:
    """Importance log-weight of arc samples under the chosen prior (see :data:`PRIORS`)."""
    if prior in ("uniform", "world"):
        return log_arc_jacobian(points, gamma, log_dadw) + log_point_prior(points, prior, window)
    ok = (np.sin(gamma) ** 2 >= LOCUS_EPS**2) & np.isfinite(log_dadw)
    return np.broadcast_to(np.where(ok, log_dadw, _NEG_INF), points.shape[:-1]).copy()


# ---------------------------------------------------------------------------------------------
# the sampling step


def sample_view(rng: np.random.Generator, phi, sigma: float, n: int, prior: str, window):
    """Camera poses of one view sampled near its locus arc under bearing noise.

    ``phi``: (3,) measured [phi_A, phi_B, phi_C]. Bearings to A and B are perturbed with
    N(0, sigma^2); each perturbed pair defines a locus arc (``gamma = phi_B - phi_A``) on which a
    position is drawn at a stratified-uniform parameter w (:func:`arc_parameter`); the heading
    follows from phi_A.
    Returns ``(poses (n, 3), logw (n,))``, logw the prior importance weight (-inf = invalid).
    """
    pa = phi[0] + sigma * rng.standard_normal(n)
    pb = phi[1] + sigma * rng.standard_normal(n)
    u = (rng.permutation(n) + rng.random(n)) / n
    gamma = wrap_angle(pb - pa)
    a, log_dadw = arc_parameter(gamma, u)
    X = locus_point(gamma, a)
    alpha = heading_on_locus(X, pa)
    logw = log_camera_prior(X, gamma, log_dadw, prior, window)
    return np.concatenate([X, alpha[:, None]], axis=-1), logw


def arc_poses(phi_a, phi_b, w, prior: str, window):
    """Camera poses on the exact locus arcs of bearings ``phi_a``, ``phi_b`` (T,) at arc
    parameters ``w`` (T, K) in (0, 1) (:func:`arc_parameter`). Returns ``(poses (T, K, 3),
    logw (T, K))`` with logw the prior importance weight per unit of w."""
    pa = np.asarray(phi_a, dtype=float)[..., None]
    gamma = wrap_angle(np.asarray(phi_b, dtype=float)[..., None] - pa)
    a, log_dadw = arc_parameter(gamma, w)
    X = locus_point(gamma, a)
    alpha = heading_on_locus(X, pa)
    logw = log_camera_prior(X, gamma, log_dadw, prior, window)
    return np.concatenate([X, alpha[..., None]], axis=-1), logw


def arc_grid(phi_a, phi_b, n: int, prior: str, window):
    """:func:`arc_poses` at the midpoints of n equal steps of w, for every arc of (...)."""
    w = np.broadcast_to((np.arange(n) + 0.5) / n, np.shape(phi_a) + (n,))
    return arc_poses(phi_a, phi_b, w, prior, window)


def ray_window_span(origin, angle, window):
    """Parameters ``[t_in, t_out]`` (t >= 0) where rays ``origin + t u(angle)`` are inside the
    window (slab method); ``t_out <= t_in`` where a ray misses it."""
    xmin, xmax, ymin, ymax = window
    ux, uy = np.cos(angle), np.sin(angle)
    t_in = np.zeros(np.broadcast_shapes(np.shape(angle), origin.shape[:-1]))
    t_out = np.full_like(t_in, np.inf)
    for o, u, lo, hi in ((origin[..., 0], ux, xmin, xmax), (origin[..., 1], uy, ymin, ymax)):
        par = np.abs(u) < 1e-15
        su = np.where(par, 1.0, u)
        t1, t2 = (lo - o) / su, (hi - o) / su
        tlo, thi = np.minimum(t1, t2), np.maximum(t1, t2)
        inside = (o >= lo) & (o <= hi)
        tlo = np.where(par, np.where(inside, -np.inf, np.inf), tlo)
        thi = np.where(par, np.where(inside, np.inf, -np.inf), thi)
        t_in = np.maximum(t_in, tlo)
        t_out = np.minimum(t_out, thi)
    return t_in, t_out


def landmarks_on_rays(origins, angles, q, window):
    """C positions along lines of sight for a single view, under a uniform prior in ``window``.

    In polar coordinates about the camera ``dL = t dt dtheta``, so along a ray C has density
    proportional to t on the part of the ray inside the window. ``q`` (..., k) in [0, 1) are the
    quantiles to place samples at: ``t = sqrt(t_in^2 + q (t_out^2 - t_in^2))``. Returns
    ``(points (..., k, 2), log_mass (...))`` with mass ``(t_out^2 - t_in^2) / 2`` the prior mass
    of that ray (-inf where the ray misses the window).
    """
    t_in, t_out = ray_window_span(origins, angles, window)
    hit = t_out > t_in
    ti2 = np.where(hit, t_in, 0.0) ** 2
    to2 = np.where(hit, t_out, 1.0) ** 2
    t = np.sqrt(ti2[..., None] + q * (to2 - ti2)[..., None])
    u = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    pts = origins[..., None, :] + t[..., None] * u[..., None, :]
    with np.errstate(divide="ignore"):
        log_mass = np.where(hit, np.log(np.maximum(0.5 * (to2 - ti2), 1e-300)), _NEG_INF)
    return pts, log_mass


def landmarks_on_rays_world(origins, angles, q):
    """As :func:`landmarks_on_rays` under the ``"world"`` prior: ``t = tau q / (1 - q)`` with
    ``tau = max(1, |O - centre|)`` and weight ``p(L) t dt/dq`` (importance sampling of the ray
    integral of ``p(L) t dt``). Returns ``(points (..., k, 2), log_weight (..., k))``."""
    tau = np.maximum(1.0, np.linalg.norm(origins - WORLD_CENTRE, axis=-1))[..., None]
    t = tau * q / (1.0 - q)
    u = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    pts = origins[..., None, :] + t[..., None] * u[..., None, :]
    lw = log_point_prior(pts, "world", None) + np.log(t) + np.log(tau) - 2 * np.log1p(-q)
    return pts, lw


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


def make_estimate(method, part, n_views, landmark, cameras, *, hypotheses: Hypotheses,
                  reasons=(), mc_error=float("nan"), opts) -> tuple[TripletEstimate, Hypotheses]:
    """The (answer, hypotheses) pair every solver's ``finish`` returns."""
    lw = hypotheses.landmark_weights
    est = TripletEstimate(
        landmark=np.asarray(landmark, dtype=float), cameras=np.asarray(cameras, dtype=float),
        n_hypotheses=int(np.count_nonzero(lw > 0)), degenerate=bool(reasons),
        reason="; ".join(reasons), method=method, partition=part.name, n_views=int(n_views),
        ess=ess(lw), mc_error=float(mc_error), prior=prior_name(opts),
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


def nominal_degenerate(bearings) -> list[int]:
    """Views whose measured bearings put the camera on line AB (|sin(phi_B - phi_A)| tiny)."""
    g = wrap_angle(bearings[:, 1] - bearings[:, 0])
    return [int(i) for i in np.flatnonzero(np.abs(np.sin(g)) < LOCUS_EPS)]


def logsumexp(a, axis=-1) -> np.ndarray:
    """``log(sum(exp(a)))`` along ``axis``; -inf where every entry is -inf (no warning)."""
    a = np.asarray(a, dtype=float)
    mx = np.max(a, axis=axis, keepdims=True, initial=-np.inf)
    ok = np.isfinite(mx)
    s = np.sum(np.exp(a - np.where(ok, mx, 0.0)), axis=axis, keepdims=True)
    with np.errstate(divide="ignore"):
        out = np.where(ok, mx + np.log(np.where(ok, s, 1.0)), -np.inf)
    return np.squeeze(out, axis=axis)
