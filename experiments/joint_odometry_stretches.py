"""The joint map's odometry model over stretches of many keyframe steps (docs/joint.md, "What it
does not do").

Each step's noise (:data:`qfg.joint.ODOMETRY_NOISE`, independent between steps) was fitted to
single keyframe steps. Over a stretch of N steps the dead-reckoned relative pose has, under that
model, the covariance propagated step by step (first order, the heading's lever arm included:
``S <- Jx S Jx' + Ju diag(sigma^2) Ju'``). Against motion capture, the squared Mahalanobis
distance z^2 of the stretch's error (x, y in the start pose's frame, heading) is chi-square with 3
degrees of freedom when the model holds: median 2.37, 90th percentile 6.25, 1 % beyond 11.34.
Printed per dataset (robots with odometry and motion capture, which only dataset 6 has for its
robots; stretches start every N / 2 steps):
N, the number of stretches, the median and 90th percentile of z^2, the share beyond 11.34.

    python experiments/joint_odometry_stretches.py 6 --steps 1 3 10 30 100 300
"""

from __future__ import annotations

import argparse

import numpy as np

from qfg import joint
from qfg.geometry import wrap_angle
from qfg.harness.studies.mrclam import dataset_dirs, prepare
from qfg.nonlinear import _relative

CHI2_3_99 = 11.345  # chi-square, 3 dof, 99th percentile


def stretch_z2(run, gt, ok, n: int) -> np.ndarray:
    """z^2 of every stretch of ``n`` steps of one robot's keyframes (starting every n / 2)."""
    out = []
    for i in range(0, run.n_poses - n, max(1, n // 2)):
        if not (ok[i] and ok[i + n]):
            continue
        p, th, S = np.zeros(2), 0.0, np.zeros((3, 3))
        for u, s in zip(run.odometry[i:i + n], run.odometry_sigma[i:i + n], strict=True):
            c, sn = np.cos(th), np.sin(th)
            R = np.array([[c, -sn], [sn, c]])
            Jx = np.eye(3)
            Jx[:2, 2] = np.array([[-sn, -c], [c, -sn]]) @ u[:2]
            Ju = np.eye(3)
            Ju[:2, :2] = R
            S = Jx @ S @ Jx.T + Ju @ np.diag(s ** 2) @ Ju.T
            p, th = p + R @ u[:2], th + u[2]
        g = _relative(gt[i][None], gt[i + n][None])[0]
        e = np.array([p[0] - g[0], p[1] - g[1], wrap_angle(th - g[2])])
        out.append(float(e @ np.linalg.solve(S, e)))
    return np.array(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("datasets", nargs="*", type=int, default=[6])
    ap.add_argument("--steps", type=int, nargs="+", default=[1, 3, 10, 30, 100, 300])
    ap.add_argument("--data", default="")
    a = ap.parse_args(argv)
    print("| dataset | N steps | stretches | z^2 median (2.37) | z^2 p90 (6.25) | beyond 11.34 (1 %) |")
    print("|---|---|---|---|---|---|")
    for d in dataset_dirs(a.data, a.datasets):
        ds, _ = prepare(d)
        runs = [r for r in joint.mrclam_runs(ds).runs
                if r.odometry is not None and ds.robot(r.robot).groundtruth is not None]
        if not runs:
            print(f"| {ds.name[14:]} | (no robot with odometry and ground truth) | | | | |")
            continue
        for n in a.steps:
            z2 = np.concatenate([stretch_z2(r, *ds.robot(r.robot).groundtruth_poses(r.times), n)
                                 for r in runs])
            if not z2.size:
                continue
            print(f"| {ds.name[14:]} | {n} | {z2.size} | {np.median(z2):.2f} | "
                  f"{np.percentile(z2, 90):.2f} | {100 * np.mean(z2 > CHI2_3_99):.1f} % |",
                  flush=True)


if __name__ == "__main__":
    main()
