"""Leave one robot out: do the other robots' configurations predict what one robot saw?

A check of the configuration map (``--map config-state``) that needs no ground truth and, unlike
the leave-one-out check over seen triplets (``ConfigurationPosterior.loo_check``), does not let
a set's evidence be predicted by sets that share its images: every history of one robot is held
out at once. For each robot r of a recorded ``qfg mrclam`` run (its solved histories, tempered
and combined as the run did), the map is made from the other robots' histories alone (the map's
own options) and each landmark set robot r saw is scored by the predictive ordinate of its
evidence relative to the prior's,

    log m_t = log E_{pi_-r}[L_t],

``L_t`` the set's (tempered, floored) state likelihood from robot r's histories, the expectation
over the other robots' configurations. Under a correct model the robots predict each other
better than the prior does (``log m_t > 0`` on average); where the map's configurations are wrong
in a way one robot's evidence shows, ``log m_t`` falls below 0, and ``lam`` (the weight toward
the prior that maximizes ``mean_t log((1 - lam) m_t + lam)``, as in ``loo_check``) grows.

The landmark ground truth is used only for the last columns, to ask whether the check sees what
matters: the held-out map's mean log p(truth) on the sets only robot r saw (unseen by the map)
against the prior alone's. One row per robot::

    python experiments/configurations/mrclam_config_robot_check.py out/d5-all [--seed 0]

Backs docs/configurations.md, "On MRCLAM". Run from the repository root as above, on a run
folder made by ``qfg mrclam``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np
from scipy.special import logsumexp

from qfg.configurations import (
    configuration_marginals,
    infer_configurations,
    prior_mixing_weight,
)
from qfg.graph import truth_states
from qfg.harness.studies import mrclam as study
from qfg.harness.studies.mrclam import maps
from qfg.metrics import log_score

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mrclam_config_options import run_estimates  # noqa: E402


def seen_of(prep, ests, opts, tau, keep):
    """The run's seen estimates from the histories ``keep`` (H,) bool only."""
    idx = np.flatnonzero(keep)
    sub = dataclasses.replace(prep, histories=[prep.histories[i] for i in idx])
    seen, _, _ = study.seen_estimates(sub, [ests[i] for i in idx],
                                      combine=opts.get("combine", "geometric"), temper=tau)
    return seen


def predictive_ordinates(post, evidence, seed=0):
    """``(triplets, log m)``: each set of ``evidence`` ({triplet: (m,)}) predicted by the
    configurations of ``post`` (a :class:`qfg.configurations.ConfigurationPosterior`), relative to
    the prior's prediction; sets with a landmark ``post`` does not hold are left out."""
    terms = infer_configurations(evidence, prior=post.prior, partition=post.partition.name,
                                 n_particles=8, n_sweeps=1, seed=seed)  # only its terms are used
    col = {lm: i for i, lm in enumerate(post.landmarks)}
    have = np.array([all(x in col for x in t) for t in terms.evidence])
    order = [col.get(lm, 0) for lm in terms.landmarks]
    ll = terms.log_likelihoods(post.positions[:, order])[have]           # (T, P)
    log_m = logsumexp(ll, axis=1, b=np.asarray(post.weights, float)[None])
    return [t for t, h in zip(terms.evidence, have, strict=True) if h], log_m


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="a qfg mrclam output folder (solved pieces)")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    prep, ests, opts = run_estimates(a.run)
    tau = float(opts.get("temper_chosen") or 1.0)
    robots = np.array([r for r, _ in prep.histories])
    ds = prep.dataset
    q = prep.prior_states
    print(f"{a.run}: temper {tau:g}, {len(prep.histories)} histories, robots "
          f"{sorted(set(robots.tolist()))}")
    print("| robot held out | sets: others / its own (only its own) | mean log m: all / only "
          "its own | log m < 0 | lam | only its own, the others' map: log p(truth) / prior "
          "alone |")
    print("|---|---|---|---|---|---|")
    for r in sorted(set(robots.tolist())):
        t0 = time.perf_counter()
        others = seen_of(prep, ests, opts, tau, robots != r)
        own = seen_of(prep, ests, opts, tau, robots == r)
        ev_o, ev_r = maps.state_evidence(others), maps.state_evidence(own)
        held = {x for t in ev_o for x in t}
        ev_r = {t: v for t, v in ev_r.items() if set(t) <= held}   # landmarks the others place
        res = configuration_marginals(ev_o, prior=others.prior, triplets=list(ev_r),
                                      partition=prep.partition.name, seed=a.seed,
                                      widen=maps.CONFIG_WIDEN, unlinked=maps.CONFIG_UNLINKED,
                                      check=maps.CONFIG_CHECK, **maps.CONFIG_OPTIONS)
        trips, log_m = predictive_ordinates(res.info["configurations"], ev_r, a.seed)
        only = np.array([t not in ev_o for t in trips], bool)
        lam, _ = prior_mixing_weight(log_m)
        rows = {t: i for i, t in enumerate(res.triplets)}
        T = np.array([rows[t] for t in trips], dtype=np.intp)
        truth = truth_states(np.array(trips, dtype=np.intp).reshape(-1, 3), ds.landmark_xy,
                             prep.partition.name)
        lp = log_score(np.asarray(res.probabilities)[T], truth)
        lq = np.log(np.maximum(q[truth], 1e-4))
        own_only = (f"{lp[only].mean():.2f} / {lq[only].mean():.2f}" if only.any() else "none")
        print(f"| {r} | {len(ev_o)} / {len(ev_r)} ({int(only.sum())}) | {log_m.mean():+.2f} / "
              + (f"{log_m[only].mean():+.2f}" if only.any() else "none")
              + f" | {100 * np.mean(log_m < 0):.0f} % | {lam:.2f} | {own_only} |", flush=True)
        print(f"  ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
