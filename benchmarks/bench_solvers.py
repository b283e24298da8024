"""Single-triplet solvers: time per 3-view triplet at the headline noise (sigma_v = 2 deg,
sigma_w = 5 deg), default options, measured side by side in one run. Batched: one
``solve_triplets`` call on T triplets, time / T, median of repeats (full and fast: T = 50, 3
repeats; fast-paper: T = 200, 5 repeats). Single calls: median over triplets (baseline 20,
reference 5). The paper's MATLAB took 0.05 s (fast), 18 s (full) and 26 s (baseline).

Views scaling, every method side by side in one run: the same geometries (10 per n, drawn like
the rows above with 20 views; the first n views of each) solved at n = 3, 10 and 20 views, full
and fast batched (one call on the 10), baseline and reference single calls (median). Each time is
also given in units of a fixed single-threaded numpy workload (``_workload``: sines and a sort;
the mean of its best-of-5 time just before and just after), so that rows measured at different
loads compare; "growth" is that normalised time at n over the one at 3 views, "raw" the same
ratio of plain times (linear in views: 3.3 at 10, 6.7 at 20). Since qfg 0.3.0 full solves up
to 3 views with its few-views package (two populations of a smaller budget, escalated where they
disagree: about half the whole budget's time) and 4 or more with the whole budget, so its growth
from 3 views is about twice the whole budget's own (docs/solvers.md).

``python -m benchmarks.bench_solvers --against DIR [--method full]`` times a solver against an
older tree's ``qfg`` package in DIR (``git archive <commit> qfg | tar -x -C DIR``), interleaved in
one process: the ratio survives the shared machine's load (also as process time, and in units of
the fixed workload); ``--set JSON`` gives the working tree other options (the older tree's
defaults otherwise), ``--both JSON`` options to both trees, ``--views N`` other numbers of
views than 3.

``python -m benchmarks.bench_solvers --logsumexp`` times the solvers' own ``logsumexp`` against
``scipy.special.logsumexp`` on the shapes the solvers use (why the solvers keep their own)."""

import os
import time

import numpy as np

from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplet, solve_triplets


def _histories(n, seed=2024, views=3):
    ss = np.random.SeedSequence(seed)
    return [random_triplet_history(np.random.default_rng(c), views, np.deg2rad(2.0),
                                   np.deg2rad(5.0)) for c in ss.spawn(n)]


def _batched(method, hs, repeats):
    """(median, min) seconds per triplet over ``repeats`` calls, and the fixed workload's
    seconds (the mean of its best-of-5 before and after the calls)."""
    solve_triplets(hs[:5], method=method, seed=0)          # warm-up
    per = []
    w0 = _workload()
    for r in range(repeats):
        t = time.perf_counter()
        solve_triplets(hs, method=method, seed=r)
        per.append((time.perf_counter() - t) / len(hs))
    return float(np.median(per)), float(min(per)), 0.5 * (w0 + _workload())


def _single(method, hs):
    solve_triplet(hs[0], method=method, seed=0)             # warm-up
    ts = []
    for k, h in enumerate(hs):
        t = time.perf_counter()
        solve_triplet(h, method=method, seed=k)
        ts.append(time.perf_counter() - t)
    return float(np.median(ts)), float(np.percentile(ts, 90))


def _workload(repeats=5):
    """Seconds of a fixed numpy computation (best of ``repeats``): the machine's speed now."""
    # single-threaded element-wise work and a sort, like the solvers' (a BLAS product would
    # take the second core when it is free and measure the other processes' load instead)
    a = np.linspace(0.0, 50.0, 400_000)
    b = np.random.default_rng(0).standard_normal(200_000)
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        np.sin(a).sum()
        np.cos(a + 1.0).sum()
        np.sort(b)
        best = min(best, time.perf_counter() - t)
    return best


#: Views at which the scaling rows are measured, and geometries per n.
VIEWS = (3, 10, 20)
VIEW_TRIPLETS = 10


def views_scaling(views=VIEWS, n=VIEW_TRIPLETS, methods=("full", "fast", "baseline",
                                                           "reference"), seed=2025):
    """Rows: seconds per triplet of every method at every n of ``views``, side by side, with the
    fixed workload's seconds just before each and the growth over 3 views."""
    from dataclasses import replace

    ss = np.random.SeedSequence(seed)
    full = [random_triplet_history(np.random.default_rng(c), max(views), np.deg2rad(2.0),
                                   np.deg2rad(5.0)) for c in ss.spawn(n)]

    def first(h, k):
        return replace(h, bearings=h.bearings[:k], headings=h.headings[:k - 1],
                       views=h.views[:k], truth=None)

    rows, base, raw = [], {}, {}
    for k in views:
        hs = [first(h, k) for h in full]
        for method in methods:
            w0 = _workload()
            load = os.getloadavg()[0]
            if method in ("full", "fast"):
                solve_triplets(hs[:2], method=method, seed=0)
                t = time.perf_counter()
                solve_triplets(hs, method=method, seed=1)
                sec, how = (time.perf_counter() - t) / len(hs), f"batched ({len(hs)} per call)"
            else:
                ts = []
                for j, h in enumerate(hs):
                    t = time.perf_counter()
                    solve_triplet(h, method=method, seed=j)
                    ts.append(time.perf_counter() - t)
                sec, how = float(np.median(ts)), f"single calls, median of {len(hs)}"
            w = 0.5 * (w0 + _workload())
            units = sec / w
            base.setdefault(method, units)
            raw.setdefault(method, sec)
            rows.append({"name": f"{method}, {k} views", "value": 1e3 * sec, "unit": "ms/triplet",
                         "target": "", "note": f"{how}; {units:.3g} workloads (workload "
                         f"{1e3 * w:.1f} ms); growth over 3 views x{units / base[method]:.2f} (raw "
                         f"x{sec / raw[method]:.2f}); "
                         f"load {load:.1f}"})
    return rows


def run():
    rows = []
    hs = _histories(200)
    load = os.getloadavg()[0]
    for method, T, reps, target in (("full", 50, 3, "<= 10"), ("fast", 50, 3, "<= 2"),
                                    ("fast-paper", 200, 5, "")):
        med, best, w = _batched(method, hs[:T], reps)
        rows.append({"name": f"{method}, batched ({T} triplets per call)", "value": 1e3 * med,
                     "unit": "ms/triplet", "target": target,
                     "note": f"median of {reps} calls; min {1e3 * best:.2f} ms; "
                             f"{med / w:.3g} workloads (workload {1e3 * w:.1f} ms); "
                             f"load {load:.1f}"})
    for method, n in (("baseline", 20), ("reference", 5)):
        med, p90 = _single(method, hs[:n])
        rows.append({"name": f"{method}, single call", "value": 1e3 * med, "unit": "ms/triplet",
                     "target": "", "note": f"median of {n}, p90 {1e3 * p90:.0f} ms"})
    return rows + views_scaling()


def load_tree(src, name="qfg_before"):
    """The ``qfg`` package found in directory ``src`` (e.g. ``git archive <commit> qfg | tar -x
    -C src``), imported under ``name`` so that it runs next to the working tree's."""
    import importlib.util
    import sys
    from pathlib import Path

    init = Path(src) / "qfg" / "__init__.py"
    if not init.is_file():
        raise ValueError(f"--against: no qfg package in {src!r}")
    spec = importlib.util.spec_from_file_location(name, init,
                                                  submodule_search_locations=[str(init.parent)])
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def compare(src, method="full", T=50, repeats=5, seed=2024, extra=None, views=3, both=None):
    """Time per triplet of ``method`` in the working tree and in an older tree ``src`` (its
    ``qfg`` package), interleaved in one process on the same histories (the benchmark's), with
    the older tree's default options (options it lacks at the working tree's defaults), next to
    ``fast-paper`` as a yardstick of the machine's speed; ``extra``: options for the working
    tree only (e.g. an option the older tree lacks, at its neutral value); ``both``: options
    for both trees (e.g. ``camera_prior``). Returns a dict of
    medians (ms) and the largest difference of the landmark distributions between the trees."""
    import importlib

    old = load_tree(src)
    old_solvers = importlib.import_module(old.__name__ + ".solvers")
    old_sim = importlib.import_module(old.__name__ + ".simulation")
    old_opts = {**old_solvers.DEFAULTS[method], **(both or {})}
    from qfg.solvers import DEFAULTS

    new_opts = {**DEFAULTS[method], **old_opts, **(extra or {})}
    ss = np.random.SeedSequence(seed)
    kids = ss.spawn(T)
    h_new = _histories(T, seed, views)
    h_old = [old_sim.random_triplet_history(np.random.default_rng(c), views, np.deg2rad(2.0),
                                            np.deg2rad(5.0)) for c in kids]
    runs = {"before": lambda s: old_solvers.solve_triplets(h_old, method=method, seed=s,
                                                           **old_opts),
            "after": lambda s: solve_triplets(h_new, method=method, seed=s, **new_opts),
            "fast-paper": lambda s: solve_triplets(h_new, method="fast-paper", seed=s)}
    dp = float(np.max(np.abs(np.array([e.landmark for e in runs["before"](0)])
                             - np.array([e.landmark for e in runs["after"](0)]))))
    runs["fast-paper"](0)
    times = {k: [] for k in runs}
    cpu = {k: [] for k in runs}
    work = [_workload()]
    for r in range(repeats):
        for k, f in runs.items():
            t, c = time.perf_counter(), time.process_time()
            f(r + 1)
            times[k].append(1e3 * (time.perf_counter() - t) / T)
            cpu[k].append(1e3 * (time.process_time() - c) / T)
        work.append(_workload())
    out = {k: float(np.median(v)) for k, v in times.items()}
    out.update({f"{k} cpu": float(np.median(v)) for k, v in cpu.items()})
    out["workload"] = 1e3 * float(np.median(work))
    out["max_landmark_difference"] = dp
    return out


def logsumexp_shapes(repeats=5, number=20):
    """Milliseconds per call (best of ``repeats``) of the solvers' logsumexp and scipy's on the
    solvers' shapes: C's ray mixture over views (n, J, k) along axis 0, landmark samples (J, k)
    along axis 1, the reference solver's mixture (N, 3) along the last axis. Both must agree."""
    import timeit

    from scipy.special import logsumexp as scipy_lse

    from qfg.solvers.common.likelihood import logsumexp

    rng = np.random.default_rng(0)
    rows = []
    for shape, axis in [((3, 4096, 4), 0), ((10, 1638, 10), 0), ((3000, 4), 1), ((4096, 16), 1),
                        ((20000, 2), 1), ((200000, 3), -1)]:
        a = rng.standard_normal(shape) * 5
        a[rng.random(shape) < 0.1] = -np.inf
        np.testing.assert_allclose(logsumexp(a, axis=axis), scipy_lse(a, axis=axis))
        ours = min(timeit.repeat(lambda a=a, axis=axis: logsumexp(a, axis=axis), number=number,
                                 repeat=repeats)) / number * 1e3
        theirs = min(timeit.repeat(lambda a=a, axis=axis: scipy_lse(a, axis=axis),
                                   number=number,
                                   repeat=repeats)) / number * 1e3
        rows.append((shape, axis, ours, theirs))
    return rows


if __name__ == "__main__":
    import argparse
    import sys

    if "--logsumexp" in sys.argv:
        import scipy

        print(f"scipy {scipy.__version__}, load {os.getloadavg()[0]:.1f}")
        for shape, axis, ours, theirs in logsumexp_shapes():
            print(f"{str(shape):15s} axis {axis:2d}: qfg {ours:7.3f} ms, scipy {theirs:7.3f} ms "
                  f"(x{theirs / ours:.1f})")
        sys.exit(0)

    ap = argparse.ArgumentParser(description="compare a solver's speed with an older tree")
    ap.add_argument("--against", required=True, help="directory holding an older qfg package")
    ap.add_argument("--method", default="full")
    ap.add_argument("--triplets", type=int, default=50)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--set", default="{}", help="JSON options for the working tree only")
    ap.add_argument("--both", default="{}", help="JSON options for both trees")
    ap.add_argument("--views", type=int, default=3, help="views per triplet (default 3)")
    a = ap.parse_args()
    load = os.getloadavg()[0]
    import json

    r = compare(a.against, a.method, a.triplets, a.repeats, extra=json.loads(a.set),
                views=a.views, both=json.loads(a.both))
    print(f"{a.method}, {a.views} views, {a.triplets} triplets per call, median of {a.repeats} "
          f"(load {load:.1f} "
          f"-> {os.getloadavg()[0]:.1f}): before {r['before']:.2f} ms/triplet, after "
          f"{r['after']:.2f}, ratio {r['before'] / r['after']:.2f}; fast-paper "
          f"{r['fast-paper']:.2f} ms (after / fast-paper {r['after'] / r['fast-paper']:.1f}); "
          f"largest landmark difference {r['max_landmark_difference']:.1e}")
    w = r["workload"]
    print(f"process time: before {r['before cpu']:.2f} ms/triplet, after {r['after cpu']:.2f}, "
          f"ratio {r['before cpu'] / r['after cpu']:.2f}; workload {w:.1f} ms (median of "
          f"{a.repeats + 1}): before {r['before'] / w:.2f} workloads, after "
          f"{r['after'] / w:.2f}")
