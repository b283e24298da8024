"""Scenario simulator: landmarks, camera trajectories, noisy bearings and motion headings.

Defaults follow the paper (section 6a): positions uniform in x in [-3, 3], y in [-3, 4]; at least
0.01 between any two objects (landmarks and camera positions); headings uniform; each pose
observes three landmarks. Everything is drawn from a ``numpy.random.Generator``, so the same seed
gives the same scenario.

Data flows one way: this module makes scenarios and measurements; solvers consume
:class:`TripletHistory` objects and never reach back here.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from . import partitions as _partitions
from ._validate import as_float_array, as_rng, non_negative, per_step_sigma, positive_int
from .geometry import bearing, motion_heading, poses_to_frame, to_frame, wrap_angle

__all__ = [
    "SimulationConfig",
    "TripletTruth",
    "TripletHistory",
    "Scenario",
    "sample_positions",
    "random_triplet_history",
    "random_scenario",
    "triplet_histories",
]


@dataclass(frozen=True)
class SimulationConfig:
    """Where objects are placed. Lengths in world units (the paper's are dimensionless).

    Attributes:
        xlim, ylim: sampling box for landmarks and camera positions.
        min_distance: least distance between any two objects (landmarks or camera positions).
        max_tries: rejection rounds before giving up with a ValueError.
    """

    xlim: tuple[float, float] = (-3.0, 3.0)
    ylim: tuple[float, float] = (-3.0, 4.0)
    min_distance: float = 0.01
    max_tries: int = 1000

    def __post_init__(self):
        for nm, lim in (("xlim", self.xlim), ("ylim", self.ylim)):
            if len(lim) != 2 or not (np.isfinite(lim).all() and lim[0] < lim[1]):
                raise ValueError(f"{nm}: expected (low, high) with low < high, got {lim!r}")
        non_negative("min_distance", self.min_distance)


def sample_positions(seed, n: int, config: SimulationConfig = SimulationConfig()) -> np.ndarray:
    """``n`` points (n, 2) uniform in the config's box, pairwise at least ``min_distance`` apart.

    Rejection in whole batches: every point closer than ``min_distance`` to an earlier one is drawn
    again, until none is.
    """
    n = positive_int("n", n)
    rng = as_rng(seed)
    lo = np.array([config.xlim[0], config.ylim[0]])
    hi = np.array([config.xlim[1], config.ylim[1]])
    pts = rng.uniform(lo, hi, size=(n, 2))
    d2min = config.min_distance ** 2
    for _ in range(config.max_tries):
        diff = pts[:, None, :] - pts[None, :, :]
        close = np.tril(np.sum(diff * diff, axis=-1) < d2min, k=-1)
        bad = close.any(axis=1)
        if not bad.any():
            return pts
        pts[bad] = rng.uniform(lo, hi, size=(int(bad.sum()), 2))
    raise ValueError(f"config: could not place {n} objects {config.min_distance} apart in "
                     f"{config.xlim} x {config.ylim} after {config.max_tries} rounds")


@dataclass(frozen=True)
class TripletTruth:
    """Ground truth of a simulated triplet history.

    Attributes:
        landmarks_world: (3, 2) A, B, C in the world.
        poses_world: (n, 3) camera poses in the world, or None when they are unknown (real data
            without robot ground truth, e.g. ``qfg.datasets.mrclam``).
        C_ab: (2,) C in the AB frame.
        poses_ab: (n, 3) camera poses in the AB frame, or None with ``poses_world``.
        partition: name of the partition the states refer to.
        state: 0-based state of C in the AB frame.
        camera_states: (n,) 0-based states of the camera positions in the AB frame, or None with
            ``poses_world``.
    """

    landmarks_world: np.ndarray
    poses_world: np.ndarray
    C_ab: np.ndarray
    poses_ab: np.ndarray
    partition: str
    state: int
    camera_states: np.ndarray


@dataclass(frozen=True)
class TripletHistory:
    """Measurements of one ordered landmark triplet AB:C.

    Attributes:
        landmarks: (A, B, C) landmark ids.
        bearings: (n, 3) radians, [phi_A, phi_B, phi_C] per view, in time order.
        headings: (n - 1,) radians, direction of travel from view i to view i+1 relative to the
            heading at view i (conventions.md).
        sigma_bearing: bearing noise standard deviation (radians) the data was made with, or the
            value the solver should assume.
        sigma_heading: heading noise standard deviation (radians), likewise: one number, or
            (n - 1,) one per step (``full`` and ``fast`` take them; e.g. the odometry's heading
            drifts with a step's duration, docs/mrclam.md).
        views: (n,) index or time of each view (pose index in a scenario, time stamp in data).
        truth: ground truth for simulated data, None for real data.
        has_motion: False when headings are not available (the solver then has no motion model).
        distances: (n - 1,) travelled distance from view i to view i+1 by odometry (any unit:
            only ratios of consecutive entries are used; 0 = unknown, no factor), or None.
        sigma_distance_ratio: noise of log(d_i / d_(i-1)) the data was made with, or the value
            the solver should assume; None when there are no distances.
    """

    landmarks: tuple
    bearings: np.ndarray
    headings: np.ndarray
    sigma_bearing: float
    sigma_heading: float | np.ndarray
    views: np.ndarray = field(default=None)
    truth: TripletTruth | None = None
    has_motion: bool = True
    distances: np.ndarray | None = None
    sigma_distance_ratio: float | None = None

    def __post_init__(self):
        b = as_float_array("bearings", self.bearings, ndim=2, last_dim=3)
        if b.shape[0] < 1:
            raise ValueError("bearings: expected at least one view, got 0 rows")
        h = as_float_array("headings", self.headings, ndim=1)
        if h.shape[0] != b.shape[0] - 1:
            raise ValueError(f"headings: expected {b.shape[0] - 1} values for {b.shape[0]} views, "
                             f"got {h.shape[0]}")
        if len(self.landmarks) != 3:
            raise ValueError(f"landmarks: expected 3 ids (A, B, C), got {self.landmarks!r}")
        non_negative("sigma_bearing", self.sigma_bearing)
        per_step_sigma("sigma_heading", self.sigma_heading, b.shape[0] - 1)
        views = np.arange(b.shape[0]) if self.views is None else np.asarray(self.views)
        if views.shape != (b.shape[0],):
            raise ValueError(f"views: expected shape ({b.shape[0]},), got {views.shape}")
        if self.distances is not None:
            d = as_float_array("distances", self.distances, ndim=1)
            if d.shape[0] != b.shape[0] - 1:
                raise ValueError(f"distances: expected {b.shape[0] - 1} values for {b.shape[0]} "
                                 f"views, got {d.shape[0]}")
            if np.any(d < 0):
                raise ValueError(f"distances: expected values >= 0, got {d.min()!r}")
            object.__setattr__(self, "distances", d)
        if self.sigma_distance_ratio is not None:
            non_negative("sigma_distance_ratio", self.sigma_distance_ratio)
        object.__setattr__(self, "bearings", b)
        object.__setattr__(self, "headings", h)
        object.__setattr__(self, "views", views)
        object.__setattr__(self, "landmarks", tuple(self.landmarks))

    @property
    def n_views(self) -> int:
        return self.bearings.shape[0]


def _make_truth(landmarks_world, poses_world, partition) -> TripletTruth:
    A, B, C = landmarks_world
    part = _partitions.get(partition)
    c_ab = to_frame(C, A, B)
    poses_ab = poses_to_frame(poses_world, A, B)
    return TripletTruth(landmarks_world=landmarks_world, poses_world=poses_world, C_ab=c_ab,
                        poses_ab=poses_ab, partition=part.name, state=int(part.state_of(c_ab)),
                        camera_states=part.state_of(poses_ab[:, :2]))


def random_triplet_history(seed, n_views: int = 3, sigma_bearing: float = 0.0,
                           sigma_heading: float = 0.0, *, config: SimulationConfig = SimulationConfig(),
                           partition="edc", landmarks=(0, 1, 2),
                           sigma_distance_ratio: float | None = None) -> TripletHistory:
    """One landmark triplet seen from ``n_views`` random poses (the single-triplet study).

    Landmarks and camera positions are uniform in the config's box and at least ``min_distance``
    apart; headings uniform. Bearings get N(0, sigma_bearing^2) noise and the headings between
    consecutive views N(0, sigma_heading^2) noise (radians). With ``sigma_distance_ratio`` (not
    None) the history also carries odometry distances: the true step lengths times
    exp(N(0, sigma_distance_ratio^2 / 2)), so that the log ratio of consecutive distances has
    noise ``sigma_distance_ratio`` (what the field means to the solvers), drawn after everything
    else (the other values are those drawn without it).

    >>> h = random_triplet_history(np.random.default_rng(0), n_views=3)
    >>> h.bearings.shape, h.headings.shape, 0 <= h.truth.state < 20
    ((3, 3), (2,), True)
    """
    rng = as_rng(seed)
    n_views = positive_int("n_views", n_views)
    sb = non_negative("sigma_bearing", sigma_bearing)
    sh = non_negative("sigma_heading", sigma_heading)
    pts = sample_positions(rng, 3 + n_views, config)
    L = pts[:3]
    alpha = rng.uniform(-np.pi, np.pi, size=n_views)
    poses = np.column_stack([pts[3:], alpha])
    phi = bearing(poses[:, None, :], L[None, :, :])
    phi = wrap_angle(phi + rng.normal(0.0, 1.0, size=phi.shape) * sb)
    psi = motion_heading(poses[:-1], poses[1:, :2])
    psi = wrap_angle(psi + rng.normal(0.0, 1.0, size=psi.shape) * sh)
    dist = sd = None
    if sigma_distance_ratio is not None:
        sd = non_negative("sigma_distance_ratio", sigma_distance_ratio)
        step = np.hypot(*np.diff(poses[:, :2], axis=0).T)
        dist = step * np.exp(rng.normal(0.0, 1.0, size=step.shape) * (sd / np.sqrt(2.0)))
    return TripletHistory(landmarks=tuple(landmarks), bearings=phi, headings=psi,
                          sigma_bearing=sb, sigma_heading=sh, views=np.arange(n_views),
                          truth=_make_truth(L, poses, partition), distances=dist,
                          sigma_distance_ratio=sd)


@dataclass(frozen=True)
class Scenario:
    """A simulated trajectory among landmarks.

    Attributes:
        landmarks: (L, 2) world positions; landmark id = row index.
        poses: (P, 3) camera poses in time order.
        visible: (P, L) bool, which landmarks each pose observes.
        bearings: (P, L) measured bearings (radians); 0.0 where not visible (check ``visible``).
        heading_noise: (P, P) noise (radians) added to the motion heading measured from pose i to
            pose j; drawn once so that triplet extraction is deterministic.
        sigma_bearing, sigma_heading: noise standard deviations (radians).
    """

    landmarks: np.ndarray
    poses: np.ndarray
    visible: np.ndarray
    bearings: np.ndarray
    heading_noise: np.ndarray
    sigma_bearing: float
    sigma_heading: float

    @property
    def n_landmarks(self) -> int:
        return self.landmarks.shape[0]

    @property
    def n_poses(self) -> int:
        return self.poses.shape[0]

    def measured_heading(self, i, j):
        """Measured direction of travel from pose(s) i to pose(s) j, relative to heading at i."""
        i, j = np.asarray(i), np.asarray(j)
        true = motion_heading(self.poses[i], self.poses[j, :2])
        return wrap_angle(true + self.heading_noise[i, j])


def random_scenario(seed, n_landmarks: int, n_poses: int, landmarks_per_view: int = 3, *,
                    sigma_bearing: float = 0.0, sigma_heading: float = 0.0,
                    config: SimulationConfig = SimulationConfig()) -> Scenario:
    """A trajectory of ``n_poses`` uniform random poses, each observing ``landmarks_per_view``
    landmarks chosen at random among ``n_landmarks`` uniform random landmarks.

    >>> s = random_scenario(np.random.default_rng(1), n_landmarks=5, n_poses=8)
    >>> s.visible.sum(axis=1).tolist()
    [3, 3, 3, 3, 3, 3, 3, 3]
    """
    rng = as_rng(seed)
    n_landmarks = positive_int("n_landmarks", n_landmarks, minimum=3)
    n_poses = positive_int("n_poses", n_poses)
    k = positive_int("landmarks_per_view", landmarks_per_view)
    if k > n_landmarks:
        raise ValueError(f"landmarks_per_view: {k} is more than n_landmarks = {n_landmarks}")
    sb = non_negative("sigma_bearing", sigma_bearing)
    sh = non_negative("sigma_heading", sigma_heading)
    pts = sample_positions(rng, n_landmarks + n_poses, config)
    L = pts[:n_landmarks]
    poses = np.column_stack([pts[n_landmarks:], rng.uniform(-np.pi, np.pi, size=n_poses)])
    # k distinct landmarks per pose: the k smallest of independent uniform keys
    keys = rng.random((n_poses, n_landmarks))
    chosen = np.argsort(keys, axis=1)[:, :k]
    visible = np.zeros((n_poses, n_landmarks), dtype=bool)
    np.put_along_axis(visible, chosen, True, axis=1)
    phi = bearing(poses[:, None, :], L[None, :, :])
    phi = wrap_angle(phi + rng.normal(0.0, 1.0, size=phi.shape) * sb)
    phi = np.where(visible, phi, 0.0)
    noise = rng.normal(0.0, 1.0, size=(n_poses, n_poses)) * sh
    return Scenario(landmarks=L, poses=poses, visible=visible, bearings=phi, heading_noise=noise,
                    sigma_bearing=sb, sigma_heading=sh)


def triplet_histories(scenario: Scenario, *, min_views: int = 1, partition="edc"
                      ) -> list[TripletHistory]:
    """Every ordered triplet AB:C whose landmarks were seen together in at least ``min_views``
    poses, with its views in time order and the measured headings between consecutive views of
    that triplet. Sorted by (A, B, C).
    """
    min_views = positive_int("min_views", min_views)
    vis = scenario.visible
    counts = vis.sum(axis=1)
    out = []
    seen_sets: dict[tuple, list] = {}
    for p in np.flatnonzero(counts >= 3):
        ids = np.flatnonzero(vis[p])
        for trip in itertools.combinations(ids.tolist(), 3):
            seen_sets.setdefault(trip, []).append(p)
    for trip in sorted(seen_sets):
        poses_idx = np.asarray(seen_sets[trip])
        if poses_idx.size < min_views:
            continue
        for perm in itertools.permutations(trip):
            idx = list(perm)
            phi = scenario.bearings[np.ix_(poses_idx, idx)]
            psi = scenario.measured_heading(poses_idx[:-1], poses_idx[1:])
            truth = _make_truth(scenario.landmarks[idx], scenario.poses[poses_idx], partition)
            out.append(TripletHistory(landmarks=tuple(perm), bearings=phi, headings=psi,
                                      sigma_bearing=scenario.sigma_bearing,
                                      sigma_heading=scenario.sigma_heading, views=poses_idx,
                                      truth=truth))
    out.sort(key=lambda h: h.landmarks)
    return out


# ----------------------------------------------------------------------------- trajectory runs
__all__ += ["TrajectoryRun", "random_trajectory_run"]


@dataclass(frozen=True, eq=False)
class TrajectoryRun:
    """One robot driving a trajectory among many landmarks, seeing several per image.

    Attributes:
        landmarks: (L, 2) world positions; landmark id = row index.
        poses: (P, 3) true camera poses (the camera looks along the robot's heading).
        visible: (P, L) bool, landmarks in each image (inside the field of view and range).
        bearings: (P, L) measured bearings (radians, N(0, sigma_bearing^2) noise); 0 where not
            visible.
        odometry: (P - 1, 3) measured relative poses ``X_i^{-1} X_{i+1}``: direction of travel
            with N(0, sigma_heading^2) noise, length times exp(N(0, sigma_step^2)), turn with
            N(0, sigma_turn^2) noise.
        odometry_sigma: (P - 1, 3) the diagonal standard deviations of (dx, dy, dtheta) that
            noise implies to first order (the (dx, dy) correlation is left out).
        sigma_bearing, sigma_heading, sigma_step, sigma_turn: the noise levels (radians, and a
            log-length ratio for ``sigma_step``).
    """

    landmarks: np.ndarray
    poses: np.ndarray
    visible: np.ndarray
    bearings: np.ndarray
    odometry: np.ndarray
    odometry_sigma: np.ndarray
    sigma_bearing: float
    sigma_heading: float
    sigma_step: float
    sigma_turn: float

    @property
    def n_landmarks(self) -> int:
        return self.landmarks.shape[0]

    @property
    def n_poses(self) -> int:
        return self.poses.shape[0]


def random_trajectory_run(rng, n_landmarks: int = 8, n_poses: int = 40, *,
                          sigma_bearing: float = float(np.deg2rad(2.0)),
                          sigma_heading: float = float(np.deg2rad(5.0)), sigma_step: float = 0.05,
                          sigma_turn: float = float(np.deg2rad(2.0)), step: float = 0.3,
                          turn_sd: float = float(np.deg2rad(20.0)), fov_deg: float = 120.0,
                          min_visible: int = 0, config: SimulationConfig = SimulationConfig(),
                          landmarks=None) -> TrajectoryRun:
    """A robot driving ``n_poses`` poses among ``n_landmarks`` uniform random landmarks.

    The robot starts at a uniform position with a uniform heading and drives ``step`` per pose,
    turning by N(0, turn_sd^2) and, once it would leave the config's box, towards the box's
    centre. Each image sees the landmarks within ``fov_deg`` / 2 of the heading (360: all);
    ``min_visible`` > 0 redraws the landmarks until every image sees that many (up to
    ``config.max_tries`` times). Noise defaults are the paper's (bearings 2 deg, direction of
    travel 5 deg) plus 5% step length and 2 deg turn for the odometry's other components.
    ``landmarks`` (L, 2) places the landmarks instead of drawing them (several robots in one
    world; ``n_landmarks`` is then ignored).

    >>> r = random_trajectory_run(np.random.default_rng(0), n_landmarks=6, n_poses=10)
    >>> r.poses.shape, r.odometry.shape, r.visible.shape
    ((10, 3), (9, 3), (10, 6))
    """
    rng = as_rng(rng)
    n_landmarks = positive_int("n_landmarks", n_landmarks, minimum=3)
    n_poses = positive_int("n_poses", n_poses, minimum=2)
    sb = non_negative("sigma_bearing", sigma_bearing)
    sh = non_negative("sigma_heading", sigma_heading)
    ss = non_negative("sigma_step", sigma_step)
    st = non_negative("sigma_turn", sigma_turn)
    step = non_negative("step", step)
    if step <= 0:
        raise ValueError("step: expected a length > 0")
    turn_sd = non_negative("turn_sd", turn_sd)
    fov = non_negative("fov_deg", fov_deg)
    if not 0 < fov <= 360:
        raise ValueError(f"fov_deg: expected a field of view in (0, 360], got {fov_deg!r}")
    min_visible = positive_int("min_visible", min_visible, minimum=0)
    if min_visible > n_landmarks:
        raise ValueError(f"min_visible: {min_visible} is more than n_landmarks = {n_landmarks}")
    lo = np.array([config.xlim[0], config.ylim[0]])
    hi = np.array([config.xlim[1], config.ylim[1]])
    centre = (lo + hi) / 2
    poses = np.empty((n_poses, 3))
    poses[0] = (*sample_positions(rng, 1, config)[0], rng.uniform(-np.pi, np.pi))
    for i in range(1, n_poses):
        x, y, th = poses[i - 1]
        th = th + rng.normal(0.0, turn_sd)
        nxt = np.array([x, y]) + step * np.array([np.cos(th), np.sin(th)])
        if np.any(nxt < lo) or np.any(nxt > hi):
            to_c = centre - np.array([x, y])
            th = np.arctan2(to_c[1], to_c[0]) + rng.normal(0.0, turn_sd / 4)
            nxt = np.array([x, y]) + step * np.array([np.cos(th), np.sin(th)])
        poses[i] = (*nxt, wrap_angle(th))
    fixed = None if landmarks is None else as_float_array("landmarks", landmarks, ndim=2,
                                                              last_dim=2)
    if fixed is not None and fixed.shape[0] < 3:
        raise ValueError(f"landmarks: expected at least 3, got {fixed.shape[0]}")
    for _ in range(config.max_tries):
        L = sample_positions(rng, n_landmarks, config) if fixed is None else fixed
        true_phi = bearing(poses[:, None, :], L[None, :, :])
        visible = np.abs(true_phi) <= np.deg2rad(fov) / 2 + 1e-12
        if visible.sum(axis=1).min() >= min_visible:
            break
        if fixed is not None:
            raise ValueError(f"min_visible: the given landmarks leave an image with fewer "
                             f"than {min_visible} in view")
    else:
        raise ValueError(f"min_visible: no landmark draw gave every image {min_visible} landmarks "
                         f"in {config.max_tries} tries")
    phi = wrap_angle(true_phi + rng.normal(0.0, 1.0, size=true_phi.shape) * sb)
    phi = np.where(visible, phi, 0.0)
    a, b = poses[:-1], poses[1:]
    d = np.hypot(*(b[:, :2] - a[:, :2]).T)
    psi = motion_heading(a, b[:, :2]) + rng.normal(0.0, 1.0, size=d.shape) * sh
    dm = d * np.exp(rng.normal(0.0, 1.0, size=d.shape) * ss)
    dth = wrap_angle(b[:, 2] - a[:, 2]) + rng.normal(0.0, 1.0, size=d.shape) * st
    odo = np.column_stack([dm * np.cos(psi), dm * np.sin(psi), dth])
    c, s = np.cos(psi), np.sin(psi)
    sx = np.sqrt((dm * ss * c) ** 2 + (dm * sh * s) ** 2)
    sy = np.sqrt((dm * ss * s) ** 2 + (dm * sh * c) ** 2)
    sig = np.column_stack([np.maximum(sx, 1e-6), np.maximum(sy, 1e-6),
                           np.full(d.shape, max(st, 1e-6))])
    return TrajectoryRun(landmarks=L, poses=poses, visible=visible, bearings=phi, odometry=odo,
                         odometry_sigma=sig, sigma_bearing=sb, sigma_heading=sh, sigma_step=ss,
                         sigma_turn=st)
