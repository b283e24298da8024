"""The seen triplets' evidence as the sampler's likelihood terms (:mod:`qfg.configurations`):
estimates checked and read (one ordering per landmark set: :func:`one_ordering_per_set`), one row
per seen triplet of the floored state or metric likelihood ``L_t`` (``_Terms``), and ``log L_t``
at given landmark positions (``_term_loglik``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .positions import PositionSummary, _chol_inverse, _log_mixture

__all__ = ["one_ordering_per_set"]


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
            raise ValueError(f"evidence: triplet {tt}: method='config-metric' needs a "
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
    from ..combine import temper

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
    """(len(idx), P) log L_t of terms ``idx`` (:mod:`qfg.configurations`: state or metric,
    floored) for the landmark positions ``pts`` = [A, B, C], each (len(idx), P, 2); ``lookup``
    maps AB-frame positions to states."""
    from ..geometry import to_frame

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
