"""The reference's conditional sampler (``sampler="conditional"``): the exact posterior by
importance sampling of ``(C, trajectory)``, Rao-Blackwellised around C, at a cost linear in the
number of views.

Model (the same as :mod:`.staged`, AB frame): configuration ``(C, X_1, alpha_1, ..,
X_n, alpha_n)``, prior ``prior(C, X_1..X_n) (2 pi)^-n`` (headings uniform), bearings
``phi_{j,P} ~ WN(atan2(P - X_j) - alpha_j, sigma_v^2)`` for P in {A, B, C}, headings
``psi_j ~ WN(atan2(X_{j+1} - X_j) - alpha_j, sigma_w^2)``.

Given C every pose is fixed by its three bearings (a resection: the second intersection of the
locus circles of AB and AC, both through A, in closed form by inversion about A), and the
headings chain consecutive poses. So, for a draw of C:

* the trajectory's conditional ``p(X, alpha | C, z)`` is approximated by a Gaussian about its
  mode in *arc coordinates* ``t_j = (a_j, g_j, alpha_j)`` (the angle at A along the view's AB
  locus arc, the angle AB subtends, the heading: the A and B bearings are linear in them, so a
  camera that its own bearings leave spread along its locus circle, near the circle through
  A, B and C, is a straight line there, not a banana; views with a camera near line AB keep
  (x, y)). The mode is found by Levenberg-Marquardt from the resection (or, where a heading
  leads in, the heading ray's points on the locus circle); the information ``J^T J`` is
  block-tridiagonal (3 x 3 blocks: the bearings of a view on the diagonal, each heading coupling
  views j and j + 1) and factored by a block Cholesky (a forward filter pass);
* trajectories are drawn by a particle filter backwards along the views, K particles per C,
  each step drawing ``t_j`` from the Gaussian's conditional given ``t_{j+1}`` (backward
  sampling) and weighting by the exact factors of view j and its outgoing heading, twisted by
  the Gaussian message of the earlier views; resampling after every view keeps the error of the
  Gaussian from compounding over views. The targets carry the prior of the points seen so far
  (:func:`intermediate_prior`), the last one the exact prior of the whole configuration, so the
  world box's coupling of every point (its scale) is corrected view by view, with resampling;
  the filter's evidence estimate Z (unbiased) over q(C) is an exact importance weight;
* C is drawn from a 2-D mixture of t components fitted by weighted EM to draws weighted by the
  Laplace marginal ``p(C, X*, alpha*, z) (2 pi)^(3n/2) det(J^T J)^(-1/2)`` (arc Jacobians
  included), reached from the heavy-tailed product prior by adaptive tempering over stages of
  3, 6, 12, .. views (the tempered target ``q_ref^(1 - b) p^b``, b raised while 30% of the draws
  where p > 0 stay effective), with defensive shares of a widened mixture and of the product prior
  (support everywhere);
* draws outside the arc domain or with a heading outside ``(alpha*_j - pi, alpha*_j + pi]``
  get weight 0 (a defective proposal: still exact, the window covers the circle once).

Whatever the quality of the approximations, this is an importance sampler of the exact
posterior; their quality shows in the ESS and the Pareto k. Rounds of final draws are added
until the ESS reaches ``ess_goal`` (at most ``final_rounds``) and combined by ESS
(:func:`.weights._combine`).
"""

from __future__ import annotations

from math import lgamma

import numpy as np

from ... import priors as _priors
from ...geometry import locus_circle, ray_circle_intersection, wrap_angle
from ..common.likelihood import logsumexp
from .weights import _log_wn, _summaries, final_answer

__all__ = ["RB_DEFAULTS", "solve_rb", "resect", "fit_trajectories", "log_joint"]

#: Options of the conditional-Laplace sampler (keys of the reference solver's options).
RB_DEFAULTS = {
    "rb_samples": 1000,        # C draws per final round (and per tempering round)
    "particles": 16,           # trajectories per C draw (the particle filter given C)
    "final_rounds": 6,         # most final rounds (stops once the ESS reaches ess_goal)
    "ess_goal": 500.0,         # total ESS wanted from the final rounds
    "tempering_rounds": 12,    # most rounds of the adaptive tempering of C's proposal
    "tempering_samples": 500,  # C draws per tempering round
    "tempering_ess": 0.3,      # share of effective draws kept when the temperature is raised
    "gn_iters": 40,            # most Levenberg-Marquardt iterations of the conditional mode
    "components": 6,           # components of C's mixture
    "refit": False,            # refit half of C's mixture to each final round's weighted draws
}

_LOG2PI = np.log(2 * np.pi)
#: Degrees of freedom and scale inflation of C's t components; defensive shares of the widened
#: (x WIDE in standard deviation) mixture and of the product prior.
C_DOF, C_INFLATE, WIDE, P_WIDE, P_PRIOR = 5.0, 1.3, 4.0, 0.05, 0.02
#: Precision added to every pose's diagonal block (arc coordinates and heading, radians): keeps
#: the Gaussian proper (standard deviations under pi / 2) when a view leaves its pose
#: unresolved (a camera on line AB); the proposal only, never the target.
ARC_PRECISION = ALPHA_PRECISION = 1.0 / (np.pi / 2) ** 2


def _quiet(f):
    """Run f with numpy's floating-point warnings off: draws whose fit degenerates (a singular
    block, a step out of the arc domain) give inf/NaN that are masked to weight 0 explicitly."""
    import functools

    @functools.wraps(f)
    def g(*args, **kwargs):
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            return f(*args, **kwargs)
    return g


# ---------------------------------------------------------------------------------------------
# the joint target


def log_joint(L, prior, C, X, alpha):
    """Exact log target ``log p(C, X, alpha, z)`` (radians and |AB| units): C (N, 2), X (N, n, 2),
    alpha (N, n) -> (N,); -inf where the prior is 0."""
    lik = _log_lik(L, C, X, alpha)
    pts = np.concatenate([C[:, None, :], X], axis=1)
    lp = prior.log_density(pts)
    out = lp - L.n * _LOG2PI + lik
    return np.where(np.isnan(out), -np.inf, out)


def _log_lik(L, C, X, alpha):
    out = np.zeros(C.shape[0])
    for k, P in enumerate(_landmarks(C)):
        d = P - X
        pred = np.arctan2(d[..., 1], d[..., 0]) - alpha
        out += np.sum(_log_wn(L.phi[None, :, k] - pred, L.sv), axis=1)
    if L.psi is not None:
        d = X[:, 1:] - X[:, :-1]
        pred = np.arctan2(d[..., 1], d[..., 0]) - alpha[:, :-1]
        out += np.sum(_log_wn(L.psi[None, :] - pred, L.sw), axis=1)
    return out


def _landmarks(C):
    return (np.zeros((1, 1, 2)), np.array([[[0.0, 1.0]]]), C[:, None, :])


# ---------------------------------------------------------------------------------------------
# resection and the conditional Gaussian


def resect(L, C):
    """Poses fixed by each view's three bearings given C (N, 2): X (N, n, 2), alpha (N, n).

    With A at the origin, the inversion w = 1/X maps the locus circle of A and P (the points that
    see P at the angle ``g = phi_P - phi_A`` from A) to the ray ``w = (1 - rho e^{ig}) / P``,
    rho > 0; the camera is where the rays of B and C meet (a 2 x 2 linear solve).

    >>> import numpy as np
    >>> from qfg.geometry import bearing
    >>> from qfg.solvers.reference.staged import _Layout
    >>> C, P = np.array([0.7, 0.4]), np.array([-0.8, 1.9, 0.3])
    >>> phi = np.array([[bearing(P, np.zeros(2)), bearing(P, np.array([0.0, 1.0])), bearing(P, C)]])
    >>> X, al = resect(_Layout(phi, None, 0.01, 0.01), C[None])
    >>> np.round(X[0, 0], 6).tolist(), round(float(al[0, 0]), 6)
    ([-0.8, 1.9], 0.3)
    """
    phi = L.phi
    gb = phi[None, :, 1] - phi[None, :, 0]
    gc = phi[None, :, 2] - phi[None, :, 0]
    eb = np.exp(1j * gb)
    ec = np.exp(1j * gc)
    Bc = 1j
    Cc = (C[:, 0] + 1j * C[:, 1])[:, None]
    Cc = np.where(np.abs(Cc) > 1e-300, Cc, 1e-300)
    a = eb / Bc
    b = -ec / Cc
    r = 1.0 / Bc - 1.0 / Cc
    det = a.real * b.imag - a.imag * b.real
    ok = np.abs(det) > 1e-12
    sdet = np.where(ok, det, 1.0)
    rho = (r.real * b.imag - r.imag * b.real) / sdet
    w = (1.0 - rho * eb) / Bc
    w = np.where(ok & (np.abs(w) > 1e-9), w, 1e-9 + 0j)
    Xc = 1.0 / w
    # where the rays do not meet (parallel, or the camera at infinity): a point on AB's circle
    Xc = np.where(np.isfinite(Xc) & (np.abs(Xc) < 1e6), Xc, -1.0 + 0.5j)
    X = np.stack([Xc.real, Xc.imag], -1)
    alpha = np.arctan2(-X[..., 1], -X[..., 0]) - phi[None, :, 0]
    return X, alpha


@_quiet
def initial_poses(L, C):
    """Start of the conditional fit given C (N, 2): view by view, the resection or, when a
    heading leads in, one of the (at most two) points where the heading's ray from the previous
    start meets the view's AB locus circle, whichever has the smaller local cost (that view's
    three bearings and its incoming heading). The resection alone is unstable where a view is
    nearly degenerate (a camera near the circle through A, B and C, or near line AB): there its
    noisy bearings put it far off, and the heading chain then holds it in a wrong local minimum.
    Returns X (N, n, 2), alpha (N, n)."""
    X, alpha = resect(L, C)
    if L.psi is None or L.n < 2:
        return X, alpha
    circ = locus_circle(L.phi[:, 0], L.phi[:, 1])
    Pc = C[:, None, :]
    for j in range(1, L.n):
        theta = alpha[:, j - 1] + L.psi[j - 1]
        rad = np.inf if circ.degenerate[j] else circ.radius[j]
        pts, ok = ray_circle_intersection(X[:, j - 1], theta, circ.center[j], rad, circ.side[j])
        # and where the ray misses the circle (noise): the circle's point nearest to the ray
        u = np.stack([np.cos(theta), np.sin(theta)], -1)
        c = circ.center[j]
        foot = X[:, j - 1] + np.maximum(np.sum((c - X[:, j - 1]) * u, -1, keepdims=True), 0.0) * u
        dv = foot - c
        dn = np.sqrt(np.sum(dv * dv, -1, keepdims=True))
        near = c + (0.0 if circ.degenerate[j] else circ.radius[j]) * dv / np.maximum(dn, 1e-300)
        near_ok = (~circ.degenerate[j]) & (dn[:, 0] > 0) & (near[:, 0] * circ.side[j] <= 0)
        cands = np.concatenate([X[:, j, None], pts, near[:, None]], axis=1)     # (N, 4, 2)
        valid = np.concatenate([np.ones((X.shape[0], 1), bool), ok, near_ok[:, None]], axis=1)
        al = np.arctan2(-cands[..., 1], -cands[..., 0]) - L.phi[j, 0]
        cost = 0.0
        for k, P in enumerate((np.zeros((1, 1, 2)), np.array([[[0.0, 1.0]]]), Pc)):
            d = P - cands
            cost = cost + (wrap_angle(L.phi[j, k] - np.arctan2(d[..., 1], d[..., 0]) + al)
                           / L.sv) ** 2
        d = cands - X[:, j - 1, None]
        cost = cost + (wrap_angle(L.psi[j - 1] - np.arctan2(d[..., 1], d[..., 0])
                                  + alpha[:, j - 1, None]) / L.sw) ** 2
        best = np.argmin(np.where(valid & np.isfinite(cost), cost, np.inf), axis=1)
        X[:, j] = np.take_along_axis(cands, best[:, None, None], axis=1)[:, 0]
        alpha[:, j] = np.take_along_axis(al, best[:, None], axis=1)[:, 0]
    return X, alpha


def arc_coords(X):
    """Arc coordinates (a, |gamma| signed as gamma) of positions X (..., 2): the angle at A
    between AB and AX, and the angle AB subtends at X (positive left of AB). The inverse of
    :func:`arc_position`."""
    ax = np.abs(X[..., 0])
    a = np.arctan2(ax, X[..., 1])
    R = np.hypot(X[..., 0], X[..., 1])
    g = np.arctan2(np.sin(a), R - np.cos(a))
    return a, np.where(X[..., 0] <= 0, g, -g)


def arc_position(a, g):
    """Position on the locus arc of subtended angle g at angle a from AB (as
    ``geometry.locus_point``), its derivatives dX/da, dX/dg (..., 2), log |det dX/d(a, g)| =
    log(|X| sin a / sin^2 g) and whether (a, g) is in the domain ``0 < a < pi - |g|``, g != 0
    (a bijection onto the plane off line AB)."""
    sg = np.where(g < 0, -1.0, 1.0)
    ag = np.abs(g)
    valid = (ag > 1e-12) & (ag < np.pi) & (a > 0) & (a < np.pi - ag)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(valid, np.sin(ag), 1.0)
        R = np.sin(ag + a) / s
        sa, ca = np.sin(a), np.cos(a)
        e = np.stack([-sg * sa, ca], -1)
        ep = np.stack([-sg * ca, -sa], -1)
        X = R[..., None] * e
        dXda = (np.cos(ag + a) / s)[..., None] * e + R[..., None] * ep
        dXdg = (sg * (-sa) / (s * s))[..., None] * e
        logdet = np.log(np.where(valid, R * sa, 1.0)) - 2.0 * np.log(s)
    return X, dXda, dXdg, np.where(valid, logdet, -np.inf), valid


#: Views whose A and B bearings are within this sine of each other or of opposite (a camera near
#: line AB, where the locus circle degenerates) keep plain (x, y) coordinates.
XY_SIN = 0.25


def xy_views(L):
    """(n,) bool: the views sampled in (x, y, alpha) rather than arc coordinates."""
    return np.abs(np.sin(L.phi[:, 1] - L.phi[:, 0])) < XY_SIN


def _pose(L, t0, t1, j=None):
    """:func:`arc_position` for the views in arc coordinates, the identity for the views of
    :func:`xy_views`: t0, t1 (..., n) (or (...,) for view j alone)."""
    xy = xy_views(L) if j is None else xy_views(L)[j]
    X, dXda, dXdg, logdet, valid = arc_position(t0, t1)
    if not np.any(xy):
        return X, dXda, dXdg, logdet, valid
    Xp = np.stack([t0, t1], -1)
    e0 = np.broadcast_to(np.array([1.0, 0.0]), Xp.shape)
    e1 = np.broadcast_to(np.array([0.0, 1.0]), Xp.shape)
    xy2 = xy[..., None] if np.ndim(xy) else xy
    return (np.where(xy2, Xp, X), np.where(xy2, e0, dXda), np.where(xy2, e1, dXdg),
            np.where(xy, 0.0, logdet), np.where(xy, True, valid))


def _jt(J, dXda, dXdg):
    """A factor's Jacobian in (x, y, alpha) turned into (a, g, alpha) coordinates."""
    return np.stack([J[..., 0] * dXda[..., 0] + J[..., 1] * dXda[..., 1],
                     J[..., 0] * dXdg[..., 0] + J[..., 1] * dXdg[..., 1], J[..., 2]], -1)


def _blocks(L, C, t, parts=False):
    """Whitened least-squares blocks of the bearings and headings at arc coordinates t (N, n, 3)
    = (a, g, alpha) per view, given C: cost 0.5 |r|^2 (N,), diagonal blocks D (N, n, 3, 3),
    blocks (j + 1, j) O (N, n - 1, 3, 3) of J^T J, gradient J^T r (N, n, 3). In these
    coordinates the bearings of A and B are linear (phi_A = angle(-X) - alpha = const + a -
    alpha, phi_B = phi_A + g): only C's bearing and the headings bend, which keeps the
    Gaussian close where a camera's own bearings leave it spread along its locus circle (near
    the circle through A, B and C)."""
    X, dXda, dXdg, _, _ = _pose(L, t[..., 0], t[..., 1])
    alpha = t[..., 2]
    N, n = alpha.shape
    D = np.zeros((N, n, 3, 3))
    g = np.zeros((N, n, 3))
    cost = np.zeros(N)
    for k, P in enumerate(_landmarks(C)):
        d = P - X
        r2 = np.maximum(d[..., 0] ** 2 + d[..., 1] ** 2, 1e-300)
        res = wrap_angle(L.phi[None, :, k] - np.arctan2(d[..., 1], d[..., 0]) + alpha) / L.sv
        J = _jt(np.stack([-d[..., 1] / r2, d[..., 0] / r2, np.ones_like(r2)], -1) / L.sv,
                dXda, dXdg)
        D += J[..., :, None] * J[..., None, :]
        g += J * res[..., None]
        cost += 0.5 * np.sum(res * res, axis=1)
    own = (D.copy(), g.copy())
    O = np.zeros((N, max(n - 1, 0), 3, 3))
    if L.psi is not None and n > 1:
        d = X[:, 1:] - X[:, :-1]
        r2 = np.maximum(d[..., 0] ** 2 + d[..., 1] ** 2, 1e-300)
        res = wrap_angle(L.psi[None, :] - np.arctan2(d[..., 1], d[..., 0]) + alpha[:, :-1]) / L.sw
        z = np.zeros_like(r2)
        J0 = _jt(np.stack([-d[..., 1] / r2, d[..., 0] / r2, np.ones_like(r2)], -1) / L.sw,
                 dXda[:, :-1], dXdg[:, :-1])
        J1 = _jt(np.stack([d[..., 1] / r2, -d[..., 0] / r2, z], -1) / L.sw,
                 dXda[:, 1:], dXdg[:, 1:])
        D[:, :-1] += J0[..., :, None] * J0[..., None, :]
        D[:, 1:] += J1[..., :, None] * J1[..., None, :]
        O = J1[..., :, None] * J0[..., None, :]
        g[:, :-1] += J0 * res[..., None]
        g[:, 1:] += J1 * res[..., None]
        cost += 0.5 * np.sum(res * res, axis=1)
        own[0][:, :-1] += J0[..., :, None] * J0[..., None, :]
        own[1][:, :-1] += J0 * res[..., None]
    D[..., 0, 0] += ARC_PRECISION
    D[..., 1, 1] += ARC_PRECISION
    D[..., 2, 2] += ALPHA_PRECISION
    if parts:
        # the blocks of the factors of view j and of the heading out of it: what a view's
        # "future" (views j..n) holds about t_j; the rest of D_j and g_j is its past
        return cost, D, O, g, own
    return cost, D, O, g


def _chol3(S):
    """Cholesky factors of (..., 3, 3) symmetric matrices, elementwise (NaN where not PD)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        l00 = np.sqrt(S[..., 0, 0])
        l10 = S[..., 1, 0] / l00
        l20 = S[..., 2, 0] / l00
        l11 = np.sqrt(S[..., 1, 1] - l10 * l10)
        l21 = (S[..., 2, 1] - l20 * l10) / l11
        l22 = np.sqrt(S[..., 2, 2] - l20 * l20 - l21 * l21)
    out = np.zeros(S.shape)
    out[..., 0, 0], out[..., 1, 0], out[..., 2, 0] = l00, l10, l20
    out[..., 1, 1], out[..., 2, 1], out[..., 2, 2] = l11, l21, l22
    return out


def _fwd3(Lm, b):
    """Solve L y = b for lower-triangular L (..., 3, 3), b (..., 3)."""
    y0 = b[..., 0] / Lm[..., 0, 0]
    y1 = (b[..., 1] - Lm[..., 1, 0] * y0) / Lm[..., 1, 1]
    y2 = (b[..., 2] - Lm[..., 2, 0] * y0 - Lm[..., 2, 1] * y1) / Lm[..., 2, 2]
    return np.stack([y0, y1, y2], -1)


def _bwd3(Lm, b):
    """Solve L^T x = b for lower-triangular L (..., 3, 3), b (..., 3)."""
    x2 = b[..., 2] / Lm[..., 2, 2]
    x1 = (b[..., 1] - Lm[..., 2, 1] * x2) / Lm[..., 1, 1]
    x0 = (b[..., 0] - Lm[..., 1, 0] * x1 - Lm[..., 2, 0] * x2) / Lm[..., 0, 0]
    return np.stack([x0, x1, x2], -1)


def block_cholesky(D, O):
    """Block Cholesky of the block-tridiagonal P (diagonal D (N, n, 3, 3), sub-diagonal O (N,
    n - 1, 3, 3), O_j = P[j + 1, j]): P = L L^T with diagonal factors Ld (N, n, 3, 3) and
    sub-diagonal blocks Lo (N, n - 1, 3, 3). The forward pass of a Kalman filter along the views."""
    N, n = D.shape[:2]
    Ld = np.empty_like(D)
    Lo = np.empty_like(O)
    Ld[:, 0] = _chol3(D[:, 0])
    for j in range(1, n):
        # Lo_j = O_j Ld_{j-1}^-T: each row o of O_j solves Ld_{j-1} y = o
        Lo[:, j - 1] = _fwd3(Ld[:, j - 1, None], O[:, j - 1])
        S = D[:, j] - np.einsum("nik,njk->nij", Lo[:, j - 1], Lo[:, j - 1])
        Ld[:, j] = _chol3(S)
    return Ld, Lo


def block_solve(Ld, Lo, b):
    """x with L L^T x = b (b (N, n, 3)), given :func:`block_cholesky`."""
    n = b.shape[1]
    y = np.empty_like(b)
    y[:, 0] = _fwd3(Ld[:, 0], b[:, 0])
    for j in range(1, n):
        y[:, j] = _fwd3(Ld[:, j], b[:, j] - np.einsum("nij,nj->ni", Lo[:, j - 1], y[:, j - 1]))
    return back_substitute(Ld, Lo, y)


def back_substitute(Ld, Lo, y):
    """x with L^T x = y: with y standard normal, x is a draw of N(0, (L L^T)^-1) (the backward
    sampling pass)."""
    n = y.shape[1]
    x = np.empty_like(y)
    x[:, n - 1] = _bwd3(Ld[:, n - 1], y[:, n - 1])
    for j in range(n - 2, -1, -1):
        x[:, j] = _bwd3(Ld[:, j], y[:, j] - np.einsum("nji,nj->ni", Lo[:, j], x[:, j + 1]))
    return x


@_quiet
def fit_trajectories(L, C, iters=40):
    """Conditional modes given C (N, 2) in arc coordinates t = (a, g, alpha) per view, by
    Levenberg-Marquardt from :func:`initial_poses` (per draw damping ``lam diag(J^T J)``:
    divided by 3 after a step that lowers the cost, multiplied by 4 and the step refused
    otherwise): t (N, n, 3), cost (N,), Cholesky blocks (Ld, Lo) of the information ``J^T J`` at
    the end point, ok (N,) (finite, positive definite, in the domain)."""
    X, alpha = initial_poses(L, C)
    a, g0 = arc_coords(X)
    xy = xy_views(L)
    t = np.stack([np.where(xy, X[..., 0], a), np.where(xy, X[..., 1], g0), alpha], -1)
    cost, D, O, g = _blocks(L, C, t)
    lam = np.full(C.shape[0], 1e-3)
    eye = np.eye(3)
    # only draws still moving are iterated: converged once an accepted step lowers the cost by
    # less than 1e-6 nats, or given up once the damping exceeds 1e10
    act = np.arange(C.shape[0])
    for _ in range(iters):
        if act.size == 0:
            break
        Da = D[act]
        dmp = Da + (lam[act, None, None, None] * np.diagonal(Da, axis1=-2, axis2=-1)[..., None]) * eye
        Ld, Lo = block_cholesky(dmp, O[act])
        step = -block_solve(Ld, Lo, g[act])
        fin = np.all(np.isfinite(step), axis=(1, 2))
        tn = t[act] + np.where(fin[:, None, None], step, 0.0)
        cn = _cost(L, C[act], tn)
        better = fin & np.isfinite(cn) & (cn <= cost[act])
        acc = act[better]
        gain = cost[acc] - cn[better]
        t[acc] = tn[better]
        lam[acc] /= 5.0
        lam[act[~better]] *= 5.0
        if acc.size:
            c2, D2, O2, g2 = _blocks(L, C[acc], t[acc])
            cost[acc], D[acc], g[acc] = c2, D2, g2
            if O.size:
                O[acc] = O2
        done = np.zeros(C.shape[0], bool)
        done[acc[gain < 1e-6]] = True
        done[act[lam[act] > 1e10]] = True
        act = act[~done[act]]
    Ld, Lo = block_cholesky(D, O)
    diag = np.diagonal(Ld, axis1=-2, axis2=-1)
    ok = np.all(np.isfinite(Ld), axis=(1, 2, 3)) & np.all(diag > 0, axis=(1, 2))
    ok &= np.all(_pose(L, t[..., 0], t[..., 1])[4], axis=1) & np.isfinite(cost)
    if Lo.size:
        ok &= np.all(np.isfinite(Lo), axis=(1, 2, 3))
    return t, cost, (Ld, Lo), ok


def _cost(L, C, t):
    X, _, _, _, valid = _pose(L, t[..., 0], t[..., 1])
    alpha = t[..., 2]
    cost = np.zeros(C.shape[0])
    for k, P in enumerate(_landmarks(C)):
        d = P - X
        res = wrap_angle(L.phi[None, :, k] - np.arctan2(d[..., 1], d[..., 0]) + alpha) / L.sv
        cost += 0.5 * np.sum(res * res, axis=1)
    if L.psi is not None and L.n > 1:
        d = X[:, 1:] - X[:, :-1]
        res = wrap_angle(L.psi[None, :] - np.arctan2(d[..., 1], d[..., 0]) + alpha[:, :-1]) / L.sw
        cost += 0.5 * np.sum(res * res, axis=1)
    return np.where(np.all(valid, axis=1), cost, np.inf)


def _log_det_half(Ld):
    """0.5 log det P = sum of the log diagonals of its Cholesky factor."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sum(np.log(np.diagonal(Ld, axis1=-2, axis2=-1)), axis=(1, 2))


@_quiet
def laplace_marginal(L, prior, C, iters=40):
    """Laplace approximation of the log marginal ``log p(C, z)`` at C (N, 2) (the trajectory
    integrated about its conditional mode, in arc coordinates): (N,), -inf where the fit failed."""
    t, _, (Ld, _), ok = fit_trajectories(L, C, iters)
    out = np.full(C.shape[0], -np.inf)
    if np.any(ok):
        X, _, _, logdet, _ = _pose(L, t[ok, :, 0], t[ok, :, 1])
        out[ok] = (log_joint(L, prior, C[ok], X, t[ok, :, 2]) + np.sum(logdet, axis=1)
                   + 1.5 * L.n * _LOG2PI - _log_det_half(Ld[ok]))
    return np.where(np.isfinite(out), out, -np.inf)


# ---------------------------------------------------------------------------------------------
# C's proposal: a 2-D t mixture


class _CMix:
    """Mixture over C: shares ``pis`` of t components (means (K, 2), scale Cholesky factors
    (K, 2, 2), dof), optionally plus defensive shares of the same components widened by WIDE and
    of the product prior."""

    def __init__(self, pis, means, chols, defensive=True):
        self.pis = np.asarray(pis, float) / np.sum(pis)
        self.means, self.chols = means, chols
        self.defensive = defensive

    def _parts(self):
        if not self.defensive:
            return [(1.0, 1.0)]
        return [(1.0 - P_WIDE - P_PRIOR, 1.0), (P_WIDE, WIDE)]

    def draw(self, rng, N):
        shares = [s for s, _ in self._parts()] + ([P_PRIOR] if self.defensive else [])
        counts = rng.multinomial(N, np.array(shares) / np.sum(shares))
        out = []
        for (_, scale), k in zip(self._parts(), counts[:len(self._parts())], strict=True):
            if not k:
                continue
            comp = rng.choice(self.pis.size, size=k, p=self.pis)
            z = rng.standard_normal((k, 2))
            gsc = np.sqrt(rng.chisquare(C_DOF, size=k) / C_DOF)
            out.append(self.means[comp] + scale * np.einsum("kij,kj->ki", self.chols[comp], z)
                       / gsc[:, None])
        if self.defensive and counts[-1]:
            out.append(_PRODUCT.sample(rng, 0, int(counts[-1]))[:, 0])
        x = np.concatenate(out) if out else np.zeros((0, 2))
        return x[rng.permutation(x.shape[0])]

    def log_density(self, x):
        terms = []
        for s, scale in self._parts():
            lt = _log_t2(x, self.means, self.chols * scale, C_DOF) + np.log(self.pis)[None, :]
            terms.append(np.log(s) + logsumexp(lt, axis=1))
        if self.defensive:
            terms.append(np.log(P_PRIOR) + _PRODUCT.log_density(x[:, None, :]))
        return logsumexp(np.stack(terms, -1), axis=-1)


_PRODUCT = _priors.ProductPrior()


class _ProductDensity:
    """The product prior's one-point density as a C density (log_density of (N, 2))."""

    @staticmethod
    def log_density(x):
        return _PRODUCT.log_density(x[:, None, :])


def _log_t2(x, means, chols, dof):
    """Log densities (N, K) of 2-D t components at x (N, 2)."""
    d = x[:, None, :] - means[None]
    z0 = d[..., 0] / chols[None, :, 0, 0]
    z1 = (d[..., 1] - chols[None, :, 1, 0] * z0) / chols[None, :, 1, 1]
    q = z0 * z0 + z1 * z1
    c = lgamma((dof + 2) / 2) - lgamma(dof / 2) - np.log(dof * np.pi)
    return (c - np.log(np.abs(chols[None, :, 0, 0] * chols[None, :, 1, 1]))
            - 0.5 * (dof + 2) * np.log1p(q / dof))


def _fit_mixture(x, w, K, rng, iters=25):
    """Weighted EM for a K-component Gaussian mixture in 2-D: (pis, means, chols) with the
    covariances inflated by C_INFLATE^2 (the proposal's scale)."""
    keep = w > 1e-10 * w.max()
    x, w = x[keep], w[keep] / w[keep].sum()
    ess = 1.0 / np.sum(w * w)
    K = int(max(1, min(K, ess // 10)))
    mean_all = w @ x
    dx = x - mean_all
    cov_all = (dx * w[:, None]).T @ dx
    floor = 1e-10 * max(np.trace(cov_all), 1e-20) * np.eye(2)
    # start: K draws by weight (systematic), each with the overall covariance
    u = (rng.random() + np.arange(K)) / K
    idx = np.minimum(np.searchsorted(np.cumsum(w), u), x.shape[0] - 1)
    mus = x[idx].copy()
    covs = np.repeat((cov_all / max(K, 1) + floor)[None], K, axis=0)
    pis = np.full(K, 1.0 / K)
    for _ in range(iters):
        ch = np.linalg.cholesky(covs)
        d = x[:, None, :] - mus[None]
        z0 = d[..., 0] / ch[None, :, 0, 0]
        z1 = (d[..., 1] - ch[None, :, 1, 0] * z0) / ch[None, :, 1, 1]
        lg = -0.5 * (z0 * z0 + z1 * z1) - np.log(ch[None, :, 0, 0] * ch[None, :, 1, 1])
        lg = lg + np.log(np.maximum(pis, 1e-300))[None]
        resp = np.exp(lg - logsumexp(lg, axis=1)[:, None])
        rw = resp * w[:, None]
        nk = rw.sum(axis=0)
        live = nk > 1e-6
        if not np.all(live):
            mus, covs, pis, rw, nk = mus[live], covs[live], pis[live], rw[:, live], nk[live]
        pis = nk / nk.sum()
        mus = (rw.T @ x) / nk[:, None]
        d = x[:, None, :] - mus[None]
        covs = np.einsum("nk,nki,nkj->kij", rw, d, d) / nk[:, None, None] + floor
    chols = np.linalg.cholesky(covs * C_INFLATE ** 2)
    return pis, mus, chols


def _ess(lw):
    lw = lw[np.isfinite(lw)]
    if lw.size == 0:
        return 0.0
    w = np.exp(lw - lw.max())
    return float(w.sum() ** 2 / np.sum(w * w))


def _stages(n):
    """Views of the successive targets of C's adaptation: 3 (or n), then doubling up to n."""
    out = [min(n, 3)]
    while out[-1] < n:
        out.append(min(n, 2 * out[-1]))
    return out


@_quiet
def adapt_c_proposal(L, prior, rng, opts):
    """C's proposal: adaptive tempering from the product prior to the Laplace marginal of the
    first 3 views, then from each stage's marginal to that of twice as many views, up to n
    (each step a geometric bridge ``q_ref^(1 - b) p_k^b`` from the proposal the previous stage
    ended with, or the product prior, to the Laplace marginal p_k of k views, b raised while
    a share ``tempering_ess`` of the draws where p_k > 0 stays effective, the t mixture
    refitted to the weighted draws after every round).
    Returns the mixture and the number of C draws spent."""
    M = int(opts["tempering_samples"])
    keep = float(opts["tempering_ess"])
    K = int(opts["components"])
    iters = int(opts["gn_iters"])
    max_rounds = int(opts["tempering_rounds"])
    spent, rounds = 0, 0
    mix = None
    ref = _ProductDensity()
    for k in _stages(L.n):
        Lk = L if k == L.n else L.first(k)
        if mix is not None:
            ref = mix           # the bridge starts from the proposal the last stage ended with
        beta = 0.0
        while rounds < max_rounds:
            rounds += 1
            if mix is None:
                C = _PRODUCT.sample(rng, 0, M)[:, 0]
                lq = _PRODUCT.log_density(C[:, None, :])
            else:
                C = mix.draw(rng, M)
                lq = mix.log_density(C)
            spent += M
            l0 = ref.log_density(C)
            l1 = laplace_marginal(Lk, prior, C, iters)
            ok = np.isfinite(l1) & np.isfinite(lq) & np.isfinite(l0)
            if not np.any(ok):
                continue
            C, l0, l1, lq = C[ok], l0[ok], l1[ok], lq[ok]
            # the share of effective draws among those where the Laplace marginal is positive:
            # draws of C that no configuration in the world box admits (up to 80% of the
            # product prior's) have weight 0 at every temperature above 0, and counted against
            # all M they held the temperature at 0 for every round (development seeds, 10 views)
            need = keep * C.shape[0]

            def lw_at(b, l0=l0, l1=l1, lq=lq):
                return b * l1 + (1.0 - b) * l0 - lq

            if _ess(lw_at(1.0)) >= need:
                beta_new = 1.0
            elif _ess(lw_at(beta)) < need:
                beta_new = beta          # refit at the same temperature
            else:
                lo, hi = beta, 1.0
                for _ in range(25):
                    mid = 0.5 * (lo + hi)
                    lo, hi = (mid, hi) if _ess(lw_at(mid)) >= need else (lo, mid)
                beta_new = lo
            lw = lw_at(beta_new)
            w = np.exp(lw - lw.max())
            mix = _CMix(*_fit_mixture(C, w, K, rng), defensive=True)
            done = beta == 1.0 and beta_new == 1.0
            beta = beta_new
            if done or (beta == 1.0 and k < L.n):
                break
    if mix is None:
        mix = _CMix([1.0], np.array([[0.0, 0.5]]), np.eye(2)[None], defensive=True)
    return mix, spent


@_quiet
def solve_rb(L, prior, part, rng, opts):
    """The reference's answer by the conditional-Laplace sampler (the dict of
    :func:`qfg.solvers.reference.staged.solve_reference`)."""
    mix, spent = adapt_c_proposal(L, prior, rng, opts)
    M = int(opts["rb_samples"])
    iters = int(opts["gn_iters"])
    finals, ess_rounds, lws = [], [], []
    total = spent
    for _ in range(int(opts["final_rounds"])):
        C = mix.draw(rng, M)
        lqc = mix.log_density(C)
        # the prior inside the filter: Z estimates the integral of the whole target given C
        logz, X, alpha = particle_trajectories(L, C, rng, int(opts["particles"]), iters,
                                               prior=prior)
        lw = np.full(M, -np.inf)
        ok = np.isfinite(logz) & np.isfinite(lqc)
        lw[ok] = logz[ok] - lqc[ok]
        lw = np.where(np.isnan(lw), -np.inf, lw)
        total += M
        s = _summaries(part, X, C, lw)
        ess_rounds.append(0.0 if s is None else s[4])
        if s is not None:
            finals.append(s + (X, C))
            lws.append(lw)
        if sum(ess_rounds) >= float(opts["ess_goal"]):
            break
        if opts["refit"] and s is not None:
            # population Monte Carlo: half of the next proposal refitted to this round's draws
            # weighted by the exact target (the Laplace marginal that fitted C's mixture can
            # miss where the trajectory's conditional is far from Gaussian)
            w = np.exp(lw - np.max(lw))
            pis, mus, chols = _fit_mixture(C, w, int(opts["components"]), rng)
            mix = _CMix(np.r_[0.5 * mix.pis, 0.5 * pis], np.concatenate([mix.means, mus]),
                        np.concatenate([mix.chols, chols]), defensive=True)
    return final_answer(L, part, finals, M, opts["min_ess"], lws, ess_rounds, total)


# ---------------------------------------------------------------------------------------------
# the trajectory given C: a particle filter twisted by the Laplace approximation


def intermediate_prior(prior):
    """The prior the particle filter's intermediate targets use on the points seen so far (C and
    the views j..n), or None (no prior before the last step). For the priors whose density on a
    subset of the points is (up to a constant) its marginal there (:class:`~qfg.priors.WorldBoxPrior`,
    exchangeable points; the independent :class:`~qfg.priors.ProductPrior` and
    :class:`~qfg.priors.WindowPrior`), that density, the world box's on ``INTER_N_RHO`` angles
    (cheaper than 128 by about 10x; only the last target, which carries the exact prior, makes
    the answer: at 20 views with C at the truth 16 angles gave the ESS of 32 within its
    scatter between seeds and the filter 25-50% faster, development seed 2, geometries 0-7).
    Any positive intermediate target keeps the filter exact; a closer one keeps its weights even.
    """
    if isinstance(prior, _priors.WorldBoxPrior):
        if prior.n_rho <= INTER_N_RHO:
            return prior
        return prior.replace(n_rho=INTER_N_RHO)
    if isinstance(prior, (_priors.ProductPrior, _priors.WindowPrior)):
        return prior
    return None


#: Quadrature angles of the world box prior in the particle filter's intermediate targets.
INTER_N_RHO = 16


@_quiet
def particle_trajectories(L, C, rng, K=8, iters=40, prior=None):
    """Trajectories given C (M, 2) by sequential Monte Carlo backwards along the views (n down
    to 1), K particles per C, using the conditional Laplace approximation in arc coordinates
    both as proposal and as twisting function: the step of view j draws t_j from the Gaussian's
    conditional ``q(t_j | t_{j+1})`` (the backward-sampling pass) and targets
    ``gamma_j = [exact factors of views j..n and the headings between them, arc Jacobians,
    headings' uniform prior] x phi_j(t_j)``, where ``phi_j`` is the Gaussian message of the
    views before j about the mode (the forward pass's information minus view j's own and
    outgoing factors); ``phi_1 = 1``, so the last target is exact. Particles are resampled (systematic,
    per C) after every step. Were the Gaussian exact, every weight would be equal; where it is
    not, resampling stops the error from compounding over the views (the plain Laplace proposal
    multiplies n such errors).

    With ``prior`` given, the targets also carry it: ``gamma_j`` times the prior of C and the
    views j..n (:func:`intermediate_prior`; none before the last step for other priors), the
    last target times ``prior(C, X_1..X_n)`` exactly. Its coupling of every point (the world
    box's scale: a density of about extent^-(2n + 4)) is then corrected view by view with
    resampling, instead of on one trajectory drawn without it, whose log prior had a standard
    deviation of 1.0-2.8 nats at 20 views with C at the truth (development seed 2,
    ``python -m benchmarks.reference_views20 --seed 2 --scenarios 0 6 --views 20 --at-truth``).

    Returns log Z (M,), the filter's unbiased estimate of ``int prod factors dX dalpha`` (times
    the prior when given), and one trajectory per C drawn from the final particles: X (M, n,
    2), alpha (M, n). ``Z / q(C)`` with the prior (``Z prior(C, X) / q(C)`` without) is an
    importance weight of the exact target (the expectation of Z f(X) is the integral of the
    target times f)."""
    M, n = C.shape[0], L.n
    tm, _, (Ld, Lo), ok = fit_trajectories(L, C, iters)
    _, _, _, _, (Down, _) = _blocks(L, C, tm, parts=True)
    Ld = np.where(ok[:, None, None, None], Ld, np.eye(3))
    Lo = np.where(ok[:, None, None, None], Lo, 0.0) if Lo.size else Lo
    # the past's message at the mode: information S_j - own_j (S_j = Ld_j Ld_j^T), gradient g_j -
    # own gradient (the full gradient is ~0 at the mode)
    S = np.einsum("mjik,mjlk->mjil", Ld, Ld)
    # the message is kept a bounded function (phi <= 1): its information clipped to positive
    # semi-definite and centred at the mode (without the linear term, which where the
    # information is nearly singular would let phi grow without bound and the weights' variance
    # with it). Any positive phi keeps the filter exact; a closer one keeps its weights even.
    lam_, vec = np.linalg.eigh(S - Down)
    Lam = np.einsum("mjik,mjk,mjlk->mjil", vec, np.maximum(lam_, 0.0), vec)
    Lam = np.where(np.isfinite(Lam), Lam, 0.0)
    P = M * K
    grp = np.repeat(np.arange(M), K)
    T = np.zeros((n, P, 3))
    anc = np.zeros((n, P), dtype=np.int64)
    logZ = np.where(ok, 0.0, -np.inf)
    base = (np.arange(M) * K)[:, None]
    nxt = None            # (t_{j+1}, X_{j+1}, log phi_{j+1}, log prior_{j+1}) of the particles
    lw = None
    inter = intermediate_prior(prior) if prior is not None else None
    path = np.zeros((P, n, 2)) if prior is not None else None   # positions of views j..n
    Cg = C[grp][:, None, :]
    for j in range(n - 1, -1, -1):
        mj = tm[grp, j]
        Lj = Ld[grp, j]
        z = rng.standard_normal((P, 3))
        rhs = z if nxt is None else z - np.einsum("pji,pj->pi", Lo[grp, j], nxt[0] - tm[grp, j + 1])
        dt = _bwd3(Lj, rhs)
        tj = mj + dt
        lq = (-0.5 * np.sum(z * z, -1) - 1.5 * _LOG2PI
              + np.sum(np.log(np.diagonal(Lj, axis1=-2, axis2=-1)), axis=1))
        X, _, _, logdet, valid = _pose(L, tj[:, 0], tj[:, 1], j)
        X = np.where(valid[:, None], X, 0.0)
        al = tj[:, 2]
        f = logdet - _LOG2PI
        for k, Pt in enumerate((np.zeros((1, 2)), np.array([[0.0, 1.0]]), C[grp])):
            d = Pt - X
            f = f + _log_wn(L.phi[j, k] - np.arctan2(d[:, 1], d[:, 0]) + al, L.sv)
        if nxt is not None and L.psi is not None:
            d = nxt[1] - X
            f = f + _log_wn(L.psi[j] - np.arctan2(d[:, 1], d[:, 0]) + al, L.sw)
        if j > 0:
            lphi = -0.5 * np.einsum("pi,pik,pk->p", dt, Lam[grp, j], dt)
        else:
            lphi = np.zeros(P)
        lwp = f + lphi - lq - (0.0 if nxt is None else nxt[2])
        lpr = np.zeros(P)
        if prior is not None:
            path[:, j] = X
            pj = prior if j == 0 else inter
            if pj is not None:
                lpr = pj.log_density(np.concatenate([Cg, path[:, j:]], axis=1))
            lwp = lwp + lpr - (0.0 if nxt is None else nxt[3])
        good = valid & (np.abs(dt[:, 2]) < np.pi) & np.isfinite(lwp)
        lw = np.where(good, lwp, -np.inf).reshape(M, K)
        lse = logsumexp(lw, axis=1)
        logZ = logZ + lse - np.log(K)
        T[j] = tj
        if j > 0:
            fin = np.isfinite(lse)
            w = np.where(fin[:, None], np.exp(lw - np.where(fin, lse, 0.0)[:, None]), 1.0 / K)
            cw = np.cumsum(w, axis=1)
            cw[:, -1] = 1.0 + 1e-12
            u = (rng.random((M, 1)) + np.arange(K)[None, :]) / K
            a = (base + np.minimum(_rows_searchsorted(cw, u), K - 1)).ravel()
            anc[j] = a
            nxt = (tj[a], X[a], lphi[a], lpr[a])
            if path is not None:
                path = path[a]
    # one trajectory per C by the final weights, traced through the ancestors
    lse = logsumexp(lw, axis=1)
    fin = np.isfinite(lse)
    w = np.where(fin[:, None], np.exp(lw - np.where(fin, lse, 0.0)[:, None]), 1.0 / K)
    cw = np.cumsum(w, axis=1)
    u = rng.random((M, 1)) * cw[:, -1:]
    p = (np.arange(M) * K + np.minimum(_rows_searchsorted(cw, u)[:, 0], K - 1))
    t = np.zeros((M, n, 3))
    for j in range(n):
        t[:, j] = T[j][p]
        if j < n - 1:
            p = anc[j + 1][p]
    X, _, _, _, valid = _pose(L, t[..., 0], t[..., 1])
    X = np.where(valid[..., None], X, 0.0)
    return np.where(np.isfinite(logZ), logZ, -np.inf), X, t[..., 2]


def _rows_searchsorted(cw, u):
    """Per row r, ``searchsorted(cw[r], u[r])`` for non-decreasing rows with cw[r, -1] > 0:
    (R, k) indices."""
    R, K = cw.shape
    span = cw[:, -1:]
    off = np.arange(R)[:, None] * 4.0
    flat = (cw / span + off).ravel()
    q = (u / span + off).ravel()
    return (np.searchsorted(flat, q) - np.repeat(np.arange(R) * K, u.shape[1])).reshape(u.shape)
