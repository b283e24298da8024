"""Escalation of a few-views answer (option ``few_views_escalate`` of ``full``): a triplet with at
most :data:`qfg.solvers.sis.engine.FEW_VIEWS` views is solved with the small few-views budget
(``few_views_budget``) split among ``few_views_populations >= 2`` independent populations; where
those populations disagree, it is solved again with the caller's whole budget and the two
answers are pooled.

Why: a sequential importance sampler with a small budget mostly errs by weighting the modes of a
multimodal posterior wrongly, and its own effective sample size cannot see that (it is computed
inside the modes it found); two independent populations can, because they weight the modes
differently. Measured on 400 development geometries x 6 solver seeds at 3 views
(docs/results/solvers_options.md, "The few-views package",
``experiments/solvers/few_views_escalation.py``): the
single run's ESS, entropy or ``mc_error`` do not find the triplets where the small budget is
worse than the whole one, the populations' disagreement does; and on those triplets the whole
budget alone is about as wrong as the small one, so its answer is pooled with the small one
rather than put in its place.

The option's value is None (off) or a threshold in (0, 1) on the few-views answer's
``mc_error``; it needs ``few_views_populations >= 2`` (:func:`qfg.solvers.common.options.resolve_options`
refuses it otherwise: one population's own error was measured blind to what escalation is for).

The rule, for one triplet whose few-views answer ``e_s`` (populations merged by
:func:`qfg.solvers.sis.populations.merge`) has ``e_s.mc_error > threshold`` (or no finite error):

* the same views are solved with the caller's options without the few-views ones (the whole
  budget, ``populations`` populations) from the seed ``child_seed(seed, ESCALATE_KEY)`` of the
  triplet's seed ``seed``, giving ``e_f``;
* the answer is ``w e_s + (1 - w) e_f`` (landmark, cameras), ``w = b_s / (b_s + b_f)`` with
  ``b = n_samples x motion_samples`` of each solve's budget (each answer's Monte Carlo variance
  scales about as ``1 / b``); ``ess = 1 / (w^2 / ess_s + (1 - w)^2 / ess_f)`` (that of the pooled
  weights), ``mc_error = sqrt(w^2 mc_s^2 + (1 - w)^2 mc_f^2)``, ``n_hypotheses`` the sum, the
  larger ``pareto_k``, the weighted mean of the model checks' p-values, the flags decided for the pool
  (:func:`qfg.solvers.common.estimate.pooled_reasons`);
  the hypotheses are both sets, weights scaled by ``w`` and ``1 - w``.

The test depends on the answer of ``n`` views only (not on how the views arrived), so the
incremental :class:`qfg.solvers.TripletSolver` and a batch solve give the same answers.
"""

from __future__ import annotations

import numpy as np

from ..common import estimate as _estimate
from ..common import seeds as _seeds
from ..common.options import FEW_VIEWS_OFF
from .engine import FEW_VIEWS

#: Spawn key (under a triplet's seed) of the escalated solve's seed.
ESCALATE_KEY = 2_000_003


def applies(opts: dict, n_views: int) -> bool:
    """Whether a solve of ``n_views`` views with ``opts`` escalates its unreliable answers."""
    return opts.get("few_views_escalate") is not None and n_views <= FEW_VIEWS


def needed(est, opts: dict) -> bool:
    """Whether the few-views answer ``est`` is escalated: its ``mc_error`` above the threshold,
    or not finite."""
    return not (est.mc_error <= opts["few_views_escalate"])


def whole_options(opts: dict) -> dict:
    """The caller's options without the few-views ones: the whole budget, ``populations``
    populations, no escalation."""
    return {**opts, **FEW_VIEWS_OFF,
            "few_views_populations": int(opts.get("populations", 1) or 1)}


def seed(root: np.random.SeedSequence) -> np.random.SeedSequence:
    """The escalated solve's seed under a triplet's seed ``root``."""
    return _seeds.child_seed(root, ESCALATE_KEY)


def _budget(opts: dict) -> float:
    o = dict(opts)
    o.update(opts.get("few_views_budget") or {})
    return float(o["n_samples"] * o["motion_samples"])


def weight(opts: dict) -> float:
    """``w``: the few-views answer's share of the pooled answer (module docstring)."""
    bs, bf = _budget(opts), _budget(whole_options(opts))
    return bs / (bs + bf)


def pool(small, whole, opts: dict):
    """One ``(estimate, hypotheses)`` pair from the few-views pair ``small`` and the escalated
    pair ``whole`` (module docstring); ``opts`` the caller's options (recorded in the
    estimate)."""
    w = weight(opts)
    return _estimate.pool([small, whole], [w, 1.0 - w], opts)


__all__ = ["ESCALATE_KEY", "applies", "needed", "whole_options", "seed", "weight",
           "pool"]
