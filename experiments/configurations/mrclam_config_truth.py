"""Is a recorded ``qfg mrclam`` run's configuration map wrong because of its sampler or because of
its evidence? (development diagnostic)

Rebuilds the run's seen estimates as ``experiments/configurations/mrclam_config_options.py`` does, samples the
configuration posterior with the map's options (``config-state``), and scores the landmarks'
ground-truth configuration under the same likelihood terms
(:meth:`qfg.configurations.ConfigurationPosterior.log_likelihoods`):

* the log target ``sum_t log L_t`` at the truth against the particles': a truth above the
  particles means the sampler missed a better mode; below them, the evidence prefers a wrong
  configuration and no sampler can fix it;
* per seen term, the share of particles whose term is below the truth's (a PIT of the truth:
  about uniform when the posterior is calibrated, near 0 when the evidence is over-counted);
* the leave-one-out check the map runs (no ground truth).

    python experiments/configurations/mrclam_config_truth.py out/d2-full [seed]

The ground truth is used only to score, as ``qfg mrclam`` does.

Backs docs/configurations.md, "On MRCLAM". Run from the repository root as above, on a run
folder made by ``qfg mrclam``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from qfg.configurations import infer_configurations
from qfg.harness.studies.mrclam import maps

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mrclam_config_options import load_run  # noqa: E402


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print(__doc__)
        return 2
    out = Path(argv[0])
    seed = int(argv[1]) if len(argv) > 1 else 0
    prep, seen, tau = load_run(out)
    ev = maps.state_evidence(seen)
    post = infer_configurations(ev, prior=seen.prior, partition=prep.partition.name, seed=seed,
                                **maps.CONFIG_OPTIONS)
    # seen triplets index the dataset's landmarks, so the truth's columns are landmark_xy's rows
    truth = prep.dataset.landmark_xy[list(post.landmarks)]
    ll_p = post.log_likelihoods()
    ll_t = post.log_likelihoods(truth)[:, 0]
    tot = ll_p.sum(axis=0)
    pit = (ll_p < ll_t[:, None]).mean(axis=1)
    chk = post.loo_check()
    print(f"{out}: {len(ev)} seen sets, {len(post.landmarks)} landmarks, temper {tau:g}, "
          f"seed {seed}, {post.diagnostics['n_stages']} stages")
    print(f"log target: truth {ll_t.sum():.1f}; particles median {np.median(tot):.1f}, "
          f"max {tot.max():.1f}; particles below the truth {np.mean(tot < ll_t.sum()):.1%}")
    print(f"per term, share of particles below the truth: mean {pit.mean():.2f}; terms with the "
          f"truth below 5% of the particles {np.mean(pit < 0.05):.0%}")
    print(f"leave-one-out check: mean log ordinate {chk.log_cpo.mean():.2f}, sets below 0 "
          f"{np.mean(chk.log_cpo < 0):.0%}, widen {chk.widen:.2f}")
    ids = prep.dataset.landmark_ids
    sets = np.array(list(post.evidence))                        # (T, 3), the rows of ll_*
    for l in post.landmarks:
        hit = np.any(sets == l, axis=1)
        print(f"  landmark {ids[l]}: {hit.sum():3d} sets, truth {ll_t[hit].sum():7.1f}, "
              f"particles median {np.median(ll_p[hit].sum(axis=0)):7.1f}")
    return 0


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    raise SystemExit(main())
