"""The motion step's proposal shares with odometry distances (``_sis._MIX_SHARES``: the ray
along the heading, the circle of the distance ratio, the odometry alone), paired on the same
simulated histories and solver seeds: mean log p(truth) (clip 1e-4), truth under 1%, flagged
share, time, and each set of shares minus the first, paired.

    python -m benchmarks.sis_mix_shares VIEWS N SIGMA_D METHOD SEED SHARES [SHARES ...]
    python -m benchmarks.sis_mix_shares 5 150 0.074 full 778 '[0.5,0.5,0]' '[0.375,0.25,0.375]'

Histories: :func:`qfg.simulation.random_triplet_history` at 2/5 deg with log-ratio noise
``SIGMA_D``, drawn from ``SeedSequence(SEED)``; the solver seed is 5 for every set of shares."""

import json
import sys
import time

import numpy as np

from qfg.simulation import random_triplet_history
from qfg.solvers import _sis, solve_triplets


def run(views, n, sigma_d, method, seed, shares):
    ss = np.random.SeedSequence(seed)
    hs = [random_triplet_history(np.random.default_rng(c), views, np.deg2rad(2.0),
                                 np.deg2rad(5.0), sigma_distance_ratio=sigma_d)
          for c in ss.spawn(n)]
    g = np.array([h.truth.state for h in hs])
    out, before = {}, _sis._MIX_SHARES
    try:
        for sh in shares:
            _sis._MIX_SHARES = sh
            t = time.perf_counter()
            est = solve_triplets(hs, method=method, seed=5)
            sec = time.perf_counter() - t
            p = np.array([e.landmark[s] for e, s in zip(est, g, strict=True)])
            out[sh] = np.log(np.clip(p, 1e-4, 1.0))
            print(f"{sh}: log p(truth) {out[sh].mean():.3f}, truth under 1% "
                  f"{np.mean(p < 0.01):.3f}, flagged {np.mean([e.degenerate for e in est]):.3f}, "
                  f"{sec:.0f} s", flush=True)
    finally:
        _sis._MIX_SHARES = before
    base = out[shares[0]]
    for sh in shares[1:]:
        d = out[sh] - base
        print(f"{views} views, {method}: {sh} minus {shares[0]}: {d.mean():+.3f} +- "
              f"{d.std(ddof=1) / np.sqrt(n):.3f}")


def main(argv=None):
    a = sys.argv[1:] if argv is None else argv
    if len(a) < 6:
        raise SystemExit(__doc__)
    run(int(a[0]), int(a[1]), float(a[2]), a[3], int(a[4]),
        [tuple(float(x) for x in json.loads(s)) for s in a[5:]])


if __name__ == "__main__":
    main()
