"""Each robot's own start without odometry, with and without moving its poses off the landmarks
they were fitted onto (docs/joint.md, "Without odometry": "A pose fitted onto a landmark is moved off it").

For each robot of the given MRCLAM datasets (odometry withheld, every image a pose, as
``experiments/joint/joint_without_odometry.py``) and each batch size of
:func:`qfg.joint.start.kinematic_start` (25, 50, 100 images), the start's final fit, then
:func:`qfg.joint.start.escape_close` on it; printed per start: the fit's robust cost before and
after, the bearings found too close and those left out, the robot's own map's median landmark
error (m, after the best similarity onto the ground truth) before and after, and the robot
check of :func:`qfg.joint.solve` (median |whitened bearing residual|, share beyond the outlier
limit) before and after. ``solve`` keeps, per robot, the start of least cost; ground truth is
used for the errors only.

Run from the repository root (MRCLAM data: ``$QFG_MRCLAM_DIR``)::

    python experiments/joint/joint_start_escape.py 6 4
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from joint_without_odometry import _error_m

from qfg import joint as J
from qfg import nonlinear as nl
from qfg.datasets import mrclam
from qfg.datasets.mrclam.joint_map import mrclam_runs
from qfg.harness.studies.mrclam import prepare
from qfg.joint import start as S
from qfg.joint.solver import robot_checks


def starts(d: int, chunks=(25, 50, 100)) -> list[dict]:
    ds, _ = prepare(mrclam.data_root() / f"MRCLAM_Dataset{d}")
    meas = mrclam_runs(ds, min_move=0.0, min_turn_deg=0.0)
    lm_index = {lid: i for i, lid in enumerate(meas.landmark_ids)}
    truth = np.asarray(ds.landmark_xy)
    out = []
    for run in meas.runs:
        r = S.kinematic_run(dataclasses.replace(run, odometry=None, odometry_sigma=None),
                            S.KINEMATIC)
        for ch in chunks:
            t = time.perf_counter()
            poses, points, have, fit = S.kinematic_start(r, lm_index, chunk=ch)
            row = {"dataset": d, "robot": r.robot, "chunk": ch}
            if fit is not None:
                pr, offs, ok = S.problem_of([r], lm_index, have, r.robot, robust=nl.HUBER_K,
                                            anchor=fit.poses[0])
                f0 = nl.fit(pr, fit.poses, fit.points)
                _, f1, dropped, close = S.escape_close(pr, f0, S.TOO_CLOSE, 200)
                before, after = np.full_like(truth, np.nan), np.full_like(truth, np.nan)
                before[ok], after[ok] = f0.points, f1.points
                c0 = robot_checks(pr, f0, offs, [r], J.OUTLIER)[r.robot]
                c1 = robot_checks(pr, f1, offs, [r], J.OUTLIER)[r.robot]
                row.update(cost=(f0.cost, f1.cost), close=close, dropped=dropped,
                           error_m=(_error_m(before, truth), _error_m(after, truth)),
                           check=(tuple(map(float, c0)), tuple(map(float, c1))))
            row["s"] = time.perf_counter() - t
            out.append(row)
            print(_line(row), flush=True)
    return out


def _line(r) -> str:
    if "cost" not in r:
        return f"| {r['dataset']} | {r['robot']} | {r['chunk']} | no fit | | | | |"
    (a, b), (e0, e1), (c0, c1) = r["cost"], r["error_m"], r["check"]
    return (f"| {r['dataset']} | {r['robot']} | {r['chunk']} | {a:.0f} -> {b:.0f} | "
            f"{r['close']} / {r['dropped']} | {e0:.2f} -> {e1:.2f} | "
            f"{c0[0]:.2f}, {c0[1]:.3f} -> {c1[0]:.2f}, {c1[1]:.3f} | {r['s']:.0f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("datasets", nargs="+", type=int, help="MRCLAM dataset numbers, e.g. 6 4")
    args = ap.parse_args()
    print("| dataset | robot | batch | cost | too close / left out | own map's error (m) | "
          "check: median, beyond | s |")
    print("|---|---|---|---|---|---|---|---|")
    for d in args.datasets:
        starts(d)


if __name__ == "__main__":
    main()
