"""How often full flags its answers with the few-views package against the whole budget, on the
first N 3-view histories of an MRCLAM robot (the study's histories: measured bearing tail, 3
views spread over each pass), counted by reason.

    QFG_MRCLAM_DIR=... python experiments/mrclam/pooled_flags.py [DATASET] [ROBOT] [N]

Backs docs/solvers.md, "Accuracy, calibration and speed". Run from the repository root as above
(``QFG_MRCLAM_DIR``: the directory holding the MRCLAM_Dataset* directories).
"""

from __future__ import annotations

import collections
import sys

from qfg.datasets import mrclam
from qfg.harness.studies import mrclam as study
from qfg.solvers import solve_triplets

#: The few-views package switched off: the solver's whole budget at every number of views.
FEW_VIEWS_OFF = {"few_views_budget": None, "few_views_populations": 1, "few_views_escalate": None}


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ds, robot, n = (int(argv[0]) if argv else 6), (int(argv[1]) if len(argv) > 1 else 1), \
        (int(argv[2]) if len(argv) > 2 else 300)
    p = study.prepare_run(mrclam.data_root() / f"MRCLAM_Dataset{ds}",
                          study.MrclamParams(robots=[robot], bearing_tail="measured",
                                             spread_views=3))
    hs = [h for _, h in p.histories][:n]
    for name, kw in (("few-views default", {}), ("whole budget", FEW_VIEWS_OFF)):
        res = solve_triplets(hs, method="full", seed=0, prior=p.prior, **p.solver_options, **kw)
        why = collections.Counter(r.split(" (")[0].split(":")[0] for e in res
                                  for r in (e.reason.split("; ") if e.reason else []))
        print(f"{name}: {sum(e.degenerate for e in res)} of {len(res)} flagged; "
              + "; ".join(f"{k} {v}" for k, v in why.most_common(5)))
    return 0


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    sys.exit(main())
