"""Metric evidence of configuration inference (:mod:`qfg.configurations`): one triplet's solver
posterior over C's AB-frame position as a compact likelihood ratio (:class:`PositionSummary`,
:func:`summarize_position`), several passes of one ordered triplet as one summary
(:func:`combine_positions`), and the world prior's state distribution that every estimate is
divided by (:func:`prior_states`).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .. import partitions as _partitions
from .. import priors as _priors
from .._validate import as_float_array, as_rng, non_negative, positive_int

__all__ = ["PositionSummary", "summarize_position", "combine_positions", "prior_states",
           "PRIOR_STATE_SAMPLES", "LOW_ESS"]

#: Samples behind the prior's state distribution (:func:`prior_states`).
PRIOR_STATE_SAMPLES = 200_000

#: A position summary made from fewer effective samples than this is flagged ``low_ess``.
LOW_ESS = 30.0


# --------------------------------------------------------------------------- prior
def _world_prior(prior, whole_map: bool = False) -> _priors.WorldBoxPrior:
    """The world prior of ``prior``; ``whole_map``: for inference over whole landmark
    configurations, drawn i.i.d. in the box (a pair-scale prior, ``scale_power`` != 0, describes
    one triplet's frame only: per-triplet summaries and state distributions take it)."""
    try:
        pr = _priors.get(prior)
    except ValueError as exc:
        raise ValueError(f"prior: {exc}") from None
    if not isinstance(pr, _priors.WorldBoxPrior):
        raise ValueError(f"prior: configuration inference samples world configurations and needs "
                         f"a world prior (qfg.priors.WorldBoxPrior or 'world'), got {pr!r}")
    if whole_map and pr.scale_power:
        raise ValueError(f"prior: configuration inference draws every landmark i.i.d. in the box; "
                         f"a pair-scale prior (scale_power={pr.scale_power}) describes one "
                         f"triplet's frame, not a whole map: give scale_power=0")
    return pr


@functools.lru_cache(maxsize=16)
def _prior_states_cached(key, partition_name):
    pr, _ = key
    from ..combine import prior_state_distribution

    q = prior_state_distribution(pr, partition_name, samples=PRIOR_STATE_SAMPLES, seed=0)
    q.setflags(write=False)
    return q


def prior_states(prior="world", partition="edc") -> np.ndarray:
    """(m,) state distribution of C under ``prior`` (the one a solver's posterior divides by):
    :func:`qfg.combine.prior_state_distribution` with :data:`PRIOR_STATE_SAMPLES` draws, seed 0,
    cached per (prior, partition).

    >>> prior_states("world", "lr").round(2).tolist()
    [0.5, 0.5]
    """
    pr = _world_prior(prior)
    part = _partitions.get(partition)
    return _prior_states_cached((pr, repr(pr)), part.name)


# --------------------------------------------------------------------------- metric evidence
@dataclass(frozen=True, eq=False)
class PositionSummary:
    """Compact, serialisable summary of one triplet's solver posterior over C's AB-frame position.

    The likelihood ratio ``r(c) = p(c | H) / prior(c)`` is represented by a kernel mixture

        r(c) = sum_j exp(log_weights[j]) N(c; centres[j], bandwidth),

    ``log_weights[j] = log(1 / K) - log prior(centres[j])``: equal-weight centres drawn from the
    solver's weighted sample, each divided by the prior density at its centre (the prior varies
    little over one kernel). Its mean under the prior is about 1.

    Attributes:
        states: (m,) the solver's state distribution P(s | H) (the estimate's ``landmark``).
        centres: (K, 2) AB-frame positions (|AB| = 1); K = 0 when the solver kept no sample.
        log_weights: (K,) natural-log weights, as above.
        bandwidth: (2, 2) covariance of every kernel.
        ess: effective sample size of the solver's weights.
        low_ess: True when ``ess`` < :data:`LOW_ESS` (the summary's tails are unreliable: the
            likelihood mixes in more of the state likelihood) or K = 0.
        partition, prior: names the states and the prior refer to.

    >>> s = PositionSummary.from_dict(PositionSummary(np.full(2, 0.5), np.zeros((1, 2)), [0.0],
    ...                                               np.eye(2), 100.0, False, "lr", "world"
    ...                                               ).to_dict())
    >>> s.centres.shape, s.low_ess
    ((1, 2), False)
    """

    states: np.ndarray
    centres: np.ndarray
    log_weights: np.ndarray
    bandwidth: np.ndarray
    ess: float
    low_ess: bool
    partition: str
    prior: str

    def __post_init__(self):
        st = as_float_array("states", self.states, ndim=1)
        c = as_float_array("centres", self.centres).reshape(-1, 2)
        lw = as_float_array("log_weights", self.log_weights).reshape(-1)
        bw = as_float_array("bandwidth", self.bandwidth)
        if lw.shape[0] != c.shape[0]:
            raise ValueError(f"log_weights: {lw.shape[0]} weights for {c.shape[0]} centres")
        if bw.shape != (2, 2) or not np.all(np.linalg.eigvalsh(0.5 * (bw + bw.T)) > 0):
            raise ValueError(f"bandwidth: expected a (2, 2) positive-definite covariance, got {bw}")
        if np.any(st < 0) or abs(st.sum() - 1) > 1e-6:
            raise ValueError("states: expected a probability vector (non-negative, sum 1)")
        for name, v in (("states", st), ("centres", c), ("log_weights", lw), ("bandwidth", bw)):
            v = np.array(v)
            v.setflags(write=False)
            object.__setattr__(self, name, v)
        object.__setattr__(self, "ess", float(self.ess))
        object.__setattr__(self, "low_ess", bool(self.low_ess))

    def ratio(self, points) -> np.ndarray:
        """``r(c)`` at AB-frame points (..., 2) -> (...)."""
        p = as_float_array("points", points, last_dim=2)
        if self.centres.shape[0] == 0:
            return np.ones(p.shape[:-1])
        lin, lnorm = _chol_inverse(self.bandwidth[None])
        out = _log_mixture(p.reshape(1, -1, 2), self.centres[None], self.log_weights[None],
                           lin, lnorm)
        return np.exp(out).reshape(p.shape[:-1])

    def to_dict(self) -> dict:
        """Plain lists and numbers (JSON-serialisable); :meth:`from_dict` inverts it."""
        return {"states": self.states.tolist(), "centres": self.centres.tolist(),
                "log_weights": self.log_weights.tolist(), "bandwidth": self.bandwidth.tolist(),
                "ess": self.ess, "low_ess": self.low_ess, "partition": self.partition,
                "prior": self.prior}

    @classmethod
    def from_dict(cls, d: Mapping) -> "PositionSummary":
        try:
            return cls(**{k: d[k] for k in ("states", "centres", "log_weights", "bandwidth",
                                            "ess", "low_ess", "partition", "prior")})
        except KeyError as exc:
            raise ValueError(f"d: missing key {exc.args[0]!r} of a PositionSummary") from None


def _chol_inverse(cov):
    """(T, 2, 2) covariances -> (T, 2, 2) inverse Cholesky factors and (T,) log normalizers."""
    L = np.linalg.cholesky(cov)
    Li = np.linalg.inv(L)
    lnorm = -np.log(2 * np.pi) - np.log(L[:, 0, 0] * L[:, 1, 1])
    return Li, lnorm


def _log_mixture(c, centres, log_w, lin, lnorm):
    """log sum_j w_j N(c; mu_j, H) for points c (T, P, 2), per-term centres (T, K, 2), log
    weights (T, K), inverse Cholesky (T, 2, 2) and log normalizers (T,) -> (T, P).

    Summed without a max shift: the log weights are moderate (-log K - log prior), so the terms
    cannot overflow, and a sum that underflows to 0 is a ratio the floor makes irrelevant."""
    d0 = c[:, :, None, 0] - centres[:, None, :, 0]                        # (T, P, K)
    d1 = c[:, :, None, 1] - centres[:, None, :, 1]
    z1 = lin[:, None, None, 1, 0] * d0
    z1 += lin[:, None, None, 1, 1] * d1
    d0 *= lin[:, None, None, 0, 0]
    d0 *= d0
    z1 *= z1
    d0 += z1
    d0 *= -0.5
    d0 += log_w[:, None, :]
    np.exp(d0, out=d0)
    with np.errstate(divide="ignore"):
        return np.log(d0.sum(axis=-1)) + lnorm[:, None]


def summarize_position(hypotheses, states=None, prior="world", *, partition="edc",
                       n_components: int = 32, bandwidth_scale: float = 1.0,
                       seed=0) -> PositionSummary:
    """A :class:`PositionSummary` from a solver's weighted samples of C.

    ``hypotheses``: a :class:`qfg.solvers.Hypotheses` (``TripletSolver.hypotheses()``) or a pair
    ``(samples (J, 2), weights (J,))`` of AB-frame positions and non-negative weights;
    ``states``: (m,) the estimate's state distribution (default: the weighted states of the
    samples). ``n_components`` centres are drawn by systematic resampling (``seed``); the kernel
    covariance is ``(bandwidth_scale h)^2 Σ`` with Σ the weighted covariance of the sample and
    ``h = min(ess, K)^(-1/6)`` (Scott's factor in 2-D: fewer effective samples, wider kernels).

    >>> rng = np.random.default_rng(0)
    >>> xy = rng.normal([0.5, 2.0], 0.1, size=(500, 2))
    >>> s = summarize_position((xy, np.full(500, 1 / 500)), prior="world")
    >>> s.centres.shape, s.low_ess, int(np.argmax(s.states))
    ((32, 2), False, 1)
    """
    pr = _world_prior(prior)
    part = _partitions.get(partition)
    if hasattr(hypotheses, "landmark_samples"):
        xy, w = hypotheses.landmark_samples, hypotheses.landmark_weights
    else:
        try:
            xy, w = hypotheses
        except (TypeError, ValueError):
            raise ValueError("hypotheses: expected a qfg.solvers.Hypotheses or a pair (samples "
                             "(J, 2), weights (J,))") from None
    xy = as_float_array("hypotheses", xy).reshape(-1, 2)
    w = as_float_array("weights", w).reshape(-1)
    if w.shape[0] != xy.shape[0] or np.any(w < 0):
        raise ValueError(f"weights: expected {xy.shape[0]} non-negative weights, got {w.shape}")
    K = positive_int("n_components", n_components)
    bscale = non_negative("bandwidth_scale", bandwidth_scale)
    if bscale == 0:
        raise ValueError("bandwidth_scale: expected a number > 0, got 0")
    m = part.n_states
    tot = w.sum()
    if states is None:
        if not tot > 0:
            raise ValueError("states: required when the samples carry no weight")
        states = np.bincount(part.state_of(xy), weights=w, minlength=m)[:m] / tot
    st = as_float_array("states", states, ndim=1)
    if st.shape != (m,):
        raise ValueError(f"states: expected shape ({m},) for partition {part.name!r}, "
                         f"got {st.shape}")
    if not tot > 0:
        return PositionSummary(st, np.zeros((0, 2)), np.zeros(0), np.eye(2), 0.0, True,
                               part.name, pr.name)
    w = w / tot
    ess = 1.0 / float(np.sum(w * w))
    rng = as_rng(seed)
    cdf = np.cumsum(w)
    cdf[-1] = 1.0
    idx = np.searchsorted(cdf, (rng.random() + np.arange(K)) / K, side="left")
    centres = xy[np.minimum(idx, xy.shape[0] - 1)]
    mu = w @ xy
    d = xy - mu
    cov = (d * w[:, None]).T @ d
    # a floor on the covariance: a sample of one point (or on a line) still gets a kernel
    scale2 = max(float(np.trace(cov)), float(np.sum(mu * mu)) * 1e-6, 1e-8)
    cov = cov + 1e-4 * scale2 * np.eye(2)
    h = min(ess, float(K)) ** (-1.0 / 6.0) * bscale
    logp = pr.log_density(centres[:, None, :])
    # a centre the prior rules out (it cannot be: the solver's weights include the prior) gets no
    # weight rather than an infinite one
    logw = np.where(np.isfinite(logp), -np.log(K) - np.where(np.isfinite(logp), logp, 0.0),
                    -np.inf)
    keep = np.isfinite(logw)
    return PositionSummary(st, centres[keep], logw[keep], h * h * cov, ess,
                           ess < LOW_ESS or not keep.any(), part.name, pr.name)


def combine_positions(summaries, prior="world", *, temper: float = 1.0, states=None,
                      n_points: int = 4000, n_components: int = 32, seed=0) -> PositionSummary:
    """One :class:`PositionSummary` for independent measurements of the same ordered triplet
    (several passes, each solved alone under the same prior): their likelihood ratios multiply,

        p(c | H_1..H_k)  ∝  prior(c) prod_h r_h(c)^temper,

    with ``r_h`` each summary's :meth:`PositionSummary.ratio` and ``temper`` the power the
    passes' agreement chose (``qfg mrclam --temper``; 1: none). The product is sampled by
    importance sampling: ``n_points`` draws from the summaries' kernel mixtures with every
    kernel's covariance doubled (each pass's posterior, widened, so that the product's region is
    covered when the passes agree), weighted by the target over that proposal, then summarized
    by :func:`summarize_position`. The result's ``ess`` is the least of the passes' and of these
    weights', so that the product of poorly sampled passes, or of passes that disagree (little
    overlap: few draws carry the weight), is flagged ``low_ess`` and read with more of the state
    likelihood. ``states``: (m,) the combined state distribution (default: the weighted states
    of the draws). One summary and ``temper`` 1: that summary (``states`` replaced if given).

    >>> rng = np.random.default_rng(0)
    >>> a = summarize_position((rng.normal([0.5, 2.0], 0.2, (400, 2)), np.ones(400)), seed=1)
    >>> b = summarize_position((rng.normal([0.7, 2.0], 0.2, (400, 2)), np.ones(400)), seed=2)
    >>> ab = combine_positions([a, b], seed=3)
    >>> bool(0.5 < ab.centres[:, 0].mean() < 0.7), ab.low_ess
    (True, False)
    """
    summ = list(summaries) if not isinstance(summaries, PositionSummary) else [summaries]
    if not summ or not all(isinstance(s, PositionSummary) for s in summ):
        raise ValueError("summaries: expected one or more PositionSummary objects")
    pr = _world_prior(prior)
    part = _partitions.get(summ[0].partition)
    for s in summ:
        if s.partition != part.name or s.prior != pr.name:
            raise ValueError(f"summaries: a summary for partition {s.partition!r} and prior "
                             f"{s.prior!r}, expected {part.name!r} and {pr.name!r}")
    tau = non_negative("temper", temper)
    if states is not None:
        st = as_float_array("states", states, ndim=1)
        if st.shape != (part.n_states,):
            raise ValueError(f"states: expected shape ({part.n_states},), got {st.shape}")
        st = st / st.sum()
    if len(summ) == 1 and tau == 1.0:
        s = summ[0]
        return s if states is None else PositionSummary(
            st, s.centres, s.log_weights, s.bandwidth, s.ess, s.low_ess, s.partition, s.prior)
    live = [s for s in summ if s.centres.shape[0] > 0]
    if not live:   # no pass kept a sample: the states alone
        return PositionSummary(summ[0].states if states is None else st, np.zeros((0, 2)),
                               np.zeros(0), np.eye(2), 0.0, True, part.name, pr.name)
    n = positive_int("n_points", n_points)
    rng = as_rng(seed)
    # proposal: an equal mixture over passes, each its centres with doubled kernels
    comp = np.concatenate([np.full(s.centres.shape[0], i) for i, s in enumerate(live)])
    cen = np.concatenate([s.centres for s in live])
    share = np.concatenate([np.full(s.centres.shape[0], 1.0 / (len(live) * s.centres.shape[0]))
                            for s in live])
    pick = rng.choice(cen.shape[0], size=n, p=share / share.sum())
    L2 = np.stack([np.linalg.cholesky(2.0 * s.bandwidth) for s in live])
    pts = cen[pick] + np.einsum("nij,nj->ni", L2[comp[pick]], rng.standard_normal((n, 2)))
    log_g = np.full(n, -np.inf)
    for s in live:
        lin, lnorm = _chol_inverse(2.0 * s.bandwidth[None])
        lg = _log_mixture(pts[None], s.centres[None],
                          np.full((1, s.centres.shape[0]), -np.log(s.centres.shape[0])),
                          lin, lnorm)[0] - np.log(len(live))
        log_g = np.logaddexp(log_g, lg)
    log_t = pr.log_density(pts[:, None, :])
    for s in live:
        lin, lnorm = _chol_inverse(s.bandwidth[None])
        log_t = log_t + tau * _log_mixture(pts[None], s.centres[None], s.log_weights[None],
                                           lin, lnorm)[0]
    ok = np.isfinite(log_t) & np.isfinite(log_g)
    lw = np.where(ok, log_t - np.where(ok, log_g, 0.0), -np.inf)
    if not np.isfinite(lw).any():   # the passes share no region at all
        return PositionSummary(live[0].states if states is None else st, np.zeros((0, 2)),
                               np.zeros(0), np.eye(2), 0.0, True, part.name, pr.name)
    w = np.exp(lw - lw.max())
    out = summarize_position((pts, w), None if states is None else st, pr,
                             partition=part.name, n_components=n_components, seed=rng)
    ess = min([out.ess] + [s.ess for s in summ])
    return PositionSummary(out.states, out.centres, out.log_weights, out.bandwidth, ess,
                           out.low_ess or ess < LOW_ESS, part.name, pr.name)
