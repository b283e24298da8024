"""The ``qfg demo``: a small simulated scenario, its ground-truth qualitative map, the single-triplet
estimates of every seen triplet against that truth, and figures."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from qfg import metrics, partitions
from qfg.simulation import random_scenario, triplet_histories
from qfg.solvers import solve_triplets


def run(seed: int = 0, output: str | Path = "out/demo", n_landmarks: int = 6, n_poses: int = 12,
        landmarks_per_view: int = 4, partition: str = "edc", methods=("fast", "full"),
        echo=print, fmt: str = "png") -> dict:
    """Simulate, print the ground-truth map and the estimates of ``methods`` for every seen
    triplet, write ``<output>/figures/scenario.<fmt>``; return what was made."""
    rng = np.random.default_rng(seed)
    part = partitions.get(partition)
    sc = random_scenario(rng, n_landmarks, n_poses, landmarks_per_view,
                         sigma_bearing=np.deg2rad(2.0), sigma_heading=np.deg2rad(5.0))
    hist = triplet_histories(sc, partition=part.name)
    echo(f"qfg demo: {n_landmarks} landmarks, {n_poses} poses, {landmarks_per_view} landmarks per "
         f"view, seed {seed}; noise sigma_v = 2 deg, sigma_w = 5 deg")
    ests, secs = {}, {}
    for m in methods:
        t0 = time.perf_counter()
        ests[m] = solve_triplets(hist, method=m, partition=part, seed=seed) if hist else []
        secs[m] = time.perf_counter() - t0
    echo(f"{len(hist)} ordered triplets seen together at least once; ground-truth "
         f"{part.name.upper()} states (1-based) and each method's most likely state with its "
         "probability [p(truth)]:")
    head = f"{'triplet':>9}  {'views':>5}  {'truth':>5}  " + "  ".join(
        f"{m:>16}" for m in methods) + "  region (truth)"
    echo(head)
    for k, h in enumerate(hist):
        a, b, c = h.landmarks
        s = h.truth.state
        cells = []
        for m in methods:
            p = ests[m][k].landmark
            j = int(np.argmax(p))
            mark = " " if j == s else "*"
            cells.append(f"{part.labels[j]:>3}{mark}{p[j]:5.2f} [{p[s]:4.2f}]")
        echo(f"{f'{a},{b}:{c}':>9}  {h.n_views:5d}  {part.labels[s]:>5}  " + "  ".join(
            f"{x:>16}" for x in cells) + f"  {part.descriptions[s]}")
    summary = {}
    if hist:
        g = np.array([h.truth.state for h in hist])
        multi = np.array([h.n_views >= 2 for h in hist])
        echo("(* = the most likely state is not the true one)")
        uni = np.full(part.n_states, 1 / part.n_states)
        for m in methods:
            P = np.array([e.landmark for e in ests[m]])
            top = metrics.gt_rating(P, g) == 1
            d = metrics.dmse(P, g)
            ls, br = metrics.log_score(P, g).mean(), metrics.brier(P, g).mean()
            summary[m] = {"top1": float(top.mean()), "dmse_median": float(np.median(d)),
                          "log_score_mean": float(ls), "brier_mean": float(br)}
            # proper scores first: a median DMSE alone rewards over-confidence
            echo(f"{m:>8}: mean log p(truth) {ls:.2f} (uniform {np.log(1 / part.n_states):.2f}), "
                 f"mean Brier {br:.2f} (uniform {float(metrics.brier(uni, 0)):.2f}); truth most "
                 f"likely for {top.sum()}/{len(hist)} triplets ({top[multi].sum()}/{multi.sum()} "
                 f"with 2+ views, {top[~multi].sum()}/{(~multi).sum()} with one view); median DMSE "
                 f"{np.median(d):.2f} (uniform {float(metrics.dmse(uni, 0)):.2f}); "
                 f"{1e3 * secs[m] / len(hist):.1f} ms per triplet")
    qmap = _qualitative_map(sc, hist, part, seed, echo) if hist else []
    fig_path = None
    if hist:
        k = max(range(len(hist)), key=lambda i: hist[i].n_views)
        best = hist[k]
        probs = ests[methods[0]][k].landmark if methods else None
        fig_path = _figure(sc, best, part, output, fmt, probs, methods[0] if methods else None)
        echo(f"figure: {fig_path} (scenario, and triplet "
             f"{best.landmarks[0]},{best.landmarks[1]}:{best.landmarks[2]} in its AB frame"
             + (f" with the {methods[0]} estimate)" if methods else ")"))
    return {"scenario": sc, "histories": hist, "estimates": ests, "summary": summary,
            "map": qmap, "figure": fig_path}


def _qualitative_map(sc, hist, part, seed, echo, n_unseen: int = 3, support: int = 2) -> list[dict]:
    """Hide up to ``n_unseen`` triplets (or use never-seen ones), propagate to them from the seen
    triplets that compose into them, and compare with the exact marginal and the truth.

    The map keeps, for each unseen triplet i,j:s, at most ``support`` pairs (i,j:k, j,k:s) of seen
    triplets, those with the most views, so that exact elimination stays small enough for a demo.
    """
    from qfg.configurations import configuration_marginals, one_ordering_per_set
    from qfg.graph import map_from_histories, truth_states
    from qfg.propagation import compare_unseen

    by_key = {h.landmarks: h for h in hist}
    L = sc.n_landmarks
    rng = np.random.default_rng(seed)
    perms = [(i, j, s) for i in range(L) for j in range(L) for s in range(L) if len({i, j, s}) == 3]
    never = [t for t in perms if t not in by_key]
    hidden = [perms[k] for k in rng.permutation(len(perms))]
    chosen, used = [], set()
    for t in never + hidden:
        i, j, s = t
        pairs = [((i, j, k), (j, k, s)) for k in range(L)
                 if k not in t and (i, j, k) in by_key and (j, k, s) in by_key]
        # the best-measured evidence first: pairs whose weaker triplet has the most views
        pairs.sort(key=lambda p: -min(by_key[p[0]].n_views, by_key[p[1]].n_views))
        pairs = pairs[:support]
        if not pairs or any(x in chosen for p in pairs for x in p):
            continue
        chosen.append(t)
        used.update(x for p in pairs for x in p)
        if len(chosen) == n_unseen:
            break
    if not chosen:
        echo("no triplet can be reached by composition in this scenario")
        return []
    seen_hist = [by_key[t] for t in sorted(used - set(chosen))]
    g = map_from_histories(seen_hist, unseen=chosen, partition=part.name, seed=seed)
    g.discover_compositions()
    truth = truth_states(g.triplets, sc.landmarks, partition=part.name)
    rows = compare_unseen(g, truth)
    # configuration inference over the same seen estimates
    evidence = one_ordering_per_set({tuple(t): p for t, p, s in zip(g.triplets, g.priors, g.seen,
                                                                     strict=True) if s})
    cfg = configuration_marginals(evidence, prior="world", triplets=[r["triplet"] for r in rows],
                                  partition=part.name, seed=seed)
    for r in rows:
        r["configurations"] = cfg[tuple(r["triplet"])]
    echo(f"qualitative map: {g.n_triplets} triplets ({int(g.seen.sum())} seen, fast-solver priors; "
         f"{len(rows)} unseen, hidden from the solver), {g.n_factors} composition factors")
    echo(f"{'unseen':>9}  {'truth':>5}  {'propagated (Alg. 2)':>20}  {'exact marginal':>16}  "
         f"{'configurations':>16}  ISC")
    for r in rows:
        a, b, c = r["triplet"]
        cells = []
        for key in ("propagated", "exact", "configurations"):
            p = r[key]
            if p is None:
                cells.append("n/a")
                continue
            j = int(np.argmax(p))
            cells.append(f"{part.labels[j]:>3}{' ' if j == r['truth'] else '*'}{p[j]:5.2f} "
                         f"[{p[r['truth']]:4.2f}]")
        echo(f"{f'{a},{b}:{c}':>9}  {part.labels[r['truth']]:>5}  {cells[0]:>20}  {cells[1]:>16}  "
             f"{cells[2]:>16}  {r['isc']:.2f}")
    if rows and rows[0]["exact"] is None:
        echo(f"(exact marginals not computed: {rows[0]['exact_error']})")
    echo("(most likely state, its probability [probability of the truth]; * = not the truth; "
         f"uniform would give {1 / part.n_states:.2f} to every state; configurations: landmark "
         "configurations sampled given the same seen estimates, qfg.configurations)")
    return rows


def _figure(scenario, history, part, output, fmt, probabilities=None, method=None):
    from qfg.harness.plotting import draw_scenario, draw_triplet, plt
    from qfg.harness.runner import save_figure

    fig, axes = plt.subplots(1, 2, figsize=(11, 5.5))
    draw_scenario(scenario, axes[0], triplet=history)
    draw_triplet(history, axes[1], partition=part, probabilities=probabilities)
    if method is not None:
        axes[1].set_title(axes[1].get_title() + f": {method} estimate")
    fig.tight_layout()
    return save_figure(fig, output, "scenario", dpi=120, fmt=fmt)
