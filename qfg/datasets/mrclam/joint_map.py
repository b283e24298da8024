"""The joint map (:mod:`qfg.joint`) on MRCLAM: a dataset's views as joint measurements, the
joint map as a stand-in ground truth, and the joint method's triplet and camera states.

* :func:`mrclam_runs`: an :class:`qfg.datasets.mrclam.MRCLAMDataset` as
  :class:`qfg.joint.JointMeasurements` (keyframes of every robot's landmark views, the
  odometry between them with its noise, bearings in radians relative to the camera heading).
* :func:`mrclam_reference`: a copy of the dataset whose ground truth is a solved joint map,
  for measuring the noise where there is no motion capture.
* :func:`mrclam_marginals` (answer :class:`MRCLAMJoint`): the joint method end to end, keyed by
  subject numbers.

This adapter sits above both the loader (the rest of :mod:`qfg.datasets.mrclam`) and the joint
map, which reads no dataset; the package does not import it (import
``qfg.datasets.mrclam.joint_map``), so that loading data needs no solver.
"""

from __future__ import annotations

import dataclasses
import time as _time
from dataclasses import dataclass

import numpy as np

from ... import partitions as _partitions
from ..._validate import as_rng, non_negative
from ...geometry import wrap_angle
from ...inference.results import Marginals
from ...joint import (
    FLOOR,
    JointMeasurements,
    JointPosterior,
    RobotRun,
    SolveParams,
    camera_marginals,
    odometry_steps,
    solve,
    triplet_marginals,
)
from ...joint.params import _removed_options
from ...joint.start import _apply, similarity
from ._constants import DEFAULT_ODOMETRY_LEAD, DEFAULT_SIGMA_BEARING
from ._data import repeated_views
from ._histories import view_poses

__all__ = ["mrclam_runs", "mrclam_reference", "mrclam_marginals", "MRCLAMJoint"]


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
    """:class:`qfg.joint.JointMeasurements` of an :class:`qfg.datasets.mrclam.MRCLAMDataset`.

    Per robot: the views with at least one landmark (inside the odometry's span; repeated views
    left out) kept as keyframes when the dead-reckoned pose moved ``min_move`` m or turned
    ``min_turn_deg`` since the last keyframe (robots without odometry: every view) and, when
    ``min_interval`` > 0, at least ``min_interval`` seconds after it (fewer images, for a curve
    over how many a run uses: 120 / k keeps at most k per 120-s pass), plus every view whose
    time is in ``keep_times[robot]`` (views to be scored as cameras); the odometry
    between keyframes from the dead-reckoned poses (:func:`qfg.joint.odometry_steps`, noise
    ``odometry_noise``, default :data:`qfg.joint.ODOMETRY_NOISE`; with ``noise_by_path`` its
    ``d`` and ``|dtheta|`` are the path length and turning the odometry covered between the
    keyframes, not the net step: they differ only where keyframes are far apart, where the path
    is the better model of a long step but did not hold up on held-out datasets, so it is off
    by default, docs/joint.md); bearings with ``sigma_bearing`` (default the loader's
    ``DEFAULT_SIGMA_BEARING``)."""
    sb = DEFAULT_SIGMA_BEARING if sigma_bearing is None else non_negative(
        "sigma_bearing", sigma_bearing)
    lead = DEFAULT_ODOMETRY_LEAD if odometry_lead is None else float(odometry_lead)
    robots = sorted(dataset.robots) if not robots else [int(r) for r in robots]
    min_turn = np.deg2rad(non_negative("min_turn_deg", min_turn_deg))
    min_move = non_negative("min_move", min_move)
    min_interval = non_negative("min_interval", min_interval)
    runs = []
    for rn in robots:
        rd = dataset.robot(rn)
        P, covered = view_poses(rd, lead)
        usable = rd.visible.any(axis=1) & covered & ~repeated_views(rd)
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
        sim = similarity(xy[placed], dataset.landmark_xy[placed])
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
        cameras: list of :class:`~qfg.inference.results.Marginals` (n_views, m), one per
            requested history, keyed by the history's triplet of subject numbers, method
            ``"joint"``, ``info["robot"]`` and ``info["pose_index"]`` (the keyframe of each
            view; None for a robot the map was not given) (or None when no history was
            requested).
        method: which method answered (``"joint"``, or ``"none"``: nothing could be solved,
            e.g. a lone robot without odometry (``posterior.flags`` say why); the solver-based
            pipeline must answer).
        posterior: the :class:`qfg.joint.JointPosterior`; time_s: wall time.
    """

    triplets: object
    cameras: list | None
    method: str
    posterior: JointPosterior
    time_s: float


def mrclam_marginals(dataset, triplets=None, histories=None, *, robots=None, prior_states=None,
                     camera_prior_states=None, samples: int = 2000, camera_samples: int = 300,
                     seed=0, partition="edc", floor: float = FLOOR, widen: float = 0.5,
                     run_options=None, params: SolveParams | None = None, progress=None,
                     **removed) -> MRCLAMJoint:
    """The joint method on one MRCLAM dataset: triplet state distributions (every ordered
    triplet of the dataset's landmarks, or ``triplets`` of subject numbers) and, for each
    history in ``histories`` (objects with ``robot``, ``views`` (time stamps) and ``landmarks``,
    e.g. :class:`qfg.datasets.mrclam.MRCLAMHistory`), the camera state of each of its views.

    ``prior_states`` / ``camera_prior_states``: the state distributions of the prior alone (for
    the floor and for what cannot be solved); ``run_options`` go to :func:`mrclam_runs`;
    ``params`` (a :class:`qfg.joint.SolveParams`, None: its defaults), ``seed`` and
    ``progress`` (a callable told each phase) to :func:`qfg.joint.solve`. A solve option
    passed as a keyword of its own (the form before :class:`qfg.joint.SolveParams`) is a
    ``TypeError`` naming it.
    When nothing can be solved (e.g. one robot without odometry: its fit
    cannot be checked against another's), ``method`` is ``"none"`` and every row is the prior:
    answer with the solver pipeline instead (``qfg mrclam --method full``).
    """
    if removed:
        raise _removed_options("mrclam_marginals", removed)
    t0 = _time.perf_counter()
    keep = None
    if histories:
        keep = {}
        for h in histories:
            keep.setdefault(int(h.robot), set()).update(float(t) for t in np.asarray(h.views))
    meas = mrclam_runs(dataset, robots, keep_times=keep, **(run_options or {}))
    post = solve(meas, params, seed=seed, progress=progress)
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
            part_name = _partitions.get(partition).name
            if run is None:
                q = (np.full(m, 1 / m) if camera_prior_states is None
                     else np.asarray(camera_prior_states, float))
                cams.append(Marginals((tuple(h.landmarks),) * len(h.views), part_name,
                                      np.tile(q, (len(h.views), 1)), "joint",
                                      {"robot": rn, "pose_index": None}))
                continue
            pi = np.searchsorted(run.times, np.asarray(h.views, float))
            pi = np.clip(pi, 0, run.n_poses - 1)
            cams.append(camera_marginals(post, rn, pi, [tuple(h.landmarks)] * len(pi),
                                         partition=partition, samples=camera_samples,
                                         seed=rng, prior_states=camera_prior_states,
                                         floor=floor))
    return MRCLAMJoint(res, cams, post.method, post, _time.perf_counter() - t0)
