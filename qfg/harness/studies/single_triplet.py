"""Single-triplet study (paper section 6c, Table 1 and its figures).

Each scenario is one random geometry: landmarks A, B, C and ``n_views`` camera poses uniform in
the paper's box (:func:`qfg.simulation.random_triplet_history`). The same geometry is measured at
every noise combination of the grid ``sigma_v_deg x sigma_w_deg`` (bearing and heading noise; the
same standard-normal draws scaled by each sigma, so that noise levels are compared on equal
footing, as the paper's "300 scenarios with 36 noise combinations each"), and solved by every
method of ``methods`` (:func:`qfg.solvers.solve_triplet`). One row per (combination, method):
the noise, the method, every metric of :mod:`qfg.metrics` for C, the camera states' top-1 rate and
mean DMSE, the number of hypotheses, the degenerate flag and the solve time.

The default grid, sigma_v in {0, 1, 2, 4, 7, 10} deg and sigma_w in {0, 2, 5, 10, 14, 20} deg,
contains the headline combination (2, 5) of Table 1, and its index-matched diagonal (0, 0), (1, 2),
(2, 5), (4, 10), (7, 14), (10, 20) has sigma_w = 2 sigma_v except 2.5 sigma_v at 2 and 4 deg:
the paper's "motion noise x2" curves.

Outputs (``summarize``): ``table1.csv``/``table1.md`` (25/50/75th percentiles at the headline
combination, the paper's numbers alongside), ``grid.csv`` (percentiles per combination and
method), ``summary.json``, and figures: DMSE, gmd, entropy and GT rating against noise along the
diagonal (median with the 25-75 band, three methods); the fast variant's sensitivity to motion
noise alone (sigma_v = 0) and to measurement noise alone (sigma_w = 0): gmd, GT rating, GT
likelihood; median DMSE over the whole grid per method.

Run: ``qfg experiment single-triplet --preset paper --output out/single-triplet``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from qfg import metrics
from qfg.harness.runner import Study, param_spec, save_figure, write_table
from qfg.partitions import get as get_partition
from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplet, solve_triplets

METHODS = ("full", "fast", "fast-paper", "baseline", "reference")
METRICS = ("dmse", "gt_rating", "gmd", "gt_likelihood", "gt_likelihood_ratio", "log_score",
           "brier", "entropy", "likelihood_ratio", "information_score")

DEFAULTS = {
    "n_scenarios": 300,
    "sigma_v_deg": [0.0, 1.0, 2.0, 4.0, 7.0, 10.0],
    "sigma_w_deg": [0.0, 2.0, 5.0, 10.0, 14.0, 20.0],
    # explicit [sigma_v_deg, sigma_w_deg] combinations instead of the grid above (empty: the grid)
    "noise_pairs": [],
    "headline": [2.0, 5.0],
    "methods": ["full", "fast", "fast-paper", "baseline"],
    "n_views": 3,
    "partition": "edc",
    "options": {},          # per-method solver options, e.g. {"full": {"n_samples": 300}}
    # the exact-posterior reference solver (seconds per triplet): only at these [sigma_v,
    # sigma_w] combinations, for the first reference_scenarios scenarios (0: all)
    "reference_noise": [],
    "reference_scenarios": 0,
    # views sweep: at the headline noise, every method of ``methods`` also solves the first k
    # views of a geometry with views_max views, for every k listed
    "views_sweep": [],
}

#: The paper's Table 1 (EDC, sigma_v = 2 deg, sigma_w = 5 deg): 25th, 50th, 75th percentiles.
PAPER_TABLE1 = {
    "baseline": {"dmse": (0.39, 0.63, 0.71), "gmd": (0.28, 1.10, 2.30),
                 "entropy": (0.28, 0.66, 0.87), "time_s": 26.0},
    "full": {"dmse": (0.0, 0.16, 0.63), "gmd": (0.0, 0.25, 1.15),
             "entropy": (0.0, 5e-3, 0.58), "time_s": 18.0},
    "fast": {"dmse": (0.0, 0.21, 0.62), "gmd": (0.0, 0.27, 1.16),
             "entropy": (0.0, 0.07, 0.64), "time_s": 0.05},
}


def _params(params: dict) -> dict:
    unknown = set(params) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"params: unknown keys {sorted(unknown)}; known: {sorted(DEFAULTS)}")
    p = {**DEFAULTS, **params}
    bad = [m for m in p["methods"] if m not in METHODS]
    if bad:
        raise ValueError(f"methods: unknown {bad}; known: {list(METHODS)}")
    for key in ("reference_noise", "noise_pairs"):
        for c in p[key]:
            if len(c) != 2 or min(c) < 0:
                raise ValueError(f"{key}: expected [sigma_v_deg, sigma_w_deg] pairs >= 0, "
                                 f"got {c!r}")
    if any(int(k) < 1 for k in p["views_sweep"]):
        raise ValueError(f"views_sweep: expected view counts >= 1, got {p['views_sweep']!r}")
    return p


def tasks(params: dict) -> list[dict]:
    """One task per geometry; each runs every noise combination and method."""
    p = _params(params)
    grid = ([[float(sv), float(sw)] for sv, sw in p["noise_pairs"]] if p["noise_pairs"] else
            [[float(sv), float(sw)] for sv in p["sigma_v_deg"] for sw in p["sigma_w_deg"]])
    nref = int(p["reference_scenarios"]) or int(p["n_scenarios"])
    return [{"scenario": i, "grid": grid, "methods": list(p["methods"]),
             "n_views": int(p["n_views"]), "partition": p["partition"],
             "options": p["options"],
             "reference_noise": [[float(a), float(b)] for a, b in p["reference_noise"]]
             if i < nref else [],
             "views_sweep": sorted(int(k) for k in p["views_sweep"]),
             # the reference in the views sweep (when in methods): the first
             # reference_scenarios geometries only (seconds to tens of seconds per triplet)
             "reference_sweep": i < nref,
             "headline": [float(v) for v in p["headline"]]}
            for i in range(int(p["n_scenarios"]))]


def _row(h, est, method, sv, sw, part, dt, n_views, sweep=False) -> dict:
    g, gc = h.truth.state, h.truth.camera_states
    row = {"sigma_v_deg": sv, "sigma_w_deg": sw, "method": method, "n_views": n_views,
           "sweep": sweep, "gt_state": int(g), "map_state": int(np.argmax(est.landmark)),
           "p_max": float(est.landmark.max()),
           "c_in_window": bool(part.in_window(h.truth.C_ab))}
    vals = metrics.evaluate(est.landmark, g, part.centroids)
    row.update({name: (int(v) if name == "gt_rating" else float(v))
                for name, v in vals.items() if name != "truth_under_1pct"})
    row["camera_top1"] = float(np.mean(metrics.gt_rating(est.cameras, gc[:n_views]) == 1))
    row["camera_dmse"] = float(np.mean(metrics.dmse(est.cameras, gc[:n_views])))
    row["n_hypotheses"] = int(est.n_hypotheses)
    row["ess"] = float(est.ess)
    row["mc_error"] = float(est.mc_error)
    row["degenerate"] = bool(est.degenerate)
    row["reason"] = est.reason
    row["model"] = est.method
    row["time_s"] = dt
    # the probabilities themselves, for reliability tables and the calibration bound
    row["p"] = " ".join(f"{v:.6g}" for v in est.landmark)
    return row


def _solve(h, method, part, seed, opts):
    t0 = time.perf_counter()
    est = solve_triplet(h, method=method, partition=part, seed=seed, **opts)
    return est, time.perf_counter() - t0


def _solve_batch(hs, method, part, seed, opts):
    """Solve the histories ``hs`` in one batched call (as a user with many triplets would);
    returns the estimates and the time per triplet (the batch's time / len(hs))."""
    t0 = time.perf_counter()
    ests = solve_triplets(hs, method=method, partition=part, seed=seed, **opts)
    return ests, (time.perf_counter() - t0) / max(1, len(hs))


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    part = get_partition(task["partition"])
    # one geometry (and one set of standard-normal noise draws) for every combination
    geometry_seed = int(rng.integers(2**63))
    solver_root = np.random.SeedSequence(int(rng.integers(2**63)))
    n = task["n_views"]
    refs = {tuple(c) for c in task.get("reference_noise", [])}
    grid = [tuple(c) for c in task["grid"]]
    hists = [random_triplet_history(np.random.default_rng(geometry_seed), n, np.deg2rad(sv),
                                    np.deg2rad(sw), partition=part) for sv, sw in grid]
    methods = list(task["methods"]) + (["reference"] if refs and "reference" not in
                                       task["methods"] else [])
    rows = []
    # every combination a method solves, in one batched call per method (solve_triplets: the
    # estimate of combination c is that of solve_triplet with the batch's child seed c)
    for method in methods:
        cs = [c for c, nz in enumerate(grid) if method != "reference" or nz in refs]
        if not cs:
            continue
        opts = task["options"].get(method, {})
        seed = np.random.SeedSequence(solver_root.entropy, spawn_key=(METHODS.index(method),))
        ests, dt = _solve_batch([hists[c] for c in cs], method, part, seed, opts)
        for c, est in zip(cs, ests, strict=True):
            sv, sw = grid[c]
            rows.append(_row(hists[c], est, method, sv, sw, part, dt, n))
    sweep = task.get("views_sweep", [])
    if sweep:
        # one geometry with max(sweep) views at the headline noise; the first k views of it
        sv, sw = task["headline"]
        kmax = max(sweep)
        hmax = random_triplet_history(np.random.default_rng(geometry_seed + 1), kmax,
                                      np.deg2rad(sv), np.deg2rad(sw), partition=part)
        for k in sweep:
            h = first_views(hmax, k)
            for method in task["methods"]:
                if method == "reference" and not task.get("reference_sweep", False):
                    continue
                opts = task["options"].get(method, {})
                seed = np.random.SeedSequence(solver_root.entropy,
                                              spawn_key=(1000 + k, METHODS.index(method)))
                est, dt = _solve(h, method, part, seed, opts)
                rows.append(_row(h, est, method, sv, sw, part, dt, k, sweep=True))
    return rows


def first_views(h, k):
    """The history of the first k views of ``h`` (the same geometry and noise draws)."""
    from dataclasses import replace

    truth = replace(h.truth, poses_ab=h.truth.poses_ab[:k], poses_world=h.truth.poses_world[:k],
                    camera_states=h.truth.camera_states[:k])
    kw = {}
    if getattr(h, "views", None) is not None:
        kw["views"] = h.views[:k]
    return replace(h, bearings=h.bearings[:k], headings=h.headings[:k - 1], truth=truth, **kw)


# ---------------------------------------------------------------------------------------------
# summaries


def _q(v):
    v = np.asarray(v, dtype=float)
    return np.percentile(v, [25, 50, 75]) if v.size else np.full(3, np.nan)


def grid_table(rows: list[dict]) -> list[dict]:
    """Per (sigma_v, sigma_w, method): n and the 25/50/75th percentiles of every metric."""
    rows = [r for r in rows if not r.get("sweep")]
    keys = sorted({(r["sigma_v_deg"], r["sigma_w_deg"], r["method"]) for r in rows},
                  key=lambda k: (k[0], k[1], METHODS.index(k[2])))
    by = {}
    for r in rows:
        by.setdefault((r["sigma_v_deg"], r["sigma_w_deg"], r["method"]), []).append(r)
    out = []
    for key in keys:
        sub = by[key]
        rec = {"sigma_v_deg": key[0], "sigma_w_deg": key[1], "method": key[2], "n": len(sub)}
        for met in METRICS + ("camera_top1", "camera_dmse", "time_s"):
            if met not in sub[0]:
                continue
            q = _q([r[met] for r in sub])
            rec.update({f"{met}_p25": q[0], f"{met}_p50": q[1], f"{met}_p75": q[2]})
        rec["top1"] = float(np.mean([r["gt_rating"] == 1 for r in sub]))
        rec.update(_scores(sub))
        rec["degenerate"] = int(sum(r["degenerate"] for r in sub))
        out.append(rec)
    return out


def _scores(sub: list[dict]) -> dict:
    """Proper scores and calibration of a set of rows: mean log p(truth) (clipped at 1e-4) with
    its standard error, mean Brier score, how often a state given more than 0.9 is wrong, the
    mean top probability, and the expected calibration error of the top state (10 bins)."""
    ls = np.array([r["log_score"] for r in sub])
    out = {"log_score_mean": float(ls.mean()),
           "log_score_se": float(ls.std(ddof=1) / np.sqrt(ls.size)) if ls.size > 1 else 0.0,
           "brier_mean": float(np.mean([r["brier"] for r in sub])),
           "confidently_wrong": float(np.mean([r["p_max"] > 0.9 and r["map_state"] != r["gt_state"]
                                               for r in sub])),
           "p_max_mean": float(np.mean([r["p_max"] for r in sub]))}
    if all("p" in r for r in sub):
        P, g = _probs(sub)
        out["ece_top"] = metrics.expected_calibration_error(P, g, 10, "top")
    return out


def _probs(sub):
    """(P (N, m), truths (N,)) from the rows; the stored probabilities (6 digits) renormalized."""
    P = np.array([[float(v) for v in r["p"].split()] for r in sub])
    return P / P.sum(axis=1, keepdims=True), np.array([int(r["gt_state"]) for r in sub])


def _write_csv(path: Path, recs: list[dict]) -> None:
    write_table(path, recs)


def _zeroed(x: float) -> float:
    """x, or 0.0 when |x| < 1e-12: percentiles of non-negative quantities (entropy, DMSE) come
    out as -0.0 or -1e-17 from floating-point rounding, which must not print as "-0"."""
    return 0.0 if abs(x) < 1e-12 else x


def _fmt(x):
    x = _zeroed(x)
    if x == 0:
        return "0"
    if abs(x) < 0.01:
        return f"{x:.0e}"
    return f"{x:.2f}"


def table1(grid: list[dict], headline) -> tuple[list[dict], str]:
    """Table 1: percentiles at the headline combination, ours next to the paper's (the paper has
    full, fast and baseline; fast-paper and reference have no paper column)."""
    sv, sw = headline
    cells = {m: next((r for r in grid if r["sigma_v_deg"] == sv and r["sigma_w_deg"] == sw
                      and r["method"] == m), None) for m in METHODS}
    methods = [m for m in METHODS if cells[m]]
    recs, lines = [], []
    head = []
    for m in methods:
        head += [f"{m} (ours)"] + ([f"{m} (paper)"] if m in PAPER_TABLE1 else [])
    lines.append("| metric (p25, p50, p75) | " + " | ".join(head) + " |")
    lines.append("|---|" + "---|" * len(head))
    for met, label in (("dmse", "DMSE"), ("gmd", "gmd"), ("entropy", "entropy"),
                       ("gt_rating", "GT rating")):
        row = [label]
        for m in methods:
            r = cells[m]
            row.append(", ".join(_fmt(r[f"{met}_p{p}"]) for p in (25, 50, 75)))
            paper = PAPER_TABLE1.get(m, {}).get(met)
            if m in PAPER_TABLE1:
                row.append(", ".join(_fmt(v) for v in paper) if paper else "-")
            recs.append({"metric": met, "method": m, "p25": r[f"{met}_p25"],
                         "p50": r[f"{met}_p50"], "p75": r[f"{met}_p75"],
                         "paper": list(paper) if paper else None})
        lines.append("| " + " | ".join(row) + " |")
    row = ["time per triplet (median)"]
    for m in methods:
        r = cells[m]
        row.append(f"{r['time_s_p50'] * 1e3:.1f} ms")
        if m in PAPER_TABLE1:
            row.append(f"{PAPER_TABLE1[m]['time_s']:g} s (MATLAB)")
        recs.append({"metric": "time_s", "method": m, "p25": r["time_s_p25"],
                     "p50": r["time_s_p50"], "p75": r["time_s_p75"],
                     "paper": PAPER_TABLE1.get(m, {}).get("time_s")})
    lines.append("| " + " | ".join(row) + " |")
    n = next((cells[m]["n"] for m in methods), 0)
    head = (f"sigma_v = {sv:g} deg, sigma_w = {sw:g} deg, {n} scenarios per method; "
            "percentiles 25, 50, 75.")
    return recs, head + "\n\n" + "\n".join(lines) + "\n"


def scores_table(grid: list[dict], combos) -> str:
    """Markdown: proper scores and calibration per combination and method."""
    lines = ["| sigma_v/sigma_w (deg) | method | n | mean log p(truth) | mean Brier | top-1 | "
             "confidently wrong | mean p_max | ECE (top) | median DMSE | median entropy |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for sv, sw in combos:
        for r in grid:
            if r["sigma_v_deg"] == sv and r["sigma_w_deg"] == sw:
                lines.append(
                    f"| {sv:g}/{sw:g} | {r['method']} | {r['n']} | {r['log_score_mean']:.3f} "
                    f"+- {r['log_score_se']:.3f} | {r['brier_mean']:.3f} | {r['top1']:.3f} | "
                    f"{r['confidently_wrong']:.3f} | {r['p_max_mean']:.3f} | "
                    f"{r.get('ece_top', float('nan')):.3f} | {_zeroed(r['dmse_p50']):.3f} | "
                    f"{_zeroed(r['entropy_p50']):.3g} |")
    return "\n".join(lines) + "\n"


def calibration_bound(rows: list[dict], headline) -> dict | None:
    """How often a calibrated forecaster can be nearly certain, from the reference rows at the
    headline. A calibrated forecast F is the conditional expectation of the exact posterior P
    given F (tower property: F = E[1{truth} | F] = E[P | F]). Where F's top state has
    probability > 1 - eps, E[1 - P_s | F] < eps, so (Markov) P_s >= 1 - delta except with
    probability eps / delta there:

        Pr(F_max > 1 - eps) <= Pr(P_max >= 1 - delta) / (1 - eps / delta).

    The paper's median entropy 5e-3 needs Pr(F_max > 0.9994) >= 1/2 (entropy 5e-3 nats forces
    1 - p_max < 6e-4); its 25th-percentile DMSE of 0 (< 0.005 as printed) needs
    Pr(p_truth > 0.9975) >= 1/4. With delta = 10 eps both bounds are about 1.11
    Pr(P_max >= 1 - 10 eps), read from the reference solver's posteriors."""
    sv, sw = headline
    ref = [r for r in rows if r["method"] == "reference" and not r.get("sweep")
           and r["sigma_v_deg"] == sv and r["sigma_w_deg"] == sw]
    if not ref:
        return None
    pm = np.array([r["p_max"] for r in ref])
    out = {"n": len(ref)}
    for name, eps, need in (("median_entropy_5e-3", 6e-4, 0.5), ("p25_dmse_0", 2.5e-3, 0.25)):
        frac = float(np.mean(pm >= 1 - 10 * eps))
        out[name] = {"eps": eps, "delta": 10 * eps, "frac_reference_p_max_ge_1_minus_delta": frac,
                     "bound": frac / (1 - 0.1), "needed": need}
    out["frac_reference_p_max_ge_0.99"] = float(np.mean(pm >= 0.99))
    out["reference_entropy_p50"] = float(np.median([r["entropy"] for r in ref]))
    out["reference_dmse_p25"] = float(np.percentile([r["dmse"] for r in ref], 25))
    return out


def reference_table(rows: list[dict]) -> tuple[list[dict], str]:
    """Every method against the reference, paired by scenario, at each combination where the
    reference ran: mean log-score difference (method - reference) with its standard error, mean
    KL(reference || method) and mean total variation of the landmark distributions."""
    main = [r for r in rows if not r.get("sweep") and "p" in r and "scenario" in r]
    ref = {(r["scenario"], r["sigma_v_deg"], r["sigma_w_deg"]): r for r in main
           if r["method"] == "reference"}
    combos = sorted({(k[1], k[2]) for k in ref})
    recs = []
    for sv, sw in combos:
        for m in METHODS:
            if m == "reference":
                continue
            pairs = [(r, ref[(r["scenario"], sv, sw)]) for r in main
                     if r["method"] == m and r["sigma_v_deg"] == sv and r["sigma_w_deg"] == sw
                     and (r["scenario"], sv, sw) in ref]
            if not pairs:
                continue
            d = np.array([a["log_score"] - b["log_score"] for a, b in pairs])
            P = _probs([a for a, _ in pairs])[0]
            R = _probs([b for _, b in pairs])[0]
            kl = np.sum(R * (np.log(np.maximum(R, 1e-12)) - np.log(np.maximum(P, 1e-6))), axis=1)
            recs.append({"sigma_v_deg": sv, "sigma_w_deg": sw, "method": m, "n": len(pairs),
                         "log_score_diff": float(d.mean()),
                         "log_score_diff_se": float(d.std(ddof=1) / np.sqrt(d.size))
                         if d.size > 1 else 0.0,
                         "kl_mean": float(kl.mean()),
                         "tv_mean": float(0.5 * np.abs(P - R).sum(axis=1).mean())})
    lines = ["| sigma_v/sigma_w (deg) | method | n | mean log p(truth) - reference's | "
             "mean KL(reference, method) | mean total variation |", "|---|---|---|---|---|---|"]
    for r in recs:
        lines.append(f"| {r['sigma_v_deg']:g}/{r['sigma_w_deg']:g} | {r['method']} | {r['n']} | "
                     f"{r['log_score_diff']:+.3f} +- {r['log_score_diff_se']:.3f} | "
                     f"{r['kl_mean']:.3f} | {r['tv_mean']:.3f} |")
    return recs, "\n".join(lines) + "\n"


def views_table(rows: list[dict]) -> tuple[list[dict], str]:
    """Scores per number of views (the views sweep rows)."""
    sw_rows = [r for r in rows if r.get("sweep")]
    keys = sorted({(r["n_views"], r["method"]) for r in sw_rows},
                  key=lambda k: (METHODS.index(k[1]), k[0]))
    recs = []
    for k, m in keys:
        sub = [r for r in sw_rows if r["n_views"] == k and r["method"] == m]
        rec = {"method": m, "n_views": k, "n": len(sub), **_scores(sub),
               "top1": float(np.mean([r["gt_rating"] == 1 for r in sub])),
               "flagged_no_survivor": float(np.mean(["survived" in str(r.get("reason", ""))
                                                     for r in sub])),
               "degenerate": float(np.mean([r["degenerate"] for r in sub])),
               "flagged_ess": float(np.mean(["effective sample size" in str(r.get("reason", ""))
                                             for r in sub])),
               "ess_p50": float(np.median([r["ess"] for r in sub])),
               "dmse_p50": float(np.median([r["dmse"] for r in sub])),
               "time_ms_p50": float(np.median([r["time_s"] for r in sub]) * 1e3)}
        # calibration where the method is nearly sure: how often a top state above 0.9 is right
        sure = [r for r in sub if r["p_max"] > 0.9]
        rec["sure_n"] = len(sure)
        rec["sure_claimed"] = float(np.mean([r["p_max"] for r in sure])) if sure else float("nan")
        rec["sure_right"] = (float(np.mean([r["map_state"] == r["gt_state"] for r in sure]))
                             if sure else float("nan"))
        recs.append(rec)
    lines = ["| method | views | n | mean log p(truth) | mean Brier | top-1 | confidently wrong | "
             "ECE (top) | p_max > 0.9: n, claimed, right | flagged | flagged ESS | median ESS | "
             "median ms |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in recs:
        lines.append(f"| {r['method']} | {r['n_views']} | {r['n']} | {r['log_score_mean']:.3f} "
                     f"+- {r['log_score_se']:.3f} | {r['brier_mean']:.3f} | {r['top1']:.3f} | "
                     f"{r['confidently_wrong']:.3f} | {r.get('ece_top', float('nan')):.3f} | "
                     f"{r['sure_n']}, {r['sure_claimed']:.3f}, {r['sure_right']:.3f} | "
                     f"{r['degenerate']:.3f} | {r['flagged_ess']:.3f} | {r['ess_p50']:.0f} | "
                     f"{r['time_ms_p50']:.1f} |")
    return recs, "\n".join(lines) + "\n"


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    """grid.csv, table1.csv/md, scores.md, views.csv/md, summary.json and figures/*.png."""
    p = _params(params)
    outdir = Path(outdir)
    if not rows:
        return
    main = [r for r in rows if not r.get("sweep")]
    grid = grid_table(rows)
    _write_csv(outdir / "grid.csv", grid)
    recs, md = table1(grid, p["headline"])
    _write_csv(outdir / "table1.csv", [{**r, "paper": json.dumps(r["paper"])} for r in recs])
    (outdir / "table1.md").write_text(md)
    hv, hw = p["headline"]
    combos = [(hv, hw)] + [d for d in _diagonal(p) if d != (hv, hw)]
    (outdir / "scores.md").write_text(scores_table(grid, combos))
    rrecs, rmd = reference_table(rows)
    if rrecs:
        (outdir / "reference.md").write_text(rmd)
    vrecs, vmd = views_table(rows)
    if vrecs:
        _write_csv(outdir / "views.csv", vrecs)
        (outdir / "views.md").write_text(vmd)
    present = [m for m in METHODS if any(r["method"] == m for r in main)]
    head = {m: next((r for r in grid if r["sigma_v_deg"] == hv and r["sigma_w_deg"] == hw
                     and r["method"] == m), None) for m in present}
    info = {
        "n_rows": len(rows),
        "n_scenarios": len({r["scenario"] for r in rows}) if "scenario" in rows[0] else None,
        "grid": {"sigma_v_deg": p["sigma_v_deg"], "sigma_w_deg": p["sigma_w_deg"]},
        "headline": p["headline"],
        "reference_noise": p["reference_noise"],
        "degenerate": {m: int(sum(r["degenerate"] for r in main if r["method"] == m))
                       for m in present},
        "headline_dmse_p50": {m: (r["dmse_p50"] if r else None) for m, r in head.items()},
        "headline_top1": {m: (r["top1"] if r else None) for m, r in head.items()},
        "headline_time_ms_p50": {m: (r["time_s_p50"] * 1e3 if r else None)
                                 for m, r in head.items()},
        # proper scores and calibration at the headline (log p(truth) clipped at 1e-4)
        "headline_mean_log_p_truth": {m: (r["log_score_mean"] if r else None)
                                      for m, r in head.items()},
        "headline_mean_brier": {m: (r["brier_mean"] if r else None) for m, r in head.items()},
        "headline_confidently_wrong": {m: (r["confidently_wrong"] if r else None)
                                       for m, r in head.items()},
        "headline_mean_p_max": {m: (r["p_max_mean"] if r else None) for m, r in head.items()},
        "headline_ece_top": {m: (r.get("ece_top") if r else None) for m, r in head.items()},
        "calibration_bound": calibration_bound(rows, p["headline"]),
        "against_reference": rrecs,
        "noiseless_top1": {m: next((r["top1"] for r in grid if r["sigma_v_deg"] == 0
                                    and r["sigma_w_deg"] == 0 and r["method"] == m), None)
                           for m in present},
        "noiseless_camera_top1_mean": {
            m: (float(np.mean([r["camera_top1"] for r in main if r["method"] == m
                               and r["sigma_v_deg"] == 0 and r["sigma_w_deg"] == 0]))
                if any(r["method"] == m and r["sigma_v_deg"] == 0 and r["sigma_w_deg"] == 0
                       for r in main) else None) for m in present},
        "views": vrecs,
    }
    (outdir / "summary.json").write_text(json.dumps(info, indent=2))
    figures(outdir / "figures", grid, p)
    reliability_figures(outdir, main, p["headline"])
    if vrecs:
        views_figure(outdir, vrecs)
    print(md)


def reliability_figures(outdir: Path, rows: list[dict], headline) -> list[Path]:
    """One reliability diagram per method at the headline: the top state (confidence = its
    probability, accuracy = how often it is the truth) and every state (probability against
    frequency true), 10 bins, with the binomial standard error of each bin."""
    import matplotlib.pyplot as plt

    sv, sw = headline
    paths = []
    for m in METHODS:
        sub = [r for r in rows if r["method"] == m and r["sigma_v_deg"] == sv
               and r["sigma_w_deg"] == sw and "p" in r]
        if not sub:
            continue
        P, g = _probs(sub)
        rel = metrics.reliability(P, g, 10)
        # constrained layout: room for the legend below the axes, where it covers no point
        fig, axes = plt.subplots(1, 2, figsize=(8.5, 4.4), layout="constrained")
        for ax, (conf, acc, cnt, title) in zip(axes, (
                (rel.top_confidence, rel.top_accuracy, rel.top_count, "most likely state"),
                (rel.all_confidence, rel.all_frequency, rel.all_count, "every state")),
                strict=True):
            ok = cnt > 0
            se = np.sqrt(np.clip(conf * (1 - conf), 0, None) / np.maximum(cnt, 1))
            ax.plot([0, 1], [0, 1], color="0.6", lw=1, ls="--", label="calibrated")
            ax.errorbar(conf[ok], acc[ok], yerr=2 * se[ok], fmt="o-", ms=4, capsize=2,
                        label="observed (+-2 se of a calibrated bin)")
            for x, y, c in zip(conf[ok], acc[ok], cnt[ok], strict=True):
                # below right of the point, but above it near the x axis and to its left near
                # the right edge, so that no count sits on an axis
                right = x > 0.85
                ax.annotate(str(int(c)), (x, y), fontsize=6, ha="right" if right else "left",
                            va="bottom" if y < 0.15 else "top",
                            xytext=(-4 if right else 4, 4 if y < 0.15 else -4),
                            textcoords="offset points")
            ax.set_xlim(0, 1)
            ax.set_ylim(-0.02, 1.02)
            ax.set_xlabel("predicted probability")
            ax.set_ylabel("frequency true")
            ax.set_title(title, fontsize=9)
            ax.grid(alpha=0.3)
        fig.legend(*axes[0].get_legend_handles_labels(), fontsize=7, loc="outside lower center",
                   ncol=2, frameon=False)
        fig.suptitle(f"{m}: reliability at sigma_v = {sv:g} deg, sigma_w = {sw:g} deg "
                     f"({len(sub)} scenarios; numbers: estimates per bin)", fontsize=9)
        paths.append(save_figure(fig, outdir, f"reliability_{m}", dpi=120))
    return paths


def views_figure(outdir: Path, vrecs: list[dict]) -> Path:
    """Mean log p(truth) (with 2 standard errors) and the confidently-wrong rate against the
    number of views."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    for m in METHODS:
        rs = sorted((r for r in vrecs if r["method"] == m), key=lambda r: r["n_views"])
        if not rs:
            continue
        color, marker, label = _STYLE[m]
        x = [r["n_views"] for r in rs]
        axes[0].errorbar(x, [r["log_score_mean"] for r in rs],
                         yerr=[2 * r["log_score_se"] for r in rs], color=color, marker=marker,
                         ms=4, capsize=2, label=label)
        axes[1].plot(x, [r["confidently_wrong"] for r in rs], color=color, marker=marker, ms=4,
                     label=label)
    axes[0].set_ylabel("mean log p(truth) (clip 1e-4)")
    axes[1].set_ylabel("confidently wrong (p_max > 0.9)")
    for ax in axes:
        ax.set_xlabel("views")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, outdir, "views_sweep", dpi=120)


def _mean(v):
    return float(np.mean(v)) if len(v) else None


def _diagonal(p):
    return [(sv, sw) for sv, sw in zip(p["sigma_v_deg"], p["sigma_w_deg"], strict=False)]


_STYLE = {"full": ("C0", "o", "ours (full)"), "fast": ("C1", "s", "ours (fast)"),
          "fast-paper": ("C3", "v", "fast, paper-literal"),
          "baseline": ("0.35", "^", "baseline (no motion)"),
          "reference": ("k", "*", "reference (exact posterior)")}
_LABEL = {"dmse": "DMSE", "gmd": "gmd (|AB|)", "entropy": "entropy (nats)",
          "gt_rating": "GT rating", "gt_likelihood": "GT likelihood"}


def _band(ax, recs, met, x, method):
    color, marker, label = _STYLE[method]
    med = np.array([r[f"{met}_p50"] for r in recs])
    lo = np.array([r[f"{met}_p25"] for r in recs])
    hi = np.array([r[f"{met}_p75"] for r in recs])
    ax.plot(x, med, color=color, marker=marker, ms=4, label=label)
    ax.fill_between(x, lo, hi, color=color, alpha=0.18, lw=0)


def figures(figdir: Path, grid: list[dict], params: dict) -> list[Path]:
    import matplotlib.pyplot as plt

    p = _params(params)
    figdir = Path(figdir)
    figdir.mkdir(parents=True, exist_ok=True)
    paths = []
    cell = {(r["sigma_v_deg"], r["sigma_w_deg"], r["method"]): r for r in grid}
    methods = [m for m in METHODS if m in p["methods"]]

    # the paper's Figs. results1/results2: metrics vs measurement noise, motion noise ~x2
    diag = [d for d in _diagonal(p) if all((d[0], d[1], m) in cell for m in methods)]
    if diag:
        for met in ("dmse", "gmd", "entropy", "gt_rating"):
            fig, ax = plt.subplots(figsize=(5.5, 3.8))
            for m in methods:
                recs = [cell[(sv, sw, m)] for sv, sw in diag]
                _band(ax, recs, met, [d[0] for d in diag], m)
            ax.set_xticks([d[0] for d in diag], [f"{sv:g}/{sw:g}" for sv, sw in diag])
            ax.set_xlabel("noise sigma_v / sigma_w (deg): bearings / headings")
            ax.set_ylabel(_LABEL[met])
            ax.set_title(f"EDC single triplet, 3 views: {_LABEL[met]} (median, 25-75%)",
                         fontsize=9)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
            fig.tight_layout()
            path = save_figure(fig, figdir.parent, f"{met}_vs_noise", dpi=120)
            paths.append(path)

    # the paper's Figs. mmResults / azResults: fast variant, one noise source at a time
    if "fast" in methods:
        for tag, fixed, key, xlab in (
                ("motion", "sigma_v_deg", "sigma_w_deg", "heading noise sigma_w (deg), sigma_v = 0"),
                ("measurement", "sigma_w_deg", "sigma_v_deg",
                 "bearing noise sigma_v (deg), sigma_w = 0")):
            recs = sorted([r for r in grid if r["method"] == "fast" and r[fixed] == 0],
                          key=lambda r: r[key])
            if len(recs) < 2:
                continue
            fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
            x = [r[key] for r in recs]
            for ax, met in zip(axes, ("gmd", "gt_rating", "gt_likelihood"), strict=True):
                _band(ax, recs, met, x, "fast")
                ax.set_xlabel(xlab)
                ax.set_ylabel(_LABEL[met])
                ax.grid(alpha=0.3)
            fig.suptitle(f"fast variant: sensitivity to {tag} noise alone (median, 25-75%)",
                         fontsize=10)
            fig.tight_layout()
            path = save_figure(fig, figdir.parent, f"fast_{tag}_noise", dpi=120)
            paths.append(path)

    # median DMSE over the whole grid
    sv, sw = p["sigma_v_deg"], p["sigma_w_deg"]
    if all((a, b, m) in cell for a in sv for b in sw for m in methods):
        fig, axes = plt.subplots(1, len(methods), figsize=(4.0 * len(methods) + 1, 3.6),
                                 layout="constrained")
        axes = np.atleast_1d(axes)
        for ax, m in zip(axes, methods, strict=True):
            Z = np.array([[cell[(a, b, m)]["dmse_p50"] for b in sw] for a in sv])
            im = ax.imshow(Z, origin="lower", vmin=0, vmax=1.2, cmap="viridis", aspect="auto")
            ax.set_xticks(range(len(sw)), [f"{b:g}" for b in sw])
            ax.set_yticks(range(len(sv)), [f"{a:g}" for a in sv])
            ax.set_xlabel("sigma_w (deg)")
            ax.set_ylabel("sigma_v (deg)")
            ax.set_title(f"{m}: median DMSE", fontsize=9)
            for i in range(len(sv)):
                for j in range(len(sw)):
                    ax.text(j, i, f"{Z[i, j]:.2f}", ha="center", va="center", fontsize=6,
                            color="w" if Z[i, j] < 0.6 else "k")
        fig.colorbar(im, ax=axes.tolist(), shrink=0.8)
        path = save_figure(fig, figdir.parent, "dmse_grid", dpi=120)
        paths.append(path)
    return paths


def hypothesis_figure(history, path, *, method: str = "full", seed: int = 0, partition="edc"):
    """Hypotheses of one triplet after each view (the paper's Fig. res_example): camera
    hypotheses of every view so far (one colour per view, size ~ weight), C hypotheses (red), the
    truth (stars and triangles), the estimate shading the partition. Views are added to a
    :class:`qfg.solvers.TripletSolver`, so each panel is the incremental estimate."""
    import matplotlib.pyplot as plt

    from qfg.harness.plotting import draw_partition
    from qfg.solvers import TripletSolver

    part = get_partition(partition)
    n = history.n_views
    fig, axes = plt.subplots(1, n, figsize=(4.6 * n, 5.2))
    axes = np.atleast_1d(axes)
    solver = TripletSolver(method, partition=part, sigma_bearing=history.sigma_bearing,
                           sigma_heading=history.sigma_heading, seed=seed)
    colors = plt.get_cmap("tab10")
    for i, ax in enumerate(axes):
        solver.add_view(history.bearings[i], history.headings[i - 1] if i else None)
        est, hyp = solver.estimate(), solver.hypotheses()
        draw_partition(part, ax, probabilities=est.landmark, highlight=history.truth.state)
        cw = hyp.camera_weights
        for t in range(est.n_views):
            w = cw[t]
            keep = w > 0
            sz = 1 + 20 * w[keep] / max(w.max(), 1e-300)
            ax.scatter(hyp.camera_samples[t, keep, 0], hyp.camera_samples[t, keep, 1], s=sz,
                       color=colors(t), alpha=0.5, lw=0, label=f"camera {t + 1} hypotheses")
        lw = hyp.landmark_weights
        keep = lw > 0
        ax.scatter(hyp.landmark_samples[keep, 0], hyp.landmark_samples[keep, 1],
                   s=1 + 20 * lw[keep] / max(lw.max(), 1e-300), color="red", alpha=0.5, lw=0,
                   label="C hypotheses")
        tc = history.truth.C_ab
        ax.plot(tc[0], tc[1], "*", color="darkred", ms=13, mec="k", label="C (truth)")
        cams = history.truth.poses_ab
        for t in range(i + 1):
            ax.plot(cams[t, 0], cams[t, 1], "^", color=colors(t), ms=9, mec="k")
        s, pm = est.most_likely
        ax.set_title(f"{method}, {i + 1} view(s): {est.n_hypotheses} hypotheses\n"
                     f"most likely {part.labels[s]} (p = {pm:.2f}), truth "
                     f"{part.labels[history.truth.state]}", fontsize=9)
        if i == 0:
            ax.legend(loc="lower left", fontsize=6, markerscale=0.6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


STUDY = Study("single-triplet", tasks, run_task, summarize,
              "single-triplet solvers vs noise: Table 1 and the figures of section 6c",
              params=param_spec(DEFAULTS, n_scenarios={"min": 1},
                                sigma_v_deg={"min": 0.0, "nonempty": True},
                                sigma_w_deg={"min": 0.0, "nonempty": True}, headline={"min": 0.0},
                                methods={"choices": METHODS, "nonempty": True}, n_views={"min": 1},
                                partition={"choices": ("edc", "fdc", "lr", "tpcc")}))
