"""Score a recorded ``qfg mrclam`` run's configuration maps under other options (development).

Rebuilds the run's seen estimates from its folder (``run.json``, ``records.jsonl``, the temper
it chose in ``summary.json``), then makes the configuration map with each variant and prints the
mean log p(truth) (clip 1e-4) of its seen and unseen triplets, the share of truths under 1 %, the
share of rows widened mostly to the prior, the share unsettled (Monte Carlo error above
:data:`qfg.configurations.UNSETTLED_ERROR`) and the largest Monte Carlo error. A variant is
``KIND[:option=value...]`` with KIND ``state`` or ``metric`` and options of
:func:`qfg.configurations.configuration_marginals` (``widen=none`` for no widening)::

    python experiments/configurations/mrclam_config_options.py out/d2 \\
        "metric,metric:widen=none,metric:widen=0.1"

and, for ``state``, ``shared=1``: each pass's estimate tempered by its composite-likelihood
weight before the passes of a set are pooled (:func:`shared_image_weights`: every bearing counted
once over the landmark sets whose passes use its image).

The landmark ground truth is used only to score, as ``qfg mrclam`` does, except by the diagnostic
KIND ``truth:c=C`` (``0 < C < 1``): every seen set's evidence replaced by ``C onehot(true state)
+ (1 - C) q`` (``q`` the prior's state distribution), correct evidence as strong as ``C`` says, to
ask how much the map can make of the run's seen sets on this layout::

    python experiments/configurations/mrclam_config_options.py out/d2 "state,truth:c=0.15,truth:c=0.98"

Backs docs/configurations.md, "On MRCLAM". Run from the repository root as above, on a run
folder made by ``qfg mrclam``.
"""

from __future__ import annotations

import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np

from qfg.configurations import configuration_marginals, one_ordering_per_set
from qfg.graph import truth_states
from qfg.harness.studies import mrclam as study
from qfg.harness.studies.mrclam import maps
from qfg.metrics import log_score


def _value(key, text):
    if text == "none":
        return None
    if key == "unlinked":
        return text
    return float(text) if "." in text or "e" in text else int(text)


def run_estimates(out: Path):
    """``(prep, estimates, options)`` of a recorded run's folder: its prepared dataset, every
    history's solved estimate (untempered) and the options of its last finish
    (``summary.json``: ``combine``, ``temper_chosen``, ...)."""
    params = json.loads((out / "run.json").read_text())["params"]
    prep = study.prepare_run(params["path"], study.params_of(params))
    rows = [r for line in open(out / "records.jsonl") for r in json.loads(line)["rows"]]
    opts = json.loads((out / "summary.json").read_text())["options"]
    return prep, study.estimates_from_rows(prep, rows), opts


def load_run(out: Path):
    """``(prep, seen, tau)`` of a recorded run's folder: its prepared dataset, its seen
    estimates combined as the run combined them, and the tempering power it chose."""
    prep, ests, opts = run_estimates(out)
    tau = float(opts.get("temper_chosen") or 1.0)
    seen, _, _ = study.seen_estimates(prep, ests, combine=opts.get("combine", "geometric"),
                                      temper=tau)
    return prep, seen, tau


def shared_image_weights(prep) -> np.ndarray:
    """(H,) composite-likelihood weight of each history of ``prep``: the mean, over its bearings
    (robot, image, landmark), of 1 / the number of landmark sets whose histories use that
    bearing. A view of k landmarks lends each bearing to up to (k - 1)(k - 2) / 2 sets, which
    the configuration map multiplies as independent evidence."""
    use: dict = {}
    keys = []
    for robot, h in prep.histories:
        s = tuple(sorted(int(x) for x in h.landmarks))
        k = [(robot, float(t), x) for t in np.round(np.asarray(h.views, dtype=float), 3)
             for x in s]
        keys.append(k)
        for b in k:
            use.setdefault(b, set()).add(s)
    return np.array([np.mean([1.0 / len(use[b]) for b in k]) for k in keys])


def _shared_evidence(out: Path, prep, seen) -> dict:
    """One ordering per seen set, each pass tempered by :func:`shared_image_weights` before
    the set's passes are pooled by their geometric mean (ValueError for a run that pooled them
    otherwise)."""
    from qfg.combine import geometric_pool, temper

    how = json.loads((out / "summary.json").read_text())["options"].get("combine", "geometric")
    if how != "geometric":
        raise ValueError(f"{out}: shared=1 pools the passes geometrically; the run used "
                         f"--combine {how}")
    w = shared_image_weights(prep)
    print(f"shared=1: weights of the {w.size} passes, 10/50/90th percentiles "
          f"{np.percentile(w, [10, 50, 90]).round(2).tolist()}")
    q = seen.prior_states
    pooled = {t: geometric_pool(np.array([temper(seen.estimates[k], q, w[k]) for k in ks]),
                                q).probabilities for t, ks in seen.groups.items()}
    return one_ordering_per_set(pooled)


def _true_evidence(evidence: dict, state: dict, q, c: float) -> dict:
    """The seen sets of ``evidence`` (same keys), each ``c onehot(state[t]) + (1 - c) q``."""
    q = np.asarray(q, dtype=float)
    return {t: c * np.eye(q.size)[state[t]] + (1.0 - c) * q for t in evidence}


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print(__doc__)
        return 2
    out = Path(argv[0])
    variants = argv[1].split(",") if len(argv) > 1 else ["state", "metric"]
    prep, seen, tau = load_run(out)
    ds = prep.dataset
    wanted = np.array(list(itertools.permutations(range(ds.landmark_ids.size), 3)),
                      dtype=np.intp).reshape(-1, 3)
    truth = truth_states(wanted, ds.landmark_xy, prep.partition.name)
    keys = {tuple(t) for t in seen.triplets.tolist()}
    is_seen = np.array([tuple(t) in keys for t in wanted.tolist()])
    state = dict(zip(map(tuple, wanted.tolist()), truth.tolist(), strict=True))
    print(f"{out}: temper {tau:g}; the prior alone: seen "
          f"{np.log(prep.prior_states[truth[is_seen]]).mean():.2f}, unseen "
          f"{np.log(prep.prior_states[truth[~is_seen]]).mean():.2f}")
    for v in variants:
        kind, *rest = v.split(":")
        kw = dict(maps.CONFIG_OPTIONS, widen=maps.CONFIG_WIDEN, unlinked=maps.CONFIG_UNLINKED,
                  seed=0)
        shared, c = False, None
        for r in rest:
            k, text = r.split("=")
            if k == "shared":
                shared = text == "1"
                continue
            if k == "c":
                c = float(text)
                continue
            kw[k] = _value(k, text)
        if kind not in ("state", "metric", "truth"):
            raise ValueError(f"{v}: expected a KIND of state, metric or truth, got {kind!r}")
        if shared and kind != "state":
            raise ValueError(f"{v}: shared=1 is an option of the state likelihood only")
        if (kind == "truth") != (c is not None) or (c is not None and not 0.0 < c < 1.0):
            raise ValueError(f"{v}: truth takes c=C with 0 < C < 1, and only truth takes c")
        if kind == "truth":
            ev = _true_evidence(maps.state_evidence(seen), state, seen.prior_states, c)
        else:
            ev = (maps.metric_evidence(seen) if kind == "metric"
                  else _shared_evidence(out, prep, seen) if shared else maps.state_evidence(seen))
        strength = ("" if kind == "metric" else "; evidence %.2f" % np.mean(log_score(
            np.array([ev[t] for t in ev]), np.array([state[t] for t in ev]))))
        t0 = time.perf_counter()
        res = configuration_marginals(ev, prior=seen.prior,
                                      triplets=[tuple(t) for t in wanted.tolist()],
                                      partition=prep.partition.name,
                                      method="config-metric" if kind == "metric" else "config-state",
                                      check=maps.CONFIG_CHECK, **kw)
        P = np.asarray(res.probabilities, dtype=float)
        P = P / P.sum(axis=1, keepdims=True)
        p = P[np.arange(len(P)), truth]
        lp = log_score(P, truth)
        w = np.asarray(res.info.get("widened", np.zeros(len(P))))
        print(f"{v}: seen {lp[is_seen].mean():.2f} ({np.mean(p[is_seen] < 0.01):.3f}) unseen "
              f"{lp[~is_seen].mean():.2f} ({np.mean(p[~is_seen] < 0.01):.3f}); widened "
              f"{np.mean(w > 0.5):.2f}; unsettled {np.mean(res.info['unsettled']):.2f}; "
              f"MC error {np.max(res.info['mc_error']):.2f}; "
              f"{time.perf_counter() - t0:.0f} s{strength}", flush=True)
    return 0


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    raise SystemExit(main())
