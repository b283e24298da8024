"""Development views sweep: how a solver's proper scores change with the number of views.

    python experiments/solvers/solver_views.py [--n 200] [--views 3,6,10] [--method fast]
        [--variants '{}' '{"mc_shrinkage": 0}'] [--distances 0.074] [--noise 2,5]

Geometries come from development seeds (``default_rng(900000 + i)``, 10 views at 2/5 deg, the
first k views solved for every k), never from the single-triplet study's seeds. Per variant and
k: mean log p(truth) (clipped at 1e-4) with its standard error, mean Brier score, the share of
confidently wrong estimates (more than 0.9 on a wrong state), the top-1 rate, the mean top
probability and the time per triplet of one batched call (shared machine: compare within a run).
With ``--distances SIGMA`` the geometries also carry odometry distances whose log ratios have
noise SIGMA (drawn after everything else: the same bearings and headings), and every variant is
solved without and with them. ``--noise SB,SH`` sets the bearing and heading noise (degrees,
default 2,5). The last column is the cameras' mean log p(truth) (clipped likewise).

Backs docs/solvers.md ("Monte Carlo shrinkage", "Odometry distances", "More views") and
docs/mrclam.md ("What a history holds"). Run from the repository root as above.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np

from qfg.metrics import brier, log_score
from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplets

DEV_SEED = 900000


def histories(n, k_max=10, sv=2.0, sw=5.0, sd=None):
    return [random_triplet_history(np.random.default_rng(DEV_SEED + i), k_max, np.deg2rad(sv),
                                   np.deg2rad(sw), sigma_distance_ratio=sd) for i in range(n)]


def first_views(h, k, distances=True):
    d = h.distances[:k - 1] if distances and h.distances is not None else None
    return replace(h, bearings=h.bearings[:k], headings=h.headings[:k - 1], views=h.views[:k],
                   truth=None, distances=d)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--views", default="3,6,10")
    ap.add_argument("--method", default="fast")
    ap.add_argument("--variants", nargs="*", default=["{}"])
    ap.add_argument("--distances", type=float, default=None, metavar="SIGMA",
                    help="also solve with odometry distances (log-ratio noise SIGMA)")
    ap.add_argument("--noise", default="2,5", help="bearing,heading noise in degrees")
    a = ap.parse_args(argv)
    ks = [int(k) for k in a.views.split(",")]
    sv, sw = (float(x) for x in a.noise.split(","))
    hs = histories(a.n, max(ks), sv, sw, sd=a.distances)
    g = np.array([h.truth.state for h in hs])
    dist = f", distances {a.distances}" if a.distances is not None else ""
    print(f"{a.n} development geometries (seeds {DEV_SEED}+i), {sv:g}/{sw:g} deg{dist}, "
          f"method {a.method}\n")
    print("| options | views | mean log p(truth) | mean Brier | confidently wrong | top-1 | "
          "mean p_max | ms per triplet | cameras: mean log p(truth) |")
    print("|---|---|---|---|---|---|---|---|---|")
    uses = (False, True) if a.distances is not None else (False,)
    for v, use in ((v, u) for v in a.variants for u in uses):
        opts = json.loads(v)
        label = (json.dumps(opts) if opts else "defaults") + (" + distances" if use else "")
        for k in ks:
            t = time.perf_counter()
            ests = solve_triplets([first_views(h, k, use) for h in hs], method=a.method, seed=7,
                                  **opts)
            ms = 1e3 * (time.perf_counter() - t) / len(hs)
            P = np.array([e.landmark for e in ests])
            Q = np.concatenate([e.cameras for e in ests])
            lc = log_score(Q, np.concatenate([h.truth.camera_states[:k] for h in hs]))
            lp = log_score(P, g)
            cw = (P.max(axis=1) > 0.9) & (P.argmax(axis=1) != g)
            print(f"| {label} | {k} | {lp.mean():.3f} +- "
                  f"{lp.std(ddof=1) / np.sqrt(len(lp)):.3f} | {np.mean(brier(P, g)):.3f} | "
                  f"{cw.mean():.3f} | {np.mean(P.argmax(axis=1) == g):.2f} | "
                  f"{P.max(axis=1).mean():.2f} | {ms:.1f} | {lc.mean():.3f} |", flush=True)


if __name__ == "__main__":
    main()
