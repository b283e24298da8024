"""How the single-triplet solvers' defaults were chosen: option variants against the
exact-posterior reference solver on development scenarios.

    python experiments/solvers/solver_defaults.py [--n 100] [--noise 2,5] [--cache DIR] [--methods full,fast]
        [--variants '{}' '{"mc_shrinkage": 0}']

Scenarios come from a development seed (``SeedSequence(555)``, 3 views), never from the
single-triplet study's seeds. For each scenario the reference posterior R is computed once
(``method="reference"``, cached in ``--cache``), then every variant's estimate P is scored by
the mean KL(R || P) (the expected log-score loss against the exact posterior, free of the noise of
which state happened to be true), the mean log p(truth) (clipped at 1e-4) next to the
reference's, the confidently-wrong rate (p_max > 0.9 on a wrong state) and the time per triplet
(one batched call; on a shared machine compare within one run only).

Backs docs/solvers.md ("Monte Carlo shrinkage", "Options and defaults", "Accuracy, calibration
and speed"). Run from the repository root as above.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplets

DEV_SEED = 555

VARIANTS = {
    "full": [
        {},
        {"mc_shrinkage": 0},
        {"move_steps": 2},
        {"landmark_samples": 2},
        {"n_samples": 300, "motion_samples": 4, "max_hypotheses": 1000},
        {"n_samples": 300, "motion_samples": 4, "max_hypotheses": 1000, "move_steps": 2},
        {"n_samples": 300, "motion_samples": 4, "max_hypotheses": 1000, "landmark_samples": 2},
        {"n_samples": 200, "motion_samples": 4, "max_hypotheses": 600, "landmark_samples": 2,
         "move_steps": 4},
    ],
    "fast": [
        {},
        {"mc_shrinkage": 0},
        {"mc_shrinkage": 2},
        {"n_samples": 128},
        {"posterior_samples": 64, "landmark_samples": 4},
        {"bearing_floor": float(np.deg2rad(0.05))},
    ],
    "fast-paper": [{}],
    "baseline": [{}],
}


def histories(n, sv, sw, seed=DEV_SEED):
    ss = np.random.SeedSequence(seed)
    return [random_triplet_history(np.random.default_rng(c), 3, np.deg2rad(sv), np.deg2rad(sw))
            for c in ss.spawn(n)]


def reference(hs, cache: Path | None, tag: str):
    path = cache / f"reference_{tag}.npz" if cache else None
    if path is not None and path.exists():
        return np.load(path)["P"]
    P = np.array([e.landmark for e in solve_triplets(hs, method="reference", seed=1)])
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, P=P)
    return P


def score(P, R, g):
    n = len(g)
    kl = np.sum(R * (np.log(np.maximum(R, 1e-12)) - np.log(np.maximum(P, 1e-6))), axis=1)
    lp = np.log(np.maximum(P[np.arange(n), g], 1e-4))
    cw = (P.max(axis=1) > 0.9) & (P.argmax(axis=1) != g)
    return {"kl": float(kl.mean()), "kl_se": float(kl.std(ddof=1) / np.sqrt(n)),
            "log_p": float(lp.mean()), "confidently_wrong": float(cw.mean()),
            "top1": float(np.mean(P.argmax(axis=1) == g))}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--noise", default="2,5", help="sigma_v,sigma_w in degrees")
    ap.add_argument("--cache", type=Path, default=None)
    ap.add_argument("--methods", default="full,fast,fast-paper,baseline")
    ap.add_argument("--variants", nargs="*", default=None,
                    help="JSON option sets to run instead of the built-in VARIANTS list")
    a = ap.parse_args(argv)
    sv, sw = (float(v) for v in a.noise.split(","))
    hs = histories(a.n, sv, sw)
    g = np.array([h.truth.state for h in hs])
    R = reference(hs, a.cache, f"{a.n}_{sv:g}_{sw:g}")
    ref = score(R, R, g)
    print(f"{a.n} development scenarios at sigma_v = {sv:g} deg, sigma_w = {sw:g} deg; "
          f"reference: mean log p(truth) {ref['log_p']:.3f}, top-1 {ref['top1']:.2f}, "
          f"confidently wrong {ref['confidently_wrong']:.3f}\n")
    print("| method | options | mean KL(reference, method) | mean log p(truth) | top-1 | "
          "confidently wrong | ms per triplet (batched) |")
    print("|---|---|---|---|---|---|---|")
    for method in a.methods.split(","):
        for opts in ([json.loads(v) for v in a.variants] if a.variants is not None
                     else VARIANTS[method]):
            t = time.perf_counter()
            P = np.array([e.landmark for e in solve_triplets(hs, method=method, seed=7, **opts)])
            ms = 1e3 * (time.perf_counter() - t) / len(hs)
            s = score(P, R, g)
            print(f"| {method} | {json.dumps(opts) if opts else 'defaults'} | {s['kl']:.3f} +- "
                  f"{s['kl_se']:.3f} | {s['log_p']:.3f} | {s['top1']:.2f} | "
                  f"{s['confidently_wrong']:.3f} | {ms:.1f} |", flush=True)


if __name__ == "__main__":
    main()
