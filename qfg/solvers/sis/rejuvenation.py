"""The measurement chart of camera trajectories, in which the SIS engine's rejuvenation moves
(resample-move, :func:`.moves._rejuvenate`) slide a whole trajectory along what its bearings and
headings leave open.

A trajectory of n poses (x, y, alpha) in the AB frame (A = (0, 0), B = (0, 1)) is, per branch
choice, one-to-one with the coordinates

* ``a1``: the angle at A of camera 1 on the locus arc of its own bearings to A and B
  (:func:`qfg.geometry.locus_point`), in (0, pi - |gamma_1|);
* ``pa``, ``pb`` (n,): the bearings of A and B each pose sees (``f_A(X_t)``, ``f_B(X_t)``);
* ``rh`` (n - 1,): the direction of each step relative to the previous heading,
  ``atan2(X_t - X_(t-1)) - alpha_(t-1)``;
* ``branch`` (n - 1,): which of the (up to) two points where that ray meets the locus arc of
  ``(pa_t, pb_t)`` the pose is (0 the nearer);

and back (:func:`poses_of`): camera 1 on its arc, each later camera where the ray from the
previous one meets its arc, every heading from the bearing of A. These are the coordinates in
which the sampling and motion steps draw (the measurement residuals ``pa - phi_A``, ``pb - phi_B``,
``rh - psi`` are their noise), so a move of ``a1`` alone, every residual held, keeps every A, B
and heading likelihood and moves camera 1 along its arc with the rest of the trajectory
following: the one direction an early collapse of the hypotheses leaves unexplored. The density
of a trajectory in these coordinates is its density in (x, y, alpha) times

    |d(x, y, alpha) / d(a1, pa, pb, rh)| = |x_1| / sin^2(gamma_1) * prod_t t_t / |grad Gamma(X_t) . u_t|

(:func:`.arcs.log_arc_jacobian` with da/dw = 1, :func:`.arcs.log_ray_jacobian`: each alpha_t
is the bearing of A minus pa_t, unit Jacobian), returned by :func:`poses_of`.
"""

from __future__ import annotations

import numpy as np

from ...geometry import heading_on_locus, locus_circle, locus_point, ray_circle_intersection, wrap_angle
from ..common.arcs import log_arc_jacobian, log_ray_jacobian
from ..common.seeds import per_triplet

#: Views (1-based) after whose resampling the hypotheses are rejuvenated: ``FIRST_VIEW`` and
#: every view about ``GROWTH`` times the previous one (4, 6, 9, 14, 20, 30, ... with 1.5; 4, 8,
#: 16, ... with 2): geometric, so the moves over whole trajectories cost about
#: ``GROWTH / (GROWTH - 1)`` times the views' poses per evaluation in all (time stays linear in
#: the views); none at 3 views. 1.5 with one sweep against 2 with two sweeps (about the same
#: time) on development geometries: docs/solvers.md, "More views".
FIRST_VIEW = 4
GROWTH = 1.5


def schedule(n_views: int, growth: float | None = None) -> list:
    """The views up to ``n_views`` after which the hypotheses are rejuvenated: the distinct
    ``round(FIRST_VIEW * growth^k)``, k = 0, 1, ... (``growth`` > 1; default :data:`GROWTH`).

    >>> schedule(40, 1.5), schedule(40, 2.0)
    ([4, 6, 9, 14, 20, 30], [4, 8, 16, 32])
    """
    g = GROWTH if growth is None else float(growth)
    out, k = [], 0
    while True:
        v = int(np.floor(FIRST_VIEW * g ** k + 0.5))
        if v > n_views:
            return out
        if not out or v > out[-1]:
            out.append(v)
        k += 1


def scheduled(view: int) -> bool:
    """Whether the hypotheses are rejuvenated after ``view`` (1-based) (:func:`schedule`).

    >>> [v for v in range(1, 40) if scheduled(v)]
    [4, 6, 9, 14, 20, 30]
    """
    v = int(view)
    return v >= FIRST_VIEW and v in schedule(v)


def work_views(n_views: int) -> int:
    """Pose-views one hypothesis processes in the moves of ``n_views`` views, per evaluation of
    the target: the sum of the scheduled views (about ``GROWTH / (GROWTH - 1)`` n at most).

    >>> work_views(3), work_views(10), work_views(20)
    (0, 19, 53)
    """
    return sum(schedule(int(n_views)))


def chart_of(poses):
    """Chart coordinates of trajectories ``poses`` (J, n, 3): ``(a1 (J,), gamma1 (J,), pa (J, n),
    pb (J, n), rh (J, n - 1), branch (J, n - 1))``; ``gamma1 = pb_1 - pa_1`` (wrapped) is returned
    for the bounds of ``a1``.

    >>> P = np.array([[[-1.0, 0.5, 0.0], [-1.0, 1.0, 0.0]]])
    >>> a1, g1, pa, pb, rh, br = chart_of(P)
    >>> np.allclose(poses_of(a1, pa, pb, rh, br)[0], P)
    True
    """
    P = np.asarray(poses, dtype=float)
    X, al = P[..., :2], P[..., 2]
    pa = wrap_angle(np.arctan2(-X[..., 1], -X[..., 0]) - al)
    pb = wrap_angle(np.arctan2(1.0 - X[..., 1], -X[..., 0]) - al)
    g1 = wrap_angle(pb[:, 0] - pa[:, 0])
    a1 = np.arctan2(np.abs(X[:, 0, 0]), X[:, 0, 1])
    d = X[:, 1:] - X[:, :-1]
    th = np.arctan2(d[..., 1], d[..., 0])
    rh = wrap_angle(th - al[:, :-1])
    branch = np.zeros(rh.shape, dtype=np.int8)
    if rh.size:
        circ = locus_circle(pa[:, 1:], pb[:, 1:])
        pts, valid = ray_circle_intersection(X[:, :-1], th, circ.center, circ.radius, circ.side)
        dist = np.hypot(*(pts - X[:, 1:, None, :]).transpose(3, 0, 1, 2))
        dist = np.where(valid, dist, np.inf)
        branch[...] = np.argmin(dist, axis=-1)
    return a1, g1, pa, pb, rh, branch


def log_jacobian(poses) -> np.ndarray:
    """(J,) ``log |d(x, y, alpha) / d(a1, pa, pb, rh)|`` of trajectories ``poses`` (J, n, 3)
    straight from the poses (what :func:`poses_of` returns with them, without the
    intersections): camera 1's arc term and each step's ray term along its own direction.

    >>> P = np.array([[[-1.0, 0.5, 0.0], [-1.0, 1.0, 0.0]]])
    >>> a1, _, pa, pb, rh, br = chart_of(P)
    >>> bool(np.isclose(log_jacobian(P)[0], poses_of(a1, pa, pb, rh, br)[1][0]))
    True
    """
    P = np.asarray(poses, dtype=float)
    X, al = P[..., :2], P[..., 2]
    pa = np.arctan2(-X[:, 0, 1], -X[:, 0, 0]) - al[:, 0]
    g1 = wrap_angle(np.arctan2(1.0 - X[:, 0, 1], -X[:, 0, 0]) - al[:, 0] - pa)
    out = log_arc_jacobian(X[:, 0], g1, np.zeros(P.shape[0]))
    if P.shape[1] > 1:
        d = X[:, 1:] - X[:, :-1]
        out = out + np.sum(log_ray_jacobian(X[:, 1:], X[:, :-1], np.arctan2(d[..., 1], d[..., 0])),
                           axis=1)
    return out


def poses_of(a1, pa, pb, rh, branch):
    """Trajectories (J, n, 3) of chart coordinates (:func:`chart_of`), their log Jacobian
    ``log |d(x, y, alpha) / d(a1, pa, pb, rh)|`` (J,) and whether they exist (J,): ``a1`` inside
    its arc and every ray meeting its locus arc at the chosen branch (where not: the log
    Jacobian is -inf and the poses are not meaningful). One vectorised pass per view."""
    a1 = np.asarray(a1, dtype=float)
    J, n = pa.shape
    g1 = wrap_angle(pb[:, 0] - pa[:, 0])
    ok = (a1 > 0) & (a1 < np.pi - np.abs(g1))
    out = np.empty((J, n, 3))
    X = locus_point(g1, np.where(ok, a1, 0.5 * (np.pi - np.abs(g1))))
    out[:, 0, :2], out[:, 0, 2] = X, heading_on_locus(X, pa[:, 0])
    lj = log_arc_jacobian(X, g1, np.zeros(J))
    rows = np.arange(J)
    for t in range(1, n):
        prev = out[:, t - 1]
        th = prev[:, 2] + rh[:, t - 1]
        circ = locus_circle(pa[:, t], pb[:, t])
        pts, valid = ray_circle_intersection(prev[:, :2], th, circ.center, circ.radius, circ.side)
        b = branch[:, t - 1]
        X = pts[rows, b]
        ok &= valid[rows, b]
        out[:, t, :2], out[:, t, 2] = X, heading_on_locus(X, pa[:, t])
        lj = lj + log_ray_jacobian(X, prev[:, :2], th)
    ok &= np.isfinite(lj)
    return out, np.where(ok, lj, -np.inf), ok


def walk_factor(poses, tid, which, scale) -> np.ndarray:
    """(T, D, D) per triplet of ``which`` (T,): the Cholesky factor of ``scale^2 / D`` times the
    covariance of its hypotheses' trajectories ``poses`` (J, n, 3) (rows sorted by triplet
    ``tid``; D = 3 n; headings unwrapped about the first hypothesis' so that the spread is not
    inflated by the wrap): a random walk's proposal covariance. A loop over triplets (one
    D x D factor each), not hypotheses; zero for triplets not in ``which`` or with one row."""
    T, n = which.size, poses.shape[1]
    D = 3 * n
    chol = np.zeros((T, D, D))
    bounds = np.searchsorted(tid, np.arange(T + 1))
    for t in np.flatnonzero(which):
        P = poses[bounds[t]:bounds[t + 1]].reshape(-1, n, 3)
        if P.shape[0] < 2:
            continue
        P = P.copy()
        P[..., 2] = P[0, :, 2] + wrap_angle(P[..., 2] - P[0, :, 2])
        Q = P.reshape(P.shape[0], D)
        Q = Q - Q.mean(axis=0)
        # einsum, not Q.T @ Q: OpenBLAS's threads made that product of (J, D) arrays take
        # ~140 ms on the loaded 2-core machine against ~3 ms here (rounding-level the same)
        cov = np.einsum("ji,jk->ik", Q, Q) / (Q.shape[0] - 1)
        cov = cov + (1e-12 + 1e-9 * np.trace(cov) / D) * np.eye(D)
        chol[t] = np.linalg.cholesky(cov) * (scale / np.sqrt(D))
    return chol


def walk_step(chol, tid, z) -> np.ndarray:
    """(J, D) steps ``chol[tid_j] z_j`` of hypotheses sorted by triplet ``tid`` (one matrix
    product per triplet, not a (J, D, D) gather)."""
    out = np.empty_like(z)
    bounds = np.searchsorted(tid, np.arange(chol.shape[0] + 1))
    for t in range(chol.shape[0]):
        lo, hi = bounds[t], bounds[t + 1]
        if hi > lo:
            out[lo:hi] = np.einsum("jk,ik->ji", z[lo:hi], chol[t])   # no BLAS threads
    return out


#: Step sizes of the chart proposals, drawn log-uniformly between the bounds per hypothesis and
#: proposal (a scale mixture, symmetric whatever the state): camera 1's move along its arc
#: (|AB| units), and the measurement residuals' (units of their sigmas).
RIDGE_STEPS = (0.003, 1.0)
NOISE_STEPS = (0.05, 1.0)

#: Proposals :func:`sweeps` knows.
KINDS = ("walk", "ridge", "noise")


def sweeps(poses, tid, movable, target, current, gens, n_sweeps, sigma_bearing, sigma_heading,
           kinds=KINDS, walk_scale=1.0, trace=None):
    """Metropolis-Hastings sweeps over trajectories ``poses`` (J, n, 3) of triplets ``tid`` (J,)
    (sorted), each leaving the density ``exp(target)`` over poses (x, y, alpha per view)
    invariant. ``target(rows, P)`` returns ``(log pi (len(rows),), extras)`` for trajectories
    ``P`` of the hypotheses ``rows``, ``extras`` a tuple of per-row arrays carried with the
    accepted state; ``current`` = (log pi (J,), extras) at ``poses``. Only hypotheses of triplets
    ``movable`` (T,) move. Per sweep, one proposal of each of ``kinds``:

    * ``"walk"``: the whole trajectory plus a Gaussian step with ``walk_scale^2 / D`` times the
      covariance of the triplet's hypotheses at the start of the sweep (:func:`walk_factor`);
      symmetric, so accepted on the target ratio;
    * ``"ridge"``: camera 1 moved ``s z`` along its arc in the chart of :func:`chart_of`, every
      residual held (``a1 += s |sin gamma_1| z``: ``|dX_1/da1| = 1 / |sin gamma_1|``);
    * ``"noise"``: every residual moved by ``s sigma z`` in that chart (``pa``, ``pb`` by the
      bearings' ``sigma_bearing``, ``rh`` by ``sigma_heading``, (T,) each), camera 1 held;

    the chart proposals are symmetric in the chart, so they are accepted on the target times the
    chart's Jacobian (:func:`poses_of`); ``s`` is drawn log-uniformly (:data:`RIDGE_STEPS`,
    :data:`NOISE_STEPS`). A proposal whose rays miss their arcs is rejected. Draws come from the
    triplets' generators ``gens`` in a fixed order. Returns (poses, log pi, extras).

    >>> rng = np.random.default_rng(0)
    >>> P0 = np.array([[[-1.0, 0.3, 0.1], [-1.1, 0.6, 0.2]]])
    >>> P = P0 + 0.01 * rng.standard_normal((50, 2, 3))
    >>> tgt = lambda k, Q: (-0.5 * np.sum(((Q - P[:1]) / 0.01) ** 2, axis=(1, 2)), ())
    >>> Q, lp, _ = sweeps(P, np.zeros(50, dtype=int), np.array([True]), tgt,
    ...                   tgt(None, P), [np.random.default_rng(1)], 2, np.array([0.03]), np.array([0.08]))
    >>> Q.shape, bool(np.all(np.isfinite(lp)))
    ((50, 2, 3), True)
    """
    poses = np.array(poses, dtype=float, copy=True)
    J, n = poses.shape[:2]
    T = movable.size
    cur = np.array(current[0], dtype=float, copy=True)
    extras = tuple(np.array(e, copy=True) for e in current[1])
    counts = np.bincount(tid, minlength=T)
    moving = movable[tid]
    a1, _, pa, pb, rh, br = chart_of(poses)
    lj = log_jacobian(poses)
    sv = np.asarray(sigma_bearing, dtype=float)[tid][:, None]
    sh = np.asarray(sigma_heading, dtype=float)[tid][:, None]
    for _ in range(int(n_sweeps)):
        # the walk's covariance from the hypotheses as they are at the start of each sweep
        # (the population's, as SMC samplers adapt their kernels; fixed within the sweep)
        chol = walk_factor(poses, tid, movable, walk_scale) if "walk" in kinds else None
        for kind in kinds:
            lo, hi = {"ridge": RIDGE_STEPS, "noise": NOISE_STEPS, "walk": (1.0, 1.0)}[kind]
            D = {"ridge": 1, "noise": 3 * n - 1, "walk": 3 * n}[kind]

            def draw(g, m, lo=lo, hi=hi, D=D):
                return (np.exp(g.uniform(np.log(lo), np.log(hi), m)), g.standard_normal((m, D)),
                        g.random(m))

            s, z, u = per_triplet(gens, counts, draw)
            if kind == "walk":
                prop = poses + walk_step(chol, tid, z).reshape(J, n, 3)
                prop[..., 2] = wrap_angle(prop[..., 2])
                lj2 = log_jacobian(prop)
                ok = moving & np.isfinite(lj2)
                dj = np.zeros(J)
            else:
                if kind == "ridge":
                    a2, pa2, pb2, rh2 = (a1 + s * np.abs(np.sin(pb[:, 0] - pa[:, 0])) * z[:, 0],
                                         pa, pb, rh)
                else:
                    zs = s[:, None] * z
                    a2, pa2, pb2, rh2 = (a1, wrap_angle(pa + sv * zs[:, :n]),
                                         wrap_angle(pb + sv * zs[:, n:2 * n]),
                                         wrap_angle(rh + sh * zs[:, 2 * n:]))
                prop, lj2, ok = poses_of(a2, pa2, pb2, rh2, br)
                ok &= moving
                with np.errstate(invalid="ignore"):
                    dj = lj2 - lj
            new = np.full(J, -np.inf)
            k = np.flatnonzero(ok)
            ex2 = None
            if k.size:
                new_k, ex2 = target(k, prop[k])
                new[k] = new_k
            with np.errstate(invalid="ignore"):
                acc = ok & np.isfinite(new) & (np.log(u) < new - cur + dj)
            if trace is not None:
                trace.append((n, kind, float(np.mean(ok[moving])) if moving.any() else 0.0,
                              float(np.mean(acc[moving])) if moving.any() else 0.0))
            if not acc.any():
                continue
            ka = np.searchsorted(k, np.flatnonzero(acc))   # accepted rows within k
            ia = k[ka]
            poses[ia], cur[ia], lj[ia] = prop[ia], new[ia], lj2[ia]
            for e, e2 in zip(extras, ex2, strict=True):
                e[ia] = e2[ka]
            if kind == "walk":
                # the chart coordinates of the accepted walks only
                a1[ia], _, pa[ia], pb[ia], rh[ia], br[ia] = chart_of(prop[ia])
            else:
                a1[ia], pa[ia], pb[ia], rh[ia], br[ia] = a2[ia], pa2[ia], pb2[ia], rh2[ia], br[ia]
    return poses, cur, extras


