"""Algorithm 2 on the full 50-landmark map: 117,600 triplets, 5,527,200 factors.

Builds ``full_map(L)`` with the shipped EDC tensor, gives every 50th triplet a random prior, runs
``propagate`` and prints wall and CPU seconds of each step and the peak RSS.

Backs docs/graph.md, "Speed of building and of Algorithms 2 and 3". Run from the repository root
(default L = 50)::

    /usr/bin/time -v python experiments/graph/propagate_50.py [L]
"""

from __future__ import annotations

import resource
import sys
import time

import numpy as np


def main(L: int = 50):
    from qfg.graph import full_map
    from qfg.propagation import propagate

    rng = np.random.default_rng(0)
    t, c = time.perf_counter(), time.process_time()
    g = full_map(L)
    for tr in g.triplets[::50]:
        g.add_triplet(tr, rng.random(20))
    t1, c1 = time.perf_counter(), time.process_time()
    r = propagate(g)
    t2, c2 = time.perf_counter(), time.process_time()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"L={L}: {g.n_triplets} triplets, {g.n_factors} factors, {int(g.seen.sum())} seen; "
          f"build {t1 - t:.1f} s wall {c1 - c:.1f} s CPU; propagate {t2 - t1:.1f} s wall "
          f"{c2 - c1:.1f} s CPU; reached {int(r.reached.sum())}; peak RSS {rss:.0f} MiB")


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 50)
