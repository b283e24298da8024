"""Where the full solver's time goes: process (thread) time per stage of the SIS engine on the
benchmark's batch (``bench_solvers``' histories: 50 three-view triplets at 2/5 deg), best of 3
calls, per view ("@2", "@3": the extension to that view; "@fin": the final weights).

    python -m benchmarks.sis_stages [--triplets 50] [--method full] [--set JSON]
    python -m benchmarks.sis_stages --primitives

``--primitives``: nanoseconds per element of the elementwise numpy functions the engine uses, on
16384-element float64 arrays (its block size), best of 5 rounds of 100 calls.

Each stage is the engine function of that name (nested calls count in both, e.g.
``update_landmark`` inside ``_child_c``); thread time leaves out other processes' load, not the
wrappers' small overhead. A diagnostic for speed work, not a recorded benchmark.
"""

from __future__ import annotations

import argparse
import time

from benchmarks.bench_solvers import _histories

_SIS_STAGES = ("_children", "_child_c", "_log_intermediate_c", "_per_triplet", "_resampling",
               "_gather", "trajectories", "_c_weight", "_final_proposal")


def stages(n=50, method="full", options=None):
    """(total seconds, {stage@view: seconds}) of the fastest of 3 calls."""
    from qfg.solvers import _landmarks, _laplace, _model_check, _prior, _sis, solve_triplets

    acc, cur, saved = {}, {"v": "start"}, []

    def timed(mod, name, key=None):
        f = getattr(mod, name)

        def g(*a, **k):
            if key is not None:
                cur["v"] = key(a)
            t = time.thread_time()
            try:
                return f(*a, **k)
            finally:
                kk = f"{name}@{cur['v']}"
                acc[kk] = acc.get(kk, 0.0) + time.thread_time() - t

        saved.append((mod, name, f))
        setattr(mod, name, g)

    timed(_sis, "_extend", key=lambda a: a[0].n_views + 1)
    timed(_sis, "finish", key=lambda a: "fin")
    for name in _SIS_STAGES:
        timed(_sis, name)
    for mod, name in ((_laplace, "laplace_landmark"), (_laplace, "update_landmark"),
                      (_landmarks, "sample_landmarks"), (_prior, "log_joint_prior"),
                      (_model_check, "posterior_predictive_p")):
        timed(mod, name)
    try:
        hs = _histories(n)
        options = options or {}
        solve_triplets(hs[:5], method=method, seed=0, **options)
        best = None
        for r in range(3):
            acc.clear()
            t = time.thread_time()
            solve_triplets(hs, method=method, seed=r + 1, **options)
            tot = time.thread_time() - t
            if best is None or tot < best[0]:
                best = (tot, dict(acc))
    finally:
        for mod, name, f in saved:
            setattr(mod, name, f)
    return best


def primitives(n=16384, rounds=5, calls=100):
    """{name: ns per element} of numpy's elementwise functions on ``n`` float64 values."""
    import numpy as np

    rng = np.random.default_rng(0)
    a, b = rng.normal(0.0, 4.0, n), rng.normal(0.0, 1.0, n)
    p = np.abs(a) + 0.1
    funcs = {"sin": lambda: np.sin(a), "cos": lambda: np.cos(a), "tan": lambda: np.tan(a),
             "arctan2": lambda: np.arctan2(a, b), "hypot": lambda: np.hypot(a, b),
             "mod": lambda: np.mod(a, 2 * np.pi), "logaddexp": lambda: np.logaddexp(a, b),
             "log": lambda: np.log(p), "exp": lambda: np.exp(b), "sqrt": lambda: np.sqrt(p),
             "multiply": lambda: a * b, "where": lambda: np.where(a > 0, a, b)}
    out = {}
    for name, f in funcs.items():
        best = np.inf
        for _ in range(rounds):
            t = time.thread_time()
            for _ in range(calls):
                f()
            best = min(best, time.thread_time() - t)
        out[name] = 1e9 * best / calls / n
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triplets", type=int, default=50)
    ap.add_argument("--method", default="full")
    ap.add_argument("--primitives", action="store_true")
    ap.add_argument("--set", default="{}", help="JSON options of the solver")
    a = ap.parse_args(argv)
    if a.primitives:
        for k, v in primitives().items():
            print(f"  {k:10s} {v:6.2f} ns per element")
        return
    import json

    tot, acc = stages(a.triplets, a.method, json.loads(a.set))
    print(f"{a.method}: {1e3 * tot / a.triplets:.2f} ms per triplet (thread time, best of 3)")
    for k, v in sorted(acc.items(), key=lambda kv: (str(kv[0].split("@")[-1]), -kv[1])):
        print(f"  {k:32s} {1e3 * v / a.triplets:6.2f} ms/triplet {100 * v / tot:5.1f}%")


if __name__ == "__main__":
    main()
