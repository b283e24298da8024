"""Composition study (paper section 6e): AB:D inferred by composition alone.

Each scenario: four landmarks A, B, C, D and ``2 n_views`` camera poses, uniform in the paper's
box with the minimum distance (:func:`qfg.simulation.sample_positions`); the first ``n_views``
poses see A, B, C, the others B, C, D, so AB:C and BC:D have histories and AB:D is never seen.
Bearings get N(0, sigma_v^2) noise and the motion headings N(0, sigma_w^2), sigma_w =
``heading_ratio`` x sigma_v. AB:C and BC:D are solved by the fast single-triplet solver
(``qfg.solvers.solve_triplets(..., method="fast")``); with ``prior = "truth"`` their ground-truth
one-hot vectors are used instead and the output says so (``prior`` column, summary.json). AB:D
is then the composition marginal ``P(k) ~ sum_ij V1(i) V2(j) T(i, j, k)`` with the shipped
tensor.

Estimates of AB:D scored against its true state (DMSE, gmd, GT rating, entropy):

* ``composition``: the marginal above;
* ``uniform``: 1/m everywhere, the estimate before composition (the paper's reference);
* ``deterministic``: the same marginal with T replaced by its 0/1 support (McClelland et al.);
* ``oracle``: composition of the *true* states of AB:C and BC:D (one-hot): the best composition
  can do, i.e. what is lost by composition itself rather than by the solver.

Run: ``qfg experiment composition --preset paper --workers 2 --output out/composition``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from qfg import metrics
from qfg.composition import marginal, tensor
from qfg.geometry import bearing, to_frame, wrap_angle
from qfg.harness.runner import Study, param_spec, print_table, save_figure, validate_params, write_table
from qfg.partitions import get as get_partition
from qfg.partitions import state_of_triplet
from qfg.simulation import Scenario, sample_positions, triplet_histories
from qfg.solvers import solve_triplets

ESTIMATES = ("composition", "uniform", "deterministic", "oracle")
METRICS = ("dmse", "gmd", "gt_rating", "entropy")

DEFAULTS = {
    "n_per_level": 100,
    "sigma_bearing_deg": [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 10.0],
    "heading_ratio": 2.5,
    "n_views": 3,
    "partition": "edc",
    "prior": "fast",     # "fast": the fast single-triplet solver; "truth": one-hot GT priors
}


PARAMS = param_spec(DEFAULTS, n_per_level={"min": 1}, sigma_bearing_deg={"min": 0.0, "nonempty": True},
                    heading_ratio={"min": 0.0}, n_views={"min": 1},
                    partition={"choices": ("edc", "fdc", "lr", "tpcc")},
                    prior={"choices": ("fast", "truth")})


def _params(params: dict) -> dict:
    return validate_params(PARAMS, params)


def tasks(params: dict) -> list[dict]:
    """One task per scenario: noise level x repetition, in level order."""
    p = _params(params)
    out = []
    for sv in p["sigma_bearing_deg"]:
        for _ in range(int(p["n_per_level"])):
            out.append({"index": len(out), "sigma_bearing_deg": float(sv),
                        "sigma_heading_deg": float(sv) * float(p["heading_ratio"]),
                        "n_views": int(p["n_views"]), "partition": p["partition"],
                        "prior": p["prior"]})
    return out


def simulate(rng, n_views: int, sigma_bearing: float, sigma_heading: float) -> Scenario:
    """Landmarks 0..3 = A, B, C, D; poses 0..n-1 see A, B, C and poses n..2n-1 see B, C, D."""
    pts = sample_positions(rng, 4 + 2 * n_views)
    L = pts[:4]
    P = 2 * n_views
    poses = np.column_stack([pts[4:], rng.uniform(-np.pi, np.pi, size=P)])
    visible = np.zeros((P, 4), dtype=bool)
    visible[:n_views, [0, 1, 2]] = True
    visible[n_views:, [1, 2, 3]] = True
    phi = bearing(poses[:, None, :], L[None, :, :])
    phi = wrap_angle(phi + rng.normal(0.0, 1.0, size=phi.shape) * sigma_bearing)
    noise = rng.normal(0.0, 1.0, size=(P, P)) * sigma_heading
    return Scenario(landmarks=L, poses=poses, visible=visible,
                    bearings=np.where(visible, phi, 0.0), heading_noise=noise,
                    sigma_bearing=sigma_bearing, sigma_heading=sigma_heading)


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    part = get_partition(task["partition"])
    T = tensor(part.name)
    m = part.n_states
    sv, sw = np.deg2rad(task["sigma_bearing_deg"]), np.deg2rad(task["sigma_heading_deg"])
    scen = simulate(rng, int(task["n_views"]), sv, sw)
    hist = {h.landmarks: h for h in triplet_histories(scen, partition=part)}
    h1, h2 = hist[(0, 1, 2)], hist[(1, 2, 3)]
    A, B, C, D = scen.landmarks
    g1, g2 = h1.truth.state, h2.truth.state
    g3 = int(state_of_triplet(A, B, D, part))
    eye = np.eye(m)

    t0 = time.perf_counter()
    if task["prior"] == "fast":
        est = solve_triplets([h1, h2], method="fast", partition=part, seed=int(rng.integers(2**63)))
        V1, V2, prior = est[0].landmark, est[1].landmark, "fast"
        degenerate = bool(est[0].degenerate or est[1].degenerate)
    else:
        V1, V2, prior, degenerate = eye[g1], eye[g2], "truth", False
    t1 = time.perf_counter()
    comp = marginal(T, V1, V2, role=3)
    t2 = time.perf_counter()
    det = marginal(T, V1, V2, role=3, deterministic=True)
    oracle = marginal(T, eye[g1], eye[g2], role=3)
    ests = {"composition": comp.p, "uniform": np.full(m, 1.0 / m), "deterministic": det.p,
            "oracle": oracle.p}

    row = {"index": task["index"], "sigma_bearing_deg": task["sigma_bearing_deg"],
           "sigma_heading_deg": task["sigma_heading_deg"], "prior": prior,
           "partition": part.name, "state_abc": g1, "state_bcd": g2, "state_abd": g3,
           "c_in_window": bool(part.in_window(to_frame(C, A, B))),
           "d_in_window": bool(part.in_window(to_frame(D, A, B))),
           "d_in_bc_window": bool(part.in_window(to_frame(D, B, C))),
           "solver_degenerate": degenerate,
           "composition_zero_mass": bool(comp.zero_mass),
           "deterministic_zero_mass": bool(det.zero_mass),
           "abc_dmse": float(metrics.dmse(V1, g1)), "bcd_dmse": float(metrics.dmse(V2, g2)),
           "abc_gt_rating": int(metrics.gt_rating(V1, g1)),
           "bcd_gt_rating": int(metrics.gt_rating(V2, g2)),
           "time_solve": t1 - t0, "time_compose": t2 - t1}
    for name, p in ests.items():
        row[f"{name}_dmse"] = float(metrics.dmse(p, g3))
        row[f"{name}_gmd"] = float(metrics.gmd(p, g3, part.centroids))
        row[f"{name}_gt_rating"] = int(metrics.gt_rating(p, g3))
        row[f"{name}_entropy"] = float(metrics.entropy(p))
        row[f"{name}_gt_likelihood"] = float(metrics.gt_likelihood(p, g3))
    return [row]


def percentile_table(rows: list[dict]) -> list[dict]:
    """Per noise level and estimate: 25/50/75th percentiles of every metric (and the mean)."""
    levels = sorted({r["sigma_bearing_deg"] for r in rows})
    out = []
    for sv in levels:
        sub = [r for r in rows if r["sigma_bearing_deg"] == sv]
        for est in ESTIMATES + ("abc", "bcd"):
            rec = {"sigma_bearing_deg": sv, "sigma_heading_deg": sub[0]["sigma_heading_deg"],
                   "estimate": est, "n": len(sub),
                   "m": get_partition(sub[0]["partition"]).n_states}
            for met in METRICS:
                key = f"{est}_{met}"
                if key not in sub[0]:
                    continue
                v = np.array([r[key] for r in sub], dtype=float)
                q = np.percentile(v, [25, 50, 75])
                rec.update({f"{met}_p25": q[0], f"{met}_p50": q[1], f"{met}_p75": q[2],
                            f"{met}_mean": float(v.mean())})
            out.append(rec)
    return out


def _in_windows(r: dict) -> bool:
    return bool(r["c_in_window"] and r["d_in_window"] and r["d_in_bc_window"])


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    """summary.csv (percentiles per noise level), summary.json, figures/*.png."""
    outdir = Path(outdir)
    if not rows:
        return
    table = percentile_table(rows)
    write_table(outdir / "summary.csv", table)
    priors = sorted({r["prior"] for r in rows})
    info = {
        "n_scenarios": len(rows),
        "priors": priors,
        "note": ("AB:C and BC:D estimated by the fast single-triplet solver" if priors == ["fast"]
                 else "AB:C and BC:D given as GROUND-TRUTH ONE-HOT priors (not solved)"
                 if priors == ["truth"] else f"mixed priors {priors}"),
        "composition_zero_mass": int(sum(r["composition_zero_mass"] for r in rows)),
        "solver_degenerate": int(sum(r["solver_degenerate"] for r in rows)),
        "outside_windows": int(sum(not _in_windows(r) for r in rows)),
        # The tensor only knows configurations inside the windows: outside them the true triple
        # can be one it calls infeasible, and then even the oracle gives the truth 0.
        "oracle_truth_zero": int(sum(r["oracle_gt_likelihood"] == 0 for r in rows)),
        "oracle_truth_zero_inside_windows": int(sum(r["oracle_gt_likelihood"] == 0
                                                    for r in rows if _in_windows(r))),
        "composition_truth_zero": int(sum(r["composition_gt_likelihood"] == 0 for r in rows)),
        "overall": {f"{e}_{m}_p50": float(np.median([r[f"{e}_{m}"] for r in rows]))
                    for e in ESTIMATES for m in METRICS},
    }
    (outdir / "summary.json").write_text(json.dumps(info, indent=2))
    print_table(headline_table(table), title=f"composition study: {info['note']}; {len(rows)} "
                "scenarios; median DMSE of AB:D per bearing noise (deg)")
    figures(outdir, table)


def headline_table(table: list[dict]) -> list[dict]:
    """Median DMSE of AB:D per noise level, one column per estimate (the printed table)."""
    out = []
    for sv in sorted({r["sigma_bearing_deg"] for r in table}):
        rec = {"sigma_v_deg": sv, "n": next(r["n"] for r in table if r["sigma_bearing_deg"] == sv)}
        for est in ESTIMATES:
            r = next((r for r in table if r["sigma_bearing_deg"] == sv and r["estimate"] == est), None)
            rec[est] = r["dmse_p50"] if r else None
        out.append(rec)
    return out


def figures(outdir: Path, table: list[dict]) -> list[Path]:
    """The paper's Fig. (results_composition1): DMSE, gmd and GT rating vs measurement noise,
    median with the 25-75 percentile band, composition against uniform (and the others);
    written to ``<outdir>/figures/`` in the run's format."""
    import matplotlib.pyplot as plt

    style = {"composition": ("C0", "-", "composition (fast priors)"),
             "uniform": ("0.4", "--", "uniform (no information)"),
             "deterministic": ("C2", ":", "deterministic composition"),
             "oracle": ("C3", "-.", "composition of the true states")}
    paths = []
    labels = {"dmse": "DMSE (dimensionless)", "gmd": "gmd [|AB|]", "gt_rating": "GT rating (rank)"}
    for met in ("dmse", "gmd", "gt_rating"):
        fig, ax = plt.subplots(figsize=(5.5, 3.8))
        for est, (color, ls, label) in style.items():
            recs = [r for r in table if r["estimate"] == est]
            x = np.array([r["sigma_bearing_deg"] for r in recs])
            med = np.array([r[f"{met}_p50"] for r in recs])
            lo = np.array([r[f"{met}_p25"] for r in recs])
            hi = np.array([r[f"{met}_p75"] for r in recs])
            if met == "gt_rating" and est == "uniform":
                # Ties count for the truth, so the uniform estimate always rates 1; its rank
                # with ties broken at random is (m + 1) / 2.
                m = recs[0]["m"]
                ax.axhline((m + 1) / 2, color=color, ls=ls,
                           label=f"uniform, ties broken at random ({(m + 1) / 2:g})")
                continue
            ax.plot(x, med, color=color, ls=ls, marker="o", ms=3, label=label)
            if est == "composition" or (est == "uniform" and met != "gt_rating"):
                ax.fill_between(x, lo, hi, color=color, alpha=0.15, lw=0)
        ax.set_xlabel("bearing noise sigma_v (deg); sigma_w = %.3g sigma_v"
                      % (table[-1]["sigma_heading_deg"] / table[-1]["sigma_bearing_deg"]
                         if table[-1]["sigma_bearing_deg"] else float("nan")))
        ax.set_ylabel(labels[met])
        title = {"dmse": "DMSE", "gmd": "gmd", "gt_rating": "GT rating"}[met]
        ax.set_title(f"AB:D by composition: {title} (median, 25-75%)", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        paths.append(save_figure(fig, outdir, f"composition_{met}"))
    return paths


STUDY = Study(name="composition", tasks=tasks, run_task=run_task, summarize=summarize,
              description="AB:D inferred by composition from solved AB:C and BC:D (paper 6e)",
              params=PARAMS)
