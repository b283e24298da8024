"""Paired views comparison on development geometries: each variant of the full solver against the
first, per number of views, with the cameras of views 1-3 scored as well.

    python experiments/solvers/solver_views_paired.py N VIEWS VARIANT [VARIANT ...]
    python experiments/solvers/solver_views_paired.py 60 3,6,10,15 '{}' '{"move_steps": 1}'

Geometries: ``solver_views.histories(N, max(VIEWS))`` (``default_rng(900000 + i)``,
2/5 deg), the first n views of each solved with ``seed=1``. Per variant and n: mean log p(truth)
of C (clipped at 1e-4) with its standard error, the mean over views 1-3 of the cameras' log
p(truth), flagged answers, median ESS, ms per triplet (one batched call); from the second variant
on, the paired differences against the first with their standard errors.

Backs docs/solvers.md, "More views". Run from the repository root as above.
"""

import json
import sys
import time
from pathlib import Path

import numpy as np

from qfg.solvers import solve_triplets

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solver_views import first_views, histories  # noqa: E402  (the sibling script)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    N, views = int(argv[0]), [int(v) for v in argv[1].split(",")]
    variants = [json.loads(v) for v in argv[2:]] or [{}]
    hs = histories(N, max(views))
    g = np.array([h.truth.state for h in hs])
    cs = np.array([h.truth.camera_states[:3] for h in hs])
    base = {}
    for v in variants:
        for k in views:
            t = time.perf_counter()
            es = solve_triplets([first_views(h, k) for h in hs], method="full", seed=1, **v)
            dt = (time.perf_counter() - t) / N * 1e3
            lp = np.log(np.clip([e.landmark[s] for e, s in zip(es, g, strict=True)], 1e-4, 1))
            lc = np.log(np.clip([[e.cameras[i, cs[j, i]] for i in range(3)]
                                 for j, e in enumerate(es)], 1e-4, 1)).mean(1)
            line = (f"{json.dumps(v):24s} n={k:2d} logp {lp.mean():.3f} +- "
                    f"{lp.std(ddof=1) / np.sqrt(N):.3f} cams1-3 {lc.mean():.3f} flagged "
                    f"{sum(e.degenerate for e in es)} ESS med "
                    f"{np.median([e.ess for e in es]):.0f} {dt:.0f} ms")
            if v is variants[0]:
                base[k] = (lp, lc)
            else:
                d, dc = lp - base[k][0], lc - base[k][1]
                line += (f" | vs first: landmark {d.mean():+.3f} +- "
                         f"{d.std(ddof=1) / np.sqrt(N):.3f}, cams {dc.mean():+.3f} +- "
                         f"{dc.std(ddof=1) / np.sqrt(N):.3f}")
            print(line, flush=True)


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    main()
