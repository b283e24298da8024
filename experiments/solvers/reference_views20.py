"""The reference solver on the views20 preset's geometries : ESS, flags, time
and log score per geometry and view count, and a paired table against another run.

The geometries and solver seeds are those of ``qfg experiment single-triplet --preset views20``
(:func:`qfg.harness.studies.single_triplet.run_task`'s views sweep: scenario i of run seed s,
its first k views at sigma_v = 2 deg, sigma_w = 5 deg), solved by the reference alone, one
triplet at a time, one JSON line per (views, geometry) appended to ``--out``:

    python experiments/solvers/reference_views20.py --seed 1 --scenarios 0 20 --views 15 20 \\
        --out new.jsonl
    python experiments/solvers/reference_views20.py --paired old.jsonl new.jsonl

(the old code measured from a git worktree: ``PYTHONPATH=<worktree> python ...``).
``--at-truth`` instead runs the reference's particle filter given the true C (400 draws of C at
the truth, 16 particles each) and prints the ESS of its weights with the prior inside the filter
and with the prior on one drawn trajectory only (the filter without it), and the spread of that
trajectory's log prior, per geometry.

Backs docs/priors.md ("The reference solver"; "Two samplers: staged and conditional") and
docs/results/single_triplet.md ("The views preset with the current engine, against the exact
posterior"; "The views sweep to 20 views"). Run from the repository root as above.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from qfg import metrics
from qfg.harness.runner import scenario_rng
from qfg.harness.studies.single_triplet import METHODS, first_views
from qfg.partitions import get as get_partition
from qfg.simulation import random_triplet_history

PART = get_partition("edc")


def scenario(seed, i, k, max_views=20):
    """History of the first k views of scenario i of a views20 run seeded ``seed`` and the
    reference's solver seed there (as ``run_task`` draws them); ``max_views=10`` for the views
    preset's geometries (each drawn with 10 views)."""
    rng = scenario_rng(seed, i)
    geometry_seed = int(rng.integers(2**63))
    solver_root = np.random.SeedSequence(int(rng.integers(2**63)))
    hmax = random_triplet_history(np.random.default_rng(geometry_seed + 1), max_views,
                                  np.deg2rad(2.0),
                                  np.deg2rad(5.0), partition=PART)
    s = np.random.SeedSequence(solver_root.entropy,
                               spawn_key=(1000 + k, METHODS.index("reference")))
    return first_views(hmax, k), s


def measure(seed, lo, hi, views, out, opts, max_views=20):
    from qfg.solvers import solve_triplet

    with open(out, "a") as fh:
        for n in views:
            for i in range(lo, hi):
                h, s = scenario(seed, i, n, max_views)
                t0 = time.perf_counter()
                est = solve_triplet(h, method="reference", partition=PART, seed=s, **opts)
                dt = time.perf_counter() - t0
                ls = float(metrics.evaluate(est.landmark, h.truth.state,
                                            PART.centroids)["log_score"])
                rec = {"seed": seed, "i": i, "n": n, "ess": est.ess, "time": dt, "log_score": ls,
                       "flagged": bool(est.degenerate), "reason": est.reason,
                       "pareto_k": est.pareto_k, "p": est.landmark.tolist(), "opts": opts}
                fh.write(json.dumps(rec) + "\n")
                fh.flush()
                print(f"n={n} i={i} ess={est.ess:.0f} t={dt:.1f}s log p={ls:.2f} "
                      f"{est.reason[:70]}", flush=True)


def paired(old_path, new_path):
    old = {(r["n"], r["i"]): r for r in map(json.loads, open(old_path))}
    new = {(r["n"], r["i"]): r for r in map(json.loads, open(new_path))}
    print("| views | run | triplets | median ESS | ESS range | ESS < 50 | flagged (any reason) "
          "| median time s | mean log p(truth) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in sorted({k[0] for k in new}):
        ks = sorted(k for k in new if k[0] == n and k in old)
        for name, d in (("old", old), ("new", new)):
            e = np.array([d[k]["ess"] for k in ks])
            print(f"| {n} | {name} | {len(ks)} | {np.median(e):.0f} | {e.min():.0f}-{e.max():.0f} "
                  f"| {int(np.sum(e < 50))} | {np.mean([d[k]['flagged'] for k in ks]):.2f} "
                  f"| {np.median([d[k]['time'] for k in ks]):.1f} "
                  f"| {np.mean([d[k]['log_score'] for k in ks]):.3f} |")
    for n in sorted({k[0] for k in new}):
        ks = sorted(k for k in new if k[0] == n and k in old)
        d = np.array([new[k]["log_score"] - old[k]["log_score"] for k in ks])
        tv = np.array([0.5 * np.abs(np.subtract(new[k]["p"], old[k]["p"])).sum() for k in ks])
        unflagged = sum(new[k]["ess"] < 50 and "effective sample size" not in new[k]["reason"]
                        for k in ks)
        print(f"{n} views: paired log p(truth) new - old {d.mean():+.3f} (se "
              f"{d.std(ddof=1) / np.sqrt(d.size):.3f}, range {d.min():+.2f} to {d.max():+.2f}); "
              f"total variation new vs old median {np.median(tv):.3f}, max {tv.max():.3f}; new "
              f"answers with ESS < 50 not flagged for it: {unflagged}")


def at_truth(seed, lo, hi, views):
    from qfg.solvers.common.prior import resolve_prior
    from qfg.solvers.reference import conditional as R
    from qfg.solvers.reference.staged import Layout

    prior = resolve_prior("world")

    ess = R.effective_sample_size

    for n in views:
        for i in range(lo, hi):
            h, _ = scenario(seed, i, n)
            L = Layout(h.bearings, h.headings, h.sigma_bearing, h.sigma_heading)
            C = np.repeat(h.truth.C_ab[None], 400, 0)
            lz, X, _ = R.particle_trajectories(L, C, np.random.default_rng(0), 16)
            lp = prior.log_density(np.concatenate([C[:, None], X], 1))
            outside = lz + lp
            inside, _, _ = R.particle_trajectories(L, C, np.random.default_rng(0), 16,
                                                   prior=prior)
            fin = np.isfinite(lp)
            print(f"n={n} i={i}: ESS of 400 draws at the true C, prior on one trajectory "
                  f"{ess(outside):.0f}, prior inside the filter {ess(inside):.0f}; log prior of "
                  f"the drawn trajectories: sd {np.std(lp[fin]):.2f} nats, 0 for "
                  f"{np.sum(~fin)} of 400", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--scenarios", type=int, nargs=2, default=[0, 20], metavar=("FROM", "TO"))
    ap.add_argument("--views", type=int, nargs="+", default=[15, 20])
    ap.add_argument("--max-views", type=int, default=20,
                    help="views each geometry is drawn with: 20 (views20 preset), 10 (views)")
    ap.add_argument("--out", default=None)
    ap.add_argument("--options", default="{}", help="reference options as JSON")
    ap.add_argument("--paired", nargs=2, metavar=("OLD", "NEW"), default=None)
    ap.add_argument("--at-truth", action="store_true")
    a = ap.parse_args(argv)
    if a.paired:
        paired(*a.paired)
    elif a.at_truth:
        at_truth(a.seed, *a.scenarios, a.views)
    else:
        if a.out is None:
            ap.error("--out: required to measure")
        measure(a.seed, *a.scenarios, a.views, a.out, json.loads(a.options), a.max_views)


if __name__ == "__main__":
    main()
