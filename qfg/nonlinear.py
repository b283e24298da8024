"""The project's one continuous nonlinear module: 2-D bearing (and odometry) least squares on
GTSAM's nonlinear factor graph.

A :class:`BearingProblem` holds measurements as arrays (no GTSAM objects): poses ``X_p = (x, y,
theta)`` and points ``L_j = (x, y)``, with

* bearing factors ``phi = wrap(atan2(L_y - y, L_x - x) - theta) + N(0, sigma^2)``
  (``gtsam.BearingFactor2D``; conventions.md);
* between factors ``z = X_a^{-1} X_b + N(0, diag(sigma^2))`` (``gtsam.BetweenFactorPose2``,
  odometry in the frame of pose ``a``);
* priors on poses and points (``PriorFactorPose2`` / ``PriorFactorPoint2``, diagonal).

Every bearing and between factor can carry a robust kernel (Huber, ``k`` in sigmas): the cost is
``sum rho(r_i)`` over whitened residuals ``r_i``, with ``rho(r) = r^2 / 2`` for ``|r| <= k`` and
``k |r| - k^2 / 2`` beyond. :func:`fit` minimises it with Levenberg-Marquardt from a start,
:func:`fit_best` from several starts (the lowest cost wins; the others are kept to detect a
second minimum), :func:`covariance` is the Laplace approximation at a fit (``gtsam.Marginals``:
the inverse of the Gauss-Newton information with the robust weights at the fit),
:func:`residuals` the whitened residuals in numpy, :func:`intersect_rays` a reweighted ray
intersection for starts without ground truth, and :func:`sample_gaussian` draws from a Gaussian.

>>> import numpy as np
>>> pr = BearingProblem(n_poses=2, n_points=1, bearing_pose=[0, 1], bearing_point=[0, 0],
...     bearing=[np.pi / 4, 3 * np.pi / 4], sigma_bearing=0.01,
...     pose_prior_index=[0, 1], pose_prior=[[0, 0, 0], [2, 0, 0]], pose_prior_sigma=1e-3)
>>> f = fit(pr, [[0, 0, 0], [2, 0, 0]], [[1.2, 0.8]])
>>> np.round(f.points, 3).tolist(), f.converged
([[1.0, 1.0]], True)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._validate import as_float_array, as_rng, non_negative, positive_int
from .geometry import wrap_angle

__all__ = ["BearingProblem", "Fit", "fit", "fit_best", "residuals", "covariance", "Laplace",
           "SingularInformation",
           "sample_gaussian", "gaussian_factor", "intersect_rays", "without_bearings",
           "robust_cost", "HUBER_K"]

#: Huber threshold in sigmas: 95% efficiency at the normal (the usual choice).
HUBER_K = 1.345


def _ints(name, v, n=None, upper=None) -> np.ndarray:
    a = np.asarray(v if v is not None else [], dtype=float).reshape(-1)
    if a.size and (not np.all(np.isfinite(a)) or np.any(a != np.round(a)) or a.min() < 0):
        raise ValueError(f"{name}: expected non-negative integers")
    a = a.astype(np.intp)
    if n is not None and a.size != n:
        raise ValueError(f"{name}: expected {n} entries, got {a.size}")
    if upper is not None and a.size and a.max() >= upper:
        raise ValueError(f"{name}: index {int(a.max())} out of range (< {upper})")
    return a


def _sig(name, v, shape) -> np.ndarray:
    a = np.broadcast_to(as_float_array(name, v if v is not None else 1.0), shape).astype(float)
    if a.size and a.min() <= 0:
        raise ValueError(f"{name}: expected standard deviations > 0, got {a.min()!r}")
    return a


@dataclass(frozen=True, eq=False)
class BearingProblem:
    """Measurements of a 2-D bearing / odometry problem (units: the caller's length, radians).

    Attributes:
        n_poses, n_points: numbers of variables (poses ``0..n_poses-1``, points
            ``0..n_points-1``).
        bearing_pose, bearing_point: (B,) indices of each bearing's pose and point.
        bearing: (B,) measured bearings; sigma_bearing: (B,) or scalar, their noise.
        between_from, between_to: (E,) pose indices; between: (E, 3) measured ``X_a^{-1} X_b``
            (dx, dy, dtheta in pose a's frame); between_sigma: (E, 3) or broadcastable.
        pose_prior_index, pose_prior (K, 3), pose_prior_sigma; point_prior_index,
            point_prior (J, 2), point_prior_sigma: diagonal Gaussian priors (anchors, weak
            priors).
        robust_bearing, robust_between: Huber thresholds in sigmas (0: plain least squares).
    """

    n_poses: int
    n_points: int
    bearing_pose: np.ndarray = None
    bearing_point: np.ndarray = None
    bearing: np.ndarray = None
    sigma_bearing: np.ndarray | float = 1.0
    between_from: np.ndarray = None
    between_to: np.ndarray = None
    between: np.ndarray = None
    between_sigma: np.ndarray | float = 1.0
    pose_prior_index: np.ndarray = None
    pose_prior: np.ndarray = None
    pose_prior_sigma: np.ndarray | float = 1.0
    point_prior_index: np.ndarray = None
    point_prior: np.ndarray = None
    point_prior_sigma: np.ndarray | float = 1.0
    robust_bearing: float = HUBER_K
    robust_between: float = 0.0

    def __post_init__(self):
        P = positive_int("n_poses", self.n_poses, minimum=0)
        L = positive_int("n_points", self.n_points, minimum=0)
        bp = _ints("bearing_pose", self.bearing_pose, upper=P)
        bl = _ints("bearing_point", self.bearing_point, n=bp.size, upper=L)
        b = as_float_array("bearing", self.bearing if self.bearing is not None else [], ndim=1)
        if b.size != bp.size:
            raise ValueError(f"bearing: expected {bp.size} values, got {b.size}")
        ef = _ints("between_from", self.between_from, upper=P)
        et = _ints("between_to", self.between_to, n=ef.size, upper=P)
        z = as_float_array("between", self.between if self.between is not None
                           else np.zeros((0, 3)), ndim=2, last_dim=3)
        if z.shape[0] != ef.size:
            raise ValueError(f"between: expected {ef.size} rows, got {z.shape[0]}")
        ki = _ints("pose_prior_index", self.pose_prior_index, upper=P)
        kp = as_float_array("pose_prior", self.pose_prior if self.pose_prior is not None
                            else np.zeros((0, 3)), ndim=2, last_dim=3)
        if kp.shape[0] != ki.size:
            raise ValueError(f"pose_prior: expected {ki.size} rows, got {kp.shape[0]}")
        ji = _ints("point_prior_index", self.point_prior_index, upper=L)
        jp = as_float_array("point_prior", self.point_prior if self.point_prior is not None
                            else np.zeros((0, 2)), ndim=2, last_dim=2)
        if jp.shape[0] != ji.size:
            raise ValueError(f"point_prior: expected {ji.size} rows, got {jp.shape[0]}")
        non_negative("robust_bearing", self.robust_bearing)
        non_negative("robust_between", self.robust_between)
        for k, v in (("bearing_pose", bp), ("bearing_point", bl), ("bearing", b),
                     ("sigma_bearing", _sig("sigma_bearing", self.sigma_bearing, b.shape)),
                     ("between_from", ef), ("between_to", et), ("between", z),
                     ("between_sigma", _sig("between_sigma", self.between_sigma, z.shape)),
                     ("pose_prior_index", ki), ("pose_prior", kp),
                     ("pose_prior_sigma", _sig("pose_prior_sigma", self.pose_prior_sigma,
                                               kp.shape)),
                     ("point_prior_index", ji), ("point_prior", jp),
                     ("point_prior_sigma", _sig("point_prior_sigma", self.point_prior_sigma,
                                                jp.shape))):
            object.__setattr__(self, k, v)

    def point_key(self, j):
        """GTSAM key of point ``j`` (poses are keys ``0..n_poses-1``)."""
        return self.n_poses + np.asarray(j)


@dataclass(frozen=True, eq=False)
class Fit:
    """A local minimum of a :class:`BearingProblem`.

    Attributes:
        poses: (P, 3); points: (L, 2).
        cost: the robust cost ``sum rho(r)`` at the fit (GTSAM's graph error).
        iterations: LM iterations; converged: the relative cost change fell below tolerance.
        bearing_residuals: (B,) whitened bearing residuals ``wrap(phi - predicted) / sigma``.
        between_residuals: (E, 3) whitened odometry residuals.
        start: index of the start that gave it (:func:`fit_best`).
        others: costs and points of the other starts' fits (``(cost, points)`` pairs).
    """

    poses: np.ndarray
    points: np.ndarray
    cost: float
    iterations: int
    converged: bool
    bearing_residuals: np.ndarray
    between_residuals: np.ndarray
    start: int = 0
    others: tuple = field(default=())


def _relative(Xa, Xb):
    """``X_a^{-1} X_b`` for pose arrays (..., 3)."""
    c, s = np.cos(Xa[..., 2]), np.sin(Xa[..., 2])
    dx, dy = Xb[..., 0] - Xa[..., 0], Xb[..., 1] - Xa[..., 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(Xb[..., 2] - Xa[..., 2])], -1)


def _between_error(h, z):
    """GTSAM's BetweenFactorPose2 error ``Logmap(z^{-1} h)`` for relative poses h, z (..., 3)."""
    cz, sz = np.cos(z[..., 2]), np.sin(z[..., 2])
    dx, dy = h[..., 0] - z[..., 0], h[..., 1] - z[..., 1]
    tx, ty = cz * dx + sz * dy, -sz * dx + cz * dy          # translation of z^{-1} h
    w = wrap_angle(h[..., 2] - z[..., 2])
    c, s = np.cos(w), np.sin(w)
    ux, uy = c * tx + s * ty - tx, -s * tx + c * ty - ty     # R^T t - t
    px, py = -uy, ux                                         # rotated by +90 degrees
    det = (c - 1.0) ** 2 + s ** 2
    small = np.abs(w) < 1e-10
    f = np.where(small, 0.0, w / np.where(small, 1.0, det))
    return np.stack([np.where(small, tx, f * px), np.where(small, ty, f * py), w], -1)


def residuals(problem: BearingProblem, poses, points):
    """Whitened residuals (bearing (B,), between (E, 3)) at ``poses`` (P, 3), ``points`` (L, 2);
    the between error is GTSAM's, the log map of ``z^{-1} X_a^{-1} X_b``."""
    X = np.asarray(poses, float).reshape(-1, 3)
    Lm = np.asarray(points, float).reshape(-1, 2)
    pr = problem
    Xb = X[pr.bearing_pose]
    d = Lm[pr.bearing_point] - Xb[:, :2]
    pred = np.arctan2(d[:, 1], d[:, 0]) - Xb[:, 2]
    rb = wrap_angle(pr.bearing - pred) / pr.sigma_bearing
    e = _between_error(_relative(X[pr.between_from], X[pr.between_to]), pr.between)
    return rb, e / pr.between_sigma


def robust_cost(problem: BearingProblem, poses, points) -> np.ndarray:
    """The problem's cost ``sum rho(r)`` (the negative log posterior up to a constant) at
    ``poses`` (..., P, 3) and ``points`` (..., L, 2), vectorized over the leading axes: Huber
    on bearings (and on betweens when ``robust_between``), squares on the priors; the same
    errors as GTSAM's factors (between: the log map of ``z^{-1} X_a^{-1} X_b``).

    >>> pr = BearingProblem(1, 1, [0], [0], [0.1], 0.1, pose_prior_index=[0],
    ...                     pose_prior=[[0, 0, 0]], pose_prior_sigma=1.0)
    >>> round(float(robust_cost(pr, [[0, 0, 0]], [[1, 0]])), 9)
    0.5
    """
    pr = problem
    X = np.asarray(poses, float)
    Lm = np.asarray(points, float)
    Xb = X[..., pr.bearing_pose, :]
    d = Lm[..., pr.bearing_point, :] - Xb[..., :2]
    pred = np.arctan2(d[..., 1], d[..., 0]) - Xb[..., 2]
    c = _rho(wrap_angle(pr.bearing - pred) / pr.sigma_bearing, pr.robust_bearing).sum(-1)
    if pr.between.shape[0]:
        e = _between_error(_relative(X[..., pr.between_from, :], X[..., pr.between_to, :]),
                           pr.between)
        c = c + _rho(e / pr.between_sigma, pr.robust_between).sum((-1, -2))
    if pr.pose_prior.shape[0]:
        e = X[..., pr.pose_prior_index, :] - pr.pose_prior
        e[..., 2] = wrap_angle(e[..., 2])
        c = c + 0.5 * ((e / pr.pose_prior_sigma) ** 2).sum((-1, -2))
    if pr.point_prior.shape[0]:
        e = (Lm[..., pr.point_prior_index, :] - pr.point_prior) / pr.point_prior_sigma
        c = c + 0.5 * (e ** 2).sum((-1, -2))
    return c


def _rho(r, k):
    a = np.abs(r)
    return np.where(a <= k, 0.5 * r * r, k * a - 0.5 * k * k) if k > 0 else 0.5 * r * r


def without_bearings(problem: BearingProblem, drop) -> BearingProblem:
    """The problem with the bearings where ``drop`` (B,) is True left out (gross outliers: a
    Huber kernel bounds their pull but does not remove it)."""
    import dataclasses

    drop = np.asarray(drop, bool)
    if drop.shape != problem.bearing.shape:
        raise ValueError(f"drop: expected shape {problem.bearing.shape}, got {drop.shape}")
    k = ~drop
    return dataclasses.replace(problem, bearing_pose=problem.bearing_pose[k],
                               bearing_point=problem.bearing_point[k],
                               bearing=problem.bearing[k], sigma_bearing=problem.sigma_bearing[k])


def _noise(sig, k):
    import gtsam

    base = gtsam.noiseModel.Diagonal.Sigmas(np.asarray(sig, float))
    if k > 0:
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(k), base)
    return base


def _graph(pr: BearingProblem):
    import gtsam

    g = gtsam.NonlinearFactorGraph()
    kb = float(pr.robust_bearing)
    cache = {}
    for p, j, phi, s in zip(pr.bearing_pose.tolist(), pr.bearing_point.tolist(),
                            pr.bearing.tolist(), pr.sigma_bearing.tolist(), strict=False):
        n = cache.get(s)
        if n is None:
            n = cache[s] = _noise([s], kb)
        g.add(gtsam.BearingFactor2D(p, pr.n_poses + j, gtsam.Rot2(phi), n))
    ke = float(pr.robust_between)
    for a, b, z, s in zip(pr.between_from.tolist(), pr.between_to.tolist(), pr.between,
                          pr.between_sigma, strict=False):
        g.add(gtsam.BetweenFactorPose2(a, b, gtsam.Pose2(*z), _noise(s, ke)))
    for i, z, s in zip(pr.pose_prior_index.tolist(), pr.pose_prior, pr.pose_prior_sigma, strict=False):
        g.add(gtsam.PriorFactorPose2(i, gtsam.Pose2(*z), _noise(s, 0.0)))
    for j, z, s in zip(pr.point_prior_index.tolist(), pr.point_prior, pr.point_prior_sigma, strict=False):
        g.add(gtsam.PriorFactorPoint2(pr.n_poses + j, np.asarray(z, float), _noise(s, 0.0)))
    return g


def _values(pr, poses, points):
    import gtsam

    v = gtsam.Values()
    for i, x in enumerate(np.asarray(poses, float).reshape(-1, 3)):
        v.insert(i, gtsam.Pose2(*x))
    for j, p in enumerate(np.asarray(points, float).reshape(-1, 2)):
        v.insert(pr.n_poses + j, np.array(p))
    return v


def _extract(pr, v):
    import gtsam

    X = gtsam.utilities.extractPose2(v).reshape(-1, 3) if pr.n_poses else np.zeros((0, 3))
    L = gtsam.utilities.extractPoint2(v).reshape(-1, 2) if pr.n_points else np.zeros((0, 2))
    return X, L


def _check_start(pr, poses, points):
    X = as_float_array("poses", poses, ndim=2, last_dim=3) if pr.n_poses else np.zeros((0, 3))
    L = as_float_array("points", points, ndim=2, last_dim=2) if pr.n_points else np.zeros((0, 2))
    if X.shape[0] != pr.n_poses:
        raise ValueError(f"poses: expected {pr.n_poses} rows, got {X.shape[0]}")
    if L.shape[0] != pr.n_points:
        raise ValueError(f"points: expected {pr.n_points} rows, got {L.shape[0]}")
    return X, L


def fit(problem: BearingProblem, poses, points, *, max_iterations: int = 100,
        relative_tolerance: float = 1e-6, _graph_cache=None) -> Fit:
    """Levenberg-Marquardt from the start ``poses`` (P, 3), ``points`` (L, 2). The problem should
    fix its gauge (a pose prior, or point priors): LM's damping lets a free gauge drift, and its
    :func:`covariance` is then undefined (a ValueError naming the problem)."""
    import gtsam

    X0, L0 = _check_start(problem, poses, points)
    g = _graph(problem) if _graph_cache is None else _graph_cache
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(positive_int("max_iterations", max_iterations))
    params.setRelativeErrorTol(float(relative_tolerance))
    params.setAbsoluteErrorTol(0.0)
    try:
        opt = gtsam.LevenbergMarquardtOptimizer(g, _values(problem, X0, L0), params)
        v = opt.optimize()
    except RuntimeError as exc:  # IndeterminantLinearSystemException and kin
        raise ValueError(f"problem: the system is not determined ({exc}); anchor a pose or "
                         "leave out points without enough rays") from None
    it = int(opt.iterations())
    X, L = _extract(problem, v)
    rb, re = residuals(problem, X, L)
    return Fit(poses=X, points=L, cost=float(g.error(v)), iterations=it,
               converged=it < max_iterations, bearing_residuals=rb, between_residuals=re)


def fit_best(problem: BearingProblem, starts, **options) -> Fit:
    """:func:`fit` from each ``(poses, points)`` start; the fit of lowest cost, with the other
    fits' ``(cost, points)`` in ``others`` (to tell a second minimum from the same one)."""
    starts = list(starts)
    if not starts:
        raise ValueError("starts: expected at least one (poses, points) start")
    g = _graph(problem)
    fits = [fit(problem, X, L, _graph_cache=g, **options) for X, L in starts]
    best = int(np.argmin([f.cost for f in fits]))
    others = tuple((f.cost, f.points) for i, f in enumerate(fits) if i != best)
    f = fits[best]
    return Fit(poses=f.poses, points=f.points, cost=f.cost, iterations=f.iterations,
               converged=f.converged, bearing_residuals=f.bearing_residuals,
               between_residuals=f.between_residuals, start=best, others=others)


class SingularInformation(ValueError):
    """The Laplace covariance is undefined: the information has a (numerically) null direction.
    ``key``: the GTSAM key of a variable involved (poses ``0..P-1``, points ``P..``), or None."""

    def __init__(self, message, key=None):
        super().__init__(message)
        self.key = key


class Laplace:
    """The Laplace approximation at a fit: joint covariances of any points and poses.

    ``gtsam.Marginals`` (multifrontal Cholesky of the Gauss-Newton information ``A^T A``, ``A``
    the whitened Jacobian with the Huber weights at the fit) answers when it can. Its Cholesky
    fails on information that is ill-conditioned but not singular: a fit that puts a pose a few
    micrometres from a landmark it sees gives that bearing information ~1e13 (its Jacobian grows
    as 1 / range) and ``cond(A^T A)`` ~ 1/eps (MRCLAM datasets 2 and 6 solved without
    odometry). Then the requested columns of ``(A^T A)^{-1}`` are solved from the augmented
    system ``[[a I, As], [As^T, 0]]`` (Bjorck; ``As``: ``A`` with unit column norms; accuracy
    ~ cond(A) eps instead of the normal equations' cond(A)^2 eps) by a sparse LU
    (``scipy.sparse.linalg.splu``) with one step of iterative refinement. A truly singular
    system is reported, not filled by round-off: two factorisations (``a`` = 1 and 0.25, other
    pivots, the same answer in exact arithmetic) must agree to ``atol`` relative and the result
    must be positive definite, else :class:`SingularInformation`.

    ``solver``: ``"auto"`` (GTSAM, the sparse solve where it fails) or ``"sparse"`` (always).
    ``method``: which answers (``"gtsam"`` / ``"sparse"``); ``error``: GTSAM's message.
    """

    def __init__(self, problem: BearingProblem, result: Fit, *, solver: str = "auto",
                 atol: float = 1e-7, rcond: float = 1e-15):
        import gtsam

        if solver not in ("auto", "sparse"):
            raise ValueError(f"solver: expected 'auto' or 'sparse', got {solver!r}")
        self.problem, self.result, self.atol, self.rcond = problem, result, atol, rcond
        self.error = None
        self._marginals = None
        self._graph = _graph(problem)
        self._values = _values(problem, result.poses, result.points)
        if solver == "auto":
            try:
                self._marginals = gtsam.Marginals(self._graph, self._values)
            except RuntimeError as exc:
                self.error = " ".join(str(exc).split())[:300]

    @property
    def method(self) -> str:
        return "gtsam" if self._marginals is not None else "sparse"

    @property
    def error_key(self):
        """The variable GTSAM's failure named (None: no failure, or none named)."""
        return _gtsam_key(self.error or "")

    def _keys(self, points, poses):
        P = self.problem.n_poses
        return [P + int(j) for j in points] + [int(i) for i in poses]

    def joint(self, points=(), poses=()) -> np.ndarray:
        """Covariance of ``points`` then ``poses`` (index lists), (2 n_points + 3 n_poses)
        square in that order; pose blocks in GTSAM's tangent coordinates (x, y along the
        pose's own axes, theta). Raises :class:`SingularInformation`."""
        import gtsam

        points, poses = [int(j) for j in points], [int(i) for i in poses]
        keys = self._keys(points, poses)
        if not keys:
            return np.zeros((0, 0))
        if len(set(keys)) != len(keys):
            raise ValueError("points / poses: a variable named twice")
        if self._marginals is not None:
            try:
                jm = self._marginals.jointMarginalCovariance(gtsam.KeyVector(keys))
            except RuntimeError as exc:
                raise SingularInformation(" ".join(str(exc).split())[:300],
                                          _gtsam_key(str(exc))) from None
            dims = [2] * len(points) + [3] * len(poses)
            off = np.concatenate([[0], np.cumsum(dims)]).astype(int)
            C = np.zeros((off[-1], off[-1]))
            for a, ka in enumerate(keys):
                for b in range(a, len(keys)):
                    blk = np.asarray(jm.at(ka, keys[b]))
                    C[off[a]:off[a + 1], off[b]:off[b + 1]] = blk
                    C[off[b]:off[b + 1], off[a]:off[a + 1]] = blk.T
            return C
        return self._sparse(keys)

    def _column(self, key):
        P = self.problem.n_poses
        return (3 * key, 3) if key < P else (3 * P + 2 * (key - P), 2)

    def _key_of(self, col):
        P = self.problem.n_poses
        return int(col // 3) if col < 3 * P else int(P + (col - 3 * P) // 2)

    def _jacobian(self):
        """GTSAM's whitened, robust-weighted Jacobian at the fit (scipy CSC, columns: poses
        then points, as ``sparseJacobian_`` orders the keys)."""
        import scipy.sparse as sp

        ijs = np.asarray(self._graph.linearize(self._values).sparseJacobian_())
        if ijs.shape[0] != 3:
            ijs = ijs.T
        i = np.rint(ijs[0]).astype(np.intp) - 1
        j = np.rint(ijs[1]).astype(np.intp) - 1
        n = 3 * self.problem.n_poses + 2 * self.problem.n_points
        var = j < n                                  # the last column is the right-hand side
        m = int(i.max()) + 1 if i.size else 0
        return sp.csc_matrix((ijs[2][var], (i[var], j[var])), shape=(m, n))

    def _sparse(self, keys, block: int = 256, check: int = 64):
        import scipy.sparse as sp
        import scipy.sparse.linalg as spla

        sel = np.concatenate([np.arange(o, o + d) for o, d in map(self._column, keys)])
        A = self._jacobian()
        d = np.sqrt(np.asarray(A.multiply(A).sum(axis=0)).ravel())
        if not np.all(d > 0):
            k = self._key_of(int(np.flatnonzero(~(d > 0))[0]))
            raise SingularInformation(f"no factor constrains variable {k}", k)
        As = A @ sp.diags(1.0 / d)
        m, n = As.shape
        n_check = min(sel.size, check)
        out = {}
        worst = 0.0
        for a in (1.0, 0.25):
            K = sp.bmat([[a * sp.identity(m), As], [As.T, None]], format="csc")
            try:
                lu = spla.splu(K, permc_spec="MMD_AT_PLUS_A")
            except RuntimeError as exc:              # "Factor is exactly singular"
                raise SingularInformation(f"information singular ({exc})",
                                          self.error_key) from None
            upto = sel.size if a == 1.0 else n_check
            C = np.empty((sel.size, upto))
            for b in range(0, upto, block):
                s = sel[b:min(b + block, upto)]
                R = np.zeros((m + n, s.size))
                R[m + s, np.arange(s.size)] = 1.0
                X = lu.solve(R)
                X += lu.solve(R - K @ X)             # one step of iterative refinement
                worst = max(worst, float(np.abs(R - K @ X).max() / max(np.abs(X).max(), 1.0)))
                C[:, b:b + s.size] = -X[m + sel] / a
            out[a] = C
        Cs, C2 = out[1.0], out[0.25]
        agree = float(np.abs(Cs[:, :n_check] - C2).max() / max(np.abs(Cs).max(), 1e-300))
        if not np.all(np.isfinite(Cs)) or worst > 1e-8 or not agree < self.atol:
            raise SingularInformation(
                f"information singular or too ill-conditioned: two factorisations differ by "
                f"{agree:.2g} relative (residual {worst:.2g}); GTSAM: {self.error}",
                self.error_key)
        Cs = 0.5 * (Cs + Cs.T)
        w, V = np.linalg.eigh(Cs)
        if not (w[0] > 0 and 1.0 / w[-1] > self.rcond):
            k = self._key_of(int(sel[int(np.argmax(np.abs(V[:, -1])))]))
            raise SingularInformation(f"information singular along a direction of the asked "
                                      f"variables, largest on variable {k}", k)
        return Cs / np.outer(d[sel], d[sel])


def _gtsam_key(message: str):
    """The variable GTSAM names in an indeterminant-system message, or None."""
    import re

    m = re.search(r"near variable\s+(\d+)", message)
    return int(m.group(1)) if m else None


def covariance(problem: BearingProblem, result: Fit, points=(), poses=()) -> np.ndarray:
    """Joint covariance (Laplace approximation at ``result``) of ``points`` then ``poses``
    (index lists), (2 n_points + 3 n_poses) square, in that order; pose blocks in GTSAM's
    tangent coordinates (x, y along the pose's own axes, theta). :class:`Laplace` has the
    method (gtsam.Marginals, a sparse solve where its Cholesky fails); a singular problem is a
    ValueError (:class:`SingularInformation`)."""
    try:
        return Laplace(problem, result).joint(points, poses)
    except SingularInformation as exc:
        raise SingularInformation(f"problem: covariance undefined ({exc})", exc.key) from None


def gaussian_factor(cov) -> np.ndarray:
    """``F`` with ``F F^T = cov`` (symmetric eigen factorisation, negative eigenvalues from
    round-off clipped to 0): ``mean + z F^T`` with standard normal ``z`` draws N(mean, cov)."""
    C = np.asarray(cov, float)
    w, V = np.linalg.eigh((C + C.T) / 2)
    return V * np.sqrt(np.clip(w, 0.0, None))


def sample_gaussian(mean, cov, n: int, seed=0, *, df: float = 0.0) -> np.ndarray:
    """``n`` draws (n, d) of N(mean, cov) (``df`` > 0: multivariate Student t with ``df``
    degrees of freedom and scale ``cov``, a heavier-tailed proposal). Symmetric eigen
    factorisation, negative eigenvalues (round-off) clipped to 0."""
    mu = as_float_array("mean", mean, ndim=1)
    C = as_float_array("cov", cov, ndim=2)
    if C.shape != (mu.size, mu.size):
        raise ValueError(f"cov: expected shape {(mu.size, mu.size)}, got {C.shape}")
    n = positive_int("n", n, minimum=0)
    rng = as_rng(seed)
    z = rng.standard_normal((n, mu.size)) @ gaussian_factor(C).T
    if df > 0:
        z = z / np.sqrt(rng.chisquare(df, size=(n, 1)) / df)
    return mu + z


def intersect_rays(origins, angles, sigma, *, iterations: int = 5, k: float = HUBER_K):
    """Reweighted intersection of rays from ``origins`` (n, 2) at world ``angles`` (n,).

    Iteratively reweighted least squares on the perpendicular distances ``n_i . (p - o_i)``:
    each ray weighted by ``1 / (sigma d_i)^2`` (an angle error sigma moves the ray by sigma d_i at
    range d_i) times the Huber weight of its angular residual (``k`` sigmas), the first round
    unweighted. Rays that point away from the estimate (behind the camera) get weight 0.
    Returns ``(point (2,), ok, parallax)``: ``ok`` False when the rays are parallel or fewer
    than 2 keep weight; ``parallax`` the largest angle (radians, <= pi/2... pi) between kept
    rays.

    >>> p, ok, par = intersect_rays([[0, 0], [2, 0], [1, -1]], [np.pi/4, 3*np.pi/4, np.pi/2], 0.01)
    >>> np.round(p, 6).tolist(), ok
    ([1.0, 1.0], True)
    """
    o = as_float_array("origins", origins, ndim=2, last_dim=2)
    th = as_float_array("angles", angles, ndim=1)
    if th.size != o.shape[0]:
        raise ValueError(f"angles: expected {o.shape[0]} values, got {th.size}")
    s = non_negative("sigma", sigma) or 1e-3
    nrm = np.stack([-np.sin(th), np.cos(th)], -1)
    u = np.stack([np.cos(th), np.sin(th)], -1)
    w = np.ones(th.size)
    p = o.mean(axis=0)
    ok = False
    for _it in range(iterations + 1):
        M = np.einsum("n,ni,nj->ij", w, nrm, nrm)
        if np.linalg.det(M) <= 1e-12 * max(w.sum(), 1.0) ** 2 or np.count_nonzero(w) < 2:
            ok = False
            break
        p = np.linalg.solve(M, np.einsum("n,ni,nj,nj->i", w, nrm, nrm, o))
        ok = True
        d = p - o
        rng_ = np.einsum("ni,ni->n", d, u)
        dist = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
        r = wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - th) / s
        hub = np.where(np.abs(r) <= k, 1.0, k / np.maximum(np.abs(r), 1e-12))
        w = np.where(rng_ > 0, hub / dist ** 2, 0.0)
    keep = w > 0 if ok else np.ones(th.size, bool)
    a = th[keep]
    par = 0.0
    if a.size >= 2:
        # the largest angle between two kept ray directions, modulo pi (lines)
        diff = np.abs(wrap_angle(a[:, None] - a[None, :]))
        par = float(np.max(np.minimum(diff, np.pi - diff)))
    return p, bool(ok), par
