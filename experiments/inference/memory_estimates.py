"""How close the exact engines' memory estimates come to what numpy allocates.

For each UAI 2014 instance of PR/ and MAR/ObjectDetection_* (the directory ``--data DIR``, else
``$QFG_UAI_DIR``; skipped, with a message, when neither is given) and for band
maps (triplets i < j < k of landmarks within a window, compositions among them, random tensors
of 4-14 states): ``JunctionTree.memory_estimate(task)`` beside the tracemalloc peak of the call
(numpy reports its buffers to tracemalloc), for MAR (linear and log domain), MAP and K-best (k=20).

Backs docs/uai.md, "Memory". Run from the repository root::

    OPENBLAS_NUM_THREADS=1 python experiments/inference/memory_estimates.py [--data DIR]
"""

from __future__ import annotations

import argparse
import os
import tracemalloc
from pathlib import Path


def band(L, w, m=20, seed=0):
    from qfg.random_graphs import band_graph

    return band_graph(L, w, m, seed)


def traced(fn):
    tracemalloc.start()
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("QFG_UAI_DIR") or None,
                    help="the UAI 2014 directory holding PR/ and MAR/ (default: $QFG_UAI_DIR)")
    a = ap.parse_args(argv)
    from qfg.inference import JunctionTree, read_evid, read_uai

    if a.data is None:
        print("no UAI 2014 data (--data DIR or QFG_UAI_DIR): the instances are skipped", flush=True)
        files = []
    elif not Path(a.data).is_dir():
        ap.error(f"--data: {a.data} is not a directory")
    else:
        data = Path(a.data)
        files = sorted(data.glob("PR/*.uai")) + sorted(data.glob("MAR/ObjectDetection_*.uai"))
    for f in files:
        ev = f.with_name(f.name + ".evid")
        jt = JunctionTree(read_uai(f), evidence=read_evid(ev) if ev.exists() else None)
        est = jt.memory_estimate("MAR").bytes
        peak = traced(jt.calibrate)
        print(f"{f.stem}: MAR estimate {est:.3g} B, traced {peak:.3g} B, ratio {est / peak:.2f}"
              f"{' (contracted cliques)' if any(jt.contracted) else ''}", flush=True)
    for L, w, m in ((7, 4, 4), (8, 5, 5), (10, 5, 7), (12, 5, 8), (10, 5, 12), (30, 4, 20),
                    (10, 5, 14)):
        g = band(L, w, m)
        row = []
        for task, k, log in (("MAR", 1, False), ("MAR", 1, True), ("MAP", 1, False),
                             ("KBEST", 20, False)):
            jt = JunctionTree(g)
            est = jt.memory_estimate(task, k=k, log_domain=log).bytes
            if task == "MAR":
                peak = traced(lambda jt=jt, log=log: jt.marginals(log_domain=log))
            else:
                peak = traced(lambda jt=jt, k=k: jt.k_best(k))
            row.append(f"{task}{' log' if log else ''} {est / peak:.2f}")
        print(f"band L={L} w={w} m={m}: estimate / traced: {', '.join(row)}", flush=True)


if __name__ == "__main__":
    main()
