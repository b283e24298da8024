"""Map methods and proper scores shared by the exact-vs-approximate and the propagation studies:
configuration inference (``config-state``, ``config-metric``) next to the composition
methods, and the per-triplet scores both studies report for seen and unseen triplets.

Scores per triplet and method (``qfg.metrics``): ``<m>_ls`` the log score ``log max(p_truth,
1e-4)``, ``<m>_brier``, ``<m>_under1`` (truth under 1 %), ``<m>_top`` / ``<m>_tophit``
(reliability of the most likely state), ``<m>_pit`` the randomized PIT of the truth: states
ranked by decreasing forecast probability (ties by index), ``PIT = F(before truth) + U p_truth``
with ``U`` uniform; a calibrated forecaster's PIT is uniform on [0, 1], an over-confident one's
piles up in the top decile (its truths fall outside the mass it claimed).
"""

from __future__ import annotations

import time

import numpy as np

from qfg.metrics import brier, clustered_se, log_score, truth_under

#: configuration-inference methods, named by their ``method=`` in :mod:`qfg.configurations`
CONFIG = ("config-state", "config-metric")

#: study parameters of the configuration methods (defaults of qfg.configurations where shared;
#: each seen estimate is widened by the effective sample size of the solver's weights behind it,
#: :func:`solver_ess`, with the library's ``ess_prior`` of each method)
PARAMS = {"map_methods": True, "config_particles": 2000, "config_floor": 0.01,
          "config_state_mix": 0.1, "config_components": 32}


def solver_ess(hypotheses) -> dict:
    """{triplet: effective sample size of the solver's weights of C} from a drawn graph's
    ``hypotheses`` ({triplet: qfg.solvers.Hypotheses}); a triplet whose weights are all zero gets
    a tiny ESS (its estimate is then the prior's states: no evidence).

    >>> from types import SimpleNamespace
    >>> solver_ess({(0, 1, 2): SimpleNamespace(landmark_weights=np.full(4, 0.25))})
    {(0, 1, 2): 4.0}
    """
    out = {}
    for t, h in hypotheses.items():
        w = np.asarray(h.landmark_weights, dtype=float)
        tot = w.sum()
        out[t] = float(tot * tot / np.sum(w * w)) if tot > 0 else 1e-9
    return out


def randomized_pit(P, truth, u) -> np.ndarray:
    """(n,) randomized PIT of truths ``truth`` (n,) under forecasts ``P`` (n, m), uniforms u (n,).

    >>> randomized_pit(np.array([[0.7, 0.2, 0.1]]), np.array([1]), np.array([0.5])).round(3)
    array([0.8])
    """
    P = np.asarray(P, dtype=float)
    n, m = P.shape
    order = np.argsort(-P, axis=1, kind="stable")
    ranked = np.take_along_axis(P, order, axis=1)
    before = np.cumsum(ranked, axis=1) - ranked
    pos = np.argmax(order == np.asarray(truth)[:, None], axis=1)
    r = np.arange(n)
    return before[r, pos] + np.asarray(u, dtype=float) * ranked[r, pos]


def score_columns(name, P, truth, u) -> dict:
    """{column: (n,) list} of the scores of method ``name`` (module docstring)."""
    P = np.asarray(P, dtype=float)
    truth = np.asarray(truth)
    top = P.max(axis=1)
    return {f"{name}_ls": log_score(P, truth).tolist(), f"{name}_brier": brier(P, truth).tolist(),
            f"{name}_under1": truth_under(P, truth).astype(int).tolist(),
            f"{name}_top": top.tolist(),
            f"{name}_tophit": (np.argmax(P, axis=1) == truth).astype(int).tolist(),
            f"{name}_pit": randomized_pit(P, truth, u).tolist()}


def config_marginals(drawn, task, seed) -> tuple[dict, dict, dict]:
    """Configuration inference on a drawn study graph: ({method: (n, m)}, {method: seconds},
    {method: diagnostics}) for the graph's triplets, both methods (config-metric's evidence from
    ``drawn.hypotheses``; the prior is the solvers' default, ``"world"``)."""
    from qfg.configurations import infer_configurations, summarize_position

    g = drawn.graph
    opts = {"n_particles": int(task["config_particles"]), "floor": float(task["config_floor"]),
            "state_mix": float(task["config_state_mix"])}
    ess = solver_ess(drawn.hypotheses) if drawn.hypotheses is not None else None
    ss = np.random.SeedSequence(int(seed))
    seeds = ss.spawn(2)
    out, times, diag = {}, {}, {}
    for name, s in zip(CONFIG, seeds, strict=True):
        t0 = time.perf_counter()
        if name == "config-metric":
            ev = {t: summarize_position(drawn.hypotheses[t], p, partition=g.partition,
                                        n_components=int(task["config_components"]), seed=0)
                  for t, p in zip(g.triplets, g.priors, strict=True) if p is not None}
        else:
            ev = g
        post = infer_configurations(ev, partition=g.partition, method=name,
                                    landmarks=sorted({x for t in g.triplets for x in t}),
                                    seed=s, ess=ess, **opts)
        res = post.marginals(g.triplets)
        times[name] = time.perf_counter() - t0
        out[name] = np.asarray(res.probabilities)
        diag[name] = {"stages": int(res.info["n_stages"]),
                      "mc_error": float(res.info["mc_error_max"]),
                      "acc": float(res.info["acceptance_landmark"])}
    return out, times, diag


def score_table(rows, methods, label_rows=True) -> list[dict]:
    """Summary rows per (triplets in {seen, unseen}, method): n, mean log score and its standard
    error clustered by graph (``scenario``: the triplets of one graph share its seen estimates,
    so they are not independent; :func:`qfg.metrics.clustered_se`), Brier, truth under 1 %,
    randomized-PIT top and bottom deciles, top-state ECE (10 bins)."""
    out = []
    for which, flag in (("unseen", 0), ("seen", 1)):
        sub = [r for r in rows if int(r.get("seen", 0)) == flag]
        for m in methods:
            vals = [r for r in sub if r.get(f"{m}_ls") is not None]
            if not vals:
                continue

            def col(k, vals=vals, m=m):
                return np.array([float(r[f"{m}_{k}"]) for r in vals])

            pit = col("pit")
            top, hit = col("top"), col("tophit")
            edges = np.linspace(0, 1, 11)
            b = np.clip(np.searchsorted(edges, top, side="right") - 1, 0, 9)
            ece = sum(abs(hit[b == k].mean() - top[b == k].mean()) * np.sum(b == k)
                      for k in range(10) if np.any(b == k)) / len(top)
            graph = [r.get("scenario", i) for i, r in enumerate(vals)]
            out.append({"triplets": which, "method": m, "n": len(vals),
                        "log_score": float(np.mean(col("ls"))),
                        "log_score_se": clustered_se(col("ls"), graph),
                        "brier": float(np.mean(col("brier"))),
                        "truth_under_1pct": float(np.mean(col("under1"))),
                        "pit_top_decile": float(np.mean(pit >= 0.9)),
                        "pit_bottom_decile": float(np.mean(pit < 0.1)), "top_ece": float(ece)})
    return out


def score_markdown(table) -> str:
    lines = ["| triplets | method | n | mean log p(truth) ± SE (by graph) | Brier | truth < 1% | "
             "PIT top decile | PIT bottom decile | top-state ECE |",
             "|---|---|---|---|---|---|---|---|---|"]
    for t in table:
        lines.append(f"| {t['triplets']} | {t['method']} | {t['n']} | {t['log_score']:.3f} ± "
                     f"{t['log_score_se']:.3f} | "
                     f"{t['brier']:.3f} | {t['truth_under_1pct']:.3f} | "
                     f"{t['pit_top_decile']:.3f} | {t['pit_bottom_decile']:.3f} | "
                     f"{t['top_ece']:.3f} |")
    return "\n".join(lines) + "\n"
