"""The solvers' answer: :class:`TripletEstimate`, the :class:`Hypotheses` behind it, and
how every solver builds them (shrinkage toward the uniform, the flagged uniform answer).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .degenerate import UNRESOLVED_REASON, UNRESOLVED_SHARE
from .diagnostics import pareto_k


@dataclass(frozen=True, eq=False, repr=False)
class TripletEstimate:
    """Qualitative estimate of one triplet AB:C from its history: the answer only (a few KB).

    Attributes:
        landmark: (m,) P(S^{AB:C} = s | H), sums to 1.
        cameras: (n, m) P(S^{AB:X}_i = s | H) for every view i, each row sums to 1.
        n_hypotheses: number of weighted hypotheses behind the estimate (trajectory hypotheses
            for ``full``/``fast``, landmark candidates with non-zero weight for ``baseline``).
        ess: effective sample size of the landmark weights, ``1 / sum w^2`` (normalized w).
        mc_error: Monte Carlo standard error of ``landmark`` where the method estimates it
            (largest over states), else NaN.
        pareto_k: Pareto k-hat of the landmark weights' upper tail
            (:func:`qfg.solvers.common.diagnostics.pareto_k`; above about 0.7 the weighted answer is
            unreliable whatever the ESS), NaN where the weights are not importance weights
            (``fast-paper``'s quadrature, the reference) or too few.
        model_check: posterior predictive p-value of the bearings and headings
            (:mod:`qfg.solvers.sis.model_check`; small: the measurements contradict the model),
            NaN where the method does not compute it (without headings, noiseless, the
            methods other than ``full`` and ``fast``).
        depth_unresolved: share of the final weight on hypotheses whose C depth along the lines
            of sight is unresolved (``full`` and ``fast`` from 2 views; NaN elsewhere); above
            ``common.degenerate.UNRESOLVED_SHARE`` the answer is flagged.
        log_evidence: log p(measurements) under the model and the prior, angles in radians
            (``reference`` only, NaN elsewhere): the marginal likelihood that compares priors
            or noise models on the same measurements (the larger, the better they explain
            them; differences of a few tenths are within its Monte Carlo error).
        degenerate: True when the input was degenerate or nothing survived; the distributions are
            then as spread as the geometry allows, uniform wherever nothing is known (never NaN).
        reason: why ``degenerate`` is set ("" otherwise).
        method: the model actually solved (``"full"``, ``"fast"``, ``"baseline"``, ...).
        partition: partition name the states refer to.
        n_views: number of views n.
        prior: name of the prior over AB-frame configurations.
        options: the solver options used (defaults filled in; the prior by name).

    The weighted hypotheses behind an estimate (for figures) are kept by the solver object,
    :meth:`qfg.solvers.TripletSolver.hypotheses`, not here.

    >>> import numpy as np
    >>> from qfg.simulation import random_triplet_history
    >>> from qfg.solvers import solve_triplet
    >>> h = random_triplet_history(np.random.default_rng(0), n_views=3)
    >>> est = solve_triplet(h, method="fast")
    >>> est.landmark.shape, est.cameras.shape, bool(np.isclose(est.landmark.sum(), 1.0))
    ((20,), (3, 20), True)
    """

    landmark: np.ndarray
    cameras: np.ndarray
    n_hypotheses: int
    degenerate: bool
    reason: str
    method: str
    partition: str
    n_views: int
    ess: float = float("nan")
    mc_error: float = float("nan")
    pareto_k: float = float("nan")
    model_check: float = float("nan")
    depth_unresolved: float = float("nan")
    log_evidence: float = float("nan")
    prior: str = ""
    options: dict = field(default_factory=dict)

    @property
    def most_likely(self) -> tuple[int, float]:
        """(0-based state, probability) of the most probable landmark state."""
        s = int(np.argmax(self.landmark))
        return s, float(self.landmark[s])

    def __repr__(self) -> str:
        s, p = self.most_likely
        flag = f", degenerate: {self.reason}" if self.degenerate else ""
        return (f"TripletEstimate(method={self.method!r}, partition={self.partition!r}, "
                f"n_views={self.n_views}, prior={self.prior!r}, most_likely=({s}, {p:.3f}), "
                f"n_hypotheses={self.n_hypotheses}, ess={self.ess:.1f}{flag})")

    def add_view(self, bearings, heading=None):
        """Not here: an estimate holds only the answer. Raises ValueError naming the
        replacement, :class:`qfg.solvers.TripletSolver`."""
        raise ValueError(ADD_VIEW_MOVED)


#: Message of the former estimate-based incremental API.
ADD_VIEW_MOVED = ("estimate: a TripletEstimate holds only the answer and cannot be updated; solve "
                  "incrementally with qfg.solvers.TripletSolver(method=..., sigma_bearing=..., "
                  "sigma_heading=..., seed=...).add_view(bearings, heading) and .estimate()")


@dataclass(frozen=True, eq=False, repr=False)
class Hypotheses:
    """The weighted hypotheses behind an estimate (for figures and diagnostics).

    Attributes:
        landmark_samples: (J, 2) AB-frame positions of C behind ``landmark``.
        landmark_weights: (J,) normalized weights (sum 1, or all 0 when J = 0).
        camera_samples: (n, K, 3) AB-frame camera poses (x, y, alpha).
        camera_weights: (n, K) their normalized weights per view.
        joint: True when hypothesis j is the trajectory ``camera_samples[:, j]`` with landmark
            ``landmark_samples[j]``.
    """

    landmark_samples: np.ndarray
    landmark_weights: np.ndarray
    camera_samples: np.ndarray
    camera_weights: np.ndarray
    joint: bool

    def __repr__(self) -> str:
        return (f"Hypotheses(landmark_samples={self.landmark_samples.shape}, "
                f"camera_samples={self.camera_samples.shape}, joint={self.joint})")


class TripletBatchSizes:
    """Sizes of a solver state holding ``bearings`` (T, i, 3): T triplets after i views."""

    @property
    def n_triplets(self) -> int:
        return self.bearings.shape[0]

    @property
    def n_views(self) -> int:
        return self.bearings.shape[1]


def ess(weights) -> float:
    """Effective sample size ``1 / sum w^2`` of normalized weights (0 when all are 0)."""
    w = np.asarray(weights, dtype=float)
    s2 = float(np.sum(w * w))
    return 1.0 / s2 if s2 > 0 else 0.0


def prior_name(opts) -> str:
    p = opts.get("prior", "")
    return p if isinstance(p, str) else getattr(p, "name", type(p).__name__)


def public_options(opts) -> dict:
    """Options as an estimate reports them: plain values, the prior by name."""
    out = dict(opts)
    if "prior" in out:
        out["prior"] = prior_name(opts)
    return out


def shrink_to_uniform(p, n_eff, alpha):
    """State probabilities estimated from ``n_eff`` effective posterior draws, shrunk toward the
    uniform distribution by ``alpha`` pseudo-draws: ``(n_eff p + alpha / m) / (n_eff + alpha)``.

    This is the posterior mean of a state distribution under a symmetric Dirichlet(alpha / m)
    prior after observing ``n_eff p`` draws in each state: a Monte Carlo estimate from a handful
    of effective draws cannot support probabilities near 0 or 1, and the shrinkage keeps it from
    claiming them (``p`` (..., m); the rows still sum to 1). ``alpha = 0`` returns ``p``.

    >>> shrink_to_uniform(np.array([1.0, 0.0, 0.0, 0.0]), 3.0, 1.0).round(4).tolist()
    [0.8125, 0.0625, 0.0625, 0.0625]
    """
    p = np.asarray(p, dtype=float)
    if alpha <= 0 or not np.isfinite(n_eff):
        return p
    m = p.shape[-1]
    return (n_eff * p + alpha / m) / (n_eff + alpha)


def ess_reason(e: float, min_ess: float) -> str:
    """The flag of an answer whose final weights have an ESS ``e`` below ``min_ess``."""
    return (f"effective sample size {e:.1f} < {min_ess:g}: the answer rests on too few "
            "effective draws")


def pooled_reasons(ests, weights, ess: float, opts: dict) -> list[str]:
    """The flags of an answer pooled from several solves of one triplet (independent
    populations, an escalated solve) with ``weights`` (summing to 1) and pooled ESS ``ess``.
    Flags read off the measurements are the same in every solve and kept; the two read off a
    solve's samples are decided again for the pool, because the union of noisy per-solve tests
    would flag more often the more solves there are: C's depth unresolved by the weighted mean
    of the solves' shares (``depth_unresolved``), and the ESS by the pooled one."""
    w = np.asarray(weights, dtype=float)
    share = np.array([e.depth_unresolved for e in ests], dtype=float)
    known = np.isfinite(share)
    out = []
    for e in ests:
        for r in e.reason.split("; ") if e.reason else []:
            sampled = r.startswith("effective sample size") or (r == UNRESOLVED_REASON
                                                                 and known.all())
            if not sampled and r not in out:
                out.append(r)
    if known.all() and float(np.sum(w * share)) > UNRESOLVED_SHARE and \
            not any("coincide" in r for r in out):
        out.append(UNRESOLVED_REASON)
    if "min_ess" in opts and ess < opts["min_ess"]:
        out.append(ess_reason(ess, opts["min_ess"]))
    return out


def pool(pairs, weights, opts: dict, *, error_floor: float = float("nan"),
         extra_reasons=()):
    """One ``(estimate, hypotheses)`` pair from several solves of one triplet (independent
    populations, an escalated solve), mixed with ``weights`` (summing to 1): the distributions
    ``sum_k w_k e_k``; the ESS of the pooled weights ``1 / sum_k (w_k^2 / ess_k)`` (0 if a
    solve has none); ``mc_error`` ``sqrt(sum_k (w_k mc_k)^2)``, at least ``error_floor`` (e.g.
    the spread between the solves); the largest ``pareto_k``; the weighted mean of the finite
    model-check p-values and of ``depth_unresolved``; ``n_hypotheses`` the sum; the flags of
    :func:`pooled_reasons` and ``extra_reasons``; the hypotheses of every solve with their
    weights scaled by ``w_k`` (None when a solve kept none). ``opts``: the caller's options,
    recorded in the estimate."""
    ests = [e for e, _ in pairs]
    w = np.asarray(weights, dtype=float)
    landmark = np.einsum("k,km->m", w, np.stack([e.landmark for e in ests]))
    cameras = np.einsum("k,knm->nm", w, np.stack([e.cameras for e in ests]))
    es = np.array([e.ess for e in ests], dtype=float)
    ess = float(1.0 / np.sum(w * w / es)) if np.all(es > 0) else 0.0
    within = float(np.sqrt(np.sum((w * np.array([e.mc_error for e in ests])) ** 2)))
    mc_error = within if np.isnan(error_floor) else (
        float(error_floor) if np.isnan(within) else max(float(error_floor), within))
    pk = np.array([e.pareto_k for e in ests], dtype=float)
    checks = np.array([e.model_check for e in ests], dtype=float)
    fin = np.isfinite(checks)
    reasons = pooled_reasons(ests, w, ess, opts) + list(extra_reasons)
    est = dataclasses.replace(
        ests[0], landmark=landmark / landmark.sum(),
        cameras=cameras / cameras.sum(axis=1, keepdims=True),
        n_hypotheses=int(sum(e.n_hypotheses for e in ests)), degenerate=bool(reasons),
        reason="; ".join(reasons), ess=ess, mc_error=mc_error,
        pareto_k=float(np.nanmax(pk)) if np.any(np.isfinite(pk)) else float("nan"),
        model_check=float(np.sum(w[fin] * checks[fin]) / w[fin].sum()) if fin.any()
        else float("nan"),
        depth_unresolved=float(np.sum(w * np.array([e.depth_unresolved for e in ests]))),
        options=public_options(opts))
    hyps = [h for _, h in pairs]
    if any(h is None for h in hyps):
        return est, None
    return est, Hypotheses(
        landmark_samples=np.concatenate([h.landmark_samples for h in hyps]),
        landmark_weights=np.concatenate([wk * h.landmark_weights for wk, h in zip(w, hyps, strict=True)]),
        camera_samples=np.concatenate([h.camera_samples for h in hyps], axis=1),
        camera_weights=np.concatenate([wk * h.camera_weights for wk, h in zip(w, hyps, strict=True)],
                                      axis=1),
        joint=all(h.joint for h in hyps))


def make_estimate(method, part, n_views, landmark, cameras, *, hypotheses: Hypotheses,
                  reasons=(), mc_error=float("nan"), model_check=float("nan"), widen=None,
                  depth_unresolved=float("nan"), opts) -> tuple[TripletEstimate, Hypotheses]:
    """The (answer, hypotheses) pair every solver's ``finish`` returns. With the option
    ``mc_shrinkage`` = alpha > 0 the landmark and camera distributions are shrunk toward the
    uniform by alpha pseudo-draws against the final sample's ESS (:func:`shrink_to_uniform`);
    with the option ``min_ess``, an answer whose ESS is smaller is flagged (a failed sampler).
    ``widen`` = (lam, q_landmark (m,), q_camera (m,)): the answer (after the shrinkage) mixed
    with those state distributions by the share lam (a failed model check,
    :mod:`.model_check`)."""
    lw = hypotheses.landmark_weights
    e = ess(lw)
    if "min_ess" in opts and e < opts["min_ess"]:
        reasons = tuple(reasons) + (ess_reason(e, opts["min_ess"]),)
    a = float(opts.get("mc_shrinkage", 0.0) or 0.0)
    landmark = shrink_to_uniform(landmark, e, a)
    cameras = shrink_to_uniform(cameras, e, a)
    if widen is not None and widen[0] > 0:
        lam, q_l, q_x = widen
        landmark = (1.0 - lam) * np.asarray(landmark) + lam * np.asarray(q_l)
        cameras = (1.0 - lam) * np.asarray(cameras) + lam * np.asarray(q_x)[None, :]
    k = float("nan")
    if method != "fast-paper":
        with np.errstate(divide="ignore"):
            k = pareto_k(np.log(np.asarray(lw, dtype=float)))
    est = TripletEstimate(
        landmark=np.asarray(landmark, dtype=float), cameras=np.asarray(cameras, dtype=float),
        n_hypotheses=int(np.count_nonzero(lw > 0)), degenerate=bool(reasons),
        reason="; ".join(reasons), method=method, partition=part.name, n_views=int(n_views),
        ess=e, mc_error=float(mc_error), pareto_k=k, model_check=float(model_check),
        depth_unresolved=float(depth_unresolved), prior=prior_name(opts),
        options=public_options(opts))
    return est, hypotheses


def empty_hypotheses(n_views) -> Hypotheses:
    return Hypotheses(landmark_samples=np.zeros((0, 2)), landmark_weights=np.zeros(0),
                      camera_samples=np.zeros((n_views, 0, 3)),
                      camera_weights=np.zeros((n_views, 0)), joint=False)


def uniform_estimate(method, part, n_views, reason, opts) -> tuple[TripletEstimate, Hypotheses]:
    m = part.n_states
    return make_estimate(method, part, n_views, np.full(m, 1.0 / m),
                         np.full((n_views, m), 1.0 / m), hypotheses=empty_hypotheses(n_views),
                         reasons=(reason,), opts=opts)
