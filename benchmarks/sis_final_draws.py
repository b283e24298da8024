"""The full solver's final C draws about C's mode (``_sis._FINAL_AT_MODE``, the default) against
about the lines' least-squares point, paired on development geometries (issue 20, item 2).

    python -m benchmarks.sis_final_draws N VIEWS
    python -m benchmarks.sis_final_draws 20 10

Geometries: ``benchmarks.solver_views.histories(N, VIEWS)`` (``default_rng(900000 + i)``, 2/5
deg), solved with ``seed=1`` both ways. Prints the mean log p(truth) of C (clipped at 1e-4), the
median and 10th percentile of the final ESS and the flagged answers of each, and the paired
difference with its standard error.
"""

import sys

import numpy as np

from benchmarks.solver_views import first_views, histories
from qfg.solvers import _sis, solve_triplets


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    N, k = int(argv[0]), int(argv[1])
    H = histories(N, k)
    hs = [first_views(h, k) for h in H]
    g = np.array([h.truth.state for h in H])
    res = {}
    try:
        for mode in (False, True):
            _sis._FINAL_AT_MODE = mode
            es = solve_triplets(hs, method="full", seed=1)
            lp = np.log(np.clip([e.landmark[s] for e, s in zip(es, g, strict=True)], 1e-4, 1))
            res[mode] = lp
            ess = [e.ess for e in es]
            print(f"at mode {mode!s:5s}: logp {lp.mean():.3f}, ESS median {np.median(ess):.0f}, "
                  f"10th percentile {np.percentile(ess, 10):.1f}, flagged "
                  f"{sum(e.degenerate for e in es)}", flush=True)
    finally:
        _sis._FINAL_AT_MODE = True
    d = res[True] - res[False]
    print(f"paired {d.mean():+.3f} +- {d.std(ddof=1) / np.sqrt(N):.3f}")


if __name__ == "__main__":
    main()
