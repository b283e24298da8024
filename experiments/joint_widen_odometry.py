"""The joint map with odometry widened by its robots' scatter, or not (docs/joint.md, "Flags").

For each dataset and each images-per-pass count K (0: every keyframe; else at most K images per
120-s pass, ``mrclam_runs(min_interval=120 / K)``): the default joint map, the robots' scatter
about it (``joint.overdispersion`` over every robot with a map), and every ordered triplet's mean
log p(truth) (truth under 1 %) seen / unseen as solved, with the covariance times kappa (when
above 1) and times 4. Seen and unseen are the mrclam study's (its histories, 3 views per pass).

    python experiments/joint_widen_odometry.py 6 1 2 3 4 --per-pass 0 10
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np

from qfg import joint, metrics
from qfg.combine import prior_state_distribution
from qfg.graph import truth_states
from qfg.harness.studies import mrclam as study
from qfg.partitions import get as get_partition


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("datasets", nargs="*", type=int, default=[6])
    ap.add_argument("--per-pass", type=int, nargs="+", default=[0, 10])
    ap.add_argument("--data", default="")
    a = ap.parse_args(argv)
    part = get_partition("edc")
    print("| dataset | K | kappa | flags | as solved | x kappa | x 4 |")
    print("|---|---|---|---|---|---|---|")
    for d in study.dataset_dirs(a.data, a.datasets):
        ds, _ = study.prepare(d)
        q = prior_state_distribution(study.make_prior(ds, "arena"), part,
                                     samples=study.PRIOR_SAMPLES, seed=1)
        rh = study.histories(ds, None, mode="honest", spread_views=3, partition=part,
                             min_travel=0.02, max_gap=120.0)
        ids = ds.landmark_ids
        seen_idx = {tuple(ds.landmark_index(h.landmarks).tolist()) for _, h in rh}
        trip = np.array(list(itertools.permutations(range(ids.size), 3)))
        keys = [tuple(int(ids[i]) for i in t) for t in trip.tolist()]
        seen = np.array([tuple(t) in seen_idx for t in trip.tolist()])
        g = truth_states(trip, ds.landmark_xy, "edc")
        for k in a.per_pass:
            post = joint.solve(joint.mrclam_runs(ds, min_interval=120 / k if k else 0.0), seed=0)
            kap = joint.overdispersion(post, seed=0)
            cells = []
            for f in (1.0, kap if np.isfinite(kap) and kap > 1 else 1.0, 4.0):
                pp = joint.scale_covariance(post, f) if f != 1 else post
                P = joint.triplet_marginals(pp, keys, prior_states=q, samples=2000,
                                            seed=0).probabilities
                cells.append(" / ".join(
                    f"{metrics.log_score(P[m], g[m]).mean():.3f} "
                    f"({100 * metrics.truth_under(P[m], g[m], 0.01).mean():.1f} %)"
                    for m in (seen, ~seen)))
            print(f"| {ds.name[14:]} | {k or 'all'} | {kap:.2f} | {','.join(post.flags)} | "
                  + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
