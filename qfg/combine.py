"""Combining several estimates of one triplet's state, made from separate histories, at the state
level with the prior counted once.

Each single-triplet estimate is a posterior ``p_i(s) = P(s | H_i)`` under the same prior. If the
histories ``H_1..H_k`` (separate passes, other robots) are independent given the state ``s``, Bayes
gives

    P(s | H_1..H_k)  ∝  P(s) prod_i P(H_i | s)  ∝  prod_i p_i(s) / P(s)^(k - 1),

with ``P(s)`` the state distribution the prior alone gives (:func:`prior_state_distribution`).
A plain product of posteriors ``prod_i p_i(s)`` counts the prior k times: with a prior that is
far from uniform over the states (a world prior puts most of C's mass in a few states near AB) it
sharpens towards the prior's favourite states. Passes are independent given C's *position*, not
given its state, so the rule is an approximation (it ignores how the passes' information about
C's position within a state agrees); ``tests/test_combine.py`` measures it against the reference
solver on two passes solved together.

>>> import numpy as np
>>> prior = np.array([0.5, 0.25, 0.25])
>>> p1 = p2 = np.array([0.5, 0.25, 0.25])          # two estimates that learned nothing
>>> combine_posteriors([p1, p2], prior).probabilities.tolist()
[0.5, 0.25, 0.25]
>>> (p1 * p2 / (p1 * p2).sum()).round(3).tolist()   # the product double-counts the prior
[0.667, 0.167, 0.167]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import partitions as _partitions
from . import priors as _priors
from ._validate import as_float_array, as_rng, positive_int

__all__ = ["CombinedEstimate", "combine_posteriors", "product_of_posteriors",
           "prior_state_distribution", "temper", "geometric_pool"]

#: Probability vectors must sum to 1 within this.
_SUM_TOL = 1e-6


@dataclass(frozen=True)
class CombinedEstimate:
    """A combination of k estimates of one triplet's state.

    Attributes:
        probabilities: (m,) the combined distribution (sums to 1).
        n_estimates: k.
        conflict: True when the estimates leave no state with positive probability in all of them
            (they contradict each other): ``probabilities`` is then the mean of the estimates,
            not a product.
    """

    probabilities: np.ndarray
    n_estimates: int
    conflict: bool


def _vectors(posteriors) -> np.ndarray:
    P = as_float_array("posteriors", posteriors)
    if P.ndim == 1:
        P = P[None, :]
    if P.ndim != 2 or P.shape[0] < 1 or P.shape[1] < 2:
        raise ValueError(f"posteriors: expected shape (k, m) with k >= 1, m >= 2, got {P.shape}")
    if np.any(P < 0):
        raise ValueError("posteriors: negative probabilities")
    s = P.sum(axis=1)
    if np.any(np.abs(s - 1) > _SUM_TOL):
        raise ValueError(f"posteriors: each row must sum to 1 (found {s[np.argmax(np.abs(s - 1))]:.6g})")
    return P


def _combine_logs(logp, P) -> CombinedEstimate:
    k = P.shape[0]
    if not np.isfinite(logp).any():
        mean = P.mean(axis=0)
        return CombinedEstimate(mean / mean.sum(), k, True)
    w = np.exp(logp - np.max(logp))
    return CombinedEstimate(w / w.sum(), k, False)


def combine_posteriors(posteriors, prior_states) -> CombinedEstimate:
    """``P(s | H_1..H_k) ∝ prod_i p_i(s) / prior(s)^(k - 1)``: k posteriors (k, m) of one triplet
    under the same prior, ``prior_states`` (m,) the state distribution of that prior
    (:func:`prior_state_distribution`). Computed in logs (products of k small numbers underflow).

    States the prior gives probability 0 are impossible: they get 0. When no state is possible in
    every estimate the estimates contradict each other; the mean of the estimates is returned with
    ``conflict=True`` (a flag, never a division by zero).

    >>> combine_posteriors([[0.8, 0.2], [0.8, 0.2]], [0.5, 0.5]).probabilities.round(3).tolist()
    [0.941, 0.059]
    """
    P = _vectors(posteriors)
    q = as_float_array("prior_states", prior_states)
    if q.shape != (P.shape[1],):
        raise ValueError(f"prior_states: expected shape ({P.shape[1]},), got {q.shape}")
    if np.any(q < 0) or abs(q.sum() - 1) > _SUM_TOL:
        raise ValueError("prior_states: expected a probability vector (non-negative, sum 1)")
    k = P.shape[0]
    with np.errstate(divide="ignore"):
        logp = np.log(P).sum(axis=0) - (k - 1) * np.log(np.where(q > 0, q, 1.0))
    logp = np.where(q > 0, logp, -np.inf)
    return _combine_logs(logp, P)


def geometric_pool(posteriors, prior_states) -> CombinedEstimate:
    """``P(s) ∝ prior(s) prod_i (p_i(s) / prior(s))^(1/k)``: the k histories' likelihoods pooled
    by their geometric mean, the prior once -- the rule for histories that repeat the same
    evidence (fully dependent: k copies of one pass give that pass). Between this and
    :func:`combine_posteriors` (independent histories) lies the truth for passes whose errors
    are shared (the same landmarks' geometry, the same camera bias).

    >>> geometric_pool([[0.8, 0.2], [0.8, 0.2]], [0.5, 0.5]).probabilities.round(3).tolist()
    [0.8, 0.2]
    """
    P = _vectors(posteriors)
    k = P.shape[0]
    return combine_posteriors(temper(P, prior_states, 1.0 / k), prior_states)


def product_of_posteriors(posteriors) -> CombinedEstimate:
    """``prod_i p_i(s)``, renormalized: the rule that counts the prior k times (kept to measure
    what counting it once changes; same conflict handling as :func:`combine_posteriors`).

    >>> product_of_posteriors([[0.8, 0.2], [0.8, 0.2]]).probabilities.round(3).tolist()
    [0.941, 0.059]
    """
    P = _vectors(posteriors)
    with np.errstate(divide="ignore"):
        logp = np.log(P).sum(axis=0)
    return _combine_logs(logp, P)


def temper(posteriors, prior_states, tau: float) -> np.ndarray:
    """Tempered estimates ``p_tau(s) ∝ prior(s) (p(s) / prior(s))^tau``: the likelihood part of
    each posterior raised to the power ``tau`` in [0, 1], the prior kept whole (a power
    likelihood, the usual remedy when a model's likelihood is overconfident). ``tau = 1`` returns
    the estimates, ``tau = 0`` the prior. Shapes: (..., m) and (m,) -> (..., m).

    >>> temper([[0.9, 0.1]], [0.5, 0.5], 0.5).round(3).tolist()
    [[0.75, 0.25]]
    """
    P = as_float_array("posteriors", posteriors)
    if P.ndim < 1 or P.shape[-1] < 2 or np.any(P < 0):
        raise ValueError(f"posteriors: expected non-negative (..., m) vectors, got shape {P.shape}")
    q = as_float_array("prior_states", prior_states)
    if q.shape != (P.shape[-1],) or np.any(q < 0) or abs(q.sum() - 1) > _SUM_TOL:
        raise ValueError(f"prior_states: expected a probability vector of length {P.shape[-1]}")
    tau = float(tau)
    if not 0 <= tau <= 1:
        raise ValueError(f"tau: expected a number in [0, 1], got {tau}")
    if tau == 1:
        return P / P.sum(axis=-1, keepdims=True)
    qs = np.where(q > 0, q, 1.0)
    with np.errstate(divide="ignore"):
        logp = np.where((P > 0) & (q > 0), tau * (np.log(np.where(P > 0, P, 1.0)) - np.log(qs))
                        + np.log(qs), -np.inf)
    if tau == 0:
        logp = np.where(q > 0, np.log(qs), -np.inf) + np.zeros_like(P)
    mx = np.max(logp, axis=-1, keepdims=True)
    mx = np.where(np.isfinite(mx), mx, 0.0)
    w = np.exp(logp - mx)
    tot = w.sum(axis=-1, keepdims=True)
    return np.where(tot > 0, w / np.where(tot > 0, tot, 1.0), q)


def prior_state_distribution(prior="world", partition="edc", *, point: int = 0,
                             n_cameras: int = 0, samples: int = 200_000, seed=0) -> np.ndarray:
    """The state distribution a prior alone gives one point of the configuration: (m,).

    Draws ``samples`` configurations ``[C, X_1..X_n]`` with ``prior.sample(rng, n_cameras,
    samples)`` (AB frame), takes the state of point ``point`` (0 = C, j = camera j) and counts.
    Each count gets half a sample added (the Jeffreys estimate, ``(count + 1/2) / (samples +
    m/2)``), so that a state the prior reaches rarely is never estimated as impossible: dividing
    by a zero would make :func:`combine_posteriors` rule it out. Its standard error is about
    ``sqrt(P (1 - P) / samples)`` (2e-4 at P = 0.01 with the default samples).

    >>> q = prior_state_distribution("world", samples=20_000)
    >>> q.shape, bool(np.isclose(q.sum(), 1.0)), bool(q.min() > 0)
    ((20,), True, True)
    """
    pr = _priors.get(prior)
    part = _partitions.get(partition)
    n_cameras = positive_int("n_cameras", n_cameras, minimum=0)
    point = positive_int("point", point, minimum=0)
    if point > n_cameras:
        raise ValueError(f"point: expected 0 (C) .. n_cameras = {n_cameras}, got {point}")
    samples = positive_int("samples", samples)
    rng = as_rng(seed)
    m = part.n_states
    counts = np.zeros(m)
    step = 50_000
    for i in range(0, samples, step):
        x = pr.sample(rng, n_cameras, min(step, samples - i))[:, point]
        s = part.state_of(x)
        counts += np.bincount(s[s >= 0], minlength=m)[:m]
    q = counts + 0.5
    return q / q.sum()
