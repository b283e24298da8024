"""The joint map's overdispersion on simulated robots (docs/joint.md, "Without odometry").

Three robots drive random trajectories (``qfg.simulation.random_trajectory_run``, 120 images,
360 deg field of view, 1 deg bearing noise) among the same 6 landmarks; each world is solved
by :func:`qfg.joint.solve` with the Laplace covariance as it is (``inflate_kinematic=1``), with
the simulated odometry (``odo``: the model is the simulator's, so the overdispersion should be
about 1) or without it (``noodo``: the kinematic prior ``SIM`` in its place, which does not
describe the simulator's motion). Printed per world: the robots kept, the overdispersion kappa
(:func:`qfg.joint.overdispersion`), and every ordered triplet's mean log p(truth) and share of
truths under 1 % with the covariance as it is and widened by max(1, kappa) (1000 samples).

    python experiments/joint/joint_overdispersion_sim.py odo 6
    python experiments/joint/joint_overdispersion_sim.py noodo 8

Run from the repository root as above (simulated data only).
"""

from __future__ import annotations

import argparse

import numpy as np

from qfg import joint
from qfg.geometry import to_frame
from qfg.joint.start import KinematicPrior
from qfg.metrics import log_score, truth_under
from qfg.partitions import get
from qfg.simulation import random_trajectory_run

EDC = get("edc")
#: the kinematic prior for the simulator's robots (their speed and turn rates' scale)
SIM = KinematicPrior(speed=0.3, sigma_speed=0.05, sigma_lateral=0.02, sigma_turn=0.3)


def world(seed: int, odometry: bool) -> list:
    rng = np.random.default_rng(100 + seed)
    a = random_trajectory_run(rng, n_landmarks=6, n_poses=120, fov_deg=360,
                              sigma_bearing=np.deg2rad(1))
    runs = [a] + [random_trajectory_run(rng, n_poses=120, fov_deg=360,
                                        sigma_bearing=np.deg2rad(1), landmarks=a.landmarks)
                  for _ in range(2)]
    meas = tuple(joint.simulated_measurements(r, odometry=odometry, robot=k).runs[0]
                 for k, r in enumerate(runs))
    post = joint.solve(joint.JointMeasurements(meas, tuple(range(6))),
                       joint.SolveParams(kinematic=SIM, kinematic_chunks=(20, 40),
                                         inflate_kinematic=1.0))
    if post.method == "none":
        return [seed, 0, float("nan")] + [float("nan")] * 4
    kept = [r for r, f in post.robot_flags.items() if f in ("ok", "kinematic")]
    k = joint.overdispersion(post, kept, seed=0)
    L = a.landmarks
    out = [seed, len(kept), k]
    for f in (1.0, max(1.0, k)):
        res = joint.triplet_marginals(joint.scale_covariance(post, f), samples=1000, seed=0)
        tri = np.array(res.triplets)
        s = EDC.state_of(to_frame(L[tri[:, 2]], L[tri[:, 0]], L[tri[:, 1]]))
        P = np.asarray(res.probabilities)
        out += [float(log_score(P, s).mean()), float(truth_under(P, s).mean())]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("kind", choices=("odo", "noodo"))
    ap.add_argument("worlds", type=int)
    a = ap.parse_args(argv)
    print("| world | robots kept | kappa | log p (x1) | under 1 % (x1) | log p (auto) | "
          "under 1 % (auto) |")
    print("|---|---|---|---|---|---|---|")
    rows = []
    for seed in range(a.worlds):
        r = world(seed, a.kind == "odo")
        rows.append(r)
        print(f"| {r[0]} | {r[1]} | {r[2]:.2f} | {r[3]:.3f} | {100 * r[4]:.1f} % | {r[5]:.3f} | "
              f"{100 * r[6]:.1f} % |", flush=True)
    x = np.array([r[2:] for r in rows], float)
    x = x[np.isfinite(x[:, 0])]
    print(f"median kappa {np.median(x[:, 0]):.2f}; mean log p x1 {x[:, 1].mean():.3f}, auto "
          f"{x[:, 3].mean():.3f}; truth under 1 % x1 {100 * x[:, 2].mean():.1f} %, auto "
          f"{100 * x[:, 4].mean():.1f} %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
