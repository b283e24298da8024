"""Full solver against an older tree's, paired, at several numbers of views:
the same geometries and solver seeds, one batched call per tree and n.

    git archive <commit> qfg | tar -x -C DIR
    python experiments/solvers/sis_paired.py DIR N VIEWS [VARIANT ...] [--seed S] [--noise 2,5]
        [--method fast]
    python experiments/solvers/sis_paired.py DIR 50 3,6,10,20 '{}' --seed 700000

Geometries: ``random_triplet_history(default_rng(S + i), max(VIEWS), sv, sw)`` (the views
preset's generator; S defaults to 700000, a development seed, not the preset's), each tree
building them with its own ``qfg.simulation`` (the same draws); the first n views solved with
``seed=1``. Per tree (or variant of the working tree's options) and n: mean log p(truth) of C
(clipped at 1e-4, natural log) with its standard error, flagged answers (each with its reason),
median ESS, ms per triplet (one batched call; a shared machine: compare within a run), the
expected calibration error of the top state and the share with the truth under 1%, and the
paired difference of every variant against the older tree with its standard error. With no VARIANT the working
tree runs at its defaults.

Backs docs/solvers.md, "More views". Run from the repository root as above.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))   # the repository root
from benchmarks.bench_solvers import load_tree  # noqa: E402


def _histories(sim, n, k_max, sv, sw, seed):
    return [sim.random_triplet_history(np.random.default_rng(seed + i), k_max, np.deg2rad(sv),
                                       np.deg2rad(sw)) for i in range(n)]


def _first(h, k):
    return replace(h, bearings=h.bearings[:k], headings=h.headings[:k - 1], views=h.views[:k],
                   truth=None)


def _metrics():
    from qfg import metrics

    return metrics


def _score(solvers, hs, k, opts, method="full"):
    t = time.perf_counter()
    es = solvers.solve_triplets([_first(h, k) for h in hs], method=method, seed=1, **opts)
    dt = (time.perf_counter() - t) / len(hs) * 1e3
    g = [h.truth.state for h in hs]
    lp = np.log(np.clip([e.landmark[s] for e, s in zip(es, g, strict=True)], 1e-4, 1.0))
    flagged = [e.reason for e in es if e.degenerate]
    p = np.array([e.landmark for e in es])
    cal = (f"ECE {_metrics().expected_calibration_error(p, g, kind='top'):.3f} truth<1% "
           f"{_metrics().truth_under(p, g).mean():.3f}")
    return lp, len(flagged), float(np.median([e.ess for e in es])), dt, flagged + [cal]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", help="directory holding the older qfg package")
    ap.add_argument("n", type=int)
    ap.add_argument("views")
    ap.add_argument("variants", nargs="*", default=["{}"])
    ap.add_argument("--seed", type=int, default=700000)
    ap.add_argument("--noise", default="2,5", help="bearing,heading noise in degrees")
    ap.add_argument("--method", default="full", choices=("full", "fast"))
    a = ap.parse_args(argv)
    views = [int(v) for v in a.views.split(",")]
    sv, sw = (float(x) for x in a.noise.split(","))
    old = load_tree(a.before)
    old_solvers = importlib.import_module(old.__name__ + ".solvers")
    old_sim = importlib.import_module(old.__name__ + ".simulation")
    import qfg.simulation as new_sim
    import qfg.solvers as new_solvers

    h_old = _histories(old_sim, a.n, max(views), sv, sw, a.seed)
    h_new = _histories(new_sim, a.n, max(views), sv, sw, a.seed)
    print(f"{a.method}, {a.n} geometries (default_rng({a.seed} + i)), {sv:g}/{sw:g} deg, load "
          f"{os.getloadavg()[0]:.1f}", flush=True)
    for k in views:
        base, _, _, _, why = r = _score(old_solvers, h_old, k, {}, a.method)
        print(f"n={k:2d} before      logp {base.mean():.3f} +- "
              f"{base.std(ddof=1) / np.sqrt(a.n):.3f} flagged {r[1]} ESS med {r[2]:.0f} "
              f"{r[3]:.0f} ms {why.pop()}", flush=True)
        for w in why:
            print(f"      flagged: {w[:110]}")
        for v in a.variants:
            lp, fl, ess, dt, why = _score(new_solvers, h_new, k, json.loads(v), a.method)
            d = lp - base
            print(f"n={k:2d} after {v:6s} logp {lp.mean():.3f} +- "
                  f"{lp.std(ddof=1) / np.sqrt(a.n):.3f} flagged {fl} ESS med {ess:.0f} "
                  f"{dt:.0f} ms {why.pop()} | paired {d.mean():+.3f} +- {d.std(ddof=1) / np.sqrt(a.n):.3f} "
                  f"(load {os.getloadavg()[0]:.1f})", flush=True)
            for w in why:
                print(f"      flagged: {w[:110]}")


if __name__ == "__main__":
    main()
