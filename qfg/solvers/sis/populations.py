"""Independent populations of the SIS engine (option ``populations`` of ``full`` and ``fast``).

One triplet is solved ``K`` times by the engine, each time from its own seed and with ``1 / K``
of the sample budget, and the ``K`` answers are averaged. Why: a sequential importance sampler
can settle in one mode of a multimodal posterior and report it with near certainty, and its
effective sample size, computed inside that mode, cannot see it. Independent populations settle
in different modes when the posterior has several, so their average keeps each in proportion to
how often a population finds it, and their spread estimates the Monte Carlo error the ESS misses
(docs/solvers.md, "Independent populations": on development geometries at 10 views one
population put the truth under 1 % in 2-3 of 150 answers, two half-budget populations' average
in 1, at the same time).

Merging (:func:`merge`), for the ``K`` estimates ``e_k`` of one triplet:

* ``landmark``, ``cameras``: the means ``(1 / K) sum_k e_k``;
* ``ess``: that of the pooled weights ``w_kj / K``, ``K^2 / sum_k (1 / ess_k)``;
* ``mc_error``: the larger of the between-population standard error of the mean,
  ``max_s sd_k(e_k[s]) / sqrt(K)``, and the populations' own errors combined,
  ``sqrt(sum_k mc_k^2) / K``;
* ``pareto_k``: the largest; ``model_check``: the mean of the p-values (each estimates the same
  posterior predictive probability); ``n_hypotheses``: the sum;
* flagged by every flag read off the measurements (the same in each population), by the two
  read off the samples decided for the pool (C's depth unresolved by the mean of the
  populations' shares, the ESS by the pooled ESS: :func:`qfg.solvers.common.estimate.pooled_reasons`;
  a union of noisy per-population tests would flag more often the more populations there are),
  or when two populations put most of their mass on different states (total variation above
  :data:`DISAGREE`): the sampler then failed to settle, and the average says only that both
  are possible.

``K = 1`` is the engine alone, unchanged (the same seed, the same answer). ``K`` may differ for
solves of at most :data:`.engine.FEW_VIEWS` views (option ``few_views_populations``), where a sampler
rarely settles in a wrong mode and ``K`` populations cost about ``K`` times the per-triplet
work the budget does not scale: :class:`qfg.solvers.TripletSolver` then solves its views again
from the first when the next view changes ``K``, so that the answer after ``n`` views depends on
``n`` only, as in a batch.
"""

from __future__ import annotations

import numpy as np

from ..common import seeds as _seeds
from ..common.estimate import pool
from .engine import FEW_VIEWS

#: Budget options divided among the populations (each gets ``max(1, round(value / K))``).
SPLIT_KEYS = ("n_samples", "max_hypotheses", "posterior_samples")

#: Total variation between two populations' landmark answers above which the answer is flagged.
DISAGREE = 0.9

#: Spawn key offset of the populations' seeds under a triplet's root (keeps them apart from the
#: engine's own per-view streams, whose keys are (view, stream)).
_POPULATION_KEY = 1_000_003


def count(opts, n_views: int | None = None) -> int:
    """``K`` for a solve that ends after ``n_views`` views: option ``few_views_populations`` up
    to :data:`qfg.solvers.sis.engine.FEW_VIEWS` views, ``populations`` beyond (and when ``n_views``
    is None); 1 where the options have neither."""
    if n_views is not None and n_views <= FEW_VIEWS and "few_views_populations" in opts:
        return int(opts["few_views_populations"])
    return int(opts.get("populations", 1) or 1)


def split_options(opts: dict, K: int) -> dict:
    """The options one of ``K`` populations runs with: the budget of :data:`SPLIT_KEYS` (and
    of ``few_views_budget``) divided by ``K`` (the options themselves when ``K = 1``)."""
    if K == 1:
        return dict(opts)
    out = dict(opts)
    for k in SPLIT_KEYS:
        if k in out:
            out[k] = max(1, int(round(out[k] / K)))
    fv = out.get("few_views_budget")
    if fv:
        out["few_views_budget"] = {k: (max(1, int(round(v / K))) if k in SPLIT_KEYS else v)
                                   for k, v in fv.items()}
    return out


def roots(root: np.random.SeedSequence, K: int) -> list:
    """The populations' seeds under a triplet's ``root`` (``[root]`` itself when ``K = 1``)."""
    if K == 1:
        return [root]
    return [_seeds.child_seed(root, _POPULATION_KEY, k) for k in range(K)]


def _tv(a, b) -> float:
    return 0.5 * float(np.abs(a - b).sum())


def merge(pairs, opts: dict):
    """One ``(estimate, hypotheses)`` pair from the ``K`` pairs of one triplet's populations
    (module docstring); ``hypotheses`` None when none were kept. ``opts`` are the caller's
    options (recorded in the estimate, ``populations`` included)."""
    pairs = list(pairs)
    K = len(pairs)
    ests = [p[0] for p in pairs]
    if K == 1:
        return pairs[0]
    L = np.stack([e.landmark for e in ests])
    between = float(np.max(L.std(axis=0, ddof=1)) / np.sqrt(K))
    tv = max(_tv(L[i], L[j]) for i in range(K) for j in range(i + 1, K))
    extra = []
    if tv > DISAGREE:
        extra.append(f"the {K} independent populations disagree (total variation {tv:.2f} "
                     "between two of them): the sampler did not settle, and the answer is their "
                     "average")
    return pool(pairs, np.full(K, 1.0 / K), opts, error_floor=between, extra_reasons=extra)


__all__ = ["count", "split_options", "roots", "merge", "DISAGREE", "SPLIT_KEYS"]
