"""Single-triplet solvers: P(S^{AB:C} | H) and P(S^{AB:X}_i | H) from one triplet's history.

One entry point, :func:`solve_triplet`, with these methods (paper section 4, Table 1):

* ``"full"``: Algorithm 1, sequential importance sampling over camera trajectories with the
  motion model, C integrated by sampling and the exact prior of the whole configuration in the
  final weights (:mod:`.sis`);
* ``"fast"``: the same engine with small budgets (the default fast variant: noise modelled);
* ``"fast-paper"``: the paper's faster variant taken literally, measured bearings and headings
  taken as exact and samples representing only the prior (:mod:`.fast_paper`);
* ``"baseline"``: the same Bayesian model without motion factors, views independent
  (:mod:`.baseline`);
* ``"reference"``: the exact posterior by adaptive importance sampling with its Monte Carlo error
  (:mod:`.reference`, seconds per triplet): the yardstick the others are measured against.

Every method takes ``prior=`` (a name or a :class:`qfg.priors.Prior`; default ``"world"``, the
exact prior of the simulator's world).

:func:`solve_triplets` solves many triplets in one call (the fast variant batched in numpy);
:class:`TripletSolver` solves one triplet incrementally (``add_view``, ``estimate``,
``hypotheses``) and gives exactly the estimate of all views solved at once. A
:class:`TripletEstimate` holds only the answer. Defaults of every option and the measurements behind them:
``docs/solvers.md``.

Where things are: the entry points and the choice of method in :mod:`.solve`; the time and
memory bounds of every method in :mod:`.budget`; one module or package per method (above); the
pieces several methods share (measurement checks, likelihoods, priors, options, the estimate,
seeds, ...) in :mod:`.common`.

>>> import numpy as np
>>> from qfg.simulation import random_triplet_history
>>> h = random_triplet_history(np.random.default_rng(3), n_views=3)
>>> est = solve_triplet(h, method="full", seed=0)
>>> int(np.argmax(est.landmark)) == h.truth.state
True
"""

from __future__ import annotations

from .common.estimate import Hypotheses, TripletEstimate
from .common.options import DEFAULTS, METHODS
from .solve import TripletSolver, add_view, solve_triplet, solve_triplets

__all__ = ["solve_triplet", "solve_triplets", "TripletSolver", "TripletEstimate", "Hypotheses",
           "add_view", "DEFAULTS", "METHODS"]
