"""Ray and arc geometry of camera and landmark hypotheses: positions on the locus arcs of (phi_A,
phi_B), points along lines of sight, and the change-of-variables densities that make them
importance samples.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians; lengths in |AB|.
"""

from __future__ import annotations

import numpy as np

from ...geometry import LOCUS_EPS, heading_on_locus, locus_point, wrap_angle
from .likelihood import NEG_INF, log_gauss
from .prior import point_log_prior

#: Scale of the heavy-tailed distance proposal along lines of sight (|AB| units).
RAY_CENTRE = np.array([0.0, 0.5])

_TWO_PI = 2.0 * np.pi


def cos_sin(angle):
    """``(cos(angle), sin(angle))`` from one tangent of the half angle ``t = tan(angle / 2)``:
    ``cos = (1 - t^2) / (1 + t^2)``, ``sin = 2 t / (1 + t^2)``, within 4.5e-16 of ``np.cos`` and
    ``np.sin`` (``tests/test_sis_fast_math.py``). numpy's float64 sine and
    cosine are scalar library calls, about 15 times the cost of its vectorised tangent, and the
    motion step takes one pair per child.

    >>> [round(float(v), 12) for v in cos_sin(np.pi / 3)]
    [0.5, 0.866025403784]
    """
    t = np.tan(0.5 * np.asarray(angle, dtype=float))
    t2 = t * t
    d = 1.0 + t2
    c = 1.0 - t2
    c /= d
    t += t
    t /= d
    return c, t


def wrap(angle):
    """``angle - 2 pi k`` with k the nearest integer to ``angle / 2 pi``: in [-pi, pi], the value
    of :func:`qfg.geometry.wrap_angle` up to rounding (about 1e-15 for |angle| < 10; at exactly
    -pi it may keep -pi where that gives pi), for angles only squared or fed to trigonometric
    functions. ``np.mod`` costs about 15 times ``np.rint``.

    >>> float(wrap(3 * np.pi / 2)), float(wrap(0.25))
    (-1.5707963267948966, 0.25)
    """
    a = np.asarray(angle, dtype=float)
    k = np.rint(a * (1.0 / _TWO_PI))
    k *= _TWO_PI
    return a - k


def ray_points(origins, angles, eps, v, sigma):
    """C along lines of sight: ``L = O + r u(theta + eps)`` with ``r = tau v / (1 - v)`` (v in
    (0, 1)) and ``tau = max(1, |O - (0, 1/2)|)`` (the distance scale of the world). ``origins``
    (..., 2), ``angles`` (...), ``eps`` and ``v`` (..., k) -> ``(L (..., k, 2), log q (..., k))``
    with q the density over positions when ``eps ~ N(0, sigma^2)`` and v is uniform:
    ``N(eps; sigma) tau / (tau + r)^2 / r`` (polar coordinates about O)."""
    tau = np.maximum(1.0, np.linalg.norm(origins - RAY_CENTRE, axis=-1))[..., None]
    v = np.clip(v, 1e-12, 1 - 1e-12)
    r = tau * v / (1.0 - v)
    th = np.asarray(angles)[..., None] + eps
    L = origins[..., None, :] + r[..., None] * np.stack(cos_sin(th), axis=-1)
    return L, ray_log_density_polar(eps, r, tau, sigma)


def ray_log_density_polar(eps, r, tau, sigma):
    """log q of :func:`ray_points` at angular offset ``eps`` and distance ``r``."""
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
        return a, np.where(dadw > 0, np.log(np.where(dadw > 0, dadw, 1.0)), NEG_INF)


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
    return np.where(ok, out, NEG_INF)


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
    return np.where(ok, out, NEG_INF)


def ray_locus(origin, angle, phi_a, phi_b):
    """Where rays from ``origin`` (B, 2) at ``angle`` (B,) meet the locus arcs of bearings
    ``phi_a``, ``phi_b`` (B,): :func:`qfg.geometry.ray_circle_intersection` on
    :func:`qfg.geometry.locus_circle` in one pass, with one :func:`cos_sin` per circle and per
    ray (the same points up to rounding). The circle has centre ``(-cot(gamma) / 2, 1/2)`` and
    radius ``1 / (2 |sin gamma|)`` (gamma = phi_b - phi_a); a point is kept on the camera's side
    of AB (x of the sign opposite to sin gamma) at t > 0 along the ray.

    Returns (points (B, 2, 2) ordered by t, valid (B, 2), the ray directions (cos, sin) (B,)
    each); invalid slots hold the origin.

    >>> pts, ok, u = ray_locus(np.array([[-2.0, 0.5]]), np.array([0.0]), np.array([-np.pi / 2]),
    ...                        np.array([0.0]))   # the arc of AB's circle of diameter 1 at x < 0
    >>> np.round(pts[0, ok[0]], 9).tolist()
    [[-0.5, 0.5]]
    """
    ox, oy = origin[:, 0], origin[:, 1]
    cg, sg = cos_sin(np.asarray(phi_b, dtype=float) - phi_a)
    ux, uy = cos_sin(angle)
    finite = np.abs(sg) >= LOCUS_EPS
    s_safe = np.where(finite, sg, 1.0)
    inv = 0.5 / s_safe
    qx = ox + cg * inv                          # origin - centre
    qy = oy - 0.5
    b = ux * qx + uy * qy
    cc = qx * qx + qy * qy - inv * inv
    disc = b * b - cc
    hit = finite & (disc >= 0)
    sq = np.sqrt(np.where(hit, disc, 0.0))
    pts = np.empty(ox.shape + (2, 2))
    valid = np.empty(ox.shape + (2,), dtype=bool)
    for k, t in enumerate((-b - sq, -b + sq)):
        v = hit & (t > 0)
        px, py = ox + t * ux, oy + t * uy
        v &= (sg * px) < 0
        pts[:, k, 0], pts[:, k, 1] = np.where(v, px, ox), np.where(v, py, oy)
        valid[:, k] = v
    return pts, valid, (ux, uy)


def log_ray_jacobian_u(X, O, ux, uy) -> np.ndarray:
    """:func:`log_ray_jacobian` for points ``X`` (K, 2) on rays from ``O`` (K, 2) with unit
    directions ``(ux, uy)`` (K,) already at hand (:func:`ray_locus`)."""
    x, y = X[:, 0], X[:, 1]
    t = (x - O[:, 0]) * ux + (y - O[:, 1]) * uy
    ra = x * x + y * y
    by = 1.0 - y
    rb = x * x + by * by
    ok = (ra > 0) & (rb > 0)
    ra, rb = np.where(ok, ra, 1.0), np.where(ok, rb, 1.0)
    # grad Gamma = (by / rb + y / ra, x / rb - x / ra) with a = A - X, b = B - X
    dot = np.abs((by / rb + y / ra) * ux + (x / rb - x / ra) * uy)
    ok &= (dot > 1e-300) & (t > 0)
    with np.errstate(divide="ignore"):
        out = np.log(np.where(ok, t, 1.0)) - np.log(np.where(ok, dot, 1.0))
    return np.where(ok, out, NEG_INF)


def log_camera_prior(points, gamma, log_dadw, prior) -> np.ndarray:
    """Intermediate importance log-weight of arc samples: the arc's change of variables times
    the per-point prior (:func:`point_log_prior`)."""
    return log_arc_jacobian(points, gamma, log_dadw) + point_log_prior(prior, points)


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
