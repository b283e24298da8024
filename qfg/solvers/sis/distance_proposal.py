"""The motion step's proposal from the odometry: triplets with distances draw some of their
children at the step length the distance ratio predicts (a circle about X_(i-1) meets the locus
arc) or from the odometry alone (heading and step length), instead of along the heading's ray,
weighted by the balance heuristic over the three proposals (:func:`mixture_weight`).
"""

from __future__ import annotations

import numpy as np

from ...geometry import wrap_angle
from ..common import arcs as _arcs
from ..common import likelihood as _likelihood
from ..common.odometry import log_distance_factor
from .state import SISState

#: Heading noise (radians) up to which the motion step also proposes children from the distance
#: ratio: above it the heading's wrapped normal is no longer the plain normal the mixture
#: density evaluates.
_MIX_MAX_SIGMA_HEADING = 0.5


#: Whether triplets with distances draw some of their motion-step children from the step-length
#: ratio and the odometry (a switch for the tests, which compare the proposals).
_MIX_DISTANCE_PROPOSAL = True


#: Shares of a mixed parent's motion-step draws (ray, circle, odometry) (:func:`mix_counts`;
#: the ray takes what the floors of the other two leave).
_MIX_SHARES = (0.375, 0.25, 0.375)


def is_mixed(state: SISState, ct, r, spread) -> np.ndarray:
    """(B,) children (of triplets ``ct``) proposed by the two-component mixture of
    :func:`mixture_weight`: the triplet has a step-length-ratio factor at this view, the
    noise is drawn at the model's width, and its heading noise is within
    (0, :data:`_MIX_MAX_SIGMA_HEADING`]."""
    if not _MIX_DISTANCE_PROPOSAL or state.n_views < 2 or spread != 1.0 \
            or not np.any(state.distances[:, -1] > 0):
        return np.zeros(ct.size, dtype=bool)
    d = state.distances[ct]
    sh = state.current_sigma(ct)
    htail = state.opts.get("heading_tail")
    if htail is not None:
        # the mixture's wide component must stay a plain (unwrapped) normal too
        sh = sh * htail.scale
    return (d[:, -1] > 0) & (d[:, -2] > 0) & (r[ct] >= 2) & (sh > 0) \
        & (sh <= _MIX_MAX_SIGMA_HEADING)


def prev_step(state: SISState, par) -> np.ndarray:
    """(B,) length of the last step of hypotheses ``par`` (AB units)."""
    last, up = state.levels[-1]
    return np.hypot(*(last[par, :2] - state.levels[-2][0][up[par], :2]).T)


def ratio_step(state: SISState, par, ct, z) -> np.ndarray:
    """(B,) step lengths drawn from the distance ratio for parents ``par`` of triplets ``ct``:
    the parent's last step times ``d_i / d_(i-1)`` times ``exp(sigma_d z)``, ``z`` (B,) standard
    normals."""
    return prev_step(state, par) * state.distances[ct, -1] / state.distances[ct, -2] \
        * np.exp(state.sigma_distance[ct] * z)


def circle_arc_intersection(origin, radius, center, arc_radius, side):
    """Points at distance ``radius`` (B,) from ``origin`` (B, 2) on locus arcs (centre (B, 2),
    radius (B,), side (B,) as :func:`qfg.geometry.ray_circle_intersection`): (points (B, 2, 2),
    valid (B, 2)); invalid slots hold the origin."""
    q = center - origin
    dd = np.hypot(q[:, 0], q[:, 1])
    R = np.where(np.isfinite(arc_radius), arc_radius, 0.0)
    ok = np.isfinite(arc_radius) & (radius > 0) & (dd > 0) & (dd <= radius + R) \
        & (dd >= np.abs(radius - R))
    dsafe = np.where(ok, dd, 1.0)
    a = (radius * radius - R * R + dsafe * dsafe) / (2.0 * dsafe)
    h = np.sqrt(np.maximum(radius * radius - a * a, 0.0))
    ex, ey = q[:, 0] / dsafe, q[:, 1] / dsafe
    pts = np.repeat(origin[:, None, :], 2, axis=1)
    valid = np.zeros((origin.shape[0], 2), dtype=bool)
    for k, sgn in enumerate((1.0, -1.0)):
        px = origin[:, 0] + a * ex - sgn * h * ey
        py = origin[:, 1] + a * ey + sgn * h * ex
        v = ok & ((side * px) < 0)
        pts[:, k, 0], pts[:, k, 1] = np.where(v, px, origin[:, 0]), np.where(v, py, origin[:, 1])
        valid[:, k] = v
    return pts, valid


def mix_counts(state: SISState, ct, r):
    """(n_circ, n_odo) (B,): of the ``r`` draws of a mixed parent (triplets ``ct``), how many
    come from the distance ratio's circle and how many from the odometry alone
    (:data:`_MIX_SHARES`; no odometry draws with noiseless bearings, whose B bearing such a
    draw cannot meet); the rest follow the heading's ray."""
    rr = r[ct]
    n_circ = np.floor(rr * _MIX_SHARES[1]).astype(rr.dtype)
    n_odo = np.where(state.sigma_bearing[ct] > 0,
                     np.floor(rr * _MIX_SHARES[2]).astype(rr.dtype), 0)
    return n_circ, n_odo


def mixture_weight(state: SISState, X, prev, psi, r, par, phi, alpha):
    """Log of the target's view-i factors over the proposal density, for children ``X`` (K, 2)
    of parents ``par`` whose triplets propose them from a mixture (:func:`mix_counts`):
    ``n_ray`` draws along the heading (ray, meeting the drawn locus arc), ``n_circ`` at the
    step length of the distance ratio (circle, meeting the arc) and ``n_odo`` from the
    odometry alone (heading and step length); ``alpha`` (K,) the children's camera headings
    (each from its drawn A bearing). Over (position, alpha), with the A bearing's density (common to
    all three) and the prior left out,

        q_ray  = L_B N(theta(X) - theta*; sigma_w) |grad Gamma . u| / t
        q_circ = L_B N(log t - log t*; sigma_d) |grad Gamma . u_perp| / t
        q_odo  = N(theta(X) - theta*; sigma_w) N(log t - log t*; sigma_d) / t^2

    (t = |X - X_(i-1)|, u its direction, theta* = alpha_(i-1) + psi, t* the previous step times
    the distance ratio, L_B the B bearing's likelihood at (X, alpha), ``phi`` (T, 3) the
    view's bearings), and the target's factors are L_B and those two Gaussians (with a
    ``distance_tail`` the target's distance factor is its mixture, the circle's and the
    odometry's density still the core normal they draw from; with a heading tail the heading
    density is its mixture, which the ray and the odometry draw from): returns
    ``log(L_B N_theta F / q_mix)``, ``q_mix = (n_ray q_ray + n_circ q_circ + n_odo q_odo) / r``
    (balance heuristic). Without odometry draws L_B cancels and is not evaluated (noiseless
    bearings); with the circle left out as well it is the ray-only ``F t / |grad Gamma . u|``.
    A parent whose last step is 0 draws no circle or odometry children (q = 0 there)."""
    ct = state.tid[par]
    O = prev[par, :2]
    dx, dy = X[:, 0] - O[:, 0], X[:, 1] - O[:, 1]
    t = np.hypot(dx, dy)
    th = np.arctan2(dy, dx)
    sh, sd = state.current_sigma(ct), state.sigma_distance[ct]
    half_log_2pi = 0.5 * np.log(2.0 * np.pi)
    htail = state.opts.get("heading_tail")
    if htail is None:
        log_n_th = _likelihood.log_gauss(wrap_angle(th - prev[par, 2] - psi[ct]), sh) \
            - half_log_2pi
    else:
        # the ray children's heading density and the target's heading factor: the mixture
        log_n_th = _likelihood.log_bearing(wrap_angle(th - prev[par, 2] - psi[ct]), sh, htail)
    sp = prev_step(state, par)
    dist = state.distances[ct, -1], state.distances[ct, -2]
    # the circle and odometry draws come from the core normal; with a distance tail the
    # target's factor is the wider mixture (the ray draws cover its tail)
    log_q_f = log_distance_factor(t, sp, *dist, sd)
    tail = state.opts.get("distance_tail")
    log_f = log_q_f if tail is None else log_distance_factor(t, sp, *dist, sd, tail)
    lj_ray = _arcs.log_ray_jacobian(X, O, th)   # log t - log |grad Gamma . u|
    # log t - log |grad Gamma . u_perp|: the ray Jacobian along u_perp from one unit back
    perp = np.stack([-np.sin(th), np.cos(th)], axis=1)
    with np.errstate(divide="ignore"):
        lj_circ = np.log(t) + _arcs.log_ray_jacobian(X, X - perp, th + 0.5 * np.pi)
    log_q_ray = log_n_th - lj_ray
    log_q_circ = np.where(sp > 0, log_q_f - lj_circ, -np.inf)
    rr = r[ct].astype(float)
    n_circ, n_odo = (c.astype(float) for c in mix_counts(state, ct, r))
    n_ray = rr - n_circ - n_odo
    odo = n_odo > 0
    log_b = np.zeros(X.shape[0])
    if np.any(odo):
        # the B bearing's likelihood at (X, alpha)
        rb = wrap_angle(phi[ct, 1] - (np.arctan2(1.0 - X[:, 1], -X[:, 0]) - alpha))
        log_b = np.where(odo, _likelihood.log_bearing(rb, state.sigma_bearing[ct],
                                                      state.opts.get("bearing_tail")), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_q_odo = np.where(odo & (sp > 0), log_n_th + log_q_f - 2.0 * np.log(t), -np.inf)
        log_mix = np.logaddexp(np.log(n_ray / rr) + log_q_ray,
                               np.log(n_circ / rr) + log_q_circ)
        # L_B multiplies the arc's two proposals and the target: it cancels without odometry
        # draws (log_b = 0 there)
        log_mix = np.logaddexp(log_b + log_mix, np.log(n_odo / rr) + log_q_odo)
        out = log_b + log_n_th + log_f - log_mix
    return np.where(np.isnan(out), -np.inf, out)
