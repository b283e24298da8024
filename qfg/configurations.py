"""Configuration inference: the marginals of every triplet, seen or not, by sampling whole landmark
configurations (issue 21).

A qualitative map's triplets are functions of one unknown: the world positions of its landmarks.
Instead of composing triplet states (the paper's composition factors, which treat states as
independent and lose what the positions within a state say), sample the configurations:

    pi(X)  ∝  prior(X) prod_{t seen} L_t(X),      X = (x_1..x_n) world positions,

with ``prior`` the world prior the single-triplet solvers used (:class:`qfg.priors.WorldBoxPrior`:
landmarks i.i.d. uniform in a box, pairwise at least ``d_min`` apart) and, for seen triplet
``t = AB:C`` with solver posterior ``P_t(s) = P(s | H_t)`` under that prior,

* state likelihood (``likelihood="state"``): ``L_t = (1 - eps) P_t(s_t) / q(s_t) + eps``, where
  ``s_t`` is C's state in the AB frame of X and ``q`` the state distribution of the same prior
  (:func:`qfg.combine.prior_state_distribution`): ``P_t / q`` is ``P(H_t | s)`` up to a constant,
  and its mean under the prior is 1, so the floor ``eps`` is a fraction of the prior: one wrong
  estimate multiplies the truth's weight by ``eps`` at worst instead of vetoing it;
* metric likelihood (``likelihood="metric"``): ``L_t = (1 - eps) [(1 - b) r_t(c_t) + b P_t(s_t) /
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

>>> import numpy as np
>>> post = infer_configurations({(0, 1, 2): np.eye(20)[1] * 0.9 + 0.005}, n_particles=400,
...                             seed=0)
>>> res = post.marginals([(0, 1, 2), (1, 0, 2)])
>>> int(np.argmax(res[(0, 1, 2)])), res.probabilities.shape
(1, (2, 20))
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from . import partitions as _partitions
from . import priors as _priors
from ._validate import as_float_array, as_rng, non_negative, positive_int

__all__ = ["PositionSummary", "summarize_position", "combine_positions", "ConfigurationPosterior",
           "infer_configurations", "configuration_marginals", "prior_states",
           "one_ordering_per_set", "LeaveOneOutCheck", "CHECK_GRID", "prior_mixing_weight", "LIKELIHOODS",
           "DEFAULTS", "NotSettledWarning", "UNSETTLED_ERROR", "UNSETTLED_SHARE"]

#: Likelihood kinds of :func:`infer_configurations`.
LIKELIHOODS = ("state", "metric")

#: Defaults of :func:`infer_configurations` (chosen on development seeds: docs/configurations.md).
DEFAULTS = {
    "n_particles": 2000, "n_groups": 4, "target_ess": 0.5, "n_sweeps": 2, "floor": 1e-2,
    "state_mix": 0.1, "low_ess_mix": 0.5, "pseudo_count": 2.0, "temper": None,
    "ess_prior": None, "block_moves": True,
}

#: ``temper=None``: the exponent of the state likelihoods per likelihood kind (seed 555: 0.6 gave
#: the state kind's best mean log score, seen and unseen; the metric kind is indifferent)
TEMPER = {"state": 0.6, "metric": 1.0}

#: ``ess_prior=None``: the pseudo-draws ``a`` of the prior with which an estimate made from ``n``
#: effective samples is read, ``(n P + a q) / (n + a)``, per likelihood kind (development seed 555,
#: fast-solver estimates, median ESS 15.5, 20 graphs: best mean log score over seen and unseen
#: triplets at a = 3 of {0, 1, 3, 10} for the state kind, a = 10 for the metric kind; an estimate
#: without an ESS is taken as exact)
ESS_PRIOR = {"state": 3.0, "metric": 10.0}

#: Samples behind the prior's state distribution (:func:`prior_states`).
PRIOR_STATE_SAMPLES = 200_000

#: A row of :meth:`ConfigurationPosterior.marginals` is *unsettled* when its largest Monte Carlo
#: error (the spread of the populations' answers) is above this: the ``widen`` of the MRCLAM
#: maps, i.e. the rows that widening replaces by the prior's states there. (Small maps at the
#: default budget have errors of 0.01-0.04.)
UNSETTLED_ERROR = 0.05
#: Share of unsettled rows above which :meth:`ConfigurationPosterior.marginals` warns
#: (:class:`NotSettledWarning`). MRCLAM's chains of landmarks (datasets 1 and 2) leave a
#: quarter to four fifths of the map's rows more than half widened even under correct evidence
#: (docs/configurations.md, "How strong the seen evidence must be").
UNSETTLED_SHARE = 0.25


class NotSettledWarning(UserWarning):
    """The sampler's populations disagree on many rows of the marginals: their answers there are
    one population's guess (or, with ``widen``, mostly the prior's states)."""

#: A position summary made from fewer effective samples than this is flagged ``low_ess``.
LOW_ESS = 30.0

#: Elements (particles x triplets) per block when the states of many triplets are looked up.
_CHUNK = 1 << 21


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
    from .combine import prior_state_distribution

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


# --------------------------------------------------------------------------- evidence
def one_ordering_per_set(evidence) -> dict:
    """One estimate per landmark set: of the seen orderings of ``{i, j, k}`` (in ``evidence``, a
    mapping ``{triplet: estimate}``), the first in sorted order. The orderings of one set are
    solved from the same views, so they are one piece of evidence; the configuration model takes
    its evidence as independent and would count it up to six times.

    >>> one_ordering_per_set({(1, 0, 2): "a", (0, 2, 1): "b", (2, 3, 4): "c"})
    {(0, 2, 1): 'b', (2, 3, 4): 'c'}
    """
    out, sets = {}, set()
    for t in sorted(evidence):
        key = frozenset(t)
        if key not in sets:
            sets.add(key)
            out[t] = evidence[t]
    return out


def _as_triplet(t, name="triplet"):
    try:
        tt = tuple(int(x) for x in t)
        ok = len(tt) == 3 and all(float(a) == float(b) for a, b in zip(tt, t, strict=True))
    except (TypeError, ValueError):
        ok = False
    if not ok or len(set(tt)) != 3 or min(tt) < 0:
        raise ValueError(f"{name}: expected three distinct non-negative landmark ids, got {t!r}")
    return tt


def _evidence_items(evidence, part, pr, likelihood, ess=None):
    """{triplet: (states (m,), PositionSummary or None, ess)} from a graph or a mapping, checked.

    ``ess``: the effective sample size behind each estimate, from ``ess`` ({triplet: number})
    where given, else the estimate's own (``TripletEstimate.ess``, ``PositionSummary.ess``), else
    inf (a plain vector: taken as exact)."""
    if hasattr(evidence, "triplets") and hasattr(evidence, "priors"):
        gpart = getattr(evidence, "partition", None)
        if gpart is not None and gpart != part.name:
            raise ValueError(f"evidence: a {gpart!r} graph, but partition is {part.name!r}")
        items = {t: p for t, p in zip(evidence.triplets, evidence.priors, strict=True)
                 if p is not None}
    elif isinstance(evidence, Mapping):
        items = dict(evidence)
    else:
        raise ValueError("evidence: expected a QualitativeFactorGraph or a mapping {triplet: "
                         f"estimate}}, got {type(evidence).__name__}")
    m = part.n_states
    ess_given = {}
    if ess is not None:
        if not isinstance(ess, Mapping):
            raise ValueError(f"ess: expected a mapping {{triplet: effective sample size}}, got "
                             f"{type(ess).__name__}")
        for t, n in ess.items():
            tt = _as_triplet(t, "ess")
            try:
                n = float(n)
            except (TypeError, ValueError):
                n = float("nan")
            if not n > 0:
                raise ValueError(f"ess: triplet {tt}: expected a number > 0 (or inf), got {n!r}")
            ess_given[tt] = n
    out = {}
    for t, e in items.items():
        tt = _as_triplet(t, "evidence")
        summ = None
        n_eff = float(getattr(e, "ess", float("inf")))
        if np.isnan(n_eff):     # not reported: taken as exact
            n_eff = float("inf")
        elif not n_eff > 0:     # an estimate with no effective sample (degenerate): no weight
            n_eff = 0.0
        if isinstance(e, PositionSummary):
            summ, vec = e, e.states
            if e.partition != part.name or e.prior != pr.name:
                raise ValueError(f"evidence: triplet {tt}: a summary for partition "
                                 f"{e.partition!r} and prior {e.prior!r}, expected "
                                 f"{part.name!r} and {pr.name!r}")
        elif hasattr(e, "landmark") and not isinstance(e, np.ndarray):
            ep, epr = getattr(e, "partition", part.name), getattr(e, "prior", "") or pr.name
            if ep != part.name or epr != pr.name:
                raise ValueError(f"evidence: triplet {tt}: an estimate for partition {ep!r} and "
                                 f"prior {epr!r}, expected {part.name!r} and {pr.name!r} (the "
                                 "likelihood divides by the prior the solver used)")
            vec = e.landmark
        else:
            vec = e
        try:
            v = np.asarray(vec, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"evidence: triplet {tt}: expected an ({m},) probability vector, a "
                             f"TripletEstimate or a PositionSummary, got {type(e).__name__}"
                             ) from None
        if v.shape != (m,):
            raise ValueError(f"evidence: triplet {tt}: expected {m} state probabilities "
                             f"(partition {part.name!r}), got shape {v.shape}")
        if not np.all(np.isfinite(v)) or np.any(v < 0) or not v.sum() > 0:
            raise ValueError(f"evidence: triplet {tt}: expected non-negative finite "
                             "probabilities, not all zero")
        if likelihood == "metric" and summ is None:
            raise ValueError(f"evidence: triplet {tt}: likelihood='metric' needs a "
                             "PositionSummary (summarize_position) for every seen triplet")
        out[tt] = (v / v.sum(), summ if likelihood == "metric" else None,
                   ess_given.get(tt, n_eff))
    unknown = set(ess_given) - set(out)
    if unknown:
        raise ValueError(f"ess: triplet {sorted(unknown)[0]} has no evidence")
    return out


@dataclass
class _Terms:
    """The likelihood terms, one row per (triplet, evidence); kind 0 fixed, 1 incoming (tempered
    in, coefficient beta), 2 outgoing (replaced, coefficient 1 - beta)."""

    ijk: np.ndarray            # (T, 3) landmark indices
    logtab: np.ndarray         # (T, m) log state likelihood (floored)
    ratiotab: np.ndarray       # (T, m) P_t / q
    eps: np.ndarray            # (T,) the term's floor: floor, widened by the estimate's ESS
    metric: np.ndarray         # (T,) bool
    mix: np.ndarray            # (T,) b: weight of the state likelihood inside the metric one
    centres: np.ndarray        # (T, K, 2)
    logw: np.ndarray           # (T, K)
    lin: np.ndarray            # (T, 2, 2)
    lnorm: np.ndarray          # (T,)
    kind: np.ndarray           # (T,)
    triplets: list = field(default_factory=list)
    evidence: list = field(default_factory=list)

    def subset(self, keep):
        keep = np.asarray(keep)
        return _Terms(self.ijk[keep], self.logtab[keep], self.ratiotab[keep], self.eps[keep],
                      self.metric[keep],
                      self.mix[keep], self.centres[keep], self.logw[keep], self.lin[keep],
                      self.lnorm[keep], self.kind[keep],
                      [t for t, k in zip(self.triplets, keep, strict=True) if k] if keep.dtype
                      == bool else [self.triplets[i] for i in keep],
                      [e for e, k in zip(self.evidence, keep, strict=True) if k] if keep.dtype
                      == bool else [self.evidence[i] for i in keep])


def _make_terms(items, index, q, o, kind):
    from .combine import temper

    floor, state_mix, low_ess_mix, tau = (o["floor"], o["state_mix"], o["low_ess_mix"],
                                          float(o["temper"]))
    m = q.shape[0]
    T = len(items)
    K = max([s.centres.shape[0] for _, s, _ in items.values() if s is not None], default=1)
    K = max(K, 1)
    ijk = np.zeros((T, 3), dtype=np.intp)
    ratio = np.ones((T, m))
    metric = np.zeros(T, dtype=bool)
    mix = np.ones(T)
    centres = np.zeros((T, K, 2))
    logw = np.full((T, K), -np.inf)
    logw[:, 0] = 0.0
    lin = np.tile(np.eye(2), (T, 1, 1))
    lnorm = np.zeros(T)
    trips, evs = [], []
    a = float(o["ess_prior"])
    eps = np.full(T, float(floor))
    for r, (t, (v, s, n_eff)) in enumerate(items.items()):
        # an estimate from n_eff effective draws is a histogram of them: read as a Dirichlet
        # posterior mean with a draws of the prior, (n P + a q) / (n + a); its ratio to q is the
        # likelihood mixed with 1 (flat) at weight a / (n + a), which then adds to the floor
        w = a / (n_eff + a) if a > 0 else 0.0
        eps[r] = 1.0 - (1.0 - floor) * (1.0 - w)
        ijk[r] = [index[x] for x in t]
        # the state likelihood P_t / q, tempered (P_t / q)^tau (renormalized: mean 1 under q)
        ratio[r] = (v if tau == 1 else temper(v, q, tau)) / q
        if s is not None and s.centres.shape[0] > 0:
            k = s.centres.shape[0]
            metric[r] = True
            mix[r] = low_ess_mix if s.low_ess else state_mix
            centres[r, :k] = s.centres
            logw[r, :k] = s.log_weights
            logw[r, k:] = -np.inf
            li, ln = _chol_inverse(s.bandwidth[None])
            lin[r], lnorm[r] = li[0], ln[0]
        trips.append(t)
        evs.append(v if s is None else s)
    logtab = np.log((1.0 - eps[:, None]) * ratio + eps[:, None])
    return _Terms(ijk, logtab, ratio, eps, metric, mix, centres, logw, lin, lnorm,
                  np.full(T, kind, dtype=np.int8), trips, evs)


def _concat_terms(a: _Terms, b: _Terms) -> _Terms:
    K = max(a.centres.shape[1], b.centres.shape[1])

    def pad(x, fill):
        if x.shape[1] == K:
            return x
        shape = (x.shape[0], K - x.shape[1]) + x.shape[2:]
        return np.concatenate([x, np.full(shape, fill)], axis=1)

    return _Terms(np.concatenate([a.ijk, b.ijk]), np.concatenate([a.logtab, b.logtab]),
                  np.concatenate([a.ratiotab, b.ratiotab]), np.concatenate([a.eps, b.eps]),
                  np.concatenate([a.metric, b.metric]),
                  np.concatenate([a.mix, b.mix]),
                  np.concatenate([pad(a.centres, 0.0), pad(b.centres, 0.0)]),
                  np.concatenate([pad(a.logw, -np.inf), pad(b.logw, -np.inf)]),
                  np.concatenate([a.lin, b.lin]), np.concatenate([a.lnorm, b.lnorm]),
                  np.concatenate([a.kind, b.kind]), a.triplets + b.triplets,
                  a.evidence + b.evidence)


def _lookup_of(part):
    """The partition's vectorized state lookup of AB-frame positions, without re-checking the
    inputs (to_frame made them finite); ``state_of`` where the partition has none."""
    lk = part.lookup
    return (lambda c: np.asarray(lk(c), dtype=np.int64)) if lk is not None else part.state_of


def _term_loglik(t: _Terms, idx, pts, lookup) -> np.ndarray:
    """(len(idx), P) log L_t of terms ``idx`` (module docstring: state or metric, floored) for
    the landmark positions ``pts`` = [A, B, C], each (len(idx), P, 2); ``lookup`` maps AB-frame
    positions to states."""
    from .geometry import to_frame

    c = to_frame(pts[2], pts[0], pts[1])
    s = lookup(c)                                                        # (T, P)
    out = np.take_along_axis(t.logtab[idx], s, axis=1)
    met = t.metric[idx]
    if met.any():
        mi = idx[met]
        sm = s[met]
        r = np.exp(_log_mixture(c[met], t.centres[mi], t.logw[mi], t.lin[mi], t.lnorm[mi]))
        st = np.take_along_axis(t.ratiotab[mi], sm, axis=1)
        b = t.mix[mi][:, None]
        e = t.eps[mi][:, None]
        out[met] = np.log((1.0 - e) * ((1.0 - b) * r + b * st) + e)
    return out


# --------------------------------------------------------------------------- the sampler
def _landmark_blocks(ijk, n) -> list:
    """Blocks of landmarks the sampler moves as one (``_Sampler.move_blocks``), from the seen
    triplets' landmark indices ``ijk`` (T, 3) of ``n`` landmarks: the connected components of the
    evidence (landmarks linked by a common seen triplet) and its rigid clusters (seen triplets
    linked when they share two landmarks: a cluster's shape is tied together, its placement
    relative to another cluster only through one shared landmark or none); blocks of fewer than
    two landmarks, or of all of them (the whole-configuration move does that), are left out.

    >>> [b.tolist() for b in _landmark_blocks(np.array([[0, 1, 2], [1, 2, 3], [3, 4, 5]]), 6)]
    [[3, 4, 5], [0, 1, 2, 3]]
    """
    def find(par, i):
        while par[i] != i:
            par[i] = par[par[i]]
            i = par[i]
        return i

    ijk = np.asarray(ijk, dtype=np.intp).reshape(-1, 3)
    blocks = []
    par = list(range(n))
    for t in ijk:
        for x in t[1:]:
            par[find(par, int(x))] = find(par, int(t[0]))
    comp = {}
    for l in {int(x) for x in ijk.ravel()}:
        comp.setdefault(find(par, l), []).append(l)
    blocks += [sorted(c) for c in comp.values()]
    T = len(ijk)
    tp = list(range(T))
    by_pair = {}
    for r, t in enumerate(ijk.tolist()):
        for a, b in ((0, 1), (0, 2), (1, 2)):
            key = (min(t[a], t[b]), max(t[a], t[b]))
            if key in by_pair:
                tp[find(tp, r)] = find(tp, by_pair[key])
            else:
                by_pair[key] = r
    cl = {}
    for r, t in enumerate(ijk.tolist()):
        cl.setdefault(find(tp, r), set()).update(t)
    blocks += [sorted(c) for c in cl.values()]
    out, seen = [], set()
    for b in sorted(blocks, key=lambda b: (len(b), b)):
        key = tuple(b)
        if 2 <= len(b) < n and key not in seen:
            seen.add(key)
            out.append(np.array(b, dtype=np.intp))
    return out


class _Sampler:
    """Tempered SMC over world configurations, stored landmark-major: ``Xt`` (n, P, 2) (gathering
    the landmarks of many triplets is then a copy of whole rows); per-term log-likelihoods ``ll``
    (T, P). Particle p belongs to group p // Pg."""

    def __init__(self, X, terms, part, pr, floor, rng, n_groups, block_moves=True):
        self.Xt = np.ascontiguousarray(np.transpose(X, (1, 0, 2)))
        self.terms, self.part, self.pr = terms, part, pr
        self.floor, self.rng, self.G = floor, rng, n_groups
        self.n, self.P = self.Xt.shape[:2]
        self.Pg = self.P // n_groups
        self.box = np.array([pr.width, pr.height])
        self.of_landmark = [np.flatnonzero(np.any(terms.ijk == l, axis=1)) for l in range(self.n)]
        self._lookup = _lookup_of(part)
        self.ll = self._loglik(np.arange(len(terms.ijk)))
        self.step = np.full(self.n, 0.5)
        self.sim_step = 0.5
        self.blocks = _landmark_blocks(terms.ijk, self.n) if block_moves else []
        self.block_step = np.full(len(self.blocks), 0.5)
        self.block_terms = [np.unique(np.concatenate([self.of_landmark[l] for l in S]))
                            for S in self.blocks]
        self._spread_all = 1.0
        self.acc_block = []
        self.acc_land, self.acc_sim = [], []

    @property
    def X(self):
        """(P, n, 2) positions."""
        return np.transpose(self.Xt, (1, 0, 2))

    # -- likelihood
    def _loglik(self, idx, l=None, prop=None):
        """(len(idx), P) log-likelihood of terms idx; with l, prop: landmark l moved to prop."""
        t = self.terms
        ijk = t.ijk[idx]
        pts = [self.Xt[ijk[:, a]] for a in range(3)]                    # (T, P, 2) each, copies
        if l is not None:
            ls = np.atleast_1d(l)
            props = prop[None] if prop.ndim == 2 else prop                  # (k, P, 2)
            for a in range(3):
                for j, lj in enumerate(ls):
                    hit = ijk[:, a] == lj
                    if hit.any():
                        pts[a][hit] = props[j][None]
        return _term_loglik(t, idx, pts, self._lookup)

    def coef(self, beta):
        k = self.terms.kind
        return np.where(k == 0, 1.0, np.where(k == 1, beta, 1.0 - beta))

    def tempered(self):
        """(P,) d log target / d beta."""
        k = self.terms.kind
        return self.ll[k == 1].sum(axis=0) - self.ll[k == 2].sum(axis=0)

    # -- prior
    def _inside(self, pts):
        return np.all((pts >= 0.0) & (pts <= self.box), axis=-1)

    def _min_dist(self, l, prop):
        """(P,) least distance from prop (P, 2) to the other landmarks."""
        if self.n < 2:
            return np.full(self.P, np.inf)
        d = self.Xt - prop[None]
        d2 = np.einsum("npk,npk->np", d, d)
        d2[l] = np.inf
        return np.sqrt(np.min(d2, axis=0))

    def _min_pair(self, Xt):
        """(P,) least pairwise distance within each configuration, Xt (n, P, 2)."""
        out = np.full(Xt.shape[1], np.inf)
        for i in range(Xt.shape[0] - 1):
            d = Xt[i + 1:] - Xt[i][None]
            np.minimum(out, np.min(np.einsum("npk,npk->np", d, d), axis=0), out=out)
        return np.sqrt(out)

    # -- moves
    def _spread(self):
        """(n,) per landmark, the mean within-group standard deviation of its position."""
        Xg = self.Xt.reshape(self.n, self.G, self.Pg, 2)
        return np.sqrt(np.mean(np.var(Xg, axis=2), axis=(1, 2)))

    def move_landmarks(self, beta):
        coef = self.coef(beta)
        spread = self._spread()
        rng = self.rng
        acc = np.zeros(self.n)
        for l in rng.permutation(self.n):
            sd = max(self.step[l] * spread[l], 1e-6)
            prop = self.Xt[l] + sd * rng.standard_normal((self.P, 2))
            ok = self._inside(prop)
            if self.pr.d_min > 0:
                ok &= self._min_dist(l, prop) >= self.pr.d_min
            idx = self.of_landmark[l]
            logu = np.log(rng.random(self.P))
            if idx.size:
                new = self._loglik(idx, l, prop)
                dlog = coef[idx] @ (new - self.ll[idx])
            else:
                new, dlog = None, np.zeros(self.P)
            a = ok & (logu < dlog)
            self.Xt[l, a] = prop[a]
            if new is not None and a.any():
                self.ll[idx] = np.where(a[None, :], new, self.ll[idx])
            acc[l] = a.mean()
        self.acc_land.append(float(acc.mean()))
        return acc

    def move_similarity(self):
        rng, P, n = self.rng, self.P, self.n
        c = self.Xt.mean(axis=0, keepdims=True)
        th = self.sim_step * 0.3 * rng.standard_normal(P)
        ls = self.sim_step * 0.5 / max(n, 1) * rng.standard_normal(P)
        tr = self.sim_step * 0.3 * rng.standard_normal((1, P, 2))
        s = np.exp(ls)
        cs, sn = np.cos(th) * s, np.sin(th) * s
        d = self.Xt - c
        Y = np.stack([cs * d[..., 0] - sn * d[..., 1], sn * d[..., 0] + cs * d[..., 1]],
                     axis=-1) + c + tr
        ok = np.all(self._inside(Y), axis=0)
        shrink = ok & (s < 1)
        if self.pr.d_min > 0 and shrink.any():
            ok[shrink] = self._min_pair(Y[:, shrink]) >= self.pr.d_min
        # likelihoods are invariant; the box prior is flat: the Jacobian decides, s^(2(n-1)) (the
        # centroid is translated, the n - 1 independent offsets from it rotated and scaled)
        a = ok & (np.log(rng.random(P)) < 2 * (n - 1) * ls)
        self.Xt[:, a] = Y[:, a]
        self.acc_sim.append(float(a.mean()))
        return float(a.mean())

    def move_blocks(self, beta):
        """A random similarity transform of one block of landmarks at a time (about the block's
        centroid; the others stay), accepted by Metropolis on the likelihood of the triplets that
        touch the block and the prior. A block whose triplets all lie inside it (a connected
        component of the evidence) keeps its likelihood: the move carries it across the
        placements relative to the rest that no evidence constrains; a rigid cluster tied to
        the rest by one or two landmarks moves about them where the evidence allows."""
        if not self.blocks:
            return np.zeros(0)
        coef = self.coef(beta)
        rng, P = self.rng, self.P
        acc = np.zeros(len(self.blocks))
        for b in rng.permutation(len(self.blocks)):
            S = self.blocks[b]
            k = S.size
            st = self.block_step[b]
            Xs = self.Xt[S]                                                   # (k, P, 2)
            c = Xs.mean(axis=0, keepdims=True)
            th = st * 0.3 * rng.standard_normal(P)
            ls = st * 0.5 / k * rng.standard_normal(P)
            tr = st * 0.3 * self._spread_all * rng.standard_normal((1, P, 2))
            sc = np.exp(ls)
            cs, sn = np.cos(th) * sc, np.sin(th) * sc
            d = Xs - c
            Y = np.stack([cs * d[..., 0] - sn * d[..., 1], sn * d[..., 0] + cs * d[..., 1]],
                         axis=-1) + c + tr
            ok = np.all(self._inside(Y), axis=0)
            if self.pr.d_min > 0:
                rest = np.setdiff1d(np.arange(self.n), S)
                md = np.full(P, np.inf)
                for j in range(k):
                    if rest.size:
                        dd = self.Xt[rest] - Y[j][None]
                        np.minimum(md, np.min(np.einsum("npk,npk->np", dd, dd), axis=0), out=md)
                if k > 1:
                    np.minimum(md, self._min_pair(Y) ** 2, out=md)
                ok &= np.sqrt(md) >= self.pr.d_min
            idx = self.block_terms[b]
            if idx.size:
                new = self._loglik(idx, S, Y)
                dlog = coef[idx] @ (new - self.ll[idx])
            else:
                new, dlog = None, np.zeros(P)
            a = ok & (np.log(rng.random(P)) < dlog + 2 * (k - 1) * ls)
            self.Xt[np.ix_(S, a)] = Y[:, a]
            if new is not None and a.any():
                self.ll[idx] = np.where(a[None, :], new, self.ll[idx])
            acc[b] = a.mean()
        self.acc_block.append(float(acc.mean()))
        return acc

    def sweep(self, beta, n_sweeps):
        accs, sims, blks = [], [], []
        for _ in range(n_sweeps):
            accs.append(self.move_landmarks(beta))
            if self.blocks:
                self._spread_all = float(np.mean(self._spread()))
                blks.append(self.move_blocks(beta))
            sims.append(self.move_similarity())
        if blks:
            self.block_step *= np.exp(np.clip(np.mean(blks, axis=0) - 0.3, -0.3, 0.3) * 2)
            self.block_step = np.clip(self.block_step, 1e-3, 3.0)
        acc = np.mean(accs, axis=0)
        # steps adapted toward an acceptance of about 0.3 (fixed within a stage)
        self.step *= np.exp(np.clip(acc - 0.3, -0.3, 0.3) * 2)
        self.step = np.clip(self.step, 1e-4, 3.0)
        self.sim_step = float(np.clip(self.sim_step * np.exp(2 * (np.mean(sims) - 0.3)),
                                      1e-3, 3.0))

    # -- resampling
    def resample(self, logw):
        """Systematic resampling within each group; returns the per-group log mean weight."""
        G, Pg = self.G, self.Pg
        lw = logw.reshape(G, Pg)
        mx = lw.max(axis=1, keepdims=True)
        w = np.exp(lw - mx)
        tot = w.sum(axis=1, keepdims=True)
        logz = (np.log(tot[:, 0] / Pg) + mx[:, 0])
        cdf = np.cumsum(w / tot, axis=1)
        cdf[:, -1] = 1.0
        u = (self.rng.random((G, 1)) + np.arange(Pg)[None, :]) / Pg
        idx = np.stack([np.searchsorted(cdf[g], u[g]) for g in range(G)])
        idx = np.minimum(idx, Pg - 1) + (np.arange(G) * Pg)[:, None]
        idx = idx.reshape(-1)
        self.Xt = self.Xt[:, idx]
        self.ll = self.ll[:, idx]
        return logz

    def ess_fraction(self, logw):
        lw = logw.reshape(self.G, self.Pg)
        w = np.exp(lw - lw.max(axis=1, keepdims=True))
        w /= w.sum(axis=1, keepdims=True)
        return float(np.mean(1.0 / np.sum(w * w, axis=1)) / self.Pg)

    def run(self, target_ess, n_sweeps, max_stages=1000):
        betas, esss, logz = [0.0], [], np.zeros(self.G)
        beta = 0.0
        D = self.tempered()
        if not np.any(self.terms.kind != 0):
            return betas, esss, logz
        while beta < 1.0 and len(betas) <= max_stages:
            D = self.tempered()
            if self.ess_fraction((1.0 - beta) * D) >= target_ess:
                nb = 1.0
            else:
                lo, hi = beta, 1.0
                for _ in range(50):
                    mid = 0.5 * (lo + hi)
                    if self.ess_fraction((mid - beta) * D) >= target_ess:
                        lo = mid
                    else:
                        hi = mid
                nb = max(lo, beta + 1e-6)
            esss.append(self.ess_fraction((nb - beta) * D))
            logz += self.resample((nb - beta) * D)
            beta = nb
            betas.append(beta)
            self.sweep(beta, n_sweeps)
        return betas, esss, logz


# --------------------------------------------------------------------------- results
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


class ConfigurationPosterior:
    """Weighted samples of the landmarks' world positions given the seen triplets' evidence.

    Attributes:
        landmarks: tuple of landmark ids (column order of ``positions``).
        positions: (P, n, 2) world positions (the prior's box units), read-only.
        weights: (P,) normalized weights (equal after the final resampling).
        groups: (P,) int, the independent population of each particle.
        partition, prior: the partition and :class:`qfg.priors.WorldBoxPrior` used.
        likelihood: ``"state"`` or ``"metric"``.
        evidence: {triplet: (m,) vector or PositionSummary}, the seen triplets' evidence.
        diagnostics: dict -- ``n_stages``, ``betas``, ``ess`` (fraction of each stage's
            particles, before resampling), ``acceptance_landmark`` / ``acceptance_similarity``
            (mean acceptance of the moves), ``log_evidence`` (per group, the SMC estimate of
            log E_prior[prod L]), ``options``.

    :meth:`marginals` gives any triplets' state distributions, :meth:`update` adds evidence.
    """

    def __init__(self, landmarks, X, groups, part, pr, likelihood, terms, options, diag, q):
        self.landmarks = tuple(landmarks)
        self._index = {l: i for i, l in enumerate(self.landmarks)}
        X = np.array(X)
        X.setflags(write=False)
        self.positions = X
        self._Xt = np.ascontiguousarray(np.transpose(X, (1, 0, 2)))
        self.weights = np.full(X.shape[0], 1.0 / X.shape[0])
        self.weights.setflags(write=False)
        self.groups = np.asarray(groups)
        self.partition, self.prior, self.likelihood = part, pr, likelihood
        self._terms, self.options, self.diagnostics, self._q = terms, options, diag, q

    @property
    def evidence(self) -> dict:
        return dict(zip(self._terms.triplets, self._terms.evidence, strict=True))

    def __repr__(self):
        return (f"ConfigurationPosterior(landmarks={len(self.landmarks)}, "
                f"particles={self.positions.shape[0]}, seen={len(self._terms.triplets)}, "
                f"likelihood={self.likelihood!r}, stages={self.diagnostics.get('n_stages')})")

    def _indices(self, triplets):
        out = np.zeros((len(triplets), 3), dtype=np.intp)
        for r, t in enumerate(triplets):
            for a, x in enumerate(t):
                try:
                    out[r, a] = self._index[x]
                except KeyError:
                    raise KeyError(f"triplet: {t} uses landmark {x}, which is not in this "
                                   f"configuration (landmarks {self.landmarks[:10]}"
                                   f"{'...' if len(self.landmarks) > 10 else ''})") from None
        return out

    def states(self, triplets) -> np.ndarray:
        """(P, len(triplets)) int states of the triplets in every sampled configuration."""
        ts = [_as_triplet(t) for t in triplets]
        return self._states(self._indices(ts))

    def _states(self, ijk):
        return self._states_t(ijk).T

    def _states_t(self, ijk):
        """(r, P) states, from the landmark-major copy (whole-row gathers)."""
        from .geometry import to_frame

        Xt = self._Xt
        return self.partition.state_of(to_frame(Xt[ijk[:, 2]], Xt[ijk[:, 0]], Xt[ijk[:, 1]]))

    def log_likelihoods(self, positions=None) -> np.ndarray:
        """(T, K) ``log L_t(X_k)``: each seen triplet's floored likelihood term (module docstring;
        the state kind tempered and floored exactly as the sampler used it) at K configurations.

        ``positions``: (K, n, 2) or (n, 2) world positions, columns in the order of
        :attr:`landmarks` (default: the sampled configurations). Rows follow the seen triplets of
        :attr:`evidence`. Any configuration can be scored: the ground truth, to ask whether a
        miss is the sampler's (the truth's ``sum_t log L_t`` above the particles') or the
        evidence's (below them). Only AB-frame positions enter, so a similarity transform of a
        configuration leaves every term unchanged.

        >>> post = infer_configurations({(0, 1, 2): np.eye(20)[1] * 0.9 + 0.005}, n_particles=40,
        ...                             seed=0)
        >>> post.log_likelihoods(np.array([[0.0, 0.0], [0.0, 1.0], [-0.5, 0.5]])).shape
        (1, 1)
        """
        if positions is None:
            Xt = self._Xt
        else:
            X = as_float_array("positions", positions)
            if X.ndim == 2:
                X = X[None]
            n = len(self.landmarks)
            if X.ndim != 3 or X.shape[1:] != (n, 2):
                raise ValueError(f"positions: expected shape (K, {n}, 2) or ({n}, 2), the "
                                 f"landmarks' world positions in the order of .landmarks; got "
                                 f"{np.shape(positions)}")
            Xt = np.ascontiguousarray(np.transpose(X, (1, 0, 2)))
        t = self._terms
        idx = np.arange(len(t.triplets))
        return _term_loglik(t, idx, [Xt[t.ijk[:, a]] for a in range(3)], _lookup_of(self.partition))

    def all_triplets(self) -> list:
        """Every ordered triplet of this configuration's landmarks (n (n-1) (n-2))."""
        L = self.landmarks
        return [(a, b, c) for a in L for b in L for c in L if a != b and b != c and a != c]

    def components(self) -> np.ndarray:
        """(n,) int, the connected component of each landmark (column of ``positions``) in the
        graph that links the landmarks of every seen triplet; a landmark in no seen triplet is
        a component of its own.

        >>> post = infer_configurations({(0, 1, 2): np.full(20, 0.05)}, landmarks=range(4),
        ...                             n_particles=40, seed=0)
        >>> post.components().tolist()
        [0, 0, 0, 1]
        """
        par = list(range(len(self.landmarks)))

        def find(i):
            while par[i] != i:
                par[i] = par[par[i]]
                i = par[i]
            return i

        for t in self._terms.ijk:
            for x in t[1:]:
                par[find(int(x))] = find(int(t[0]))
        roots = [find(i) for i in range(len(par))]
        return np.unique(roots, return_inverse=True)[1].astype(np.intp)

    def marginals(self, triplets=None, *, pseudo_count=None, widen=None, unlinked="sample",
                  check=False):
        """:class:`qfg.inference.Marginals` of ``triplets`` (default: every ordered triplet of
        the landmarks), seen and unseen alike.

        Each row is the particles' state histogram shrunk toward the prior's state distribution
        by ``pseudo_count`` pseudo-draws, ``(P f + a q) / (P + a)`` (no state the particles missed
        is given probability 0). ``info``: ``mc_error`` (n, m) the standard error from the
        spread of the ``n_groups`` populations' estimates, ``mc_error_max``, ``seen`` (n,) bool,
        the sampler's diagnostics and ``configurations`` (this object).

        ``widen`` (None: off): a row whose populations disagree is not trusted. Each row is mixed
        toward the prior's state distribution, ``(1 - w) f + w q`` with ``w = min(1, e / widen)``
        and ``e`` the row's largest Monte Carlo error: where the sampler has not settled (e.g.
        clusters of landmarks tied by few seen triplets, whose relative placement the
        populations choose differently), the answer says "unknown" instead of picking one
        population's guess. ``info["widened"]``: (n,) the weights ``w``.

        ``unlinked``: the answer for a triplet whose landmarks lie in different connected
        components of the evidence (:meth:`components`), about whose relative placement only the
        prior speaks: ``"sample"`` (the samples, i.e. the world prior's model of where unlinked
        groups lie) or ``"prior"`` (the prior's state distribution ``q``: "unknown", for data whose
        landmarks the i.i.d. box prior does not describe, e.g. an arena's). ``info["unlinked"]``:
        (n,) bool.

        ``check``: when True, every row is mixed toward ``q`` by the weight
        :meth:`loo_check` finds (0 when the seen triplets predict each other at least as well as
        the prior does); ``info["check"]``: the :class:`LeaveOneOutCheck`.

        ``info["unsettled"]``: (n,) bool, rows whose largest Monte Carlo error is above
        :data:`UNSETTLED_ERROR` (not the unlinked rows with ``unlinked="prior"``); a
        :class:`NotSettledWarning` when they are more than :data:`UNSETTLED_SHARE` of the rows.
        """
        if unlinked not in ("sample", "prior"):
            raise ValueError(f"unlinked: expected 'sample' or 'prior', got {unlinked!r}")
        from .inference.results import Marginals

        if triplets is None:
            triplets = self.all_triplets()
        ts = [_as_triplet(t) for t in triplets]
        ijk = self._indices(ts)
        a = float(self.options["pseudo_count"] if pseudo_count is None else
                  non_negative("pseudo_count", pseudo_count))
        m, P = self.partition.n_states, self.positions.shape[0]
        G = int(self.groups.max()) + 1
        R = len(ts)
        counts = np.zeros((G, R, m))
        step = max(1, _CHUNK // P)
        for r0 in range(0, R, step):
            s = self._states_t(ijk[r0:r0 + step])                         # (r, P)
            r = s.shape[0]
            flat = (self.groups[None, :] * r + np.arange(r)[:, None]) * m + s
            counts[:, r0:r0 + r] = np.bincount(flat.ravel(), minlength=G * r * m
                                               ).reshape(G, r, m)
        Pg = P // G
        fg = (counts + (a / G) * self._q) / (Pg + a / G)                  # per group, shrunk
        f = (counts.sum(axis=0) + a * self._q) / (P + a)
        se = np.std(fg, axis=0, ddof=1) / np.sqrt(G) if G > 1 else np.full((R, m), np.nan)
        seen = set(self._terms.triplets)
        info = dict(self.diagnostics)
        if widen is not None:
            widen = non_negative("widen", widen)
            if not widen > 0:
                raise ValueError("widen: expected a number > 0 (or None: off)")
            if G < 2:
                raise ValueError("widen: needs n_groups >= 2 (the error is their spread)")
            w = np.minimum(1.0, se.max(axis=1, initial=0.0) / widen)[:, None]
            f = (1.0 - w) * f + w * self._q
            info["widened"] = w[:, 0]
        comp = self.components()[ijk]
        cut = (comp[:, 0] != comp[:, 1]) | (comp[:, 0] != comp[:, 2])
        if unlinked == "prior" and cut.any():
            f[cut] = self._q
        info["unlinked"] = cut
        if check:
            chk = self.loo_check()
            f = (1.0 - chk.widen) * f + chk.widen * self._q
            info["check"] = chk
        unsettled = se.max(axis=1, initial=0.0) > UNSETTLED_ERROR if G > 1 else np.zeros(R, bool)
        if unlinked == "prior":
            unsettled &= ~cut   # answered by q, whatever the populations say
        if R and unsettled.mean() > UNSETTLED_SHARE:
            warnings.warn(
                f"configuration marginals: the sampler's {G} populations disagree on "
                f"{unsettled.sum()} of {R} rows (Monte Carlo error above {UNSETTLED_ERROR}); "
                + ("they are mixed toward the prior's states (widen), " if widen is not None
                   else "they are one population's guess, ")
                + "so more particles or sweeps (n_particles, n_sweeps) may sharpen them; on real "
                "data check that a settled answer is not confidently wrong "
                "(docs/configurations.md)", NotSettledWarning, stacklevel=2)
        info.update(mc_error=se, mc_error_max=float(np.max(se)) if se.size else 0.0,
                    unsettled=unsettled, seen=np.array([t in seen for t in ts], dtype=bool),
                    configurations=self)
        return Marginals(tuple(ts), self.partition.name, f, f"configurations-{self.likelihood}",
                         info)

    def loo_check(self) -> LeaveOneOutCheck:
        """Leave-one-out check of the model against the seen triplets (no ground truth).

        Each seen triplet's evidence is predicted by the configurations the other seen triplets
        give: with ``L_t`` its likelihood (normalized: mean 1 under the prior), the posterior
        without ``t`` is the posterior reweighted by ``1 / L_t``, and its prediction of ``t``'s
        data relative to the prior's is the harmonic mean (the conditional predictive ordinate)

            m_t = E_{pi_-t}[L_t] = 1 / E_pi[1 / L_t]

        (bounded: ``L_t`` is floored). Mixing the configurations with the prior by ``lam`` (every
        marginal ``(1 - lam) f + lam q``) predicts ``(1 - lam) m_t + lam``; ``widen`` is the ``lam``
        of :data:`CHECK_GRID` with the best mean log prediction. Under a correct model the seen
        triplets predict each other better than the prior (``mean(1 / m_t)`` about 1, ``widen``
        near 0); when they contradict each other under it (wrong estimates, a prior that does
        not describe the landmarks), ``widen`` grows toward 1: "unknown" instead of a confident
        answer the evidence does not support.

        >>> post = infer_configurations({(0, 1, 2): np.eye(20)[1] * 0.9 + 0.005,
        ...                              (0, 1, 3): np.eye(20)[1] * 0.9 + 0.005},
        ...                             n_particles=400, seed=0)
        >>> chk = post.loo_check()
        >>> chk.log_cpo.shape, 0.0 <= chk.widen <= 1.0
        ((2,), True)
        """
        t = self._terms
        T = len(t.triplets)
        if T == 0:
            return LeaveOneOutCheck((), np.zeros(0), 0.0, (0.0, 0.0))
        lookup = _lookup_of(self.partition)
        w = np.asarray(self.weights, dtype=float)
        log_cpo = np.empty(T)
        step = max(1, _CHUNK // self.positions.shape[0])
        for r0 in range(0, T, step):
            idx = np.arange(r0, min(T, r0 + step))
            pts = [self._Xt[t.ijk[idx, a]] for a in range(3)]
            ll = _term_loglik(t, idx, pts, lookup)                      # (r, P)
            # log 1 / E_w[exp(-ll)], stably
            neg = -ll
            mx = neg.max(axis=1, keepdims=True)
            log_cpo[idx] = -(mx[:, 0] + np.log(np.exp(neg - mx) @ w))
        lam, agreement = prior_mixing_weight(log_cpo)
        return LeaveOneOutCheck(tuple(t.triplets), log_cpo, lam, agreement)

    def update(self, evidence, *, seed=None, landmarks=(), ess=None) -> "ConfigurationPosterior":
        """A new posterior with more evidence, tempered in from these particles (cheaper than a
        restart when the new evidence is a small part of the whole).

        ``evidence``: {triplet: estimate} as in :func:`infer_configurations`; a triplet already
        seen has its old evidence replaced (the old likelihood tempered out while the new one
        comes in). Landmarks new to the map get positions drawn from the prior given the others.
        """
        o = self.options
        rng = as_rng(seed)
        items = _evidence_items(evidence, self.partition, self.prior, self.likelihood, ess)
        new_ids = [x for x in dict.fromkeys([*landmarks, *(x for t in items for x in t)])
                   if x not in self._index]
        ids = self.landmarks + tuple(new_ids)
        index = {l: i for i, l in enumerate(ids)}
        X = np.array(self.positions)
        if new_ids:
            X = np.concatenate([X, _prior_extension(self.prior, X, len(new_ids), rng)], axis=1)
        old = _Terms(**{k: getattr(self._terms, k) for k in (
            "ijk", "logtab", "ratiotab", "eps", "metric", "mix", "centres", "logw", "lin", "lnorm",
            "kind")}, triplets=list(self._terms.triplets), evidence=list(self._terms.evidence))
        old.kind = np.where(np.isin(np.arange(len(old.triplets)),
                                    [i for i, t in enumerate(old.triplets) if t in items]),
                            2, 0).astype(np.int8)
        new = _make_terms(items, index, self._q, o, 1)
        terms = _concat_terms(old, new) if len(old.triplets) else new
        return _run(ids, X, terms, self.partition, self.prior, self.likelihood, o, self._q, rng,
                    self.groups)


def _prior_extension(pr, X, k, rng):
    """(P, k, 2) positions of k new landmarks from the box prior given the configurations X."""
    P = X.shape[0]
    out = rng.uniform((0.0, 0.0), (pr.width, pr.height), size=(P, k, 2))
    if pr.d_min <= 0:
        return out
    for j in range(k):
        for _ in range(1000):
            others = np.concatenate([X, out[:, :j]], axis=1)
            d = np.sqrt(np.min(np.sum((others - out[:, j:j + 1]) ** 2, axis=-1), axis=1))
            bad = d < pr.d_min
            if not bad.any():
                break
            out[bad, j] = rng.uniform((0.0, 0.0), (pr.width, pr.height), size=(int(bad.sum()), 2))
    return out


def _run(ids, X, terms, part, pr, likelihood, options, q, rng, groups):
    G = options["n_groups"]
    s = _Sampler(np.array(X, dtype=float), terms, part, pr, options["floor"], rng, G,
                 bool(options["block_moves"]))
    betas, esss, logz = s.run(options["target_ess"], options["n_sweeps"])
    if len(betas) > 1:
        # after the last stage the particles have moved once; one more sweep decorrelates the
        # duplicates resampling made
        s.sweep(1.0, options["n_sweeps"])
    keep = terms.kind != 2
    terms = terms.subset(keep)
    terms.kind = np.zeros(len(terms.triplets), dtype=np.int8)
    diag = {"n_stages": len(betas) - 1, "betas": np.array(betas), "ess": np.array(esss),
            "acceptance_landmark": float(np.mean(s.acc_land)) if s.acc_land else float("nan"),
            "acceptance_similarity": float(np.mean(s.acc_sim)) if s.acc_sim else float("nan"),
            "acceptance_block": float(np.mean(s.acc_block)) if s.acc_block else float("nan"),
            "n_blocks": len(s.blocks),
            "log_evidence": logz, "options": dict(options), "likelihood": likelihood,
            "n_seen": len(terms.triplets), "n_metric": int(terms.metric.sum())}
    return ConfigurationPosterior(ids, s.X, groups, part, pr, likelihood, terms, options, diag, q)


def infer_configurations(evidence, prior="world", *, partition="edc", likelihood="state",
                         landmarks=(), seed=None, ess=None, **options) -> ConfigurationPosterior:
    """Sample landmark configurations given seen triplets' evidence (module docstring).

    Args:
        evidence: a :class:`qfg.graph.QualitativeFactorGraph` (its seen triplets' priors are the
            solvers' estimates) or a mapping {triplet: estimate}, estimate an (m,) probability
            vector, a :class:`qfg.solvers.TripletEstimate` or a :class:`PositionSummary`
            (needed for every seen triplet with ``likelihood="metric"``).
        prior: the world prior the solvers used (``"world"`` or a
            :class:`qfg.priors.WorldBoxPrior`); its state distribution
            (:func:`prior_states`) is what each estimate is divided by.
        partition: partition name (must match the estimates').
        likelihood: ``"state"`` or ``"metric"``.
        landmarks: extra landmark ids to include (e.g. landmarks no seen triplet contains).
        seed: int, SeedSequence or Generator. Same seed, same samples.
        ess: {triplet: effective sample size behind its estimate} (default: the estimate's own
            ``ess`` where it has one, else inf: taken as exact). Each estimate is read as
            ``(n P + a q) / (n + a)`` with ``a = ess_prior``: its likelihood is mixed with 1 at
            weight ``a / (n + a)`` on top of the floor.
        **options: :data:`DEFAULTS` -- ``n_particles`` (P, a multiple of ``n_groups``),
            ``n_groups`` (independent populations, >= 2 for an error estimate), ``target_ess``
            (fraction kept per tempering stage), ``n_sweeps`` (Metropolis sweeps per stage),
            ``floor`` (eps), ``state_mix``, ``low_ess_mix`` (b), ``temper`` (tau: every state
            likelihood enters as ``(P_t / q)^tau``, renormalized, :func:`qfg.combine.temper`;
            1 = as the solver says; None: :data:`TEMPER` of the likelihood kind),
            ``ess_prior`` (a, above; None: :data:`ESS_PRIOR` of the likelihood kind),
            ``block_moves`` (random similarity moves of the evidence's components and rigid
            clusters, :func:`_landmark_blocks`), ``pseudo_count`` (the
            marginals' shrinkage toward the prior's state distribution).

    Returns:
        :class:`ConfigurationPosterior`; ``.marginals(triplets)`` for the answers.
    """
    unknown = set(options) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"options: unknown {sorted(unknown)}; known: {sorted(DEFAULTS)}")
    o = {**DEFAULTS, **options}
    G = positive_int("n_groups", o["n_groups"])
    P = positive_int("n_particles", o["n_particles"], minimum=G)
    if P % G:
        raise ValueError(f"n_particles: expected a multiple of n_groups = {G}, got {P}")
    if not 0 < float(o["target_ess"]) < 1:
        raise ValueError(f"target_ess: expected a fraction in (0, 1), got {o['target_ess']!r}")
    positive_int("n_sweeps", o["n_sweeps"])
    if o["temper"] is None:
        o = {**o, "temper": TEMPER[likelihood] if likelihood in TEMPER else 1.0}
    if o["ess_prior"] is None:
        o = {**o, "ess_prior": ESS_PRIOR[likelihood] if likelihood in ESS_PRIOR else 0.0}
    for k in ("floor", "state_mix", "low_ess_mix", "temper"):
        v = non_negative(k, o[k])
        if v > 1:
            raise ValueError(f"{k}: expected a number in [0, 1], got {v}")
    if not o["floor"] > 0:
        raise ValueError("floor: expected a number > 0 (a zero floor lets one estimate veto)")
    non_negative("pseudo_count", o["pseudo_count"])
    non_negative("ess_prior", o["ess_prior"])
    o = {**o, "n_groups": G, "n_particles": P, "floor": float(o["floor"])}
    if likelihood not in LIKELIHOODS:
        raise ValueError(f"likelihood: expected one of {LIKELIHOODS}, got {likelihood!r}")
    pr = _world_prior(prior, whole_map=True)
    part = _partitions.get(partition)
    items = _evidence_items(evidence, part, pr, likelihood, ess)
    extra = [_as_triplet(t) for t in getattr(evidence, "triplets", ())]
    ids = list(dict.fromkeys([*(int(x) for x in landmarks), *(x for t in items for x in t),
                              *(x for t in extra for x in t)]))
    if len(ids) < 3:
        raise ValueError("evidence: no triplet (and fewer than three landmarks): nothing to infer")
    q = prior_states(pr, part)
    rng = as_rng(seed)
    index = {l: i for i, l in enumerate(ids)}
    X = pr.sample_world(rng, len(ids), P)
    terms = _make_terms(items, index, q, o, 1)
    groups = np.repeat(np.arange(G), P // G)
    return _run(ids, X, terms, part, pr, likelihood, o, q, rng, groups)


def configuration_marginals(evidence, prior="world", *, triplets=None, partition=None,
                            likelihood="state", seed=None, widen=None, ess=None,
                            unlinked="sample", check=False, **options):
    """Marginals of ``triplets`` (default: a graph's triplets, else every ordered triplet of the
    landmarks) by configuration inference: :func:`infer_configurations` then
    :meth:`ConfigurationPosterior.marginals` (``widen``: rows the populations disagree on mixed
    toward the prior, see there; ``unlinked``: the answer for triplets across unlinked groups of
    landmarks, see there; ``check``: the leave-one-out check's widening,
    :meth:`ConfigurationPosterior.loo_check`). The result's ``info["configurations"]`` holds the
    samples. ``partition`` defaults to the graph's (else ``"edc"``).

    >>> import numpy as np
    >>> from qfg.graph import QualitativeFactorGraph
    >>> g = QualitativeFactorGraph("edc")
    >>> _ = g.add_triplet((0, 1, 2), np.eye(20)[1] * 0.9 + 0.005)
    >>> _ = g.add_triplet((1, 2, 0))
    >>> r = configuration_marginals(g, n_particles=400, seed=1)
    >>> r.info["seen"].tolist(), r.method
    ([True, False], 'configurations-state')
    """
    if partition is None:
        partition = getattr(evidence, "partition", None) or "edc"
    post = infer_configurations(evidence, prior, partition=partition, likelihood=likelihood,
                                landmarks=sorted({x for t in (triplets or ()) for x in
                                                  _as_triplet(t)}), seed=seed, ess=ess,
                                **options)
    if triplets is None and hasattr(evidence, "triplets"):
        triplets = evidence.triplets
    return post.marginals(triplets, widen=widen, unlinked=unlinked, check=check)
