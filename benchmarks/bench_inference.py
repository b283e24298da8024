"""Exact inference, all marginals: qfg one-pass junction tree vs qfg per-variable contraction vs
GTSAM DiscreteMarginals vs pgmpy (junction-tree BeliefPropagation, VariableElimination), on the
same graphs in one run, engines interleaved per graph (median of repeats per graph, then the
median over graphs of each ratio). Families (shipped EDC tensor, m = 20, seen triplets with
Dirichlet(0.5) priors): chains and trees of composition factors, loopy graphs (random factor sets
on 5 landmarks with a cycle), and the propagation study's graphs (qfg.random_graphs.
propagation_graph, scenario streams 0.. of seed 0: its paper preset). pgmpy gets factors rescaled
to max 1 (without it its BP is wrong on some graphs) and runs only where its own
triangulation keeps tables <= 20^5 entries. GTSAM and VE run on the first 3 graphs of each family
whose junction tree has at most 4 triplets per clique (seconds to minutes each). Also: loopy BP
to convergence on full maps of 10, 15, 20 and 25 landmarks (a third of the triplets seen), and its
message step as one matrix product per role against the einsum it replaced. pgmpy is the
optional `bench` extra."""

from __future__ import annotations

import itertools
import sys
import time
import warnings

import numpy as np

from qfg.graph import QualitativeFactorGraph, full_map
from qfg.inference import exact_marginals, size_estimate

N_PER_FAMILY = 12       # graphs per family
N_SLOW = 3              # graphs per family for GTSAM and pgmpy VE
REPEATS = 3
PGMPY_MAX = 20 ** 5     # largest clique table pgmpy may build (its own triangulation)
SLOW_MAX_WIDTH = 4      # GTSAM and pgmpy VE only on graphs whose junction tree has width <= 4


def _tensor():
    from qfg.composition import tensor
    return tensor("edc")


def _prior(rng, m=20):
    return rng.dirichlet(np.full(m, 0.5))


def chain(rng, T, n_fc):
    """Factors (i, i+1, i+2, i+3) for i = 0..n_fc-1: consecutive factors share one triplet."""
    g = QualitativeFactorGraph("edc", tensor=T)
    fs = [(i, i + 1, i + 2, i + 3) for i in range(n_fc)]
    ts = sorted({t for i, j, k, s in fs for t in ((i, j, k), (j, k, s), (i, j, s))})
    for t in ts:
        g.add_triplet(t, _prior(rng) if rng.random() < 0.5 else None)
    for f in fs:
        g.add_composition(f)
    return g


def tree(rng, T, n_fc):
    """Each new factor joins one existing triplet (in a random role) with a new landmark."""
    g = QualitativeFactorGraph("edc", tensor=T)
    fs = [(0, 1, 2, 3)]
    ts = [(0, 1, 2), (1, 2, 3), (0, 1, 3)]
    nxt = 4
    while len(fs) < n_fc:
        a, b, c = ts[rng.integers(len(ts))]
        d = nxt
        nxt += 1
        role = rng.integers(3)
        f = ((a, b, c, d) if role == 0 else (d, a, b, c) if role == 1 else (a, b, d, c))
        i, j, k, s = f
        new = [(i, j, k), (j, k, s), (i, j, s)]
        assert (a, b, c) in new
        fs.append(f)
        ts += [t for t in new if t not in ts]
    for t in sorted(ts):
        g.add_triplet(t, _prior(rng) if rng.random() < 0.5 else None)
    for f in fs:
        g.add_composition(f)
    return g


def loopy(rng, T, n_fc=14, max_width=4):
    """Random factor sets among 5 landmarks with a cycle and a junction tree of width <= 4."""
    import networkx as nx

    all_f = list(itertools.permutations(range(5), 4))
    while True:
        fs = [all_f[i] for i in rng.choice(len(all_f), size=n_fc, replace=False)]
        g = QualitativeFactorGraph("edc", tensor=T)
        ts = sorted({t for i, j, k, s in fs for t in ((i, j, k), (j, k, s), (i, j, s))})
        for t in ts:
            g.add_triplet(t, _prior(rng) if rng.random() < 0.5 else None)
        for f in fs:
            g.add_composition(f)
        if nx.cycle_basis(g.to_networkx()) and size_estimate(g).width <= max_width:
            return g


def study_graphs(T, n):
    from qfg.harness.runner import scenario_rng
    from qfg.inference import ZeroMassError
    from qfg.random_graphs import propagation_graph

    out, i = [], 0
    while len(out) < n:  # graphs whose priors contradict the tensor have no marginals: skipped
        g = propagation_graph(scenario_rng(0, i), T).graph
        i += 1
        try:
            exact_marginals(g)
        except ZeroMassError:
            continue
        out.append(g)
    return out


# ------------------------------------------------------------------ pgmpy
def _pgmpy_models(g):
    """One pgmpy DiscreteMarkovNetwork per connected component (pgmpy's junction tree needs a
    connected network), factors rescaled to max 1: list of (model, variable names, indices)."""
    import networkx as nx

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from pgmpy.factors.discrete import DiscreteFactor
        from pgmpy.models import DiscreteMarkovNetwork
    T = g.table / g.table.max()
    names = [f"v{v}" for v in range(g.n_triplets)]
    G = nx.Graph()
    G.add_nodes_from(range(g.n_triplets))
    for a, b, c in g.factor_vars:
        G.add_edges_from([(a, b), (b, c), (a, c)])
    out = []
    fv = g.factor_vars
    for comp in nx.connected_components(G):
        comp = sorted(comp)
        cs = set(comp)
        mn = DiscreteMarkovNetwork()
        mn.add_nodes_from([names[v] for v in comp])
        fac = []
        for v in comp:
            p = g.priors[v]
            # pgmpy needs a factor on every node: uniform for unseen ones
            fac.append(DiscreteFactor([names[v]], [g.m], np.ones(g.m) if p is None
                                      else p / p.max()))
        for a, b, c in fv:
            if a in cs:
                mn.add_edges_from([(names[a], names[b]), (names[b], names[c]),
                                   (names[a], names[c])])
                fac.append(DiscreteFactor([names[a], names[b], names[c]], [g.m] * 3, T))
        mn.add_factors(*fac)
        out.append((mn, [names[v] for v in comp], comp))
    return out


def pgmpy_width(models) -> int:
    """Largest clique (variables) of pgmpy's own triangulation (the one its junction tree uses)."""
    import networkx as nx

    w = 1
    for mn, names, _ in models:
        if len(names) > 1:
            chordal = mn.triangulate()
            w = max(w, max(len(c) for c in nx.find_cliques(chordal)))
    return w


def pgmpy_bp(models, n, m):
    """Calibrate pgmpy's junction tree once per component, then read every variable's marginal
    from a calibrated clique belief that holds it."""
    from pgmpy.inference import BeliefPropagation

    out = np.zeros((n, m))
    for mn, names, idx in models:
        if len(names) == 1:
            out[idx[0]] = mn.get_factors()[0].values
            continue
        bp = BeliefPropagation(mn)
        bp.calibrate()
        beliefs = bp.get_clique_beliefs()
        home = {}
        for clique in beliefs:
            for x in clique:
                home.setdefault(x, clique)
        for x, v in zip(names, idx, strict=True):
            f = beliefs[home[x]]
            out[v] = f.marginalize([y for y in f.variables if y != x], inplace=False).values
    return out / out.sum(axis=1, keepdims=True)


def pgmpy_ve(models, n, m):
    from pgmpy.inference import VariableElimination

    out = np.zeros((n, m))
    for mn, names, idx in models:
        ve = VariableElimination(mn)
        for x, v in zip(names, idx, strict=True):
            out[v] = ve.query(variables=[x], show_progress=False).values
    return out / out.sum(axis=1, keepdims=True)


# ------------------------------------------------------------------ comparison
def _t(fn):
    t = time.perf_counter()
    out = fn()
    return time.perf_counter() - t, out


def compare(graphs):
    """Per graph: median time of each engine (interleaved repeats) and max |diff| to qfg."""
    have_pgmpy = True
    try:
        import pgmpy  # noqa: F401
    except ImportError:
        have_pgmpy = False
    out = []
    skipped_pgmpy = 0
    n_slow = 0
    for gi, g in enumerate(graphs):
        width = size_estimate(g).width
        slow = n_slow < N_SLOW and width <= SLOW_MAX_WIDTH
        n_slow += slow
        print(f"   graph {gi}: {g.n_triplets} triplets, {g.n_factors} factors, width {width}",
              file=sys.stderr, flush=True)
        engines = {"junction": lambda g=g: np.asarray(exact_marginals(g)),
                   "contract": lambda g=g: np.asarray(exact_marginals(g, method="contract"))}
        if have_pgmpy:
            models = _pgmpy_models(g)
            n, m = g.n_triplets, g.m
            pw = pgmpy_width(models)
            skipped_pgmpy += m ** pw > PGMPY_MAX
        if have_pgmpy and m ** pw <= PGMPY_MAX:   # else pgmpy builds tables of GBs, for minutes
            engines["pgmpy_bp"] = lambda models=models, n=n, m=m: pgmpy_bp(models, n, m)
            if slow:
                engines["pgmpy_ve"] = lambda models=models, n=n, m=m: pgmpy_ve(models, n, m)
        if slow:
            engines["gtsam"] = lambda g=g: np.asarray(exact_marginals(g, method="gtsam"))
        times = {k: [] for k in engines}
        ans = {}
        for rep in range(REPEATS):
            for k, fn in engines.items():
                if k in ("gtsam", "pgmpy_ve") and rep > 0:
                    continue  # seconds per call: one run
                dt, a = _t(fn)
                times[k].append(dt)
                ans[k] = a
        ref = ans["junction"]
        out.append({"n_v": g.n_triplets, "n_fc": g.n_factors, "width": width,
                    "pgmpy_width": pw if have_pgmpy else 0,
                    **{f"t_{k}": float(np.median(v)) for k, v in times.items()},
                    **{f"d_{k}": float(np.abs(a - ref).max()) for k, a in ans.items()}})
    return out


def _family_rows(name, res):
    rows = []
    tj = np.array([r["t_junction"] for r in res])
    rows.append({"name": f"{name}: qfg one-pass junction tree, median per graph",
                 "value": float(np.median(tj)), "unit": "s",
                 "note": f"{len(res)} graphs, {int(np.median([r['n_v'] for r in res]))} triplets / "
                         f"{int(np.median([r['n_fc'] for r in res]))} factors (median), widths "
                         f"{min(r['width'] for r in res)}-{max(r['width'] for r in res)}"})
    for k, label, target in (("contract", "qfg per-variable contraction", ">= 10 (study graphs)"),
                             ("pgmpy_bp", "pgmpy BeliefPropagation", "> 1"),
                             ("pgmpy_ve", "pgmpy VariableElimination", ""),
                             ("gtsam", "GTSAM DiscreteMarginals", ">= 100")):
        sel = [r for r in res if f"t_{k}" in r]
        if not sel:
            continue
        ratio = np.array([r[f"t_{k}"] / r["t_junction"] for r in sel])
        diff = max(r[f"d_{k}"] for r in sel)
        miss = ""
        if k == "pgmpy_bp" and len(sel) < len(res):
            miss = (f"; not run on {len(res) - len(sel)} graphs where pgmpy's triangulation "
                    f"has a clique of up to {max(r['pgmpy_width'] for r in res)} triplets (> 20^5 "
                    f"entries)")
        rows.append({"name": f"{name}: {label} / qfg one-pass, time ratio", "value": float(
            np.median(ratio)), "unit": "x", "target": target,
            "note": f"median over {len(sel)} graphs (min {ratio.min():.3g}, max {ratio.max():.3g}); "
                    f"max abs diff to qfg {diff:.1e}{miss}"})
    return rows


def bench_bp_full_maps(T, sizes=(10, 15, 20, 25), max_iters=200):
    from qfg.inference import loopy_bp

    rows = []
    for n in sizes:
        rng = np.random.default_rng(n)
        g = full_map(n, tensor=T)
        for v in np.flatnonzero(rng.random(g.n_triplets) < 1 / 3):
            g.add_triplet(g.triplets[v], _prior(rng))
        dt, r = _t(lambda g=g: loopy_bp(g, max_iters=max_iters, tol=1e-6, damping=0.5))
        rows.append({"name": f"loopy BP, full {n}-landmark map, to convergence (damping 0.5, "
                             f"tol 1e-6)", "value": dt, "unit": "s",
                     "note": f"{g.n_triplets} triplets, {g.n_factors} factors; "
                             f"{r.iterations} iterations, converged={r.converged}, "
                             f"{dt / r.iterations * 1e3:.0f} ms/iteration"})
    return rows


def bench_message_step(T, n=15):
    """One factor-to-variable message step, all roles: einsum (before) vs matrix products."""
    from benchmarks import median_time
    from qfg.inference.loopy import role_matrices

    g = full_map(n, tensor=T)
    F, m = g.n_factors, g.m
    rng = np.random.default_rng(0)
    q = rng.random((F, 3, m))
    Tn = g.table / g.table.max()
    mats = role_matrices(Tn)
    eqs = ("abc,fb,fc->fa", "abc,fa,fc->fb", "abc,fa,fb->fc")

    def einsum_step():
        return np.stack([np.einsum(eq, Tn, *[q[:, o] for o in range(3) if o != r])
                         for r, eq in enumerate(eqs)], axis=1)

    def matmul_step():
        out = np.empty((F, 3, m))
        for r, (x, y) in enumerate(((1, 2), (0, 2), (0, 1))):
            outer = (q[:, x, :, None] * q[:, y, None, :]).reshape(F, m * m)
            np.matmul(outer, mats[r].T, out=out[:, r])
        return out

    diff = float(np.abs(einsum_step() - matmul_step()).max() / np.abs(einsum_step()).max())
    te, tm = median_time(einsum_step, 3), median_time(matmul_step, 3)
    return [{"name": f"loopy BP message step, full {n}-landmark map: einsum / matrix products",
             "value": te / tm, "unit": "x", "note": f"einsum {te:.3f} s, matmul {tm:.3f} s; "
                                                     f"max rel diff {diff:.1e}"}]


def run():
    T = _tensor()
    rng = np.random.default_rng(0)
    fams = {
        "chains (4-16 factors)": [chain(rng, T, n) for n in np.linspace(4, 16, N_PER_FAMILY)
                                  .astype(int)],
        "trees (4-16 factors)": [tree(rng, T, n) for n in np.linspace(4, 16, N_PER_FAMILY)
                                 .astype(int)],
        "loopy (14 factors on 5 landmarks)": [loopy(rng, T) for _ in range(N_PER_FAMILY)],
        "propagation-study graphs": study_graphs(T, N_PER_FAMILY),
    }
    rows = []
    for name, graphs in fams.items():
        print(f"  {name}", file=sys.stderr, flush=True)
        rows += _family_rows(name, compare(graphs))
    rows += bench_message_step(T)
    rows += bench_bp_full_maps(T)
    return rows


if __name__ == "__main__":
    for row in run():
        print(row)
