"""qfg's exact engine beside pgmpy and GTSAM on public UAI 2014 instances.

Every instance of the UAI 2014 directory (``--data DIR``, else ``$QFG_UAI_DIR``: its PR/ and MAR/,
one row per model; see its README) whose exact answer fits: the evidence is clamped into the model
first (the same clamped model is given to every engine), then each engine computes every
variable's marginal:

* ``qfg``: :class:`qfg.inference.JunctionTree` (one calibration; also log Z);
* ``pgmpy``: ``VariableElimination``, one query per variable (its default "greedy" order; its
  junction tree, ``BeliefPropagation``, triangulates the 10x10 grid into a clique of 2^38 entries
  and asks for 256 GiB; ``query(joint=False)`` with "MinFill" asks for 64 GiB on Promedus_24);
* ``gtsam``: ``gtsam.DiscreteMarginals`` (elimination to a Bayes tree, one query per variable),
  only where :func:`qfg.inference.exact.gtsam_estimate` fits the budget.

Each (instance, engine) runs in its own process with a time limit, engines interleaved per
instance (qfg, pgmpy, gtsam, then the next instance), each with one BLAS/OpenMP thread. Times
are the process's CPU seconds (reading the file excluded): on the shared 2-core machine wall
time mostly measures the other processes' load; wall seconds are kept in the JSON. Errors: the
largest absolute difference to the competition's reference marginals (6 significant digits:
5e-7 is agreement), else to qfg; ``log10 Z`` against the ``.PR`` reference.

Run: ``python -m benchmarks.bench_uai [--data DIR] [--timeout S] [--out FILE]``; ``python -m
benchmarks uai`` skips it when ``$QFG_UAI_DIR`` is not set.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ENGINES = ("qfg", "pgmpy", "gtsam")

#: The environment variable naming the UAI 2014 directory (its PR/ and MAR/ folders).
DATA_ENV = "QFG_UAI_DIR"

_CHILD = r"""
import json, sys, time, warnings, numpy as np
from qfg.inference import read_uai, read_evid, JunctionTree
from qfg.inference.evidence import clamp
path, evid, engine = sys.argv[1], sys.argv[2], sys.argv[3]
source = read_uai(path)
ev = read_evid(evid) if evid else {}
model = clamp(source, ev)
out = {}
t_start, c_start = time.perf_counter(), time.process_time()
if engine == "qfg":
    jt = JunctionTree(model)
    P, logz, _ = jt.calibrate()
    out["log10_z"] = logz / np.log(10)
    out["width"] = jt.estimate.width
elif engine == "pgmpy":
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from pgmpy.factors.discrete import DiscreteFactor
        from pgmpy.inference import VariableElimination
        from pgmpy.models import DiscreteMarkovNetwork
    import networkx as nx
    names = [f"x{v}" for v in range(model.n)]
    G = nx.Graph()
    G.add_nodes_from(range(model.n))
    for s in model.scopes:
        G.add_edges_from((a, b) for i, a in enumerate(s) for b in s[i + 1:])
    P = np.zeros((model.n, max(model.cards)))
    for comp in nx.connected_components(G):
        comp = sorted(comp)
        cs = set(comp)
        fac = [DiscreteFactor([names[v]], [model.cards[v]], np.ones(model.cards[v])) for v in comp]
        fac += [DiscreteFactor([names[v] for v in s], [model.cards[v] for v in s],
                               t / t.max() if t.max() > 0 else t)
                for s, t in zip(model.scopes, model.tables) if s and s[0] in cs]
        if len(comp) == 1:
            p = np.ones(model.cards[comp[0]])
            for f in fac:
                p = p * f.values
            P[comp[0], :len(p)] = p / p.sum()
            continue
        mn = DiscreteMarkovNetwork()
        mn.add_nodes_from([names[v] for v in comp])
        mn.add_edges_from((names[a], names[b]) for a, b in G.subgraph(comp).edges)
        mn.add_factors(*fac)
        ve = VariableElimination(mn)
        res = {}
        for v in comp:       # one query per variable: pgmpy plans each (its "greedy" order)
            res[names[v]] = ve.query(variables=[names[v]], show_progress=False)
        for v in comp:
            m = np.asarray(res[names[v]].values, float)
            P[v, :len(m)] = m / m.sum()
else:
    import gtsam
    from qfg.inference.exact import gtsam_estimate
    from qfg.inference.memory import memory_budget
    need = gtsam_estimate(model)
    if need > memory_budget():
        print(json.dumps({"refused": f"refused, estimate {need:.3g} bytes > budget "
                                     f"{memory_budget():.3g}"}))
        sys.exit(0)
    graph = gtsam.DiscreteFactorGraph()
    for s, t in zip(model.scopes, model.tables):
        if s:
            graph.push_back(gtsam.DecisionTreeFactor([(v, model.cards[v]) for v in s],
                                                     np.asarray(t, float).ravel().tolist()))
    marg = gtsam.DiscreteMarginals(graph)
    P = np.zeros((model.n, max(model.cards)))
    touched = {v for s in model.scopes for v in s}
    for v in range(model.n):
        c = model.cards[v]
        if v in touched:
            p = np.asarray(marg.marginalProbabilities((v, c)), float)
        else:
            p = np.ones(c)
        P[v, :c] = p / p.sum()
out["seconds"] = time.process_time() - c_start       # CPU: the machine is shared
out["wall"] = time.perf_counter() - t_start
from qfg.inference.evidence import expand_marginals
P = expand_marginals(P, source, ev)          # observed rows one-hot over their own states
out["P"] = [P[v, :c].tolist() for v, c in enumerate(source.cards)]
print(json.dumps(out))
"""


def _reference(path: Path):
    if not path.exists():
        return None
    from qfg.inference.tasks import read_result

    return read_result(path)


def instances(data: Path) -> list[dict]:
    """One entry per model name: its .uai, .evid and the references found in PR/ and MAR/."""
    out: dict[str, dict] = {}
    for task in ("MAR", "PR"):
        for uai in sorted((data / task).glob("*.uai")):
            e = out.setdefault(uai.stem, {"name": uai.stem, "uai": uai, "evid": None})
            ev = uai.with_name(uai.name + ".evid")
            if ev.exists() and e["evid"] is None:
                e["evid"] = ev
            ref = _reference(uai.with_name(f"{uai.name}.{task}"))
            if ref is not None:
                e[task] = ref
    return list(out.values())


def run_engine(inst, engine, timeout):
    cmd = [sys.executable, "-c", _CHILD, str(inst["uai"]), str(inst["evid"] or ""), engine]
    # one thread each, as the competition ran solvers: a threaded BLAS on a loaded 2-core
    # machine spends many times the work spinning, in every engine
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"error": f"stopped at the {timeout:.0f} s wall-clock limit"}
    if r.returncode != 0:
        return {"error": r.stderr.strip().splitlines()[-1][:80] if r.stderr.strip() else "failed"}
    return json.loads(r.stdout.strip().splitlines()[-1])


def _maxerr(P, ref):
    return max(float(np.abs(np.asarray(p) - r).max()) for p, r in zip(P, ref, strict=True))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get(DATA_ENV) or None,
                    help=f"the UAI 2014 directory holding PR/ and MAR/ (default: ${DATA_ENV})")
    ap.add_argument("--timeout", type=float, default=300.0)
    ap.add_argument("--out", default=None, help="JSON file for the rows")
    args = ap.parse_args(argv)
    if not args.data:
        ap.error(f"--data: no UAI 2014 directory; pass --data DIR or set {DATA_ENV}")
    if not Path(args.data).is_dir():
        ap.error(f"--data: {args.data} is not a directory")
    from qfg.inference import read_evid, read_uai

    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else []
    print(f"# load before: {' '.join(load)}")
    rows = []
    for inst in instances(Path(args.data)):
        model = read_uai(inst["uai"])
        ev = read_evid(inst["evid"]) if inst["evid"] else {}
        row = {"instance": inst["name"], "variables": model.n, "max_card": max(model.cards),
               "evidence": len(ev)}
        res = {e: run_engine(inst, e, args.timeout) for e in ENGINES}   # interleaved
        q = res["qfg"]
        row["width"] = q.get("width")
        for e in ENGINES:
            r = res[e]
            if "P" not in r:
                row[e] = r.get("refused") or r.get("error")
                continue
            ref = inst.get("MAR")
            err = _maxerr(r["P"], ref) if ref is not None else (
                _maxerr(r["P"], [np.array(p) for p in q["P"]]) if "P" in q else float("nan"))
            row[e] = {"seconds": r["seconds"], "max_error": err,
                      "vs": "reference" if ref is not None else "qfg"}
        if "PR" in inst and "log10_z" in q:
            row["log10_z_error"] = abs(q["log10_z"] - inst["PR"])
        rows.append(row)
        print(_line(row), flush=True)
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else []
    print(f"# load after: {' '.join(load)}")
    if args.out:
        Path(args.out).write_text(json.dumps(rows, indent=1))
    return rows


def _cell(r):
    return f"{r['seconds']:.3g} s ({r['max_error']:.1g})" if isinstance(r, dict) else str(r)


def _line(row) -> str:
    q = row["qfg"]
    ratios = []
    for e in ("pgmpy", "gtsam"):
        r = row[e]
        ratios.append(f"{r['seconds'] / q['seconds']:.3g}x" if isinstance(r, dict)
                      and isinstance(q, dict) else "-")
    pr = f"{row['log10_z_error']:.1g}" if "log10_z_error" in row else "-"
    return (f"| {row['instance']} | {row['variables']} | {row['max_card']} | {row['evidence']} | "
            f"{row['width']} | {_cell(q)} | {pr} | {_cell(row['pgmpy'])} | {ratios[0]} | "
            f"{_cell(row['gtsam'])} | {ratios[1]} |")


def rows_for_doc(rows, load_before="", load_after="") -> list[dict]:
    """The rows of :func:`main` as ``python -m benchmarks`` rows: one per instance, value = qfg's
    CPU seconds, the note the rest (errors, pgmpy and GTSAM seconds and ratios)."""
    out = []
    for r in rows:
        q = r["qfg"]
        if not isinstance(q, dict):
            out.append({"name": r["instance"], "value": float("nan"), "unit": "s",
                        "note": f"qfg: {q}"})
            continue
        parts = [f"error {q['max_error']:.1g} vs {q['vs']}"]
        if "log10_z_error" in r:
            parts.append(f"log10 Z error {r['log10_z_error']:.1g}")
        for e, label in (("pgmpy", "pgmpy VE"), ("gtsam", "GTSAM")):
            x = r[e]
            if isinstance(x, dict):
                parts.append(f"{label} {x['seconds']:.3g} s = {x['seconds'] / q['seconds']:.3g}x "
                             f"(error {x['max_error']:.1g})")
            else:
                parts.append(f"{label}: {x}")
        out.append({"name": f"{r['instance']}: {r['variables']} variables, largest card "
                            f"{r['max_card']}, width {r['width']}, {r['evidence']} observed",
                    "value": q["seconds"], "unit": "s (qfg CPU)", "note": "; ".join(parts)})
    if load_before or load_after:
        out.append({"name": "load average (1, 5, 15 min) before / after", "value": float("nan"),
                    "unit": "", "note": f"{load_before} / {load_after}"})
    return out


def run():
    """``python -m benchmarks uai``: skipped (:class:`benchmarks.Skip`) unless ``$QFG_UAI_DIR``
    names the UAI 2014 directory."""
    from benchmarks import Skip

    data = os.environ.get(DATA_ENV)
    if not data or not Path(data).is_dir():
        raise Skip(f"no UAI 2014 data: set {DATA_ENV} to the directory holding PR/ and MAR/")
    before = " ".join(Path("/proc/loadavg").read_text().split()[:3])
    rows = main(["--data", data])
    after = " ".join(Path("/proc/loadavg").read_text().split()[:3])
    return rows_for_doc(rows, before, after)


if __name__ == "__main__":
    t0 = time.time()
    main()
    print(f"# total {time.time() - t0:.0f} s")
