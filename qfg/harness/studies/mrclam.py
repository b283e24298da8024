"""MRCLAM study (paper section 6d, Table 2): qualitative mapping on real data.

For one MRCLAM dataset directory (:func:`run_dataset`):

1. Load it (:func:`qfg.datasets.mrclam.load`) and check the landmark ground truth against the
   measurements (:func:`~qfg.datasets.mrclam.check_landmarks`); landmark pairs seen at each
   other's ground-truth position are swapped back before scoring (dataset 1: subjects 11 and 17).
   The swaps applied are in every row (``gt_swaps``) and in ``summary.json``.
2. Every triplet history of the chosen robots (:func:`~qfg.datasets.mrclam.triplet_histories`,
   loader defaults) is solved with :func:`qfg.solvers.solve_triplets` (``method``); a robot without
   odometry is solved without motion model (``baseline``), and the row's ``method`` says so.
3. Several histories of one ordered triplet (several passes or robots) are combined by
   ``combine``: ``"product"`` (default) ``P(S | H_1..H_r) ~ prod_h P(S | H_h)``, renormalized -- the
   passes' measurements are independent given the landmarks, so their likelihoods multiply (the
   solver's state prior, uniform positions in its window, is counted r times instead of once: an
   approximation that sharpens, documented in docs/results/mrclam.md); if the product is zero
   everywhere (contradicting passes), the mean of the estimates is used and ``combine_fallback``
   is set. ``"mean"``: the mixture; ``"best"``: the estimate of least entropy.
4. The whole qualitative map: every ordered triplet of the dataset's landmarks
   (:func:`qfg.graph.full_map`, 15 landmarks: 2730 triplets, 32760 composition factors), the
   combined estimates as priors, the rest propagated by Algorithm 2
   (:func:`qfg.propagation.propagate`).
5. Scoring against the landmark ground truth (:func:`qfg.graph.truth_states`): DMSE, gmd, entropy,
   GT rating (:mod:`qfg.metrics`) of the seen triplets (their combined estimate) and of the unseen
   ones (after propagation), each next to the uniform estimate.

Rows: one per ordered triplet (``kind`` = ``"seen"`` or ``"propagated"``). ``summarize`` writes
``triplets.csv``, ``summary.json`` (``{"n_triplets", "seen": {metric: [p25, p50, p75]},
"propagated": {...}, "uniform_seen", "uniform_propagated", "datasets": {name: ...}}``) and figures.

Command: ``qfg mrclam PATH`` (one dataset); ``qfg experiment mrclam --preset paper`` (every
dataset under ``data``, one runner task each).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from qfg import metrics
from qfg.datasets import mrclam as _mrclam
from qfg.harness.runner import Study, figure_format, param_spec, save_figure, write_table
from qfg.partitions import get as get_partition

METRICS = ("dmse", "gmd", "entropy", "gt_rating")
COMBINE = ("product", "mean", "best")
METHODS = ("fast", "full", "baseline")
EDC_WINDOW_CORNERS = ((-2.0, -2.0), (2.0, 3.0))

DEFAULTS = {
    "data": "",                            # directory holding MRCLAM_Dataset* ("": $QFG_MRCLAM_DIR)
    "datasets": [],                        # dataset numbers (empty: every one found)
    "robots": [],                          # robot numbers (empty: every robot)
    "method": "fast",
    "combine": "product",
    "partition": "edc",
    "fix_landmarks": True,                 # swap back landmark pairs found by check_landmarks
    "tensor": "",                          # .npz file; "" = the shipped tensor of the partition
}


# ----------------------------------------------------------------------------- combination
def combine_estimates(vectors, how: str = "product") -> tuple[np.ndarray, bool]:
    """Combine r estimates (r, m) of one triplet into one (m,) vector; returns (vector, fallback).

    ``product``: ``prod_h p_h`` renormalized (independent evidence); when it is zero everywhere,
    the mean is returned with ``fallback=True``. ``mean``: ``sum_h p_h / r``. ``best``: the row of
    least entropy (:func:`qfg.metrics.entropy`).

    >>> combine_estimates([[0.5, 0.5], [0.8, 0.2]])[0].round(2).tolist()
    [0.8, 0.2]
    """
    if how not in COMBINE:
        raise ValueError(f"combine: expected one of {COMBINE}, got {how!r}")
    P = metrics._probs(np.atleast_2d(np.asarray(vectors, dtype=float)))
    if P.ndim != 2 or P.shape[0] == 0:
        raise ValueError(f"vectors: expected shape (r, m) with r >= 1, got {P.shape}")
    if how == "best":
        return P[int(np.argmin(metrics.entropy(P)))].copy(), False
    mean = P.mean(axis=0)
    if how == "mean":
        return mean / mean.sum(), False
    # product in logs with a per-row max shift: r small, but entries can be tiny
    with np.errstate(divide="ignore"):
        logp = np.log(P).sum(axis=0)
    if not np.isfinite(logp).any():
        return mean / mean.sum(), True
    w = np.exp(logp - logp.max())
    return w / w.sum(), False


# ----------------------------------------------------------------------------- one dataset
def _load_tensor(partition: str, path: str | None):
    from qfg.composition import load, tensor

    return load(path, partition) if path else tensor(partition)


def prepare(path, *, fix_landmarks: bool = True):
    """Load a dataset directory; returns (dataset with ground truth fixed, swaps applied)."""
    ds = _mrclam.load(path)
    swaps = _mrclam.check_landmarks(ds).swaps if fix_landmarks else ()
    if swaps:
        ds = _mrclam.swap_landmarks(ds, swaps)
    return ds, tuple(tuple(int(x) for x in s) for s in swaps)


def histories(ds, robots=None, **options):
    """Triplet histories of ``robots`` (None / empty: every robot), robot-major, with the robot."""
    robots = sorted(ds.robots) if not robots else [int(r) for r in robots]
    out = []
    for r in robots:
        out += [(r, h) for h in _mrclam.triplet_histories(ds, r, **options)]
    return out


#: Histories solved per call: an estimate keeps its solver state (for add_view), megabytes for the
#: baseline, so only the (m,) vectors are kept and the estimates dropped chunk by chunk (dataset 5,
#: 3270 baseline histories in one call, exhausted 24 GB).
CHUNK = 128


@dataclass(frozen=True)
class _Light:
    landmark: np.ndarray
    method: str
    degenerate: bool


def _solve(hs, method, part, seed, options) -> list[_Light]:
    """Solve in chunks of :data:`CHUNK`; chunk c gets child c of ``SeedSequence(seed)``."""
    from qfg.solvers import solve_triplets

    n_chunks = -(-len(hs) // CHUNK)
    seeds = np.random.SeedSequence(seed).spawn(n_chunks) if n_chunks else []
    out: list[_Light] = []
    for c in range(n_chunks):
        ests = solve_triplets(hs[c * CHUNK:(c + 1) * CHUNK], method=method, partition=part,
                              seed=seeds[c], **options)
        out += [_Light(e.landmark, e.method, bool(e.degenerate)) for e in ests]
        del ests
    return out


def run_dataset(path, *, robots=None, method: str = "fast", combine: str = "product",
                partition: str = "edc", tensor=None, fix_landmarks: bool = True, seed=0,
                return_details: bool = False, **solver_options):
    """Solve, combine, map, propagate and score one dataset directory.

    Args:
        path: an MRCLAM dataset directory.
        robots: robot numbers (None: all).
        method: single-triplet solver (``"fast"``, ``"full"``, ``"baseline"``); robots without
            odometry always get the baseline (the row's ``method``).
        combine: how several histories of one ordered triplet become one prior
            (:func:`combine_estimates`).
        tensor: composition tensor ((m, m, m) array or CompositionTensor); None: the shipped one.
        seed: solver seed (histories are solved in chunks of :data:`CHUNK`, chunk c with child c
            of ``SeedSequence(seed)``; the fast variant does not depend on the seed).

    Returns:
        rows: list of dicts, one per ordered triplet of the dataset's landmarks. With
        ``return_details``: ``(rows, details)``, details a dict with the dataset, histories,
        estimates, the graph and the propagation result (for figures).
    """
    from qfg.graph import full_map, truth_states
    from qfg.propagation import propagate

    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    if combine not in COMBINE:
        raise ValueError(f"combine: expected one of {COMBINE}, got {combine!r}")
    part = get_partition(partition)
    T = _load_tensor(part.name, None) if tensor is None else tensor
    ds, swaps = prepare(path, fix_landmarks=fix_landmarks)
    t0 = time.perf_counter()
    rh = histories(ds, robots, partition=part)
    hs = [h for _, h in rh]
    ests = _solve(hs, method, part, seed, solver_options)
    t_solve = time.perf_counter() - t0

    # group the histories by ordered triplet, in landmark-column indices
    groups: dict[tuple, list[int]] = {}
    for q, h in enumerate(hs):
        groups.setdefault(tuple(ds.landmark_index(h.landmarks).tolist()), []).append(q)
    priors, fallback = {}, {}
    for t, qs in groups.items():
        priors[t], fallback[t] = combine_estimates([ests[q].landmark for q in qs], combine)

    t0 = time.perf_counter()
    L = ds.landmark_ids.size
    g = full_map(L, partition=part.name, tensor=T, priors=priors)
    res = propagate(g)
    t_prop = time.perf_counter() - t0

    trip = np.array(g.triplets, dtype=np.intp)
    truth = truth_states(trip, ds.landmark_xy, part.name)
    P = res.marginals
    ev = metrics.evaluate(P, truth, part.centroids)
    U = np.full_like(P, 1.0 / P.shape[1])
    uv = metrics.evaluate(U, truth, part.centroids)
    ids = ds.landmark_ids
    swap_txt = ";".join(f"{a}-{b}" for a, b in swaps)
    rows = []
    for v, t in enumerate(map(tuple, trip.tolist())):
        qs = groups.get(t, [])
        seen = bool(g.seen[v])
        row = {
            "dataset": ds.name, "path": str(Path(path)), "kind": "seen" if seen else "propagated",
            "A": int(ids[t[0]]), "B": int(ids[t[1]]), "C": int(ids[t[2]]),
            "truth_state": int(truth[v]), "map_state": int(np.argmax(P[v])),
            "n_histories": len(qs), "n_views": int(sum(hs[q].n_views for q in qs)),
            "robots": ";".join(str(r) for r in sorted({rh[q][0] for q in qs})),
            "method": ";".join(sorted({ests[q].method for q in qs})) if qs else "propagated",
            "n_degenerate": int(sum(ests[q].degenerate for q in qs)),
            "combine": combine if seen else "", "combine_fallback": bool(fallback.get(t, False)),
            "reached": bool(res.reached[v]), "isc": float(res.isc[v]), "gt_swaps": swap_txt,
        }
        for k in ("dmse", "gmd", "entropy", "gt_rating", "gt_likelihood"):
            row[k] = float(ev[k][v]) if k != "gt_rating" else int(ev[k][v])
        for k in METRICS:
            row[f"uniform_{k}"] = float(uv[k][v]) if k != "gt_rating" else int(uv[k][v])
        rows.append(row)
    if rows:
        rows[0]["time_solve_s"] = t_solve
        rows[0]["time_propagate_s"] = t_prop
    if not return_details:
        return rows
    return rows, {"dataset": ds, "swaps": swaps, "histories": rh, "estimates": ests,  # light
                  "graph": g, "propagation": res, "partition": part}


# ----------------------------------------------------------------------------- summaries
def percentiles(values) -> list[float]:
    """[p25, p50, p75] of ``values`` (NaNs when empty)."""
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return [float("nan")] * 3
    return [float(x) for x in np.percentile(v, [25, 50, 75])]


def summary(rows: list[dict]) -> dict:
    """``{"n_triplets", "n_seen", "n_propagated", "n_reached", "seen": {metric: [p25, p50, p75]},
    "propagated": {...}, "uniform_seen": {...}, "uniform_propagated": {...}}`` of some rows."""
    out: dict = {"n_triplets": len(rows)}
    for kind in ("seen", "propagated"):
        sel = [r for r in rows if r["kind"] == kind]
        out[f"n_{kind}"] = len(sel)
        out[kind] = {k: percentiles([r[k] for r in sel]) for k in METRICS}
        out[f"uniform_{kind}"] = {k: percentiles([r[f"uniform_{k}"] for r in sel]) for k in METRICS}
    prop = [r for r in rows if r["kind"] == "propagated"]
    out["n_reached"] = int(sum(r["reached"] for r in prop))
    seen = [r for r in rows if r["kind"] == "seen"]
    out["n_fallback"] = int(sum(r["combine_fallback"] for r in seen))
    out["n_baseline"] = int(sum("baseline" in r["method"] for r in seen))
    out["gt_swaps"] = sorted({r["gt_swaps"] for r in rows if r["gt_swaps"]})
    for kind in ("seen", "propagated"):
        sel = [r for r in rows if r["kind"] == kind]
        out[f"{kind}_top1"] = float(np.mean([r["gt_rating"] == 1 for r in sel])) if sel else float("nan")
    return out


def _fmt(x) -> str:
    return "nan" if not np.isfinite(x) else (f"{x:.2g}" if abs(x) < 0.01 and x != 0 else f"{x:.2f}")


def table_lines(summ: dict) -> list[str]:
    """Markdown rows (dataset, kind, estimate, metrics as p25/p50/p75) for summary dicts."""
    lines = ["| dataset | triplets | estimate | DMSE | gmd | entropy | GT rating |",
             "|---|---|---|---|---|---|---|"]
    names = list(summ.get("datasets", {})) + ["all"]
    for name in names:
        s = summ if name == "all" else summ["datasets"][name]
        for kind in ("seen", "propagated"):
            for est in (kind, f"uniform_{kind}"):
                label = ("uniform" if est.startswith("uniform") else
                         ("solver" if kind == "seen" else "propagated"))
                cells = [" / ".join(_fmt(x) for x in s[est][k]) for k in METRICS]
                lines.append(f"| {name} | {kind} {s[f'n_{kind}']} | {label} | " + " | ".join(cells) + " |")
    return lines


def _write_csv(path: Path, rows: list[dict]):
    write_table(path, rows, digits=None)


def write_outputs(outdir, rows: list[dict], *, figures: bool = True, figure_robot=None,
                  details=None) -> dict:
    """``triplets.csv``, ``summary.json``, ``table.md`` and figures for rows of one or more
    datasets; returns the summary dict."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    _write_csv(out / "triplets.csv", rows)
    names = list(dict.fromkeys(r["dataset"] for r in rows))
    summ = summary(rows)
    summ["datasets"] = {n: summary([r for r in rows if r["dataset"] == n]) for n in names}
    (out / "summary.json").write_text(json.dumps(summ, indent=2) + "\n")
    (out / "table.md").write_text("\n".join(table_lines(summ)) + "\n")
    if figures and rows:
        fig_dir = out / "figures"
        fig_dir.mkdir(exist_ok=True)
        for n in names:
            sub = [r for r in rows if r["dataset"] == n]
            det = details if details is not None and details["dataset"].name == n else None
            make_figures(fig_dir, sub, details=det, robot=figure_robot)
    return summ


# ----------------------------------------------------------------------------- figures
def _pick_triplet(rows, robot=None):
    """The seen row with the most views (of ``robot`` if given; motion model and no degenerate
    history preferred: a degenerate estimate is uniform and shows no hypotheses)."""
    seen = [r for r in rows if r["kind"] == "seen"
            and (robot is None or str(robot) in r["robots"].split(";"))]
    if not seen:
        return None
    return max(seen, key=lambda r: ("baseline" not in r["method"], int(r["n_degenerate"]) == 0,
                                    r["n_views"], -r["A"], -r["B"], -r["C"]))


def make_figures(fig_dir: Path, rows: list[dict], *, details=None, robot=None) -> list[Path]:
    """Landmarks + one robot's dead-reckoned path, and one triplet's hypotheses in its AB frame.

    The triplet is the seen one with most views; its longest non-degenerate history is solved
    again (seed 0, the rows' method) to get the hypotheses: C samples (size ~ weight), camera
    samples per view, and the state probabilities of that history.
    """
    import matplotlib.pyplot as plt

    from qfg.harness.plotting import draw_partition
    from qfg.harness.plotting_mrclam import dataset_figure
    from qfg.solvers import TripletSolver

    row = _pick_triplet(rows, robot) or _pick_triplet(rows)
    name = rows[0]["dataset"]
    if details is not None:
        ds = details["dataset"]
    else:
        ds, _ = prepare(rows[0]["path"], fix_landmarks=bool(rows[0]["gt_swaps"]))
    paths = []
    if row is None:
        return paths
    r = int(row["robots"].split(";")[0]) if robot is None else int(robot)
    trip = (row["A"], row["B"], row["C"])
    hs = [h for rr, h in histories(ds, [r]) if tuple(h.landmarks) == trip]
    sols = [(x, TripletSolver.solve(x, method=row["method"].split(";")[0], seed=0)) for x in hs]
    h, solver = max(sols, key=lambda he: (not he[1].estimate().degenerate, he[0].n_views))
    est, hyp = solver.estimate(), solver.hypotheses()
    p = dataset_figure(ds, r, fig_dir / f"{name}_robot{r}.{figure_format()}", history=h)
    paths.append(Path(p))

    fig, axes = plt.subplots(1, 2, figsize=(11, 6))
    ax = draw_partition("edc", axes[0], probabilities=est.landmark, highlight=h.truth.state,
                        label_states=True)
    w = hyp.landmark_weights
    if hyp.landmark_samples.size and w.size:
        keep = w > w.max() * 1e-3
        ax.scatter(*hyp.landmark_samples[keep].T, s=4 + 40 * w[keep] / w.max(), c="tab:blue",
                   alpha=0.6, label="C hypotheses")
    cs = hyp.camera_samples
    if cs.size:
        cw = hyp.camera_weights
        for i in range(cs.shape[0]):
            sel = slice(None) if cw is None else cw[i] > cw[i].max() * 1e-3
            ax.scatter(*cs[i][sel][:, :2].T, s=3, alpha=0.3, label=f"camera {i + 1}")
    c = h.truth.C_ab
    ax.plot(c[0], c[1], "r*", ms=14, label="C (truth)")
    # cameras are often outside the partition window: widen the view to every point drawn
    pts = np.vstack([ax.dataLim.get_points(), np.reshape(EDC_WINDOW_CORNERS, (2, 2))])
    ax.set_xlim(pts[:, 0].min() - 0.2, pts[:, 0].max() + 0.2)
    ax.set_ylim(pts[:, 1].min() - 0.2, pts[:, 1].max() + 0.2)
    ax.legend(loc="lower right", fontsize=6)
    ax.set_title(f"{name} robot {r}: {trip[0]},{trip[1]}:{trip[2]}, {h.n_views} views, "
                 f"{est.method}", fontsize=9)
    draw_partition("edc", axes[1], probabilities=est.landmark, highlight=h.truth.state)
    axes[1].plot(c[0], c[1], "r*", ms=14)
    top = int(np.argmax(est.landmark))
    axes[1].set_title(f"P(state | this history); truth {h.truth.state + 1} (red), most likely "
                      f"{top + 1} (p = {est.landmark[top]:.2f})", fontsize=9)
    fig.tight_layout()
    paths.append(save_figure(fig, Path(fig_dir).parent, f"{name}_triplet_{trip[0]}_{trip[1]}_{trip[2]}",
                             dpi=120))
    return paths


# ----------------------------------------------------------------------------- runner study
def _params(params: dict) -> dict:
    unknown = set(params) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"params: unknown keys {sorted(unknown)}; known: {sorted(DEFAULTS)}")
    p = {**DEFAULTS, **params}
    if p["method"] not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {p['method']!r}")
    if p["combine"] not in COMBINE:
        raise ValueError(f"combine: expected one of {COMBINE}, got {p['combine']!r}")
    return p


def dataset_dirs(data, numbers=()) -> list[Path]:
    """``MRCLAM_Dataset<N>`` directories under ``data`` (only ``numbers`` if given), by N. An empty
    ``data`` means the directory named by ``$QFG_MRCLAM_DIR`` (:func:`qfg.datasets.mrclam.data_root`)."""
    root = _mrclam.data_root(data or None)
    if not root.is_dir():
        raise ValueError(f"data: {root} is not a directory")
    found = {}
    for d in root.iterdir():
        if d.is_dir() and d.name.startswith("MRCLAM_Dataset") and d.name[14:].isdigit():
            found[int(d.name[14:])] = d
    want = [int(n) for n in numbers] if numbers else sorted(found)
    missing = [n for n in want if n not in found]
    if missing:
        raise ValueError(f"datasets: {missing} not found under {root} (has {sorted(found)})")
    return [found[n] for n in want]


def tasks(params: dict) -> list[dict]:
    """One task per dataset directory."""
    p = _params(params)
    return [{"index": i, "path": str(d), "robots": list(p["robots"]), "method": p["method"],
             "combine": p["combine"], "partition": p["partition"],
             "fix_landmarks": bool(p["fix_landmarks"]), "tensor": p["tensor"]}
            for i, d in enumerate(dataset_dirs(p["data"], p["datasets"]))]


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    T = _load_tensor(task["partition"], task["tensor"] or None)
    return run_dataset(task["path"], robots=task["robots"] or None, method=task["method"],
                       combine=task["combine"], partition=task["partition"], tensor=T,
                       fix_landmarks=task["fix_landmarks"], seed=int(rng.integers(2**63)))


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    print("\n".join(table_lines(write_outputs(outdir, rows))))


STUDY = Study(name="mrclam", tasks=tasks, run_task=run_task, summarize=summarize,
              description="MRCLAM datasets: triplet estimates, full map, propagation (paper 6d)",
              params=param_spec(DEFAULTS, method={"choices": METHODS},
                                combine={"choices": COMBINE}, partition={"choices": ("edc",)}))

__all__ = ["run_dataset", "combine_estimates", "summary", "write_outputs", "make_figures",
           "dataset_dirs", "tasks", "run_task", "summarize", "STUDY", "DEFAULTS", "prepare",
           "histories", "percentiles", "table_lines"]
