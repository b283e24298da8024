"""Composition tensors: build time and online composition throughput.

* Build time of each shipped tensor at its shipped sample count: *not re-run here* (EDC takes tens
  of minutes); the value is the wall time the build command measured and recorded in the file
  (``meta.build_seconds``, from ``qfg tensors build --partition NAME --workers W``), with the
  worker count. A short build (EDC, 64 samples per state, 1 worker) is timed here to give the
  per-sample cost on this machine now.
* Batched marginal composition throughput for EDC (aim: >= 1e5 factor marginals per second):
  ``qfg.composition.marginal`` on 10^5 random (V1, V2) pairs, median of 5 runs; also the joint
  and the deterministic version.
"""

import time

import numpy as np

from benchmarks import median_time
from qfg import composition
from qfg.composition import build as qb


def _median_time(fn, repeats=5):
    return median_time(fn, repeats)


def run():
    rows = []
    for name in ("edc", "tpcc", "fdc", "lr"):
        t = composition.tensor(name)
        rows.append({"name": f"{name} tensor build (shipped, {t.samples_per_state} samples/state)",
                     "value": float(t.meta["build_seconds"]), "unit": "s",
                     "note": f"recorded by `qfg tensors build --partition {name} --workers "
                             f"{t.meta['workers']}` when the shipped file was made (not re-run); "
                             f"{t.nnz} non-zero entries"})
    t0 = time.perf_counter()
    small = qb.build("edc", 64, seed=0, support_samples=16, progress=False)
    dt = time.perf_counter() - t0
    n_c = 10 * (64 + 16)  # mirror symmetry: 10 of the 20 states are sampled
    rows.append({"name": "edc tensor build, 64 + 16 samples/state, 1 worker", "value": dt,
                 "unit": "s", "note": f"{dt / n_c * 1e3:.2f} ms per C sample (all m^2 "
                                     f"intersections); nnz {small.nnz}"})

    T = composition.tensor("edc")
    F = 100_000
    rng = np.random.default_rng(0)
    V1, V2 = rng.dirichlet(np.ones(20), F), rng.dirichlet(np.ones(20), F)
    tm = _median_time(lambda: composition.marginal(T, V1, V2, role=3))
    rows.append({"name": "edc marginal composition, batch of 1e5 factors", "value": F / tm,
                 "unit": "marginals/s", "target": ">= 1e5",
                 "note": f"{tm * 1e3:.0f} ms per call (role 3; roles 1, 2 cost the same)"})
    tm1 = _median_time(lambda: composition.marginal(T, V1[:1], V2[:1], role=3), repeats=200)
    rows.append({"name": "edc marginal composition, single factor", "value": 1 / tm1,
                 "unit": "calls/s", "note": f"{tm1 * 1e6:.0f} us per call (argument checks "
                                            f"dominate)"})
    Fj = 10_000
    tj = _median_time(lambda: composition.joint(T, V1[:Fj], V2[:Fj], V1[:Fj]))
    rows.append({"name": "edc joint composition, batch of 1e4 factors", "value": Fj / tj,
                 "unit": "joints/s", "note": f"{tj * 1e3:.0f} ms per call (20^3 entries each)"})
    S1, S2 = V1 > 0.05, V2 > 0.05
    td = _median_time(lambda: composition.feasible(T, S1, S2, role=3))
    rows.append({"name": "edc deterministic composition (feasible sets), batch of 1e5",
                 "value": F / td, "unit": "factors/s", "note": f"{td * 1e3:.0f} ms per call"})
    return rows
