"""State lookup: `Partition.state_of` throughput on 10^6 uniform points in the partition's window
(median of 7 runs after a warm-up)."""


import numpy as np

from benchmarks import median_time
from qfg import partitions


def _median_time(fn, repeats=7):
    return median_time(fn, repeats)


def run():
    rows = []
    n = 10**6
    for name in ("edc", "fdc", "lr", "tpcc"):
        part = partitions.get(name)
        xmin, xmax, ymin, ymax = part.window
        pts = np.random.default_rng(0).uniform([xmin, ymin], [xmax, ymax], size=(n, 2))
        t = _median_time(lambda part=part, pts=pts: part.state_of(pts))
        rows.append({"name": f"{name} state_of, 1e6 points", "value": n / t, "unit": "points/s",
                     "target": ">= 1e7" if name == "edc" else "",
                     "note": f"{t * 1e3:.1f} ms per call"})
    return rows
