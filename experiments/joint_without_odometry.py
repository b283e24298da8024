"""The joint map of MRCLAM runs without odometry (docs/joint.md, "Without odometry").

Dataset 5 has no odometry; on datasets 1-4 and 6 (development) the odometry is withheld. Each
dataset's robots are solved by :func:`qfg.joint.solve` with the kinematic motion prior in place
of the odometry (:mod:`qfg.joint_start`: starts at batches of 25, 50 and 100 images, the least
cost kept per robot, robots kept when their maps agree in shape), every image a pose
(``mrclam_runs(min_move=0, min_turn_deg=0)``). Printed per dataset:

* each robot's flag, the batch size of its kept start, and its own map's median landmark error
  after the best similarity onto the ground truth (m; states are similarity-invariant);
* the joint map's every ordered triplet (``triplet_marginals``, the arena prior's states as the
  floor) scored against the ground truth beside the prior alone: mean log p(truth) (clip 1e-4),
  Brier, truth under 1 %, and the top-probability calibration error (10 bins);
* the landmarks' z: the Mahalanobis distance of each landmark's ground truth (mapped into the
  map's frame by the best similarity) under its marginal covariance (the best mode), median and
  90th percentile (a calibrated 2-D Gaussian: 1.18 and 2.15).

Ground truth is used for these scores only. ``--measure-prior`` prints the odometry's speeds on
the datasets that have it, from which :class:`qfg.joint_start.KinematicPrior`'s defaults were
set (datasets 1-4 and 6; dataset 5 never used for them). The diagnostics of the prototype
(starts from the ground truth and from the arena, the per-robot tables at each batch size) are
in this file at commit 4c7311c.

    python experiments/joint_without_odometry.py 5 1 2 3 4 6 [--save DIR]
    python experiments/joint_without_odometry.py --measure-prior
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import time

import numpy as np

from qfg import joint as J
from qfg import partitions
from qfg.configurations import prior_states
from qfg.datasets import mrclam
from qfg.geometry import to_frame
from qfg.harness.studies.mrclam import make_prior, prepare
from qfg.joint_start import similarity
from qfg.metrics import brier, expected_calibration_error, log_score, truth_under


def _error_m(P, truth) -> float:
    """Median landmark error (m) of ``P`` (NaN rows: not placed) after the best similarity."""
    m = np.isfinite(P[:, 0])
    if m.sum() < 3:
        return float("nan")
    s, R, t = similarity(P[m], truth[m])
    return float(np.median(np.hypot(*(s * P[m] @ R.T + t - truth[m]).T)))


def _landmark_z(post, truth) -> np.ndarray:
    """Per constrained landmark of the best mode: the Mahalanobis distance of the ground truth
    (mapped into the map's frame by the best similarity) from the posterior mean, under the
    mode's 2x2 marginal covariance (calibrated: median 1.18, 90th percentile 2.15)."""
    if not post.modes:
        return np.zeros(0)
    m = post.modes[0]
    ok = np.flatnonzero(post.constrained)
    s, R, t = similarity(truth[ok], m.points[ok])
    e = s * truth[ok] @ R.T + t - m.points[ok]
    C = m.covariance.reshape(ok.size, 2, ok.size, 2)[np.arange(ok.size), :, np.arange(ok.size), :]
    return np.sqrt(np.einsum("ni,nij,nj->n", e, np.linalg.inv(C), e))


def joint_map(d: int, samples: int = 2000, save=None) -> dict:
    root = mrclam.data_root()
    ds, _ = prepare(root / f"MRCLAM_Dataset{d}")
    t0 = time.perf_counter()
    meas = J.mrclam_runs(ds, min_move=0.0, min_turn_deg=0.0)
    runs = tuple(dataclasses.replace(r, odometry=None, odometry_sigma=None) for r in meas.runs)
    post = J.solve(J.JointMeasurements(runs, meas.landmark_ids), seed=0)
    q = prior_states(make_prior(ds, "arena"))
    res = J.triplet_marginals(post, prior_states=q, samples=samples, seed=0)
    wall = time.perf_counter() - t0
    ids = list(ds.landmark_ids)
    truth = np.asarray(ds.landmark_xy)
    tri = np.array([[ids.index(x) for x in t] for t in res.triplets], dtype=np.intp)
    s_true = partitions.get("edc").state_of(
        to_frame(truth[tri[:, 2]], truth[tri[:, 0]], truth[tri[:, 1]]))
    P = np.asarray(res.probabilities)
    Q = np.broadcast_to(q, P.shape)
    maps = post.info.get("robot_maps", {})
    starts = post.info.get("kinematic_starts", {})
    out = {"dataset": d, "method": post.method, "flags": list(post.flags),
           "robots": {str(k): {"flag": v, "chunk": starts.get(k, {}).get("chunk"),
                               "error_m": _error_m(maps[k], truth) if k in maps else None}
                      for k, v in post.robot_flags.items()},
           "log_score": float(log_score(P, s_true).mean()), "brier": float(brier(P, s_true).mean()),
           "truth_under_1pct": float(truth_under(P, s_true).mean()),
           "ece": float(expected_calibration_error(P, s_true)),
           "prior_log_score": float(log_score(Q, s_true).mean()),
           "prior_brier": float(brier(Q, s_true).mean()), "n": int(len(s_true)), "time_s": wall}
    z = _landmark_z(post, truth)
    out["landmark_z"] = z.tolist()
    if save:
        p = pathlib.Path(save)
        p.mkdir(parents=True, exist_ok=True)
        (p / f"d{d}.json").write_text(json.dumps(out, indent=1))
        np.savez(p / f"d{d}.npz", probabilities=P, truth=s_true, triplets=np.asarray(res.triplets))
    return out


def _zs(z) -> str:
    return f"{np.median(z):.2f}, {np.quantile(z, 0.9):.2f}" if len(z) else "-"


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
    ap.add_argument("datasets", nargs="*", type=int, help="MRCLAM dataset numbers, e.g. 5 1 3")
    ap.add_argument("--measure-prior", action="store_true")
    ap.add_argument("--samples", type=int, default=2000)
    ap.add_argument("--save", help="directory: each dataset's row (json) and its triplets' "
                                   "probabilities and true states (npz)")
    a = ap.parse_args(argv)
    if a.measure_prior:
        measure_prior()
        return 0
    bad = [d for d in a.datasets if d not in range(1, 7)]
    if bad:
        ap.error(f"datasets {bad}: expected MRCLAM dataset numbers 1-6")
    print("| dataset | answer, flags | robots: flag, batch, own map's error (m) | mean log p(truth) "
          "| Brier | truth under 1 % | calibration error | landmarks' z: median, 90 % | "
          "prior alone: log p, Brier | s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for d in a.datasets:
        o = joint_map(d, a.samples, a.save)
        rob = "; ".join(f"{k}: {v['flag']}"
                        + (f", {v['chunk']}" if v["chunk"] else "")
                        + (f", {v['error_m']:.2f}" if v["error_m"] is not None else "")
                        for k, v in o["robots"].items())
        print(f"| {d} | {o['method']}, {', '.join(o['flags']) or '-'} | {rob} | "
              f"{o['log_score']:.2f} | {o['brier']:.3f} | {100 * o['truth_under_1pct']:.1f} % | "
              f"{o['ece']:.3f} | {_zs(o['landmark_z'])} | "
              f"{o['prior_log_score']:.2f}, {o['prior_brier']:.3f} | "
              f"{o['time_s']:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
