"""Checking the data against itself: landmark fixes, the landmark identity check, bearing
residuals at fixes, the odometry's turn against fixes, dead reckoning placed at a fix."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..._validate import as_float_array, positive_int
from ...geometry import bearing, wrap_angle
from ._constants import DEFAULT_ODOMETRY_LEAD
from ._data import MRCLAMDataset


@dataclass(frozen=True, eq=False)
class LandmarkFixes:
    """Robot poses estimated from range and bearing to known landmarks, one per view with >= 2.

    Not ground truth (only dataset 6 has robot ground truth); used to check the odometry and the
    bearing noise and to place a dead-reckoned path in the world frame.

    Attributes:
        times: (F,) view times (s).
        view_index: (F,) indices into ``RobotData.view_times``.
        poses: (F, 3) world poses (x, y, theta).
        n_landmarks: (F,) landmarks used.
        residual: (F,) root-mean-square distance (m) between the landmarks and their measured
            positions after the fit.
    """

    times: np.ndarray
    view_index: np.ndarray
    poses: np.ndarray
    n_landmarks: np.ndarray
    residual: np.ndarray


def _rigid_fits(ranges, bearings, visible, landmark_xy):
    """Poses (V, 3) and rms residuals (V,) of rigid fits, vectorized over views (see
    :func:`landmark_fixes`). ``visible`` (V, L) must have at least 2 True per row."""
    vis = visible.astype(float)
    n = vis.sum(axis=1)
    q = ranges[..., None] * np.stack([np.cos(bearings), np.sin(bearings)], axis=-1)
    p = np.broadcast_to(landmark_xy, q.shape)
    qm = np.einsum("vl,vld->vd", vis, q) / n[:, None]
    pm = np.einsum("vl,vld->vd", vis, p) / n[:, None]
    qc, pc = q - qm[:, None], p - pm[:, None]
    cross = np.einsum("vl,vl->v", vis, qc[..., 0] * pc[..., 1] - qc[..., 1] * pc[..., 0])
    dot = np.einsum("vl,vl->v", vis, np.sum(qc * pc, axis=-1))
    th = np.arctan2(cross, dot)
    c, s = np.cos(th), np.sin(th)
    t = pm - np.stack([c * qm[:, 0] - s * qm[:, 1], s * qm[:, 0] + c * qm[:, 1]], axis=-1)
    rq = np.stack([c[:, None] * q[..., 0] - s[:, None] * q[..., 1],
                   s[:, None] * q[..., 0] + c[:, None] * q[..., 1]], axis=-1) + t[:, None]
    res = np.sqrt(np.einsum("vl,vl->v", vis, np.sum((rq - p) ** 2, axis=-1)) / n)
    return np.column_stack([t, wrap_angle(th)]), res


def landmark_fixes(dataset: MRCLAMDataset, robot, *, min_landmarks: int = 2,
                   exclude=None) -> LandmarkFixes:
    """Least-squares rigid fit of each view's measured landmark positions to their ground truth.

    A landmark seen at range r and bearing phi is at ``q = r (cos phi, sin phi)`` in the robot
    frame. For views with at least ``min_landmarks`` landmarks, the pose (R(theta), t) minimizing
    ``sum_i |R q_i + t - p_i|^2`` is the 2-D Procrustes solution: with centred points,
    ``theta = atan2(sum q x p, sum q . p)`` and ``t = mean(p) - R mean(q)`` (vectorized over views).
    ``exclude``: landmark subject numbers left out of every fit.
    """
    rd = dataset.robot(robot)
    min_landmarks = positive_int("min_landmarks", min_landmarks, minimum=2)
    visible = rd.visible
    if exclude is not None:
        visible = visible.copy()
        visible[:, dataset.landmark_index(np.atleast_1d(exclude))] = False
    sel = np.flatnonzero(visible.sum(axis=1) >= min_landmarks)
    poses, res = _rigid_fits(rd.view_ranges[sel], rd.view_bearings[sel], visible[sel],
                             dataset.landmark_xy)
    return LandmarkFixes(times=rd.view_times[sel], view_index=sel, poses=poses,
                         n_landmarks=visible[sel].sum(axis=1).astype(int), residual=res)


@dataclass(frozen=True, eq=False)
class LandmarkCheck:
    """Where each landmark is seen, against its ground truth (:func:`check_landmarks`).

    Attributes:
        landmark_ids: (L,) subject numbers.
        n_observations: (L,) measurements used (seen from a good fix made without the landmark).
        observed_xy: (L, 2) median world position of those measurements (m); ground truth where
            there are none.
        error: (L,) distance (m) from ``observed_xy`` to the landmark's ground truth.
        nearest: (L,) subject whose ground truth is nearest to ``observed_xy``.
        swaps: pairs (a, b), a < b, each seen at the other's ground-truth position.
    """

    landmark_ids: np.ndarray
    n_observations: np.ndarray
    observed_xy: np.ndarray
    error: np.ndarray
    nearest: np.ndarray
    swaps: tuple


def check_landmarks(dataset: MRCLAMDataset, *, min_landmarks: int = 3, max_residual: float = 0.15,
                    tolerance: float = 0.5) -> LandmarkCheck:
    """Check the barcode -> landmark -> ground-truth chain against the measurements themselves.

    For each landmark l and robot, fix the robot's pose in every view from the *other* landmarks
    (:func:`landmark_fixes` with ``exclude=l``, at least ``min_landmarks``, rms residual at most
    ``max_residual`` m) and place l's range-bearing measurement in the world. The median of those
    positions should be at l's ground truth; a pair of landmarks each seen within ``tolerance`` m
    of the other's ground truth (and not of its own) is reported as a swap.
    """
    L = dataset.landmark_ids.size
    n_obs = np.zeros(L, dtype=int)
    obs_xy = dataset.landmark_xy.copy()
    for li, lid in enumerate(dataset.landmark_ids):
        pts = []
        for n, rd in dataset.robots.items():
            f = landmark_fixes(dataset, n, min_landmarks=min_landmarks, exclude=lid)
            ok = (f.residual <= max_residual) & rd.visible[f.view_index, li]
            v, P = f.view_index[ok], f.poses[ok]
            r, b = rd.view_ranges[v, li], rd.view_bearings[v, li]
            pts.append(P[:, :2] + r[:, None] * np.stack([np.cos(P[:, 2] + b), np.sin(P[:, 2] + b)], -1))
        pts = np.concatenate(pts) if pts else np.zeros((0, 2))
        n_obs[li] = pts.shape[0]
        if pts.shape[0]:
            obs_xy[li] = np.median(pts, axis=0)
    d = np.linalg.norm(obs_xy[:, None, :] - dataset.landmark_xy[None, :, :], axis=-1)  # (L, L)
    nearest_col = np.argmin(d, axis=1)
    err = d[np.arange(L), np.arange(L)]
    swaps = []
    for i in range(L):
        j = int(nearest_col[i])
        if (j > i and nearest_col[j] == i and d[i, j] <= tolerance and d[j, i] <= tolerance
                and err[i] > tolerance and err[j] > tolerance):
            swaps.append((int(dataset.landmark_ids[i]), int(dataset.landmark_ids[j])))
    return LandmarkCheck(landmark_ids=dataset.landmark_ids.copy(), n_observations=n_obs,
                         observed_xy=obs_xy, error=err, nearest=dataset.landmark_ids[nearest_col],
                         swaps=tuple(swaps))


def swap_landmarks(dataset: MRCLAMDataset, pairs) -> MRCLAMDataset:
    """A copy of ``dataset`` with the ground truth (position, std-dev) of each landmark pair (a, b)
    exchanged. Measurements, barcodes and views are unchanged: only what the ids are scored
    against moves. Use with :func:`check_landmarks`: ``swap_landmarks(ds, check_landmarks(ds).swaps)``.
    """
    xy, sd = dataset.landmark_xy.copy(), dataset.landmark_std.copy()
    for pair in pairs:
        if len(pair) != 2:
            raise ValueError(f"pairs: expected (a, b) pairs of landmark subjects, got {pair!r}")
        i, j = dataset.landmark_index(pair)
        xy[[i, j]] = xy[[j, i]]
        sd[[i, j]] = sd[[j, i]]
    return replace(dataset, landmark_xy=xy, landmark_std=sd)


def bearing_residuals(dataset: MRCLAMDataset, robot, *, min_landmarks: int = 4,
                      max_residual: float = 0.3) -> np.ndarray:
    """Measured minus predicted bearings (radians) at the landmark fixes of views with at least
    ``min_landmarks`` landmarks (rms residual at most ``max_residual`` m).

    The fit uses the same measurements (3 pose parameters from 2n numbers), so the spread of
    these residuals underestimates the bearing noise by about ``sqrt((2n - 3) / 2n)``.
    """
    rd = dataset.robot(robot)
    f = landmark_fixes(dataset, robot, min_landmarks=min_landmarks)
    ok = f.residual <= max_residual
    v = f.view_index[ok]
    pred = bearing(f.poses[ok][:, None, :], dataset.landmark_xy[None, :, :])
    return wrap_angle(rd.view_bearings[v] - pred)[rd.visible[v]]


def odometry_check(dataset: MRCLAMDataset, robot, *, bins=((0.5, 3.0), (3.0, 10.0), (10.0, 30.0),
                                                           (30.0, 100.0)),
                   max_residual: float = 0.1, min_landmarks: int = 3,
                   odometry_lead: float = DEFAULT_ODOMETRY_LEAD) -> list[dict]:
    """How far the odometry's turn drifts from the landmark fixes' turn, by time between fixes.

    The odometry is read at ``fix time - odometry_lead`` (as the histories read it).

    For every pair of good fixes (rms residual at most ``max_residual`` m) whose time difference
    falls in a bin ``(lo, hi]`` seconds, the error is ``wrap((theta_j - theta_i)_fixes -
    (theta_j - theta_i)_odometry)``. Returns one row per bin: ``lo, hi, n`` and the median and
    90th percentile of the absolute error in degrees (NaN-free: bins without pairs have n = 0 and
    zeros). Empty for a robot without odometry.
    """
    rd = dataset.robot(robot)
    if rd.odometry is None:
        return []
    f = landmark_fixes(dataset, robot, min_landmarks=min_landmarks)
    o = rd.odometry
    q = f.times - odometry_lead
    good = (f.residual <= max_residual) & (q >= o.time[0]) & (q <= o.time[-1])
    ft, fth = f.times[good], f.poses[good, 2]
    oth = o.poses(q[good])[:, 2]
    dt = ft[None, :] - ft[:, None]
    rows = []
    for lo, hi in bins:
        i, j = np.nonzero((dt > lo) & (dt <= hi))
        err = np.degrees(np.abs(wrap_angle((fth[j] - fth[i]) - (oth[j] - oth[i]))))
        rows.append({"lo": float(lo), "hi": float(hi), "n": int(i.size),
                     "median_abs_deg": float(np.median(err)) if i.size else 0.0,
                     "p90_abs_deg": float(np.percentile(err, 90)) if i.size else 0.0})
    return rows


def anchored_dead_reckoning(dataset: MRCLAMDataset, robot, times=None, *, anchor_time=None,
                            max_residual: float = 0.15, min_landmarks: int = 3):
    """Dead-reckoned world poses (n, 3) of a robot at ``times`` (default: its odometry records).

    Robot ground truth being absent, the odometry path is placed in the world by the rigid
    transform that makes it pass through one landmark fix (at least ``min_landmarks`` landmarks,
    rms residual at most ``max_residual`` m) with the fix's heading: the first such fix, or the
    one nearest to ``anchor_time``. Drift then shows as the distance to other fixes. Returns
    ``(poses, anchor_time)``; ValueError if the robot has no odometry or no such fix.
    """
    rd = dataset.robot(robot)
    if rd.odometry is None:
        raise ValueError(f"robot: robot {rd.robot} of {dataset.name} has no odometry")
    f = landmark_fixes(dataset, robot, min_landmarks=min_landmarks)
    o = rd.odometry
    good = np.flatnonzero((f.residual <= max_residual) & (f.times >= o.time[0]) & (f.times <= o.time[-1]))
    if good.size == 0:
        raise ValueError(f"robot: robot {rd.robot} has no landmark fix with >= {min_landmarks} "
                         f"landmarks and residual <= {max_residual} m")
    k = good[0] if anchor_time is None else good[np.argmin(np.abs(f.times[good] - anchor_time))]
    times = o.time if times is None else as_float_array("times", times, ndim=1)
    D = o.poses(np.concatenate([[f.times[k]], times]))
    phi = f.poses[k, 2] - D[0, 2]
    c, s = np.cos(phi), np.sin(phi)
    rel = D[1:, :2] - D[0, :2]
    xy = f.poses[k, :2] + np.column_stack([c * rel[:, 0] - s * rel[:, 1], s * rel[:, 0] + c * rel[:, 1]])
    return np.column_stack([xy, wrap_angle(D[1:, 2] + phi)]), float(f.times[k])


