"""Sampling C given camera trajectories: the defensive mixture of the Laplace Gaussian and draws
along the lines of sight, with its exact density.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians; lengths in |AB|.
"""

from __future__ import annotations

import numpy as np

from ..common.arcs import RAY_CENTRE, ray_log_density_polar, ray_points, wrap
from ..common.laplace import CHUNK_ROWS, depth_spread, triangulate
from ..common.likelihood import log_bearing, logaddexp, logsumexp, sum_views


def sample_landmarks(rng, poses, phi_c, sigma, k: int, ray_fraction: float, draws=None,
                     laplace=None, tail=None):
    """C samples for each camera trajectory, from a defensive mixture: a Gaussian about the
    least-squares triangulation with covariance ``(1.5 sigma)^2 H^-1`` (``H = sum_t g_t g_t^T``,
    ``g_t = grad_L f(L, X_t)``; the Laplace approximation of C's conditional, inflated) and, for
    a share ``ray_fraction`` of the samples (all of them with one view), :func:`ray_points` along
    the line of sight of a view chosen uniformly. The mixture density is evaluated exactly, so
    ``exp(log prior + log lik - log q)`` is an unbiased estimate of C's integral for every
    geometry, including lines of sight that coincide (C's depth then comes from the prior).

    ``poses`` (J, n, 3), ``phi_c`` (n,) or (J, n), ``sigma`` > 0 (scalar or (J,)); the random
    numbers come from ``rng`` or, if given, ``draws`` (dict: ``z`` (J, kg, 2) and ``eps`` (J, kr)
    standard normals, ``t`` (J, kr) views, ``u`` (J, kr) uniforms); ``laplace``: the
    triangulation and ``H`` of these rows if already computed (:func:`laplace_landmark` with
    ``parts``). Returns ``L (J, k, 2)``, ``log q
    (J, k)``, ``log lik (J, k)`` (sum over views of the normalized Gaussian C-bearing
    likelihood; with ``tail`` a :class:`.likelihood.BearingTail`, its mixture) and the depth
    spread ``(J,)``: the standard deviation of C along its least
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
            None if laplace is None else tuple(v[sl] for v in laplace), tail)
    return L, log_q, log_lik, spread


def _sample_landmarks_rows(poses, phi_c, sig, kg, kr, draws, laplace=None, tail=None):
    """:func:`sample_landmarks` on one block of rows."""
    J, n = poses.shape[:2]
    k = kg + kr
    X = poses[..., :2]
    theta = poses[..., 2] + phi_c
    L = np.empty((J, k, 2))
    spread = np.full(J, np.inf)
    # the proposal's width: with a tail, as wide as its mixture's normal part
    sq = sig if tail is None else sig * tail.width_factor
    c2 = (1.5 * sq) ** 2
    if kg:
        Ls, ok, h00, h01, h11, det, r2min = triangulate(X, theta) if laplace is None else laplace
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
        eps = sq[:, None] * draws["eps"]
        v = (np.arange(kr) + draws["u"]) / kr
        Lr, _ = ray_points(X[jj, t], theta[jj, t], eps[..., None], v[..., None],
                           sq[:, None, None])
        L[:, kg:] = Lr[..., 0, :]
    # per view: distance and angular residual of every sample, views along the first axis
    # (n, J, k) so that the sums over views are adds of contiguous blocks
    ddx = L[:, :, 0][None] - X[..., 0].T[:, :, None]
    ddy = L[:, :, 1][None] - X[..., 1].T[:, :, None]
    res = np.arctan2(ddy, ddx)
    res -= theta.T[:, :, None]
    res = wrap(res)
    if tail is None:
        log_lik = -0.5 * sum_views(res * res) / (sig * sig)[:, None] - n * (
            np.log(sig) + 0.5 * np.log(2 * np.pi))[:, None]
    else:
        log_lik = sum_views(log_bearing(res, sig[None, :, None], tail))
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
        lr = ray_log_density_polar(res, r, tau.T[:, :, None], sq[None, :, None])
        logs.append(np.log(kr / k) + logsumexp(lr, axis=0) - np.log(n))
    log_q = logs[0] if len(logs) == 1 else logaddexp(logs[0], logs[1])
    return L, log_q, log_lik, spread
