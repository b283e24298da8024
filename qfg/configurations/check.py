"""The leave-one-out check of configuration inference (:mod:`qfg.configurations`): how well the
seen triplets predict each other under the model, relative to the prior alone
(:class:`LeaveOneOutCheck`, :func:`prior_mixing_weight`), as
:meth:`~qfg.configurations.ConfigurationPosterior.loo_check` computes it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LeaveOneOutCheck", "CHECK_GRID", "prior_mixing_weight"]


@dataclass(frozen=True, eq=False)
class LeaveOneOutCheck:
    """The seen triplets predicted from each other (:meth:`ConfigurationPosterior.loo_check`).

    Attributes:
        triplets: the seen triplets, in the order of ``log_cpo``.
        log_cpo: (T,) ``log m_t``, each seen triplet's evidence predicted by the configurations
            sampled from the other seen triplets, relative to the prior's prediction (0: as well
            as the prior alone; below 0: worse).
        widen: the weight ``lam`` in [0, 1] maximizing ``mean_t log((1 - lam) m_t + lam)``: 0 when
            the seen triplets predict each other at least as well as the prior does.
        agreement: (mean log m_t, the mean at ``widen``).
    """

    triplets: tuple
    log_cpo: np.ndarray
    widen: float
    agreement: tuple

    @property
    def contradicted(self) -> bool:
        """Whether the seen triplets predict each other worse than the prior alone would."""
        return self.widen > 0


#: The grid of ``widen`` weights :meth:`ConfigurationPosterior.loo_check` maximizes over.
CHECK_GRID = np.linspace(0.0, 1.0, 101)


def prior_mixing_weight(log_m) -> tuple:
    """``(lam, (mean log m, the mean at lam))``: the weight ``lam`` of :data:`CHECK_GRID` that
    maximizes ``mean_t log((1 - lam) m_t + lam)``, for predictive ordinates ``log_m`` (T,) of
    evidence relative to the prior's (:meth:`ConfigurationPosterior.loo_check`): the share of the
    prior a mixture needs to predict the evidence best (0 when it predicts it at least as well
    as the prior does on average).

    >>> lam, _ = prior_mixing_weight(np.log([2.0, 3.0]))
    >>> lam
    0.0
    >>> prior_mixing_weight(np.log([1e-3, 1e-3]))[0]
    1.0
    """
    m = np.exp(np.asarray(log_m, dtype=float))
    score = np.mean(np.log((1.0 - CHECK_GRID[:, None]) * m[None] + CHECK_GRID[:, None]), axis=1)
    k = int(np.argmax(score))
    return float(CHECK_GRID[k]), (float(score[0]), float(score[k]))
