"""Degenerate geometry, noiseless: how often each method is confidently wrong (p_max > 0.9 on a
wrong state) and how often it flags the answer, over ``n`` random configurations per kind:

* ``one-pose``: every view from the same pose;
* ``on-a``: the first camera stands on landmark A (its bearing to A is then that of the
  direction (1, 0), ``atan2(0, 0) = 0``), the others elsewhere;
* ``toward-c`` / ``away-c``: the camera travels straight toward (away from) C.

``python experiments/solvers/solver_degenerate.py [--n 25] [--methods fast-paper,baseline]``

Backs docs/solvers.md, "Degenerate geometry and bad input", and docs/results/composition.md.
Run from the repository root as above.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from qfg import geometry, partitions
from qfg.solvers import solve_triplet

EDC = partitions.get("edc")
KINDS = ("one-pose", "on-a", "toward-c", "away-c")


def measure(C, poses):
    """Noiseless AB-frame bearings (n, 3) and headings (n - 1,) of cameras ``poses`` (n, 3)."""
    P = np.array([[0.0, 0.0], [0.0, 1.0], C])
    b = geometry.bearing(poses[:, None, :], P[None, :, :])
    psi = geometry.motion_heading(poses[:-1], poses[1:, :2])
    return b, psi


def configuration(kind, rng, n_views=3):
    """(C (2,), poses (n, 3)) of one configuration of ``kind``."""
    while True:
        C = rng.uniform(-2, 2, 2)
        if min(np.linalg.norm(C), np.linalg.norm(C - [0, 1])) < 0.3:
            continue
        alpha = rng.uniform(-np.pi, np.pi, n_views)
        if kind == "one-pose":
            X = rng.uniform(-3, 3, 2)
            if min(np.linalg.norm(X), np.linalg.norm(X - [0, 1]), np.linalg.norm(X - C)) < 0.3:
                continue
            return C, np.tile(np.append(X, alpha[0]), (n_views, 1))
        if kind == "on-a":
            X = np.vstack([[0.0, 0.0], rng.uniform(-3, 3, (n_views - 1, 2))])
            if np.min(np.linalg.norm(X[1:] - C, axis=1)) < 0.3:
                continue
            return C, np.column_stack([X, alpha])
        X1 = rng.uniform(-3, 3, 2)
        d = np.linalg.norm(C - X1)
        if d < 0.5:
            continue
        u = (C - X1) / d
        pts = X1 + (np.linspace(0.0, 0.5, n_views) * d)[:, None] * u
        if kind == "away-c":
            pts = pts[::-1]
        return C, np.column_stack([pts, alpha])


def run(kinds, methods, n, n_views=3, seed=0):
    rows = []
    for kind in kinds:
        rng = np.random.default_rng([seed, KINDS.index(kind)])
        cfgs = [configuration(kind, rng, n_views) for _ in range(n)]
        for method in methods:
            wrong = flagged = 0
            lp = []
            t0 = time.perf_counter()
            for k, (C, poses) in enumerate(cfgs):
                b, psi = measure(C, poses)
                truth = int(EDC.state_of(C[None])[0])
                e = solve_triplet(b, psi, method=method, sigma_bearing=0.0, sigma_heading=0.0,
                                  seed=k)
                s, p = e.most_likely
                wrong += int(s != truth and p > 0.9)
                flagged += int(e.degenerate)
                lp.append(np.log(max(e.landmark[truth], 1e-4)))
            rows.append((kind, method, n, wrong, flagged, float(np.mean(lp)),
                         (time.perf_counter() - t0) / n))
    return rows


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=25)
    ap.add_argument("--views", type=int, default=3)
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--methods", default="full,fast,fast-paper,baseline")
    a = ap.parse_args()
    print("kind, method, configurations, confidently wrong, flagged, mean log p(truth), s each")
    for r in run(a.kinds.split(","), a.methods.split(","), a.n, a.views):
        print(f"{r[0]:9s} {r[1]:10s} {r[2]:3d} wrong {r[3]:3d} flagged {r[4]:3d} "
              f"logp {r[5]:6.2f} {r[6]:.3f}s", flush=True)
