"""Configuration inference: the marginals of every triplet, seen or not, by sampling whole landmark
configurations.

A qualitative map's triplets are functions of one unknown: the world positions of its landmarks.
Instead of composing triplet states (the paper's composition factors, which treat states as
independent and lose what the positions within a state say), sample the configurations:

    pi(X)  ∝  prior(X) prod_{t seen} L_t(X),      X = (x_1..x_n) world positions,

with ``prior`` the world prior the single-triplet solvers used (:class:`qfg.priors.WorldBoxPrior`:
landmarks i.i.d. uniform in a box, pairwise at least ``d_min`` apart) and, for seen triplet
``t = AB:C`` with solver posterior ``P_t(s) = P(s | H_t)`` under that prior,

* state likelihood (``method="config-state"``): ``L_t = (1 - eps) P_t(s_t) / q(s_t) + eps``, where
  ``s_t`` is C's state in the AB frame of X and ``q`` the state distribution of the same prior
  (:func:`qfg.combine.prior_state_distribution`): ``P_t / q`` is ``P(H_t | s)`` up to a constant,
  and its mean under the prior is 1, so the floor ``eps`` is a fraction of the prior: one wrong
  estimate multiplies the truth's weight by ``eps`` at worst instead of vetoing it;
* metric likelihood (``method="config-metric"``): ``L_t = (1 - eps) [(1 - b) r_t(c_t) + b P_t(s_t) /
  q(s_t)] + eps`` with ``c_t`` C's AB-frame position and ``r_t(c) ≈ p(c | H_t) / prior(c)`` the
  solver's posterior density of C's position divided by the prior's, from a compact summary of
  the solver's weighted samples (:class:`PositionSummary`, :func:`summarize_position`: a kernel
  mixture whose component weights are divided by the prior density at their centres). ``b`` is
  ``state_mix`` (``low_ess_mix`` for summaries made from a sample with a low effective size).

Then the marginal of any triplet is the distribution of its state over the configurations.

The sampler is tempered sequential Monte Carlo (:func:`infer_configurations`): particles from the
prior, the likelihood brought in as ``L^beta`` with ``beta`` raised from 0 to 1 in stages chosen
to keep the effective sample size at ``target_ess`` of the particles, after each stage a
resampling and Metropolis moves: one landmark at a time (only the triplets containing it are
recomputed) and moves of the whole configuration by a random similarity transform, which leave
every AB-frame position (hence every likelihood) unchanged and are accepted on the prior alone
(the box and the Jacobian ``s^(2(n-1))`` of a scale change), and the same for blocks of
landmarks (the evidence's components and rigid clusters), accepted on the likelihood of the
triplets that touch them. Each estimate is widened by the effective sample size behind it
(``ess``, ``ess_prior``). The particles are split into
``n_groups`` populations resampled separately; the spread of their estimates is the Monte Carlo
error reported. Adding evidence later (:meth:`ConfigurationPosterior.update`) tempers only the new
likelihoods in from the current particles.

The package, in the order data flows through it:

* :mod:`~qfg.configurations.positions`: the metric evidence (:class:`PositionSummary`,
  :func:`summarize_position`, :func:`combine_positions`) and the prior's state distribution
  (:func:`prior_states`);
* :mod:`~qfg.configurations.evidence`: estimates read and checked (:func:`one_ordering_per_set`)
  and turned into the likelihood terms ``L_t``;
* :mod:`~qfg.configurations.sampler`: the tempered SMC sampler and its moves;
* :mod:`~qfg.configurations.check`: the leave-one-out check (:class:`LeaveOneOutCheck`,
  :func:`prior_mixing_weight`, :data:`CHECK_GRID`);
* :mod:`~qfg.configurations.posterior`: the samples and their answers
  (:class:`ConfigurationPosterior`);
* :mod:`~qfg.configurations.infer`: the entry points (:func:`infer_configurations`,
  :func:`configuration_marginals`) and their options (:data:`DEFAULTS`).

>>> import numpy as np
>>> post = infer_configurations({(0, 1, 2): np.eye(20)[1] * 0.9 + 0.005}, n_particles=400,
...                             seed=0)
>>> res = post.marginals([(0, 1, 2), (1, 0, 2)])
>>> int(np.argmax(res[(0, 1, 2)])), res.probabilities.shape
(1, (2, 20))
"""

from .check import CHECK_GRID, LeaveOneOutCheck, prior_mixing_weight
from .evidence import one_ordering_per_set
from .infer import (
    DEFAULTS,
    ESS_PRIOR,
    METHODS,
    TEMPER,
    configuration_marginals,
    infer_configurations,
)
from .positions import (
    LOW_ESS,
    PRIOR_STATE_SAMPLES,
    PositionSummary,
    combine_positions,
    prior_states,
    summarize_position,
)
from .posterior import (
    UNSETTLED_ERROR,
    UNSETTLED_SHARE,
    ConfigurationPosterior,
    NotSettledWarning,
)


def __getattr__(name):
    if name == "LIKELIHOODS":
        raise AttributeError("LIKELIHOODS was removed from qfg.configurations: use METHODS "
                             "(CHANGELOG.md, 0.6.0)")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = ["PositionSummary", "summarize_position", "combine_positions", "ConfigurationPosterior",
           "infer_configurations", "configuration_marginals", "prior_states",
           "one_ordering_per_set", "LeaveOneOutCheck", "CHECK_GRID", "prior_mixing_weight", "METHODS",
           "DEFAULTS", "NotSettledWarning", "UNSETTLED_ERROR", "UNSETTLED_SHARE", "TEMPER",
           "ESS_PRIOR", "PRIOR_STATE_SAMPLES", "LOW_ESS"]
