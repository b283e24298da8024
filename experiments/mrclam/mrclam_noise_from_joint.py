"""The noise of every MRCLAM dataset measured against its joint map instead of motion capture.

Datasets 1-5 have no motion capture, so the noise the single-triplet solvers assume (measured on
dataset 6, docs/mrclam.md) could not be checked there. The joint map (`qfg.joint.solve`, every
usable view a pose: ``min_move=0``, ``min_turn_deg=0``) fits every robot's bearings and odometry
at once; its poses and landmarks stand in for the capture
(`qfg.datasets.mrclam.joint_map.mrclam_reference`), and
`qfg.datasets.mrclam.measure_noise` measures against them exactly as it measures against motion
capture. The fit absorbs part of the noise (each pose is fitted to the bearings it explains), so
the stand-in is checked on dataset 6, where both references exist: rows ``capture`` and
``joint`` of dataset 6 side by side say how far the stand-in reads low or high. The clock
offsets are not searched (the map's poses are at the measurement stamps by construction; the
odometry is read with the loader's lead, as the map read it).

Per dataset and reference: the bearing residuals' robust std and ``sigma90``, the share beyond
2 deg, the maximum-likelihood fit of the solvers' tail mixture (``BearingTail``:
sigma, share, scale, outlier; the solvers' bearing likelihood, median removed), the
within-view ``sigma90``, the odometry's direction of travel per step and per pass (median and
``sigma90``), the log ratio of consecutive step lengths (robust std), and the persistence of
the bearing errors (Pearson at 0.5-3 s and 10-30 s).

    QFG_MRCLAM_DIR=... python experiments/mrclam/mrclam_noise_from_joint.py 6 1 2 3 4 5 \\
        [--csv FILE] [--per-robot]

Backs docs/mrclam.md, "Datasets 1-5: the noise against the joint map". Run from the repository
root as above (``QFG_MRCLAM_DIR``: the directory holding the MRCLAM_Dataset* directories).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import sys

import numpy as np
from scipy.optimize import minimize
from scipy.special import expit, logit

from qfg import joint
from qfg.datasets import mrclam
from qfg.datasets.mrclam import landmark_rows, truth_bearing_residuals
from qfg.datasets.mrclam.joint_map import mrclam_reference, mrclam_runs
from qfg.harness.studies.mrclam import prepare
from qfg.solvers.common.likelihood import BearingTail, log_bearing

TAIL_AT = np.deg2rad(2.0)


def bearing_residuals(ds, offset: float) -> np.ndarray:
    """Every covered landmark row's measured minus reference bearing (radians), as
    `measure_noise` computes them."""
    out = []
    for rd in ds.robots.values():
        if rd.groundtruth is not None:
            t, phi, lxy, _, _ = landmark_rows(ds, rd)
            r, ok = truth_bearing_residuals(rd, t, phi, lxy, offset)
            out.append(r[ok])
    return np.concatenate(out)


def fit_tail(r: np.ndarray):
    """Maximum-likelihood (sigma, BearingTail) of the solvers' bearing mixture for residuals r."""
    r = r - np.median(r)
    s0 = 1.4826 * np.median(np.abs(r))

    def unpack(x):
        sigma, scale = np.exp(x[0]), 1.0 + np.exp(x[2])
        share, outlier = 0.98 * expit(x[1]), 0.01 * expit(x[3])
        return sigma, BearingTail(share=float(share), scale=float(scale), outlier=float(outlier))

    def nll(x):
        s, t = unpack(x)
        return -float(np.sum(log_bearing(r, s, t)))

    x0 = np.array([np.log(s0), logit(0.2 / 0.98), np.log(2.0), logit(0.1)])
    res = minimize(nll, x0, method="Nelder-Mead", options={"maxiter": 4000, "xatol": 1e-6,
                                                           "fatol": 1e-3})
    return unpack(res.x)


def row(d, ref, m, r, extra=""):
    sigma, tail = fit_tail(r)
    lag = {(lo, hi): p for lo, hi, _, p, _ in m.bearing_lag_correlation}

    def deg(s, attr):
        # a robot without odometry has no steps: no number, not the all-zero summary
        return float(np.degrees(getattr(s, attr))) if s.n else float("nan")

    return {
        "dataset": d, "reference": ref, "robots": " ".join(map(str, m.robots)),
        "bearings": m.bearing.n, "bearing_robust_deg": deg(m.bearing, "robust_std"),
        "bearing_sigma90_deg": deg(m.bearing, "sigma90"),
        "beyond_2deg_pct": 100 * float(np.mean(np.abs(r - np.median(r)) > TAIL_AT)),
        "tail_sigma_deg": float(np.degrees(sigma)), "tail_share": tail.share, "tail_scale": tail.scale,
        "tail_outlier": tail.outlier, "within_view_sigma90_deg": deg(m.bearing_within_view, "sigma90"),
        "heading_steps": m.heading_step.n,
        "heading_step_median_deg": deg(m.heading_step, "median"),
        "heading_step_sigma90_deg": deg(m.heading_step, "sigma90"),
        "heading_pass_median_deg": deg(m.heading_pass, "median"),
        "heading_pass_sigma90_deg": deg(m.heading_pass, "sigma90"),
        "ratio_robust_pct": 100 * m.distance_ratio.robust_std if m.distance_ratio.n else np.nan,
        "lag_0.5-3s": lag.get((0.5, 3.0), np.nan), "lag_10-30s": lag.get((10.0, 30.0), np.nan),
        "note": extra,
    }


COLUMNS = [("dataset", "{}"), ("reference", "{}"), ("robots", "{}"), ("bearings", "{}"),
           ("bearing_robust_deg", "{:.3f}"), ("bearing_sigma90_deg", "{:.3f}"),
           ("beyond_2deg_pct", "{:.2f}"), ("tail_sigma_deg", "{:.3f}"), ("tail_share", "{:.3f}"),
           ("tail_scale", "{:.2f}"), ("tail_outlier", "{:.4f}"),
           ("within_view_sigma90_deg", "{:.3f}"), ("heading_steps", "{}"),
           ("heading_step_median_deg", "{:+.2f}"),
           ("heading_step_sigma90_deg", "{:.2f}"), ("heading_pass_median_deg", "{:+.2f}"),
           ("heading_pass_sigma90_deg", "{:.2f}"), ("ratio_robust_pct", "{:.1f}"),
           ("lag_0.5-3s", "{:+.3f}"), ("lag_10-30s", "{:+.3f}"), ("note", "{}")]


def cell(value, fmt: str) -> str:
    return "-" if isinstance(value, float) and not np.isfinite(value) else fmt.format(value)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("datasets", nargs="+", type=int)
    ap.add_argument("--csv", help="also write the rows to this file")
    ap.add_argument("--per-robot", action="store_true",
                    help="also one joint row per solved robot (only its ground truth kept)")
    ap.add_argument("--root", default=None,
                    help="the folder of the MRCLAM_Dataset* folders (default $QFG_MRCLAM_DIR)")
    a = ap.parse_args(argv)
    print("| " + " | ".join(c for c, _ in COLUMNS) + " |")
    print("|" + "---|" * len(COLUMNS), flush=True)
    rows = []
    for d in a.datasets:
        ds, _ = prepare(mrclam.data_root(a.root) / f"MRCLAM_Dataset{d}")
        refs = []
        if any(rd.groundtruth is not None for rd in ds.robots.values()):
            m = mrclam.measure_noise(ds)
            refs.append(("capture", m, bearing_residuals(ds, m.measurement_offset), ""))
        meas = mrclam_runs(ds, min_move=0.0, min_turn_deg=0.0)
        post = joint.solve(meas, seed=0)
        pseudo = mrclam_reference(ds, post, meas)
        m = mrclam.measure_noise(pseudo, offsets=[0.0])
        flags = ",".join(f"{k}:{v}" for k, v in sorted(post.robot_flags.items()) if v != "ok")
        refs.append(("joint", m, bearing_residuals(pseudo, 0.0),
                     " ".join(x for x in (flags, ",".join(post.flags)) if x)))
        for n in sorted(pseudo.robots) if a.per_robot else ():
            if pseudo.robot(n).groundtruth is None:
                continue
            one = dataclasses.replace(pseudo, robots={
                k: rd if k == n else dataclasses.replace(rd, groundtruth=None)
                for k, rd in pseudo.robots.items()})
            refs.append((f"joint, robot {n}", mrclam.measure_noise(one, offsets=[0.0]),
                         bearing_residuals(one, 0.0), ""))
        for ref, m, r, note in refs:
            out = row(d, ref, m, r, note)
            rows.append(out)
            print("| " + " | ".join(cell(out[c], f) for c, f in COLUMNS) + " |", flush=True)
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
