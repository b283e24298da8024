"""One tempering power per robot against one for the whole run (development measurement).

The check over histories (``--temper auto`` / ``auto-1se``, :func:`qfg.harness.studies.mrclam.
choose_power`) picks one power from every pair of passes of one ordered triplet. Errors that a
robot's passes share (its camera, its odometry) differ by robot, so this script also picks a power
per robot from that robot's pairs alone (a robot with no pair keeps the run's power), tempers each
history by its robot's power, combines as the run does, and scores the seen triplets of both
against the landmark ground truth (used only to score), paired per ordered triplet with the
standard error over landmark sets::

    python experiments/mrclam/mrclam_robot_power.py out/d2-full [auto-1se|auto]

The folder is a recorded ``qfg mrclam`` run (``run.json``, ``records.jsonl``, ``summary.json``).

Backs docs/results/mrclam.md, "What limits the rest". Run from the repository root as above.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from qfg.combine import temper
from qfg.graph import truth_states
from qfg.harness.studies import mrclam as study
from qfg.metrics import log_score

# run_estimates: the configuration experiments' reading of a recorded run
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "configurations"))
from mrclam_config_options import run_estimates  # noqa: E402


def _score(prep, ests, combine):
    seen, _, _ = study.seen_estimates(prep, ests, combine=combine, temper=1.0)
    truth = truth_states(seen.triplets, prep.dataset.landmark_xy, prep.partition.name)
    p = seen.probabilities[np.arange(truth.size), truth]
    return seen.triplets, log_score(seen.probabilities, truth), p


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print(__doc__)
        return 2
    out = Path(argv[0])
    rule = argv[1] if len(argv) > 1 else "auto-1se"
    prep, ests, opts = run_estimates(out)
    combine = opts.get("combine", "geometric")
    q = prep.prior_states
    P = np.array([e.landmark for e in ests])
    groups = study.history_groups(prep)
    robot = np.array([r for r, _ in prep.histories])
    tau_all, _ = study.choose_power(P, groups, q, rule=rule)
    taus = {}
    for r in np.unique(robot):
        g = {t: [k for k in ks if robot[k] == r] for t, ks in groups.items()}
        g = {t: ks for t, ks in g.items() if len(ks) >= 2}
        taus[int(r)] = study.choose_power(P, g, q, rule=rule)[0] if g else tau_all
    print(f"{out}: {rule}; the run's power {tau_all:g}; per robot {taus}")

    def tempered(power_of):
        return [study.LightEstimate(temper(e.landmark, q, power_of(k)), e.cameras, e.method,
                             e.degenerate, e.model_check, e.position)
                for k, e in enumerate(ests)]

    trip, la, pa = _score(prep, tempered(lambda k: tau_all), combine)
    _, lb, pb = _score(prep, tempered(lambda k: taus[int(robot[k])]), combine)
    truth = truth_states(trip, prep.dataset.landmark_xy, prep.partition.name)
    prior = log_score(np.tile(q, (truth.size, 1)), truth)
    sets = [tuple(sorted(t)) for t in trip.tolist()]
    d = {}
    for s, x in zip(sets, lb - la, strict=True):
        d.setdefault(s, []).append(x)
    m = np.array([np.mean(v) for v in d.values()])
    print(f"seen {trip.shape[0]}: one power {la.mean():.3f} (truth < 1% {np.mean(pa < 0.01):.3f}),"
          f" per robot {lb.mean():.3f} ({np.mean(pb < 0.01):.3f}), prior alone {prior.mean():.3f};"
          f" paired {np.mean(lb - la):+.3f} +- {m.std(ddof=1) / np.sqrt(m.size):.3f}")
    return 0


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    raise SystemExit(main())
