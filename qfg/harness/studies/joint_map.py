"""Joint map study: the joint metric posterior (:mod:`qfg.joint`) against the paper's
pipeline and its map methods, on the same simulated trajectory runs.

Each scenario is one robot driving a trajectory among landmarks
(:func:`qfg.simulation.random_trajectory_run`: paper noise, bearings 2 deg, direction of travel
5 deg, plus 5 % step length and 2 deg turn), in one of these ``cases``:

==================  =================================================================
``base``            ``n_landmarks`` landmarks, ``n_poses`` poses, odometry
``few_landmarks``   4 landmarks
``few_views``       ``few_poses`` poses
``noisy_odometry``  odometry noise x ``noisy_factor`` (direction, length and turn)
``no_odometry``     no odometry: one robot, whose fit the joint method cannot check against
                    another's, so it falls back (flag ``unverified``); the pipeline solves
                    without motion model (``baseline``)
==================  =================================================================

Methods, each giving every ordered triplet a state distribution, scored against the truth on
*seen* triplets (three landmarks in one image in at least 3 images, as MRCLAM defines it) and
*unseen* ones:

* ``joint``: :func:`qfg.joint.solve` + :func:`qfg.joint.triplet_marginals` on all the
  measurements (answer = the prior's state distribution where it cannot solve, flagged);
* the paper's pipeline: every seen triplet's 3 views spread over the images that saw it, the
  odometry's direction of travel between them (dead-reckoned), solved by
  :func:`qfg.solvers.solve_triplets` (``solver``; ``baseline`` without odometry), the six
  orderings' estimates as priors of the full map (:func:`qfg.graph.full_map`), then
  ``best`` (Algorithm 2, :func:`qfg.propagation.propagate` with ``method="best"``), ``pooled``
  (``method="pooled"``),
  ``exact`` (exact composition, :func:`qfg.propagation.exact_marginals`; only where the
  junction tree fits, else empty) and ``config-state`` (configuration inference on the seen
  estimates, :func:`qfg.configurations.configuration_marginals`, ``method="config-state"``);
* ``prior``: the world prior's state distribution alone.

Rows: one per (scenario, method, kind) with mean log score (clip 1e-4), Brier, truth under 1 %,
ECE (top state), n and the method's time. Run: ``qfg experiment joint_map --preset quick``.
"""

from __future__ import annotations

import itertools
import json
import time
from pathlib import Path

import numpy as np

from qfg import metrics
from qfg.harness.runner import Study, param_spec, print_table, validate_params, write_table

CASES = ("base", "few_landmarks", "few_views", "noisy_odometry", "no_odometry")
METHODS = ("joint", "config-state", "exact", "best", "pooled", "prior")
KINDS = ("seen", "unseen")

DEFAULTS = {
    "n_per_case": 10,
    "cases": list(CASES),
    "n_landmarks": 8,
    "n_poses": 40,
    "few_poses": 12,
    "fov_deg": 150.0,
    "noisy_factor": 4.0,
    "solver": "fast",
    "samples": 1000,
    "config_particles": 1000,
    "methods": list(METHODS),
}

PARAMS = param_spec(DEFAULTS, n_per_case={"min": 1}, n_landmarks={"min": 4},
                    n_poses={"min": 4}, few_poses={"min": 4}, fov_deg={"min": 1.0},
                    noisy_factor={"min": 0.0}, solver={"choices": ("fast", "full")},
                    samples={"min": 10}, config_particles={"min": 50},
                    cases={"choices": CASES, "nonempty": True},
                    methods={"choices": METHODS, "nonempty": True})


def _params(params: dict) -> dict:
    return validate_params(PARAMS, params)


def tasks(params: dict) -> list[dict]:
    """One task per (case, repetition), case-major."""
    p = _params(params)
    out = []
    for c in p["cases"]:
        for i in range(int(p["n_per_case"])):
            out.append({"index": len(out), "case": c, "rep": i,
                        **{k: p[k] for k in DEFAULTS if k not in ("n_per_case", "cases")}})
    return out


def simulate(task: dict, rng):
    """The case's trajectory run and whether the odometry is available."""
    from qfg.simulation import random_trajectory_run

    c = task["case"]
    kw = dict(n_landmarks=int(task["n_landmarks"]), n_poses=int(task["n_poses"]),
              fov_deg=float(task["fov_deg"]))
    if c == "few_landmarks":
        kw["n_landmarks"] = 4
    if c == "few_views":
        kw["n_poses"] = int(task["few_poses"])
    if c == "noisy_odometry":
        f = float(task["noisy_factor"])
        kw.update(sigma_heading=np.deg2rad(5.0) * f, sigma_step=0.05 * f,
                  sigma_turn=np.deg2rad(2.0) * f)
    return random_trajectory_run(rng, **kw), c != "no_odometry"


def seen_histories(run, odometry: bool):
    """The pipeline's input: every ordered triplet whose landmarks share at least 3 images, with
    3 of them spread over those images, the dead-reckoned direction of travel between them, and
    the noise the solver is told (bearings: the run's; directions: the run's direction noise plus
    the accumulated turn noise over the steps between the views)."""
    from qfg.geometry import motion_heading
    from qfg.joint.start import chain as _chain
    from qfg.simulation import TripletHistory

    P = _chain(np.zeros(3), run.odometry)
    vis = run.visible
    out = []
    for trip in itertools.combinations(range(run.n_landmarks), 3):
        idx = np.flatnonzero(vis[:, list(trip)].all(axis=1))
        if idx.size < 3:
            continue
        keep = idx[np.unique(np.round(np.linspace(0, idx.size - 1, 3)).astype(int))]
        if odometry:
            psi = motion_heading(P[keep[:-1]], P[keep[1:], :2])
            steps = np.diff(keep).max()
            sh = float(run.sigma_heading + np.sqrt(steps) * run.sigma_turn)
        else:
            psi, sh = np.zeros(keep.size - 1), 0.0
        for perm in itertools.permutations(trip):
            out.append(TripletHistory(landmarks=perm, bearings=run.bearings[np.ix_(keep, perm)],
                                      headings=psi, sigma_bearing=run.sigma_bearing,
                                      sigma_heading=sh, views=keep, has_motion=odometry))
    return out


def _score(P, g):
    if len(g) == 0:
        return {"n": 0}
    return {"n": int(len(g)), "log_score": float(metrics.log_score(P, g).mean()),
            "brier": float(metrics.brier(P, g).mean()),
            "truth_under_1pct": float(metrics.truth_under(P, g, 0.01).mean()),
            "p_top_hit": float(np.mean(P.argmax(1) == g)),
            "ece": float(metrics.expected_calibration_error(P, g))}


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    import qfg
    from qfg import joint
    from qfg.combine import prior_state_distribution
    from qfg.graph import full_map, truth_states

    run, odo = simulate(task, rng)
    L = run.n_landmarks
    trip = np.array(list(itertools.permutations(range(L), 3)), dtype=np.intp)
    keys = [tuple(t) for t in trip.tolist()]
    g = truth_states(trip, run.landmarks, "edc")
    q = prior_state_distribution("world", "edc", samples=100_000, seed=0)
    methods = list(task["methods"])
    P, times, flags = {}, {}, {}
    seeds = np.random.SeedSequence(int(rng.integers(2**63))).spawn(4)
    hs = seen_histories(run, odo)
    seen_set = {h.landmarks for h in hs}
    seen = np.array([k in seen_set for k in keys])
    if "joint" in methods:
        t0 = time.perf_counter()
        post = joint.solve(joint.simulated_measurements(run, odometry=odo), seed=0)
        res = joint.triplet_marginals(post, keys, samples=int(task["samples"]), seed=seeds[0],
                                      prior_states=q)
        P["joint"] = res.probabilities
        times["joint"] = time.perf_counter() - t0
        flags["joint"] = ";".join(post.flags) or "-"
    if "prior" in methods:
        P["prior"], times["prior"], flags["prior"] = np.tile(q, (len(keys), 1)), 0.0, "-"
    graph_methods = [m for m in ("config-state", "exact", "best", "pooled") if m in methods]
    if graph_methods:
        t0 = time.perf_counter()
        ests = qfg.solve_triplets(hs, method=task["solver"] if odo else "baseline",
                                  seed=seeds[1]) if hs else []
        t_solve = time.perf_counter() - t0
        priors = {h.landmarks: e.landmark for h, e in zip(hs, ests, strict=False)}
        # a flagged answer's ESS may be 0 or NaN: it carries no evidence
        ess = {h.landmarks: (e.ess if e.ess > 0 else 1e-9) for h, e in zip(hs, ests, strict=False)}
        for m in graph_methods:
            t0 = time.perf_counter()
            fl = "-"
            try:
                if not priors:
                    out = np.tile(q, (len(keys), 1))
                    fl = "nothing_seen"
                elif m == "config-state":
                    from qfg.configurations import configuration_marginals, one_ordering_per_set

                    ev = one_ordering_per_set(priors)
                    # each estimate widened by the ESS behind it, as in the other studies
                    r = configuration_marginals(ev, "world", triplets=keys,
                                                n_particles=int(task["config_particles"]),
                                                ess={t: ess[t] for t in ev}, seed=seeds[2])
                    out = np.array([r[k] for k in keys])
                else:
                    gr = full_map(L, partition="edc", priors=priors)
                    if m == "exact":
                        r = qfg.exact_marginals(gr)
                    else:
                        r = qfg.propagate(gr, method=m)
                    out = np.array([r[k] for k in keys])
            except (MemoryError, ValueError) as exc:  # exact: junction tree too large
                out, fl = None, type(exc).__name__
            P[m] = out
            times[m] = time.perf_counter() - t0 + t_solve
            flags[m] = fl
    rows = []
    for m in methods:
        if m not in P:
            continue
        for kind, sel in (("seen", seen), ("unseen", ~seen)):
            row = {"case": task["case"], "rep": int(task["rep"]), "method": m, "kind": kind,
                   "n_landmarks": L, "n_poses": run.n_poses, "odometry": odo,
                   "views_per_image": float(run.visible.sum(1).mean()),
                   "time_s": float(times[m]), "flags": flags[m]}
            if P[m] is None:
                row["n"] = int(sel.sum())
            else:
                Pm = np.asarray(P[m], float)
                Pm = Pm / Pm.sum(1, keepdims=True)
                row.update(_score(Pm[sel], g[sel]))
            rows.append(row)
    return rows


SUMMARY_KEYS = ("log_score", "brier", "truth_under_1pct", "ece", "time_s")


def summary_rows(rows: list[dict]) -> list[dict]:
    """Means over scenarios per (case, kind, method), weighting each scenario's mean by its
    number of triplets (scores) or once (time); scenarios where a method had no answer are
    counted in ``n_missing``."""
    out = []
    keys = sorted({(r["case"], r["kind"], r["method"]) for r in rows},
                  key=lambda k: (CASES.index(k[0]), KINDS.index(k[1]), METHODS.index(k[2])))
    for case, kind, m in keys:
        sel = [r for r in rows if (r["case"], r["kind"], r["method"]) == (case, kind, m)]
        ok = [r for r in sel if r.get("log_score") not in (None, "") and int(r.get("n", 0))]
        rec = {"case": case, "kind": kind, "method": m, "scenarios": len(sel),
               "n_missing": len(sel) - len(ok), "triplets": int(sum(int(r["n"]) for r in ok))}
        w = np.array([int(r["n"]) for r in ok], float)
        for k in SUMMARY_KEYS[:-1]:
            v = np.array([float(r[k]) for r in ok])
            rec[k] = float(np.sum(v * w) / w.sum()) if w.sum() else float("nan")
        rec["time_s"] = float(np.mean([float(r["time_s"]) for r in sel])) if sel else float("nan")
        fl = [str(r.get("flags", "-")) for r in sel if str(r.get("flags", "-")) != "-"]
        rec["flagged_scenarios"] = len(fl)
        out.append(rec)
    return out


def winners(summ: list[dict]) -> list[dict]:
    """Per (case, kind): the method with the highest mean log score."""
    out = []
    for case, kind in sorted({(r["case"], r["kind"]) for r in summ},
                             key=lambda k: (CASES.index(k[0]), KINDS.index(k[1]))):
        sel = [r for r in summ if (r["case"], r["kind"]) == (case, kind)
               and np.isfinite(r["log_score"]) and r["n_missing"] == 0]
        if sel:
            b = max(sel, key=lambda r: r["log_score"])
            out.append({"case": case, "kind": kind, "best": b["method"],
                        "log_score": b["log_score"]})
    return out


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    summ = summary_rows(rows)
    out = Path(outdir)
    write_table(out / "summary.csv", summ)
    (out / "summary.json").write_text(json.dumps({"summary": summ, "winners": winners(summ)},
                                                 indent=1) + "\n")
    print_table(summ, ["case", "kind", "method", "triplets", "n_missing", "log_score", "brier",
                       "truth_under_1pct", "ece", "time_s", "flagged_scenarios"],
                title="joint map study: mean over triplets (log score clip 1e-4)")


STUDY = Study(name="joint_map", tasks=tasks, run_task=run_task, summarize=summarize,
              description="joint metric posterior (GTSAM) vs the paper's pipeline, composition "
                          "and configuration inference on simulated trajectories, seen and unseen",
              params=PARAMS)

__all__ = ["STUDY", "DEFAULTS", "CASES", "METHODS", "tasks", "run_task", "summarize",
           "summary_rows", "winners", "simulate", "seen_histories"]
