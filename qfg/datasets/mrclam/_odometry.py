"""Odometry: the single integrator of MRCLAM's velocity logs."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..._validate import as_float_array
from ...geometry import wrap_angle

if TYPE_CHECKING:  # an annotation only: _data imports this module (RobotData.poses)
    from ._data import RobotData


def _commands(time, v, omega, query_times):
    """The checked velocity log ``(time, v, omega)``, ``query_times`` and, per query, the
    command k in force (command k holds on ``[time[k], time[k+1])``; the last query time
    ``time[-1]`` ends the last interval)."""
    t = as_float_array("time", time, ndim=1)
    v = as_float_array("v", v, ndim=1)
    w = as_float_array("omega", omega, ndim=1)
    if not (t.shape == v.shape == w.shape):
        raise ValueError(f"time, v, omega: expected equal lengths, got {t.shape}, {v.shape}, {w.shape}")
    if t.size < 2:
        raise ValueError(f"time: expected at least 2 records, got {t.size}")
    if np.any(np.diff(t) < 0):
        raise ValueError("time: expected non-decreasing values")
    q = as_float_array("query_times", query_times)
    if q.size and (q.min() < t[0] or q.max() > t[-1]):
        raise ValueError(f"query_times: expected values in [{float(t[0])}, {float(t[-1])}] (the "
                         f"odometry's span), got [{float(q.min())}, {float(q.max())}]")
    return t, v, w, q, np.clip(np.searchsorted(t, q, side="right") - 1, 0, t.size - 2)


def travelled(time, v, omega, query_times) -> np.ndarray:
    """(..., 2) the path length (m) and the total turning (rad) of a velocity log from
    ``time[0]`` to each of ``query_times`` (...), in the log's span: the integrals of ``|v|``
    and ``|omega|``, exact for commands that hold between records (as in
    :func:`integrate_odometry`). Between two poses the difference is what the robot
    travelled, which can far exceed the net displacement (a robot that drives away and back).

    >>> travelled([0.0, 1.0, 2.0], [1.0, -1.0, 0.0], [0.0, 0.5, 0.0], [0.5, 2.0]).tolist()
    [[0.5, 0.0], [2.0, 0.5]]
    """
    t, v, w, q, k = _commands(time, v, omega, query_times)
    rate = np.abs(np.stack([v, w], axis=1))
    cum = np.vstack([np.zeros((1, 2)), np.cumsum(rate[:-1] * np.diff(t)[:, None], axis=0)])
    return cum[k] + rate[k] * (q - t[k])[..., None]


def integrate_odometry(time, v, omega, query_times, *, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Dead-reckoned poses (n, 3) ``(x, y, theta)`` at ``query_times`` (n,) from a velocity log.

    Command k, ``(v[k], omega[k])``, holds on ``[time[k], time[k+1])``; the robot is at ``start``
    at ``time[0]``. Over an interval of length dt with heading theta at its start the motion is the
    exact circular arc: the heading turns by ``d = omega dt`` and the position moves along the chord

        ``v dt * sinc(d / 2) * (cos(theta + d / 2), sin(theta + d / 2))``,  sinc(u) = sin(u) / u,

    which is the straight segment ``v dt`` when omega = 0 (no division by omega anywhere). Headings
    and positions at the records are prefix sums (vectorized); a query inside an interval applies
    the partial arc from the record before it. Headings are wrapped to (-pi, pi].

    ``query_times`` must lie in ``[time[0], time[-1]]``: the last command's duration is unknown.

    >>> integrate_odometry([0, 1, 2], [1, 1, 0], [0, np.pi / 2, 0], [1, 2]).round(6).tolist()
    [[1.0, 0.0, 0.0], [1.63662, 0.63662, 1.570796]]
    """
    t, v, w, q, k = _commands(time, v, omega, query_times)
    s = as_float_array("start", start, ndim=1, last_dim=3)
    dt = np.diff(t)
    dth = w[:-1] * dt
    theta = s[2] + np.concatenate([[0.0], np.cumsum(dth)])  # heading at each record
    chord = v[:-1] * dt * np.sinc(dth / (2 * np.pi))
    mid = theta[:-1] + dth / 2
    x = s[0] + np.concatenate([[0.0], np.cumsum(chord * np.cos(mid))])
    y = s[1] + np.concatenate([[0.0], np.cumsum(chord * np.sin(mid))])
    tau = q - t[k]
    d = w[k] * tau
    c = v[k] * tau * np.sinc(d / (2 * np.pi))
    m = theta[k] + d / 2
    out = np.stack([x[k] + c * np.cos(m), y[k] + c * np.sin(m), wrap_angle(theta[k] + d)], axis=-1)
    return out


def dead_reckon(robot: RobotData, times=None, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Odometry poses (n, 3) of a robot at ``times`` (default: its view times), from ``start``
    at its first odometry record. ValueError when the robot has no odometry."""
    if robot.odometry is None:
        raise ValueError(f"robot: robot {robot.robot} has no odometry")
    times = robot.view_times if times is None else times
    return robot.odometry.poses(times, start=start)

