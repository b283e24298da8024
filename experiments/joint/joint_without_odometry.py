"""The joint map of MRCLAM runs without odometry (docs/joint.md, "Without odometry").

Dataset 5 has no odometry; on datasets 1-4 and 6 (development) the odometry is withheld. Each
dataset's robots are solved by :func:`qfg.joint.solve` with the kinematic motion prior in place
of the odometry (:mod:`qfg.joint.start`: starts at batches of 25, 50 and 100 images, the least
cost kept per robot, robots kept when their maps agree in shape), every image a pose
(``mrclam_runs(min_move=0, min_turn_deg=0)``). Printed per dataset:

* each robot's flag, the batch size of its kept start, and its own map's median landmark error
  after the best similarity onto the ground truth (m; states are similarity-invariant);
* the joint map's every ordered triplet (``triplet_marginals``, the arena prior's states as the
  floor) scored against the ground truth beside the prior alone: mean log p(truth) (clip 1e-4),
  Brier, truth under 1 %, and the top-probability calibration error (10 bins);
* the landmarks' z: the Mahalanobis distance of each landmark's ground truth (mapped into the
  map's frame by the best similarity) under its marginal covariance (the best mode), median and
  90th percentile (a calibrated 2-D Gaussian: 1.18 and 2.15);
* the AB-frame z^2: per ordered triplet, the squared Mahalanobis distance of the truth's C in
  the frame A = (0, 0), B = (0, 1) under the posterior's samples of it (free of the map's gauge
  and scale; calibrated: chi-square with 2 dof, median 1.39), median; and the map's
  overdispersion (:func:`qfg.joint.overdispersion`, no ground truth);
* a second table: each covariance rule (fixed factors x1 ... x16 and ``auto``) applied to the
  same solve, mean log p(truth) / truth under 1 % / ECE (the first table is the library's
  default rule, :data:`qfg.joint.KINEMATIC_INFLATE`).

Ground truth is used for these scores only. ``--measure-prior`` prints the odometry's speeds on
the datasets that have it, from which :class:`qfg.joint.start.KinematicPrior`'s defaults were
set (datasets 1-4 and 6; dataset 5 never used for them). The diagnostics of the prototype
(starts from the ground truth and from the arena, the per-robot tables at each batch size) are
in this file at commit 4c7311c.

    python experiments/joint/joint_without_odometry.py 5 1 2 3 4 6 [--save DIR]
    python experiments/joint/joint_without_odometry.py --measure-prior

Run from the repository root as above (MRCLAM data: ``$QFG_MRCLAM_DIR``).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import pathlib
import time

import numpy as np

from qfg import joint as J
from qfg import partitions
from qfg.configurations import prior_states
from qfg.datasets import mrclam
from qfg.datasets.mrclam.joint_map import mrclam_runs
from qfg.geometry import to_frame
from qfg.harness.studies.mrclam import make_prior, prepare
from qfg.joint.start import apply_similarity, similarity
from qfg.metrics import brier, expected_calibration_error, log_score, truth_under


def _error_m(P, truth) -> float:
    """Median landmark error (m) of ``P`` (NaN rows: not placed) after the best similarity."""
    m = np.isfinite(P[:, 0])
    if m.sum() < 3:
        return float("nan")
    moved = apply_similarity(P[m], similarity(P[m], truth[m]))
    return float(np.median(np.hypot(*(moved - truth[m]).T)))


def _landmark_z(post, truth) -> np.ndarray:
    """Per constrained landmark of the best mode: the Mahalanobis distance of the ground truth
    (mapped into the map's frame by the best similarity) from the posterior mean, under the
    mode's 2x2 marginal covariance (calibrated: median 1.18, 90th percentile 2.15)."""
    if not post.modes:
        return np.zeros(0)
    m = post.modes[0]
    ok = np.flatnonzero(post.constrained)
    e = apply_similarity(truth[ok], similarity(truth[ok], m.points[ok])) - m.points[ok]
    C = m.covariance.reshape(ok.size, 2, ok.size, 2)[np.arange(ok.size), :, np.arange(ok.size), :]
    return np.sqrt(np.einsum("ni,nij,nj->n", e, np.linalg.inv(C), e))


def _ab_z2(post, truth, ids, samples: int = 2000) -> np.ndarray:
    """Per ordered triplet of constrained landmarks: the squared Mahalanobis distance of the
    truth's C in the AB frame under the posterior's mean and covariance of it
    (:func:`qfg.joint.ab_frame_z2`; a calibrated posterior: chi-square with 2 dof, median
    1.39)."""
    ok = np.flatnonzero(post.constrained)
    tri = np.array(list(itertools.permutations(ok.tolist(), 3)), dtype=np.intp).reshape(-1, 3)
    if not len(tri) or post.method == "none":
        return np.zeros(0)
    return J.ab_frame_z2(post, truth, np.asarray(ids)[tri].tolist(), samples, 0)


def _scores(post, q, truth, ids, samples):
    res = J.triplet_marginals(post, prior_states=q, samples=samples, seed=0)
    tri = np.array([[ids.index(x) for x in t] for t in res.triplets], dtype=np.intp)
    s_true = partitions.get("edc").state_of(
        to_frame(truth[tri[:, 2]], truth[tri[:, 0]], truth[tri[:, 1]]))
    P = np.asarray(res.probabilities)
    return P, s_true, np.asarray(res.triplets), {"log_score": float(log_score(P, s_true).mean()),
                       "brier": float(brier(P, s_true).mean()),
                       "truth_under_1pct": float(truth_under(P, s_true).mean()),
                       "ece": float(expected_calibration_error(P, s_true))}


def joint_map(d: int, samples: int = 2000, save=None, factors=(1.0, 2.0, 4.0, 8.0, 16.0)) -> dict:
    """Solve dataset ``d`` without odometry once with the Laplace covariance as it is
    (``inflate_kinematic=1``), then score it under each covariance rule: the fixed ``factors``
    and ``"auto"`` (:func:`qfg.joint.overdispersion` of the kept robots, as ``solve`` computes
    it); the row's scores are those of the library's default rule
    (:data:`qfg.joint.KINEMATIC_INFLATE`)."""
    root = mrclam.data_root()
    ds, _ = prepare(root / f"MRCLAM_Dataset{d}")
    t0 = time.perf_counter()
    meas = mrclam_runs(ds, min_move=0.0, min_turn_deg=0.0)
    runs = tuple(dataclasses.replace(r, odometry=None, odometry_sigma=None) for r in meas.runs)
    post = J.solve(J.JointMeasurements(runs, meas.landmark_ids),
                   J.SolveParams(inflate_kinematic=1.0), seed=0)
    wall = time.perf_counter() - t0
    q = prior_states(make_prior(ds, "arena"))
    ids = list(ds.landmark_ids)
    truth = np.asarray(ds.landmark_xy)
    kept = [k for k, v in post.robot_flags.items() if v in ("ok", "kinematic")]
    kappa = J.overdispersion(post, kept, seed=0) if post.method != "none" else float("nan")
    rules = {f"{f:g}": f for f in factors}
    rules["auto"] = max(1.0, kappa) if np.isfinite(kappa) else 1.0
    default = J.KINEMATIC_INFLATE
    name = "auto" if default == "auto" else f"{float(default):g}"
    if name not in rules:
        rules[name] = float(default)
    by_rule, kept_P = {}, None
    for rule, f in rules.items():
        p = J.scale_covariance(post, f) if post.method != "none" else post
        P, s_true, tri, sc = _scores(p, q, truth, ids, samples)
        by_rule[rule] = {"factor": f, **sc}
        if rule == name:
            kept_P, kept_post = P, p
    Q = np.broadcast_to(q, kept_P.shape)
    maps = post.info.get("robot_maps", {})
    starts = post.info.get("kinematic_starts", {})
    z2 = _ab_z2(kept_post, truth, ids)
    out = {"dataset": d, "method": post.method, "flags": list(post.flags),
           "robots": {str(k): {"flag": v, "chunk": starts.get(k, {}).get("chunk"),
                               "error_m": _error_m(maps[k], truth) if k in maps else None}
                      for k, v in post.robot_flags.items()},
           "rule": name, "overdispersion": kappa, **by_rule[name], "rules": by_rule,
           "prior_log_score": float(log_score(Q, s_true).mean()),
           "prior_brier": float(brier(Q, s_true).mean()), "n": int(len(s_true)), "time_s": wall,
           "ab_z2_median": float(np.median(z2)) if len(z2) else None,
           "cost": post.info.get("cost"), "too_close": post.info.get("too_close"),
           "too_close_dropped": post.info.get("too_close_dropped")}
    z = _landmark_z(kept_post, truth)
    out["landmark_z"] = z.tolist()
    if save:
        p = pathlib.Path(save)
        p.mkdir(parents=True, exist_ok=True)
        (p / f"d{d}.json").write_text(json.dumps(out, indent=1))
        np.savez(p / f"d{d}.npz", probabilities=kept_P, truth=s_true, triplets=tri)
    return out


def _zs(z) -> str:
    return f"{np.median(z):.2f}, {np.quantile(z, 0.9):.2f}" if len(z) else "-"


def measure_prior():
    for p in mrclam.find_datasets(mrclam.data_root()):
        ds, _ = prepare(p)
        meas = mrclam_runs(ds, min_move=0.0, min_turn_deg=0.0)
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
          "AB-frame z^2: median | overdispersion | prior alone: log p, Brier | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for d in a.datasets:
        o = joint_map(d, a.samples, a.save)
        rows.append(o)
        rob = "; ".join(f"{k}: {v['flag']}"
                        + (f", {v['chunk']}" if v["chunk"] else "")
                        + (f", {v['error_m']:.2f}" if v["error_m"] is not None else "")
                        for k, v in o["robots"].items())
        z2 = "-" if o["ab_z2_median"] is None else f"{o['ab_z2_median']:.2f}"
        print(f"| {d} | {o['method']}, {', '.join(o['flags']) or '-'} | {rob} | "
              f"{o['log_score']:.2f} | {o['brier']:.3f} | {100 * o['truth_under_1pct']:.1f} % | "
              f"{o['ece']:.3f} | {_zs(o['landmark_z'])} | {z2} | {o['overdispersion']:.2f} | "
              f"{o['prior_log_score']:.2f}, {o['prior_brier']:.3f} | "
              f"{o['time_s']:.0f} |", flush=True)
    # every covariance rule on the same solves: mean log p(truth), truth under 1 %, ECE
    names = list(rows[0]["rules"]) if rows else []
    print("\n| dataset | " + " | ".join(f"x{n}" if n != "auto" else "auto" for n in names) + " |")
    print("|---|" + "---|" * len(names))
    for o in rows:
        cells = [f"{r['log_score']:.3f} / {100 * r['truth_under_1pct']:.1f} % / {r['ece']:.3f}"
                 + (f" (x{r['factor']:.2f})" if n == "auto" else "")
                 for n, r in o["rules"].items()]
        print(f"| {o['dataset']} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
