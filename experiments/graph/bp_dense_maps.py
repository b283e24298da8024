"""Loopy BP against exact marginals and uniform on maps of growing factor overlap.

Graphs: the propagation study's (``propagation_graph(scenario_rng(BASE, i), tensor("edc"))``,
fast-solver priors), the full 6-landmark map over the same seen triplets, and that map with a
random 10, 20, 35 and 50% of its factors (``default_rng(1000 + i)``). Score: mean log p(truth)
over the unseen triplets (clipped at 1e-4; uniform is -3.00); exact marginals where they fit
2 GiB. Summaries by :func:`qfg.graph.factor_overlap` bins and by the rule ``loopy_bp`` warns with.

Backs docs/graph.md, "Loopy BP on dense maps" (BASE 0, N 20 to choose the thresholds; BASE 1,
N 10 to report). Run from the repository root::

    python experiments/graph/bp_dense_maps.py BASE N
"""

from __future__ import annotations

import itertools
import sys
import warnings

import numpy as np


def _score(P, truth, mask):
    lp = np.log(np.clip(P[np.arange(len(truth)), truth], 1e-4, 1.0))
    return float(lp[mask].mean())


def main(base: int, n: int):
    from qfg import composition
    from qfg.graph import factor_overlap, map_from_triplets, truth_states
    from qfg.harness.runner import scenario_rng
    from qfg.inference import BP_DEGREE_WARN, BP_OVERLAP_WARN, exact_marginals, loopy_bp
    from qfg.random_graphs import propagation_graph

    T = composition.tensor("edc")
    allt = list(itertools.permutations(range(6), 3))
    rows = []          # (kind, overlap, degree, bp, exact)
    for i in range(n):
        pg = propagation_graph(scenario_rng(base, i), T)
        g = pg.graph
        tr = truth_states(g.triplets, pg.landmarks)
        ov = factor_overlap(g)
        bp = loopy_bp(g, max_iters=300, warn=False).probabilities
        ex = exact_marginals(g).probabilities
        rows.append(("study", ov["overlap"], ov["mean_degree"], _score(bp, tr, ~g.seen),
                     _score(ex, tr, ~g.seen)))
        seen = {t: p for t, p in zip(g.triplets, g.priors, strict=True) if p is not None}
        full = map_from_triplets(seen, allt, tensor=T)
        trf = truth_states(full.triplets, pg.landmarks)
        ovf = factor_overlap(full)
        bf = loopy_bp(full, max_iters=300, warn=False).probabilities
        rows.append(("full", ovf["overlap"], ovf["mean_degree"], _score(bf, trf, ~full.seen),
                     np.nan))
        rs = np.random.default_rng(1000 + i)
        for keep in (0.1, 0.2, 0.35, 0.5):
            fs = [f for f in full.factors if rs.random() < keep]
            gp = map_from_triplets(seen, allt, tensor=T, discover=False)
            for f in fs:
                gp.add_composition(f)
            op = factor_overlap(gp)
            b = loopy_bp(gp, max_iters=300, warn=False).probabilities
            try:
                e = _score(exact_marginals(gp, memory=2 ** 31).probabilities, trf, ~gp.seen)
            except ValueError:
                e = np.nan
            rows.append(("partial", op["overlap"], op["mean_degree"], _score(b, trf, ~gp.seen), e))
        print(f"{i}: study overlap {ov['overlap']:.2f}, full BP {rows[-5][3]:.2f}", flush=True)
    R = np.array([r[1:] for r in rows], dtype=float)
    kind = np.array([r[0] for r in rows])
    for k in ("study", "partial", "full"):
        for lo, hi in ((0, .25), (.25, .5), (.5, .75), (.75, 1.01)):
            s = (kind == k) & (R[:, 0] >= lo) & (R[:, 0] < hi)
            if s.any():
                print(f"{k} overlap [{lo}, {hi}): {s.sum()} graphs, mean degree "
                      f"{R[s, 1].mean():.1f}, BP {R[s, 2].mean():.2f}, exact "
                      f"{np.nanmean(R[s, 3]) if np.isfinite(R[s, 3]).any() else np.nan:.2f} "
                      f"({np.isfinite(R[s, 3]).sum()} fit)")
    w = (R[:, 0] >= BP_OVERLAP_WARN) & (R[:, 1] >= BP_DEGREE_WARN)
    bad = R[:, 2] < np.log(1 / 20) - 1
    print(f"warned: {w.sum()} graphs, BP {R[w, 2].mean():.2f}, more than 1 nat below uniform "
          f"{bad[w].mean():.0%}; not warned: {(~w).sum()} graphs, BP {R[~w, 2].mean():.2f}, "
          f"{bad[~w].mean():.0%}")


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    warnings.simplefilter("ignore")
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 0, int(sys.argv[2]) if len(sys.argv) > 2 else 20)
