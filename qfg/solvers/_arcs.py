"""Ray and arc geometry of camera and landmark hypotheses: positions on the locus arcs of (phi_A,
phi_B), points along lines of sight, and the change-of-variables densities that make them
importance samples.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians; lengths in |AB|.
"""

from __future__ import annotations

import numpy as np

from ..geometry import LOCUS_EPS, heading_on_locus, locus_point, wrap_angle
from ._likelihood import NEG_INF, log_gauss
from ._prior import point_log_prior

#: Scale of the heavy-tailed distance proposal along lines of sight (|AB| units).
RAY_CENTRE = np.array([0.0, 0.5])


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
    L = origins[..., None, :] + r[..., None] * np.stack([np.cos(th), np.sin(th)], axis=-1)
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
