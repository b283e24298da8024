"""Inference on a :class:`~qfg.graph.QualitativeFactorGraph` (paper section 5c, 06f).

Plain functions over the graph object (networkx style); the graph module imports none of this:

* :func:`exact_marginals` (re-exported from :mod:`qfg.inference`): marginals of the normalized
  product of all factors, one junction-tree calibration (or GTSAM / per-variable contraction).
* :func:`propagate`: the paper's label-correcting Algorithm 2 (``method="best"``) or pooled
  composition (``method="pooled"``).
* :func:`topology_scores`: Algorithm 3 with the information decay model (eqs. decay1, decay2).
* :func:`composition_levels`: eqs. cl1, cl2 and the normalized cl3.

Loopy BP (damped synchronous sum-product on the same factors) sits beside the exact engines:
:func:`qfg.inference.loopy_bp`. :func:`propagate`, :func:`~qfg.inference.loopy_bp` and
:func:`exact_marginals` return one labelled type, :class:`qfg.inference.Marginals`
(``res[(i, j, k)]``, ``np.asarray(res)``; engine extras such as ``isc``, ``reached``,
``converged`` in ``res.info`` and as attributes).

Algorithms 2 and 3 and the composition levels share one label-correcting engine: seen triplets are
sources (updated); a composition factor is *open* while it touches both updated and non-updated
triplets; each open factor proposes a value for each of its non-updated triplets from its updated
ones (one updated: both others get the proposal from that one, the other unknown treated as
uniform; two updated: the third from both); the best proposal over all open factors is kept, its
triplet marked updated (never updated again). A factor's proposals change only when one of its
triplets is updated, so proposals live in a priority queue and after an update only the factors
touching the updated triplet are recomputed: the cost grows with the number of factors, not with
steps x factors. Ties are broken by the smaller triplet index, then the smaller factor index.

Factor closing. The paper defines open/closed by membership (open: at least one updated and one
non-updated triplet) and also says the factor used is "marked closed". We follow the membership
definition: a factor that updated one of its two non-updated triplets stays open for the third
(now with two updated triplets, eq. decay2 / the two-known marginal); it closes when all three are
updated. ``close_used=True`` (in :func:`propagate`, :func:`topology_scores`,
:func:`composition_levels`) takes the other reading: a factor closes for good once it has updated a
triplet. Triplets never reached end uniform (ISC 0, TSC 0, CL infinite).
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from ._vocabulary import check_method, renamed_keywords
from .composition import marginal as compose_marginal
from .inference.exact import elimination_estimate, exact_marginals
from .inference.results import GraphTooLargeError, Marginals, ZeroMassError
from .metrics import information_score

__all__ = [
    "GraphTooLargeError", "ZeroMassError", "Marginals", "ScoreResult", "LevelResult",
    "exact_marginals", "elimination_estimate", "propagate", "topology_scores",
    "composition_levels", "compare_unseen", "PROPAGATION_METHODS",
]

#: names removed in 0.6.0 (CHANGELOG.md) -> what replaces them
_REMOVED = {
    "PropagationResult": "qfg.inference.Marginals",
    "BPResult": "qfg.inference.Marginals",
    "propagate_pooled": 'propagate(g, method="pooled")',
    "PROPAGATION_RULES": "PROPAGATION_METHODS",
}


def __getattr__(name):
    if name in _REMOVED:
        raise AttributeError(f"qfg.propagation.{name} was removed: use {_REMOVED[name]} "
                             "(CHANGELOG.md, 0.6.0)")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclass(frozen=True)
class ScoreResult:
    """Result of :func:`topology_scores` (Algorithm 3): ``scores`` (n,) TSC in [0, 1] (0 where
    unreachable); ``order``, ``updated_by``, ``reached``, ``seen`` as in :func:`propagate`'s result."""

    scores: np.ndarray
    order: np.ndarray
    updated_by: np.ndarray
    reached: np.ndarray
    seen: np.ndarray


@dataclass(frozen=True)
class LevelResult:
    """Result of :func:`composition_levels`: ``levels`` (n,) CL (0 for seen, inf unreachable);
    ``normalized`` (n,) eq. cl3 ``1 - CL / CL_max`` (CL_max the largest finite level; 0 where
    unreachable; all reached ones 1 when CL_max = 0); ``order``, ``updated_by``, ``reached``."""

    levels: np.ndarray
    normalized: np.ndarray
    order: np.ndarray
    updated_by: np.ndarray
    reached: np.ndarray


# ----------------------------------------------------------------------------- label correcting
def _label_correcting(g, sources_value, propose, close_used=False):
    """Shared engine of Algorithms 2/3 and composition levels.

    ``sources_value``: per-variable payload list (None for non-sources). ``propose(fs, upd, vals)``
    gets factor indices (B,), their (B, 3) updated mask and the payload list; returns
    (factor idx (P,), role (P,), score (P,), payloads list of length P) for the non-updated roles.
    Returns (values list, order, updated_by, reached).
    """
    n = g.n_triplets
    fvars = g.factor_vars
    F = len(fvars)
    values = list(sources_value)
    updated = np.array([v is not None for v in values], dtype=bool)
    order: list[int] = []
    updated_by = np.full(n, -1, dtype=np.intp)
    if F == 0:
        return values, np.array(order, dtype=np.intp), updated_by, updated
    inc = g.incidence()
    count = updated[fvars].sum(axis=1)
    closed = np.zeros(F, dtype=bool)
    heap: list = []
    payloads: list = []

    def push(fs):
        fs = np.asarray(fs, dtype=np.intp)
        fs = fs[(count[fs] > 0) & (count[fs] < 3) & ~closed[fs]]
        if len(fs) == 0:
            return
        pf, prole, pscore, pay = propose(fs, updated[fvars[fs]], values)
        base = len(payloads)
        payloads.extend(pay)
        for q in range(len(pf)):
            f = int(pf[q])
            v = int(fvars[f, prole[q]])
            heapq.heappush(heap, (-float(pscore[q]), v, f, int(count[f]), base + q))

    push(np.arange(F))
    while heap:
        _, v, f, version, q = heapq.heappop(heap)
        if updated[v] or count[f] != version or closed[f]:
            continue  # stale: the triplet was updated, or the factor's proposal changed since
        updated[v] = True
        values[v] = payloads[q]
        payloads[q] = None
        order.append(v)
        updated_by[v] = f
        if close_used:
            closed[f] = True
        touch = inc[v]
        count[touch] += 1
        push(touch)
    return values, np.array(order, dtype=np.intp), updated_by, updated


#: How :func:`propagate` forms a reached triplet's value (``method=``): the paper's best proposal
#: (Algorithm 2), or the mean of all proposals of the nearest level (pooled composition).
PROPAGATION_METHODS = ("best", "pooled")


def _propagate_pooled(g) -> Marginals:
    """Breadth-first propagation by pooled composition.

    Round r = 1, 2, ...: every factor with both updated and non-updated triplets proposes, for
    each non-updated one, the marginal composition from its updated triplets (the other
    non-updated one uniform), as in :func:`propagate`; every triplet with at least one proposal
    takes their linear mean

        P_v = (1 / |F_v|) sum_{f in F_v} compose_f(V_updated),

    and all of them become updated at once (level r). Sources (level 0) are the seen triplets.
    Unlike Algorithm 2, which keeps the single proposal with the best information score, no
    proposal is chosen for being sharp, and values come from the fewest composition steps: a
    linear mean of distributions never puts more on a state than its sharpest member does.
    Returns :class:`~qfg.inference.Marginals` (``method="pooled"``,
    ``info``: ``level`` (n,) rounds from the seen triplets (0 seen, -1 unreachable),
    ``n_proposals`` (n,), ``reached``, ``seen``).

    >>> import numpy as np
    >>> from qfg.graph import QualitativeFactorGraph
    >>> T = np.zeros((2, 2, 2)); T[0, 0, 0] = T[1, 1, 1] = 1       # all three equal
    >>> g = QualitativeFactorGraph("lr", tensor=T)
    >>> for t, p in [((0, 1, 2), [0.9, 0.1]), ((1, 2, 3), None), ((0, 1, 3), None)]:
    ...     _ = g.add_triplet(t, p)
    >>> _ = g.discover_compositions()
    >>> r = propagate(g, method="pooled")
    >>> r.probabilities.round(2).tolist(), r.info["level"].tolist()
    ([[0.9, 0.1], [0.9, 0.1], [0.9, 0.1]], [0, 1, 1])

    (Algorithm 2 gives the last triplet 0.99, counting triplet 0 twice; here both unseen
    triplets are composed from triplet 0 alone, in one round.)
    """
    T = g.table
    m = g.m
    n = g.n_triplets
    fvars = np.asarray(g.factor_vars, dtype=np.intp).reshape(-1, 3)
    values = np.full((n, m), 1.0 / m)
    level = np.full(n, -1, dtype=np.intp)
    n_props = np.zeros(n, dtype=np.intp)
    for v, p in enumerate(g.priors):
        if p is not None:
            values[v] = np.asarray(p, dtype=float) / np.sum(p)
            level[v] = 0
    r = 0
    while len(fvars):
        upd = level[fvars] >= 0
        k = upd.sum(axis=1)
        open_ = (k > 0) & (k < 3)
        if not np.any(open_):
            break
        r += 1
        sums = np.zeros((n, m))
        cnt = np.zeros(n, dtype=np.intp)
        fo, uo = fvars[open_], upd[open_]
        for role in range(3):
            sel = np.flatnonzero(~uo[:, role])
            if len(sel) == 0:
                continue
            V = [None, None, None]
            for other in range(3):
                if other != role:
                    V[other] = np.where(uo[sel, other][:, None], values[fo[sel, other]], 1.0)
            p = np.atleast_2d(compose_marginal(T, V[0], V[1], V[2], role=role + 1).p)
            np.add.at(sums, fo[sel, role], p)
            np.add.at(cnt, fo[sel, role], 1)
        new = cnt > 0
        values[new] = sums[new] / cnt[new, None]
        level[new] = r
        n_props[new] = cnt[new]
    return Marginals(tuple(g.triplets), g.partition, values, "pooled",
                     {"level": level, "n_proposals": n_props, "reached": level > 0,
                      "seen": g.seen, "isc": information_score(values)})


#: Decimals of the information scores Algorithm 2 ranks proposals by: the same composition
#: computed by the two engines (batched products here, :func:`qfg.composition.marginal` in the
#: reference) differs in its last bits, and with BLAS kernels that differ between machines an
#: exact tie (then broken by the smaller triplet, then factor) became a 1e-17 preference for
#: either one; scores are ranked on a 1e-12 grid, far below any difference that means something.
RANK_DECIMALS = 12


def _rank(score):
    """Information scores as Algorithm 2 ranks them (:data:`RANK_DECIMALS`)."""
    return np.round(score, RANK_DECIMALS)


def _isc(p: np.ndarray, log_m: float) -> np.ndarray:
    """:func:`qfg.metrics.information_score` of rows that are already distributions (composed
    here: finite, non-negative, normalized), without its input checks, which cost more than the
    composition on the 50-landmark map. ``(log m - H) / log m``, ``0 log 0 = 0``, clipped to
    [0, 1]; ``tests/test_propagation.py`` checks it against the metric."""
    # the same operations as entropy() and information_score(): the same bits, the same ties
    h = -np.sum(p * np.log(np.where(p > 0, p, 1.0)), axis=-1)
    return np.clip((log_m - h) / log_m, 0.0, 1.0)


def _best_first(g, close_used: bool):
    """See :func:`_best_first_loop`; BLAS limited to one thread: its products are small
    ((about 140, 400) x (400, 20) on the 50-landmark map), and a threaded BLAS spent 30-80 times
    their CPU time spinning on the shared 2-core machine."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return _best_first_loop(g, close_used)


def _best_first_loop(g, close_used: bool):
    """Algorithm 2's label-correcting loop with one best proposal per target triplet.

    The same choices as :func:`_label_correcting` (highest ISC, ties: smaller triplet, then
    smaller factor), with memory in O(F): the ISC of every open factor's proposal for each of its
    non-updated triplets is kept in an (F, 3) array, each non-updated triplet keeps its best
    (score, factor), and the heap holds one entry per change of a triplet's best. Proposals are
    not stored: the accepted one is composed again when popped (its factor has not changed since:
    the entry is valid only while it is its target's best). After an update, only the factors of
    the updated triplet are recomposed, in one batch per role (``(V_x outer V_y) @ T_r``), and a
    target whose best came from one of them and got worse is re-scanned over its own factors.
    """
    T = g.table
    m = g.m
    n = g.n_triplets
    fv = np.asarray(g.factor_vars, dtype=np.int64)
    F = len(fv)
    Ts = T / T.max()
    others = ((1, 2), (0, 2), (0, 1))
    cubes = [np.moveaxis(Ts, r, -1) for r in range(3)]        # (x, y, target) per role
    mats = [np.ascontiguousarray(c.reshape(m * m, m)) for c in cubes]
    # one known triplet, the other uniform: the cube summed over the uniform axis, (m, m)
    sum_y = [np.ascontiguousarray(c.sum(axis=1)) for c in cubes]
    sum_x = [np.ascontiguousarray(c.sum(axis=0)) for c in cubes]
    seen = g.seen
    values = g.prior_matrix()
    updated = seen.copy()
    # the composition's inputs: unit-max rows of the updated triplets, ones for the others
    unit = np.where(updated[:, None], values / values.max(axis=1, keepdims=True), 1.0)
    log_m = np.log(m)
    order: list[int] = []
    updated_by = np.full(n, -1, dtype=np.intp)
    if F == 0:
        return values, np.array(order, dtype=np.intp), updated_by, updated
    indptr, indices = g.incidence_csr()
    count = updated[fv].sum(axis=1).astype(np.int8)
    closed = np.zeros(F, dtype=bool)
    S = np.full((F, 3), -np.inf)
    best_s = np.full(n, -np.inf)
    best_f = np.full(n, -1, dtype=np.int64)
    tiny = np.finfo(float).tiny

    def compose(ff, role):
        """(k, m) proposals of factors ``ff`` for their triplet in ``role``."""
        x, y = others[role]
        vx, vy = fv[ff, x], fv[ff, y]
        kx, ky = updated[vx], updated[vy]
        if kx.all() and ky.all():
            Vx, Vy = unit[vx], unit[vy]
            p = (Vx[:, :, None] * Vy[:, None, :]).reshape(len(ff), m * m) @ mats[role]
        else:
            p = np.empty((len(ff), m))
            both = kx & ky
            if both.any():
                Vx, Vy = unit[vx[both]], unit[vy[both]]
                p[both] = (Vx[:, :, None] * Vy[:, None, :]).reshape(len(Vx), m * m) @ mats[role]
            one = kx & ~ky
            if one.any():
                p[one] = unit[vx[one]] @ sum_y[role]
            one = ky & ~kx
            if one.any():
                p[one] = unit[vy[one]] @ sum_x[role]
        tot = p.sum(axis=1, keepdims=True)
        zero = tot[:, 0] <= tiny
        p = p / np.where(zero[:, None], 1.0, tot)
        if zero.any():
            p[zero] = 1.0 / m
        return p

    def rescore(fs):
        """Recompute S for factors ``fs``; returns (targets, factors, scores) of open ones."""
        S[fs] = -np.inf
        live = fs[(count[fs] > 0) & (count[fs] < 3) & ~closed[fs]]
        tv, tf, tr, ps = [], [], [], []
        for role in range(3):
            ff = live[~updated[fv[live, role]]]
            if len(ff):
                ps.append(compose(ff, role))
                tv.append(fv[ff, role])
                tf.append(ff)
                tr.append(np.full(len(ff), role))
        if not tv:
            return None
        tf, tr = np.concatenate(tf), np.concatenate(tr)
        sc = _rank(_isc(np.concatenate(ps), log_m))
        S[tf, tr] = sc
        return np.concatenate(tv), tf, sc

    heap: list = []

    def offer(tv, tf, ts):
        """Candidates (target, factor, score): keep each target's best, push improvements."""
        o = np.lexsort((tf, -ts, tv))                       # per target: best score, then factor
        tv, tf, ts = tv[o], tf[o], ts[o]
        first = np.ones(len(tv), dtype=bool)
        first[1:] = tv[1:] != tv[:-1]
        tv, tf, ts = tv[first], tf[first], ts[first]
        bs, bf = best_s[tv], best_f[tv]
        better = (ts > bs) | ((ts == bs) & ((tf < bf) | (bf < 0)))
        better &= ts > -np.inf
        for v, f, sc in zip(tv[better].tolist(), tf[better].tolist(), ts[better].tolist(), strict=True):
            best_s[v], best_f[v] = sc, f
            heapq.heappush(heap, (-sc, v, f))

    def rescan(w):
        fs = indices[indptr[w]:indptr[w + 1]]
        sc = S[fs, np.argmax(fv[fs] == w, axis=1)]
        mx = sc.max() if len(sc) else -np.inf
        if mx == -np.inf:
            best_s[w], best_f[w] = -np.inf, -1
            return
        f = int(fs[sc == mx].min())
        best_s[w], best_f[w] = float(mx), f
        heapq.heappush(heap, (-float(mx), w, f))

    # every open factor at the start, in chunks that bound the (chunk, m^2) products
    chunk = max(1, (1 << 22) // (m * m))
    for lo in range(0, F, chunk):
        got = rescore(np.arange(lo, min(F, lo + chunk), dtype=np.int64))
        if got is not None:
            offer(*got)
    while heap:
        negs, v, f = heapq.heappop(heap)
        if updated[v] or best_f[v] != f or best_s[v] != -negs:
            continue                                        # stale
        role = int(np.flatnonzero(fv[f] == v)[0])
        p = compose(np.array([f]), role)[0]
        values[v] = p
        unit[v] = p / p.max()
        updated[v] = True
        order.append(v)
        updated_by[v] = f
        if close_used:
            closed[f] = True
        fs = indices[indptr[v]:indptr[v + 1]]
        count[fs] += 1
        # targets whose best came from a factor of v: its proposal changed (or closed)
        tw = fv[fs].ravel()
        tf_ = np.repeat(fs, 3)
        lost = ~updated[tw] & (best_f[tw] == tf_)
        lost_w = np.unique(tw[lost])
        got = rescore(fs)
        for w in lost_w.tolist():
            best_s[w], best_f[w] = -np.inf, -1
        if got is not None:
            tv, tf, ts = got
            # a target that lost its best is re-scanned over all of its factors instead
            keep = ~np.isin(tv, lost_w)
            if keep.any():
                offer(tv[keep], tf[keep], ts[keep])
        for w in lost_w.tolist():
            rescan(w)
    return values, np.array(order, dtype=np.intp), updated_by, updated


@renamed_keywords(rule="method")
def propagate(g, close_used: bool = False, method: str = "best", *, _reference: bool = False
              ) -> Marginals:
    """Algorithm 2 (label-correcting propagation by composition), or pooled composition.

    ``method``: ``"best"`` (default, Algorithm 2, below) or ``"pooled"`` (pooled composition,
    :func:`_propagate_pooled`: breadth-first rounds, no factor is closed, so
    ``close_used=True`` with it is a ValueError). The result's ``method`` is the same string.

    Returns a :class:`~qfg.inference.Marginals` (``method="best"``): probabilities
    (n, m) -- the prior for seen triplets, the kept composition marginal for reached ones,
    uniform for unreachable ones -- and in ``info`` (also attributes): ``isc`` (n,) information
    score of each row, ``order`` (u,) non-seen triplets in update order, ``updated_by`` (n,)
    factor that updated each triplet (-1: seen or unreachable), ``reached`` (n,) bool, ``seen``.

    Sources: the seen triplets (their priors, ISC = information score). Proposal of an open factor
    for a non-updated triplet: the marginal composition (eq. marginalComposition,
    :func:`qfg.composition.marginal`) ``P(s_r) propto sum_{a,b} V_a V_b T`` with ``V`` of the
    updated triplets and uniform for the other non-updated one; the target's own vector is uniform
    (unseen). The best ISC proposal is kept each step (see the module docstring).

    >>> import numpy as np
    >>> from qfg.graph import QualitativeFactorGraph
    >>> T = np.zeros((2, 2, 2)); T[0, 0, 0] = T[1, 1, 1] = 1       # all three equal
    >>> g = QualitativeFactorGraph("lr", tensor=T)
    >>> for t, p in [((0, 1, 2), [0.9, 0.1]), ((1, 2, 3), None), ((0, 1, 3), None)]:
    ...     _ = g.add_triplet(t, p)
    >>> _ = g.discover_compositions()
    >>> r = propagate(g)
    >>> r.probabilities.round(2).tolist(), r.order.tolist(), r.updated_by.tolist()
    ([[0.9, 0.1], [0.9, 0.1], [0.99, 0.01]], [1, 2], [-1, 0, 0])

    Triplet 2 is composed from triplet 0 and from triplet 1, itself a copy of triplet 0: the
    evidence is counted twice (0.99), where the exact marginal is 0.9 -- an approximation.
    """
    check_method(method, PROPAGATION_METHODS, {"mean": "pooled"})
    if not g.compositions_asked and not g.seen.all():
        # the order-of-call mistake: without factors every unseen row would come back uniform
        raise ValueError("g: the map has unseen triplets but no composition was asked for: call "
                         "g.discover_compositions() (or add_composition) before propagating")
    if method == "pooled":
        if close_used:
            raise ValueError("close_used: applies to method='best' only (method='pooled' pools "
                             "every proposal of a round; no factor is closed)")
        return _propagate_pooled(g)
    T = g.table
    m = g.m
    fvars = g.factor_vars
    priors = g.priors
    ones = np.ones(m)

    def propose(fs, upd, values):
        rows_f, rows_r, rows_s, pay = [], [], [], []
        for role in range(3):
            sel = np.flatnonzero(~upd[:, role])
            if len(sel) == 0:
                continue
            V = []
            for other in range(3):
                if other == role:
                    V.append(None)
                    continue
                vs = fvars[fs[sel], other]
                V.append(np.stack([values[v] if u else ones
                                   for v, u in zip(vs, upd[sel, other], strict=True)]))
            p = compose_marginal(T, V[0], V[1], V[2], role=role + 1).p
            p = np.atleast_2d(p)
            rows_f.append(fs[sel])
            rows_r.append(np.full(len(sel), role))
            rows_s.append(_rank(information_score(p)))
            pay.extend(p)
        return (np.concatenate(rows_f), np.concatenate(rows_r), np.concatenate(rows_s), pay)

    if _reference:
        values, order, updated_by, reached = _label_correcting(g, priors, propose, close_used)
        marg = np.array([np.full(m, 1.0 / m) if v is None else v for v in values]).reshape(-1, m)
    else:
        marg, order, updated_by, reached = _best_first(g, close_used)
    return Marginals(tuple(g.triplets), g.partition, marg, "best",
                     {"isc": information_score(marg), "order": order, "updated_by": updated_by,
                      "reached": reached, "seen": g.seen, "close_used": bool(close_used)})


def _scalar_engine(g, init, one_known, two_known, maximize=True, close_used=False):
    """Label-correcting on scalars: ``one_known(x)`` for both others, ``two_known(x, y)``."""
    fvars = g.factor_vars
    sign = 1.0 if maximize else -1.0

    def propose(fs, upd, values):
        vals = np.array([[values[v] if u else np.nan for v, u in zip(fvars[f], uu, strict=True)]
                         for f, uu in zip(fs, upd, strict=True)]).reshape(-1, 3)
        k = upd.sum(axis=1)
        rf, rr, rs = [], [], []
        for role in range(3):
            tgt = ~upd[:, role]
            one = tgt & (k == 1)
            two = tgt & (k == 2)
            known = np.where(upd, vals, np.nan)
            if one.any():
                x = np.nanmax(known[one], axis=1)
                rf.append(fs[one])
                rr.append(np.full(one.sum(), role))
                rs.append(one_known(x))
            if two.any():
                kk = known[two][upd[two]].reshape(-1, 2)
                rf.append(fs[two])
                rr.append(np.full(two.sum(), role))
                rs.append(two_known(kk[:, 0], kk[:, 1]))
        scores = np.concatenate(rs)
        return np.concatenate(rf), np.concatenate(rr), sign * scores, list(scores)

    values, order, updated_by, reached = _label_correcting(g, init, propose, close_used)
    return values, order, updated_by, reached


def topology_scores(g, alpha: float = 0.5, seen_score=None, close_used: bool = False
                    ) -> ScoreResult:
    """Algorithm 3: topology score TSC by the information decay model.

    Seen triplets start at the information score of their prior (``seen_score=None``) or at
    ``seen_score`` (e.g. 1.0, as the paper does when comparing with composition levels). Through an
    open factor: one updated triplet a -> ``TSC = (1 - alpha) TSC_a`` for both others (eq. decay1);
    two updated a, b -> ``TSC = (1 - alpha^2) (TSC_a + TSC_b) / 2`` for the third (eq. decay2).
    The best proposal is kept each step; unreachable triplets score 0.

    >>> import numpy as np
    >>> from qfg.graph import QualitativeFactorGraph
    >>> g = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)))
    >>> for t, p in [((0, 1, 2), [1, 0]), ((1, 2, 3), None), ((0, 1, 3), None)]:
    ...     _ = g.add_triplet(t, p)
    >>> _ = g.discover_compositions()
    >>> topology_scores(g, alpha=0.5).scores.tolist()     # 0.5 * 1, then 0.75 * (1 + 0.5) / 2
    [1.0, 0.5, 0.5625]
    """
    alpha = float(alpha)
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha: expected 0 < alpha < 1, got {alpha!r}")
    seen = g.seen
    if seen_score is None:
        base = information_score(g.prior_matrix())
    else:
        s = float(seen_score)
        if not 0.0 <= s <= 1.0:
            raise ValueError(f"seen_score: expected a number in [0, 1] or None, got {seen_score!r}")
        base = np.full(g.n_triplets, s)
    init = [float(base[v]) if seen[v] else None for v in range(g.n_triplets)]
    values, order, updated_by, reached = _scalar_engine(
        g, init, lambda x: (1 - alpha) * x, lambda x, y: (1 - alpha ** 2) * (x + y) / 2,
        close_used=close_used)
    scores = np.array([0.0 if v is None else float(v) for v in values])
    return ScoreResult(scores=scores, order=order, updated_by=updated_by, reached=reached,
                       seen=seen)


def composition_levels(g, close_used: bool = False) -> LevelResult:
    """Composition levels (eqs. cl1, cl2, cl3), propagated like Algorithm 3 (lowest level first).

    Seen: CL = 0. One updated triplet a -> ``CL_a + 1`` for both others (cl1); two updated a, b ->
    ``min(CL_a, CL_b) + 1`` for the third (cl2). Normalized (cl3): ``1 - CL / CL_max``.

    >>> import numpy as np
    >>> from qfg.graph import QualitativeFactorGraph
    >>> g = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)))
    >>> for t, p in [((0, 1, 2), [1, 0]), ((1, 2, 3), None), ((0, 1, 3), None), ((5, 6, 7), None)]:
    ...     _ = g.add_triplet(t, p)
    >>> _ = g.discover_compositions()
    >>> r = composition_levels(g)
    >>> r.levels.tolist(), r.normalized.tolist()
    ([0.0, 1.0, 1.0, inf], [1.0, 0.0, 0.0, 0.0])
    """
    seen = g.seen
    init = [0.0 if seen[v] else None for v in range(g.n_triplets)]
    values, order, updated_by, reached = _scalar_engine(
        g, init, lambda x: x + 1, lambda x, y: np.minimum(x, y) + 1, maximize=False,
        close_used=close_used)
    levels = np.array([np.inf if v is None else float(v) for v in values])
    finite = np.isfinite(levels)
    cmax = levels[finite].max() if finite.any() else 0.0
    norm = np.zeros_like(levels)
    norm[finite] = 1.0 - levels[finite] / cmax if cmax > 0 else 1.0
    return LevelResult(levels=levels, normalized=norm, order=order, updated_by=updated_by,
                       reached=reached)


# ----------------------------------------------------------------------------- reporting
@renamed_keywords(engine="method")
def compare_unseen(g, truth=None, method: str = "junction", max_table: int | None = None
                   ) -> list[dict]:
    """For each unseen triplet: the Algorithm 2 estimate, the exact marginal and the truth.

    Returns one dict per unseen triplet (in ``g.triplets`` order) with ``triplet``, ``propagated``
    ((m,) from :func:`propagate`), ``reached``, ``isc``, ``exact`` ((m,) from
    :func:`exact_marginals` with ``method`` ``"junction"``, ``"contract"`` or ``"gtsam"``; None
    when the graph is too big or has no mass; ``exact_error`` then says why), and ``truth``
    (``truth[v]`` if an (n,) array of states is given, e.g. from :func:`qfg.graph.truth_states`;
    else None).

    >>> import numpy as np
    >>> from qfg.graph import QualitativeFactorGraph
    >>> T = np.zeros((2, 2, 2)); T[0, 0, 0] = T[1, 1, 1] = 1
    >>> g = QualitativeFactorGraph("lr", tensor=T)
    >>> for t, p in [((0, 1, 2), [0.9, 0.1]), ((1, 2, 3), None)]:
    ...     _ = g.add_triplet(t, p)
    >>> g.discover_compositions()                   # none: the two triplets share no factor
    0
    >>> [(r["triplet"], r["exact"].tolist(), r["truth"]) for r in compare_unseen(g, truth=[0, 1])]
    [((1, 2, 3), [0.5, 0.5], 1)]
    """
    n = g.n_triplets
    if truth is not None:
        truth = np.asarray(truth)
        if truth.shape != (n,) or not np.issubdtype(truth.dtype, np.integer):
            raise ValueError(f"truth: expected ({n},) integer states, got {truth.shape} "
                             f"{truth.dtype}")
    res = propagate(g)
    exact, why = None, ""
    try:
        exact = exact_marginals(g, method=method, max_table=max_table)
    except (GraphTooLargeError, ZeroMassError) as exc:
        why = str(exc)
    rows = []
    for v in np.flatnonzero(~g.seen):
        rows.append({"triplet": g.triplets[v], "propagated": res.probabilities[v],
                     "reached": bool(res.reached[v]), "isc": float(res.isc[v]),
                     "exact": None if exact is None else exact[v], "exact_error": why,
                     "truth": None if truth is None else int(truth[v])})
    return rows
