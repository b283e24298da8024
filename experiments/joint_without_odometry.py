"""A metric fit of one MRCLAM robot's bearings without its odometry (a prototype measured toward a
joint map for dataset 5, which has none; docs/joint.md, "Without odometry: measured").

The odometry is replaced by a kinematic motion prior between consecutive images, the same for
every robot: the relative pose ``X_i^{-1} X_{i+1}`` is ``N((V dt, 0, 0), diag(s)^2)`` with
``s = (c + S_V dt, c + S_LAT dt, c_w + S_W dt)`` (a differential-drive robot moves along its
heading). ``--measure-prior`` prints the odometry's speeds on the datasets that have it, from
which ``V``, ``S_V``, ``S_LAT`` and ``S_W`` below were set (datasets 1-4 and 6; dataset 5 never
used for them).

Starts (``--start``):

* ``incremental`` (the prototype): headings chained from the image-to-image change of the common
  landmarks' bearings (visual rotation), positions stepped forward by ``V dt``; every ``chunk``
  images the new poses are localised against the landmarks placed so far (windows of 40 images,
  landmarks held), landmarks with ``min_rays`` rays and ``min_parallax`` degrees of parallax are
  placed by ray intersection, and Levenberg-Marquardt refits every pose and landmark so far;
  a chunk whose fit leaves more than 3 % of the bearings beyond 4 sigmas (or a median above 1)
  is fitted again without the landmarks it placed, and dropped when that fails too.
* ``truth``: the landmarks' ground truth, poses localised against it, then the same whole
  refit (a diagnostic of the information in the data, not a method); ``--noise M`` moves every
  landmark of that start by normal noise of M metres (seeded), ``--start arena`` draws the
  landmarks uniformly in the arena box instead (``--seeds N`` starts, each a row).

For each run: the landmarks placed, the final fit's whitened bearing residuals (median, share
beyond 4) and its cost (the negative log posterior up to a constant, so that two starts' fits
compare), the landmarks' error after the best similarity transform onto the ground truth
(median, m: states are similarity-invariant) and the share of ordered triplets whose EDC state at
the fitted landmarks is the true one. Ground truth is used for these scores only.

``--save DIR`` keeps each robot's fit (of least cost over ``--chunk`` sizes); ``--agree DIR``
then finds, per dataset, the largest group of robots whose fits agree pairwise (the median misfit
after a similarity, over the configuration's rms radius, at most ``--tolerance``): a check
that needs no ground truth (docs/joint.md); ``--joint DIR`` runs :func:`qfg.joint.solve` over each
dataset's agreeing robots, started from their saved fits, and scores every ordered triplet.

    python experiments/joint_without_odometry.py 2:1 1:1 6:1 5:1 [--start truth] [--chunk 50]
    python experiments/joint_without_odometry.py --chunk 25,50,100 --save DIR 5:1 5:2 ...
    python experiments/joint_without_odometry.py --agree DIR
    python experiments/joint_without_odometry.py --joint DIR
    python experiments/joint_without_odometry.py --measure-prior
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import pathlib
import time

import numpy as np

from qfg import joint as J
from qfg import nonlinear as nl
from qfg import partitions
from qfg.datasets import mrclam
from qfg.geometry import to_frame, wrap_angle
from qfg.harness.studies.mrclam import arena_extent, prepare
from qfg.metrics import brier, log_score, truth_under

#: The kinematic prior (m/s, rad/s; set from --measure-prior on datasets 1-4 and 6: forward speed
#: mean 0.048-0.060, rms 0.056-0.063 m/s; lateral rms 0.0015-0.0017 m/s; turn rms 0.13-0.17 rad/s).
V, S_V, S_LAT, S_W = 0.055, 0.035, 0.01, 0.2
C_XY, C_W = 0.003, 0.01


def kinematic_run(r: J.RobotRun) -> J.RobotRun:
    """``r`` with its odometry replaced by the kinematic prior (module docstring)."""
    dt = np.diff(r.times)
    z = np.column_stack([V * dt, np.zeros_like(dt), np.zeros_like(dt)])
    s = np.column_stack([C_XY + S_V * dt, C_XY + S_LAT * dt, C_W + S_W * dt])
    return dataclasses.replace(r, odometry=z, odometry_sigma=s)


def visual_steps(r: J.RobotRun) -> np.ndarray:
    """(P - 1, 3) start steps: forward ``V dt``, the heading change minus the median change of
    the bearings of the landmarks both images see (0 when they share none)."""
    by_pose = {}
    for p, lm, b in zip(r.bearing_pose.tolist(), r.bearing_landmark.tolist(),
                        r.bearing.tolist(), strict=True):
        by_pose.setdefault(p, {})[lm] = b
    dth = np.zeros(r.n_poses - 1)
    for i in range(r.n_poses - 1):
        a, b = by_pose.get(i, {}), by_pose.get(i + 1, {})
        common = set(a) & set(b)
        if common:
            dth[i] = -np.median([wrap_angle(b[k] - a[k]) for k in common])
    dt = np.diff(r.times)
    return np.column_stack([V * dt, np.zeros_like(dt), dth])


def _window_problem(r, lm_index, s, e, points, start, held=None):
    sel = (r.bearing_pose >= s) & (r.bearing_pose < e)
    j = np.array([lm_index[int(x)] for x in r.bearing_landmark[sel]], dtype=np.intp)
    if held is not None:
        keep = held[j]
        sel[np.flatnonzero(sel)[~keep]] = False
        j = j[keep]
    n = e - s
    pose_prior = ({} if start is None else
                  dict(pose_prior_index=[0], pose_prior=[start], pose_prior_sigma=[0.05, 0.05, 0.1]))
    return nl.BearingProblem(
        n_poses=n, n_points=len(points), bearing_pose=r.bearing_pose[sel] - s, bearing_point=j,
        bearing=r.bearing[sel], sigma_bearing=r.sigma_bearing, between_from=np.arange(n - 1),
        between_to=np.arange(1, n), between=r.odometry[s:e - 1],
        between_sigma=r.odometry_sigma[s:e - 1], point_prior_index=np.arange(len(points)),
        point_prior=points, point_prior_sigma=0.01, **pose_prior)


def localise(r, lm_index, poses, points, held, steps, a, b, window=40, first_starts=None):
    """Poses a..b-1 fitted window by window against the landmarks ``held`` (held by tight
    priors), each window started from the previous one's last pose (or, with
    ``first_starts``, from the best of those poses)."""
    start = None if first_starts is not None else (
        J._chain(poses[a - 1], steps[a - 1:a])[-1] if a > 0 else poses[a])
    for s in range(a, b, window):
        e = min(s + window, b)
        pr = _window_problem(r, lm_index, s, e, points, start, held)
        cands = first_starts if start is None else [start]
        best = None
        for x0 in cands:
            f = nl.fit(pr, J._chain(x0, steps[s:e - 1]), points, max_iterations=50)
            if best is None or f.cost < best.cost:
                best = f
        poses[s:e] = best.poses
        start = J._chain(best.poses[-1], steps[e - 1:e])[-1] if e < b else None


def _bad(f) -> bool:
    rb = np.abs(f.bearing_residuals)
    return bool(rb.size) and (np.mean(rb > 4) > 0.03 or np.median(rb) > 1.0)


def incremental(r, lm_index, *, chunk=50, min_rays=5, min_parallax=15.0):
    """The incremental start (module docstring): (poses, points, placed)."""
    steps = visual_steps(r)
    L = len(lm_index)
    poses = J._chain(np.zeros(3), steps)
    points, have = np.zeros((L, 2)), np.zeros(L, bool)
    a = 0
    for end in list(range(chunk, r.n_poses, chunk)) + [r.n_poses]:
        saved = have.copy(), points.copy(), poses.copy()
        if have.any():
            localise(r, lm_index, poses, points, have, steps, a, end)
        J._init_landmarks(poses, r, lm_index, points, have, upto=end, min_rays=min_rays,
                          min_par=np.deg2rad(min_parallax))
        f = None
        if have.any():
            sub = J._cut(r, end)
            for _ in range(2):
                while True:
                    pr, _, ok = J._problem_of([sub], lm_index, have, r.robot, robust=nl.HUBER_K)
                    f = nl.fit(pr, poses[:end], points[ok], max_iterations=100)
                    far = J._diverged(pr, f)
                    if not far.any():
                        break
                    have[ok[far]] = False
                    if not have.any():
                        f = None
                        break
                new = have & ~saved[0]
                if f is None or not _bad(f) or not new.any():
                    break
                have[new] = False           # again without the landmarks this chunk placed
            if f is not None and not _bad(f):
                poses[:end], points[ok] = f.poses, f.points
            else:
                have[:], points[:], poses[:] = saved
        if end < r.n_poses:
            poses[end - 1:] = J._chain(poses[end - 1], steps[end - 1:])
        a = end
    return poses, points, have


def _similarity_error(A, B) -> float:
    """Median distance (B's units) of A mapped onto B by the best similarity (no reflection)."""
    A0, B0 = A - A.mean(0), B - B.mean(0)
    U, S, Vt = np.linalg.svd(A0.T @ B0)
    D = np.diag([1.0, np.sign(np.linalg.det(U @ Vt))])
    R = (U @ D @ Vt).T
    sc = (S * np.diag(D)).sum() / (A0 ** 2).sum()
    return float(np.median(np.hypot(*((A0 @ R.T) * sc - B0).T)))


def run_one(path, robot, start, chunk, noise=0.0, seed=0):
    ds, _ = prepare(path)
    meas = J.mrclam_runs(ds, [robot], min_move=0.0, min_turn_deg=0.0)
    ids = list(meas.landmark_ids)
    lm_index = {lm: i for i, lm in enumerate(ids)}
    truth = np.asarray(ds.landmark_xy)              # mrclam_runs keeps the dataset's landmark order
    r = kinematic_run(meas.runs[0])
    t0 = time.perf_counter()
    if start in ("truth", "arena"):
        rng = np.random.default_rng(seed)
        if start == "arena":
            e = arena_extent(ds)
            points = np.column_stack([rng.uniform(*e["x"], len(ids)), rng.uniform(*e["y"], len(ids))])
        else:
            points = truth + rng.normal(0.0, noise, truth.shape)
        have = np.ones(len(ids), bool)
        poses = np.zeros((r.n_poses, 3))
        lo, hi = points.min(0), points.max(0)
        grid = [np.array([x, y, th]) for x in np.linspace(lo[0], hi[0], 4)
                for y in np.linspace(lo[1], hi[1], 3)
                for th in np.linspace(-np.pi, np.pi, 8, endpoint=False)]
        localise(r, lm_index, poses, points, have, visual_steps(r), 0, r.n_poses,
                 first_starts=grid)
    else:
        poses, points, have = incremental(r, lm_index, chunk=chunk)
    row = {"dataset": ds.name, "robot": robot, "start": start, "poses": r.n_poses,
           "placed": int(have.sum())}
    if have.sum() >= 3:
        pr, _, ok = J._problem_of([r], lm_index, have, robot, robust=nl.HUBER_K)
        pr = dataclasses.replace(pr, pose_prior=np.array([poses[0]]))
        f = nl.fit(pr, poses, points[ok], max_iterations=200)
        rb = np.abs(f.bearing_residuals)
        P = np.full((len(ids), 2), np.nan)
        P[ok] = f.points
        part = partitions.get("edc")
        tri = np.array([t for t in itertools.permutations(np.flatnonzero(have), 3)])
        same = (part.state_of(to_frame(P[tri[:, 2]], P[tri[:, 0]], P[tri[:, 1]]))
                == part.state_of(to_frame(truth[tri[:, 2]], truth[tri[:, 0]], truth[tri[:, 1]])))
        row["points"], row["poses_fit"] = P, f.poses
        row.update(cost=float(f.cost), median_residual=float(np.median(rb)), beyond_4=float(np.mean(rb > 4)),
                   shape_error_m=_similarity_error(P[ok], truth[ok]),
                   states_right=float(np.mean(same)))
    row["time_s"] = time.perf_counter() - t0
    return row


#: Two robots' fits agree when, after the best similarity on their common landmarks, the median
#: misfit is at most this share of the configuration's rms radius (set on datasets 1-4 and 6).
AGREE = 0.05


def _misfit(A, B) -> float:
    """Median distance of A mapped onto B by the best similarity, over B's rms radius."""
    B0 = B - B.mean(0)
    return _similarity_error(A, B) / float(np.sqrt(np.mean(np.sum(B0 ** 2, axis=1))))


def _agree(A, B, tolerance) -> bool:
    m = np.isfinite(A[:, 0]) & np.isfinite(B[:, 0])
    return bool(m.sum() >= 4) and max(_misfit(A[m], B[m]), _misfit(B[m], A[m])) <= tolerance


def _largest_agreeing(fits: dict, tolerance) -> tuple:
    """The largest group (>= 2) of ``fits`` (robot -> points) that agree pairwise, or ()."""
    names = sorted(fits)
    for k in range(len(names), 1, -1):
        for g in itertools.combinations(names, k):
            if all(_agree(fits[i], fits[j], tolerance) for i, j in itertools.combinations(g, 2)):
                return g
    return ()


def agree(folder, tolerance):
    """Per dataset: the largest group of robots whose fits agree pairwise (``_misfit`` on
    their common landmarks, both ways, at most ``tolerance``), and each member's landmark error
    against the ground truth (the score only)."""
    fits = {d: {k: v[0] for k, v in rob.items()} for d, rob in _saved(folder).items()}
    root = mrclam.data_root()
    print("| dataset | robots fitted | agreeing group | members' landmark error (m) | others' |")
    print("|---|---|---|---|---|")
    for d, rob in sorted(fits.items()):
        ds, _ = prepare(root / f"MRCLAM_Dataset{d}")
        truth = np.asarray(ds.landmark_xy)
        names = sorted(rob)

        best = _largest_agreeing(rob, tolerance)
        errs = {i: _similarity_error(rob[i][np.isfinite(rob[i][:, 0])],
                                     truth[np.isfinite(rob[i][:, 0])]) for i in names}

        print(f"| {d} | {len(names)} | {', '.join(map(str, best)) or 'none'} | "
              f"{', '.join(f'{errs[i]:.2f}' for i in best) or '-'} | "
              f"{', '.join(f'{i}: {errs[i]:.2f}' for i in names if i not in best) or '-'} |")


def _saved(folder) -> dict:
    fits = {}
    for f in sorted(pathlib.Path(folder).glob("d*_r*.npz")):
        z = np.load(f)
        fits.setdefault(int(z["dataset"]), {})[int(z["robot"])] = (
            z["points"], z["poses"] if "poses" in z.files else None)
    return fits


def joint_maps(folder, tolerance, samples=2000):
    """Per dataset: :func:`qfg.joint.solve` over the agreeing robots (their runs with the
    kinematic prior as odometry, each robot started from its saved fit instead of the solver's
    odometry chain), every ordered triplet's state distribution (:func:`qfg.joint.
    triplet_marginals`, the arena prior's states as the floor), scored against the ground
    truth beside the prior alone: mean log p(truth) (clip 1e-4), Brier, truth under 1 %."""
    from qfg.configurations import prior_states
    from qfg.harness.studies.mrclam import make_prior

    root = mrclam.data_root()
    part = partitions.get("edc")
    print("| dataset | robots | method, flags | mean log p(truth) | Brier | truth under 1 % | "
          "prior alone: log p, Brier | s |")
    print("|---|---|---|---|---|---|---|---|")
    for d, saved in sorted(_saved(folder).items()):
        pts = {k: v[0] for k, v in saved.items()}
        group = _largest_agreeing(pts, tolerance)
        ds, _ = prepare(root / f"MRCLAM_Dataset{d}")
        q = prior_states(make_prior(ds, "arena"))
        if not group:
            print(f"| {d} | none agree | - | - | - | - | - | - |")
            continue
        t0 = time.perf_counter()
        meas = J.mrclam_runs(ds, list(group), min_move=0.0, min_turn_deg=0.0)
        runs = tuple(kinematic_run(r) for r in meas.runs)
        starts = {}
        for r in runs:
            P, X = saved[r.robot]
            have = np.isfinite(P[:, 0])
            starts[r.robot] = (X.copy(), np.where(have[:, None], P, 0.0), have, True)
        orig = J._solve_run
        J._solve_run = lambda r, lm_index, _s=starts, **kw: _s[r.robot]   # noqa: E731
        try:
            post = J.solve(J.JointMeasurements(runs, meas.landmark_ids), seed=0)
        finally:
            J._solve_run = orig
        res = J.triplet_marginals(post, prior_states=q, samples=samples, seed=0)
        ids = list(ds.landmark_ids)
        truth = np.asarray(ds.landmark_xy)
        tri = np.array([[ids.index(x) for x in t] for t in res.triplets], dtype=np.intp)
        s_true = part.state_of(to_frame(truth[tri[:, 2]], truth[tri[:, 0]], truth[tri[:, 1]]))
        P = np.asarray(res.probabilities)
        Q = np.broadcast_to(q, P.shape)
        print(f"| {d} | {', '.join(map(str, group))} | {post.method}, {', '.join(post.flags) or '-'} | "
              f"{log_score(P, s_true).mean():.2f} | {brier(P, s_true).mean():.3f} | "
              f"{100 * truth_under(P, s_true).mean():.1f} % | "
              f"{log_score(Q, s_true).mean():.2f}, {brier(Q, s_true).mean():.3f} | "
              f"{time.perf_counter() - t0:.0f} |", flush=True)


def measure_prior():
    for p in mrclam.find_datasets(mrclam.data_root()):
        ds, _ = prepare(p)
        meas = J.mrclam_runs(ds, min_move=0.0, min_turn_deg=0.0)
        z = [np.column_stack([r.odometry, np.diff(r.times)]) for r in meas.runs
             if r.has_odometry]
        if not z:
            print(f"{ds.name}: no odometry")
            continue
        a = np.concatenate(z)
        a = a[a[:, 3] < 1.0]
        fwd, lat, w = (a[:, k] / a[:, 3] for k in range(3))
        print(f"{ds.name}: {len(a)} steps; forward mean {fwd.mean():.3f} rms "
              f"{np.sqrt(np.mean(fwd ** 2)):.3f} m/s, lateral rms {np.sqrt(np.mean(lat ** 2)):.4f}"
              f" m/s, turn rms {np.sqrt(np.mean(w ** 2)):.3f} rad/s")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="*", help="DATASET:ROBOT, e.g. 2:1")
    ap.add_argument("--start", choices=("incremental", "truth", "arena"), default="incremental")
    ap.add_argument("--noise", type=float, default=0.0, help="m, on the truth start's landmarks")
    ap.add_argument("--seeds", type=int, default=1, help="starts per robot (truth with noise, arena)")
    ap.add_argument("--chunk", default="50",
                    help="images per batch; a comma list runs each and adds the fit of least "
                         "cost (a multi-start that needs no ground truth)")
    ap.add_argument("--measure-prior", action="store_true")
    ap.add_argument("--save", help="directory: each robot's kept fit (landmark points, poses, "
                                   "cost), incremental starts only")
    ap.add_argument("--agree", help="directory of --save: the robots of each dataset that agree")
    ap.add_argument("--joint", help="directory of --save: the joint map of each dataset's agreeing "
                                    "robots (qfg.joint.solve started from their fits), scored")
    ap.add_argument("--tolerance", type=float, default=AGREE,
                    help="agreement: median misfit after a similarity over the configuration's "
                         "rms radius")
    a = ap.parse_args(argv)
    if a.measure_prior:
        measure_prior()
        return 0
    if a.agree:
        agree(a.agree, a.tolerance)
        return 0
    if a.joint:
        joint_maps(a.joint, a.tolerance)
        return 0
    root = mrclam.data_root()
    print("| dataset | robot | start | images | landmarks placed | median whitened residual | "
          "beyond 4 | landmark error (m, after similarity) | triplet states right | cost | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    chunks = [int(c) for c in str(a.chunk).split(",")]

    def show(d, rb, start, row):
        print(f"| {d} | {rb} | {start} | {row['poses']} | {row['placed']} | "
              f"{row.get('median_residual', float('nan')):.2f} | "
              f"{row.get('beyond_4', float('nan')):.3f} | "
              f"{row.get('shape_error_m', float('nan')):.3f} | "
              f"{row.get('states_right', float('nan')):.3f} | {row.get('cost', float('nan')):.0f} | "
              f"{row['time_s']:.0f} |", flush=True)

    for spec in a.runs:
        try:
            d, rb = (int(x) for x in spec.split(":"))
        except ValueError:
            ap.error(f"run {spec!r}: expected DATASET:ROBOT, e.g. 2:1")
        rows = []
        if a.start != "incremental":
            for k in range(a.seeds):
                row = run_one(root / f"MRCLAM_Dataset{d}", rb, a.start, 0, a.noise, k)
                show(d, rb, a.start + (f", noise {a.noise:g} m" if a.noise else "")
                     + (f", seed {k}" if a.seeds > 1 else ""), row)
            continue
        for c in chunks:
            row = run_one(root / f"MRCLAM_Dataset{d}", rb, a.start, c)
            rows.append(row)
            show(d, rb, a.start if len(chunks) == 1 else f"{a.start}, chunk {c}", row)
        best = min(rows, key=lambda r: r.get("cost", np.inf))
        if len(rows) > 1:
            show(d, rb, f"least cost of chunks {a.chunk}", best)
        if a.save and "points" in best:
            out = pathlib.Path(a.save)
            out.mkdir(parents=True, exist_ok=True)
            np.savez(out / f"d{d}_r{rb}.npz", points=best["points"], poses=best["poses_fit"],
                     cost=best["cost"], dataset=d, robot=rb)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
