"""Each robot's camera bearing calibration, measured against motion capture and applied to every
dataset (the same five robots record them all).

Against motion capture (dataset 6) a robot's bearing error is not only noise: robot 4's rises by
about 1.4 deg across its image and sits 0.8 deg off (docs/mrclam.md, "Measured noise"), an error
every image of the robot shares, so the passes of a triplet share it too and no check over
passes can see it. The model per robot,

    measured = bias + (1 + scale) phi + noise,

``phi`` the bearing from the captured pose, is fitted by least squares to the rows within
:data:`GROSS` of the truth (the gross misreads left out), and undone by
``phi = (measured - bias) / (1 + scale)``. The bias matters beyond the bearings: the odometry's
direction of travel is relative to the robot's forward axis, the bearings to the camera's, and a
solver takes both in one frame. The captured heading is neither: it sits 0.2-0.9 deg off the
direction the robot drives straight along (the markers' placement), so the bias is taken relative
to the forward axis: the fitted intercept plus the median of (direction of travel - captured
heading) over 1-s windows of straight driving. (A forward camera offset, which would also bend the
error across the image, is not what robot 4 shows: its slope is the same at 1.5-2.5, 2.5-3.5 and
3.5-9 m, where an offset's would fall with the range.)
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..._validate import as_float_array
from ...geometry import bearing, wrap_angle
from ._data import MRCLAMDataset

#: Rows further than this from the captured bearing are left out of the fit (gross errors).
GROSS = float(np.deg2rad(3.0))

#: Capture time minus measurement stamp (s) of the bearings: dataset 6's, ``measure_noise``.
CAPTURE_OFFSET = -0.04

#: ``{robot: (bias [rad], scale)}`` measured on dataset 6 by :func:`measure_bearing_calibration`
#: (``python -m qfg.datasets.mrclam --calibration DATASET6``; 1,504-4,336 rows per robot), the
#: bias relative to the forward axis: robot 4 -0.81 deg and +3.9 % (its error across the image),
#: robot 1 +0.38 deg and -2.3 % (its image's edges bend down), robots 2, 3, 5 -0.57, +0.08,
#: -0.97 deg and within 0.5 %.
DEFAULT_BEARING_CALIBRATION = {
    1: (float(np.deg2rad(0.378)), -0.0230),
    2: (float(np.deg2rad(-0.572)), 0.0029),
    3: (float(np.deg2rad(0.083)), -0.0043),
    4: (float(np.deg2rad(-0.809)), 0.0390),
    5: (float(np.deg2rad(-0.974)), -0.0004),
}


def measure_bearing_calibration(dataset: MRCLAMDataset, *, offset: float = CAPTURE_OFFSET,
                                min_rows: int = 200) -> dict:
    """``{robot: (bias [rad], scale, rows)}`` of every robot with motion capture: the least
    squares fit of ``measured - phi = bias + scale phi`` over its landmark rows within
    :data:`GROSS` of the captured bearing ``phi`` (module docstring); robots with fewer than
    ``min_rows`` such rows are left out. ValueError naming the dataset when none has capture."""
    off = float(as_float_array("offset", offset, ndim=0))
    if not any(rd.groundtruth is not None for rd in dataset.robots.values()):
        raise ValueError(f"dataset: {dataset.name} has no robot ground truth (RobotN_Groundtruth)")
    out = {}
    for n, rd in sorted(dataset.robots.items()):
        if rd.groundtruth is None:
            continue
        v, col = np.nonzero(rd.visible)
        P, ok = rd.groundtruth_poses(rd.view_times[v] + off)
        phi = bearing(P, dataset.landmark_xy[col])
        e = wrap_angle(rd.view_bearings[v, col] - phi)
        use = ok & (np.abs(e) < GROSS)
        if use.sum() < min_rows:
            continue
        X = np.c_[np.ones(use.sum()), phi[use]]
        bias, scale = np.linalg.lstsq(X, e[use], rcond=None)[0]
        out[int(n)] = (float(bias + forward_axis(rd.groundtruth)), float(scale), int(use.sum()))
    return out


def forward_axis(groundtruth, window: float = 1.0, max_turn: float = float(np.deg2rad(2.0)),
                 min_travel: float = 0.05) -> float:
    """The robot's forward axis relative to its captured heading (rad): the median of (direction
    of travel - captured heading) over ``window``-second windows, every half window, in which the
    robot turned less than ``max_turn`` and moved at least ``min_travel`` m (0 when there are
    fewer than 20 such windows). ``groundtruth`` (g, 4): time, x, y, heading rows."""
    g = as_float_array("groundtruth", groundtruth, ndim=2, last_dim=4)
    t = g[:, 0]
    if t.size < 2 or t[-1] - t[0] <= window:
        return 0.0
    T = np.arange(t[0], t[-1] - window, window / 2)
    a = np.unwrap(g[:, 3])
    dx = np.interp(T + window, t, g[:, 1]) - np.interp(T, t, g[:, 1])
    dy = np.interp(T + window, t, g[:, 2]) - np.interp(T, t, g[:, 2])
    da = np.interp(T + window, t, a) - np.interp(T, t, a)
    ok = (np.hypot(dx, dy) >= min_travel) & (np.abs(da) < max_turn)
    if ok.sum() < 20:
        return 0.0
    mid = np.interp(T + window / 2, t, a)
    return float(np.median(wrap_angle(np.arctan2(dy, dx) - mid)[ok]))


def calibrate_bearings(dataset: MRCLAMDataset, calibration) -> MRCLAMDataset:
    """A copy of ``dataset`` with each robot's bearings (its measurement rows and its views)
    corrected by ``calibration`` ``{robot: (bias, scale, ...)}``: ``(measured - bias) / (1 +
    scale)``, wrapped. Robots not in ``calibration`` are left as they are.

    Measured on dataset 6 and applied to datasets 1-5: :data:`DEFAULT_BEARING_CALIBRATION`.
    """
    robots = dict(dataset.robots)
    for n, c in dict(calibration).items():
        if n not in robots:
            continue
        bias, scale = float(c[0]), float(c[1])
        if not (np.isfinite(bias) and np.isfinite(scale) and abs(scale) < 0.5
                and abs(bias) < 0.2):
            raise ValueError(f"calibration: robot {n}: expected a bias under 0.2 rad and a "
                             f"scale under 0.5 in size, got {c!r}")
        rd = robots[n]
        vb = np.where(rd.visible, wrap_angle((rd.view_bearings - bias) / (1.0 + scale)),
                      rd.view_bearings)
        robots[n] = replace(rd, bearing=wrap_angle((rd.bearing - bias) / (1.0 + scale)),
                            view_bearings=vb)
    return replace(dataset, robots=robots)
