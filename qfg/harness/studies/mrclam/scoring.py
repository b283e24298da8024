"""Scores of the MRCLAM study (step 7): every row of a map (:func:`score_map`) and every
captured camera view scored against the ground truth beside the uniform and prior-alone
baselines; the summaries of rows (:func:`kind_summary`, :func:`summary`) and their table
(:func:`table_lines`, :data:`TABLE_KEY`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from qfg import metrics
from qfg.harness.studies.mrclam.params import KINDS, MODES

if TYPE_CHECKING:
    from qfg.harness.studies.mrclam.pipeline import LightEstimate, Prepared


def score_map(prep: Prepared, seen, result, ests: list[LightEstimate], common: dict) -> list[dict]:
    """Rows of a map (module docstring, step 7): every row of ``result`` scored against the
    landmark ground truth, beside the uniform and prior-alone baselines."""
    from qfg.graph import truth_states

    ds, part = prep.dataset, prep.partition
    trip = np.asarray(result.triplets, dtype=np.intp).reshape(-1, 3)
    P = np.asarray(result.probabilities, dtype=float).reshape(len(trip), part.n_states)
    P = P / P.sum(axis=1, keepdims=True)
    missing = {tuple(t) for t in seen.triplets.tolist()} - {tuple(t) for t in trip.tolist()}
    if missing:
        raise ValueError(f"map {common.get('map')!r}: leaves out {len(missing)} seen triplet(s)")
    truth = truth_states(trip, ds.landmark_xy, part.name) if len(trip) else np.zeros(0, int)
    sc = _score_rows(P, truth, prep.prior_states, part.centroids) if len(trip) else {}
    conflict = {tuple(t): bool(c) for t, c in zip(seen.triplets.tolist(), seen.conflict,
                                                   strict=True)}
    rh, ids = prep.histories, ds.landmark_ids
    rows = []
    for v, t in enumerate(map(tuple, trip.tolist())):
        ks = seen.groups.get(t, [])
        row = {**common, "kind": "seen" if result.seen[v] else "propagated",
               "A": int(ids[t[0]]), "B": int(ids[t[1]]), "C": int(ids[t[2]]),
               "truth_state": int(truth[v]), "map_state": int(np.argmax(P[v])),
               "n_histories": len(ks), "n_views": int(sum(rh[k][1].n_views for k in ks)),
               "robots": ";".join(str(r) for r in sorted({rh[k][0] for k in ks})),
               "method": ";".join(sorted({ests[k].method for k in ks})) if ks else "propagated",
               # share of the row's histories the solver flagged (degenerate geometry, low ESS)
               "flagged": float(np.mean([ests[k].degenerate for k in ks])) if ks else 0.0,
               "conflict": conflict.get(t, False),
               "reached": bool(result.reached[v])}
        for key, arr in sc.items():
            row[key] = float(arr[v])
        row["probabilities"] = _enc(P[v])
        rows.append(row)
    return rows


def _enc(p) -> str:
    return ";".join(f"{x:.6g}" for x in p)


def decode(text: str) -> np.ndarray:
    """A row's ``probabilities`` back to an (m,) vector (renormalized: 6 digits were written)."""
    p = np.array([float(x) for x in str(text).split(";")])
    return p / p.sum()


def _scores(P, g, prefix=""):
    """Scores of estimates (n, m) at truths (n,): dict of (n,) arrays, keys prefixed."""
    return {f"{prefix}p_truth": metrics.gt_likelihood(P, g),
            f"{prefix}log_score": metrics.log_score(P, g),
            f"{prefix}brier": metrics.brier(P, g),
            f"{prefix}gt_rating": metrics.gt_rating(P, g),
            f"{prefix}truth_under_1pct": metrics.truth_under(P, g, 0.01).astype(float)}


def _score_rows(P, g, q, centroids):
    """Per row: the estimate's scores, DMSE, entropy, whether it is uniform, and the baselines
    (uniform; the prior's state distribution ``q``)."""
    n, m = P.shape
    out = _scores(P, g)
    out.update(_scores(np.full((n, m), 1.0 / m), g, "uniform_"))
    out.update(_scores(np.broadcast_to(q, (n, m)), g, "prior_"))
    out["dmse"] = metrics.dmse(P, g)
    out["entropy"] = metrics.entropy(P)
    out["uniform_estimate"] = (np.ptp(P, axis=1) < 1e-9).astype(float)
    return out


def _camera_rows(hs, rh, ests, q, part, common) -> list[dict]:
    """One row per view covered by motion capture: P(S^{AB:X}_i | H) against the captured
    camera's state."""
    rows = []
    for k, h in enumerate(hs):
        cs = h.truth.camera_states
        if cs is None:
            continue
        ok = np.ones(h.n_views, bool) if h.groundtruth_valid is None else np.asarray(
            h.groundtruth_valid, bool)
        ok &= np.asarray(cs) >= 0
        idx = np.flatnonzero(ok)
        if idx.size == 0:
            continue
        Pc = np.asarray(ests[k].cameras, dtype=float)[idx]
        Pc = Pc / Pc.sum(axis=1, keepdims=True)
        g = np.asarray(cs)[idx].astype(int)
        sc = _score_rows(Pc, g, q, part.centroids)
        for j, i in enumerate(idx):
            row = {**common, "kind": "camera", "A": int(h.landmarks[0]), "B": int(h.landmarks[1]),
                   "C": int(h.landmarks[2]), "robot": int(rh[k][0]), "history": k,
                   "view": int(i), "time": float(h.views[i]), "n_views": int(h.n_views),
                   "truth_state": int(g[j]), "map_state": int(np.argmax(Pc[j])),
                   "method": ests[k].method, "flagged": float(ests[k].degenerate)}
            for key, arr in sc.items():
                row[key] = float(arr[j])
            row["probabilities"] = _enc(Pc[j])
            rows.append(row)
    return rows


# ----------------------------------------------------------------------------- summaries
def _mean(rows, key) -> float:
    v = [float(r[key]) for r in rows if r.get(key) not in (None, "")]
    return float(np.mean(v)) if v else float("nan")


def kind_summary(rows: list[dict]) -> dict:
    """Scores of rows of one kind: ``n``; mean log score, Brier, GT rating, truth-under-1% rate
    of the estimate and of both baselines (``uniform_*``, ``prior_*``); flagged and uniform
    estimates; median DMSE; expected calibration error (top state)."""
    out: dict = {"n": len(rows)}
    for pre in ("", "uniform_", "prior_"):
        for k in ("log_score", "brier", "gt_rating", "truth_under_1pct"):
            out[f"{pre}{k}"] = _mean(rows, f"{pre}{k}")
    out["flagged"] = _mean(rows, "flagged")
    out["uniform_estimate"] = _mean(rows, "uniform_estimate")
    out["dmse_median"] = float(np.median([float(r["dmse"]) for r in rows])) if rows else float("nan")
    if rows:
        P = np.array([decode(r["probabilities"]) for r in rows])
        g = np.array([int(r["truth_state"]) for r in rows])
        out["ece"] = metrics.expected_calibration_error(P, g)
    else:
        out["ece"] = float("nan")
    return out


def summary(rows: list[dict]) -> dict:
    """``{mode: {kind: kind_summary}}`` plus counts: seen triplets whose histories conflict,
    propagated triplets reached, baseline-solved seen triplets."""
    out: dict = {"n_rows": len(rows)}
    for mode in sorted({r["mode"] for r in rows}):
        sel = [r for r in rows if r["mode"] == mode]
        d = {kind: kind_summary([r for r in sel if r["kind"] == kind]) for kind in KINDS}
        d["n_conflict"] = int(sum(str(r.get("conflict")) == "True" for r in sel
                                  if r["kind"] == "seen"))
        d["n_reached"] = int(sum(str(r.get("reached")) == "True" for r in sel
                                 if r["kind"] == "propagated"))
        d["n_baseline"] = int(sum("baseline" in str(r["method"]) for r in sel
                                  if r["kind"] == "seen"))
        out[mode] = d
    out["gt_swaps"] = sorted({r["gt_swaps"] for r in rows if r.get("gt_swaps")})
    return out


def _fmt(x, d=2) -> str:
    return "nan" if x is None or not np.isfinite(x) else f"{x:.{d}f}"


#: What the table's columns mean (printed under it by ``qfg mrclam``).
TABLE_KEY = ("Key: each score of the estimates (est.) beside two baselines: uniform (every state "
             "1/m) and prior (the state distribution the prior alone gives, no measurement). "
             "log score: mean ln p(truth), clipped at 1e-4, higher is better; Brier: lower is "
             "better; GT rating: rank of the true state, 1 best; truth < 1%: share of rows giving "
             "the truth under 1%; flagged: share of solves flagged degenerate; flat: share of "
             "uniform estimates; ECE: expected calibration error of the top state.")

_TABLE_SCORES = (("log_score", "log score", 2), ("brier", "Brier", 3), ("gt_rating", "GT rating", 2),
                 ("truth_under_1pct", "truth < 1%", 2))


def table_lines(summ: dict) -> list[str]:
    """Markdown rows: per dataset, mode and kind, each score of the estimates beside its uniform
    and prior-alone baselines, in labelled columns (:data:`TABLE_KEY`)."""
    head = ["dataset", "mode", "kind", "n"]
    for _, label, _ in _TABLE_SCORES:
        head += [f"{label} est.", "uniform", "prior"]
    head += ["flagged", "flat", "ECE"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    names = list(summ.get("datasets", {})) + ["all"]
    for name in names:
        s = summ if name == "all" else summ["datasets"][name]
        for mode in MODES:
            if mode not in s:
                continue
            for kind in KINDS:
                k = s[mode][kind]
                if not k["n"]:
                    continue
                cells = [name, mode, kind, str(k["n"])]
                for key, _, d in _TABLE_SCORES:
                    cells += [_fmt(k[f"{p}{key}"], d) for p in ("", "uniform_", "prior_")]
                cells += [_fmt(k["flagged"]), _fmt(k["uniform_estimate"]), _fmt(k["ece"])]
                lines.append("| " + " | ".join(cells) + " |")
    return lines
