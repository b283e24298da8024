"""The joint method (qfg.joint) on MRCLAM datasets, scored exactly as the mrclam study scores
seen and unseen triplets (qfg.harness.studies.mrclam: same histories, same truth states, same
prior), against uniform and the prior alone.

    QFG_MRCLAM_DIR=DIR python experiments/joint/joint_mrclam.py 1 2 3 4 5 6

Prints one markdown row per dataset and kind (seen, unseen, camera); ``--json FILE`` writes the
rows. Dataset 6 is development (options chosen on it), 1-5 are evaluation.

``--per-pass K [K ...]`` draws the curve over how many images the map uses instead: each run
thinned to at most K images per 120-s pass (``mrclam_runs(min_interval=120 / K)``; 0 = every
image the default keyframing keeps), the same seen and unseen triplets scored at every K (the
study's, from all the views), no camera states (their views would be kept as keyframes);
``--figure FILE`` draws it.

    python experiments/joint/joint_mrclam.py 1 2 3 4 6 5 --per-pass 2 3 5 10 30 0 \\
        --json out/joint_per_pass.json --figure out/joint_per_pass.png

Backs docs/joint.md ("Flags"; "Development choices and what they are measured on"),
docs/results/joint_map.md ("MRCLAM datasets 1-6") and docs/results/mrclam.md ("More images: the
joint map"). Run from the repository root as above; the MRCLAM data come from ``--data DIR`` or
``$QFG_MRCLAM_DIR``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time

import numpy as np

from qfg import metrics
from qfg.combine import prior_state_distribution
from qfg.datasets.mrclam.joint_map import mrclam_marginals, mrclam_runs
from qfg.graph import truth_states
from qfg.harness.studies import mrclam as study
from qfg.joint import SolveParams
from qfg.partitions import get as get_partition


def score(P, g):
    if not len(g):
        return {"n": 0, "log_score": np.nan, "brier": np.nan, "truth_under_1pct": np.nan,
                "ece": np.nan}
    return {"n": int(len(g)), "log_score": float(metrics.log_score(P, g).mean()),
            "brier": float(metrics.brier(P, g).mean()),
            "truth_under_1pct": float(metrics.truth_under(P, g, 0.01).mean()),
            "ece": float(metrics.expected_calibration_error(P, g))}


def pipeline(path, seed=0):
    """The fallback when the joint method cannot answer (no robot with odometry): the mrclam
    study's own pipeline with its defaults (robots without odometry: the baseline model), its
    seen and propagated rows scored as it scores them."""
    t0 = time.perf_counter()
    rows = study.run_dataset(path, seed=seed)
    wall = time.perf_counter() - t0
    out = []
    for kind, k in (("seen", "seen"), ("unseen", "propagated")):
        sel = [r for r in rows if r["kind"] == k]
        P = np.array([study.decode(r["probabilities"]) for r in sel])
        g = np.array([int(r["truth_state"]) for r in sel])
        out.append({"dataset": rows[0]["dataset"], "kind": kind,
                    "method": "pipeline (" + ";".join(sorted({r["method"] for r in sel})) + ")",
                    **score(P, g), "uniform_log_score": float(np.log(1 / 20)),
                    "prior_log_score": float(np.mean([r["prior_log_score"] for r in sel])),
                    "flagged": float(np.mean([float(r["flagged"]) for r in sel])),
                    "time_s": wall, "flags": "fallback", "robots": ""})
    return out


def run(path, *, seed=0, samples=2000, cameras=True, run_options=None, params=None):
    part = get_partition("edc")
    ds, swaps = study.prepare(path)
    pr = study.make_prior(ds, "arena")
    q_c = prior_state_distribution(pr, part, samples=study.PRIOR_SAMPLES, seed=1)
    q_x = prior_state_distribution(pr, part, point=1, n_cameras=1, samples=study.PRIOR_SAMPLES,
                                   seed=2)
    rh = study.histories(ds, None, mode="honest", spread_views=3, partition=part,
                         min_travel=0.02, max_gap=120.0)
    hs = [h for _, h in rh]
    ids = ds.landmark_ids
    seen_idx = {tuple(ds.landmark_index(h.landmarks).tolist()) for h in hs}
    trip = np.array(list(itertools.permutations(range(ids.size), 3)), dtype=np.intp)
    keys = [tuple(int(ids[i]) for i in t) for t in trip.tolist()]
    has_gt = any(rd.groundtruth is not None for rd in ds.robots.values())
    cam_h = [h for h in hs if h.truth.camera_states is not None] if (cameras and has_gt) else None
    t0 = time.perf_counter()
    c0 = time.process_time()
    res = mrclam_marginals(ds, keys, cam_h, prior_states=q_c, camera_prior_states=q_x,
                           samples=samples, seed=seed, run_options=run_options, params=params)
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    P = np.array([res.triplets[k] for k in keys])
    g = truth_states(trip, ds.landmark_xy, "edc")
    seen = np.array([tuple(t) in seen_idx for t in trip.tolist()])
    out = []
    for kind, m in (("seen", seen), ("unseen", ~seen)):
        row = {"dataset": ds.name, "kind": kind, "method": res.method, **score(P[m], g[m])}
        row["uniform_log_score"] = float(np.log(1 / 20))
        row["prior_log_score"] = score(np.tile(q_c, (int(m.sum()), 1)), g[m])["log_score"]
        row["flagged"] = float(np.mean(np.asarray(res.triplets.info["flagged"])[m]))
        out.append(row)
    if cam_h:
        Pc, gc = [], []
        for h, C in zip(cam_h, res.cameras, strict=False):
            ok = np.asarray(h.truth.camera_states) >= 0
            if h.groundtruth_valid is not None:
                ok &= np.asarray(h.groundtruth_valid, bool)
            Pc.append(C.probabilities[ok])
            gc.append(np.asarray(h.truth.camera_states)[ok])
        Pc, gc = np.concatenate(Pc), np.concatenate(gc).astype(int)
        row = {"dataset": ds.name, "kind": "camera", "method": res.method, **score(Pc, gc),
               "uniform_log_score": float(np.log(1 / 20)),
               "prior_log_score": score(np.tile(q_x, (len(gc), 1)), gc)["log_score"],
               "flagged": 0.0}
        out.append(row)
    # every run the map was given, solved or not, has its poses there (NaN rows if not solved)
    n_img = sum(len(v) for v in res.posterior.poses.values())
    for r in out:
        r["images"] = int(n_img)
        r["time_s"] = wall
        r["cpu_s"] = cpu
        r["flags"] = ";".join(res.posterior.flags)
        r["robots"] = ";".join(f"{k}:{v}" for k, v in res.posterior.robot_flags.items())
    return out


PASS_S = 120.0  # the study's pass (``histories(max_gap=120)``): K per pass = one per 120 / K s


def curve(path, per_pass, *, seed=0, samples=2000, run_options=None, progress=print):
    """Rows of :func:`run` (seen and unseen, no cameras) at each images-per-pass count of
    ``per_pass`` (0: every keyframe), each row with ``per_pass`` and ``images`` (the poses the
    map was given, all robots); ``run_options``: more options of ``mrclam_runs``."""
    rows = []
    for k in per_pass:
        k = int(k)
        if k < 0:
            raise ValueError(f"per_pass: expected counts >= 0, got {k}")
        ro = dict(run_options or {}, **({"min_interval": PASS_S / k} if k else {}))
        got = run(path, seed=seed, samples=samples, cameras=False, run_options=ro)
        for r in got:
            r["per_pass"] = k
        rows += got
        if progress:
            s, u = got[0], got[1]
            progress(f"  {s['dataset']} K={k or 'all'}: {s['images']} images, seen {s['log_score']:.3f}, "
                     f"unseen {u['log_score']:.3f} ({s['time_s']:.0f} s)")
    return rows


def plot_curve(rows, path):
    """Mean log p(truth) against images per pass, one line per dataset and kind."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, kind in zip(axes, ("seen", "unseen"), strict=True):
        for name in sorted({r["dataset"] for r in rows}):
            rs = sorted((r for r in rows if r["dataset"] == name and r["kind"] == kind
                         and r["method"] == "joint"), key=lambda r: r["images"])
            if not rs:
                continue
            line, = ax.plot([r["images"] for r in rs], [r["log_score"] for r in rs], "o-",
                            label=f"dataset {name[14:]}")
            ax.axhline(rs[0]["prior_log_score"], color=line.get_color(), lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_xlabel("images the joint map uses (all robots; K per 120-s pass)")
        ax.set_title(f"{kind} triplets")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("mean log p(truth)  (dotted: the prior alone)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def sweep(path, *, seed=0, samples=2000, inflates=(1, 2, 4, 9), floors=(0.0, 1e-4, 1e-3, 1e-2),
          min_interval=0.0):
    """Development table: one solve of a dataset (keyframes ``min_interval`` s apart or more),
    its seen and unseen triplets scored with the covariances scaled by each of ``inflates``
    (floor 1e-3), by the robots' measured scatter about the map (``joint.overdispersion`` as
    ``solve`` measured it over the robots in the map, when above 1) and with each of ``floors``
    (inflate 1)."""
    from qfg import joint

    part = get_partition("edc")
    ds, _ = study.prepare(path)
    q = prior_state_distribution(study.make_prior(ds, "arena"), part,
                                 samples=study.PRIOR_SAMPLES, seed=1)
    rh = study.histories(ds, None, mode="honest", spread_views=3, partition=part,
                         min_travel=0.02, max_gap=120.0)
    ids = ds.landmark_ids
    seen_idx = {tuple(ds.landmark_index(h.landmarks).tolist()) for _, h in rh}
    trip = np.array(list(itertools.permutations(range(ids.size), 3)), dtype=np.intp)
    keys = [tuple(int(ids[i]) for i in t) for t in trip.tolist()]
    seen = np.array([tuple(t) in seen_idx for t in trip.tolist()])
    g = truth_states(trip, ds.landmark_xy, "edc")
    post = joint.solve(mrclam_runs(ds, min_interval=min_interval), seed=seed)
    kappa = float(post.info.get("overdispersion", np.nan))   # measured by solve, its robots
    print(f"{ds.name} (keyframes {min_interval:g} s apart or more): flags {post.flags}, robots "
          f"{post.robot_flags}, bearings dropped {post.info['outliers_dropped']}, the robots' "
          f"scatter kappa {kappa:.2f}")
    print("| inflate | floor | seen log p | seen truth < 1% | seen ECE | unseen log p | "
          "unseen truth < 1% | unseen ECE |")
    print("|---|---|---|---|---|---|---|---|")
    combos = [(1, f) for f in floors] + [(i, 1e-3) for i in inflates if i != 1]
    if np.isfinite(kappa) and kappa > 1:
        combos.append((kappa, 1e-3))
    for infl, fl in combos:
        pp = joint.scale_covariance(post, infl) if infl != 1 else post
        P = joint.triplet_marginals(pp, keys, prior_states=q, samples=samples, seed=seed,
                                    floor=fl).probabilities
        cells = []
        for m in (seen, ~seen):
            s = score(P[m], g[m])
            cells += [f"{s['log_score']:.3f}", f"{100 * s['truth_under_1pct']:.1f}%",
                      f"{s['ece']:.3f}"]
        print(f"| {infl:.3g} | {fl:g} | " + " | ".join(cells) + " |", flush=True)


def main_curve(a):
    """``--per-pass``: the curve's table, rows and figure."""
    rows = []
    print("| dataset | K per pass | images | seen log p | seen < 1% | unseen log p | "
          "unseen < 1% | prior alone (seen / unseen) | wall (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for d in study.dataset_dirs(a.data, a.datasets):
        got = curve(d, a.per_pass, seed=a.seed, samples=a.samples,
                    run_options={"noise_by_path": True} if a.noise_by_path else None)
        rows += got
        for k in a.per_pass:
            s, u = [r for r in got if r["per_pass"] == k]
            print(f"| {s['dataset'][14:]} | {k or 'all'} | {s['images']} | "
                  f"{s['log_score']:.3f} | {100 * s['truth_under_1pct']:.1f}% | "
                  f"{u['log_score']:.3f} | {100 * u['truth_under_1pct']:.1f}% | "
                  f"{s['prior_log_score']:.2f} / {u['prior_log_score']:.2f} | "
                  f"{s['time_s']:.0f} |", flush=True)
        if a.json:
            with open(a.json, "w") as f:
                json.dump(rows, f, indent=1)
    if a.figure:
        plot_curve(rows, a.figure)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("datasets", nargs="*", type=int, default=[6])
    ap.add_argument("--data", default="",
                    help="directory holding the MRCLAM_Dataset* directories (default: $QFG_MRCLAM_DIR)")
    ap.add_argument("--samples", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--inflate", type=float, default=None)
    ap.add_argument("--starts", type=int, default=None)
    ap.add_argument("--no-cameras", action="store_true")
    ap.add_argument("--no-fallback", action="store_true",
                    help="do not run the solver pipeline where the joint method cannot answer")
    ap.add_argument("--outlier", type=float, default=None,
                    help="bearings beyond this many sigmas dropped (qfg.joint.solve; 0: none)")
    ap.add_argument("--sweep", action="store_true",
                    help="development table instead: covariance scale and floor from one solve "
                         "(with --per-pass: one per images-per-pass count)")
    ap.add_argument("--per-pass", type=int, nargs="+", default=None,
                    help="the curve over images per 120-s pass instead (0: every keyframe)")
    ap.add_argument("--figure", default="", help="with --per-pass: draw the curve here")
    ap.add_argument("--noise-by-path", action="store_true",
                    help="the odometry's noise from the path between keyframes "
                         "(mrclam_runs(noise_by_path=True))")
    ap.add_argument("--from-json", default="", help="with --figure: draw a recorded curve")
    ap.add_argument("--json", default="")
    a = ap.parse_args(argv)
    if a.from_json:
        plot_curve(json.loads(open(a.from_json).read()), a.figure or "joint_per_pass.png")
        return
    if a.per_pass and not a.sweep:
        return main_curve(a)
    opts = {}   # the solve's options given on the command line (qfg.joint.SolveParams)
    if a.inflate is not None:
        opts["inflate"] = a.inflate
    if a.starts is not None:
        opts["starts"] = a.starts
    if a.outlier is not None:
        opts["outlier"] = a.outlier
    if a.sweep:
        for d in study.dataset_dirs(a.data, a.datasets):
            for k in a.per_pass or [0]:
                sweep(d, seed=a.seed, samples=a.samples,
                      min_interval=PASS_S / k if k else 0.0)
        return
    rows = []
    print("| dataset | kind | method | n | log p(truth) | uniform | prior alone | Brier | "
          "truth < 1% | ECE | flagged | wall (s) | CPU (s) | flags |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for d in study.dataset_dirs(a.data, a.datasets):
        got = run(d, seed=a.seed, samples=a.samples, cameras=not a.no_cameras,
                  params=SolveParams(**opts))
        if got[0]["method"] == "none" and not a.no_fallback:
            got += pipeline(d, seed=a.seed)
        for r in got:
            rows.append(r)
            print(f"| {r['dataset'][14:]} | {r['kind']} | {r['method']} | {r['n']} | "
                  f"{r['log_score']:.3f} | {r['uniform_log_score']:.2f} | "
                  f"{r['prior_log_score']:.2f} | {r['brier']:.3f} | "
                  f"{100 * r['truth_under_1pct']:.1f}% | {r['ece']:.3f} | {r['flagged']:.2f} | "
                  f"{r['time_s']:.0f} | {r.get('cpu_s', float('nan')):.0f} | "
                  f"{r['flags']} {r['robots']} |", flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
