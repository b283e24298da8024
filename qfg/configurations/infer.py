"""The entry points of configuration inference (:mod:`qfg.configurations`):
:func:`infer_configurations` (evidence -> :class:`~qfg.configurations.ConfigurationPosterior`)
and :func:`configuration_marginals` (evidence -> marginals), with their options
(:data:`DEFAULTS`, :data:`TEMPER`, :data:`ESS_PRIOR`).
"""

from __future__ import annotations

import numpy as np

from .. import partitions as _partitions
from .._validate import as_rng, non_negative, positive_int
from .._vocabulary import check_method, renamed_keywords
from .evidence import _as_triplet, _evidence_items, _make_terms
from .positions import _world_prior, prior_states
from .posterior import ConfigurationPosterior, _run

__all__ = ["infer_configurations", "configuration_marginals", "METHODS", "DEFAULTS", "TEMPER",
           "ESS_PRIOR"]

#: The methods of :func:`infer_configurations` (``method=``, default first): the seen triplets'
#: state likelihood or metric likelihood (:mod:`qfg.configurations`).
METHODS = ("config-state", "config-metric")

#: the values ``likelihood=`` took before 0.6.0 (CHANGELOG.md)
_RENAMED = {"state": "config-state", "metric": "config-metric"}


def _kind(method: str) -> str:
    """The likelihood kind of a method, ``"state"`` or ``"metric"`` (the evidence's terms)."""
    return check_method(method, METHODS, _RENAMED).removeprefix("config-")


def __getattr__(name):
    if name == "LIKELIHOODS":
        raise AttributeError(f"{__name__}.LIKELIHOODS was removed: use METHODS "
                             "(CHANGELOG.md, 0.6.0)")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

#: Defaults of :func:`infer_configurations` (chosen on development seeds: docs/configurations.md).
DEFAULTS = {
    "n_particles": 2000, "n_groups": 4, "target_ess": 0.5, "n_sweeps": 2, "floor": 1e-2,
    "state_mix": 0.1, "low_ess_mix": 0.5, "pseudo_count": 2.0, "temper": None,
    "ess_prior": None, "block_moves": True,
}

#: ``temper=None``: the exponent of the state likelihoods per method (seed 555: 0.6 gave
#: config-state's best mean log score, seen and unseen; config-metric is indifferent)
TEMPER = {"config-state": 0.6, "config-metric": 1.0}

#: ``ess_prior=None``: the pseudo-draws ``a`` of the prior with which an estimate made from ``n``
#: effective samples is read, ``(n P + a q) / (n + a)``, per method (development seed 555,
#: fast-solver estimates, median ESS 15.5, 20 graphs: best mean log score over seen and unseen
#: triplets at a = 3 of {0, 1, 3, 10} for config-state, a = 10 for config-metric; an estimate
#: without an ESS is taken as exact)
ESS_PRIOR = {"config-state": 3.0, "config-metric": 10.0}


@renamed_keywords(likelihood="method")
def infer_configurations(evidence, prior="world", *, partition="edc", method="config-state",
                         landmarks=(), seed=0, ess=None, **options) -> ConfigurationPosterior:
    """Sample landmark configurations given seen triplets' evidence (:mod:`qfg.configurations`).

    Args:
        evidence: a :class:`qfg.graph.QualitativeFactorGraph` (its seen triplets' priors are the
            solvers' estimates) or a mapping {triplet: estimate}, estimate an (m,) probability
            vector, a :class:`qfg.solvers.TripletEstimate` or a :class:`PositionSummary`
            (needed for every seen triplet with ``method="config-metric"``).
        prior: the world prior the solvers used (``"world"`` or a
            :class:`qfg.priors.WorldBoxPrior`); its state distribution
            (:func:`prior_states`) is what each estimate is divided by.
        partition: partition name (must match the estimates').
        method: ``"config-state"`` (the state likelihood) or ``"config-metric"`` (the metric
            likelihood), :mod:`qfg.configurations`; the marginals' ``method`` is the same.
        landmarks: extra landmark ids to include (e.g. landmarks no seen triplet contains).
        seed: int, SeedSequence or Generator (default 0). Same seed, same samples.
        ess: {triplet: effective sample size behind its estimate} (default: the estimate's own
            ``ess`` where it has one, else inf: taken as exact). Each estimate is read as
            ``(n P + a q) / (n + a)`` with ``a = ess_prior``: its likelihood is mixed with 1 at
            weight ``a / (n + a)`` on top of the floor.
        **options: :data:`DEFAULTS` -- ``n_particles`` (P, a multiple of ``n_groups``),
            ``n_groups`` (independent populations, >= 2 for an error estimate), ``target_ess``
            (fraction kept per tempering stage), ``n_sweeps`` (Metropolis sweeps per stage),
            ``floor`` (eps), ``state_mix``, ``low_ess_mix`` (b), ``temper`` (tau: every state
            likelihood enters as ``(P_t / q)^tau``, renormalized, :func:`qfg.combine.temper`;
            1 = as the solver says; None: :data:`TEMPER` of the method),
            ``ess_prior`` (a, above; None: :data:`ESS_PRIOR` of the method),
            ``block_moves`` (random similarity moves of the evidence's components and rigid
            clusters, :func:`qfg.configurations.sampler._landmark_blocks`), ``pseudo_count``
            (the marginals' shrinkage toward the prior's state distribution).

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
        o = {**o, "temper": TEMPER[method] if method in TEMPER else 1.0}
    if o["ess_prior"] is None:
        o = {**o, "ess_prior": ESS_PRIOR[method] if method in ESS_PRIOR else 0.0}
    for k in ("floor", "state_mix", "low_ess_mix", "temper"):
        v = non_negative(k, o[k])
        if v > 1:
            raise ValueError(f"{k}: expected a number in [0, 1], got {v}")
    if not o["floor"] > 0:
        raise ValueError("floor: expected a number > 0 (a zero floor lets one estimate veto)")
    non_negative("pseudo_count", o["pseudo_count"])
    non_negative("ess_prior", o["ess_prior"])
    o = {**o, "n_groups": G, "n_particles": P, "floor": float(o["floor"])}
    kind = _kind(method)
    pr = _world_prior(prior, whole_map=True)
    part = _partitions.get(partition)
    items = _evidence_items(evidence, part, pr, kind, ess)
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
    return _run(ids, X, terms, part, pr, method, o, q, rng, groups)


@renamed_keywords(likelihood="method")
def configuration_marginals(evidence, prior="world", *, triplets=None, partition=None,
                            method="config-state", seed=0, widen=None, ess=None,
                            unlinked="sample", check=False, **options):
    """Marginals of ``triplets`` (default: a graph's triplets, else every ordered triplet of the
    landmarks) by configuration inference: :func:`infer_configurations` then
    :meth:`ConfigurationPosterior.marginals` (``widen``: rows the populations disagree on mixed
    toward the prior, see there; ``unlinked``: the answer for triplets across unlinked groups of
    landmarks, see there; ``check``: the leave-one-out check's widening,
    :meth:`ConfigurationPosterior.loo_check`). The result's ``info["configurations"]`` holds the
    samples. ``partition`` defaults to the graph's (else ``"edc"``); ``method``
    (``"config-state"`` or ``"config-metric"``) is the result's ``method``; ``seed`` defaults
    to 0.

    >>> import numpy as np
    >>> from qfg.graph import QualitativeFactorGraph
    >>> g = QualitativeFactorGraph("edc")
    >>> _ = g.add_triplet((0, 1, 2), np.eye(20)[1] * 0.9 + 0.005)
    >>> _ = g.add_triplet((1, 2, 0))
    >>> r = configuration_marginals(g, n_particles=400, seed=1)
    >>> r.info["seen"].tolist(), r.method
    ([True, False], 'config-state')
    """
    if partition is None:
        partition = getattr(evidence, "partition", None) or "edc"
    post = infer_configurations(evidence, prior, partition=partition, method=method,
                                landmarks=sorted({x for t in (triplets or ()) for x in
                                                  _as_triplet(t)}), seed=seed, ess=ess,
                                **options)
    if triplets is None and hasattr(evidence, "triplets"):
        triplets = evidence.triplets
    return post.marginals(triplets, widen=widen, unlinked=unlinked, check=check)
