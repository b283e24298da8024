"""Single-triplet solvers: median time per 3-view triplet at the headline noise (sigma_v = 2 deg,
sigma_w = 5 deg), default options. The fast variant is timed batched (200 triplets per
``solve_triplets`` call, 5 repeats) and per single call; full and baseline per single call over 40
triplets. The paper's MATLAB took 0.05 s (fast), 18 s (full) and 26 s (baseline)."""

import time

import numpy as np

from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplet, solve_triplets


def _histories(n, seed=2024):
    ss = np.random.SeedSequence(seed)
    return [random_triplet_history(np.random.default_rng(c), 3, np.deg2rad(2.0), np.deg2rad(5.0))
            for c in ss.spawn(n)]


def _single(method, hs):
    solve_triplet(hs[0], method=method, seed=0)      # warm-up
    ts = []
    for k, h in enumerate(hs):
        t = time.perf_counter()
        solve_triplet(h, method=method, seed=k)
        ts.append(time.perf_counter() - t)
    return float(np.median(ts)), float(np.percentile(ts, 90))


def run():
    rows = []
    hs = _histories(200)
    solve_triplets(hs[:20], method="fast")           # warm-up
    per = []
    for _ in range(5):
        t = time.perf_counter()
        solve_triplets(hs, method="fast")
        per.append((time.perf_counter() - t) / len(hs))
    rows.append({"name": "fast, batched (200 triplets per call)", "value": 1e3 * float(np.median(per)),
                 "unit": "ms/triplet", "target": "<= 1",
                 "note": f"median of 5 calls; min {1e3 * min(per):.2f} ms"})
    med, p90 = _single("fast", hs[:40])
    rows.append({"name": "fast, single call", "value": 1e3 * med, "unit": "ms/triplet",
                 "target": "", "note": f"median of 40, p90 {1e3 * p90:.1f} ms"})
    for method, target in (("full", "<= 100"), ("baseline", "<= 500")):
        med, p90 = _single(method, hs[:40])
        rows.append({"name": f"{method}, single call", "value": 1e3 * med, "unit": "ms/triplet",
                     "target": target, "note": f"median of 40, p90 {1e3 * p90:.1f} ms"})
    return rows
