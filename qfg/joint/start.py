"""Starts for the joint metric solve (:func:`qfg.joint.solve`): where each robot's poses and the
landmarks begin before Levenberg-Marquardt, with odometry and without it.

* **With odometry** (:func:`odometry_start`): the poses chained from the odometry, first pose at
  the origin; every ``chunk`` poses the landmarks with enough rays and parallax are placed by ray
  intersection and everything so far refitted; the poses ahead re-chained from the last refitted
  one.
* **Without odometry** (:func:`kinematic_start`): the odometry is replaced by a kinematic motion
  prior between consecutive images (:class:`KinematicPrior`: a differential-drive robot moves
  along its heading, ``X_i^{-1} X_{i+1} ~ N((v dt, 0, 0), diag(s)^2)``), the headings are
  started from the image-to-image change of the common landmarks' bearings
  (:func:`visual_steps`), and every ``chunk`` images the new poses are localised against the
  landmarks placed so far before new ones are placed and everything is refitted. A chunk whose
  fit leaves more than 3 % of its bearings beyond 4 sigmas (or a median above 1) is refitted
  without the landmarks it placed, and dropped when that fails too. Which minimum this reaches
  depends on ``chunk``: :func:`qfg.joint.solve` tries several sizes and keeps the least cost.
* **Robots checked against each other** (:func:`agreeing_group`): a fit without odometry can
  pass every residual check in a wrong minimum (docs/joint.md counts how often), so the robots
  whose maps agree in shape (:func:`shape_misfit`, similarity-invariant like the qualitative
  states) are the ones kept.

The measurements behind each number are in docs/joint.md ("Without odometry").

>>> import numpy as np
>>> s, R, t = similarity([[0, 0], [1, 0], [0, 1]], [[1, 1], [1, 3], [-1, 1]])
>>> round(s, 6), round(float(np.degrees(np.arctan2(R[1, 0], R[0, 0]))), 6), np.round(t, 6).tolist()
(2.0, 90.0, [1.0, 1.0])
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np

from .. import nonlinear as _nl
from .._validate import non_negative, positive_int
from ..geometry import wrap_angle

__all__ = ["KinematicPrior", "KINEMATIC", "AGREE", "kinematic_run", "visual_steps",
           "odometry_start", "kinematic_start", "similarity", "apply_similarity", "shape_misfit",
           "agreeing_group",
           "chain"]

#: Two robots' maps agree when, on their common landmarks, the median misfit after the best
#: similarity (each onto the other) is at most this share of the configuration's rms radius.
#: Loose enough that maps with ordinary noise agree, tight enough that a robot fitted in a wrong
#: minimum joins no group; chosen with the odometry withheld from runs whose ground truth shows
#: which fits are wrong (docs/joint.md, "Without odometry").
AGREE = 0.05


@dataclass(frozen=True)
class KinematicPrior:
    """The motion between consecutive images of a robot without odometry:
    ``X_i^{-1} X_{i+1} ~ N((speed dt, 0, 0), diag(s)^2)`` with
    ``s = (c_xy + sigma_speed dt, c_xy + sigma_lateral dt, c_turn + sigma_turn dt)``.

    Units: m/s, rad/s, m, rad. The defaults were set from the odometry of MRCLAM datasets 1-4
    and 6 (forward speed mean 0.048-0.060 m/s, rms 0.056-0.063; lateral rms 0.0015-0.0017;
    turn rms 0.13-0.17 rad/s; docs/joint.md); dataset 5 (no odometry) never set them.
    """

    speed: float = 0.055
    sigma_speed: float = 0.035
    sigma_lateral: float = 0.01
    sigma_turn: float = 0.2
    c_xy: float = 0.003
    c_turn: float = 0.01

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = non_negative(f.name, getattr(self, f.name))
            if f.name in ("c_xy", "c_turn") and v <= 0:
                raise ValueError(f"{f.name}: expected a standard deviation > 0, got {v}")

    def steps(self, dt) -> tuple[np.ndarray, np.ndarray]:
        """Mean relative poses (n, 3) and their standard deviations (n, 3) for time steps
        ``dt`` (n,) in seconds.

        >>> z, s = KinematicPrior().steps([1.0])
        >>> np.round(z, 3).tolist(), np.round(s, 3).tolist()
        ([[0.055, 0.0, 0.0]], [[0.038, 0.013, 0.21]])
        """
        dt = np.asarray(dt, float)
        z = np.column_stack([self.speed * dt, np.zeros_like(dt), np.zeros_like(dt)])
        s = np.column_stack([self.c_xy + self.sigma_speed * dt, self.c_xy + self.sigma_lateral * dt,
                             self.c_turn + self.sigma_turn * dt])
        return z, s


#: The default :class:`KinematicPrior`.
KINEMATIC = KinematicPrior()


def kinematic_run(run, prior: KinematicPrior = KINEMATIC):
    """``run`` (a :class:`qfg.joint.RobotRun`) with its odometry set to the kinematic prior's
    steps between its time stamps."""
    z, s = prior.steps(np.diff(run.times))
    return dataclasses.replace(run, odometry=z, odometry_sigma=s)


def visual_steps(run, prior: KinematicPrior = KINEMATIC) -> np.ndarray:
    """Start steps (P - 1, 3) of a run without odometry: forward ``speed dt`` and a heading
    change of minus the median change of the bearings of the landmarks both images see, 0 where
    they share none (a landmark's bearing turns opposite to the camera, and far landmarks'
    bearings change little with the small translation between images). A landmark with several
    bearings in one image counts by its last.

    >>> from qfg.joint import RobotRun
    >>> r = RobotRun(robot=1, times=[0.0, 1.0], bearing_pose=[0, 0, 1, 1],
    ...              bearing_landmark=[7, 8, 7, 8], bearing=[0.5, -0.2, 0.4, -0.3],
    ...              sigma_bearing=0.01)
    >>> np.round(visual_steps(r), 3).tolist()
    [[0.055, 0.0, 0.1]]
    """
    n = run.n_poses - 1
    dth = np.zeros(max(n, 0))
    if n > 0 and run.bearing.size:
        _, lm = np.unique(run.bearing_landmark, return_inverse=True)
        width = int(lm.max()) + 1
        key = run.bearing_pose.astype(np.int64) * width + lm
        # the last bearing of each (image, landmark): unique over the reversed arrays
        ukey, first = np.unique(key[::-1], return_index=True)
        val = run.bearing[::-1][first]
        nxt = np.searchsorted(ukey, ukey + width)
        has = nxt < ukey.size
        has[has] = ukey[nxt[has]] == ukey[has] + width
        pose = ukey[has] // width
        d = wrap_angle(val[nxt[has]] - val[has])
        if pose.size:
            order = np.lexsort((d, pose))
            pose, d = pose[order], d[order]
            starts = np.flatnonzero(np.r_[True, pose[1:] != pose[:-1]])
            counts = np.diff(np.r_[starts, pose.size])
            med = 0.5 * (d[starts + (counts - 1) // 2] + d[starts + counts // 2])
            dth[pose[starts]] = -med
    z, _ = prior.steps(np.diff(run.times))
    z[:, 2] = dth
    return z


def chain(start, steps) -> np.ndarray:
    """Poses (n + 1, 3) from ``start`` (3,) composed with relative ``steps`` (n, 3)."""
    out = np.empty((len(steps) + 1, 3))
    out[0] = start
    x, y, th = (float(v) for v in start)
    for i, (dx, dy, dt) in enumerate(np.asarray(steps, float)):
        c, s = np.cos(th), np.sin(th)
        x, y, th = x + c * dx - s * dy, y + s * dx + c * dy, th + dt
        out[i + 1] = (x, y, th)
    out[:, 2] = wrap_angle(out[:, 2])
    return out


# ----------------------------------------------------------------------------- shared pieces
def problem_of(runs, lm_index, points_ok, anchor_robot, *, robust, weak_prior=None,
               anchor=(0.0, 0.0, 0.0)):
    """One BearingProblem over ``runs`` (poses stacked run by run) and the landmarks with
    ``points_ok``; the first pose of ``anchor_robot`` anchored at ``anchor``. Returns
    ``(problem, pose offset of each robot, landmark rows in the problem)``."""
    offs, n = {}, 0
    for r in runs:
        offs[r.robot] = n
        n += r.n_poses
    col = -np.ones(len(lm_index), np.intp)
    ok = np.flatnonzero(points_ok)
    col[ok] = np.arange(ok.size)
    bp, bl, b, sb, ef, et, z, zs = [], [], [], [], [], [], [], []
    for r in runs:
        j = col[np.array([lm_index[int(x)] for x in r.bearing_landmark.tolist()], dtype=np.intp)
                if r.bearing_landmark.size else np.zeros(0, np.intp)]
        keep = j >= 0
        bp.append(r.bearing_pose[keep] + offs[r.robot])
        bl.append(j[keep])
        b.append(r.bearing[keep])
        sb.append(np.full(int(keep.sum()), r.sigma_bearing))
        if r.has_odometry and r.n_poses > 1:
            ef.append(np.arange(r.n_poses - 1) + offs[r.robot])
            et.append(np.arange(1, r.n_poses) + offs[r.robot])
            z.append(r.odometry)
            zs.append(r.odometry_sigma)

    def cat(xs, shape):
        return (np.concatenate(xs) if xs else np.zeros(shape))
    kw = {}
    if weak_prior is not None:
        kw = dict(point_prior_index=np.arange(ok.size), point_prior=weak_prior[0][ok],
                  point_prior_sigma=weak_prior[1])
    pr = _nl.BearingProblem(
        n_poses=n, n_points=ok.size, bearing_pose=cat(bp, 0), bearing_point=cat(bl, 0),
        bearing=cat(b, 0), sigma_bearing=cat(sb, 0) if sb else 1.0,
        between_from=cat(ef, 0), between_to=cat(et, 0), between=cat(z, (0, 3)),
        between_sigma=cat(zs, (0, 3)) if zs else 1.0,
        pose_prior_index=[offs[anchor_robot]], pose_prior=[list(anchor)],
        pose_prior_sigma=1e-6, robust_bearing=robust, **kw)
    return pr, offs, ok


def init_landmarks(poses, r, lm_index, points, have, *, upto, min_rays, min_par):
    """Place the landmarks of run ``r`` not yet in ``have`` from its rays at poses < ``upto``
    (in place): at least ``min_rays`` rays with ``min_par`` radians of parallax."""
    sel = r.bearing_pose < upto
    if not sel.any():
        return
    ids = r.bearing_landmark[sel]
    P = poses[r.bearing_pose[sel]]
    ang = P[:, 2] + r.bearing[sel]
    for lid in np.unique(ids).tolist():
        j = lm_index[lid]
        if have[j]:
            continue
        m = ids == lid
        if m.sum() < min_rays:
            continue
        p, ok, par = _nl.intersect_rays(P[m, :2], ang[m], r.sigma_bearing)
        if ok and par >= min_par and np.all(np.isfinite(p)):
            points[j] = p
            have[j] = True


def _spare(pr, drop) -> np.ndarray:
    """``drop`` (B,) bool without the bearings of points that would keep fewer than 3 rays."""
    left = np.bincount(pr.bearing_point[~drop], minlength=pr.n_points)
    return drop & (left[pr.bearing_point] >= 3)


def drop_outliers(pr, fit, limit, max_iterations):
    """Bearings whose whitened residual exceeds ``limit`` left out and the fit redone from it
    (misread barcodes and the like; a point keeps at least 3 rays). Returns (problem, fit,
    number dropped)."""
    if not limit:
        return pr, fit, 0
    drop = _spare(pr, np.abs(fit.bearing_residuals) > limit)
    if not drop.any():
        return pr, fit, 0
    pr2 = _nl.without_bearings(pr, drop)
    return pr2, _nl.fit(pr2, fit.poses, fit.points, max_iterations=max_iterations), int(drop.sum())


#: A bearing whose range in the fit is under this share of the median range of all bearings
#: marks a pose fitted onto the landmark it sees (:func:`escape_close`).
TOO_CLOSE = 1e-3


def _ranges(pr, fit) -> np.ndarray:
    return np.hypot(*(fit.points[pr.bearing_point] - fit.poses[pr.bearing_pose, :2]).T)


def escape_close(pr, fit, share: float, max_iterations: int, rounds: int = 5):
    """Poses fitted onto a landmark they see, moved off it. A bearing taken from a pose that
    stands on its landmark fits at any angle, so the least-squares fit can park a pose a few
    micrometres from a landmark (seen on MRCLAM without odometry: its information then makes
    the covariance ill-conditioned, and the fit's cost is higher than a nearby minimum's); a
    robot cannot stand on a landmark. The bearings under ``share`` x the median range are
    left out and the fit redone from it, again while the new fit parks a pose on a landmark
    (at most ``rounds`` times); then they are put back and the fit redone once more: kept back
    when that fit stays clear of them, else left out (a point keeps at least 3 rays). Returns
    (problem, fit, bearings left out, bearings found too close)."""
    if not share or not pr.bearing.size:
        return pr, fit, 0, 0
    keep = np.ones(pr.bearing.size, bool)
    cur, f = pr, fit
    for _ in range(rounds):
        d = _ranges(cur, f)
        close = _spare(cur, d < share * np.median(d))
        if not close.any():
            break
        keep[np.flatnonzero(keep)[close]] = False
        cur = _nl.without_bearings(pr, ~keep)
        f = _nl.fit(cur, f.poses, f.points, max_iterations=max_iterations)
    found = int(np.count_nonzero(~keep))
    if not found:
        return pr, fit, 0, 0
    back = _nl.fit(pr, f.poses, f.points, max_iterations=max_iterations)
    d = _ranges(pr, back)
    if not np.any(d < share * np.median(d)):
        return pr, back, 0, found
    return cur, f, found, found


#: A landmark farther from the poses that see it than this many times the median such distance
#: has diverged along its rays (:func:`diverged`).
DIVERGED = 10.0


def diverged(pr, fit, factor: float = DIVERGED) -> np.ndarray:
    """Points that ran away along their rays: median distance from the poses that see them
    above ``factor`` times the median of that distance over all points (a landmark initialised
    from rays of too little parallax drifts towards infinity, where every bearing fits)."""
    n = pr.n_points
    if n == 0:
        return np.zeros(0, bool)
    d = _ranges(pr, fit)
    med = np.array([np.median(d[pr.bearing_point == c]) if np.any(pr.bearing_point == c)
                    else 0.0 for c in range(n)])
    return med > factor * max(float(np.median(med)), 1e-12)


def cut(r, end: int):
    """The first ``end`` poses of a run (bearings of those poses only)."""
    if end >= r.n_poses:
        return r
    m = r.bearing_pose < end
    return dataclasses.replace(
        r, times=r.times[:end], bearing_pose=r.bearing_pose[m],
        bearing_landmark=r.bearing_landmark[m], bearing=r.bearing[m],
        odometry=None if r.odometry is None else r.odometry[:end - 1],
        odometry_sigma=None if r.odometry is None else r.odometry_sigma[:end - 1])


def _fit_placed(r, lm_index, have, poses, points, robust, max_iterations):
    """Levenberg-Marquardt over ``r``'s poses and its placed landmarks, leaving out (in
    ``have``) any that run away along their rays. Returns (problem, fit, rows) or Nones."""
    while True:
        pr, _, ok = problem_of([r], lm_index, have, r.robot, robust=robust)
        fit = _nl.fit(pr, poses, points[ok], max_iterations=max_iterations)
        far = diverged(pr, fit)
        if not far.any():
            return pr, fit, ok
        have[ok[far]] = False  # placed again later, from more rays
        if not have.any():
            return None, None, None


# ----------------------------------------------------------------------------- with odometry
def odometry_start(r, lm_index, *, chunk, min_rays, min_par, robust, max_iterations,
                   outlier=0.0):
    """Incremental batches for one run with odometry, first pose at the origin. Returns
    ``(poses (P, 3), points (L, 2), placed (L,) bool, fit or None)``."""
    L = len(lm_index)
    poses = chain(np.zeros(3), r.odometry)
    points = np.zeros((L, 2))
    have = np.zeros(L, bool)
    fit = None
    for end in list(range(chunk, r.n_poses, chunk)) + [r.n_poses]:
        init_landmarks(poses, r, lm_index, points, have, upto=end, min_rays=min_rays,
                       min_par=min_par)
        if not have.any():
            continue
        pr, fit, ok = _fit_placed(cut(r, end), lm_index, have, poses[:end], points, robust,
                                  max_iterations)
        if fit is None:
            continue
        if end == r.n_poses:
            pr, fit, _ = drop_outliers(pr, fit, outlier, max_iterations)
        poses[:end] = fit.poses
        points[ok] = fit.points
        if end < r.n_poses:
            poses[end - 1:] = chain(fit.poses[-1], r.odometry[end - 1:])
    return poses, points, have, fit


# ----------------------------------------------------------------------------- without odometry
def _localise(r, lm_index, poses, points, held, steps, a, b, *, window=40):
    """Poses a..b-1 fitted window by window against the landmarks ``held`` (held by tight
    priors, 1 cm), each window started from the previous one's last pose (loose prior: 5 cm,
    0.1 rad) and the run's kinematic steps."""
    start = chain(poses[a - 1], steps[a - 1:a])[-1] if a > 0 else poses[a]
    for s in range(a, b, window):
        e = min(s + window, b)
        sel = (r.bearing_pose >= s) & (r.bearing_pose < e)
        j = np.array([lm_index[int(x)] for x in r.bearing_landmark[sel]], dtype=np.intp)
        keep = held[j]
        sel[np.flatnonzero(sel)[~keep]] = False
        n = e - s
        pr = _nl.BearingProblem(
            n_poses=n, n_points=len(points), bearing_pose=r.bearing_pose[sel] - s,
            bearing_point=j[keep], bearing=r.bearing[sel], sigma_bearing=r.sigma_bearing,
            between_from=np.arange(n - 1), between_to=np.arange(1, n),
            between=r.odometry[s:e - 1], between_sigma=r.odometry_sigma[s:e - 1],
            point_prior_index=np.arange(len(points)), point_prior=points, point_prior_sigma=0.01,
            pose_prior_index=[0], pose_prior=[start], pose_prior_sigma=[0.05, 0.05, 0.1])
        f = _nl.fit(pr, chain(start, steps[s:e - 1]), points, max_iterations=50)
        poses[s:e] = f.poses
        if e < b:
            start = chain(f.poses[-1], steps[e - 1:e])[-1]


def _misfits(f) -> bool:
    """A chunk's fit disagrees with its bearings: over 3 % beyond 4 sigmas or a median above 1."""
    rb = np.abs(f.bearing_residuals)
    return bool(rb.size) and (np.mean(rb > 4) > 0.03 or np.median(rb) > 1.0)


def kinematic_start(r, lm_index, *, chunk: int = 50, min_rays: int = 5,
                    min_parallax_deg: float = 15.0, robust: float = _nl.HUBER_K,
                    prior: KinematicPrior = KINEMATIC, max_iterations: int = 200):
    """The start of a run without odometry (module docstring), then one fit of every pose and
    placed landmark under the kinematic prior, first pose at the origin.

    ``r`` must carry the kinematic prior as its odometry (:func:`kinematic_run`). Returns
    ``(poses (P, 3), points (L, 2), placed (L,) bool, fit or None)``; the fit's ``cost`` is the
    robust negative log posterior up to a constant, so that starts with the same placed
    landmarks compare.
    """
    if r.odometry is None:
        raise ValueError(f"robot {r.robot}: expected the kinematic prior as its odometry "
                         "(qfg.joint.start.kinematic_run)")
    chunk = positive_int("chunk", chunk, minimum=2)
    min_rays = positive_int("min_rays", min_rays, minimum=2)
    min_parallax_deg = non_negative("min_parallax_deg", min_parallax_deg)
    steps = visual_steps(r, prior)
    L = len(lm_index)
    min_par = np.deg2rad(min_parallax_deg)
    poses = chain(np.zeros(3), steps)
    points, have = np.zeros((L, 2)), np.zeros(L, bool)
    a = 0
    for end in list(range(chunk, r.n_poses, chunk)) + [r.n_poses]:
        saved = have.copy(), points.copy(), poses.copy()
        if have.any():
            _localise(r, lm_index, poses, points, have, steps, a, end)
        init_landmarks(poses, r, lm_index, points, have, upto=end, min_rays=min_rays,
                       min_par=min_par)
        f = None
        if have.any():
            sub = cut(r, end)
            for _ in range(2):
                _, f, ok = _fit_placed(sub, lm_index, have, poses[:end], points, robust, 100)
                new = have & ~saved[0]
                if f is None or not _misfits(f) or not new.any():
                    break
                have[new] = False           # again without the landmarks this chunk placed
            if f is not None and not _misfits(f):
                poses[:end], points[ok] = f.poses, f.points
            else:
                have[:], points[:], poses[:] = saved
        if end < r.n_poses:
            poses[end - 1:] = chain(poses[end - 1], steps[end - 1:])
        a = end
    if have.sum() < 3:
        return poses, points, have, None
    pr, _, ok = problem_of([r], lm_index, have, r.robot, robust=robust, anchor=poses[0])
    fit = _nl.fit(pr, poses, points[ok], max_iterations=max_iterations)
    poses = fit.poses.copy()
    points = points.copy()
    points[ok] = fit.points
    return poses, points, have, fit


# ----------------------------------------------------------------------------- agreement
def similarity(src, dst, *, scale: bool = True) -> tuple:
    """The similarity ``dst ~ s R src + t`` of least squares (Umeyama; a rotation, no
    reflection; ``scale=False``: s = 1, a rigid fit). ``src``, ``dst``: (n, 2) matched points,
    or stacks of them (..., n, 2) that broadcast (one fit per stack, e.g. every sample of a
    posterior onto one configuration). Returns ``(s, R (2, 2), t (2,))``; for stacks
    ``s`` (...), ``R`` (..., 2, 2), ``t`` (..., 2).

    >>> A = np.array([[0.0, 0], [1, 0], [0, 1]])
    >>> s, R, t = similarity(A, 2 * A[:, ::-1] * [1, -1] + 3)    # x2, turned -90 deg, moved
    >>> round(s, 9), (np.round(R, 9) + 0.0).tolist(), np.round(t, 9).tolist()
    (2.0, [[0.0, 1.0], [-1.0, 0.0]], [3.0, 3.0])
    >>> similarity(np.stack([A, 2 * A]), A)[0].round(9).tolist()
    [1.0, 0.5]
    """
    A, B = np.asarray(src, float), np.asarray(dst, float)
    ma, mb = A.mean(-2), B.mean(-2)
    A0, B0 = A - ma[..., None, :], B - mb[..., None, :]
    U, S, Vt = np.linalg.svd(np.swapaxes(A0, -1, -2) @ B0)
    d = np.sign(np.linalg.det(U @ Vt))
    d = np.where(d == 0, 1.0, d)
    D = np.zeros(d.shape + (2, 2))
    D[..., 0, 0], D[..., 1, 1] = 1.0, d
    R = np.swapaxes(U @ D @ Vt, -1, -2)
    if scale:
        s = (S[..., 0] + S[..., 1] * d) / np.maximum((A0 ** 2).sum((-2, -1)), 1e-300)
    else:
        s = np.ones(d.shape)
    t = mb - s[..., None] * (R @ ma[..., None])[..., 0]
    if np.ndim(s) == 0:
        return float(s), R, t
    return s, R, t


def apply_similarity(points, sim) -> np.ndarray:
    """``points`` (..., n, 2) moved by ``sim = (s, R, t)`` (:func:`similarity`'s answer, one
    fit or a stack of them): ``s R x + t``.

    >>> A = np.array([[0.0, 0], [1, 0], [0, 1]])
    >>> B = 2 * A + 3
    >>> np.round(apply_similarity(A, similarity(A, B)), 9).tolist() == B.tolist()
    True
    """
    s, R, t = sim
    X = np.asarray(points, float)
    return (np.asarray(s, float)[..., None, None] * X @ np.swapaxes(R, -1, -2)
            + np.asarray(t, float)[..., None, :])


def _apply(sc, R, t, poses=None, points=None):
    """Poses and points moved by the similarity ``x -> sc R x + t`` (headings turned by R)."""
    out = []
    if poses is not None:
        xy = apply_similarity(poses[:, :2], (sc, R, t))
        out.append(np.column_stack([xy, wrap_angle(poses[:, 2] + np.arctan2(R[1, 0], R[0, 0]))]))
    if points is not None:
        out.append(apply_similarity(points, (sc, R, t)))
    return out



def shape_misfit(a, b) -> float:
    """How far two maps of the same landmarks differ in shape: the median distance of ``a``
    (n, 2) mapped onto ``b`` by the best similarity, over ``b``'s rms radius (0: the same shape
    up to position, rotation and scale; qualitative states are invariant to these).

    >>> b = np.array([[0.0, 0], [1, 0], [0, 1], [1, 1]])
    >>> float(round(shape_misfit(3 * b + 5, b), 9))
    0.0
    """
    A, B = np.asarray(a, float), np.asarray(b, float)
    radius = float(np.sqrt(np.mean(np.sum((B - B.mean(0)) ** 2, axis=1))))
    return float(np.median(np.hypot(*(apply_similarity(A, similarity(A, B)) - B).T))) / max(
        radius, 1e-300)


def agreeing_group(maps: dict, tolerance: float = AGREE, *, min_common: int = 4) -> tuple:
    """The largest group (at least 2) of robots whose maps agree pairwise, or ``()``.

    ``maps``: robot -> (L, 2) landmark positions in any frame (NaN rows for landmarks it did
    not place). Two maps agree when they share at least ``min_common`` landmarks and
    :func:`shape_misfit` both ways is at most ``tolerance``. Among groups of the largest size
    the one of the lowest robot numbers is returned (networkx's maximal cliques of the
    agreement graph).

    >>> b = np.array([[0.0, 0], [1, 0], [0, 1], [1, 1], [2, 0]])
    >>> agreeing_group({1: b, 2: 2 * b + 1, 3: b[::-1]})
    (1, 2)
    """
    import networkx as nx

    non_negative("tolerance", tolerance)
    names = sorted(maps)
    g = nx.Graph()
    g.add_nodes_from(names)
    for i, j in itertools.combinations(names, 2):
        A, B = np.asarray(maps[i], float), np.asarray(maps[j], float)
        m = np.isfinite(A).all(1) & np.isfinite(B).all(1)
        if m.sum() >= min_common and max(shape_misfit(A[m], B[m]),
                                         shape_misfit(B[m], A[m])) <= tolerance:
            g.add_edge(i, j)
    best = ()
    for c in nx.find_cliques(g):
        c = tuple(sorted(c))
        if len(c) >= 2 and (len(c) > len(best) or (len(c) == len(best) and c < best)):
            best = c
    return best
