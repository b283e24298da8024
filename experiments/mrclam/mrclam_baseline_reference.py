"""The baseline's answers on a recorded ``qfg mrclam`` run against the exact posterior (development).

For each history of the run folder whose recorded estimate puts the truth under 1%, solves it
again without headings under the run's prior with normal bearings (0.66 deg, the reference's
only noise model): the baseline with the product of per-point priors (``joint_samples=0``), the
baseline with the whole configuration's prior (the default) and the reference solver (the exact
posterior of the same model). Prints per history the total variation of each baseline from the
reference and p(truth) of the three, then a summary::

    python experiments/mrclam/mrclam_baseline_reference.py out/d5

The landmark ground truth is used only to pick and score the histories.

Backs docs/results/mrclam.md, "The tail model and the model checks", and docs/solvers.md,
"Methods" (``baseline``). Run from the repository root as above, on a run folder made by ``qfg
mrclam`` (its ``run.json`` names the data).
"""

from __future__ import annotations

import json
import sys

import numpy as np

from qfg.harness.studies import mrclam as study
from qfg.solvers import solve_triplet

SIGMA_BEARING = np.deg2rad(0.66)


def main(folder: str) -> None:
    run = json.load(open(f"{folder}/run.json"))["params"]
    prep = study.prepare_run(run["path"], study.params_of(run))
    rows = [r for line in open(f"{folder}/records.jsonl") for r in json.loads(line)["rows"]]
    ests = study.estimates_from_rows(prep, rows)
    out = []
    print("A B C | TV product, TV joint | p(truth): product, joint, reference")
    for (_, h), e in zip(prep.histories, ests, strict=True):
        g = h.truth.state
        if e.landmark[g] >= 0.01:
            continue

        kw = dict(sigma_bearing=SIGMA_BEARING, prior=prep.prior, seed=0)
        prod = solve_triplet(h.bearings, None, method="baseline", joint_samples=0, **kw).landmark
        joint = solve_triplet(h.bearings, None, method="baseline", **kw).landmark
        ref = solve_triplet(h.bearings, None, method="reference", n_samples=4000, **kw).landmark
        tv = [0.5 * np.abs(p - ref).sum() for p in (prod, joint)]
        out.append(tv + [prod[g], joint[g], ref[g]])
        print(*h.landmarks, "|", " ".join(f"{x:.3g}" for x in out[-1]), flush=True)
    if not out:
        print("no history puts the truth under 1%")
        return
    a = np.array(out)
    for name, col in (("product", 0), ("joint", 1)):
        print(f"TV from the reference, {name}: median {np.median(a[:, col]):.2f} "
              f"({a[:, col].min():.2f}-{a[:, col].max():.2f})")
    print(f"{len(a)} histories; truth under 1%: product {int((a[:, 2] < 0.01).sum())}, joint "
          f"{int((a[:, 3] < 0.01).sum())}, reference {int((a[:, 4] < 0.01).sum())}; the joint "
          f"prior nearer the reference in {int((a[:, 1] < a[:, 0]).sum())}")


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    main(sys.argv[1])
