"""The model check on simulated histories (development seeds): how often it fires on
well-specified data (false alarms) and on misfits, and how the widened answers score.

usage: python experiments/solvers/solver_model_check.py N VIEWS [LEVELS]   (e.g. 40 3,5 0.01,0.05,0.1)

One JSON line per (views, case): the mean log p(truth) as solved, widened at each level as
``model_check=level`` widens (``qfg.solvers.sis.model_check.widening``, after the shrinkage) and of
the prior alone; how often the check fires; the share of truths under 1%. A misfit moves one
bearing of the middle view by 20 deg, or draws the noise at 5x the sigmas the solver is told.

Backs docs/solvers.md, "Heavy-tailed bearings and the model check". Run from the repository
root as above.
"""

import dataclasses
import json
import sys

import numpy as np

from qfg.combine import prior_state_distribution
from qfg.metrics import log_score
from qfg.partitions import get as get_partition
from qfg.priors import get as get_prior
from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplets
from qfg.solvers.sis import model_check as mc


def _scores(P, g, q_c):
    return float(log_score(P, g).mean()) if len(g) else None


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    N, views = int(argv[0]), [int(v) for v in argv[1].split(",")]
    levels = [float(v) for v in (argv[2] if len(argv) > 2 else "0.01,0.05,0.1").split(",")]
    sb, sh = np.deg2rad(2.0), np.deg2rad(5.0)
    # C's state distribution under the world prior, as the model check widens toward it
    q_c = prior_state_distribution(get_prior("world"), get_partition("edc"), point=0, n_cameras=0,
                                   samples=50_000, seed=7)
    for n in views:
        rng = np.random.default_rng(np.random.SeedSequence(424242, spawn_key=(n,)))
        clean = [random_triplet_history(rng, n, sb, sh) for _ in range(N)]
        five = [dataclasses.replace(random_triplet_history(rng, n, 5 * sb, 5 * sh),
                                    sigma_bearing=sb, sigma_heading=sh) for _ in range(N)]

        def off(h, j, n=n):
            b = h.bearings.copy()
            b[n // 2, j] += np.deg2rad(20.0)
            return dataclasses.replace(h, bearings=b)

        cases = {"well specified": clean, "A bearing +20 deg": [off(h, 0) for h in clean],
                 "C bearing +20 deg": [off(h, 2) for h in clean], "5x the stated noise": five}
        for name, hs in cases.items():
            est = solve_triplets(hs, method="full", seed=1)
            g = np.array([h.truth.state for h in hs])
            P = np.stack([e.landmark for e in est])
            p = np.array([e.model_check for e in est])
            Q = np.tile(q_c, (N, 1))
            rec = {"views": n, "case": name, "n": N, "log_score": _scores(P, g, q_c),
                   "prior": _scores(Q, g, q_c),
                   "under_1pct": float(np.mean(P[np.arange(N), g] < 0.01)),
                   "nan": int(np.isnan(p).sum())}
            for lv in levels:
                lam = np.array([mc.widening(x, lv) for x in p])
                W = (1 - lam)[:, None] * P + lam[:, None] * q_c
                f = p < lv
                rec[f"level {lv:g}"] = {
                    "fired": float(f.mean()), "log_score": _scores(W, g, q_c),
                    "under_1pct": float(np.mean(W[np.arange(N), g] < 0.01)),
                    "fired: widened": _scores(W[f], g[f], q_c),
                    "fired: as solved": _scores(P[f], g[f], q_c),
                    "fired: prior": _scores(Q[f], g[f], q_c)}
            print(json.dumps(rec), flush=True)


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    main()
