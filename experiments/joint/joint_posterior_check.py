"""How close the joint method's samples are to the exact posterior, on small simulated runs with
few views (where the posterior is not Gaussian): total variation between the triplet state
distributions of (a) one Laplace approximation (``sir_rays=0``), (b) the default (weak landmarks
resampled from their exact conditional, 32 / 64 / 256 proposals) and a long random-walk
Metropolis run on the exact robust posterior (``qfg.joint.reference_samples``); ``ref-vs-ref``
is two independent reference runs (their Monte Carlo error).

    python experiments/joint/joint_posterior_check.py --seeds 5 6 7 8

Backs docs/joint.md, "Development choices and what they are measured on". Run from the
repository root as above (simulated data only).
"""

from __future__ import annotations

import argparse
import itertools
import time

import numpy as np

from qfg import joint
from qfg.joint import states as joint_states
from qfg.partitions import get as get_partition
from qfg.simulation import random_trajectory_run


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", nargs="*", type=int, default=[5, 6, 7, 8])
    ap.add_argument("--landmarks", type=int, default=5)
    ap.add_argument("--poses", type=int, default=8)
    ap.add_argument("--chains", type=int, default=400)
    ap.add_argument("--steps", type=int, default=2000)
    a = ap.parse_args(argv)
    edc = get_partition("edc")

    def tv(p, q):
        return float(0.5 * np.abs(p - q).sum(1).mean())

    print("| seed | landmarks solved | ref-vs-ref | Laplace | SIR 32 | SIR 64 (default) | SIR 256 | "
          "reference time (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for seed in a.seeds:
        run = random_trajectory_run(np.random.default_rng(seed), n_landmarks=a.landmarks,
                                    n_poses=a.poses, fov_deg=360)
        meas = joint.simulated_measurements(run)
        pg = joint.solve(meas, joint.SolveParams(sir_rays=0))
        ps = joint.solve(meas)
        ok = pg.constrained
        tri = np.array([t for t in itertools.permutations(range(len(ok)), 3) if ok[list(t)].all()])

        def st(S, tri=tri):
            return joint_states.state_counts(S, tri, edc) / len(S)

        t0 = time.perf_counter()
        R = st(joint.reference_samples(pg, a.chains, steps=a.steps, seed=10))
        tr = time.perf_counter() - t0
        R2 = st(joint.reference_samples(pg, a.chains, steps=a.steps, seed=11))
        cells = [tv(R2, R), tv(st(joint.sample_landmarks(pg, a.chains, seed=2)), R)]
        cells += [tv(st(joint.sample_landmarks(ps, a.chains, seed=2, proposals=k)), R)
                  for k in (32, 64, 256)]
        print(f"| {seed} | {int(ok.sum())} of {a.landmarks} | "
              + " | ".join(f"{c:.3f}" for c in cells) + f" | {tr:.0f} |", flush=True)


if __name__ == "__main__":
    main()
