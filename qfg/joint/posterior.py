"""What :func:`qfg.joint.solve` answers: a :class:`JointPosterior` over the landmark positions
(and the poses), a mixture of Gaussian :class:`Mode` s with its flags and the fit it came from.

The posterior is read by :mod:`qfg.joint.sampling` (joint samples), :mod:`qfg.joint.states`
(qualitative states) and :mod:`qfg.joint.moments` (gauge-free moments and calibration checks).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Mode", "JointPosterior"]


@dataclass(frozen=True, eq=False)
class Mode:
    """One Gaussian of the landmark posterior: ``weight``, ``points`` (L, 2) (NaN rows for
    landmarks not in the solve), ``covariance`` over the constrained landmarks' coordinates
    (2 n_c square, landmark-major), ``cost`` (robust cost of the fit)."""

    weight: float
    points: np.ndarray
    covariance: np.ndarray
    cost: float


@dataclass(frozen=True, eq=False)
class JointPosterior:
    """A joint posterior over landmark positions (and poses) from :func:`solve`.

    Attributes:
        landmark_ids: (L,) tuple, the map's landmarks in order.
        modes: tuple of :class:`Mode` (best first), weights summing to 1.
        constrained: (L,) bool, landmarks in the metric solve.
        landmark_flags: (L,) tuple of ``"ok"``, ``"weak"`` (few rays: sampled from its exact
            conditional), ``"inconsistent"`` (residual check failed), ``"unconstrained"``.
        robot_flags: dict robot -> ``"ok"``, ``"kinematic"`` (no odometry: solved with the
            kinematic motion prior in its place), ``"no_odometry"`` (left out:
            ``without_odometry="skip"``), ``"unverified"`` (no odometry and its map agrees
            with no other robot's: left out), ``"local_minimum"`` (dropped), ``"unaligned"``
            (fewer than 2 landmarks shared with the others: dropped).
        flags: overall flags (``"local_minimum"``, ``"second_mode"``, ``"no_odometry"``,
            ``"kinematic_prior"`` (some run solved without odometry), ``"unverified"``,
            ``"indeterminate"``, ``"inconsistent_landmark"``, ``"unconstrained_landmark"``,
            ``"overdispersed"`` (the robots' own maps scatter about the joint map beyond its
            covariance: :func:`overdispersion`)).
        method: ``"joint"`` (metric posterior) or ``"none"`` (nothing could be solved, e.g. a
            lone robot without odometry; every triplet is the prior).
        poses: dict robot -> (P, 3) poses of that run in the map frame (best mode; NaN rows for
            robots not solved).
        info: extras (``cost``, ``n_bearings``, ``n_poses``, ``time_s``, ``starts``;
            ``robot_maps``: robot -> (L, 2) its landmarks as placed by its own start, in its
            own frame, NaN where not placed; ``kinematic_starts``: robot -> the batch size
            whose start was kept and every size's cost, for runs without odometry).
    """

    landmark_ids: tuple
    modes: tuple
    constrained: np.ndarray
    landmark_flags: tuple
    robot_flags: dict
    flags: tuple
    method: str
    poses: dict
    info: dict = field(default_factory=dict)
    _problem: object = None
    _fit: object = None
    _pose_offset: dict = None
    _weak: dict = None

    @property
    def points(self) -> np.ndarray:
        """(L, 2) landmark positions of the best mode (NaN where unconstrained)."""
        return self.modes[0].points if self.modes else np.full((len(self.landmark_ids), 2), np.nan)

    def index(self, ids) -> np.ndarray:
        """Positions of landmark ids in :attr:`landmark_ids` (KeyError naming an unknown id)."""
        pos = {l: i for i, l in enumerate(self.landmark_ids)}
        try:
            return np.array([pos[int(x)] for x in np.ravel(ids)], dtype=np.intp)
        except KeyError as exc:
            raise KeyError(f"landmark: {exc.args[0]} is not in this map") from None

