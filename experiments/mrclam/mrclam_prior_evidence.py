"""Can the measurements choose the prior? The reference solver's evidence on MRCLAM passes.

The exact posterior is over-confident on the held-out datasets' single passes because the arena
box does not fit their geometry (docs/mrclam.md, "Held out: the misfit is in the geometry, not
in the errors"), and the priors tried against it each helped one development set and hurt the
other. A prior is a model of the data too: its marginal likelihood
``Z = p(measurements | prior)`` (:attr:`qfg.solvers.TripletEstimate.log_evidence`, the reference
solver's) says how well it explains the passes without any ground truth. This script solves each
history (the twin's selection: one ordering per landmark set, 120-s passes, ``k`` views spread
over each) with the reference solver under every prior of ``--priors`` and reports, per prior
and ``k``, the mean log p(truth) (clip 1e-4), the truth under 1% and the gap to the answers' own
expectation, and two answers that choose without ground truth:

* ``mixture``: each history's posterior under the equal mixture of the priors, ``sum_i Z_i p_i /
  sum_i Z_i`` (Bayesian model averaging per history);
* ``run``: the prior with the largest sum of log Z over the run's histories (type-II maximum
  likelihood with the histories taken as independent, which they are not: landmark sets share
  images).

Priors (normalized densities of the same configurations, so their Z compare; the log-scale
box is known only up to a constant and is left out):

* ``box``: the arena box (``qfg mrclam``'s default);
* ``path``: :class:`qfg.priors.TrajectoryPrior` over the arena box (C and the first camera from
  the box, every later camera a scale-free step).

The reference solver takes the simple model (normal bearings and headings), without the
odometry's distances.

    QFG_MRCLAM_DIR=... python experiments/mrclam/mrclam_prior_evidence.py --dataset 1 --robots 1
        --reference joint [--views 3 5] [--variants real] [--limit 60]
        [--priors box path] [--seed 0] [--csv out/evidence.csv] [--from-csv out/evidence.csv]

Backs docs/mrclam.md ("Can the measurements choose the prior?", under "Datasets 1-5: the noise
against the joint map") and docs/solvers.md, "Methods" (``reference``). Run from the repository
root as above (``QFG_MRCLAM_DIR``: the directory holding the MRCLAM_Dataset* directories).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from qfg.harness.studies import mrclam as study
from qfg.metrics import clustered_se, expected_log_score, log_score, truth_under
from qfg.priors import TrajectoryPrior
from qfg.solvers import solve_triplet

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mrclam_synthetic_twin import reference_dataset, select, twin, write_rows  # noqa: E402

PRIORS = ("box", "path")
CLIP = 1e-4


def make_prior(name: str, box):
    return TrajectoryPrior(box) if name == "path" else box


def solve_all(hs, priors: dict, seed: int) -> dict:
    """{prior name: (landmark (T, m), log evidence (T,))} by the reference solver."""
    out = {}
    for name, pr in priors.items():
        P, Z = [], []
        for i, h in enumerate(hs):
            est = solve_triplet(h, method="reference", seed=np.random.SeedSequence(
                seed, spawn_key=(i,)), prior=pr)
            P.append(est.landmark)
            Z.append(est.log_evidence)
        out[name] = (np.array(P), np.array(Z))
    return out


def mixture(P: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """(T, m) the per-history posterior under the equal mixture of the priors: P (I, T, m),
    Z (I, T) log evidence (NaN: that prior left out of the history's mixture)."""
    Zf = np.where(np.isfinite(Z), Z, -np.inf)
    Zf[:, ~np.isfinite(Zf).any(axis=0)] = 0.0          # no evidence at all: equal weights
    w = np.exp(Zf - Zf.max(axis=0, keepdims=True))
    w /= w.sum(axis=0, keepdims=True)
    return np.einsum("it,itm->tm", w, P)


def report(rows: list[dict], names: list[str]) -> None:
    print("\n| variant | views | n | answer | log p(truth) | truth under 1% | gap to self-expected "
          "(SE clustered by landmark set) | sum log Z |")
    print("|---|---|---|---|---|---|---|---|")
    keys = dict.fromkeys((r["variant"], r["views"]) for r in rows)
    for v, k in keys:
        sub = [r for r in rows if r["variant"] == v and r["views"] == k]
        cl = [r["landmarks"] for r in sub]
        sums = {n: float(np.nansum([r[f"logz_{n}"] for r in sub])) for n in names}
        chosen = max(sums, key=sums.get)
        for n in [*names, "mixture", f"run ({chosen})"]:
            col = chosen if n.startswith("run") else n
            ls = np.array([r[f"score_{col}"] for r in sub])
            ex = np.array([r[f"expected_{col}"] for r in sub])
            under = np.mean([r[f"under_{col}"] for r in sub])
            z = f"{sums[n]:.1f}" if n in sums else ""
            print(f"| {v} | {k} | {len(sub)} | {n} | {ls.mean():.3f} | {under:.3f} | "
                  f"{(ls - ex).mean():+.3f} ± {clustered_se(ls - ex, cl):.3f} | {z} |")


def report_paired(rows: list[dict], names: list[str], against: str = "box") -> None:
    """Each answer minus ``against`` per history, and each answer's larger ``k`` minus its
    smallest, paired by robot, landmark set and pass (SE clustered by landmark set)."""
    def key(r):
        return r["variant"], r["robot"], r["landmarks"], round(float(r["start"]), 6)

    views = sorted({r["views"] for r in rows})
    print(f"\n| variant | views | answer | minus {against}, paired | minus {views[0]} views, "
          "paired |")
    print("|---|---|---|---|---|")
    for v in dict.fromkeys(r["variant"] for r in rows):
        first = {key(r): r for r in rows if r["variant"] == v and r["views"] == views[0]}
        for k in views:
            sub = [r for r in rows if r["variant"] == v and r["views"] == k]
            cl = [r["landmarks"] for r in sub]
            for n in [*names, "mixture"]:
                d = np.array([r[f"score_{n}"] - r[f"score_{against}"] for r in sub])
                vs = f"{d.mean():+.3f} ± {clustered_se(d, cl):.3f}" if n != against else ""
                pk = [(r, first[key(r)]) for r in sub if key(r) in first]
                if k != views[0] and pk:
                    e = np.array([r[f"score_{n}"] - f[f"score_{n}"] for r, f in pk])
                    over = f"{e.mean():+.3f} ± {clustered_se(e, [r['landmarks'] for r, _ in pk]):.3f}"
                else:
                    over = ""
                print(f"| {v} | {k} | {n} | {vs} | {over} |")


def read_rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    for r in rows:
        for key, val in r.items():
            if key.startswith(("score_", "expected_", "logz_")):
                r[key] = float(val)
            elif key.startswith("under_"):
                r[key] = val == "True"
            elif key == "views":
                r[key] = int(val)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", type=int, default=6)
    ap.add_argument("--robots", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--reference", choices=("capture", "joint"), default="capture")
    ap.add_argument("--views", type=int, nargs="+", default=[3, 5])
    ap.add_argument("--variants", nargs="+", default=["real"], choices=("real", "clean"))
    ap.add_argument("--limit", type=int, default=60)
    ap.add_argument("--priors", nargs="+", default=["box", "path"], choices=PRIORS)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--csv", type=Path, default=None)
    ap.add_argument("--from-csv", type=Path, default=None)
    a = ap.parse_args(argv)
    if a.from_csv is not None:
        rows = read_rows(a.from_csv)
        names = [k[len("logz_"):] for k in rows[0] if k.startswith("logz_")]
        report(rows, names)
        if "box" in names:
            report_paired(rows, names)
        return
    path, ds = reference_dataset(a.dataset, a.reference)
    box = study.make_prior(ds, "arena")
    priors = {n: make_prior(n, box) for n in a.priors}
    rows = []
    for k in a.views:
        prep = study.prepare_run(path, study.MrclamParams(robots=a.robots or (), spread_views=k),
                                 dataset=ds)
        sel = select(prep, a.limit)
        for v in a.variants:
            rng = np.random.default_rng(np.random.SeedSequence(a.seed, spawn_key=(k, 7)))
            hs = [h if v == "real" else twin(h, rng, prep.solver_options, bearings=True,
                                             odometry=True, noise=0.0) for _, h in sel]
            hs = [dataclasses.replace(h, distances=None) for h in hs]
            t0 = time.time()
            sol = solve_all(hs, priors, a.seed)
            g = np.array([h.truth.state for h in hs])
            answers = {n: sol[n][0] for n in a.priors}
            answers["mixture"] = mixture(np.stack([sol[n][0] for n in a.priors]),
                                         np.stack([sol[n][1] for n in a.priors]))
            scores = {n: log_score(P, g, clip=CLIP) for n, P in answers.items()}
            expected = {n: expected_log_score(P, clip=CLIP) for n, P in answers.items()}
            under = {n: truth_under(P, g) for n, P in answers.items()}
            print(f"k={k} {v}: {len(hs)} histories ({time.time() - t0:.0f} s)", flush=True)
            for i, h in enumerate(hs):
                row = dict(variant=v, views=k, robot=sel[i][0],
                           landmarks="-".join(map(str, h.landmarks)), start=float(h.views[0]))
                for n in answers:
                    row[f"score_{n}"] = float(scores[n][i])
                    row[f"expected_{n}"] = float(expected[n][i])
                    row[f"under_{n}"] = bool(under[n][i])
                for n in a.priors:
                    row[f"logz_{n}"] = float(sol[n][1][i])
                rows.append(row)
    if a.csv:
        write_rows(a.csv, rows)
    report(rows, a.priors)
    if "box" in a.priors:
        report_paired(rows, a.priors)


if __name__ == "__main__":
    main()
