"""The joint map's odometry model over stretches of many keyframe steps (docs/joint.md, "What it
does not do").

Each step's noise (:data:`qfg.joint.ODOMETRY_NOISE`, independent between steps) was fitted to
single keyframe steps, and the map uses it as GTSAM's ``BetweenFactorPose2`` does: the error of a
step is ``Logmap(z^-1 h)``, normal with the step's sigmas. Over a stretch of N steps the
dead-reckoned relative pose ``D = z_1 ... z_N`` then has, to first order, the covariance GTSAM's
``Pose2.compose`` Jacobians carry step by step (``S <- H1 S H1' + H2 diag(sigma^2) H2'``), and
the stretch's error against motion capture ``G`` is ``D.localCoordinates(G)``. Its squared
Mahalanobis distance z^2 is chi-square with 3 degrees of freedom when the model holds: median
2.37, 90th percentile 6.25, 1 % beyond 11.34. Over long stretches the first-order covariance is
no longer exact (the heading's uncertainty bends the position's), so the same statistic is also
computed on poses drawn from the model itself (``--draws`` runs of each robot, each step
``h = z Exp(xi)``, ``xi ~ N(0, diag(sigma^2))``, from the first pose): the real stretches are
inside the model where their z^2 is no larger than the model's own draws give.
Printed per dataset (robots with odometry and motion capture, which only dataset 6 has for its
robots; stretches start every N / 2 steps):
N, the number of stretches, the median and 90th percentile of z^2 and the share beyond 11.34,
for the real stretches and for the model's draws.

    python experiments/joint/joint_odometry_stretches.py 6 --steps 1 3 10 30 100 300

Run from the repository root as above (MRCLAM data: ``$QFG_MRCLAM_DIR`` or ``--data DIR``).
"""

from __future__ import annotations

import argparse

import gtsam
import numpy as np

from qfg.datasets.mrclam.joint_map import mrclam_runs
from qfg.harness.studies.mrclam import dataset_dirs, prepare

CHI2_3_99 = 11.345  # chi-square, 3 dof, 99th percentile


def stretch_z2(run, gt, ok, n: int) -> np.ndarray:
    """z^2 of every stretch of ``n`` steps of one robot's keyframes (starting every n / 2)."""
    out = []
    for i in range(0, run.n_poses - n, max(1, n // 2)):
        if not (ok[i] and ok[i + n]):
            continue
        D, S = gtsam.Pose2(), np.zeros((3, 3))
        H1, H2 = np.zeros((3, 3), order="F"), np.zeros((3, 3), order="F")
        for u, s in zip(run.odometry[i:i + n], run.odometry_sigma[i:i + n], strict=True):
            D = D.compose(gtsam.Pose2(*u), H1, H2)
            S = H1 @ S @ H1.T + H2 @ np.diag(s ** 2) @ H2.T
        e = D.localCoordinates(gtsam.Pose2(*gt[i]).between(gtsam.Pose2(*gt[i + n])))
        out.append(float(e @ np.linalg.solve(S, e)))
    return np.array(out)


def model_poses(run, rng) -> np.ndarray:
    """(P, 3) poses of ``run`` drawn from the map's odometry model (each step ``z Exp(xi)``)."""
    xi = rng.normal(0.0, run.odometry_sigma)
    X = [gtsam.Pose2()]
    for u, e in zip(run.odometry, xi, strict=True):
        X.append(X[-1].compose(gtsam.Pose2(*u)).compose(gtsam.Pose2.Expmap(e)))
    return np.array([[p.x(), p.y(), p.theta()] for p in X])


def _cells(z2) -> str:
    return (f"{np.median(z2):.2f} | {np.percentile(z2, 90):.2f} | "
            f"{100 * np.mean(z2 > CHI2_3_99):.1f} %")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("datasets", nargs="*", type=int, default=[6])
    ap.add_argument("--steps", type=int, nargs="+", default=[1, 3, 10, 30, 100, 300])
    ap.add_argument("--data", default="")
    ap.add_argument("--draws", type=int, default=10, help="model draws per robot (0: none)")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    print("| dataset | N steps | stretches | z^2 median (2.37) | z^2 p90 (6.25) | beyond 11.34 (1 %) "
          "| model's draws: stretches | median | p90 | beyond 11.34 |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for d in dataset_dirs(a.data, a.datasets):
        ds, _ = prepare(d)
        runs = [r for r in mrclam_runs(ds).runs
                if r.odometry is not None and ds.robot(r.robot).groundtruth is not None]
        if not runs:
            print(f"| {ds.name[14:]} | (no robot with odometry and ground truth) | | | | | | | | |")
            continue
        rng = np.random.default_rng(a.seed)
        drawn = [(r, model_poses(r, rng)) for r in runs for _ in range(a.draws)]
        for n in a.steps:
            z2 = np.concatenate([stretch_z2(r, *ds.robot(r.robot).groundtruth_poses(r.times), n)
                                 for r in runs])
            if not z2.size:
                continue
            m2 = np.concatenate([stretch_z2(r, X, np.ones(len(X), bool), n) for r, X in drawn]
                                + [np.zeros(0)])
            model = f"{m2.size} | {_cells(m2)}" if m2.size else "| | |"
            print(f"| {ds.name[14:]} | {n} | {z2.size} | {_cells(z2)} | {model} |", flush=True)


if __name__ == "__main__":
    main()
