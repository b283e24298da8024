"""Two recorded ``qfg mrclam`` runs, paired triplet by triplet: which one scores higher, and by how
much beyond its noise.

Each run's ``triplets.csv`` (one row per scored ordered triplet and kind) is matched on (kind, A,
B, C); for each kind present in both, prints the rows matched, each run's mean log p(truth) (as
the run scored it: clip 1e-4) and share of truths under 1%, and the paired difference (second
run minus first) with a standard error clustered by landmark set (the orderings of one set share
their histories, so they are not independent).

    python experiments/mrclam/mrclam_paired.py out/d1-point out/d1-joint [out/d2-point out/d2-joint ...]

Backs docs/results/mrclam.md, "More views per pass: the solver, not the data". Run from the
repository root as above, on run folders made by ``qfg mrclam``.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from qfg.metrics import clustered_se


def read(run: Path) -> dict:
    """{(kind, A, B, C): (log score, truth under 1%)} of a run folder's triplets.csv."""
    path = run / "triplets.csv"
    if not path.is_file():
        raise SystemExit(f"{run}: no triplets.csv (not a finished qfg mrclam run)")
    out = {}
    with open(path, newline="") as fh:
        for line, r in enumerate(csv.DictReader(fh), start=2):
            try:
                key = (r["kind"], int(r["A"]), int(r["B"]), int(r["C"]))
                out[key] = (float(r["log_score"]), float(r["truth_under_1pct"]))
            except (KeyError, ValueError) as e:
                raise SystemExit(f"{path}:{line}: {e!r}") from None
    return out


def compare(a: Path, b: Path) -> list[str]:
    """Table rows for ``b`` minus ``a``, one per kind both runs scored."""
    A, B = read(a), read(b)
    rows = []
    for kind in sorted({k[0] for k in A} & {k[0] for k in B}):
        keys = sorted(k for k in A.keys() & B.keys() if k[0] == kind)
        la, lb = (np.array([X[k][0] for k in keys]) for X in (A, B))
        ua, ub = (np.mean([X[k][1] for k in keys]) for X in (A, B))
        sets = np.unique(["-".join(map(str, sorted(k[1:]))) for k in keys],
                         return_inverse=True)[1]
        d = lb - la
        rows.append(f"| {a.name} | {b.name} | {kind} | {len(keys)} | {la.mean():.3f} / "
                    f"{100 * ua:.1f}% | {lb.mean():.3f} / {100 * ub:.1f}% | {d.mean():+.3f} ± "
                    f"{clustered_se(d, sets):.3f} |")
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", type=Path, nargs="+", help="run folders, in pairs: first, second")
    a = ap.parse_args(argv)
    if len(a.runs) % 2:
        ap.error(f"runs come in pairs; got {len(a.runs)} folders")
    print("| first | second | kind | n | first: log p(truth) / under 1% | second | second minus "
          "first, paired (SE clustered by landmark set) |")
    print("|---|---|---|---|---|---|---|")
    for i in range(0, len(a.runs), 2):
        for row in compare(a.runs[i], a.runs[i + 1]):
            print(row)


if __name__ == "__main__":
    main()
