"""Exact inference on a :class:`~qfg.graph.QualitativeFactorGraph`: marginals (three methods), MAP
and the K most probable joint assignments.

Methods of :func:`exact_marginals` (``method=``, the string the result's ``method`` reports):

* ``"junction"`` (default): one calibration of a junction tree, every marginal read from it
  (:class:`~qfg.inference.junction.JunctionTree`).
* ``"contract"``: one ``opt_einsum`` contraction per variable (the previous default; kept as an
  independent cross-check and for the benchmarks).
* ``"gtsam"``: ``gtsam.DiscreteMarginals`` (elimination to a Bayes tree, one query per variable).

All three check the size first (:func:`~qfg.inference.junction.size_estimate`, milliseconds even
on the full 15-landmark map) and raise :class:`~qfg.inference.results.ZeroMassError` when the
priors contradict the tensor's support.
"""

from __future__ import annotations

import numpy as np

from .._vocabulary import check_method, renamed_keywords
from .junction import (
    FactorModel,
    JunctionTree,
    _too_large,
    check_max_table,
    contract_scaled,
    size_estimate,
)
from .memory import check_memory, memory_budget
from .results import Assignment, GraphTooLargeError, Marginals, ZeroMassError

__all__ = ["exact_marginals", "map_assignment", "k_best", "elimination_estimate", "clique_sizes",
           "METHODS"]

#: The methods of :func:`exact_marginals` (``method=``), default first.
METHODS = ("junction", "contract", "gtsam")


def __getattr__(name):
    if name == "ENGINES":
        raise AttributeError(f"ENGINES was removed from {__name__}: use METHODS "
                             "(CHANGELOG.md, 0.6.0)")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _result(g, P, method, **info) -> Marginals:
    return Marginals(tuple(g.triplets), g.partition, P, method, info)


@renamed_keywords(engine="method")
def exact_marginals(g, method: str = "junction", max_table: int | None = None,
                    log_domain: bool = False, *, evidence=None, memory=None) -> Marginals:
    """Exact marginals ``P(S_v) = sum over the other variables of prod(factors) / Z``, labelled.

    The product runs over the unary priors and the composition factors ``T[s_t1, s_t2, s_t3]``;
    triplets without any factor are uniform.

    Args:
        g: a :class:`~qfg.graph.QualitativeFactorGraph`.
        method: ``"junction"``, ``"contract"`` or ``"gtsam"`` (see the module docstring).
        max_table: optional limit on the largest clique (entries); above it
            :class:`GraphTooLargeError` names the estimate, before any work. None (default):
            only the memory budget limits.
        log_domain: ``method="junction"`` only: calibrate in the log domain from the start (it falls
            back there by itself when linear arithmetic would underflow).
        evidence: ``method="junction"`` only: observed triplets, ``{triplet: state}`` (clamped
            before planning; their rows are one-hot, ``info["log_partition"]`` is ``log Z(e)``).
        memory: budget in bytes (:func:`~qfg.inference.memory.memory_budget`); the method's
            estimated peak allocation above it -> :class:`~qfg.inference.memory.MemoryBudgetError`
            before any work.

    Returns a :class:`~qfg.inference.results.Marginals` (``method`` = the method; ``info``:
    ``log_partition`` and ``largest_table`` for ``"junction"``).

    >>> import numpy as np
    >>> from qfg.graph import QualitativeFactorGraph
    >>> g = QualitativeFactorGraph(None, tensor=np.eye(2)[:, :, None] * np.eye(2)[None])  # all equal
    >>> for t, p in [((0, 1, 2), [0.8, 0.2]), ((1, 2, 3), None), ((0, 1, 3), None)]:
    ...     _ = g.add_triplet(t, p)
    >>> _ = g.discover_compositions()
    >>> r = exact_marginals(g)
    >>> r[(1, 2, 3)].round(3).tolist(), np.asarray(r).shape
    ([0.8, 0.2], (3, 2))
    """
    max_table = check_max_table(max_table)
    check_method(method, METHODS)
    budget = memory_budget(memory)
    if evidence is not None and method != "junction":
        raise ValueError(f"evidence: supported by method='junction' only, got method={method!r}")
    n, m = g.n_triplets, g.m
    if n == 0:
        return _result(g, np.zeros((0, m)), method)
    if method == "junction":
        jt = JunctionTree(FactorModel.from_graph(g), max_table=max_table, evidence=evidence,
                          memory=budget)
        P, logz, domain = jt.calibrate(log_domain=bool(log_domain))
        return _result(g, P, "junction", log_partition=logz, largest_table=jt.estimate.entries,
                       domain=domain)
    model = FactorModel.from_graph(g)
    limit = max_table if max_table is not None else max(1, budget // 8)
    est = size_estimate(model, limit)
    if not est.complete:
        if max_table is not None:
            raise _too_large(est, max_table, "elimination order")
        check_memory(8.0 * max(est.entries, est.lower_bound), budget, f"method={method!r}",
                     f"a clique over {est.width} variables, about {est.entries:.3g} entries",
                     entries=est.entries, width=est.width)
    out = np.full((n, m), 1.0 / m)
    if method == "gtsam":
        check_memory(gtsam_estimate(model, est), budget, "method='gtsam'",
                     f"about {GTSAM_BYTES_PER_ENTRY} bytes per entry of its decision-tree "
                     f"factors over the cliques (largest {est.entries:.3g} entries)",
                     entries=est.entries, width=est.width)
        return _result(g, _exact_gtsam(g, out, model), "gtsam")
    return _result(g, _exact_contract(g, out, max_table, model, budget), "contract")


#: Bytes GTSAM's DecisionTreeFactor takes per table entry (a leaf and its share of the choice
#: nodes, shared pointers included): 98-145 measured by peak RSS on band graphs of 5-20 states
#: (docs/uai.md, "Memory"; experiments/inference/gtsam_memory.py), with a margin.
GTSAM_BYTES_PER_ENTRY = 160


def gtsam_estimate(model, est=None) -> float:
    """Peak bytes of ``method="gtsam"``: decision trees over the min-fill cliques, about
    :data:`GTSAM_BYTES_PER_ENTRY` per entry (GTSAM orders by COLAMD, not min-fill; its cliques
    are no smaller than the min-fill ones on the graphs measured), the largest three at once
    plus every clique's conditional kept in the Bayes tree."""
    jt_sizes = clique_sizes(model)
    if not jt_sizes:
        return 0.0
    top = sorted(jt_sizes, reverse=True)[:3]
    return float(GTSAM_BYTES_PER_ENTRY * (sum(jt_sizes) + sum(top)))


def clique_sizes(model) -> list[float]:
    """Entries of each elimination clique of the junction tree's order for ``model`` (a
    :class:`~qfg.inference.junction.FactorModel`): one float per eliminated variable, the product
    of its cardinality and its neighbours' at elimination. What the GTSAM memory estimate sums."""
    from .junction import _plan

    est, order, nbrs = _plan(model, None)
    cards = model.cards
    out = []
    for v, nb in zip(order, nbrs, strict=True):
        size = float(cards[v])
        for x in nb:
            size *= cards[x]
        out.append(size)
    return out


def elimination_estimate(g) -> tuple[int, int]:
    """(clique size w, table entries m**w) of the largest table of the min-fill junction tree.

    >>> import numpy as np
    >>> from qfg.graph import full_map
    >>> elimination_estimate(full_map(3, partition=None, tensor=np.ones((2, 2, 2))))
    (1, 2)
    """
    est = size_estimate(g)
    return est.width, int(g.m) ** est.width


def _zero_mass(g, model, exc=None):
    """The junction engine's ZeroMassError (with the component and the local contradictions)."""
    jt = JunctionTree(model, max_table=2 ** 62)
    try:
        jt.calibrate(log_domain=True)
    except ZeroMassError as err:
        return err
    return ZeroMassError(f"g: the product of the factors has no mass ({exc})")


def _exact_gtsam(g, out, model):
    import gtsam

    from ..graph import triplet_key

    graph = g.to_gtsam()
    if graph.size() == 0:
        return out
    try:
        marg = gtsam.DiscreteMarginals(graph)
    except RuntimeError as exc:  # GTSAM: "Product factor is 0.0" when the priors contradict T
        raise _zero_mass(g, model, exc) from None
    touched = np.zeros(g.n_triplets, dtype=bool)
    touched[g.factor_vars.ravel()] = True
    touched |= g.seen
    for v in np.flatnonzero(touched):
        key = (triplet_key(*g.triplets[v]), g.m)
        p = np.asarray(marg.marginalProbabilities(key), dtype=float)
        if not (np.all(np.isfinite(p)) and p.sum() > 0):
            raise _zero_mass(g, model)
        out[v] = p / p.sum()
    return out


def _components(n: int, fvars: np.ndarray) -> list[np.ndarray]:
    """Connected components of variables linked by composition factors (arrays of indices)."""
    parent = np.arange(n)

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b, c in fvars:
        ra, rb, rc = find(a), find(b), find(c)
        parent[rb] = ra
        parent[find(rc)] = ra
    roots = np.array([find(a) for a in range(n)])
    return [np.flatnonzero(roots == r) for r in np.unique(roots)]


def _exact_contract(g, out, max_table, model, budget):
    import opt_einsum as oe

    T = g.table
    T = T / T.max()
    P = g.prior_matrix()
    seen = g.seen
    fvars = g.factor_vars
    for comp in _components(g.n_triplets, fvars):
        in_comp = np.zeros(g.n_triplets, dtype=bool)
        in_comp[comp] = True
        fs = np.flatnonzero(in_comp[fvars[:, 0]]) if len(fvars) else np.array([], dtype=int)
        if len(fs) == 0:
            v = comp[0]
            out[v] = P[v]  # prior, or uniform for an unseen triplet without factors
            continue
        sym = {int(v): oe.get_symbol(i) for i, v in enumerate(comp)}
        terms, ops = [], []
        for v in comp:
            if seen[v]:
                terms.append(sym[int(v)])
                ops.append(P[v] / P[v].max())
        for f in fs:
            terms.append("".join(sym[int(v)] for v in fvars[f]))
            ops.append(T)
        lhs = ",".join(terms)
        plans = []
        for v in comp:      # every plan first: the refusal comes before any contraction
            eq = f"{lhs}->{sym[int(v)]}"
            path, info = oe.contract_path(eq, *ops, optimize="auto")
            if max_table is not None and info.largest_intermediate > max_table:
                raise GraphTooLargeError(
                    f"g: contraction would build an intermediate of about "
                    f"{float(info.largest_intermediate):.3g} entries > max_table={max_table}",
                    entries=float(info.largest_intermediate), max_table=max_table)
            inter = sorted((float(x) for x in info.size_list), reverse=True)
            need = 8.0 * (sum(inter[:2]) + sum(np.size(o) for o in ops))
            check_memory(need, budget, "method='contract'",
                         f"an intermediate of {float(info.largest_intermediate):.3g} entries",
                         entries=float(info.largest_intermediate))
            plans.append((v, eq, info))
        for v, eq, info in plans:
            r = contract_scaled(eq, ops, info.contraction_list)[0]
            s = r.sum()
            if not s > 0:
                raise _zero_mass(g, model)
            out[v] = r / s
    return out


def _assignment(g, X, logp) -> Assignment:
    with np.errstate(under="ignore"):
        p = np.exp(logp)
    return Assignment(tuple(g.triplets), g.partition, X, p, logp)


def map_assignment(g, max_table: int | None = None, *, evidence=None, memory=None
                   ) -> Assignment:
    """The most probable joint assignment of all triplet states (max-product on the junction
    tree), with its probability under the normalized joint.

    >>> import numpy as np
    >>> from qfg.graph import QualitativeFactorGraph
    >>> g = QualitativeFactorGraph(None, tensor=np.eye(2)[:, :, None] * np.eye(2)[None])
    >>> for t, p in [((0, 1, 2), [0.8, 0.2]), ((1, 2, 3), None), ((0, 1, 3), None)]:
    ...     _ = g.add_triplet(t, p)
    >>> _ = g.discover_compositions()
    >>> a = map_assignment(g)
    >>> a.best, a.probabilities.round(3).tolist()
    ({(0, 1, 2): 0, (1, 2, 3): 0, (0, 1, 3): 0}, [0.8])
    """
    return k_best(g, 1, max_table=max_table, evidence=evidence, memory=memory)


def k_best(g, k: int, max_table: int | None = None, *, evidence=None, memory=None
           ) -> Assignment:
    """The ``k`` most probable joint assignments (best first) with their probabilities.

    Fewer than ``k`` rows when fewer assignments have non-zero probability. Equal probabilities
    come out in an order fixed by the graph (deterministic), not by state index. With
    ``evidence`` ({triplet: state}), assignments consistent with it and their probabilities
    given it. ``memory``: as in :func:`exact_marginals` (the queue of Lawler-Murty
    subproblems grows with ``k``: a ``k`` whose queue does not fit is refused up front).
    """
    max_table = check_max_table(max_table)
    jt = JunctionTree(FactorModel.from_graph(g), max_table=max_table, evidence=evidence,
                      memory=memory)
    X, logp = jt.k_best(k)
    return _assignment(g, X, logp)
