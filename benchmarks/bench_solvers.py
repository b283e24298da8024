"""Single-triplet solvers: time per 3-view triplet at the headline noise (sigma_v = 2 deg,
sigma_w = 5 deg), default options, measured side by side in one run. Batched: one
``solve_triplets`` call on T triplets, time / T, median of repeats (full and fast: T = 50, 3
repeats; fast-paper: T = 200, 5 repeats). Single calls: median over triplets (baseline 20,
reference 5). The paper's MATLAB took 0.05 s (fast), 18 s (full) and 26 s (baseline)."""

import os
import time

import numpy as np

from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplet, solve_triplets


def _histories(n, seed=2024):
    ss = np.random.SeedSequence(seed)
    return [random_triplet_history(np.random.default_rng(c), 3, np.deg2rad(2.0), np.deg2rad(5.0))
            for c in ss.spawn(n)]


def _batched(method, hs, repeats):
    solve_triplets(hs[:5], method=method, seed=0)          # warm-up
    per = []
    for r in range(repeats):
        t = time.perf_counter()
        solve_triplets(hs, method=method, seed=r)
        per.append((time.perf_counter() - t) / len(hs))
    return float(np.median(per)), float(min(per))


def _single(method, hs):
    solve_triplet(hs[0], method=method, seed=0)             # warm-up
    ts = []
    for k, h in enumerate(hs):
        t = time.perf_counter()
        solve_triplet(h, method=method, seed=k)
        ts.append(time.perf_counter() - t)
    return float(np.median(ts)), float(np.percentile(ts, 90))


def run():
    rows = []
    hs = _histories(200)
    load = os.getloadavg()[0]
    for method, T, reps, target in (("full", 50, 3, "<= 10"), ("fast", 50, 3, "<= 2"),
                                    ("fast-paper", 200, 5, "")):
        med, best = _batched(method, hs[:T], reps)
        rows.append({"name": f"{method}, batched ({T} triplets per call)", "value": 1e3 * med,
                     "unit": "ms/triplet", "target": target,
                     "note": f"median of {reps} calls; min {1e3 * best:.2f} ms; load {load:.1f}"})
    for method, n in (("baseline", 20), ("reference", 5)):
        med, p90 = _single(method, hs[:n])
        rows.append({"name": f"{method}, single call", "value": 1e3 * med, "unit": "ms/triplet",
                     "target": "", "note": f"median of {n}, p90 {1e3 * p90:.0f} ms"})
    return rows
