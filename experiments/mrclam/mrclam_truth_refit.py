"""Does the landmarks' ground truth decide any score of a recorded ``qfg mrclam`` run on dataset 6?
(a check of the scoring, not of a method)

The landmarks' ground truth sits a few centimetres from where the bearings put them
(``measure_noise``: 2.6 cm at the median on dataset 6). This refits every landmark from every
robot's bearings and motion-capture poses (``qfg.nonlinear.intersect_rays``, as ``measure_noise``
does), counts the ordered triplets whose EDC state differs between the two, and scores each run's
estimates against both: if the truths the estimates miss were the ground truth's own errors, the
refitted truth would score them better.

    QFG_MRCLAM_DIR=... python experiments/mrclam/mrclam_truth_refit.py out/d6-run/triplets.csv [...]

Backs docs/mrclam.md, "Measured noise (dataset 6, motion capture)". Run from the repository
root as above (``QFG_MRCLAM_DIR``: the directory holding the MRCLAM_Dataset* directories).
"""

from __future__ import annotations

import csv
import itertools
import sys

import numpy as np

from qfg import partitions
from qfg.datasets import mrclam
from qfg.geometry import to_frame
from qfg.metrics import log_score


def main(paths) -> int:
    ds = mrclam.load(mrclam.data_root() / "MRCLAM_Dataset6")
    robots = [k for k, rd in ds.robots.items() if rd.groundtruth is not None]
    rows = {k: mrclam.landmark_rows(ds, ds.robots[k]) for k in robots}
    m = mrclam.measure_noise(ds, offsets=[-0.040])
    refit = mrclam.refit_landmarks(ds, robots, rows, m.measurement_offset, m.bearing.sigma90)
    part = partitions.get("edc")
    tri = np.array(list(itertools.permutations(range(len(ds.landmark_ids)), 3)))

    def states(P):
        return part.state_of(to_frame(P[tri[:, 2]], P[tri[:, 0]], P[tri[:, 1]]))

    s0, s1 = states(ds.landmark_xy), states(refit)
    differ = s0 != s1
    print(f"ordered triplets {len(tri)}, EDC state differs between ground truth and refit: "
          f"{differ.sum()} ({100 * differ.mean():.1f}%)")
    lid = {int(x): i for i, x in enumerate(ds.landmark_ids)}
    at = {tuple(t): k for k, t in enumerate(tri.tolist())}
    for path in paths:
        recs = list(csv.DictReader(open(path)))
        for kind in ("seen", "propagated"):
            sub = [r for r in recs if r["kind"] == kind]
            if not sub:
                continue
            k = np.array([at[(lid[int(r["A"])], lid[int(r["B"])], lid[int(r["C"])])]
                          for r in sub])
            if any(int(r["truth_state"]) != s0[j] for r, j in zip(sub, k, strict=True)):
                raise ValueError(f"{path}: its truth states are not dataset 6's ground truth")
            P = np.array([[float(x) for x in r["probabilities"].split(";")] for r in sub])
            P /= P.sum(axis=1, keepdims=True)   # written with 6 digits
            lg, lr = log_score(P, s0[k]), log_score(P, s1[k])
            miss = lg < np.log(0.01)
            print(f"{path} {kind}: {len(sub)} triplets, {differ[k].sum()} with another state "
                  f"refitted; truth under 1%: {miss.sum()} against the ground truth "
                  f"({(miss & differ[k]).sum()} of them with another state refitted), "
                  f"{(lr < np.log(0.01)).sum()} against the refit; mean log p: "
                  f"{lg.mean():.3f} / {lr.mean():.3f}")
    return 0


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    sys.exit(main(sys.argv[1:]))
