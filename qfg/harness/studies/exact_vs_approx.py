"""Exact versus approximate inference on the propagation study's graphs at the paper's scale.

Each scenario is one graph of the propagation study, drawn by :func:`qfg.random_graphs.
propagation_graph` from the same random stream: ``qfg experiment exact-vs-approx --preset paper
--seed S`` sees exactly the 5400 graphs of ``qfg experiment propagation --preset paper --seed S``
(6 landmarks, 5-40 composition factors, the best of 10 candidates by connectivity score, half the
triplets seen with fast-solver priors). For every graph:

* exact marginals, one junction-tree calibration (:func:`qfg.inference.exact_marginals`); a graph
  whose priors contradict the tensor's support has none (``zero_mass``; ``zero_mass_local`` = how
  many single factors contradict their own triplets' priors -- 0 means only a loop or chain of
  factors does);
* Algorithm 2 in both readings of closing (:func:`qfg.propagation.propagate`, ``alg2``:
  membership, ``alg2c``: ``close_used=True``);
* loopy BP without and with damping (``bp``: damping 0, ``bpd``: ``bp_damping``);
* pooled composition (``pooled``: :func:`qfg.propagation.propagate` with ``method="pooled"``);
* configuration inference (:mod:`qfg.configurations`): ``config-state`` (each seen
  triplet's likelihood from its state estimate) and ``config-metric`` (from a summary of the
  solver's weighted samples of C), ``config_particles`` particles (``map_methods=false`` skips
  them);
* the topology score (Algorithm 3, seen triplets at their prior's ISC: ``tsc``; at 1: ``tsc1``).

Every triplet is scored, seen and unseen (``seen`` column), by every method plus ``prior`` (the
prior's state distribution alone) and, for seen triplets, ``solver`` (the estimate itself):
``<method>_ls`` (log score clipped at 1e-4), ``_brier``, ``_under1``, ``_pit`` (randomized PIT),
``_top``/``_tophit`` (:mod:`qfg.harness.studies._map_methods`); ``scores.md`` / ``scores.csv``
summarize them. The comparison with exact inference below is over the unseen triplets.

Rows: one per triplet, with per method ``<method>_tv`` and ``<method>_kl`` (KL(exact ||
method), natural log) to exact, ``<method>_logscore`` (log of the probability given to the true
state), ``<method>_dmse`` (to the true state), ``<method>_isc``; graph columns (``n_v``, ``n_fc``,
``n_seen``, ``width`` (largest clique of the junction tree, triplets), ``has_loop``, BP
convergence) and per-graph times ``time_<method>`` (seconds, timings.csv).

Run: ``qfg experiment exact-vs-approx --preset quick --output out/exact_vs_approx``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from qfg.graph import truth_states
from qfg.harness.runner import Study, param_spec, print_table, save_figure, write_table
from qfg.harness.studies import _map_methods as mm
from qfg.harness.studies.propagation import GRAPH_KEYS as _GRAPH_KEYS
from qfg.inference import ZeroMassError, exact_marginals, loopy_bp
from qfg.metrics import dmse, information_score
from qfg.propagation import propagate, topology_scores
from qfg.random_graphs import propagation_graph

#: approximate methods: name -> label
APPROX = {"alg2": "Algorithm 2 (membership closing)", "alg2c": "Algorithm 2 (close used)",
          "pooled": "pooled composition (method='pooled')",
          "bp": "loopy BP", "bpd": "loopy BP, damped",
          "config-state": "configuration inference, state likelihoods",
          "config-metric": "configuration inference, metric evidence"}
METHODS = ("exact", *APPROX)
#: methods scored on every triplet (``solver``: seen triplets only)
SCORED = ("prior", "solver", *METHODS)

DEFAULTS = {
    # the propagation study's graph parameters (its paper preset)
    "n_graphs": 20, "n_landmarks": 6, "n_fc_min": 5, "n_fc_max": 40, "n_candidates": 10,
    "coverage_rate": 0.5, "alpha": 0.5, "n_views": 3, "sigma_bearing_deg": 2.0,
    "sigma_heading_deg": 5.0, "solver": "fast", "partition": "edc", "n_bins": 10,
    # the approximate methods
    "bp_damping": 0.5, "bp_max_iters": 200, "bp_tol": 1e-9,
    # configuration inference
    **mm.PARAMS,
    # Tests only: a seeded random tensor (m = 20) instead of tensors/<partition>.npz.
    "random_tensor": False,
}

def tasks(params: dict) -> list[dict]:
    unknown = set(params) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"params: unknown keys {sorted(unknown)}")
    p = {**DEFAULTS, **params}
    n = p["n_graphs"]
    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
        raise ValueError(f"n_graphs: expected an integer >= 0, got {n!r}")
    if not 0.0 <= float(p["bp_damping"]) < 1.0:
        raise ValueError(f"bp_damping: expected 0 <= damping < 1, got {p['bp_damping']!r}")
    return [{"index": i, **{k: v for k, v in p.items() if k != "n_graphs"}} for i in range(n)]


def _tensor(task):
    if task["random_tensor"]:
        # the propagation study's test tensor, so both studies draw the same graphs in tests too
        rng = np.random.default_rng(12345)
        return rng.random((20, 20, 20)) * (rng.random((20, 20, 20)) < 0.3) + 1e-6
    from qfg.composition import tensor
    return tensor(task["partition"])


def _tv_kl(p, q):
    eps = 1e-300
    tv = 0.5 * np.abs(p - q).sum(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        kl = np.where(p > 0, p * (np.log(np.maximum(p, eps)) - np.log(np.maximum(q, eps))), 0.0)
    return tv, np.maximum(kl.sum(axis=-1), 0.0)  # KL >= 0; rounding can give -1e-17


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    from qfg.inference import size_estimate

    cfg = bool(task["map_methods"])
    drawn = propagation_graph(rng, _tensor(task), **{k: task[k] for k in _GRAPH_KEYS},
                              hypotheses=cfg)
    g, L = drawn.graph, drawn.landmarks
    # drawn after the graph: the graph is the propagation study's whatever is run on it
    cfg_seed, u_pit = int(rng.integers(2**63)), rng.random(g.n_triplets)
    truth = truth_states(g.triplets, L, task["partition"])
    est = size_estimate(g)
    zero_mass, zero_local, why = False, 0, ""
    try:
        ex, t_ex = _timed(lambda: exact_marginals(g))
        E = np.asarray(ex)
    except ZeroMassError as exc:
        zero_mass, zero_local, why = True, len(exc.local_factors), str(exc)
        E, t_ex = None, float("nan")
    res, times = {}, {"exact": t_ex}
    res["alg2"], times["alg2"] = _timed(lambda: propagate(g))
    res["alg2c"], times["alg2c"] = _timed(lambda: propagate(g, close_used=True))
    res["pooled"], times["pooled"] = _timed(lambda: propagate(g, method="pooled"))
    bp_kw = {"max_iters": int(task["bp_max_iters"]), "tol": float(task["bp_tol"])}
    res["bp"], times["bp"] = _timed(lambda: loopy_bp(g, damping=0.0, **bp_kw))
    res["bpd"], times["bpd"] = _timed(lambda: loopy_bp(g, damping=float(task["bp_damping"]),
                                                       **bp_kw))
    cdiag = {}
    if cfg:
        cm, ct, cdiag = mm.config_marginals(drawn, task, cfg_seed)
        res.update(cm)
        times.update(ct)
    tsc = topology_scores(g, alpha=float(task["alpha"])).scores
    tsc1 = topology_scores(g, alpha=float(task["alpha"]), seen_score=1.0).scores
    # every triplet, seen and unseen (the comparison with exact is read over the unseen ones)
    unseen = np.arange(g.n_triplets)
    truth_u = truth[unseen]
    cols = {}
    mats = {"exact": E, **{k: np.asarray(r) for k, r in res.items()}}
    from qfg.configurations import prior_states

    q = prior_states("world", task["partition"])   # the solvers' prior: the state prior alone
    seen_v = np.flatnonzero(g.seen)
    for name, M in {"prior": np.tile(q, (g.n_triplets, 1)), **mats}.items():
        if M is None:
            continue
        for k, c in mm.score_columns(name, M, truth, u_pit).items():
            cols[k] = c
    for k, c in mm.score_columns("solver", g.prior_matrix()[seen_v], truth[seen_v],
                                 u_pit[seen_v]).items():
        full = [None] * g.n_triplets
        for i, v in enumerate(seen_v):
            full[v] = c[i]
        cols[k] = full
    for name, M in mats.items():
        if M is None:
            for c in ("tv", "kl", "logscore", "dmse", "isc"):
                cols[f"{name}_{c}"] = [None] * len(unseen)
            continue
        Q = M[unseen]
        q_true = Q[np.arange(len(unseen)), truth_u]
        with np.errstate(divide="ignore"):
            cols[f"{name}_logscore"] = np.maximum(np.log(q_true), -1e3).tolist()  # floor: -inf
        cols[f"{name}_dmse"] = dmse(Q, truth_u).tolist()
        cols[f"{name}_isc"] = information_score(Q).tolist()
        if E is None or name == "exact":
            cols[f"{name}_tv"] = [None if E is None else 0.0] * len(unseen)
            cols[f"{name}_kl"] = [None if E is None else 0.0] * len(unseen)
        else:
            tv, kl = _tv_kl(E[unseen], Q)
            cols[f"{name}_tv"], cols[f"{name}_kl"] = tv.tolist(), kl.tolist()
    F, n = g.n_factors, g.n_triplets
    # bipartite factor graph (compositions only): a cycle iff edges > nodes - components
    from qfg.inference.exact import _components
    n_comp = len(_components(n, g.factor_vars))
    has_loop = 3 * F > (n + F) - n_comp
    graph = {"n_v": n, "n_fc": F, "n_seen": int(g.seen.sum()), "width": est.width,
             "has_loop": bool(has_loop), "connectivity": drawn.connectivity,
             "zero_mass": zero_mass, "zero_mass_local": zero_local,
             "bp_converged": bool(res["bp"].converged), "bp_iterations": res["bp"].iterations,
             "bpd_converged": bool(res["bpd"].converged),
             "bpd_iterations": res["bpd"].iterations,
             **{f"time_{k}": v for k, v in times.items()},
             **{f"{k}_{d}": v for k, dd in cdiag.items() for d, v in dd.items()}}
    rows = []
    for r, v in enumerate(unseen):
        row = {"triplet": "-".join(map(str, g.triplets[v])), "seen": int(g.seen[v]),
               "truth": int(truth[v]),
               "reached": bool(res["alg2"].reached[v]), "tsc": float(tsc[v]),
               "tsc1": float(tsc1[v]), **{k: c[r] for k, c in cols.items()}, **graph}
        if v == int(np.flatnonzero(~g.seen)[0]) and zero_mass:
            row["zero_mass_why"] = why
        rows.append(row)
    if not rows:  # every triplet seen: keep the graph's zero-mass / timing record anyway
        rows.append({"triplet": "", **graph})
    return rows


# ------------------------------------------------------------------------------ summary
def _spearman(x, y):
    from scipy import stats

    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return None
    return float(stats.spearmanr(x, y).statistic)


def _pearson(x, y):
    from scipy import stats

    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return None
    return float(stats.pearsonr(x, y).statistic)


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    outdir = Path(outdir)
    rows = [r for r in rows if r.get("triplet")]
    scored = [r for r in rows if not r["zero_mass"]]
    scores = mm.score_table(scored, [m for m in SCORED if any(f"{m}_ls" in r for r in rows)])
    write_table(outdir / "scores.csv", scores, None if scores else ["triplets"], digits=None)
    (outdir / "scores.md").write_text(
        f"Graphs with exact marginals ({len({r['scenario'] for r in scored})}); every method on "
        "the same triplets.\n\n" + mm.score_markdown(scores))
    if scores:
        print_table(scores, title="proper scores, seen and unseen triplets")
    rows = [r for r in rows if not int(r.get("seen", 0))]
    graphs = {}
    for r in rows:
        graphs.setdefault(r["scenario"], r)
    g_rows = list(graphs.values())
    ok = [r for r in rows if not r["zero_mass"]]

    def col(rs, k):
        return np.array([np.nan if r.get(k) is None else float(r[k]) for r in rs], dtype=float)

    table = []
    for sub_name, sub in (("all", ok), ("tree", [r for r in ok if not r["has_loop"]]),
                          ("loopy", [r for r in ok if r["has_loop"]])):
        gsub = {r["scenario"]: r for r in sub}.values()
        for m in METHODS:
            if not sub:
                continue
            tv, kl = col(sub, f"{m}_tv"), col(sub, f"{m}_kl")
            ls = col(sub, f"{m}_logscore")
            table.append({
                "graphs": sub_name, "method": m, "n_graphs": len(gsub), "n_triplets": len(sub),
                "tv_mean": float(np.mean(tv)), "tv_median": float(np.median(tv)),
                "tv_p90": float(np.percentile(tv, 90)), "kl_mean": float(np.mean(kl)),
                # log score: a probability of exactly 0 for the truth is -inf (stored as -1000),
                # so report how often that happens and the mean with q floored at 1e-6
                "truth_zero": float(np.mean(ls < -690)),
                "logscore_median": float(np.median(ls)),
                "logscore_mean_floor6": float(np.mean(np.maximum(ls, np.log(1e-6)))),
                "dmse_mean": float(np.mean(col(sub, f"{m}_dmse"))),
                "isc_mean": float(np.mean(col(sub, f"{m}_isc"))),
                "time_ms_median": 1e3 * float(np.median(col(list(gsub), f"time_{m}"))),
                "time_ms_p90": 1e3 * float(np.percentile(col(list(gsub), f"time_{m}"), 90)),
            })
    write_table(outdir / "table.csv", table, None if table else ["graphs"], digits=None)
    lines = ["| graphs | method | graphs (n) | unseen triplets | TV mean | TV median | TV p90 | "
             "KL mean | truth at p = 0 | log score median | log score mean (p >= 1e-6) | "
             "DMSE mean | ISC mean | time median (ms) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for t in table:
        lines.append(f"| {t['graphs']} | {t['method']} | {t['n_graphs']} | {t['n_triplets']} | "
                     f"{t['tv_mean']:.4f} | {t['tv_median']:.4f} | {t['tv_p90']:.4f} | "
                     f"{t['kl_mean']:.4f} | {t['truth_zero']:.4f} | {t['logscore_median']:.3f} | "
                     f"{t['logscore_mean_floor6']:.3f} | {t['dmse_mean']:.4f} | "
                     f"{t['isc_mean']:.4f} | {t['time_ms_median']:.2f} |")
    (outdir / "table.md").write_text("\n".join(lines) + "\n")
    print_table([{k: t[k] for k in ("method", "n_triplets", "tv_mean", "tv_median", "kl_mean",
                                    "dmse_mean", "isc_mean", "time_ms_median")}
                 for t in table if t["graphs"] == "all"],
                title="exact vs approximate marginals of unseen triplets (all graphs)")
    # does the topology score predict the exact ISC better than Algorithm 2's ISC?
    pred = {}
    reached_ok = [r for r in ok if r["reached"]]
    for sname, sub in (("unseen", ok), ("unseen_reached", reached_ok)):
        for score in ("tsc", "tsc1"):
            x = col(sub, score)
            for target in ("exact", "alg2", "alg2c", "bp"):
                y = col(sub, f"{target}_isc")
                pred[f"{sname}/spearman_{score}_{target}_isc"] = _spearman(x, y)
                pred[f"{sname}/pearson_{score}_{target}_isc"] = _pearson(x, y)
    zm = [r for r in g_rows if r["zero_mass"]]
    summary = {
        "n_graphs": len(g_rows), "n_unseen_triplets": len(rows),
        "zero_mass_graphs": len(zm),
        "zero_mass_local": sum(1 for r in zm if r["zero_mass_local"] > 0),
        "zero_mass_loop_only": sum(1 for r in zm if r["zero_mass_local"] == 0),
        "zero_mass_scenarios": sorted(r["scenario"] for r in zm),
        "width_counts": {str(w): int(c) for w, c in zip(*np.unique(
            [r["width"] for r in g_rows], return_counts=True), strict=True)} if g_rows else {},
        "loopy_graphs": sum(1 for r in g_rows if r["has_loop"]),
        "bp_converged_fraction": float(np.mean([r["bp_converged"] for r in g_rows]))
        if g_rows else None,
        "bpd_converged_fraction": float(np.mean([r["bpd_converged"] for r in g_rows]))
        if g_rows else None,
        "exact_time_s_total": float(np.nansum(col(g_rows, "time_exact"))),
        "exact_time_s_percentiles_50_90_99_max": np.nanpercentile(
            col(g_rows, "time_exact"), [50, 90, 99, 100]).tolist() if g_rows else None,
        "zero_mass_examples": [r.get("zero_mass_why", "") for r in zm[:3]],
        "table": table, "scores": scores, "predictors": pred, "params": {**DEFAULTS, **params},
    }
    run = {}
    if (outdir / "run.json").exists():
        run = json.loads((outdir / "run.json").read_text())
    summary["command"], summary["seed"] = run.get("command"), run.get("seed")
    (outdir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    _figures(outdir, ok, col)


def _figures(outdir, ok, col):
    import matplotlib.pyplot as plt

    if not ok:
        return
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    approx = list(APPROX)
    for ax, key, label in ((axes[0], "tv", "total variation to exact"),
                           (axes[1], "kl", "KL(exact || method) (nats)")):
        data = [np.clip(col(ok, f"{m}_{key}"), 1e-16, None) for m in approx]
        ax.boxplot(data, whis=(5, 95), showfliers=False)
        ax.set_xticks(range(1, len(approx) + 1), approx)
        ax.set_yscale("log")
        ax.set_ylabel(label)
        ax.set_xlabel("method (whiskers 5-95 %)")
    ax = axes[2]
    for m, c in zip(METHODS, ("k", "C0", "C1", "C4", "C2", "C3", "C5", "C6"), strict=True):
        x = np.sort(col(ok, f"{m}_dmse"))
        ax.plot(x, np.arange(1, len(x) + 1) / len(x), color=c, label=m)
    ax.set_xlabel("DMSE to the true state")
    ax.set_ylabel("fraction of unseen triplets")
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, outdir, "exact_vs_approx", dpi=120)
    # topology score against exact and Algorithm 2 ISC (binned medians, quartile bands)
    fig, ax = plt.subplots(figsize=(5, 4))
    x = col(ok, "tsc")
    b = np.clip((x * 10).astype(int), 0, 9)
    for m, c in (("exact", "k"), ("alg2", "C0"), ("bp", "C2")):
        y = col(ok, f"{m}_isc")
        ctr, med, lo, hi = [], [], [], []
        for k in range(10):
            sel = y[b == k]
            if sel.size:
                q = np.percentile(sel, [25, 50, 75])
                ctr.append((k + 0.5) / 10)
                lo.append(q[0])
                med.append(q[1])
                hi.append(q[2])
        ax.fill_between(ctr, lo, hi, color=c, alpha=0.2)
        ax.plot(ctr, med, "o-", color=c, label=f"ISC of {m}")
    ax.set_xlabel("topology score (seen at their ISC), bin centre")
    ax.set_ylabel("information score (25/50/75 %)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, outdir, "tsc_vs_isc", dpi=120)


STUDY = Study("exact-vs-approx", tasks, run_task, summarize,
              "exact marginals vs Algorithm 2 (both closings), loopy BP (damped or not) and the "
              "topology score on the propagation study's graphs",
              params=param_spec(DEFAULTS, n_graphs={"min": 0}, n_landmarks={"min": 4},
                                n_fc_min={"min": 1}, n_fc_max={"min": 1}, n_candidates={"min": 1},
                                coverage_rate={"min": 0.0, "max": 1.0}, alpha={"min": 0.0, "max": 1.0},
                                n_views={"min": 1}, sigma_bearing_deg={"min": 0.0},
                                sigma_heading_deg={"min": 0.0}, n_bins={"min": 1},
                                solver={"choices": ("fast", "full", "baseline")},
                                bp_damping={"min": 0.0, "max": 1.0}, bp_max_iters={"min": 1},
                                bp_tol={"min": 0.0}, config_particles={"min": 4},
                                config_floor={"min": 0.0, "max": 1.0},
                                config_state_mix={"min": 0.0, "max": 1.0},
                                config_components={"min": 1}))
