"""The qualitative map from all the measurements at once: a joint metric posterior over landmarks
and poses on GTSAM's nonlinear factor graph (:mod:`qfg.nonlinear`), turned into qualitative
states by sampling.

Input (:class:`JointMeasurements`): one :class:`RobotRun` per robot, its poses at the times it
took images, the bearings of every landmark seen in each image, and (optionally) the odometry
between consecutive poses with its per-step noise. Output: a :class:`JointPosterior` over the
landmark positions (and the poses), and from samples of it the state distribution of every
ordered landmark triplet (:func:`triplet_marginals`, a labelled
:class:`qfg.inference.results.Marginals` keyed by landmark ids) and of the cameras
(:func:`camera_marginals`).

The method (docs/joint.md has the math and the measurements behind each default):

1. **Per robot, incremental batches.** A robot's poses start from its odometry chain with the
   first pose at the origin; every ``chunk`` poses, landmarks with at least ``min_rays`` rays and
   ``min_parallax_deg`` of parallax (from the current pose estimates) are initialised by
   reweighted ray intersection (:func:`qfg.nonlinear.intersect_rays`), and Levenberg-Marquardt
   refines everything so far (Huber kernel on the bearings); the poses ahead are re-chained from
   the last refined one. No ground truth anywhere.
2. **All robots.** Each robot's map is aligned to the reference robot (the one with most
   landmarks) by a rigid fit on the shared landmarks, then one joint solve with only the
   reference robot's first pose anchored.
3. **Several starts, residual checks.** The joint solve is repeated from starts with every
   landmark's depth halved and doubled (from the poses that see it); a start that ends in a
   different minimum with a cost within ``mode_cost`` of the best becomes a second mode. A
   robot whose whitened bearing residuals have a median above ``residual_limit`` sits in a wrong
   local minimum: it is dropped and the rest re-solved (flag ``local_minimum``). A landmark
   with too few rays is ``unconstrained``; one whose residuals fail the check is
   ``inconsistent``.
4. **Posterior.** The Laplace approximation at each mode (``gtsam.Marginals``: joint landmark
   covariance, scaled by ``inflate``, and by ``inflate_kinematic`` when a run without odometry
   is in the map); modes weighted by ``exp(-cost) sqrt(det Sigma)``. Landmarks
   with few rays (``weak``: fewer than ``sir_rays``) are sampled from their exact conditional
   given the sampled poses (sampling-importance-resampling against the robust bearing
   likelihood), because their depth along the rays is not Gaussian.
5. **States.** Each ordered triplet's EDC state in every sample; triplets touching a flagged or
   unconstrained landmark are mixed toward ``prior_states`` (weight ``widen``; 1 for
   unconstrained), every row toward it with weight ``floor``.

Robots without odometry (MRCLAM dataset 5) are solved with a kinematic motion prior in place
of it, started from the bearings alone at several batch sizes (:mod:`qfg.joint_start`), and
kept only when their maps agree in shape with other robots' (flag ``kinematic``; a lone robot
without odometry cannot be checked and is left out, flag ``unverified``). When nothing can be
solved the posterior has ``method == "none"`` and every triplet is the prior: the
solver-based pipeline must answer (:func:`mrclam_marginals` says which method answered).

>>> import numpy as np
>>> from qfg.simulation import random_trajectory_run
>>> run = random_trajectory_run(np.random.default_rng(0), n_landmarks=5, n_poses=30,
...                             fov_deg=360)
>>> post = solve(simulated_measurements(run), seed=0)
>>> post.method, post.flags
('joint', ())
>>> res = triplet_marginals(post, samples=200, seed=0)
>>> res.probabilities.shape
(60, 20)
"""

from __future__ import annotations

import dataclasses
import itertools
import time as _time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from . import joint_start as _start
from . import nonlinear as _nl
from . import partitions as _partitions
from ._validate import as_float_array, as_rng, non_negative, positive_int
from .geometry import poses_to_frame, to_frame, wrap_angle

if TYPE_CHECKING:
    from .inference.results import Marginals

__all__ = ["RobotRun", "JointMeasurements", "Mode", "JointPosterior", "solve",
           "sample_landmarks", "triplet_marginals", "camera_marginals", "odometry_steps",
           "mrclam_runs", "mrclam_reference", "mrclam_marginals", "MRCLAMJoint",
           "simulated_measurements",
           "reference_samples", "ab_frame_moments", "ab_frame_z2", "landmark_moments",
           "aligned_errors", "overdispersion", "scale_covariance",
           "ODOMETRY_NOISE", "FLOOR", "OUTLIER", "KINEMATIC_INFLATE", "OVERDISPERSED"]

#: Per-step odometry noise model ``sigma = c0 + c_turn |dtheta| + c_dist d`` for (x, y, theta)
#: of the relative pose (m, m, rad); fitted against motion capture on MRCLAM dataset 6 (robust
#: spread of keyframe-to-keyframe errors binned by step length, docs/joint.md).
ODOMETRY_NOISE = {"c0": (0.004, 0.002, 0.010), "c_turn": (0.0, 0.0, 0.10),
                  "c_dist": (0.15, 0.15, 0.30)}
#: Bearings beyond this many sigmas at a fit are gross errors (MRCLAM dataset 6: dropping them
#: takes robots 3 and 5's maps from 15-17 cm to 5-6 cm median error, docs/joint.md).
OUTLIER = 4.0
#: A run with more than this share of its bearings beyond :data:`OUTLIER` disagrees with the
#: map (MRCLAM dataset 6: at most 1.4 % of the bearings are gross errors, docs/mrclam.md).
OUTLIER_SHARE = 0.1
#: Weight of the prior's state distribution mixed into every row (chosen on MRCLAM dataset 6
#: and development simulations: docs/joint.md).
FLOOR = 1e-3
#: Factor on the covariance of a map that holds a run solved with the kinematic prior (no
#: odometry), or ``"auto"``: the robots' own maps' scatter about the joint map
#: (:func:`overdispersion`) when above 1. Such maps' relative landmark positions are more
#: certain than their errors (the truth's C in the AB frame a median squared Mahalanobis
#: distance of 1.5-5.1 from the posterior's even after the widening, against chi-square's
#: 1.39); chosen on MRCLAM datasets 1-3 with their odometry withheld, reported on 5 and 6
#: (docs/joint.md, "Without odometry").
KINEMATIC_INFLATE = "auto"


# ----------------------------------------------------------------------------- inputs
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


# ----------------------------------------------------------------------------- results
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


# ----------------------------------------------------------------------------- solve
def _apply(sc, R, t, poses=None, points=None):
    """Poses and points moved by the similarity ``x -> sc R x + t`` (headings turned by R)."""
    out = []
    if poses is not None:
        xy = _start.apply_similarity(poses[:, :2], (sc, R, t))
        out.append(np.column_stack([xy, wrap_angle(poses[:, 2] + np.arctan2(R[1, 0], R[0, 0]))]))
    if points is not None:
        out.append(_start.apply_similarity(points, (sc, R, t)))
    return out


def _robot_checks(pr, fit, offs, runs, outlier):
    """Per run of a fit: (median |whitened bearing residual|, share of bearings beyond
    ``outlier``), over every bearing of ``pr`` (the problem before outliers were dropped, so
    that dropping cannot hide a run that disagrees with the map)."""
    rb, _ = _nl.residuals(pr, fit.poses, fit.points)
    rb = np.abs(rb)
    out = {}
    for r in runs:
        m = (pr.bearing_pose >= offs[r.robot]) & (pr.bearing_pose < offs[r.robot] + r.n_poses)
        out[r.robot] = ((float(np.median(rb[m])), float(np.mean(rb[m] > outlier)))
                        if m.any() else (0.0, 0.0))
    return out


def _failed(check, residual_limit, outlier) -> bool:
    med, frac = check
    return med > residual_limit or (outlier > 0 and frac > OUTLIER_SHARE)


def solve(measurements: JointMeasurements, *, chunk: int = 100, min_rays: int = 3,
          min_parallax_deg: float = 10.0, starts: int = 3, robust: float = _nl.HUBER_K,
          residual_limit: float = 2.0, landmark_limit: float = 3.0, mode_cost: float = 10.0,
          inflate: float = 1.0, sir_rays: int = 20, max_iterations: int = 100,
          outlier: float = OUTLIER, without_odometry: str = "kinematic",
          inflate_kinematic: float | str = KINEMATIC_INFLATE,
          kinematic: _start.KinematicPrior = _start.KINEMATIC,
          kinematic_chunks=(25, 50, 100), agree: float | None = _start.AGREE,
          too_close: float = _start.TOO_CLOSE, seed=0, progress=None) -> JointPosterior:
    """The joint posterior of :class:`JointMeasurements` (module docstring, steps 1-4).

    Args:
        chunk: poses per incremental batch of a run.
        min_rays, min_parallax_deg: a landmark is initialised once it has this many rays with
            this much parallax (largest angle between two of its rays, modulo 180 degrees).
        starts: joint solves (1: the incremental start only; 2 adds every landmark's depth
            halved, 3 also doubled).
        robust: Huber threshold on the bearings (sigmas; 0 for plain least squares).
        outlier: bearings with a whitened residual above it are left out and the fit redone,
            at the end of each run's batches and after the joint solve (0: keep all).
        residual_limit: a robot whose median |whitened bearing residual| exceeds it, or with
            more than :data:`OUTLIER_SHARE` of its bearings beyond ``outlier``, is in a wrong
            local minimum (a Gaussian gives a median of 0.67).
        landmark_limit: a landmark whose median |whitened residual| exceeds it is
            ``inconsistent``.
        mode_cost: another start's minimum within this much cost of the best is kept as a mode.
        inflate: factor on every covariance (1: the Laplace approximation as is).
        inflate_kinematic: a further factor on the covariance when a run solved with the
            kinematic prior is in the map (:data:`KINEMATIC_INFLATE`; 1: none), or ``"auto"``:
            the robots' own maps' scatter about the joint map (:func:`overdispersion`) when
            it exceeds 1 (flag ``overdispersed`` above :data:`OVERDISPERSED`). The scatter is
            measured on every map of two or more robots (``info["overdispersion"]``; NaN when
            too few triplets are placed by two of them) and reported, not acted on, when
            every run has odometry.
        sir_rays: landmarks with fewer rays are ``weak`` (sampled from their exact conditional).
        without_odometry: ``"kinematic"``: a run without odometry is solved with the
            ``kinematic`` motion prior in its place (:mod:`qfg.joint_start`), started at each
            of ``kinematic_chunks`` batch sizes (the fit of least cost kept), and used only if
            its map agrees with other robots' (``agree``); ``"skip"``: left out (flag
            ``no_odometry``).
        agree: a run without odometry is kept only if it is in the largest group of robots
            whose maps agree pairwise (:func:`qfg.joint_start.agreeing_group` with this
            tolerance); a fit without odometry can pass every residual check in a wrong
            minimum, so a lone run without odometry is left out (flag ``unverified``). None:
            no check (every such run kept, at the user's risk).
        too_close: a pose fitted closer to a landmark it sees than this share of the median
            range of all bearings is moved off it (:func:`qfg.joint_start.escape_close`; 0:
            not checked); ``info["too_close"]`` counts such bearings, ``info["too_close_dropped"]``
            those left out because the fit returned to them.
        seed: for the starts' order of tie-breaking (the solve is otherwise deterministic).
        progress: a callable told each phase in one line (each robot's start, the joint
            solve, the covariance), for a user watching a long solve; None: silent.
    """
    if not isinstance(measurements, JointMeasurements):
        raise ValueError(f"measurements: expected JointMeasurements, got "
                         f"{type(measurements).__name__}")
    chunk = positive_int("chunk", chunk, minimum=2)
    min_rays = positive_int("min_rays", min_rays, minimum=2)
    min_par = np.deg2rad(non_negative("min_parallax_deg", min_parallax_deg))
    starts = positive_int("starts", starts)
    non_negative("robust", robust)
    non_negative("residual_limit", residual_limit)
    non_negative("mode_cost", mode_cost)
    inflate = non_negative("inflate", inflate)
    auto = isinstance(inflate_kinematic, str)
    if auto and inflate_kinematic != "auto":
        raise ValueError(f"inflate_kinematic: expected a factor >= 0 or 'auto', got "
                         f"{inflate_kinematic!r}")
    if not auto:
        inflate_kinematic = non_negative("inflate_kinematic", inflate_kinematic)
    if without_odometry not in ("kinematic", "skip"):
        raise ValueError(f"without_odometry: expected 'kinematic' or 'skip', got "
                         f"{without_odometry!r}")
    if not isinstance(kinematic, _start.KinematicPrior):
        raise ValueError(f"kinematic: expected a qfg.joint_start.KinematicPrior, got "
                         f"{type(kinematic).__name__}")
    kinematic_chunks = tuple(positive_int("kinematic_chunks", c, minimum=2)
                             for c in np.atleast_1d(kinematic_chunks).tolist())
    if agree is not None:
        agree = non_negative("agree", agree)
    too_close = non_negative("too_close", too_close)
    if too_close >= 1:
        raise ValueError(f"too_close: expected a share of the median range in [0, 1), got "
                         f"{too_close!r}")
    as_rng(seed)
    if progress is not None and not callable(progress):
        raise ValueError(f"progress: expected a callable or None, got {type(progress).__name__}")
    t0 = _time.perf_counter()

    def tell(msg):
        if progress is not None:
            progress(f"joint: {msg} ({_time.perf_counter() - t0:.0f} s)")
    ids = measurements.landmark_ids
    L = len(ids)
    lm_index = {l: i for i, l in enumerate(ids)}
    robot_flags = {r.robot: "ok" for r in measurements.runs}
    flags = []
    runs = []
    for r in measurements.runs:
        if r.has_odometry:
            runs.append(r)
        elif without_odometry == "kinematic":
            runs.append(_start.kinematic_run(r, kinematic))
            robot_flags[r.robot] = "kinematic"
        else:
            robot_flags[r.robot] = "no_odometry"
            flags.append("no_odometry")
    kinematic_robots = {r.robot for r in runs if robot_flags[r.robot] == "kinematic"}
    nan_poses = {r.robot: np.full((r.n_poses, 3), np.nan) for r in measurements.runs}

    def nothing(**extra):
        return JointPosterior(ids, (), np.zeros(L, bool), ("unconstrained",) * L, robot_flags,
                              tuple(dict.fromkeys(flags)), "none", nan_poses,
                              {"time_s": _time.perf_counter() - t0, **extra})
    if agree is not None and len(runs) == 1 and kinematic_robots:
        # one run without odometry and nothing to check its fit against: not worth solving
        robot_flags[runs[0].robot] = "unverified"
        flags.append("unverified")
        return nothing()
    if not runs:
        return nothing()
    opts = dict(chunk=chunk, min_rays=min_rays, min_par=min_par, robust=robust,
                max_iterations=max_iterations, outlier=outlier)
    # 1. each run alone, in its own frame
    per, starts_info = {}, {}
    for k_run, r in enumerate(runs):
        tell(f"robot {r.robot} ({k_run + 1} of {len(runs)}): its own map, "
             + ("a kinematic motion prior for its odometry" if r.robot in kinematic_robots
                else "from its odometry"))
        if r.robot in kinematic_robots:
            # the minimum reached depends on the batch size; the least cost is kept
            tries = [_start.kinematic_start(r, lm_index, chunk=ch, robust=robust,
                                            prior=kinematic) for ch in kinematic_chunks]
            costs = [np.inf if t[3] is None else float(t[3].cost) for t in tries]
            best_try = int(np.argmin(costs))
            candidates = [tries[best_try]] if np.isfinite(costs[best_try]) else []
            starts_info[r.robot] = {"chunk": kinematic_chunks[best_try], "costs": costs}
        else:
            # several starts: other batch sizes when a run ends in a wrong minimum
            candidates = (_start.odometry_start(r, lm_index, **{**opts, "chunk": ch})
                          for ch in dict.fromkeys((chunk, 2 * chunk, max(chunk // 2, 2))))
        fit = None
        for poses, points, have, fit in candidates:
            if fit is None:
                continue
            pr1, offs1, ok1 = _start.problem_of([r], lm_index, have, r.robot, robust=robust)
            chk = _robot_checks(pr1, _nl.Fit(poses, points[ok1], 0.0, 0, True, None, None),
                                offs1, [r], outlier)[r.robot]
            if not _failed(chk, residual_limit, outlier):
                per[r.robot] = (poses, points, have)
                break
        else:
            robot_flags[r.robot] = "unconstrained" if fit is None else "local_minimum"
            flags.append("local_minimum" if fit is not None else "unconstrained_robot")
    robot_maps = {k: np.where(v[2][:, None], v[1], np.nan) for k, v in per.items()}
    if agree is not None and kinematic_robots & set(per):
        # a fit without odometry is trusted only when another robot's map has its shape
        group = set(_start.agreeing_group(robot_maps, agree))
        for k in sorted(kinematic_robots & set(per) - group):
            del per[k]
            robot_flags[k] = "unverified"
            flags.append("unverified")
    if kinematic_robots & set(per):
        flags.append("kinematic_prior")
    runs = [r for r in runs if r.robot in per]
    if not runs:
        if "unverified" not in flags:
            flags.append("unconstrained_landmark")
        return nothing(robot_maps=robot_maps, kinematic_starts=starts_info)
    # 2. align to the reference run; 3. joint solve, dropping runs in wrong minima
    while True:
        ref = max(runs, key=lambda r: (r.robot not in kinematic_robots, per[r.robot][2].sum(),
                                       -r.robot)).robot
        pts = np.where(per[ref][2][:, None], per[ref][1], 0.0)
        have = per[ref][2].copy()
        init = {ref: per[ref][0]}
        for r in runs:
            if r.robot == ref:
                continue
            p, q, h = per[r.robot]
            common = h & have
            if common.sum() < 2:
                robot_flags[r.robot] = "unaligned"
                continue
            # without odometry a run's scale is the kinematic prior's guess: a similarity
            sc, R, t = _start.similarity(q[common], pts[common],
                                         scale=r.robot in kinematic_robots)
            Xr, Pr = _apply(sc, R, t, p, q)
            init[r.robot] = Xr
            new = h & ~have
            pts[new] = Pr[new]
            have |= new
        use = [r for r in runs if r.robot in init]
        pr, offs, ok = _start.problem_of(use, lm_index, have, ref, robust=robust,
                                         anchor=init[ref][0])
        X0 = np.concatenate([init[r.robot] for r in use])
        tell(f"the joint solve of robot{'s' if len(use) > 1 else ''} "
             f"{', '.join(str(r.robot) for r in use)}: {pr.bearing.size} bearings, "
             f"{pr.n_poses} poses, {pr.n_points} landmarks, {starts} start(s)")
        starts_list = [(X0, pts[ok])]
        for f in (0.5, 2.0)[:starts - 1]:
            starts_list.append((X0, _scale_depths(pr, X0, pts[ok], f)))
        fits = [_nl.fit(pr, X, P, max_iterations=max_iterations) for X, P in starts_list]
        best = int(np.argmin([f.cost for f in fits]))
        fit = fits[best]
        far = _start.diverged(pr, fit)
        if far.any():
            # a landmark ran away in the joint solve: leave it out (unconstrained) and redo
            for rr in runs:
                per[rr.robot][2][ok[far]] = False
            continue
        pr_all = pr
        pr, fit, n_out = _start.drop_outliers(pr, fit, outlier, max_iterations)
        pr, fit, n_close_out, n_close = _start.escape_close(pr, fit, too_close, max_iterations)
        chk = _robot_checks(pr_all, fit, offs, use, outlier)
        med = {r: c[0] for r, c in chk.items()}
        bad = [r for r, c in chk.items() if _failed(c, residual_limit, outlier)]
        if bad and len(use) > 1:
            worst = max(bad, key=lambda r: (chk[r][1], chk[r][0]))
            robot_flags[worst] = "local_minimum"
            flags.append("local_minimum")
            runs = [r for r in runs if r.robot != worst]
            continue
        if bad:
            flags.append("local_minimum")
        # landmark checks
        rb = np.abs(fit.bearing_residuals)
        n_rays = np.bincount(pr.bearing_point, minlength=ok.size)
        med_l = np.array([np.median(rb[pr.bearing_point == c]) if n_rays[c] else 0.0
                          for c in range(ok.size)])
        lflags = ["unconstrained"] * L
        for c, j in enumerate(ok.tolist()):
            lflags[j] = ("inconsistent" if med_l[c] > landmark_limit or bad
                         else "weak" if n_rays[c] < sir_rays else "ok")
        kin = any(r.robot in kinematic_robots for r in use)
        scale = inflate * (inflate_kinematic if kin and not auto else 1.0)
        tell("the covariance (Laplace)")
        try:
            marg = _marginals(pr, fit)
            cov0 = _points_cov(marg, pr, np.arange(ok.size)) * scale
            weak = _weak_info(pr, fit, marg, ok, lflags, scale)
        except _nl.SingularInformation as exc:
            if exc.key is None or exc.key < pr.n_poses:
                # no covariance at all: an honest "cannot say", flagged
                flags.append("indeterminate")
                return nothing(error=str(exc), robot_maps=robot_maps,
                               kinematic_starts=starts_info)
            # a landmark whose rays leave it undetermined (nearly parallel after outliers were
            # dropped): leave it out, flagged unconstrained, and solve again
            for rr in runs:
                per[rr.robot][2][ok[exc.key - pr.n_poses]] = False
            continue
        break
    runs = use
    if "inconsistent" in lflags:
        flags.append("inconsistent_landmark")
    if "unconstrained" in lflags:
        flags.append("unconstrained_landmark")
    # 4. modes and their covariances
    modes = [(fit, cov0)]
    for k, f in enumerate(fits):
        if k == best or f.cost - fit.cost > mode_cost:
            continue
        if _same_mode(f.points, fit.points, cov0) or any(
                _same_mode(f.points, m[0].points, cov0) for m in modes):
            continue
        try:
            modes.append((f, _points_cov(_marginals(pr, f), pr, np.arange(ok.size)) * scale))
        except _nl.SingularInformation:  # a degenerate second minimum is no mode
            continue
    if len(modes) > 1:
        flags.append("second_mode")
    logw = np.array([-f.cost + 0.5 * np.linalg.slogdet(C)[1] for f, C in modes])
    w = np.exp(logw - logw.max())
    w /= w.sum()
    out_modes = []
    for (f, C), wk in zip(modes, w, strict=False):
        P = np.full((L, 2), np.nan)
        P[ok] = f.points
        out_modes.append(Mode(float(wk), P, C, float(f.cost)))
    poses = dict(nan_poses)
    for r in runs:
        poses[r.robot] = fit.poses[offs[r.robot]:offs[r.robot] + r.n_poses]
    constrained = np.zeros(L, bool)
    constrained[ok] = True
    info = {"cost": float(fit.cost), "n_bearings": int(pr.bearing.size),
            "n_poses": int(pr.n_poses), "starts": len(fits), "costs": [f.cost for f in fits],
            "robot_median_residual": med, "outliers_dropped": n_out,
            "too_close": n_close, "too_close_dropped": n_close_out,
            "time_s": _time.perf_counter() - t0,
            "reference_robot": ref, "marginals": marg, "robot_maps": robot_maps,
            "covariance_scale": scale,
            "kinematic_starts": starts_info}
    post = JointPosterior(ids, tuple(out_modes), constrained, tuple(lflags), robot_flags,
                          tuple(dict.fromkeys(flags)), "joint", poses, info, pr, fit, offs, weak)
    if len(use) >= 2:
        # errors the model leaves out show as the robots' maps scattering about the joint one;
        # measured on every map, acted on only where a run had no odometry (with odometry the
        # widening was measured to cost more than it gives, docs/joint.md)
        tell("the robots' own maps against the joint one (overdispersion)")
        kappa = overdispersion(post, [r.robot for r in use], seed=seed)
        info["overdispersion"] = kappa
        if auto and kin and kappa > 1.0:
            post = scale_covariance(post, kappa)
            info["covariance_scale"] = scale * kappa
        if auto and kin and kappa > OVERDISPERSED:
            post = dataclasses.replace(post, flags=post.flags + ("overdispersed",))
    return post


def _scale_depths(pr, X, P, f):
    """Every point moved to ``f`` times its distance from the mean position of the poses that
    see it (a start for the depth ambiguity of bearings)."""
    out = P.copy()
    for c in range(P.shape[0]):
        m = pr.bearing_point == c
        if m.any():
            o = X[pr.bearing_pose[m], :2].mean(0)
            out[c] = o + f * (P[c] - o)
    return out


def _same_mode(a, b, cov) -> bool:
    """Two fits are the same minimum when no point moved by more than 3 of its sigmas."""
    sd = np.sqrt(np.clip(np.diag(cov), 1e-18, None)).reshape(-1, 2).max(axis=1)
    return bool(np.all(np.hypot(*(a - b).T) <= 3 * sd + 1e-9))


def _marginals(pr, fit) -> _nl.Laplace:
    """The Laplace approximation at ``fit``. Where GTSAM's Cholesky fails near a landmark (its
    rays nearly parallel) the landmark is left out by the caller; near a pose (ill-conditioned:
    a pose fitted onto a landmark it sees) :class:`qfg.nonlinear.Laplace`'s sparse solve
    answers, and only a singular system is indeterminate."""
    lap = _nl.Laplace(pr, fit)
    if lap.error_key is not None and lap.error_key >= pr.n_poses:
        raise _nl.SingularInformation(lap.error[:200], lap.error_key)
    return lap


def _points_cov(marg: _nl.Laplace, pr, cols, poses=()):
    """Joint covariance of points ``cols`` then ``poses`` (raises
    :class:`qfg.nonlinear.SingularInformation`, whose ``key`` names the variable)."""
    return marg.joint([int(c) for c in cols], [int(p) for p in poses])


def _weak_info(pr, fit, marg, ok, lflags, inflate):
    """For weak landmarks: their rays and the joint covariance of (every point, the poses that
    see a weak landmark), for conditional resampling."""
    weak = [c for c, j in enumerate(ok.tolist()) if lflags[j] == "weak"]
    if not weak:
        return None
    m = np.isin(pr.bearing_point, weak)
    pidx = np.unique(pr.bearing_pose[m])
    C = _points_cov(marg, pr, np.arange(ok.size), pidx) * inflate
    return {"cols": np.array(weak), "poses": pidx, "cov": C,
            "ray_pose": pr.bearing_pose[m], "ray_point": pr.bearing_point[m],
            "ray_bearing": pr.bearing[m], "ray_sigma": pr.sigma_bearing[m],
            "pose_mean": fit.poses[pidx], "robust": pr.robust_bearing}


# ----------------------------------------------------------------------------- sampling
def _huber(r, k):
    a = np.abs(r)
    return np.where(a <= k, 0.5 * r * r, k * a - 0.5 * k * k) if k > 0 else 0.5 * r * r


def sample_landmarks(posterior: JointPosterior, n: int = 2000, seed=0, *,
                     proposals: int = 64) -> np.ndarray:
    """``n`` joint samples (n, L, 2) of the landmark positions (NaN for unconstrained ones):
    modes chosen by weight, Gaussian within a mode; weak landmarks of the best mode resampled
    from their exact conditional given the sampled poses (``proposals`` Student-t draws per
    sample and landmark, one kept by its importance weight)."""
    n = positive_int("n", n)
    rng = as_rng(seed)
    L = len(posterior.landmark_ids)
    out = np.full((n, L, 2), np.nan)
    if posterior.method == "none" or not posterior.modes:
        return out
    ok = np.flatnonzero(posterior.constrained)
    counts = rng.multinomial(n, [m.weight for m in posterior.modes])
    start = 0
    for k, (mode, c) in enumerate(zip(posterior.modes, counts, strict=False)):
        if c == 0:
            continue
        sl = slice(start, start + c)
        start += c
        wk = posterior._weak if k == 0 else None
        if wk is None:
            z = _nl.sample_gaussian(mode.points[ok].ravel(), mode.covariance, int(c), rng)
            out[sl, ok] = z.reshape(c, ok.size, 2)
            continue
        mu = np.concatenate([mode.points[ok].ravel(), wk["pose_mean"].ravel()])
        z = _nl.sample_gaussian(mu, wk["cov"], int(c), rng)
        pts = z[:, :2 * ok.size].reshape(c, ok.size, 2)
        # GTSAM's pose tangent (x, y in the pose's own axes) -> world perturbation
        d = z[:, 2 * ok.size:].reshape(c, -1, 3) - wk["pose_mean"][None]
        th = wk["pose_mean"][None, :, 2]
        poses = wk["pose_mean"][None] + np.stack(
            [np.cos(th) * d[..., 0] - np.sin(th) * d[..., 1],
             np.sin(th) * d[..., 0] + np.cos(th) * d[..., 1], d[..., 2]], -1)
        pos_of = {int(p): i for i, p in enumerate(wk["poses"].tolist())}
        for col in wk["cols"].tolist():
            m = wk["ray_point"] == col
            pi = np.array([pos_of[int(p)] for p in wk["ray_pose"][m]])
            # proposal: the Gaussian conditional of this landmark given the sampled poses
            # (regression on the pose block), widened x2 in sd, Student t with 4 dof
            # (a landmark is tied to the other poses only through the ones that see it, so
            # conditioning on those is conditioning on all)
            jj = np.arange(2 * col, 2 * col + 2)
            up = np.unique(pi)
            xx = (2 * ok.size + 3 * up[:, None] + np.arange(3)[None, :]).ravel()
            Cxx = wk["cov"][np.ix_(xx, xx)]
            Cxx = (Cxx + Cxx.T) / 2 + np.eye(xx.size) * 1e-12 * max(np.trace(Cxx), 1e-30)
            Bm = np.linalg.solve(Cxx, wk["cov"][np.ix_(xx, jj)]).T          # (2, 3 |up|)
            Cj = (wk["cov"][np.ix_(jj, jj)] - Bm @ wk["cov"][np.ix_(xx, jj)]) * 4.0
            Cj = (Cj + Cj.T) / 2 + np.eye(2) * 1e-12
            mu_j = mode.points[ok][col] + d[:, up].reshape(c, -1) @ Bm.T   # (c, 2)
            prop = mu_j[:, None, :] + _nl.sample_gaussian(
                np.zeros(2), Cj, int(c) * proposals, rng, df=4).reshape(c, proposals, 2)
            X = poses[:, pi]                                       # (c, R, 3)
            dxy = prop[:, :, None, :] - X[:, None, :, :2]          # (c, K, R, 2)
            pred = np.arctan2(dxy[..., 1], dxy[..., 0]) - X[:, None, :, 2]
            r = wrap_angle(wk["ray_bearing"][m] - pred) / wk["ray_sigma"][m]
            # a point behind a camera has a residual near pi / sigma: ruled out by the likelihood
            loglik = -_huber(r, wk["robust"]).sum(-1)
            logq = _t_logpdf(prop, mu_j[:, None, :], Cj, 4)
            lw = loglik - logq
            lw -= lw.max(axis=1, keepdims=True)
            w = np.exp(lw)
            w /= w.sum(axis=1, keepdims=True)
            u = rng.random((c, 1))
            pick = np.minimum((np.cumsum(w, axis=1) < u).sum(axis=1), proposals - 1)
            pts[:, col] = prop[np.arange(c), pick]
        out[sl, ok] = pts
    return out


def reference_samples(posterior: JointPosterior, n: int = 1000, *, steps: int = 2000,
                      seed=0) -> np.ndarray:
    """Long-run sampling of the exact (robust, nonlinear) posterior of a solved problem, to check
    the approximations against: ``n`` random-walk Metropolis chains over every pose and
    landmark, started from the Laplace approximation, proposals ``N(0, 2.38^2 / d Sigma)``
    (Sigma the Laplace covariance of everything, poses turned to world coordinates), ``steps``
    steps each; returns the chains' last states' landmarks (n, L, 2) (NaN where unconstrained).
    Cost grows with the number of variables: meant for small problems (tests, development)."""
    n = positive_int("n", n)
    steps = positive_int("steps", steps)
    rng = as_rng(seed)
    L = len(posterior.landmark_ids)
    out = np.full((n, L, 2), np.nan)
    if posterior.method == "none":
        return out
    pr, fit = posterior._problem, posterior._fit
    C = _points_cov(posterior.info["marginals"], pr, np.arange(pr.n_points),
                    np.arange(pr.n_poses))
    J = np.eye(C.shape[0])
    for i, th in enumerate(fit.poses[:, 2]):
        a = 2 * pr.n_points + 3 * i
        J[a:a + 2, a:a + 2] = [[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]]
    C = J @ C @ J.T
    x0 = np.concatenate([fit.points.ravel(), fit.poses.ravel()])
    dim = x0.size
    cut = 2 * pr.n_points

    def logp(x):
        return -_nl.robust_cost(pr, x[:, cut:].reshape(len(x), -1, 3),
                                x[:, :cut].reshape(len(x), -1, 2))

    x = _nl.sample_gaussian(x0, C, n, rng)
    lp = logp(x)
    F = _nl.gaussian_factor(C) * (2.38 / np.sqrt(dim))
    for _ in range(steps):
        y = x + rng.standard_normal((n, dim)) @ F.T
        ly = logp(y)
        acc = np.log(rng.random(n)) < ly - lp
        x[acc], lp[acc] = y[acc], ly[acc]
    out[:, posterior.constrained] = x[:, :cut].reshape(n, -1, 2)
    return out


def _t_logpdf(x, mu, C, df):
    """Log density (up to a constant) of a 2-D Student t with scale ``C``."""
    Ci = np.linalg.inv(C)
    d = x - mu
    q = np.einsum("...i,ij,...j->...", d, Ci, d)
    return -0.5 * (df + 2) * np.log1p(q / df)


# ----------------------------------------------------------------------------- states
def _all_triplets(L):
    return [t for t in itertools.permutations(range(L), 3)]


#: A map whose robots' own maps scatter about it by more than this factor (in variance) over
#: what its covariance allows is flagged ``overdispersed`` (:func:`overdispersion`).
OVERDISPERSED = 2.0


def ab_frame_moments(posterior: JointPosterior, triplets, samples: int = 2000, seed=0):
    """Mean (T, 2) and covariance (T, 2, 2) of C's position in the AB frame (A = (0, 0),
    B = (0, 1), in units of |AB|) of each landmark-id triplet ``(A, B, C)`` under the posterior,
    from ``samples`` joint samples (:func:`sample_landmarks` with ``seed``): what a triplet's
    state depends on, free of the map's gauge and scale. Triplets with an unconstrained
    landmark get NaN.

    >>> import numpy as np
    >>> from qfg.simulation import random_trajectory_run
    >>> run = random_trajectory_run(np.random.default_rng(0), n_landmarks=5, n_poses=30,
    ...                             fov_deg=360)
    >>> mu, cov = ab_frame_moments(solve(simulated_measurements(run)), [(0, 1, 2)], 500)
    >>> mu.shape, cov.shape, bool(np.all(np.linalg.eigvalsh(cov) > 0))
    ((1, 2), (1, 2, 2), True)
    """
    samples = positive_int("samples", samples, minimum=3)
    tl = [tuple(t) for t in triplets]
    if any(len(t) != 3 or len(set(t)) != 3 for t in tl):
        raise ValueError("triplets: expected (A, B, C) triplets of three distinct ids")
    tri = posterior.index([x for t in tl for x in t]).reshape(-1, 3)
    S = sample_landmarks(posterior, samples, seed)
    T = len(tri)
    mu, cov = np.full((T, 2), np.nan), np.full((T, 2, 2), np.nan)
    ok = np.asarray(posterior.constrained, bool)[tri].all(axis=1)
    if posterior.method == "none" or not ok.any():
        return mu, cov
    t = tri[ok]
    F = to_frame(S[:, t[:, 2]], S[:, t[:, 0]], S[:, t[:, 1]])         # (n, T', 2)
    mu[ok] = F.mean(axis=0)
    D = F - mu[ok]
    cov[ok] = np.einsum("nti,ntj->tij", D, D) / (samples - 1)
    return mu, cov


def landmark_moments(posterior: JointPosterior, samples: int = 2000, seed=0):
    """Mean (L, 2) and covariance (L, 2, 2) of each landmark in the map frame, free of the
    map's gauge: every joint sample (:func:`sample_landmarks` with ``seed``) is first mapped
    onto the best mode's landmarks by its best similarity (:func:`qfg.joint_start.similarity`,
    over the constrained landmarks). The covariances then describe the configuration's
    shape, on which every qualitative state depends, and not where the map's anchor put it:
    a landmark's uncertainty relative to the others, what an ellipse on a map should show.
    Unconstrained landmarks (and every landmark of a map with fewer than 3 constrained) get
    NaN.

    >>> import numpy as np
    >>> from qfg.simulation import random_trajectory_run
    >>> run = random_trajectory_run(np.random.default_rng(0), n_landmarks=5, n_poses=30,
    ...                             fov_deg=360)
    >>> post = solve(simulated_measurements(run))
    >>> mu, cov = landmark_moments(post, 500)
    >>> mu.shape, cov.shape, bool(np.all(np.linalg.eigvalsh(cov) > 0))
    ((5, 2), (5, 2, 2), True)
    """
    samples = positive_int("samples", samples, minimum=3)
    L = len(posterior.landmark_ids)
    mu, cov = np.full((L, 2), np.nan), np.full((L, 2, 2), np.nan)
    ok = np.flatnonzero(np.asarray(posterior.constrained, bool)
                        & np.isfinite(posterior.points).all(axis=1))
    if posterior.method == "none" or ok.size < 3:
        return mu, cov
    S = sample_landmarks(posterior, samples, seed)[:, ok]              # (n, k, 2)
    F = _start.apply_similarity(S, _start.similarity(S, posterior.points[ok]))
    mu[ok] = F.mean(axis=0)
    D = F - mu[ok]
    cov[ok] = np.einsum("nki,nkj->kij", D, D) / (samples - 1)
    return mu, cov


def aligned_errors(mean, covariance, truth):
    """A map's landmarks against their true positions: ``mean`` (k, 2) and ``covariance``
    (k, 2, 2) (e.g. :func:`landmark_moments`' rows without NaN) mapped onto ``truth`` (k, 2)
    by the best similarity (a map's gauge is its own). Returns ``(errors (k, 2), covariances
    (k, 2, 2), z2 (k,), (s, R, t))`` in the truth's frame; ``z2`` is each truth's squared
    Mahalanobis distance, chi-square with 2 dof for a calibrated map (95 % under 5.99).

    >>> import numpy as np
    >>> truth = np.array([[0.0, 0], [2, 0], [0, 2], [2, 2]])
    >>> e = np.array([[1, 0], [-1, 0], [-1, 0], [1, 0]]) * 1e-3    # no similarity in it
    >>> err, C, z2, _ = aligned_errors(3 * (truth + e) + 1, np.tile(9e-6 * np.eye(2), (4, 1, 1)),
    ...                                truth)                       # map: x3, its sd 3e-3
    >>> np.round(z2, 2).tolist()
    [1.0, 1.0, 1.0, 1.0]
    """
    mu = as_float_array("mean", mean, ndim=2, last_dim=2)
    C = as_float_array("covariance", covariance, ndim=3)
    X = as_float_array("truth", truth, ndim=2, last_dim=2)
    if C.shape != (mu.shape[0], 2, 2) or X.shape != mu.shape:
        raise ValueError(f"covariance, truth: expected {(mu.shape[0], 2, 2)} and {mu.shape}, "
                         f"got {C.shape} and {X.shape}")
    if mu.shape[0] < 3:
        raise ValueError(f"mean: at least 3 landmarks to align, got {mu.shape[0]}")
    s, R, t = sim = _start.similarity(mu, X)
    err = _start.apply_similarity(mu, sim) - X
    Cw = s * s * np.einsum("ij,kjl,ml->kim", R, C, R)
    z2 = np.einsum("ki,kij,kj->k", err, np.linalg.inv(Cw), err)
    return err, Cw, z2, (s, R, t)


def overdispersion(posterior: JointPosterior, robots=None, *, triplets: int = 2000,
                   samples: int = 500, seed=0) -> float:
    """How far the robots' own maps scatter about the joint map, against what its covariance
    allows, in the AB frame (a Birge ratio; no ground truth).

    Each robot's own map (``posterior.info["robot_maps"]``, placed from its run alone) is
    compared with the joint map, triplet by triplet, where the comparison is free of the
    maps' gauge and scale: C's position in the frame A = (0, 0), B = (0, 1). With ``x_rt`` the
    robot's, ``mu_t`` and ``Sigma_t`` the joint posterior's mean and covariance of that
    position (from ``samples`` samples), and K robots that inform the map equally, the robot's
    deviation has covariance ``(K - 1) Sigma_t`` (the joint map holds the robot's own
    information), so

        kappa = median_{r, t} (x_rt - mu_t)' Sigma_t^-1 (x_rt - mu_t) / ((K - 1) chi2_2.median)

    is about 1 when the covariance accounts for the errors and grows with errors it does not
    model (shared by an image, a robot, a stretch of a run). ``robots``: the robots compared
    (default: every robot with a map, K >= 2 needed); ``triplets``: at most this many ordered
    triplets, drawn with ``seed`` when there are more. Returns NaN when fewer than two robots
    have maps or no triplet is placed by both.

    >>> import numpy as np
    >>> from qfg.simulation import random_trajectory_run
    >>> rng = np.random.default_rng(0)
    >>> a = random_trajectory_run(rng, n_landmarks=6, n_poses=40, fov_deg=360)
    >>> b = random_trajectory_run(rng, n_poses=40, fov_deg=360, landmarks=a.landmarks)
    >>> runs = tuple(simulated_measurements(r, robot=k).runs[0] for k, r in enumerate((a, b)))
    >>> post = solve(JointMeasurements(runs, tuple(range(6))))
    >>> bool(0.2 < overdispersion(post) < 5)      # simulated with the model's own noise
    True
    """
    samples = positive_int("samples", samples, minimum=3)
    triplets = positive_int("triplets", triplets)
    maps = posterior.info.get("robot_maps", {})
    use = [r for r in (maps if robots is None else robots) if r in maps]
    if len(use) < 2 or posterior.method == "none":
        return float("nan")
    L = len(posterior.landmark_ids)
    ok = np.asarray(posterior.constrained, bool)
    rng = as_rng(seed)
    tri = np.flatnonzero(ok)[np.array(_all_triplets(int(ok.sum())), dtype=np.intp)
                             .reshape(-1, 3)]
    if len(tri) > triplets:
        tri = tri[np.sort(rng.choice(len(tri), triplets, replace=False))]
    if not len(tri):
        return float("nan")
    ids = np.asarray(posterior.landmark_ids)
    mu, cov = ab_frame_moments(posterior, ids[tri].tolist(), samples, rng)
    z2 = [z[np.isfinite(z)] for z in (_z2(np.asarray(maps[r], float).reshape(L, 2), tri, mu, cov)
                                      for r in use)]
    z2 = [z for z in z2 if z.size]
    if len(z2) < 2:
        return float("nan")
    return float(np.median(np.concatenate(z2)) / ((len(z2) - 1) * 2.0 * np.log(2.0)))


def _z2(P, tri, mu, cov) -> np.ndarray:
    """(T,) squared Mahalanobis distances of C's AB-frame position in the landmark positions
    ``P`` (L, 2) for index triplets ``tri`` (T, 3) from ``mu`` (T, 2) under ``cov`` (T, 2, 2);
    NaN where a position is missing or the covariance singular."""
    out = np.full(len(tri), np.nan)
    det = cov[:, 0, 0] * cov[:, 1, 1] - cov[:, 0, 1] * cov[:, 1, 0]
    have = np.isfinite(P[tri]).all(axis=(1, 2)) & (det > 0)
    if have.any():
        t = tri[have]
        e = to_frame(P[t[:, 2]], P[t[:, 0]], P[t[:, 1]]) - mu[have]
        c = cov[have]
        # e' C^-1 e for 2 x 2 C, without inverting T matrices
        out[have] = (c[:, 1, 1] * e[:, 0] ** 2 - 2 * c[:, 0, 1] * e[:, 0] * e[:, 1]
                     + c[:, 0, 0] * e[:, 1] ** 2) / det[have]
    return out


def ab_frame_z2(posterior: JointPosterior, positions, triplets, samples: int = 2000,
                seed=0) -> np.ndarray:
    """(T,) the squared Mahalanobis distance of C's AB-frame position in landmark ``positions``
    (L, 2, in the order of ``posterior.landmark_ids``; e.g. the ground truth, in any frame and
    scale) from the posterior's mean under its covariance (:func:`ab_frame_moments`), for each
    landmark-id triplet of ``triplets``; calibrated: chi-square with 2 dof (median 1.39). NaN
    where a landmark is unconstrained or its position missing."""
    try:
        P = np.asarray(positions, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"positions: expected numbers ({exc})") from None
    if P.shape != (len(posterior.landmark_ids), 2) or np.isinf(P).any():
        raise ValueError(f"positions: expected shape ({len(posterior.landmark_ids)}, 2), one "
                         f"finite position (or NaN: not placed) per landmark id, got shape "
                         f"{P.shape}")
    tl = [tuple(t) for t in triplets]
    mu, cov = ab_frame_moments(posterior, tl, samples, seed)
    tri = posterior.index([x for t in tl for x in t]).reshape(-1, 3)
    return _z2(P, tri, mu, cov)


def scale_covariance(posterior: JointPosterior, factor: float) -> JointPosterior:
    """The posterior with every covariance (modes and the weak landmarks' block) times
    ``factor`` (> 0); mode weights are unchanged by a common factor. ``solve``'s ``inflate``
    and ``inflate_kinematic`` do this at the solve; this does it afterwards (e.g. to compare
    factors on one solve)."""
    factor = non_negative("factor", factor)
    if factor <= 0:
        raise ValueError("factor: expected a factor > 0")
    wk = posterior._weak
    return dataclasses.replace(
        posterior, modes=tuple(dataclasses.replace(m, covariance=m.covariance * factor)
                               for m in posterior.modes),
        _weak=None if wk is None else {**wk, "cov": wk["cov"] * factor})


def _mix(P, q, w):
    return (1.0 - w)[:, None] * P + w[:, None] * q[None, :]


def triplet_marginals(posterior: JointPosterior, triplets=None, *, partition="edc",
                      samples: int = 2000, seed=0, prior_states=None, floor: float = FLOOR,
                      widen: float = 0.5) -> "Marginals":
    """State distribution of every ordered triplet (landmark ids ``(A, B, C)``) from samples of
    the posterior: ``P(S) = (1 - w) #{samples in S} / n + w q`` with ``q`` = ``prior_states``
    (m,) (default uniform) and ``w`` = ``floor``, or ``widen`` for triplets with an
    inconsistent landmark (or when a robot sat in a wrong minimum that could not be dropped), or
    1 for triplets with an unconstrained landmark.

    Returns a :class:`qfg.inference.results.Marginals` keyed by landmark-id triplets, method
    ``"joint"`` (or ``"joint:none"`` when nothing was solved), ``info["flagged"]`` (n,) bool,
    ``info["widen"]`` (n,) the weight given to the prior, ``info["flags"]``.
    """
    from .inference.results import Marginals

    part = _partitions.get(partition)
    m = part.n_states
    ids = posterior.landmark_ids
    if triplets is None:
        tri_idx = np.array(_all_triplets(len(ids)), dtype=np.intp).reshape(-1, 3)
    else:
        tl = [tuple(t) for t in triplets]
        if any(len(t) != 3 or len(set(t)) != 3 for t in tl):
            raise ValueError("triplets: expected (A, B, C) triplets of three distinct ids")
        tri_idx = posterior.index([x for t in tl for x in t]).reshape(-1, 3)
    q = (np.full(m, 1.0 / m) if prior_states is None
         else as_float_array("prior_states", prior_states, ndim=1))
    if q.size != m or q.min() < 0 or not np.isclose(q.sum(), 1.0):
        raise ValueError(f"prior_states: expected {m} probabilities summing to 1")
    floor = non_negative("floor", floor)
    widen = non_negative("widen", widen)
    if floor > 1 or widen > 1:
        raise ValueError("floor, widen: expected weights in [0, 1]")
    n = len(tri_idx)
    P = np.tile(q, (n, 1))
    lf = np.array(posterior.landmark_flags)
    w = np.full(n, floor)
    if posterior.method != "none" and n:
        S = sample_landmarks(posterior, samples, seed)
        solvable = posterior.constrained[tri_idx].all(axis=1)
        idx = np.flatnonzero(solvable)
        P[idx] = _state_counts(S, tri_idx[idx], part) / samples
        bad = (lf[tri_idx] == "inconsistent").any(axis=1)
        if "local_minimum" in posterior.flags and all(
                v != "local_minimum" for v in posterior.robot_flags.values()):
            bad[:] = True  # the only run sits in a wrong minimum: nothing is trustworthy
        w = np.where(bad, np.maximum(widen, floor), w)
        w = np.where(solvable, w, 1.0)
    else:
        w[:] = 1.0
    P = _mix(P, q, w)
    keys = tuple(tuple(int(ids[i]) for i in t) for t in tri_idx.tolist())
    return Marginals(keys, part.name, P, "joint" if posterior.method != "none" else "joint:none",
                     {"flagged": w > floor, "widen": w, "flags": posterior.flags})


def _state_counts(S, tri, part, chunk: int = 256):
    """Counts (T, m) of each triplet's state over the samples S (n, L, 2)."""
    m = part.n_states
    out = np.zeros((len(tri), m))
    for a in range(0, len(tri), chunk):
        t = tri[a:a + chunk]
        A, B, C = S[:, t[:, 0]], S[:, t[:, 1]], S[:, t[:, 2]]
        s = part.state_of(_safe_frame(C, A, B))                     # (n, T')
        k = np.arange(len(t))[None, :] * m + np.where(s >= 0, s, 0)
        out[a:a + chunk] = np.bincount(k.ravel(), minlength=len(t) * m).reshape(len(t), m)
    return out


def _safe_frame(C, A, B):
    """to_frame, with a sample where A and B coincide moved by a hair (measure zero)."""
    d = B - A
    near = np.sum(d * d, axis=-1) <= 1e-24
    if near.any():
        B = np.where(near[..., None], B + 1e-9, B)
    return to_frame(C, A, B)


def camera_marginals(posterior: JointPosterior, robot, pose_index, triplets, *,
                     partition="edc", samples: int = 500, seed=0, prior_states=None,
                     floor: float = FLOOR) -> np.ndarray:
    """State distributions (n, m) of camera poses in triplet frames: row i is the state of pose
    ``pose_index[i]`` of ``robot`` in the AB frame of ``triplets[i]`` (landmark ids), from
    samples of the joint Gaussian of that pose and the landmarks (best mode). Rows whose robot
    was not solved, or whose A or B is unconstrained, are ``prior_states`` (default uniform);
    every row is mixed with it by ``floor``."""
    part = _partitions.get(partition)
    m = part.n_states
    pose_index = np.asarray(pose_index, dtype=np.intp).reshape(-1)
    tl = [tuple(t) for t in triplets]
    if len(tl) != pose_index.size:
        raise ValueError(f"triplets: expected {pose_index.size} triplets (one per pose), "
                         f"got {len(tl)}")
    q = np.full(m, 1.0 / m) if prior_states is None else np.asarray(prior_states, float)
    out = np.tile(q, (pose_index.size, 1))
    if robot not in posterior.robot_flags:
        raise KeyError(f"robot: {robot} is not in this posterior")
    if (posterior.method == "none" or posterior._pose_offset is None
            or robot not in posterior._pose_offset or not pose_index.size):
        return _mix(out, q, np.full(len(out), 1.0))
    rng = as_rng(seed)
    pr, fit = posterior._problem, posterior._fit
    ok = np.flatnonzero(posterior.constrained)
    col = -np.ones(len(posterior.landmark_ids), np.intp)
    col[ok] = np.arange(ok.size)
    marg = posterior.info["marginals"]
    off = posterior._pose_offset[robot]
    AB = posterior.index([x for t in tl for x in t[:2]]).reshape(-1, 2)
    for p in np.unique(pose_index).tolist():
        rows = np.flatnonzero(pose_index == p)
        need = np.unique(col[AB[rows]])
        if (need < 0).any():
            continue
        try:
            C = _points_cov(marg, pr, need, [off + p])
        except _nl.SingularInformation:  # this pose cannot be placed: its rows stay the prior
            continue
        mu = np.concatenate([fit.points[need].ravel(), fit.poses[off + p]])
        z = _nl.sample_gaussian(mu, C, samples, rng)
        d = z[:, -3:] - fit.poses[off + p]
        th = fit.poses[off + p, 2]
        X = fit.poses[off + p] + np.stack([np.cos(th) * d[:, 0] - np.sin(th) * d[:, 1],
                                           np.sin(th) * d[:, 0] + np.cos(th) * d[:, 1],
                                           d[:, 2]], -1)
        pos = {int(c): i for i, c in enumerate(need.tolist())}
        for i in rows.tolist():
            a, b = pos[int(col[AB[i, 0]])], pos[int(col[AB[i, 1]])]
            A, B = z[:, 2 * a:2 * a + 2], z[:, 2 * b:2 * b + 2]
            s = part.state_of(poses_to_frame(X, A, B)[:, :2])
            out[i] = np.bincount(s[s >= 0], minlength=m)[:m] / samples
    return _mix(out, q, np.full(len(out), non_negative("floor", floor)))


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


# ----------------------------------------------------------------------------- MRCLAM
def _keyframes(idx, t, P, forced, min_move, min_turn, min_interval) -> np.ndarray:
    """Greedy keyframes among views ``idx``: each view ``min_interval`` s or more after the
    last keyframe where the dead-reckoned pose ``P`` moved ``min_move`` or turned ``min_turn``
    (every view counts as a move when ``P`` is None: no odometry), and every ``forced`` one."""
    kf = [idx[0]]
    for i in idx[1:]:
        j = kf[-1]
        if forced[i] or (t[i] - t[j] >= min_interval and (
                P is None or np.hypot(*(P[i, :2] - P[j, :2])) >= min_move
                or abs(wrap_angle(P[i, 2] - P[j, 2])) >= min_turn)):
            kf.append(i)
    return np.array(kf)


def mrclam_runs(dataset, robots=None, *, min_move: float = 0.02, min_turn_deg: float = 1.0,
                min_interval: float = 0.0, sigma_bearing: float | None = None,
                odometry_noise=None, keep_times=None, odometry_lead: float | None = None,
                noise_by_path: bool = False) -> JointMeasurements:
    """:class:`JointMeasurements` of an :class:`qfg.datasets.mrclam.MRCLAMDataset`.

    Per robot: the views with at least one landmark (inside the odometry's span; repeated views
    left out) kept as keyframes when the dead-reckoned pose moved ``min_move`` m or turned
    ``min_turn_deg`` since the last keyframe (robots without odometry: every view) and, when
    ``min_interval`` > 0, at least ``min_interval`` seconds after it (fewer images, for a curve
    over how many a run uses: 120 / k keeps at most k per 120-s pass), plus every view whose
    time is in ``keep_times[robot]`` (views to be scored as cameras); the odometry
    between keyframes from the dead-reckoned poses (:func:`odometry_steps`, noise
    ``odometry_noise``, default :data:`ODOMETRY_NOISE`; with ``noise_by_path`` its ``d`` and
    ``|dtheta|`` are the path length and turning the odometry covered between the keyframes,
    not the net step: they differ only where keyframes are far apart, and there the option
    helped dataset 6 and hurt datasets 1 and 3, docs/joint.md); bearings with
    ``sigma_bearing`` (default the loader's ``DEFAULT_SIGMA_BEARING``)."""
    from .datasets import mrclam as _m

    sb = _m.DEFAULT_SIGMA_BEARING if sigma_bearing is None else non_negative(
        "sigma_bearing", sigma_bearing)
    lead = _m.DEFAULT_ODOMETRY_LEAD if odometry_lead is None else float(odometry_lead)
    robots = sorted(dataset.robots) if not robots else [int(r) for r in robots]
    min_turn = np.deg2rad(non_negative("min_turn_deg", min_turn_deg))
    min_move = non_negative("min_move", min_move)
    min_interval = non_negative("min_interval", min_interval)
    runs = []
    for rn in robots:
        rd = dataset.robot(rn)
        P, covered = _m.view_poses(rd, lead)
        usable = rd.visible.any(axis=1) & covered & ~_m.repeated_views(rd)
        idx = np.flatnonzero(usable)
        if idx.size == 0:
            continue
        forced = np.zeros(rd.n_views, bool)
        if keep_times and rn in keep_times:
            kt = np.asarray(sorted(keep_times[rn]), float)
            pos = np.searchsorted(rd.view_times, kt)
            pos = pos[(pos < rd.n_views)]
            pos = pos[np.isclose(rd.view_times[pos], kt[:pos.size]) if pos.size == kt.size
                      else np.isin(rd.view_times[pos], kt)]
            forced[pos] = True
        kf = _keyframes(idx, rd.view_times, P, forced, min_move, min_turn, min_interval)
        if P is not None:
            tr = (np.diff(rd.odometry.travelled(rd.view_times[kf] - lead), axis=0)
                  if noise_by_path else None)
            z, s = odometry_steps(P[kf], odometry_noise, tr)
        else:
            z, s = None, None
        vis = rd.visible[kf]
        vi, col = np.nonzero(vis)
        runs.append(RobotRun(robot=rn, times=rd.view_times[kf], bearing_pose=vi,
                             bearing_landmark=dataset.landmark_ids[col],
                             bearing=rd.view_bearings[kf][vi, col], sigma_bearing=sb,
                             odometry=z, odometry_sigma=s))
    if not runs:
        raise ValueError(f"dataset: {dataset.name} has no robot with landmark views")
    return JointMeasurements(tuple(runs), tuple(int(x) for x in dataset.landmark_ids))


def mrclam_reference(dataset, posterior: JointPosterior, measurements: JointMeasurements, *,
                     align: bool = False):
    """A copy of ``dataset`` whose ground truth is the joint map: the landmarks at the map's
    points (its best mode) and each solved robot's ``groundtruth`` its map poses at the
    measurement times of its kept views, so that :func:`qfg.datasets.mrclam.measure_noise`
    measures the noise against the map where there is no motion capture (datasets 1-5).

    Robots the map did not solve (flags other than ``"ok"`` and ``"kinematic"``, or NaN
    poses) get no ground truth and drop out of every measurement; landmarks it did not place
    are made invisible; a posterior solved from other measurements (pose counts that differ)
    gets a ValueError naming the robot. The map's poses sit at the measurement stamps by
    construction, so measure with ``offsets=[0.0]``. The fit absorbs part of the noise it is fitted to (each
    pose explains its own bearings): docs/mrclam.md measures how far this reads low on
    dataset 6, where both references exist. The map keeps its own frame (bearings, headings'
    errors and step-length ratios do not depend on it); ``align``: moved first onto the
    dataset's landmark ground truth by the best similarity of the placed landmarks (for what
    does depend on the frame, e.g. an arena prior built from the landmarks' box). Usage (``ds``
    an MRCLAM dataset)::

        meas = mrclam_runs(ds, min_move=0.0, min_turn_deg=0.0)   # every usable view a pose
        ref = mrclam_reference(ds, solve(meas), meas)
        noise = qfg.datasets.mrclam.measure_noise(ref, offsets=[0.0])
    """
    xy = np.full((len(dataset.landmark_ids), 2), np.nan)
    xy[dataset.landmark_index(list(posterior.landmark_ids))] = posterior.points
    placed = np.isfinite(xy).all(axis=1)
    sim = None
    if align:
        if placed.sum() < 3:
            raise ValueError(f"posterior: at least 3 placed landmarks to align, got "
                             f"{int(placed.sum())}")
        sim = _start.similarity(xy[placed], dataset.landmark_xy[placed])
        xy[placed] = _apply(*sim, points=xy[placed])[0]
    by_robot = {r.robot: r for r in measurements.runs}
    robots = {}
    for n, rd in dataset.robots.items():
        P = posterior.poses.get(n)
        gt = None
        if n in by_robot and P is not None and len(P) != len(by_robot[n].times):
            raise ValueError(f"posterior: robot {n} has {len(P)} poses, the measurements "
                             f"{len(by_robot[n].times)} views: not the measurements it solved")
        if (n in by_robot and P is not None and np.isfinite(P).all()
                and posterior.robot_flags.get(n) in ("ok", "kinematic")):
            if sim is not None:
                P = _apply(*sim, poses=P)[0]
            gt = np.column_stack([by_robot[n].times, P])
        robots[n] = dataclasses.replace(rd, groundtruth=gt, visible=rd.visible & placed[None, :])
    return dataclasses.replace(dataset, landmark_xy=np.where(placed[:, None], xy, 0.0),
                               robots=robots)


@dataclass(frozen=True, eq=False)
class MRCLAMJoint:
    """:func:`mrclam_marginals`' answer.

    Attributes:
        triplets: :class:`~qfg.inference.results.Marginals` keyed by subject-number triplets.
        cameras: list of (n_views, m) arrays, one per requested history (or None when none
            were requested).
        method: which method answered (``"joint"``, or ``"none"``: nothing could be solved,
            e.g. a lone robot without odometry (``posterior.flags`` say why); the solver-based
            pipeline must answer).
        posterior: the :class:`JointPosterior`; time_s: wall time.
    """

    triplets: object
    cameras: list | None
    method: str
    posterior: JointPosterior
    time_s: float


def mrclam_marginals(dataset, triplets=None, histories=None, *, robots=None, prior_states=None,
                     camera_prior_states=None, samples: int = 2000, camera_samples: int = 300,
                     seed=0, partition="edc", floor: float = FLOOR, widen: float = 0.5,
                     run_options=None, progress=None, **solve_options) -> MRCLAMJoint:
    """The joint method on one MRCLAM dataset: triplet state distributions (every ordered
    triplet of the dataset's landmarks, or ``triplets`` of subject numbers) and, for each
    history in ``histories`` (objects with ``robot``, ``views`` (time stamps) and ``landmarks``,
    e.g. :class:`qfg.datasets.mrclam.MRCLAMHistory`), the camera state of each of its views.

    ``prior_states`` / ``camera_prior_states``: the state distributions of the prior alone (for
    the floor and for what cannot be solved); ``run_options`` go to :func:`mrclam_runs`, the
    rest to :func:`solve` (``progress``: a callable told each phase, as in :func:`solve`).
    When nothing can be solved (e.g. one robot without odometry: its fit
    cannot be checked against another's), ``method`` is ``"none"`` and every row is the prior:
    answer with the solver pipeline instead (``qfg mrclam --method full``).
    """
    t0 = _time.perf_counter()
    keep = None
    if histories:
        keep = {}
        for h in histories:
            keep.setdefault(int(h.robot), set()).update(float(t) for t in np.asarray(h.views))
    meas = mrclam_runs(dataset, robots, keep_times=keep, **(run_options or {}))
    post = solve(meas, seed=seed, progress=progress, **solve_options)
    if progress is not None:
        progress("joint: the states of " + ("every ordered triplet" if triplets is None else
                                             f"{len(triplets)} ordered triplet"
                                             + ("s" if len(triplets) != 1 else ""))
                 + (f" and the cameras of {len(histories)} histories" if histories else ""))
    res = triplet_marginals(post, triplets, partition=partition, samples=samples, seed=seed,
                            prior_states=prior_states, floor=floor, widen=widen)
    cams = None
    if histories:
        cams = []
        rng = as_rng(seed)
        for h in histories:
            rn = int(h.robot)
            try:
                run = meas.run(rn)
            except KeyError:
                run = None
            m = _partitions.get(partition).n_states
            if run is None:
                q = (np.full(m, 1 / m) if camera_prior_states is None
                     else np.asarray(camera_prior_states, float))
                cams.append(np.tile(q, (len(h.views), 1)))
                continue
            pi = np.searchsorted(run.times, np.asarray(h.views, float))
            pi = np.clip(pi, 0, run.n_poses - 1)
            cams.append(camera_marginals(post, rn, pi, [tuple(h.landmarks)] * len(pi),
                                         partition=partition, samples=camera_samples,
                                         seed=rng, prior_states=camera_prior_states,
                                         floor=floor))
    return MRCLAMJoint(res, cams, post.method, post, _time.perf_counter() - t0)
