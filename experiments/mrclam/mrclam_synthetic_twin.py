"""Where more views per pass stop helping on MRCLAM: the data, or the solver? A synthetic twin.

For dataset 6's histories (120-s passes, ``k`` views spread evenly over each, every view covered
by motion capture, the ascending ordering of each landmark set), each history is solved in up to
five variants by one solver (``--method``) with one noise model (``--model measured``: the
measured bearing tail, the heading walk and the step-length-ratio tail, as ``qfg mrclam
--bearing-tail measured --heading-walk measured --distance-tail measured``; ``--model simple``:
normal bearings and headings and a normal ratio, the model the reference solver takes):

* ``real``: as recorded;
* ``twin``: bearings, headings and step lengths made from the captured poses and the landmarks'
  ground truth, with noise drawn from the very model the solver assumes (each bearing from the
  bearing model, each step's heading from its sigma, each log ratio of consecutive step lengths
  from the ratio model, all independent). The geometry is the real one; only the errors are the
  model's;
* ``twin-bearings``: the twin's bearings with the recorded odometry;
* ``twin-odometry``: the recorded bearings with the twin's odometry;
* ``clean``: the twin without noise (the captured geometry's exact values).

On datasets 1-5, which have no motion capture, ``--reference joint`` makes the twin from the
joint map of every robot's views instead (`qfg.datasets.mrclam.joint_map.mrclam_reference`: its poses at every
usable view and its landmarks, aligned onto the landmarks' ground truth) and scores every variant
against the states that map gives; on dataset 6 the two references can be compared.

If more views help the twin but not the real data, the solver is sound on this geometry and the
loss is in how the real errors differ from the model; the two hybrids say which measurement
carries it. Prints, per variant and ``k``, the mean log p(truth) of the seen states (clip 1e-4),
the truth under 1%, and the paired difference against the smallest ``k`` with a standard error
clustered by landmark set; beside them what the answers expect of themselves
(:func:`qfg.metrics.expected_log_score`, :func:`qfg.metrics.expected_truth_under`): calibrated
answers score their self-expected mean, so a log score below it (by more than its standard
error, clustered by landmark set) says the truths are less likely than the solver claims, and an
exact solver's answers fall short only where the model (its prior above all) does not fit the
geometry.

    QFG_MRCLAM_DIR=... python experiments/mrclam/mrclam_synthetic_twin.py [--views 3 5] [--robots 1 2]
        [--dataset 6] [--reference capture]
        [--limit 0] [--seed 0] [--solver-seed SEED] [--method full] [--prior arena]
        [--model measured] [--camera-prior point]
        [--budget 1] [--populations 1] [--no-distances] [--csv out/twin.csv]
        [--against out/other.csv] [--from-csv out/twin.csv] [--detail] [--travel] [--geometry]
        [--detection] [--trajectory] [--mixture]

``--travel`` gives each history its own prior, :class:`qfg.priors.TravelPrior`: the arena box
joined with the odometry's first step length in metres (log error 0.07 with 10% at five times
that: dataset 6's steps against motion capture, robust sigma 0.064-0.072, 7-9% beyond 0.2), the
scale the ratios of step lengths do not carry. Histories are then solved one by one.
``--detection`` adds the camera's detection range to that prior (``DETECTION``);
``--trajectory`` reaches every camera after the first (after ``--travel``'s first two) by a
scale-free step (:class:`qfg.priors.TrajectoryPrior`); ``--mixture`` takes the equal mixture of
the box and that path (:class:`qfg.priors.MixturePrior`). docs/mrclam.md ("Held out: the misfit
is in the geometry, not in the errors", "Can the measurements choose the prior?") reports them.

Backs docs/mrclam.md ("Datasets 1-5: the noise against the joint map"), docs/results/mrclam.md
("More views per pass: the solver, not the data") and docs/solvers.md ("The cameras' prior in the
intermediate weights", "The budget"). Run from the repository root as above
(``QFG_MRCLAM_DIR``: the directory holding the MRCLAM_Dataset* directories).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import time
from pathlib import Path

import numpy as np

from qfg import joint
from qfg.datasets import mrclam
from qfg.datasets.mrclam.joint_map import mrclam_reference, mrclam_runs
from qfg.geometry import bearing, motion_heading, wrap_angle
from qfg.harness.studies import mrclam as study
from qfg.metrics import (
    clustered_se,
    expected_log_score,
    expected_truth_under,
    log_score,
    truth_under,
)
from qfg.priors import MixturePrior, TrajectoryPrior, TravelPrior
from qfg.solvers import solve_triplet, solve_triplets
from qfg.solvers.common.options import scaled_budget

VARIANTS = ("real", "twin", "twin-bearings", "twin-odometry", "clean")
CHUNK = 64


#: the parts of the measured noise model (``qfg mrclam`` options), each on or off
MODEL_PARTS = {"bearing_tail": "measured", "heading_walk": study.HEADING_WALK,
               "distance_tail": "measured"}


def model_parts(text: str) -> frozenset:
    """``--model``: "measured" (every part), "simple" (none) or parts joined by commas."""
    if text in ("measured", "simple"):
        return frozenset(MODEL_PARTS if text == "measured" else ())
    parts = frozenset(p.strip().replace("-", "_") for p in text.split(",") if p.strip())
    if not parts or parts - set(MODEL_PARTS):
        raise argparse.ArgumentTypeError(
            f"expected measured, simple or a subset of {', '.join(MODEL_PARTS)}; got {text!r}")
    return parts


def _mixture(rng, shape, sigma, share=0.0, scale=1.0, outlier=0.0) -> np.ndarray:
    """Draws of ``(1 - share - outlier) N(0, sigma) + share N(0, scale sigma) + outlier U(-pi,
    pi)``; ``sigma`` broadcasts against ``shape``."""
    u = rng.random(shape)
    z = rng.standard_normal(shape) * np.broadcast_to(sigma, shape)
    z = np.where(u < share, z * scale, z)
    return np.where(u >= 1.0 - outlier, rng.uniform(-np.pi, np.pi, shape), z)


def twin(h, rng, solver_options: dict, *, bearings: bool, odometry: bool, noise: float = 1.0,
         scale_error=None):
    """History ``h`` with its bearings and/or odometry replaced by the model's draws about the
    captured geometry (module docstring); ``noise`` 0: the captured geometry's exact values.
    ``scale_error`` (sigma, (share, scale)): every step length also scaled by one log error
    drawn from it (the lengths' scale, which ``--travel`` reads; None: exact)."""
    t = h.truth
    P = np.asarray(t.poses_world, dtype=float)
    out = {}
    if bearings:
        tail = solver_options.get("bearing_tail")
        if tail is not None and not isinstance(tail, tuple):
            tail = (tail.share, tail.scale, tail.outlier)
        kw = {} if tail is None else dict(zip(("share", "scale", "outlier"), tail, strict=True))
        phi = bearing(P[:, None, :], np.asarray(t.landmarks_world)[None, :, :])
        out["bearings"] = wrap_angle(phi + noise * _mixture(rng, phi.shape, h.sigma_bearing,
                                                            **kw))
    if odometry and h.n_views > 1:
        steps = h.n_views - 1
        psi = motion_heading(P[:-1], P[1:, :2])
        sh = np.broadcast_to(np.asarray(h.sigma_heading, dtype=float), (steps,))
        out["headings"] = wrap_angle(psi + noise * rng.standard_normal(steps) * sh)
        s = np.maximum(np.hypot(*np.diff(P[:, :2], axis=0).T), 1e-6)
        dtail = solver_options.get("distance_tail")
        kw = {} if dtail is None else dict(share=dtail[0], scale=dtail[1])
        e = _mixture(rng, (steps,), float(h.sigma_distance_ratio or 0.0), **kw)
        e[0] = 0.0 if scale_error is None else _mixture(
            rng, (), scale_error[0], share=scale_error[1][0], scale=scale_error[1][1])
        out["distances"] = s * np.exp(noise * np.cumsum(e))
    return dataclasses.replace(h, **out)


def select(prep, limit: int = 0) -> list:
    """The ascending ordering of each history with motion, covered by the capture throughout."""
    out, seen = [], set()
    for r, h in prep.histories:
        t = h.truth
        if (list(h.landmarks) != sorted(h.landmarks) or not h.has_motion or h.n_views < 2
                or t.poses_world is None or h.distances is None
                or (h.groundtruth_valid is not None and not np.all(h.groundtruth_valid))):
            continue
        key = (r, tuple(h.landmarks), float(h.views[0]))
        if key in seen:
            continue
        seen.add(key)
        out.append((r, h))
    return out[:limit] if limit else out


#: The odometry's log step-length error (core sigma, (share, scale) of the wider normal) for
#: ``--travel``: dataset 6 against motion capture (module docstring).
TRAVEL_ERROR = (0.07, (0.1, 5.0))

#: The camera's detection range for ``--detection`` (near, far, near_width, far_width; m): a
#: logistic edge at each end fitted to dataset 6's measured ranges (every robot) divided by the
#: ranges of two points uniform in its arena box, in 0.1-m bins (weighted least squares; the
#: least measured range is 0.94 m). The ratio also carries the landmarks' layout, not only the
#: camera.
DETECTION = (1.18, 6.27, 0.07, 0.40)


def solve(prep, hs, seed, method="full", travel=None, detection=None, trajectory=False,
          mixture=False, **options) -> np.ndarray:
    """(T, m) the solver's state distributions, in chunks, seeded per chunk (``options`` on top
    of the run's); ``travel`` (T,) first step lengths (m): each history under its own
    :class:`TravelPrior`, one by one."""
    opts = dict({k: v for k, v in prep.solver_options.items() if v}, **options)
    out = []
    if travel is not None:
        for i, (h, d) in enumerate(zip(hs, travel, strict=True)):
            ss = np.random.SeedSequence(int(seed), spawn_key=(i // CHUNK, i % CHUNK))
            pr = TravelPrior(prep.prior, float(d), sigma=TRAVEL_ERROR[0],
                             tail=TRAVEL_ERROR[1], detection=detection)
            if trajectory:
                pr = TrajectoryPrior(pr, n_first=2)
            out.append(solve_triplet(h, method=method, partition=prep.partition, seed=ss,
                                     prior=pr, **opts).landmark)
        return np.array(out)
    for i in range(0, len(hs), CHUNK):
        ss = np.random.SeedSequence(int(seed), spawn_key=(i // CHUNK,))
        est = solve_triplets(hs[i:i + CHUNK], method=method, partition=prep.partition, seed=ss,
                             prior=batch_prior(prep.prior, trajectory, mixture), **opts)
        out.extend(e.landmark for e in est)
    return np.array(out)


def batch_prior(box, trajectory: bool = False, mixture: bool = False):
    """The prior of a batched solve: the run's box, one robot's path over it
    (``--trajectory``), or the equal mixture of the two (``--mixture``)."""
    if mixture:
        return MixturePrior([box, TrajectoryPrior(box)])
    return TrajectoryPrior(box) if trajectory else box


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dataset", type=int, default=6)
    ap.add_argument("--robots", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--reference", default="capture", choices=("capture", "joint"),
                    help="the geometry the twin is made from and scored against: motion capture "
                         "(dataset 6) or the joint map of every robot's views "
                         "(qfg.datasets.mrclam.joint_map.mrclam_reference, aligned onto the "
                         "landmarks' ground truth; "
                         "datasets 1-5)")
    ap.add_argument("--views", type=int, nargs="+", default=[3, 5])
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    ap.add_argument("--limit", type=int, default=0, help="histories per k (0: all)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--solver-seed", type=int, default=None,
                    help="the solver's seed (default --seed): another solver seed on the same "
                         "twin measurements, with --against, shows the answers' seed-to-seed "
                         "spread")
    ap.add_argument("--method", default="full", choices=("full", "fast", "reference"))
    ap.add_argument("--prior", default="arena", choices=study.PRIORS,
                    help="the solvers' prior (qfg mrclam --prior; default arena)")
    ap.add_argument("--model", default="measured", type=model_parts,
                    help="measured (default): the measured bearing tail, heading walk and "
                         "ratio tail (the reference takes none of them); simple: normal "
                         "bearings and headings, one sigma each, and a normal ratio; or a "
                         "comma-separated subset of " + ", ".join(MODEL_PARTS))
    ap.add_argument("--camera-prior", default="point", choices=("point", "joint"),
                    help="the solvers' camera_prior option")
    ap.add_argument("--budget", type=float, default=1.0,
                    help="full only: n_samples, max_hypotheses and posterior_samples this many "
                         "times their defaults (1: the defaults, with the few-views budget)")
    ap.add_argument("--populations", type=int, default=1,
                    help="full/fast: the solvers' independent SIS populations (1: the default)")
    ap.add_argument("--no-distances", action="store_true",
                    help="solve without the odometry's distances")
    ap.add_argument("--travel", action="store_true",
                    help="each history under the arena box joined with its first step's "
                         "length in metres (qfg.priors.TravelPrior; module docstring)")
    ap.add_argument("--trajectory", action="store_true",
                    help="the cameras after the box's first (after --travel's first two) reached "
                         "by scale-free steps (qfg.priors.TrajectoryPrior) instead of each "
                         "uniform in the box")
    ap.add_argument("--mixture", action="store_true",
                    help="the equal mixture of the box and --trajectory's path over it "
                         "(qfg.priors.MixturePrior): each history's answer averages the two by "
                         "their evidence")
    ap.add_argument("--detection", action="store_true",
                    help="with --travel: the prior also weighs every camera-landmark range by "
                         "the camera's detection range (DETECTION, fitted on dataset 6)")
    ap.add_argument("--geometry", action="store_true",
                    help="also print where the histories' true AB-frame geometry falls under the "
                         "solvers' prior (percentiles of the first step, the first-to-last "
                         "baseline, the first camera's and C's distance from A, in |AB|)")
    ap.add_argument("--csv", type=Path, default=None)
    ap.add_argument("--detail", action="store_true",
                    help="also print each history whose answer puts the truth under 1%%: its "
                         "p(truth), top state's probability, the truth state's prior mass and "
                         "how far the camera moved from first view to last (m)")
    ap.add_argument("--against", type=Path, default=None,
                    help="another run's --csv: print this run minus that one, paired")
    ap.add_argument("--from-csv", type=Path, default=None,
                    help="report a recorded run's --csv instead of solving")
    a = ap.parse_args(argv)
    if a.mixture and a.prior == "arena-logscale":
        ap.error("--mixture: over the arena box (the log-scale box is not normalized, so a "
                 "mixture would weigh it arbitrarily)")
    if a.mixture and a.travel:
        ap.error("--mixture: not with --travel")
    if a.detection and not a.travel:
        ap.error("--detection: only with --travel (the ranges need the step's metres)")
    if a.budget != 1.0 and a.method != "full":
        ap.error("--budget: only with --method full")
    try:
        extra = scaled_budget("full", a.budget) if a.method == "full" else {}
    except ValueError as e:
        ap.error(f"--{e}")
    if a.method != "reference":
        extra["camera_prior"] = a.camera_prior
    if a.populations != 1:
        if a.method not in ("full", "fast") or a.populations < 1:
            ap.error("--populations: a whole number >= 1, with --method full or fast")
        extra["populations"] = a.populations
    other = read_rows(a.against) if a.against is not None else None
    if a.from_csv is not None:
        rows = read_rows(a.from_csv)
        report(rows, sorted({r["views"] for r in rows}))
        if other is not None:
            report_against(rows, other, a.against)
        return
    path, ds = reference_dataset(a.dataset, a.reference)
    rows = []
    for k in a.views:
        model = {k: v for k, v in MODEL_PARTS.items() if k in a.model}
        prep = study.prepare_run(path, study.MrclamParams(robots=a.robots or (), spread_views=k,
                                                          prior=a.prior, **model), dataset=ds)
        if a.no_distances:
            prep.solver_options.pop("distance_tail", None)
        sel = select(prep, a.limit)
        if a.geometry:
            report_geometry(prep, sel, k)
        for v in a.variants:
            rng = np.random.default_rng(np.random.SeedSequence(a.seed, spawn_key=(k, 7)))
            hs = [h if v == "real" else twin(h, rng, prep.solver_options,
                                             bearings=v in ("twin", "twin-bearings", "clean"),
                                             odometry=v in ("twin", "twin-odometry", "clean"),
                                             noise=0.0 if v == "clean" else 1.0,
                                             scale_error=TRAVEL_ERROR if a.travel else None)
                  for _, h in sel]
            t0 = time.time()
            travel = [h.distances[0] for h in hs] if a.travel else None
            if a.no_distances:
                hs = [dataclasses.replace(h, distances=None) for h in hs]
            P = solve(prep, hs, a.seed if a.solver_seed is None else a.solver_seed,
                      a.method, travel=travel,
                      detection=DETECTION if a.detection else None,
                      trajectory=a.trajectory, mixture=a.mixture, **extra)
            g = np.array([h.truth.state for h in hs])
            ls, under = log_score(P, g), truth_under(P, g)
            print(f"k={k} {v}: {len(hs)} histories, log p(truth) {ls.mean():.3f}, "
                  f"under 1% {under.mean():.3f} ({time.time() - t0:.0f} s)", flush=True)
            for (r, h), p, u in zip(sel, P, under, strict=True) if a.detail else ():
                if u:
                    xy = np.asarray(h.truth.poses_world)[:, :2]
                    print(f"  robot {r} {'-'.join(map(str, h.landmarks))} t={h.views[0]:.1f}: "
                          f"p(truth) {p[h.truth.state]:.5f}, top {p.max():.2f}, prior mass "
                          f"{prep.prior_states[h.truth.state]:.3f}, moved "
                          f"{np.hypot(*(xy[-1] - xy[0])):.2f} m")
            for (r, h), s, u, es, eu in zip(sel, ls, under, expected_log_score(P),
                                            expected_truth_under(P), strict=True):
                rows.append(dict(variant=v, views=k, robot=r, landmarks="-".join(map(str, h.landmarks)),
                                 start=float(h.views[0]), end=float(h.views[-1]),
                                 log_score=float(s), under=bool(u),
                                 expected_log_score=float(es), expected_under=float(eu)))
    if a.csv:
        write_rows(a.csv, rows)
    report(rows, a.views)
    if a.against is not None:
        report_against(rows, other, a.against)


GEOMETRY = ("first step", "first to last view", "first camera from A", "C from A")


def _geometry(q) -> np.ndarray:
    """(..., 4) lengths in |AB| of AB-frame configurations q (..., 1 + n, 2) = [C, X_1..X_n]."""
    C, X = q[..., 0, :], q[..., 1:, :]
    return np.stack([np.linalg.norm(X[..., 1, :] - X[..., 0, :], axis=-1),
                     np.linalg.norm(X[..., -1, :] - X[..., 0, :], axis=-1),
                     np.linalg.norm(X[..., 0, :], axis=-1), np.linalg.norm(C, axis=-1)], -1)


def report_geometry(prep, sel, k, draws: int = 200_000) -> None:
    """Where the histories' true geometry falls under the solvers' prior: per length of
    :data:`GEOMETRY`, the median over histories and over the prior's draws, and the histories'
    percentiles under the prior (median, 10th-90th)."""
    # a pass may have fewer than k views: each history's own lengths
    F = np.array([_geometry(np.concatenate([np.asarray(h.truth.C_ab)[None],
                                            np.asarray(h.truth.poses_ab)[:, :2]]))
                  for _, h in sel])
    G = np.sort(_geometry(np.asarray(prep.prior.sample(0, k, draws))), axis=0)
    print(f"\nk={k}: the true geometry of {len(sel)} histories under the prior ({draws} draws)")
    print("| length (|AB|) | histories' median | prior's median | histories' percentile "
          "under the prior: median (10th-90th) |")
    print("|---|---|---|---|")
    for j, name in enumerate(GEOMETRY):
        pct = 100.0 * np.searchsorted(G[:, j], F[:, j]) / draws
        print(f"| {name} | {np.median(F[:, j]):.3g} | {np.median(G[:, j]):.3g} | "
              f"{np.median(pct):.0f} ({np.percentile(pct, 10):.0f}-{np.percentile(pct, 90):.0f}) |")


def reference_dataset(number: int, reference: str = "capture"):
    """(path, dataset): MRCLAM dataset ``number`` as ``qfg mrclam`` prepares it, its ground
    truth the motion capture (``"capture"``) or the joint map of every robot's views aligned
    onto the landmarks' ground truth (``"joint"``; module docstring)."""
    path = mrclam.data_root() / f"MRCLAM_Dataset{number}"
    ds = study.prepare(path)[0]
    if reference == "joint":
        meas = mrclam_runs(ds, min_move=0.0, min_turn_deg=0.0)
        ds = mrclam_reference(ds, joint.solve(meas, seed=0), meas, align=True)
    return path, ds


def write_rows(path: Path, rows: list[dict]) -> None:
    """A run's rows as the csv ``--from-csv`` reads (the first row's keys are the columns)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def read_rows(path: Path) -> list[dict]:
    """Rows of a run's --csv, typed as the run made them."""
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise SystemExit(f"{path}: no rows")
    # runs recorded before the self-expected columns have none: reported as "-"
    return [dict(r, views=int(r["views"]), robot=int(r["robot"]), start=float(r["start"]),
                 end=float(r["end"]), log_score=float(r["log_score"]),
                 under=r["under"] == "True",
                 expected_log_score=float(r.get("expected_log_score") or "nan"),
                 expected_under=float(r.get("expected_under") or "nan")) for r in rows]


def report_against(rows, other, name) -> None:
    """This run minus ``other`` (rows of another run's csv), paired by variant, views, robot,
    landmark set and pass."""
    def key(r):
        return r["variant"], r["views"], r["robot"], r["landmarks"], round(r["start"], 6)
    theirs = {key(r): r["log_score"] for r in other}
    print(f"\n| variant | views | n | this run minus {name}, paired (SE clustered by landmark "
          "set) | root mean square difference | median absolute difference |")
    print("|---|---|---|---|---|---|")
    for v, k in dict.fromkeys((r["variant"], r["views"]) for r in rows):
        pairs = [(r["log_score"] - theirs[key(r)], r["landmarks"]) for r in rows
                 if r["variant"] == v and r["views"] == k and key(r) in theirs]
        if pairs:
            d = np.array([p[0] for p in pairs])
            print(f"| {v} | {k} | {len(d)} | {d.mean():+.3f} ± "
                  f"{clustered_se(d, [p[1] for p in pairs]):.3f} | "
                  f"{np.sqrt(np.mean(d * d)):.3f} | {np.median(np.abs(d)):.3f} |")


def report(rows, views) -> None:
    """Paired differences against the smallest k, per variant, matched by robot, landmark set
    and pass (the pass's first view time at the smallest k)."""
    k0 = min(views)
    print("\n| variant | views | n | log p(truth) | truth under 1% | paired vs "
          f"{k0} views (SE clustered by landmark set) | self-expected log p / under 1% | "
          "log p minus self-expected (SE clustered) |")
    print("|---|---|---|---|---|---|---|---|")
    for v in dict.fromkeys(r["variant"] for r in rows):
        base = {(r["robot"], r["landmarks"], r["start"]): r["log_score"] for r in rows
                if r["variant"] == v and r["views"] == k0}
        for k in views:
            sub = [r for r in rows if r["variant"] == v and r["views"] == k]
            if not sub:
                continue
            ls = np.array([r["log_score"] for r in sub])
            pairs = [(r["log_score"] - base[key], r["landmarks"]) for r in sub
                     if (key := (r["robot"], r["landmarks"], r["start"])) in base]
            diff = ""
            if k != k0 and pairs:
                d = np.array([p[0] for p in pairs])
                diff = (f"{d.mean():+.3f} ± {clustered_se(d, [p[1] for p in pairs]):.3f} "
                        f"({len(d)})")
            es = np.array([r["expected_log_score"] for r in sub])
            selfx = gap = "-"
            if np.all(np.isfinite(es)):
                selfx = f"{es.mean():.3f} / {np.mean([r['expected_under'] for r in sub]):.3f}"
                gap = (f"{(ls - es).mean():+.3f} ± "
                       f"{clustered_se(ls - es, [r['landmarks'] for r in sub]):.3f}")
            print(f"| {v} | {k} | {len(sub)} | {ls.mean():.3f} | "
                  f"{np.mean([r['under'] for r in sub]):.3f} | {diff} | {selfx} | {gap} |")


if __name__ == "__main__":
    main()
