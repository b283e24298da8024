"""The full solver's carried C summaries (``_sis._INCREMENTAL_C``, the default) against refitting
C over all views at every view, paired on development geometries (issue 20, item 2).

    python -m benchmarks.sis_c_paths N VIEWS MAX_VIEWS SEEDS
    python -m benchmarks.sis_c_paths 60 10 10 1,2

Geometries: ``random_triplet_history(default_rng(700000 + i), MAX_VIEWS, 2 deg, 5 deg)``, the
first VIEWS views, solved with every solver seed of SEEDS both ways; prints the mean log
p(truth) of C (clipped at 1e-4) per seed and the paired difference (averaged over the seeds)
with its standard error.
"""

import sys
from dataclasses import replace

import numpy as np

from qfg import metrics
from qfg.simulation import random_triplet_history
from qfg.solvers import _sis, solve_triplets


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    N, k, km = int(argv[0]), int(argv[1]), int(argv[2])
    seeds = [int(x) for x in argv[3].split(",")]
    H = [random_triplet_history(np.random.default_rng(700000 + i), km, np.deg2rad(2.0),
                                np.deg2rad(5.0)) for i in range(N)]
    hs = [replace(h, bearings=h.bearings[:k], headings=h.headings[:k - 1], views=h.views[:k],
                  truth=None) for h in H]
    g = np.array([h.truth.state for h in H])
    res = {}
    try:
        for inc in (False, True):
            _sis._INCREMENTAL_C = inc
            ls = np.array([metrics.log_score(np.array(
                [e.landmark for e in solve_triplets(hs, method="full", seed=s)]), g)
                for s in seeds])
            res[inc] = ls
            print(f"{'carried summaries' if inc else 'refit every view'}: logp per seed "
                  f"{', '.join(f'{v:.3f}' for v in ls.mean(axis=1))}", flush=True)
    finally:
        _sis._INCREMENTAL_C = True
    d = (res[True] - res[False]).mean(axis=0)
    print(f"paired (carried - refit) {d.mean():+.3f} +- {d.std(ddof=1) / np.sqrt(N):.3f}")


if __name__ == "__main__":
    main()
