"""Full's rejuvenation (option ``rejuvenate``) on development geometries of the
views20 preset, paired against the defaults and against the reference solver.

    python experiments/solvers/sis_rejuvenation.py run LO HI VIEWS OUT [VARIANT ...] [--run-seed S]
        [--replicate R]
    python experiments/solvers/sis_rejuvenation.py reference LO HI N OUT [--run-seed S]
    python experiments/solvers/sis_rejuvenation.py report OUT [OUT ...] [--ref REF]

Geometries: the views20 preset's, rebuilt as ``qfg.harness.studies.single_triplet.run_task``
does for its sweep but with the development run seed 2 (``scenario_rng(2, i)``, geometry seed +
1, 20 views at 2/5 deg, the first n; the preset reports seed 1, which ``--run-seed 1`` rebuilds
for a look at single cases, not for choices): geometries LO..HI-1. The solver
seed is the study's own for full (``SeedSequence(solver_root.entropy, spawn_key=(1000 + n,
METHODS.index("full")))``; the reference's for ``reference``). ``run`` solves every (geometry,
n) at full's defaults and with each VARIANT (JSON options of the solver, e.g. ``'{"rejuvenate":
2}'``) and appends one JSON line per (geometry, n) to OUT. ``--replicate R`` (R > 0) solves with
another seed of the same geometry (spawn key extended by R), for a second look at Monte Carlo
luck (each line holds the defaults and the variants of one seed). ``report``: per n and
variant, mean log p(truth) (clip 1e-4) paired against the defaults
with its standard error, confidently wrong (p_max > 0.9 on a wrong state), flagged, median ESS,
the median time ratio; with ``--ref`` (lines of ``reference``), the mean total variation and
KL(reference || method) to the reference on the geometries it has, paired against the
defaults. Single calls, one at a time: times on a shared machine compare within a run only.

Backs docs/solvers.md, "More views" and "Accuracy, calibration and speed". Run from the
repository root as above.
"""

from __future__ import annotations

import json
import sys
import time
from collections import defaultdict

import numpy as np


def geometry(i, k, run_seed=2):
    from qfg.harness.runner import scenario_rng
    from qfg.harness.studies.single_triplet import first_views
    from qfg.partitions import get as get_partition
    from qfg.simulation import random_triplet_history

    part = get_partition("edc")
    rng = scenario_rng(run_seed, i)
    geometry_seed = int(rng.integers(2**63))
    root = np.random.SeedSequence(int(rng.integers(2**63)))
    hmax = random_triplet_history(np.random.default_rng(geometry_seed + 1), 20, np.deg2rad(2.0),
                                  np.deg2rad(5.0), partition=part)
    return first_views(hmax, k), root, part


def solver_seed(root, k, method, replicate=0):
    from qfg.harness.studies.single_triplet import METHODS

    key = (1000 + k, METHODS.index(method)) + ((replicate,) if replicate else ())
    return np.random.SeedSequence(root.entropy, spawn_key=key)


def run(lo, hi, views, out, variants, run_seed=2, replicate=0):
    from qfg.solvers import solve_triplet

    with open(out, "a") as fh:
        for i in range(lo, hi):
            for k in views:
                h, root, part = geometry(i, k, run_seed)
                rec = {"g": i, "n": k, "gt": int(h.truth.state)}
                if replicate:
                    rec["rep"] = replicate
                for name, o in [("default", {})] + [(json.dumps(v, sort_keys=True), v)
                                                    for v in variants]:
                    t0 = time.perf_counter()
                    e = solve_triplet(h, method="full", partition=part,
                                      seed=solver_seed(root, k, "full", replicate), **o)
                    dt = time.perf_counter() - t0
                    rec[name] = {"p": np.asarray(e.landmark, float).tolist(), "t": dt,
                                 "flag": bool(e.degenerate), "ess": float(e.ess)}
                fh.write(json.dumps(rec) + "\n")
                fh.flush()
            print(i, "done", time.strftime("%H:%M:%S"), flush=True)


def reference(lo, hi, k, out, run_seed=2):
    from qfg.solvers import solve_triplet

    with open(out, "a") as fh:
        for i in range(lo, hi):
            h, root, part = geometry(i, k, run_seed)
            t0 = time.perf_counter()
            e = solve_triplet(h, method="reference", partition=part,
                              seed=solver_seed(root, k, "reference"))
            fh.write(json.dumps({"g": i, "n": k, "gt": int(h.truth.state),
                                 "p": np.asarray(e.landmark, float).tolist(), "ess": float(e.ess),
                                 "t": time.perf_counter() - t0, "flag": bool(e.degenerate)}) + "\n")
            fh.flush()
            print(i, "done", time.strftime("%H:%M:%S"), flush=True)


def _log_p(r, name):
    return float(np.log(np.clip(r[name]["p"][r["gt"]], 1e-4, 1.0)))


def _conf_wrong(r, name):
    p = np.asarray(r[name]["p"])
    return float(p.max() > 0.9 and int(np.argmax(p)) != r["gt"])


def _se(d):
    d = np.asarray(d, dtype=float)
    return d.std(ddof=1) / np.sqrt(d.size) if d.size > 1 else float("nan")


def report(files, ref_file=None):
    recs = [json.loads(line) for f in files for line in open(f)]
    ref = {}
    if ref_file:
        ref = {(r["g"], r["n"]): r for r in map(json.loads, open(ref_file))}
    by = defaultdict(list)
    for r in recs:
        by[r["n"]].append(r)
    names = sorted({k for r in recs for k in r if k not in ("g", "n", "gt", "rep")} - {"default"})
    lines = []
    for n in sorted(by):
        for name in names:
            R = [r for r in by[n] if name in r]
            if not R:
                continue
            d = np.array([_log_p(r, "default") for r in R])
            v = np.array([_log_p(r, name) for r in R])
            tr = np.median([r[name]["t"] / r["default"]["t"] for r in R])
            lines.append(
                f"n={n} N={len(R)} {name}: log p(truth) default {d.mean():.3f} variant "
                f"{v.mean():.3f} paired {np.mean(v - d):+.3f} +- {_se(v - d):.3f} | confidently "
                f"wrong {np.mean([_conf_wrong(r, 'default') for r in R]):.3f} -> "
                f"{np.mean([_conf_wrong(r, name) for r in R]):.3f} | flagged "
                f"{np.mean([r['default']['flag'] for r in R]):.3f} -> "
                f"{np.mean([r[name]['flag'] for r in R]):.3f} | median ESS "
                f"{np.median([r['default']['ess'] for r in R]):.0f} -> "
                f"{np.median([r[name]['ess'] for r in R]):.0f} | median time ratio {tr:.2f} "
                f"(default median {np.median([r['default']['t'] for r in R]):.3f} s)")
            Rr = [r for r in R if (r["g"], n) in ref]
            if Rr:
                tv, kl = [], []
                for r in Rr:
                    p = np.asarray(ref[(r["g"], n)]["p"])

                    def dist(q, p=p):
                        q = np.asarray(q)
                        return (0.5 * np.abs(p - q).sum(),
                                float(np.sum(p * (np.log(np.clip(p, 1e-12, 1))
                                                  - np.log(np.clip(q, 1e-4, 1))))))

                    (a0, b0), (a1, b1) = dist(r["default"]["p"]), dist(r[name]["p"])
                    tv.append((a0, a1))
                    kl.append((b0, b1))
                tv, kl = np.array(tv), np.array(kl)
                lines.append(
                    f"    against the reference (N={len(Rr)}): total variation {tv[:, 0].mean():.3f} "
                    f"-> {tv[:, 1].mean():.3f} (paired {np.mean(tv[:, 1] - tv[:, 0]):+.3f} +- "
                    f"{_se(tv[:, 1] - tv[:, 0]):.3f}), KL {kl[:, 0].mean():.3f} -> "
                    f"{kl[:, 1].mean():.3f} (paired {np.mean(kl[:, 1] - kl[:, 0]):+.3f} +- "
                    f"{_se(kl[:, 1] - kl[:, 0]):.3f})")
    return "\n".join(lines)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in ("run", "reference", "report"):
        raise SystemExit(__doc__)
    cmd, rest = argv[0], argv[1:]
    run_seed = 2
    if "--run-seed" in rest:
        j = rest.index("--run-seed")
        run_seed = int(rest[j + 1])
        rest = rest[:j] + rest[j + 2:]
    replicate = 0
    if "--replicate" in rest:
        j = rest.index("--replicate")
        replicate = int(rest[j + 1])
        rest = rest[:j] + rest[j + 2:]
    if cmd == "run":
        run(int(rest[0]), int(rest[1]), [int(v) for v in rest[2].split(",")], rest[3],
            [json.loads(v) for v in rest[4:]], run_seed, replicate)
    elif cmd == "reference":
        reference(int(rest[0]), int(rest[1]), int(rest[2]), rest[3], run_seed)
    else:
        ref = None
        if "--ref" in rest:
            j = rest.index("--ref")
            ref = rest[j + 1]
            rest = rest[:j] + rest[j + 2:]
        print(report(rest, ref))


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    main()
