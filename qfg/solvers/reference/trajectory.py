"""The trajectory given C for the reference's conditional sampler (:mod:`.conditional`): the
exact joint target ``log p(C, X, alpha, z)`` (:func:`log_joint`), the poses each view's three
bearings fix given C (:func:`resect`), and the Gaussian approximation of the trajectory's
conditional ``p(X, alpha | C, z)`` about its mode in arc coordinates ``t_j = (a_j, g_j,
alpha_j)`` (:func:`arc_coords`, :func:`arc_position`): the mode by Levenberg-Marquardt
(:func:`fit_trajectories`), the block-tridiagonal information ``J^T J`` factored by a block
Cholesky (:func:`block_cholesky`, :func:`block_solve`, :func:`back_substitute`), and the Laplace
marginal of C (:func:`laplace_marginal`). Radians and |AB| units, AB frame.
"""

from __future__ import annotations

import numpy as np

from ...geometry import locus_circle, ray_circle_intersection, wrap_angle
from .weights import _log_wn

__all__ = ["resect", "fit_trajectories", "log_joint", "laplace_marginal"]

_LOG2PI = np.log(2 * np.pi)
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
    >>> from qfg.solvers.reference.staged import Layout
    >>> C, P = np.array([0.7, 0.4]), np.array([-0.8, 1.9, 0.3])
    >>> phi = np.array([[bearing(P, np.zeros(2)), bearing(P, np.array([0.0, 1.0])), bearing(P, C)]])
    >>> X, al = resect(Layout(phi, None, 0.01, 0.01), C[None])
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
