"""Checks of one triplet's measurements (bearings, headings, odometry distances, noise sigmas);
ValueError naming the argument for bad input.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import partitions as _partitions
from ..._validate import as_float_array, non_negative, per_step_sigma
from ...geometry import wrap_angle


@dataclass(frozen=True)
class Measurements:
    """Validated measurements of one triplet: bearings (n, 3), headings (n - 1,) or None, and
    the odometry's travelled distances (n - 1,) (0 = unknown) with the noise of their log
    ratios, or None (used by the SIS methods and the reference). ``step_sigma_heading`` (n - 1,): each step's
    heading sigma when they differ (``sigma_heading`` is then their largest), else None."""

    bearings: np.ndarray
    headings: np.ndarray | None
    sigma_bearing: float
    sigma_heading: float
    distances: np.ndarray | None = None
    sigma_distance_ratio: float | None = None
    step_sigma_heading: np.ndarray | None = None

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


def check_heading_sigma(value, n_views: int) -> tuple[float, np.ndarray | None]:
    """``sigma_heading`` as one number or one per step (:func:`qfg._validate.per_step_sigma`),
    capped at :data:`SIGMA_CAP`: (the largest, the (n - 1,) steps' values or None when they are
    all equal).

    >>> check_heading_sigma([0.1, 0.3], 3)
    (0.3, array([0.1, 0.3]))
    >>> check_heading_sigma([0.2, 0.2], 3)
    (0.2, None)
    """
    v = per_step_sigma("sigma_heading", value, max(n_views - 1, 0))
    if np.ndim(v) == 0:
        return check_sigma("sigma_heading", v), None
    v = np.minimum(v, SIGMA_CAP)
    if v.size == 0 or np.all(v == v[0]):
        return (float(v[0]) if v.size else 0.0), None
    return float(v.max()), v


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
    from ...simulation import TripletHistory

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
    sh, steps = check_heading_sigma(sh, b.shape[0])
    return Measurements(bearings=b, headings=h, sigma_bearing=check_sigma("sigma_bearing", sb),
                        sigma_heading=sh, distances=d,
                        sigma_distance_ratio=check_distance_sigma(sigma_distance_ratio, d),
                        step_sigma_heading=steps)


def get_partition(partition):
    return _partitions.get(partition)
