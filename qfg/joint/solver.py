"""The joint metric solve (:func:`solve`): every robot's run alone from its start
(:mod:`qfg.joint.start`), the runs aligned to a reference robot and solved together on GTSAM
(Levenberg-Marquardt, Huber kernel on the bearings) from several starts, the residual checks
that drop robots and flag landmarks, and the Laplace approximation at each mode
(:mod:`qfg.joint`'s docstring has the method, docs/joint.md the measurements behind each
default).

In: :class:`qfg.joint.JointMeasurements`. Out: :class:`qfg.joint.JointPosterior` (landmark
positions in the frame of the reference robot's first pose, metres).
"""

from __future__ import annotations

import dataclasses
import time as _time

import numpy as np

from .. import nonlinear as _nl
from .._validate import as_rng
from . import start as _start
from ._laplace import _marginals, _points_cov, _weak_info
from .inputs import JointMeasurements
from .moments import overdispersion, scale_covariance
from .params import KINEMATIC_INFLATE, OUTLIER, SolveParams, _removed_options
from .posterior import JointPosterior, Mode
from .start import _apply

__all__ = ["solve", "OUTLIER", "OUTLIER_SHARE", "KINEMATIC_INFLATE", "OVERDISPERSED"]

#: A run with more than this share of its bearings beyond :data:`OUTLIER` disagrees with the
#: map: gross errors are rare in the data (docs/mrclam.md), so a run with many of them sits in
#: a wrong minimum rather than being unlucky in its bearings.
OUTLIER_SHARE = 0.1
#: A map whose robots' own maps scatter about it by more than this factor (in variance) over
#: what its covariance allows is flagged ``overdispersed`` (:func:`overdispersion`).
OVERDISPERSED = 2.0


def robot_checks(pr, fit, offs, runs, outlier):
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



def solve(measurements: JointMeasurements, params: SolveParams | None = None, *, seed=0,
          progress=None, **removed) -> JointPosterior:
    """The joint posterior of :class:`JointMeasurements` (:mod:`qfg.joint`, steps 1-4).

    Args:
        params: the options (:class:`qfg.joint.SolveParams`, each documented there); None: the
            defaults, ``SolveParams()``.
        seed: for the starts' order of tie-breaking (the solve is otherwise deterministic).
        progress: a callable told each phase in one line (each robot's start, the joint
            solve, the covariance), for a user watching a long solve; None: silent.

    An option passed as a keyword of its own (``solve(meas, starts=1)``, the form before
    :class:`SolveParams`) is a ``TypeError`` that names :class:`SolveParams`.

    >>> import numpy as np
    >>> from qfg.simulation import random_trajectory_run
    >>> from qfg.joint import SolveParams, simulated_measurements
    >>> run = random_trajectory_run(np.random.default_rng(0), n_landmarks=5, n_poses=30,
    ...                             fov_deg=360)
    >>> solve(simulated_measurements(run), SolveParams(starts=1), seed=0).info["starts"]
    1
    """
    if not isinstance(measurements, JointMeasurements):
        raise ValueError(f"measurements: expected JointMeasurements, got "
                         f"{type(measurements).__name__}")
    if removed:
        raise _removed_options("solve", removed)
    if params is None:
        params = SolveParams()
    elif not isinstance(params, SolveParams):
        raise ValueError(f"params: expected a qfg.joint.SolveParams or None, got "
                         f"{type(params).__name__}")
    chunk, min_rays, starts = params.chunk, params.min_rays, params.starts
    min_par = np.deg2rad(params.min_parallax_deg)
    robust, outlier, max_iterations = params.robust, params.outlier, params.max_iterations
    residual_limit, landmark_limit = params.residual_limit, params.landmark_limit
    mode_cost, inflate, sir_rays = params.mode_cost, params.inflate, params.sir_rays
    inflate_kinematic = params.inflate_kinematic
    auto = isinstance(inflate_kinematic, str)
    without_odometry, kinematic = params.without_odometry, params.kinematic
    kinematic_chunks, agree, too_close = params.kinematic_chunks, params.agree, params.too_close
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
            chk = robot_checks(pr1, _nl.Fit(poses, points[ok1], 0.0, 0, True, None, None),
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
        chk = robot_checks(pr_all, fit, offs, use, outlier)
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

