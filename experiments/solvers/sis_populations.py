"""Independent SIS populations against one (development): does averaging K populations, each
with 1/K of the budget, beat one population with the whole budget?

Geometries as the single-triplet views sweep draws them (``scenario_rng(RUN_SEED, i)``, 2/5 deg,
the paper box), each solved with its first n views by ``full`` with ``populations=K`` (the
options' budget split K ways, ``qfg/solvers/sis/populations.py``). ``run`` writes one JSON line per
(geometry, n) with the K populations' answers (solved as K single-population calls, so each
population's answer is kept) and prints their mean log p(truth), the average's, and the
populations' total variation; ``compare`` pairs runs by geometry against a base run::

    python experiments/solvers/sis_populations.py run 2 0:150 6,20 1 out/k1.jsonl
    python experiments/solvers/sis_populations.py run 2 0:150 6,20 2 out/k2.jsonl
    python experiments/solvers/sis_populations.py compare out/k1.jsonl out/k2.jsonl

Run seed 2 is a development seed (the views presets report seed 1).

Backs docs/solvers.md, "More views". Run from the repository root as above.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from qfg.harness.runner import scenario_rng
from qfg.harness.studies.single_triplet import first_views
from qfg.partitions import get
from qfg.simulation import random_triplet_history
from qfg.solvers import DEFAULTS, solve_triplets
from qfg.solvers.sis.populations import split_options


def _histories(run_seed, lo, hi, n_max, part):
    out = {}
    for i in range(lo, hi):
        rng = scenario_rng(run_seed, i)
        geometry_seed = int(rng.integers(2**63))
        out[i] = random_triplet_history(np.random.default_rng(geometry_seed + 1), n_max,
                                        np.deg2rad(2), np.deg2rad(5), partition=part)
    return out


def run(run_seed: int, span: str, views: str, K: int, path: str) -> None:
    part = get("edc")
    lo, hi = map(int, span.split(":"))
    ns = [int(x) for x in views.split(",")]
    H = _histories(run_seed, lo, hi, max(ns), part)
    keys = ("n_samples", "max_hypotheses", "posterior_samples")
    opts = {k: v for k, v in split_options({k: DEFAULTS["full"][k] for k in keys}, K).items()}
    with open(path, "w") as out:
        for n in ns:
            hs = [first_views(H[i], n) for i in range(lo, hi)]
            t0 = time.process_time()
            P = np.array([[e.landmark for e in solve_triplets(
                hs, method="full", partition=part,
                seed=np.random.SeedSequence(123, spawn_key=(k,)), **opts)] for k in range(K)])
            dt = (time.process_time() - t0) / len(hs)
            g = np.array([h.truth.state for h in hs])
            for j, i in enumerate(range(lo, hi)):
                out.write(json.dumps({"geom": i, "n": n, "truth": int(g[j]),
                                      "p": P[:, j].round(6).tolist()}) + "\n")
            idx = np.arange(len(g))
            one = np.log(np.clip(P[:, idx, g], 1e-4, None)).mean(axis=1)
            avg = np.log(np.clip(P.mean(axis=0)[idx, g], 1e-4, None)).mean()
            tv = (0.5 * np.abs(P[0] - P[1]).sum(-1)) if K > 1 else np.zeros(len(g))
            print(f"n={n}: each population {one.round(3)}; their average {avg:.3f}; total "
                  f"variation of populations 0 and 1: median {np.median(tv):.3f}, max "
                  f"{tv.max():.2f}; {dt * 1e3:.0f} ms process time per triplet", flush=True)


def _load(path):
    out = {}
    for line in open(path):
        r = json.loads(line)
        out[(r["geom"], r["n"])] = (np.array(r["p"]).mean(axis=0), r["truth"])
    return out


def compare(base_path: str, *paths: str) -> None:
    base = _load(base_path)
    for path in paths:
        new = _load(path)
        for n in sorted({k[1] for k in new}):
            ks = [k for k in new if k[1] == n and k in base]
            lb = np.array([np.log(max(base[k][0][base[k][1]], 1e-4)) for k in ks])
            ln = np.array([np.log(max(new[k][0][new[k][1]], 1e-4)) for k in ks])
            d = ln - lb
            under = [sum(r[k][0][r[k][1]] < 0.01 for k in ks) for r in (base, new)]
            wrong = [sum(r[k][0].max() > 0.9 and r[k][0].argmax() != r[k][1] for k in ks)
                     for r in (base, new)]
            print(f"{path} n={n} ({len(ks)}): base {lb.mean():.3f}, this {ln.mean():.3f}, paired "
                  f"{d.mean():+.3f} +- {d.std(ddof=1) / np.sqrt(len(d)):.3f}; truth under 1% "
                  f"{under[0]} -> {under[1]}; confidently wrong {wrong[0]} -> {wrong[1]}")


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) >= 6 and argv[0] == "run":
        run(int(argv[1]), argv[2], argv[3], int(argv[4]), argv[5])
        return 0
    if len(argv) >= 3 and argv[0] == "compare":
        compare(argv[1], *argv[2:])
        return 0
    print(__doc__)
    return 2


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    raise SystemExit(main())
