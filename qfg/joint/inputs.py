"""The joint map's measurements: one :class:`RobotRun` per robot, gathered in
:class:`JointMeasurements` (frozen dataclasses, validated on construction), and the helpers that
build them: :func:`odometry_steps` (relative poses and their noise from a dead-reckoned chain)
and :func:`simulated_measurements` (from a :class:`qfg.simulation.TrajectoryRun`).

Frames and units: bearings in radians relative to the camera heading; odometry steps
``X_i^{-1} X_{i+1}`` as (dx, dy) in metres in pose i's frame and dtheta in radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import nonlinear as _nl
from .._validate import as_float_array, non_negative

__all__ = ["RobotRun", "JointMeasurements", "odometry_steps", "simulated_measurements",
           "ODOMETRY_NOISE"]

#: Per-step odometry noise model ``sigma = c0 + c_turn |dtheta| + c_dist d`` for (x, y, theta)
#: of the relative pose (m, m, rad); fitted against motion capture on MRCLAM dataset 6 (robust
#: spread of keyframe-to-keyframe errors binned by step length, docs/joint.md).
ODOMETRY_NOISE = {"c0": (0.004, 0.002, 0.010), "c_turn": (0.0, 0.0, 0.10),
                  "c_dist": (0.15, 0.15, 0.30)}


@dataclass(frozen=True, eq=False)
class RobotRun:
    """One robot's measurements.

    Attributes:
        robot: its number (any int, unique within a :class:`JointMeasurements`).
        times: (P,) increasing time stamps of its poses (one per image kept).
        bearing_pose: (B,) index into ``times`` of each bearing's image.
        bearing_landmark: (B,) landmark id of each bearing.
        bearing: (B,) measured bearings (radians, relative to the camera heading).
        sigma_bearing: bearing noise (radians).
        odometry: (P - 1, 3) relative pose ``X_i^{-1} X_{i+1}`` (dx, dy in pose i's frame,
            dtheta) by odometry, or None without odometry.
        odometry_sigma: (P - 1, 3) its per-step noise (standard deviations), or None.
    """

    robot: int
    times: np.ndarray
    bearing_pose: np.ndarray
    bearing_landmark: np.ndarray
    bearing: np.ndarray
    sigma_bearing: float
    odometry: np.ndarray | None = None
    odometry_sigma: np.ndarray | None = None

    def __post_init__(self):
        t = as_float_array("times", self.times, ndim=1)
        if t.size < 1:
            raise ValueError("times: expected at least one pose")
        if np.any(np.diff(t) < 0):
            raise ValueError("times: expected increasing time stamps")
        bp = _nl._ints("bearing_pose", self.bearing_pose, upper=t.size)
        bl = _nl._ints("bearing_landmark", self.bearing_landmark, n=bp.size)
        b = as_float_array("bearing", self.bearing, ndim=1)
        if b.size != bp.size:
            raise ValueError(f"bearing: expected {bp.size} values, got {b.size}")
        sb = non_negative("sigma_bearing", self.sigma_bearing)
        if sb <= 0:
            raise ValueError("sigma_bearing: expected a standard deviation > 0")
        z = s = None
        if self.odometry is not None:
            z = as_float_array("odometry", self.odometry, ndim=2, last_dim=3)
            if z.shape[0] != t.size - 1:
                raise ValueError(f"odometry: expected {t.size - 1} steps for {t.size} poses, "
                                 f"got {z.shape[0]}")
            if self.odometry_sigma is None:
                raise ValueError("odometry_sigma: required with odometry")
            s = np.broadcast_to(as_float_array("odometry_sigma", self.odometry_sigma),
                                z.shape).astype(float)
            if s.size and s.min() <= 0:
                raise ValueError("odometry_sigma: expected standard deviations > 0")
        for k, v in (("times", t), ("bearing_pose", bp), ("bearing_landmark", bl),
                     ("bearing", b), ("sigma_bearing", sb), ("odometry", z),
                     ("odometry_sigma", s), ("robot", int(self.robot))):
            object.__setattr__(self, k, v)

    @property
    def has_odometry(self) -> bool:
        return self.odometry is not None

    @property
    def n_poses(self) -> int:
        return self.times.size


@dataclass(frozen=True, eq=False)
class JointMeasurements:
    """The runs of one or more robots among the same landmarks.

    Attributes:
        runs: tuple of :class:`RobotRun` (distinct robot numbers).
        landmark_ids: the landmarks of the map (default: every id seen, sorted); triplets are
            formed over these.
    """

    runs: tuple
    landmark_ids: tuple = None

    def __post_init__(self):
        runs = tuple(self.runs)
        if not runs or not all(isinstance(r, RobotRun) for r in runs):
            raise ValueError("runs: expected one or more RobotRun")
        nums = [r.robot for r in runs]
        if len(set(nums)) != len(nums):
            raise ValueError(f"runs: robot numbers must be distinct, got {nums}")
        seen = sorted({int(x) for r in runs for x in r.bearing_landmark.tolist()})
        ids = tuple(seen) if self.landmark_ids is None else tuple(int(x) for x in self.landmark_ids)
        if len(set(ids)) != len(ids):
            raise ValueError("landmark_ids: expected distinct ids")
        missing = sorted(set(seen) - set(ids))
        if missing:
            raise ValueError(f"landmark_ids: bearings name landmarks {missing} not in the list")
        if len(ids) < 3:
            raise ValueError(f"landmark_ids: a qualitative map needs at least 3 landmarks, got "
                             f"{len(ids)}")
        object.__setattr__(self, "runs", runs)
        object.__setattr__(self, "landmark_ids", ids)

    def run(self, robot) -> RobotRun:
        for r in self.runs:
            if r.robot == int(robot):
                return r
        raise KeyError(f"robot: {robot} is not in these measurements "
                       f"(has {[r.robot for r in self.runs]})")


def odometry_steps(poses, noise=None, travelled=None):
    """Relative poses ``X_i^{-1} X_{i+1}`` (P - 1, 3) of a dead-reckoned chain ``poses``
    (P, 3) and their noise from the model ``sigma = c0 + c_turn |dtheta| + c_dist d``
    (:data:`ODOMETRY_NOISE` by default). ``d`` and ``|dtheta|`` are the step's length and
    turn or, given ``travelled`` (P - 1, 2), the path length and total turning the robot
    covered between the poses (:func:`qfg.datasets.mrclam.travelled`), whichever
    is larger: the error grows with the path, and a robot that drove away and came back has
    a short step but a long path. Returns ``(steps, sigmas)``.

    >>> z, s = odometry_steps([[0, 0, 0], [1, 0, np.pi / 2]])
    >>> np.round(z, 3).tolist(), np.round(s, 3).tolist()
    ([[1.0, 0.0, 1.571]], [[0.154, 0.152, 0.467]])
    >>> _, s = odometry_steps([[0, 0, 0], [0, 0, 0]], travelled=[[2.0, np.pi]])
    >>> np.round(s, 3).tolist()          # there and back: the path's noise, not the step's
    [[0.304, 0.302, 0.924]]
    """
    P = as_float_array("poses", poses, ndim=2, last_dim=3)
    nm = ODOMETRY_NOISE if noise is None else noise
    z = _nl._relative(P[:-1], P[1:])
    d, turn = np.hypot(z[:, 0], z[:, 1])[:, None], np.abs(z[:, 2:3])
    if travelled is not None:
        tr = as_float_array("travelled", travelled, ndim=2, last_dim=2)
        if tr.shape[0] != z.shape[0] or (tr < 0).any():
            raise ValueError(f"travelled: expected ({z.shape[0]}, 2) non-negative path "
                             f"lengths and turns, one per step, got shape {tr.shape}")
        # the path's integral and the chord agree to rounding on a straight step
        d, turn = np.maximum(tr[:, :1], d), np.maximum(tr[:, 1:], turn)
    s = (np.asarray(nm["c0"], float) + np.asarray(nm["c_turn"], float) * turn
         + np.asarray(nm["c_dist"], float) * d)
    return z, s



def simulated_measurements(run, *, odometry: bool = True, robot: int = 0) -> JointMeasurements:
    """:class:`JointMeasurements` of a :class:`qfg.simulation.TrajectoryRun` (one robot; every
    image a pose; ``odometry=False`` leaves the odometry out). Landmark ids are row indices."""
    vi, col = np.nonzero(run.visible)
    r = RobotRun(robot=robot, times=np.arange(run.n_poses, dtype=float), bearing_pose=vi,
                 bearing_landmark=col, bearing=run.bearings[vi, col],
                 sigma_bearing=max(run.sigma_bearing, 1e-6),
                 odometry=run.odometry if odometry else None,
                 odometry_sigma=run.odometry_sigma if odometry else None)
    return JointMeasurements((r,), tuple(range(run.n_landmarks)))

