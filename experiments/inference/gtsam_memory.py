"""Peak RSS of ``exact_marginals(method="gtsam")`` per entry of the min-fill cliques, the basis of
``qfg.inference.exact.GTSAM_BYTES_PER_ENTRY``.

A band map: triplets i < j < k of L landmarks within a window of w, every composition among
them, a random m-state tensor, half the triplets seen. Prints the clique entries and the bytes
of peak RSS above the baseline (gtsam imported) per entry of (all cliques + the largest three).

Backs docs/uai.md, "Memory" (L w m: 20 4 20, 8 5 6, 10 5 5). Run from the repository root::

    python experiments/inference/gtsam_memory.py L w m
"""
import itertools
import resource
import sys
import time

import gtsam  # noqa: F401  (imported before the baseline is taken)
import numpy as np

from qfg.graph import QualitativeFactorGraph
from qfg.inference import FactorModel
from qfg.inference.exact import clique_sizes, exact_marginals


def main(L: int, w: int, m: int):
    rng = np.random.default_rng(0)
    g = QualitativeFactorGraph(None, tensor=rng.random((m, m, m)) + 0.1)
    for t in itertools.combinations(range(L), 3):
        if max(t) - min(t) < w:
            g.add_triplet(t, rng.random(m) + 0.1 if rng.random() < 0.5 else None)
    g.discover_compositions()
    cs = clique_sizes(FactorModel.from_graph(g))
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    t = time.time()
    exact_marginals(g, method="gtsam", memory=2 ** 40)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    per = (peak - base) / (sum(cs) + sum(sorted(cs)[-3:]))
    print(f"L={L} w={w} m={m} n={g.n_triplets} F={g.n_factors} clique entries {sum(cs):.3g} "
          f"(largest {max(cs):.3g}); peak RSS {peak / 1e6:.0f} MB over a baseline of "
          f"{base / 1e6:.0f} MB: {per:.0f} bytes per entry; {time.time() - t:.1f} s", flush=True)


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    main(*(int(a) for a in sys.argv[1:4]))
