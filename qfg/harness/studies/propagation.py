"""The factor-graph propagation study (paper sections 5c and 6f).

One scenario = one factor graph, drawn by :func:`qfg.random_graphs.propagation_graph` (steps 1-3;
the exact-vs-approximate study and the inference benchmark draw the same graphs from it):

1. Landmarks placed as in the simulation (:func:`qfg.simulation.sample_positions`: uniform in the
   box, at least ``min_distance`` apart), ids ``0 .. n_landmarks - 1``.
2. ``n_candidates`` candidate graphs. Each: ``n_fc`` (uniform in ``[n_fc_min, n_fc_max]``)
   composition factors drawn without replacement from all ``n (n-1) (n-2) (n-3)`` factors of the
   landmarks, and the triplets they touch (``n_v``); ``n_seen = round(coverage_rate * n_v)``
   (conventions.md: the paper's text divides, read as a product; at least 1, at most ``n_v - 1``)
   of them drawn as seen. Connectivity score: Algorithm 3 with every seen triplet at 1, the
   entropy (natural log, :func:`qfg.metrics.entropy`) of the histogram of all triplets' topology
   scores in 10 equal bins on [0, 1]. The candidate with the highest connectivity score is kept
   (the first of equal ones).
3. Each seen triplet of the kept graph gets its own ``n_views`` camera poses, placed with the
   landmarks (one :func:`~qfg.simulation.sample_positions` call over landmarks and all cameras),
   bearings with N(0, sigma_bearing^2) noise and motion headings with N(0, sigma_heading^2) noise
   (paper eqs. MsrLkl, MotionModel; :func:`qfg.geometry.bearing`, :func:`~qfg.geometry.
   motion_heading`), solved by :func:`qfg.solvers.solve_triplets` (``method=solver``, "fast").
   The rest are unseen.
4. Algorithm 2 (:func:`qfg.propagation.propagate`) -> ISC of every triplet; Algorithm 3
   (:func:`~qfg.propagation.topology_scores`) with seen triplets starting at their prior's ISC
   (``tsc``) and at 1 (``tsc1``, the paper's unbiased comparison with composition levels);
   composition levels (``cl``, normalized ``cl_norm`` = eq. cl3).

5. The map methods (configuration inference beside composition), scored on every triplet (seen
   and unseen) with proper scores
   (:mod:`qfg.harness.studies._map_methods`: ``<method>_ls`` log score clipped at 1e-4,
   ``_brier``, ``_under1``, ``_pit`` randomized PIT, ``_top``/``_tophit``): ``alg2`` (Algorithm
   2's marginals), ``pooled`` (``propagate(g, method="pooled")``), ``config-state`` and ``config-metric``
   (configuration inference, :mod:`qfg.configurations`), ``prior`` (the prior's state
   distribution alone), ``solver`` (seen triplets: the estimate). ``map_methods=false`` skips the
   configuration methods; ``scores.md`` summarizes.

Rows: one per triplet (``scenario``, ``triplet``, ``seen``, ``reached``, ``isc``, ``tsc``,
``tsc1``, ``cl`` (-1 where unreachable), ``cl_norm``, ground-truth ``dmse``, ``gt_rating``,
``gmd`` of the Algorithm 2 marginal (or the prior for seen triplets) and graph-level columns). The
first row of a graph also carries ``factors`` (``"i-j-k-s;..."``) so the summary can draw graphs.

Run: ``qfg experiment propagation --preset quick --output results/propagation-quick``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from qfg.graph import truth_states
from qfg.harness.runner import Study, param_spec, print_table, save_figure, validate_params, write_table
from qfg.harness.studies import _map_methods as mm
from qfg.metrics import dmse, gmd, gt_rating
from qfg.propagation import composition_levels, propagate, topology_scores
from qfg.random_graphs import (  # one generator; the helpers re-exported for tests and tools
    candidate_graph,  # noqa: F401
    connectivity_score,  # noqa: F401
    factor_triplets,  # noqa: F401
    propagation_graph,
)

DEFAULTS = {
    "n_graphs": 20, "n_landmarks": 6, "n_fc_min": 5, "n_fc_max": 40, "n_candidates": 10,
    "coverage_rate": 0.5, "alpha": 0.5, "n_views": 3, "sigma_bearing_deg": 2.0,
    "sigma_heading_deg": 5.0, "solver": "fast", "partition": "edc", "n_bins": 10,
    # Tests only: a seeded random tensor instead of tensors/<partition>.npz (needs m = 20: edc).
    "random_tensor": False,
    # configuration inference
    **mm.PARAMS,
}

PARAMS = param_spec(DEFAULTS, n_graphs={"min": 1}, n_landmarks={"min": 4}, n_fc_min={"min": 1},
                    n_fc_max={"min": 1}, n_candidates={"min": 1},
                    coverage_rate={"min": 0.0, "max": 1.0}, alpha={"min": 0.0, "max": 1.0},
                    n_views={"min": 1}, sigma_bearing_deg={"min": 0.0},
                    sigma_heading_deg={"min": 0.0}, solver={"choices": ("fast", "full", "baseline")},
                    partition={"choices": ("edc", "fdc", "lr", "tpcc")}, n_bins={"min": 1},
                    config_particles={"min": 4}, config_floor={"min": 0.0, "max": 1.0},
                    config_state_mix={"min": 0.0, "max": 1.0}, config_components={"min": 1})


_HEADLINE = ("spearman_tsc_isc", "spearman_cl_isc", "pearson_tsc_isc", "pearson_cl_isc")


#: The task parameters that :func:`~qfg.random_graphs.propagation_graph` draws a graph from.
GRAPH_KEYS = ("n_landmarks", "n_fc_min", "n_fc_max", "n_candidates", "coverage_rate", "n_views",
              "sigma_bearing_deg", "sigma_heading_deg", "solver", "partition", "n_bins")


def tasks(params: dict) -> list[dict]:
    """One task per graph: the merged parameters (validated) and the graph's index."""
    p = validate_params(PARAMS, params)
    n_l = int(p["n_landmarks"])
    if n_l < 4:
        raise ValueError(f"n_landmarks: expected >= 4 (a factor needs 4 landmarks), got {n_l}")
    n_all = n_l * (n_l - 1) * (n_l - 2) * (n_l - 3)
    if not 1 <= int(p["n_fc_min"]) <= int(p["n_fc_max"]) <= n_all:
        raise ValueError(f"n_fc_min, n_fc_max: expected 1 <= min <= max <= {n_all} (all factors "
                         f"of {n_l} landmarks), got {p['n_fc_min']}, {p['n_fc_max']}")
    if not 0.0 < float(p["coverage_rate"]) < 1.0:
        raise ValueError(f"coverage_rate: expected in (0, 1), got {p['coverage_rate']}")
    if int(p["n_candidates"]) < 1:
        raise ValueError(f"n_candidates: expected >= 1, got {p['n_candidates']}")
    return [{"index": i, **{k: v for k, v in p.items() if k != "n_graphs"}}
            for i in range(int(p["n_graphs"]))]


def _tensor(task):
    if task["random_tensor"]:
        rng = np.random.default_rng(12345)
        return rng.random((20, 20, 20)) * (rng.random((20, 20, 20)) < 0.3) + 1e-6
    from qfg.composition import tensor
    return tensor(task["partition"])


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    from qfg.composition.online import as_table
    from qfg.partitions import get

    table = as_table(_tensor(task))
    cfg = bool(task["map_methods"])
    drawn = propagation_graph(rng, table, **{k: task[k] for k in GRAPH_KEYS}, hypotheses=cfg)
    g, L = drawn.graph, drawn.landmarks
    # drawn after the graph: the same graphs whatever runs on them
    cfg_seed, u_pit = int(rng.integers(2**63)), rng.random(g.n_triplets)
    n_seen, conn, kept = int(g.seen.sum()), drawn.connectivity, drawn.kept_candidate

    prop = propagate(g)
    tsc = topology_scores(g, alpha=float(task["alpha"])).scores
    tsc1 = topology_scores(g, alpha=float(task["alpha"]), seen_score=1.0).scores
    cl = composition_levels(g)
    truth = truth_states(g.triplets, L, task["partition"])
    part = get(task["partition"])
    M = prop.probabilities
    d, r, gm = dmse(M, truth), gt_rating(M, truth), gmd(M, truth, part.centroids)
    graph_cols = {"n_v": g.n_triplets, "n_fc": g.n_factors, "n_seen": n_seen,
                  "connectivity": conn, "kept_candidate": kept}
    from qfg.configurations import prior_states

    mats = {"prior": np.tile(prior_states("world", task["partition"]), (g.n_triplets, 1)),
            "alg2": np.asarray(M), "pooled": np.asarray(propagate(g, method="pooled"))}
    if cfg:
        cm, ct, cdiag = mm.config_marginals(drawn, task, cfg_seed)
        mats.update(cm)
        graph_cols.update({f"time_{k}": v for k, v in ct.items()})
        graph_cols.update({f"{k}_{d}": v for k, dd in cdiag.items() for d, v in dd.items()})
    score = {}
    for name, P in mats.items():
        score.update(mm.score_columns(name, P, truth, u_pit))
    sv = np.flatnonzero(g.seen)
    for k, c in mm.score_columns("solver", g.prior_matrix()[sv], truth[sv], u_pit[sv]).items():
        full = [None] * g.n_triplets
        for i, v in enumerate(sv):
            full[v] = c[i]
        score[k] = full
    rows = []
    for v, t in enumerate(g.triplets):
        row = {"triplet": "-".join(map(str, t)), "seen": int(g.seen[v]),
               "reached": int(prop.reached[v]), "isc": float(prop.isc[v]), "tsc": float(tsc[v]),
               "tsc1": float(tsc1[v]),
               "cl": float(cl.levels[v]) if np.isfinite(cl.levels[v]) else -1.0,
               "cl_norm": float(cl.normalized[v]), "truth": int(truth[v]),
               "dmse": float(d[v]), "gt_rating": float(r[v]), "gmd": float(gm[v]), **graph_cols,
               **{k: c[v] for k, c in score.items()}}
        if v == 0:
            row["factors"] = ";".join("-".join(map(str, f)) for f in g.factors)
        rows.append(row)
    return rows


# ------------------------------------------------------------------------------ summary
def _corr(x, y):
    from scipy import stats

    if len(x) < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return None, None  # undefined for constant inputs
    return float(stats.spearmanr(x, y).statistic), float(stats.pearsonr(x, y).statistic)


def binned_percentiles(x, y, n_bins: int = 10):
    """For ``n_bins`` equal bins of ``x`` on [0, 1]: count and 25/50/75 percentiles of ``y``.

    Returns a list of dicts (``lo, hi, count, p25, p50, p75``; percentiles None for empty bins).
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    b = np.clip((x * n_bins).astype(int), 0, n_bins - 1)
    out = []
    for k in range(n_bins):
        sel = y[b == k]
        q = np.percentile(sel, [25, 50, 75]).tolist() if sel.size else [None] * 3
        out.append({"lo": k / n_bins, "hi": (k + 1) / n_bins, "count": int(sel.size),
                    "p25": q[0], "p50": q[1], "p75": q[2]})
    return out


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    outdir = Path(outdir)
    p = {**DEFAULTS, **params}
    nb = int(p["n_bins"])
    methods = [m for m in ("prior", "solver", "alg2", "pooled", *mm.CONFIG)
               if any(f"{m}_ls" in r for r in rows)]
    scores = mm.score_table(rows, methods)
    write_table(outdir / "scores.csv", scores, None if scores else ["triplets"], digits=None)
    (outdir / "scores.md").write_text(mm.score_markdown(scores))
    cols = {k: np.array([r[k] for r in rows], dtype=float)
            for k in ("isc", "tsc", "tsc1", "cl", "cl_norm", "seen", "reached", "dmse",
                      "gt_rating", "gmd")}
    seen = cols["seen"] > 0
    reached = cols["reached"] > 0
    sets = {"all": np.ones(len(rows), bool), "unseen": ~seen}
    corr, bins_rows = {}, []
    # diagnostics: among reached unseen triplets only (unreachable ones score 0 in every model),
    # and the raw level (lower is closer; negated so a positive correlation means "predicts")
    sel = ~seen & reached
    for pred, x in (("tsc", cols["tsc"]), ("tsc1", cols["tsc1"]), ("cl", cols["cl_norm"]),
                    ("negcl", -cols["cl"])):
        s, pr = _corr(x[sel], cols["isc"][sel])
        corr[f"unseen_reached/spearman_{pred}_isc"] = s
        corr[f"unseen_reached/pearson_{pred}_isc"] = pr
    for sname, sel in sets.items():
        for pred in ("tsc", "tsc1", "cl_norm"):
            s, pr = _corr(cols[pred][sel], cols["isc"][sel])
            short = "cl" if pred == "cl_norm" else pred
            corr[f"{sname}/spearman_{short}_isc"] = s
            corr[f"{sname}/pearson_{short}_isc"] = pr
            for b in binned_percentiles(cols[pred][sel], cols["isc"][sel], nb):
                bins_rows.append({"triplets": sname, "predictor": pred, **b})
    write_table(outdir / "bins.csv", bins_rows, digits=None)
    unseen = ~seen
    reached_u = unseen & (cols["reached"] > 0)
    # why one model beats the other: ISC of reached unseen triplets by (level, TSC with seen = 1);
    # equal levels with different TSC show what the decay model sees that the level does not
    by_level = []
    keys = np.round(np.column_stack([cols["cl"], cols["tsc1"]])[reached_u], 6)
    isc_u = cols["isc"][reached_u]
    for cl_v, t_v in sorted({tuple(k) for k in keys.tolist()}):
        sel = (keys[:, 0] == cl_v) & (keys[:, 1] == t_v)
        if sel.sum() >= 20:
            q = np.percentile(isc_u[sel], [25, 50, 75]).tolist()
            by_level.append({"cl": cl_v, "tsc1": t_v, "count": int(sel.sum()),
                             "isc_p25": q[0], "isc_p50": q[1], "isc_p75": q[2]})
    gt = {}
    for name, sel in (("unseen", unseen), ("unseen_reached", reached_u),
                      ("unseen_unreached", unseen & ~(cols["reached"] > 0)), ("seen", seen)):
        gt[name] = {"count": int(sel.sum())}
        for k in ("dmse", "gt_rating", "gmd", "isc"):
            gt[name][k] = (np.percentile(cols[k][sel], [25, 50, 75]).tolist() if sel.any() else None)
    run = {}
    if (outdir / "run.json").exists():
        run = json.loads((outdir / "run.json").read_text())
    graphs = sorted({r["scenario"] for r in rows})
    summary = {
        "n_graphs": len(graphs), "n_triplets": len(rows), "n_unseen": int(unseen.sum()),
        # headline: unseen triplets (what the models predict; a seen triplet's tsc is its isc)
        "headline_triplets": "unseen",
        **{k: corr[f"unseen/{k}"] for k in _HEADLINE},
        "correlations": corr, "ground_truth": gt, "isc_by_level_and_tsc1": by_level,
        # per kept graph, percentiles 0/25/50/75/100 (the selection favours bigger graphs: more
        # triplets can fill more histogram bins)
        "graphs": {k: np.percentile([r[k] for r in rows if "factors" in r],
                                    [0, 25, 50, 75, 100]).tolist()
                   for k in ("n_v", "n_fc", "n_seen", "connectivity", "kept_candidate")},
        "command": run.get("command"), "seed": run.get("seed"), "params": p,
        "tensor": _tensor_info(p), "scores": scores,
    }
    (outdir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print_table([{"triplets": s, "predictor": name, "spearman": corr[f"{s}/spearman_{k}_isc"],
                  "pearson": corr[f"{s}/pearson_{k}_isc"]}
                 for s in ("unseen", "all") for k, name in (("tsc", "topology score"),
                                                           ("cl", "composition level"))],
                title=f"propagation study: {len(graphs)} graphs, {len(rows)} triplets; correlation "
                      "of each predictor with the information score")
    _figures(outdir, rows, cols, bins_rows, summary, nb)


def _tensor_info(p):
    """Which composition tensor the run used (the summary must say: results depend on it)."""
    if p["random_tensor"]:
        return {"random": True}
    try:
        from qfg.composition import tensor
        t = tensor(p["partition"])
    except Exception as exc:  # noqa: BLE001 - reported, not fatal for a summary
        return {"error": str(exc)}
    return {"path": str(t.path), "samples_per_state": t.samples_per_state, "sha256": t.sha256}


def _figures(outdir, rows, cols, bins_rows, summary, nb):
    import matplotlib.pyplot as plt

    def band(ax, triplets, pred, color, label):
        bs = [b for b in bins_rows if b["triplets"] == triplets and b["predictor"] == pred
              and b["count"]]
        x = [(b["lo"] + b["hi"]) / 2 for b in bs]
        ax.fill_between(x, [b["p25"] for b in bs], [b["p75"] for b in bs], color=color, alpha=0.25)
        ax.plot(x, [b["p50"] for b in bs], "o-", color=color, label=label)

    c = summary["correlations"]
    # decay-model correlation (paper fig. decayModelCorrelation): all triplets and unseen only
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.8), sharey=True)
    for ax, sname in zip(axes, ("all", "unseen"), strict=True):
        band(ax, sname, "tsc", "C0", "TSC (seen at their ISC)")
        ax.plot([0, 1], [0, 1], ":", color="grey", lw=0.8)
        ax.set_title(f"{sname} triplets: Spearman {_fmt(c[f'{sname}/spearman_tsc_isc'])}, "
                     f"Pearson {_fmt(c[f'{sname}/pearson_tsc_isc'])}", fontsize=8)
        ax.set_xlabel("topology score bin (dimensionless, 0-1)")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("information score (25/50/75 %, 0-1)")
    fig.tight_layout()
    save_figure(fig, outdir, "decay_model_correlation", dpi=120)
    # the two models side by side (paper fig. comareModels: TSC with seen at 1 vs normalized CL);
    # top row all triplets as in the paper, bottom row unseen triplets only
    fig, axes = plt.subplots(2, 2, figsize=(9, 7), sharey=True)
    for row, sname in enumerate(("all", "unseen")):
        for ax, pred, color, label in ((axes[row, 0], "tsc1", "C0", "topology score (seen = 1)"),
                                       (axes[row, 1], "cl_norm", "C3",
                                        "normalized composition level")):
            band(ax, sname, pred, color, label)
            short = "cl" if pred == "cl_norm" else pred
            ax.set_title(f"{sname} triplets, {label}\nSpearman "
                         f"{_fmt(c[f'{sname}/spearman_{short}_isc'])}, Pearson "
                         f"{_fmt(c[f'{sname}/pearson_{short}_isc'])}", fontsize=8)
            ax.set_xlabel(f"{label} bin (0-1)")
            ax.set_xlim(0, 1)
        axes[row, 0].set_ylabel(f"information score, {sname} triplets (0-1)")
    fig.tight_layout()
    save_figure(fig, outdir, "tsc_vs_cl", dpi=120)
    _example_graphs(outdir, rows, nb, plt)


def _fmt(x):
    return "n/a" if x is None else f"{x:.3f}"


def _example_graphs(outdir, rows, nb, plt, n_examples: int = 4):
    """Paper fig. fgSelection: kept graphs (seen triplets dark) and their TSC (seen = 1)
    histograms with the connectivity score."""
    import networkx as nx

    by = {}
    for r in rows:
        by.setdefault(r["scenario"], []).append(r)
    chosen = sorted(by)[:n_examples]
    if not chosen:
        return
    fig, axes = plt.subplots(2, len(chosen), figsize=(3.2 * len(chosen), 6), squeeze=False)
    for col, s in enumerate(chosen):
        rs = by[s]
        G = nx.Graph()
        for r in rs:
            G.add_node(r["triplet"], seen=r["seen"], tsc=r["tsc1"])
        for f in rs[0].get("factors", "").split(";"):
            if f:
                G.add_node(f, factor=True)
                i, j, k, t = f.split("-")
                for tr in ((i, j, k), (j, k, t), (i, j, t)):
                    G.add_edge(f, "-".join(tr))
        pos = nx.spring_layout(G, seed=0)
        var = [n for n in G if not G.nodes[n].get("factor")]
        fac = [n for n in G if G.nodes[n].get("factor")]
        ax = axes[0, col]
        nx.draw_networkx_edges(G, pos, ax=ax, width=0.5, alpha=0.5)
        nx.draw_networkx_nodes(G, pos, nodelist=fac, node_shape="s", node_size=12,
                               node_color="k", ax=ax)
        nx.draw_networkx_nodes(G, pos, nodelist=var, node_size=30, ax=ax, cmap="viridis",
                               vmin=0, vmax=1, node_color=[G.nodes[n]["tsc"] for n in var],
                               edgecolors=["r" if G.nodes[n]["seen"] else "none" for n in var])
        ax.set_title(f"graph {s}: {len(var)} triplets, {len(fac)} factors\n"
                     "(red ring: seen; colour: TSC)", fontsize=7)
        ax.axis("off")
        ax = axes[1, col]
        ax.hist([r["tsc1"] for r in rs], bins=nb, range=(0, 1), color="C0")
        ax.set_title(f"connectivity score {rs[0]['connectivity']:.3f}", fontsize=8)
        ax.set_xlabel("topology score (seen = 1)")
        ax.set_ylabel("triplets")
    fig.tight_layout()
    save_figure(fig, outdir, "example_graphs", dpi=110)


STUDY = Study("propagation", tasks, run_task, summarize,
              "factor-graph propagation: topology score vs composition level vs ISC (paper 6f)",
              params=PARAMS)
