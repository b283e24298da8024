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
from qfg.solvers import solve_triplet

METHODS = ("full", "fast", "baseline")
METRICS = ("dmse", "gt_rating", "gmd", "gt_likelihood", "gt_likelihood_ratio", "entropy",
           "likelihood_ratio", "information_score")

DEFAULTS = {
    "n_scenarios": 300,
    "sigma_v_deg": [0.0, 1.0, 2.0, 4.0, 7.0, 10.0],
    "sigma_w_deg": [0.0, 2.0, 5.0, 10.0, 14.0, 20.0],
    "headline": [2.0, 5.0],
    "methods": list(METHODS),
    "n_views": 3,
    "partition": "edc",
    "options": {},          # per-method solver options, e.g. {"full": {"n_samples": 300}}
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
    return p


def tasks(params: dict) -> list[dict]:
    """One task per geometry; each runs every noise combination and method."""
    p = _params(params)
    grid = [[float(sv), float(sw)] for sv in p["sigma_v_deg"] for sw in p["sigma_w_deg"]]
    return [{"scenario": i, "grid": grid, "methods": list(p["methods"]),
             "n_views": int(p["n_views"]), "partition": p["partition"],
             "options": p["options"]} for i in range(int(p["n_scenarios"]))]


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    part = get_partition(task["partition"])
    # one geometry (and one set of standard-normal noise draws) for every combination
    geometry_seed = int(rng.integers(2**63))
    solver_root = np.random.SeedSequence(int(rng.integers(2**63)))
    rows = []
    for c, (sv, sw) in enumerate(task["grid"]):
        h = random_triplet_history(np.random.default_rng(geometry_seed), task["n_views"],
                                   np.deg2rad(sv), np.deg2rad(sw), partition=part)
        g, gc = h.truth.state, h.truth.camera_states
        for k, method in enumerate(task["methods"]):
            opts = task["options"].get(method, {})
            seed = np.random.SeedSequence(solver_root.entropy, spawn_key=(c, k))
            t0 = time.perf_counter()
            est = solve_triplet(h, method=method, partition=part, seed=seed, **opts)
            dt = time.perf_counter() - t0
            row = {"sigma_v_deg": sv, "sigma_w_deg": sw, "method": method,
                   "gt_state": int(g), "map_state": int(np.argmax(est.landmark)),
                   "p_max": float(est.landmark.max()),
                   "c_in_window": bool(part.in_window(h.truth.C_ab))}
            vals = metrics.evaluate(est.landmark, g, part.centroids)
            row.update({name: (int(v) if name == "gt_rating" else float(v))
                        for name, v in vals.items()})
            row["camera_top1"] = float(np.mean(metrics.gt_rating(est.cameras, gc) == 1))
            row["camera_dmse"] = float(np.mean(metrics.dmse(est.cameras, gc)))
            row["n_hypotheses"] = int(est.n_hypotheses)
            row["degenerate"] = bool(est.degenerate)
            row["model"] = est.method
            row["time_s"] = dt
            rows.append(row)
    return rows


# ---------------------------------------------------------------------------------------------
# summaries


def _q(v):
    v = np.asarray(v, dtype=float)
    return np.percentile(v, [25, 50, 75]) if v.size else np.full(3, np.nan)


def grid_table(rows: list[dict]) -> list[dict]:
    """Per (sigma_v, sigma_w, method): n and the 25/50/75th percentiles of every metric."""
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
        rec["degenerate"] = int(sum(r["degenerate"] for r in sub))
        out.append(rec)
    return out


def _write_csv(path: Path, recs: list[dict]) -> None:
    write_table(path, recs)


def _fmt(x):
    if x == 0:
        return "0"
    if abs(x) < 0.01:
        return f"{x:.0e}"
    return f"{x:.2f}"


def table1(grid: list[dict], headline) -> tuple[list[dict], str]:
    """Table 1: percentiles at the headline combination, ours next to the paper's."""
    sv, sw = headline
    recs, lines = [], []
    lines.append("| metric (p25, p50, p75) | " + " | ".join(
        f"{m} (ours) | {m} (paper)" for m in METHODS) + " |")
    lines.append("|---|" + "---|---|" * len(METHODS))
    cells = {m: next((r for r in grid if r["sigma_v_deg"] == sv and r["sigma_w_deg"] == sw
                      and r["method"] == m), None) for m in METHODS}
    for met, label in (("dmse", "DMSE"), ("gmd", "gmd"), ("entropy", "entropy"),
                       ("gt_rating", "GT rating")):
        row = [label]
        for m in METHODS:
            r = cells[m]
            ours = ", ".join(_fmt(r[f"{met}_p{p}"]) for p in (25, 50, 75)) if r else "-"
            paper = PAPER_TABLE1[m].get(met)
            row += [ours, ", ".join(_fmt(v) for v in paper) if paper else "-"]
            if r:
                recs.append({"metric": met, "method": m, "p25": r[f"{met}_p25"],
                             "p50": r[f"{met}_p50"], "p75": r[f"{met}_p75"],
                             "paper": list(paper) if paper else None})
        lines.append("| " + " | ".join(row) + " |")
    row = ["time per triplet (median)"]
    for m in METHODS:
        r = cells[m]
        row += [f"{r['time_s_p50'] * 1e3:.1f} ms" if r else "-",
                f"{PAPER_TABLE1[m]['time_s']:g} s (MATLAB)"]
        if r:
            recs.append({"metric": "time_s", "method": m, "p25": r["time_s_p25"],
                         "p50": r["time_s_p50"], "p75": r["time_s_p75"],
                         "paper": PAPER_TABLE1[m]["time_s"]})
    lines.append("| " + " | ".join(row) + " |")
    n = next((r["n"] for r in cells.values() if r), 0)
    head = (f"sigma_v = {sv:g} deg, sigma_w = {sw:g} deg, {n} scenarios per method; "
            "percentiles 25, 50, 75.")
    return recs, head + "\n\n" + "\n".join(lines) + "\n"


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    """grid.csv, table1.csv/md, summary.json and figures/*.png."""
    p = _params(params)
    outdir = Path(outdir)
    if not rows:
        return
    grid = grid_table(rows)
    _write_csv(outdir / "grid.csv", grid)
    recs, md = table1(grid, p["headline"])
    _write_csv(outdir / "table1.csv", [{**r, "paper": json.dumps(r["paper"])} for r in recs])
    (outdir / "table1.md").write_text(md)
    hv, hw = p["headline"]
    head = {m: next((r for r in grid if r["sigma_v_deg"] == hv and r["sigma_w_deg"] == hw
                     and r["method"] == m), None) for m in METHODS}
    hrows = {m: [r for r in rows if r["method"] == m and r["sigma_v_deg"] == hv
                 and r["sigma_w_deg"] == hw] for m in METHODS}
    info = {
        "n_rows": len(rows),
        "n_scenarios": len({r["scenario"] for r in rows}) if "scenario" in rows[0] else None,
        "grid": {"sigma_v_deg": p["sigma_v_deg"], "sigma_w_deg": p["sigma_w_deg"]},
        "headline": p["headline"],
        "degenerate": {m: int(sum(r["degenerate"] for r in rows if r["method"] == m))
                       for m in METHODS},
        "headline_dmse_p50": {m: (r["dmse_p50"] if r else None) for m, r in head.items()},
        "headline_top1": {m: (r["top1"] if r else None) for m, r in head.items()},
        "headline_time_ms_p50": {m: (r["time_s_p50"] * 1e3 if r else None)
                                 for m, r in head.items()},
        # calibration at the headline: log-likelihood of the truth (clipped at 1e-9) and how often
        # a state given more than 0.9 is not the true one
        "headline_mean_log_p_truth": {
            m: _mean([np.log(max(r["gt_likelihood"], 1e-9)) for r in hrows[m]]) for m in METHODS},
        "headline_confidently_wrong": {
            m: _mean([r["p_max"] > 0.9 and r["map_state"] != r["gt_state"] for r in hrows[m]])
            for m in METHODS},
        "headline_mean_p_max": {m: _mean([r["p_max"] for r in hrows[m]]) for m in METHODS},
        "noiseless_top1": {m: next((r["top1"] for r in grid if r["sigma_v_deg"] == 0
                                    and r["sigma_w_deg"] == 0 and r["method"] == m), None)
                           for m in METHODS},
        "noiseless_camera_top1_mean": {
            m: (float(np.mean([r["camera_top1"] for r in rows if r["method"] == m
                               and r["sigma_v_deg"] == 0 and r["sigma_w_deg"] == 0]))
                if any(r["method"] == m and r["sigma_v_deg"] == 0 and r["sigma_w_deg"] == 0
                       for r in rows) else None) for m in METHODS},
    }
    (outdir / "summary.json").write_text(json.dumps(info, indent=2))
    figures(outdir / "figures", grid, p)
    print(md)


def _mean(v):
    return float(np.mean(v)) if len(v) else None


def _diagonal(p):
    return [(sv, sw) for sv, sw in zip(p["sigma_v_deg"], p["sigma_w_deg"], strict=False)]


_STYLE = {"full": ("C0", "o", "ours (full)"), "fast": ("C1", "s", "ours (fast)"),
          "baseline": ("0.35", "^", "baseline (no motion)")}
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
