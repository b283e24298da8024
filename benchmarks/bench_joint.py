"""Joint map method (qfg.joint): wall time of the metric solve (per-robot incremental batches,
alignment, joint Levenberg-Marquardt with 3 starts, gtsam.Marginals) and of the triplet states
(1000 samples, every ordered triplet), on simulated trajectory runs at the paper's noise
(``random_trajectory_run``, field of view 150 deg), by number of views (poses of one robot),
landmarks and robots (each robot 80 poses in one world of 8 landmarks); and, when the data are
present (``$QFG_MRCLAM_DIR``), MRCLAM dataset 6 end to end (5 robots, 15 landmarks, 2730
triplets, 2000 samples, no camera states). One run each (seed 0); the note has the machine's
load (1-min average from ``/proc/loadavg``) at the start of the row: time grows with it."""

import os
import time

import numpy as np

from qfg import joint
from qfg.simulation import random_trajectory_run


def _load():
    try:
        return float(open("/proc/loadavg").read().split()[0])
    except OSError:
        return float("nan")


def _sim(runs, samples=1000):
    runs = list(runs)
    rr = [joint.simulated_measurements(r, robot=k).runs[0] for k, r in enumerate(runs)]
    meas = joint.JointMeasurements(tuple(rr), tuple(range(runs[0].n_landmarks)))
    t0 = time.perf_counter()
    post = joint.solve(meas, seed=0)
    t1 = time.perf_counter()
    res = joint.triplet_marginals(post, samples=samples, seed=0)
    t2 = time.perf_counter()
    weak = post.landmark_flags.count("weak")
    return t1 - t0, t2 - t1, len(res.triplets), weak, post


def run():
    rows = []

    def add(name, ts, tm, n, weak, post, load):
        rows.append({"name": name, "value": ts + tm, "unit": "s",
                     "note": f"solve {ts:.2f} s, states {tm:.2f} s ({n} triplets, {weak} weak "
                             f"landmarks resampled); {post.info['n_bearings']} bearings, "
                             f"{post.info['n_poses']} poses; load {load:.1f}"})

    for n in (40, 160, 640):
        load = _load()
        r = random_trajectory_run(np.random.default_rng(0), n_landmarks=8, n_poses=n,
                                  fov_deg=150)
        add(f"views: 1 robot, {n} poses, 8 landmarks", *_sim([r]), load)
    for L in (8, 16, 32):
        load = _load()
        r = random_trajectory_run(np.random.default_rng(1), n_landmarks=L, n_poses=80,
                                  fov_deg=150)
        add(f"landmarks: 1 robot, 80 poses, {L} landmarks", *_sim([r]), load)
    world = random_trajectory_run(np.random.default_rng(2), n_landmarks=8, n_poses=2).landmarks
    for k in (1, 2, 4):
        load = _load()
        rs = [random_trajectory_run(np.random.default_rng(10 + i), n_poses=80, fov_deg=150,
                                    landmarks=world) for i in range(k)]
        add(f"robots: {k} x 80 poses, 8 landmarks", *_sim(rs), load)
    root = os.environ.get("QFG_MRCLAM_DIR")
    if root and os.path.isdir(os.path.join(root, "MRCLAM_Dataset6")):
        from qfg.datasets import mrclam
        from qfg.datasets.mrclam.joint_map import mrclam_marginals

        load = _load()
        ds = mrclam.load(os.path.join(root, "MRCLAM_Dataset6"))
        t0 = time.perf_counter()
        res = mrclam_marginals(ds, samples=2000, seed=0)
        t = time.perf_counter() - t0
        p = res.posterior
        rows.append({"name": "MRCLAM dataset 6, 5 robots, end to end", "value": t, "unit": "s",
                     "target": "<= 120",
                     "note": f"{len(res.triplets.triplets)} triplets; {p.info['n_bearings']} "
                             f"bearings, {p.info['n_poses']} poses; load {load:.1f}"})
    else:
        print("   MRCLAM dataset 6 row skipped: set QFG_MRCLAM_DIR to the directory holding "
              "MRCLAM_Dataset6", flush=True)
    return rows
