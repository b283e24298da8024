"""Exact versus approximate inference on small qualitative factor graphs (issue 5).

Each scenario: a random trajectory among ``n_landmarks`` landmarks (:func:`qfg.simulation.
random_scenario`), the triplets it saw solved by a single-triplet solver (priors), and a random
connected set of composition factors over the map of those landmarks grown until it holds at most
``max_triplets`` triplets; with probability ``loop_probability`` the growth prefers factors that
close a loop (the ``has_loop`` column says whether the graph has one).
The seen triplets of the graph keep their solver priors with probability ``coverage``; the rest are
unseen. A graph whose priors contradict the tensor's support (zero total mass: no exact answer)
is drawn again (``zero_mass_redraws`` counts them). For each graph: exact marginals (einsum
contraction), label-correcting propagation (Algorithm 2) and loopy BP; per non-seen triplet and
method: total variation and KL(exact || method) to the exact marginals, DMSE to the ground-truth
state, information score, time of the method on the whole graph.

Run: ``qfg experiment exact-vs-approx --preset quick --output out/exact_vs_approx``.
"""

from __future__ import annotations

import itertools
import json
import time
from pathlib import Path

import numpy as np

from qfg.graph import QualitativeFactorGraph, truth_states
from qfg.metrics import dmse, information_score
from qfg.propagation import ZeroMassError, exact_marginals, loopy_bp, propagate
from qfg.harness.runner import Study
from qfg.simulation import random_scenario, triplet_histories

METHODS = ("exact", "label_correcting", "loopy_bp")

DEFAULTS = {
    "n_scenarios": 20, "n_landmarks": 5, "n_poses": 6, "landmarks_per_view": 4,
    "max_triplets": 8, "max_factors": 5, "coverage": 0.5, "sigma_bearing": 0.02,
    "sigma_heading": 0.05, "solver": "fast", "partition": "edc", "bp_damping": 0.0,
    "bp_max_iters": 200, "bp_tol": 1e-9, "loop_probability": 0.5,
    # Tests only: a seeded random tensor of this many states instead of the shipped tensor.
    "random_tensor_states": 0,
}


def tasks(params: dict) -> list[dict]:
    p = {**DEFAULTS, **params}
    unknown = set(params) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"params: unknown keys {sorted(unknown)}")
    return [{"index": i, **{k: v for k, v in p.items() if k != "n_scenarios"}}
            for i in range(int(p["n_scenarios"]))]


def _tensor(task):
    m = int(task["random_tensor_states"])
    if m:
        rng = np.random.default_rng(12345)
        return rng.random((m, m, m)) * (rng.random((m, m, m)) < 0.3) + 1e-6
    from qfg.composition import tensor
    return tensor(task["partition"])


def _grow_factors(rng, seen_set, n_land, max_triplets, max_factors, prefer_loops=False):
    """Random connected factor set, starting at a factor touching a seen triplet.

    ``prefer_loops``: when some candidate factor shares two or more triplets with the set (adding
    it closes a loop), draw among those only."""
    factors = [(i, j, k, s) for i, j, k, s in itertools.permutations(range(n_land), 4)]
    trip = {f: {(f[0], f[1], f[2]), (f[1], f[2], f[3]), (f[0], f[1], f[3])} for f in factors}
    starts = [f for f in factors if trip[f] & seen_set]
    if not starts:
        return [], set()
    chosen = [starts[rng.integers(len(starts))]]
    ts = set(trip[chosen[0]])
    target = int(rng.integers(1, max_factors + 1))
    while len(chosen) < target:
        cands = [f for f in factors if f not in chosen and trip[f] & ts
                 and len(ts | trip[f]) <= max_triplets]
        if not cands:
            break
        if prefer_loops:
            loops = [f for f in cands if len(trip[f] & ts) >= 2]
            cands = loops or cands
        f = cands[rng.integers(len(cands))]
        chosen.append(f)
        ts |= trip[f]
    return chosen, ts


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    import networkx as nx

    from qfg.solvers import solve_triplet

    T = _tensor(task)
    zero_mass_redraws = 0
    for _ in range(100):
        sc = random_scenario(rng, task["n_landmarks"], task["n_poses"], task["landmarks_per_view"],
                             sigma_bearing=task["sigma_bearing"],
                             sigma_heading=task["sigma_heading"])
        hists = {h.landmarks: h for h in triplet_histories(sc, partition=task["partition"])}
        chosen, ts = _grow_factors(rng, set(hists), task["n_landmarks"], task["max_triplets"],
                                   task["max_factors"],
                                   prefer_loops=bool(rng.random() < task["loop_probability"]))
        cands = sorted(t for t in ts if t in hists)
        seen = [t for t in cands if rng.random() < task["coverage"]]
        if not (chosen and seen and len(seen) < len(ts)):
            continue
        g = QualitativeFactorGraph(task["partition"], tensor=T)
        for t in sorted(ts):
            prior = None
            if t in seen:
                prior = solve_triplet(hists[t], method=task["solver"],
                                      partition=task["partition"], seed=rng)
            g.add_triplet(t, prior)
        for f in chosen:
            g.add_composition(f)
        t0 = time.perf_counter()
        try:
            ex = exact_marginals(g, engine="contract")
            t1 = time.perf_counter()
        except ZeroMassError:
            # the solver priors contradict the tensor's support: no exact answer; draw again
            zero_mass_redraws += 1
            continue
        break
    else:
        raise RuntimeError("no usable graph (seen and unseen triplets, non-zero mass) in 100 draws")
    has_loop = len(nx.cycle_basis(g.to_networkx())) > 0
    t2s = time.perf_counter()
    lc = propagate(g)
    t2 = time.perf_counter()
    bp = loopy_bp(g, damping=task["bp_damping"], max_iters=task["bp_max_iters"], tol=task["bp_tol"])
    t3 = time.perf_counter()
    results = {"exact": (ex, t1 - t0), "label_correcting": (lc.marginals, t2 - t2s),
               "loopy_bp": (bp.marginals, t3 - t2)}
    truth = truth_states(g.triplets, sc.landmarks, task["partition"])
    rows = []
    eps = 1e-300
    for v, t in enumerate(g.triplets):
        if g.seen[v]:
            continue
        for name, (M, dt) in results.items():
            p, q = ex[v], M[v]
            rows.append({
                "triplet": "-".join(map(str, t)), "method": name,
                "tv": float(0.5 * np.abs(p - q).sum()),
                "kl": float(np.sum(np.where(p > 0, p * (np.log(np.maximum(p, eps))
                                                        - np.log(np.maximum(q, eps))), 0.0))),
                "dmse": float(dmse(q / q.sum(), truth[v])),
                "isc": float(information_score(q / q.sum())),
                "reached": bool(lc.reached[v]),
                "has_loop": has_loop, "n_triplets": g.n_triplets, "n_factors": g.n_factors,
                "n_seen": int(g.seen.sum()), "bp_converged": bp.converged,
                "bp_iterations": bp.iterations, "zero_mass_redraws": zero_mass_redraws,
                "time_s": dt,
            })
    return rows


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    import csv

    outdir = Path(outdir)
    groups = {}
    for r in rows:
        for loop in ("all", "loopy" if r["has_loop"] else "tree"):
            groups.setdefault((r["method"], loop), []).append(r)
    table = []
    for (method, loop), rs in sorted(groups.items()):
        def col(k, rs=rs):
            return np.array([x[k] for x in rs], dtype=float)
        table.append({"method": method, "graphs": loop, "triplets": len(rs),
                      "tv_mean": col("tv").mean(), "tv_median": float(np.median(col("tv"))),
                      "kl_mean": col("kl").mean(), "dmse_mean": col("dmse").mean(),
                      "isc_mean": col("isc").mean(),
                      "time_ms_median": 1e3 * float(np.median(col("time_s")))})
    if table:
        with open(outdir / "table.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(table[0]))
            w.writeheader()
            w.writerows(table)
        lines = ["| method | graphs | unseen triplets | TV mean | TV median | KL mean | DMSE mean "
                 "| ISC mean | time median (ms) |", "|---|---|---|---|---|---|---|---|---|"]
        for t in table:
            lines.append(f"| {t['method']} | {t['graphs']} | {t['triplets']} | {t['tv_mean']:.3f} "
                         f"| {t['tv_median']:.3f} | {t['kl_mean']:.3f} | {t['dmse_mean']:.3f} "
                         f"| {t['isc_mean']:.3f} | {t['time_ms_median']:.2f} |")
        (outdir / "table.md").write_text("\n".join(lines) + "\n")
    bp_rows = [r for r in rows if r["method"] == "loopy_bp"]
    summary = {"rows": len(rows), "table": table,
               "bp_converged_fraction": float(np.mean([r["bp_converged"] for r in bp_rows]))
               if bp_rows else None}
    (outdir / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover
        return
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
    for ax, key, label in ((axes[0], "tv", "total variation to exact"),
                           (axes[1], "dmse", "DMSE to ground truth")):
        data, labels = [], []
        for method in METHODS:
            for loop in (False, True):
                vals = [r[key] for r in rows if r["method"] == method and r["has_loop"] == loop]
                if vals:
                    data.append(vals)
                    short = {"exact": "exact", "label_correcting": "Alg. 2",
                             "loopy_bp": "loopy BP"}[method]
                    labels.append(f"{short}\n{'loopy' if loop else 'tree'}")
        if data:
            ax.boxplot(data)
            ax.set_xticks(range(1, len(labels) + 1), labels, fontsize=7)
        ax.set_ylabel(label)
    fig.tight_layout()
    fig.savefig(outdir / "exact_vs_approx.png", dpi=120)
    plt.close(fig)


STUDY = Study("exact-vs-approx", tasks, run_task, summarize,
              "exact marginals vs label-correcting (Alg. 2) vs loopy BP on small graphs")
