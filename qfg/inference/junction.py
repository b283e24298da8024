"""Exact inference by a junction tree over a greedy min-fill elimination order.

A discrete factor model ``p(x) = prod_f phi_f(x_f) / Z`` (:class:`FactorModel`; a
:class:`~qfg.graph.QualitativeFactorGraph` converts with :meth:`FactorModel.from_graph`) is
compiled once (:class:`JunctionTree`, plain numpy, nothing per graph is generated or compiled):

1. **Order.** Greedy min-fill elimination on the interaction graph (ties: fewer neighbours, then the
   smaller index). Eliminating ``v`` with current neighbours ``N_v`` makes the clique
   ``C_v = {v} u N_v``; its parent is the clique of the first-eliminated variable of ``N_v``
   (the elimination tree, a junction tree: running intersection holds by construction). Every
   variable owns one clique, so every marginal is read from a table that holds it.
2. **Size first.** Before any table is built, :func:`size_estimate` bounds the largest clique
   table: a lower bound from the degeneracy of the interaction graph (treewidth >= degeneracy, so
   *every* elimination order builds a table over at least ``degeneracy + 1`` variables), then the
   min-fill plan itself, abandoned as soon as one of its cliques exceeds ``max_table``. Too large
   -> :class:`~qfg.inference.results.GraphTooLargeError` naming the estimate, in milliseconds even
   for the full 15-landmark map.
3. **Calibrate once** (Hugin): upward ``psi_v = prod(assigned factors) prod(child messages)``,
   ``mu_v = sum_{x_v} psi_v`` (rescaled to max 1, the scale kept in ``log Z``); downward
   ``beta_v = psi_v * delta_v``, ``delta_c = sum_{C_v \\ N_c} beta_v / mu_c`` (0/0 = 0: where
   ``mu_c`` is zero the clique belief is zero too). Marginal of ``v``: ``beta_v`` summed over
   ``N_v``, normalized. Cost: two passes over the clique tables.
   Two kinds of node skip the clique table in the linear pass: a node of one 3-variable
   factor whose other parts are each over one variable (matrix-vector products with the
   factor), and a node above ``contract_above`` entries (one contraction per message).
4. **Underflow.** Factors and messages are rescaled to max 1, so every value is <= 1 and one
   multiplication can lose at most ``tau = 1e-291`` in absolute terms (underflow). The linear pass
   carries a first-order bound on the absolute error of every table (upward: ``k tau`` per
   clique plus the children's message errors, divided by the message's normalizer; downward:
   the parent's belief error through the Hugin division -- where it divides by a tiny
   ``mu_c(x)``, the child's ``psi_c(., x) <= mu_c(x)`` multiplies it back -- including entries
   of a message that underflowed to zero) and accepts its answer only if, at every clique, the bound on the
   marginal's error is below 1e-13 of the clique's mass. Otherwise (tiny masses, e.g. products
   of many 1e-200 factors) the whole calibration runs in the log domain (products become sums,
   sums log-sum-exp), with full relative precision. A component whose log-domain mass is
   ``-inf`` has no mass: :class:`~qfg.inference.results.ZeroMassError`.
5. **MAP / K-best.** Max-product (log domain) up the same tree, then decoding down it
   (:meth:`JunctionTree.map_assignment`); the K best by Lawler-Murty partitioning of the
   assignment space (the scheme of Nilsson's algorithm; each subproblem is one max-product pass
   with some states clamped or excluded) (:meth:`JunctionTree.k_best`).

>>> import numpy as np
>>> T = np.array([[0.9, 0.1], [0.2, 0.8]])             # phi(x0, x1)
>>> model = FactorModel(cards=[2, 2], scopes=[(0, 1), (0,)], tables=[T, [0.5, 0.5]])
>>> JunctionTree(model).marginals().round(3).tolist()   # x1: (0.9 + 0.2) / 2, (0.1 + 0.8) / 2
[[0.5, 0.5], [0.55, 0.45]]
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from .results import GraphTooLargeError, ZeroMassError

__all__ = ["FactorModel", "SizeEstimate", "JunctionTree", "size_estimate", "MAX_TABLE"]

#: A conventional limit on the largest table (entries; 2**26: 512 MiB). No longer the default of
#: the engines: they are bounded by the memory they would allocate (:mod:`qfg.inference.memory`);
#: ``max_table=`` adds a limit on the largest clique when given.
MAX_TABLE = 2 ** 26

#: Absolute error one multiplication of values <= 1 can make by underflow (below ~1e-292 a double
#: has lost relative precision: subnormals start at 2.2e-308, 52 bits above that is 1e-292).
_TAU = 1e-291
#: The linear pass is accepted when its error bound is below this fraction of every clique's mass.
_REL_TOL = 1e-13


def check_max_table(max_table) -> int | None:
    """``max_table`` as a positive int, or None (no limit on one table: the memory budget
    decides); ValueError naming it otherwise."""
    if max_table is None:
        return None
    if isinstance(max_table, bool) or not isinstance(max_table, (int, np.integer)) or max_table < 1:
        raise ValueError(f"max_table: expected a positive integer (table entries), got "
                         f"{max_table!r}")
    return int(max_table)


# ----------------------------------------------------------------------------- the model
@dataclass(frozen=True, repr=False)
class FactorModel:
    """A discrete factor model: variables ``0..n-1`` with ``cards[v]`` states, factors
    ``tables[f]`` over ``scopes[f]`` (axes in scope order, C order as in the UAI format).

    ``names``: optional row labels (for a factor graph, the triplets); ``partition``: state label.
    """

    cards: tuple
    scopes: tuple
    tables: tuple
    names: tuple = ()
    partition: str | None = None

    def __post_init__(self):
        cards = tuple(int(c) for c in self.cards)
        if any(c < 1 for c in cards):
            raise ValueError(f"cards: expected positive cardinalities, got {cards}")
        scopes = tuple(tuple(int(v) for v in s) for s in self.scopes)
        if len(scopes) != len(self.tables):
            raise ValueError(f"tables: expected {len(scopes)} tables (one per scope), got "
                             f"{len(self.tables)}")
        tables = []
        checked: dict[int, np.ndarray] = {}  # a table shared by many factors is checked once
        for f, (s, t) in enumerate(zip(scopes, self.tables, strict=True)):
            if len(set(s)) != len(s) or any(not 0 <= v < len(cards) for v in s):
                raise ValueError(f"scopes: factor {f} has scope {s} (expected distinct "
                                 f"variables in [0, {len(cards)}))")
            want = tuple(cards[v] for v in s)
            if id(t) in checked and checked[id(t)].shape == want:
                tables.append(checked[id(t)])
                continue
            key = id(t)
            t = np.asarray(t, dtype=float)
            if t.shape != want:
                if t.size != math.prod(want):
                    raise ValueError(f"tables: factor {f} has {t.size} entries, its scope "
                                     f"{s} needs {want}")
                t = t.reshape(want)
            if not np.all(np.isfinite(t)) or np.any(t < 0):
                raise ValueError(f"tables: factor {f} has negative or non-finite entries")
            checked[key] = t
            tables.append(t)
        object.__setattr__(self, "cards", cards)
        object.__setattr__(self, "scopes", scopes)
        object.__setattr__(self, "tables", tuple(tables))
        object.__setattr__(self, "names", tuple(self.names))

    @property
    def n(self) -> int:
        return len(self.cards)

    def __repr__(self) -> str:
        # the tables can hold millions of entries: counts only
        entries = sum(t.size for t in {id(t): t for t in self.tables}.values())
        return (f"FactorModel(n={self.n}, factors={len(self.scopes)}, max_card="
                f"{max(self.cards) if self.cards else 0}, max_scope="
                f"{max((len(s) for s in self.scopes), default=0)}, distinct_entries={entries}, "
                f"partition={self.partition!r}, named={bool(self.names)})")

    @classmethod
    def from_graph(cls, g) -> FactorModel:
        """The factors of a :class:`~qfg.graph.QualitativeFactorGraph`: one unary table per seen
        triplet (its normalized prior), then one ``T`` per composition factor over
        ``(t1, t2, t3)`` (all sharing one array)."""
        T = g.table
        P = g.priors
        scopes, tables = [], []
        for v, p in enumerate(P):
            if p is not None:
                scopes.append((v,))
                tables.append(p)
        for vs in g.factor_vars.tolist():
            scopes.append(tuple(vs))
            tables.append(T)
        # the graph has validated its tensor, priors and ids: skip the per-table checks
        model = object.__new__(cls)
        for name, value in (("cards", (g.m,) * g.n_triplets), ("scopes", tuple(scopes)),
                            ("tables", tuple(tables)), ("names", tuple(g.triplets)),
                            ("partition", getattr(g, "partition", None))):
            object.__setattr__(model, name, value)
        return model

    def log_value(self, states) -> np.ndarray:
        """(K,) ``log prod_f phi_f(x_f)`` of (K, n) joint assignments (unnormalized)."""
        X = np.atleast_2d(np.asarray(states, dtype=np.intp))
        out = np.zeros(len(X))
        with np.errstate(divide="ignore"):
            for s, t in zip(self.scopes, self.tables, strict=True):
                out += np.log(t[tuple(X[:, v] for v in s)])
        return out


# ----------------------------------------------------------------------------- planning
def _adjacency(model: FactorModel) -> list[set]:
    adj = [set() for _ in range(model.n)]
    for s in model.scopes:
        for a in s:
            adj[a].update(s)
    for v, nb in enumerate(adj):
        nb.discard(v)
    return adj


def _degeneracy(adj) -> int:
    """Largest k such that the graph has a k-core (Batagelj-Zaversnik bucket algorithm, O(E))."""
    n = len(adj)
    if n == 0:
        return 0
    deg = [len(a) for a in adj]
    maxd = max(deg)
    buckets = [[] for _ in range(maxd + 1)]
    for v, d in enumerate(deg):
        buckets[d].append(v)
    removed = [False] * n
    k = 0
    d = 0
    left = n
    while left:
        while d <= maxd and not buckets[d]:
            d += 1
        v = buckets[d].pop()
        if removed[v] or deg[v] != d:
            continue  # stale bucket entry
        removed[v] = True
        left -= 1
        k = max(k, d)
        for u in adj[v]:
            if not removed[u]:
                deg[u] -= 1
                buckets[deg[u]].append(u)
                if deg[u] < d:
                    d = deg[u]
    return k


@dataclass(frozen=True)
class SizeEstimate:
    """Largest clique table of the min-fill junction tree.

    ``width``: variables in the largest clique; ``entries``: its table size (float, exact below
    2**53); ``lower_bound``: entries of the smallest largest-table any elimination order could
    reach by the degeneracy bound; ``complete``: False when planning stopped at ``max_table``
    (``width``/``entries`` are then those of the first clique over the limit)."""

    width: int
    entries: float
    lower_bound: float
    complete: bool
    order: tuple = ()


def _plan(model: FactorModel, max_table: int | None):
    """(SizeEstimate, order, neighbour lists at elimination) -- order empty when refused."""
    cards = model.cards
    n = model.n
    adj = _adjacency(model)
    log_limit = math.inf if max_table is None else math.log(max_table) * (1 + 1e-12)
    # Lower bound: degeneracy k => some clique has >= k + 1 variables under every order. With
    # unequal cardinalities, use the k + 1 smallest cards (a valid, weaker bound).
    k = _degeneracy(adj)
    smallest = sorted(cards)[:k + 1] if n else []
    lb_log = float(sum(math.log(c) for c in smallest))
    if lb_log > log_limit:
        est = SizeEstimate(width=k + 1, entries=math.exp(min(lb_log, 709.0)), lower_bound=math.exp(
            min(lb_log, 709.0)), complete=False)
        return est, (), ()
    adj = [set(a) for a in adj]
    alive = [True] * n
    logc = [math.log(c) for c in cards]

    def fill(u):
        nb = adj[u]
        d = len(nb)
        if d < 2:
            return 0
        links = sum(len(adj[a] & nb) for a in nb) // 2
        return d * (d - 1) // 2 - links

    cur = [fill(v) for v in range(n)]
    heap = [(cur[v], len(adj[v]), v) for v in range(n)]
    heapq.heapify(heap)
    order, nbrs = [], []
    best_log, best_w = 0.0, 0
    while heap:
        f_, d_, v = heapq.heappop(heap)
        if not alive[v] or f_ != cur[v] or d_ != len(adj[v]):
            continue  # stale
        nb = adj[v]
        clog = sum(logc[x] for x in nb) + logc[v]
        if clog > best_log or not order:
            best_log, best_w = clog, len(nb) + 1
        if clog > log_limit:
            est = SizeEstimate(width=len(nb) + 1, entries=math.exp(min(clog, 709.0)),
                               lower_bound=math.exp(min(lb_log, 709.0)), complete=False)
            return est, (), ()
        alive[v] = False
        order.append(v)
        nbrs.append(tuple(sorted(nb)))
        nl = list(nb)
        for a in nl:
            adj[a].discard(v)
            adj[a].update(x for x in nl if x != a)
        adj[v] = set()
        touched = set(nl)
        for a in nl:
            touched |= adj[a]
        for u in touched:
            if alive[u]:
                cur[u] = fill(u)
                heapq.heappush(heap, (cur[u], len(adj[u]), u))
    est = SizeEstimate(width=best_w, entries=math.exp(min(best_log, 709.0)),
                       lower_bound=math.exp(min(lb_log, 709.0)), complete=True, order=tuple(order))
    return est, tuple(order), tuple(nbrs)


def size_estimate(model, max_table: int | None = None) -> SizeEstimate:
    """Largest table of the junction tree of ``model`` (a :class:`FactorModel` or a factor graph).

    With ``max_table``, planning stops at the first clique above it (``complete=False``), so a
    too-large graph is recognised in milliseconds.

    >>> from qfg.graph import full_map
    >>> e = size_estimate(full_map(15, tensor=np.ones((20, 20, 20))), max_table=2 ** 26)
    >>> e.complete, e.lower_bound > 1e70        # at least 20**61 entries
    (False, True)
    """
    if not isinstance(model, FactorModel):
        model = FactorModel.from_graph(model)
    if max_table is not None:
        max_table = check_max_table(max_table)
    return _plan(model, max_table)[0]


def _too_large(est: SizeEstimate, max_table: int, what: str = "junction tree") -> GraphTooLargeError:
    if est.lower_bound > max_table:
        how = (f"every elimination order builds a table over at least {est.width} variables "
               f"(degeneracy bound): at least {est.lower_bound:.3g} entries")
    else:
        how = (f"the min-fill {what} has a table over {est.width} variables "
               f"(about {est.entries:.3g} entries)")
    return GraphTooLargeError(
        f"g: exact inference refused before any work: {how} > max_table={max_table}; use "
        f"propagate() or loopy_bp(), or a smaller graph", entries=est.entries, width=est.width,
        max_table=max_table)


# ----------------------------------------------------------------------------- tree
def _expander(scope, target, cards):
    """(perm, shape): ``table.transpose(perm).reshape(shape)`` broadcasts a table over ``scope``
    against a clique table over ``target``."""
    where = {x: i for i, x in enumerate(target)}
    pos = [where[x] for x in scope]
    perm = tuple(sorted(range(len(pos)), key=pos.__getitem__))
    shape = [1] * len(target)
    for x in scope:
        shape[where[x]] = cards[x]
    return perm, tuple(shape)


def _expand(table, ex):
    perm, shape = ex
    if perm != tuple(range(len(perm))):
        table = table.transpose(perm)
    return table.reshape(shape)


def contract_scaled(eq: str, ops, steps=None):
    """``opt_einsum`` contraction of ``eq`` run pairwise, every intermediate divided by its max:
    (result with max 1, log of the scale removed). A long product of small values (24 factors
    of 1e-100: 1e-2400) cannot underflow to zero as one plain contraction does; what a step can
    still lose is below 1e-308 of that step's largest entry. ``steps``: a precomputed
    ``contraction_list``. A result that is all zero comes back with log scale ``-inf``.

    >>> r, ls = contract_scaled("a,a->", [np.full(2, 1e-200), np.full(2, 1e-200)])
    >>> float(r), round(float(ls) / math.log(10), 6)    # 2e-400 = 1 * 10**(-399.69897)
    (1.0, -399.69897)
    """
    import opt_einsum as oe

    ops = list(ops)
    if steps is None:
        steps = oe.contract_path(eq, *ops, optimize="auto")[1].contraction_list
    log_scale = 0.0
    for i, op in enumerate(ops):
        mx = float(np.max(op)) if np.size(op) else 0.0
        if mx > 0:
            ops[i] = op / mx
            log_scale += math.log(mx)
    for step in steps:
        inds, sub = step[0], step[2]
        args = [ops.pop(i) for i in inds]   # opt_einsum lists the indices in descending order
        r = oe.contract(sub, *args) if len(args) > 1 else np.einsum(sub, *args)
        mx = float(np.max(r)) if np.size(r) else 0.0
        if mx > 0:
            r = r / mx
            log_scale += math.log(mx)
        ops.append(r)
    out = np.asarray(ops[0], dtype=float)
    return out, (log_scale if out.any() else -math.inf)


class JunctionTree:
    """The compiled junction tree of a :class:`FactorModel` (or a factor graph).

    Args:
        model: a :class:`FactorModel` or a :class:`~qfg.graph.QualitativeFactorGraph`.
        max_table: refuse (:class:`GraphTooLargeError`, before any table is built) when the
            largest clique table would exceed this many entries.
        contract_above: in the linear pass, a node whose table would have more entries than
            this (default 20^5: cliques of 6 triplets and more) is never built: its messages and
            marginals are contractions of its factors and messages (:func:`contract_scaled`,
            one per message or marginal). Below it, building the table is faster.

    Attributes: ``estimate`` (:class:`SizeEstimate`), ``order`` (elimination order),
    ``parent`` (per variable: its parent in the elimination tree or -1), ``nodes`` (per clique
    node: its variables, the ones it owns first), ``owned`` (per node: how many variables it
    owns). A variable's clique ``{v} u N_v`` that is contained in the clique of the variable
    eliminated just before it (``C_v = N_c``, c a child of v) is merged into that clique: the
    tree keeps only maximal cliques (about half as many tables on chains of factors), and
    every variable owns the node whose table holds it and from which its marginal is read.
    """

    def __init__(self, model, max_table: int | None = None, contract_above: int = 20 ** 5, *,
                 evidence=None, memory=None):
        from .evidence import check_evidence, clamp
        from .memory import check_memory, memory_budget

        max_table = check_max_table(max_table)
        contract_above = check_max_table(contract_above)
        if contract_above is None:
            raise ValueError("contract_above: expected a positive integer (table entries), "
                             "got None")
        self.budget = memory_budget(memory)
        if not isinstance(model, FactorModel):
            model = FactorModel.from_graph(model)
        self.source = model
        self.evidence = check_evidence(model, evidence)
        model = clamp(model, self.evidence)
        self.model = model
        # no limit given: a clique whose table alone is over the budget is not planned further
        # (a contracted clique's intermediates are smaller, but such cliques are hours of work)
        limit = max_table if max_table is not None else max(1, self.budget // 8)
        est, order, nbrs = _plan(model, limit)
        self.estimate = est
        if not est.complete:
            if max_table is not None:
                raise _too_large(est, max_table)
            check_memory(8.0 * max(est.entries, est.lower_bound), self.budget, "exact inference",
                         f"the min-fill junction tree has a clique over {est.width} variables, "
                         f"about {est.entries:.3g} entries" if est.lower_bound <= limit else
                         f"every elimination order has a clique over at least {est.width} "
                         f"variables, at least {est.lower_bound:.3g} entries",
                         entries=est.entries, width=est.width)
        n, cards = model.n, model.cards
        self.order = np.asarray(order, dtype=np.intp)
        pos = [0] * n
        for i, v in enumerate(order):
            pos[v] = i
        self.parent = np.full(n, -1, dtype=np.intp)
        nb_of = [()] * n
        for v, nb in zip(order, nbrs, strict=True):
            nb_of[v] = nb
            if nb:
                self.parent[v] = min(nb, key=pos.__getitem__)
        # merge: v joins the node of a child c with N_c = C_v (then C_v is a subset of C_c)
        node_of = [-1] * n
        owned_vars: list[list] = []    # per node, in elimination order
        last_child = [-1] * n          # per v: a child whose clique contains C_v, if any
        for v in order:
            c = last_child[v]
            if c >= 0:
                k = node_of[c]
                owned_vars[k].append(v)
            else:
                k = len(owned_vars)
                owned_vars.append([v])
            node_of[v] = k
            p = self.parent[v]
            if p >= 0 and last_child[p] < 0 and len(nb_of[v]) == len(nb_of[p]) + 1:
                last_child[p] = v
        # nodes in the order of their last owned variable: children before parents
        nn = len(owned_vars)
        rank = sorted(range(nn), key=lambda k: pos[owned_vars[k][-1]])
        owned_vars = [owned_vars[k] for k in rank]
        node_of = [0] * n
        for k, ov in enumerate(owned_vars):
            for v in ov:
                node_of[v] = k
        self.nodes, self.owned = [], []
        self._sep, self._shape = [], []
        self._node_parent = [-1] * nn
        self._node_children = [[] for _ in range(nn)]
        for k, ov in enumerate(owned_vars):
            last = ov[-1]
            # owned axes first, the last eliminated first (decoded first in MAP)
            vs = tuple(ov[::-1]) + nb_of[last]
            self.nodes.append(vs)
            self.owned.append(len(ov))
            self._sep.append(nb_of[last])
            self._shape.append(tuple(cards[x] for x in vs))
            p = self.parent[last]
            if p >= 0:
                self._node_parent[k] = node_of[p]
                self._node_children[node_of[p]].append(k)
        self._node_of = node_of
        # every factor to the node of its first-eliminated variable (holds its whole scope)
        assigned = [[] for _ in range(nn)]
        for f, sc in enumerate(model.scopes):
            if sc:
                assigned[node_of[min(sc, key=pos.__getitem__)]].append(f)
        self.empty_factors = [f for f, sc in enumerate(model.scopes) if not sc]
        scopes = model.scopes
        self._assigned = assigned
        self._own_axes = [tuple(range(self.owned[k])) for k in range(nn)]
        self._n_owned = [math.prod(self._shape[k][:self.owned[k]]) for k in range(nn)]
        # downward: sum beta_k over its variables outside S_c, then reorder to S_c's order
        self._down = {}
        for k in range(nn):
            C = self.nodes[k]
            for c in self._node_children[k]:
                Sc = self._sep[c]
                ns = set(Sc)
                keep = [x for x in C if x in ns]
                axes = tuple(i for i, x in enumerate(C) if x not in ns)
                perm = tuple(keep.index(x) for x in Sc)
                self._down[c] = (axes, None if perm == tuple(range(len(perm))) else perm)
        self._comp = self._components()
        # Fast nodes (linear pass): three variables, one factor over all of them, every other
        # part (unary factors, child messages, the message from the parent) over one variable.
        # Their belief is T * w0 (x) w1 (x) w2, so messages and marginals are matrix-vector
        # products of T with the per-axis vectors; the 20^3 table is never formed.
        self._fast = [None] * nn
        for k in range(nn):
            C = self.nodes[k]
            full = [f for f in assigned[k] if len(scopes[f]) == 3]
            if (len(C) != 3 or len(self._sep[k]) > 1 or len(full) != 1
                    or any(len(scopes[f]) not in (1, 3) for f in assigned[k])
                    or any(len(self._sep[c]) != 1 for c in self._node_children[k])):
                continue
            unary = [(C.index(scopes[f][0]), f) for f in assigned[k] if len(scopes[f]) == 1]
            kids = [(C.index(self._sep[c][0]), c) for c in self._node_children[k]]
            self._fast[k] = (full[0], _expander(scopes[full[0]], C, cards), unary, kids)
        # Large nodes (more than contract_above entries; e.g. a clique of 6 triplets: 20^6) are
        # never materialized in the linear pass: each message and marginal is one contraction of
        # the node's factors and messages (opt_einsum plan, rescaled steps, contract_scaled).
        # Free nodes: no factor and no child (variables in no factor): uniform, never built.
        self._free = [not assigned[k] and not self._node_children[k] for k in range(nn)]
        self._big = [self._fast[k] is None and not self._free[k]
                     and math.prod(self._shape[k]) > contract_above for k in range(nn)]
        # broadcasting plans of the factors and child messages of the nodes that build a table
        # (the others get theirs on first use: the log domain and max-product build every table)
        self._fac_ex = [None] * nn
        self._child_ex = [None] * nn
        self._expanders([k for k in range(nn) if self._fast[k] is None and not self._big[k]
                         and not self._free[k]])

    def _expanders(self, nodes=None):
        cards, scopes = self.model.cards, self.model.scopes
        for k in range(len(self.nodes)) if nodes is None else nodes:
            if self._fac_ex[k] is None:
                C = self.nodes[k]
                self._fac_ex[k] = [(f, _expander(scopes[f], C, cards)) for f in self._assigned[k]]
                self._child_ex[k] = [(c, _expander(self._sep[c], C, cards))
                                     for c in self._node_children[k]]

    def __repr__(self) -> str:
        return (f"JunctionTree(n={self.model.n}, nodes={len(self.nodes)}, width="
                f"{self.estimate.width}, largest_table={self.estimate.entries:.3g}, evidence="
                f"{len(self.evidence)}, budget={self.budget})")

    # ------------------------------------------------------------------ memory
    def _big_peak(self, k) -> float:
        """Entries a large node's contractions hold at once (linear pass): the rescaled copies of
        its operands plus, for the worst of its contractions, three times its largest
        intermediate and the next two (the same ``opt_einsum`` plans the pass runs, from shapes
        only)."""
        import opt_einsum as oe

        cards, scopes = self.model.cards, self.model.scopes
        shapes = [tuple(cards[x] for x in scopes[f]) for f in self._assigned[k]]
        terms = [self._letters(k, scopes[f]) for f in self._assigned[k]]
        for c in self._node_children[k]:
            shapes.append(tuple(cards[x] for x in self._sep[c]))
            terms.append(self._letters(k, self._sep[c]))
        eqs = []
        lhs = ",".join(terms)
        eqs.append((f"{lhs}->{self._letters(k, self._sep[k])}", shapes))
        if self._node_parent[k] >= 0:
            shapes = shapes + [tuple(cards[x] for x in self._sep[k])]
            lhs = lhs + "," + self._letters(k, self._sep[k])
        C = self.nodes[k]
        outs = [(C[i],) for i in range(self.owned[k])] + [self._sep[c]
                                                          for c in self._node_children[k]]
        eqs += [(f"{lhs}->{self._letters(k, o)}", shapes) for o in outs]
        worst = 0.0
        for eq, shp in eqs:
            _, info = oe.contract_path(eq, *shp, shapes=True, optimize="auto")
            inter = sorted((float(x) for x in getattr(info, "size_list", ())), reverse=True)
            # a step holds its inputs, its result and the result's rescaled copy; tensordot
            # may copy a transposed input as well
            big = inter[0] if inter else float(info.largest_intermediate)
            worst = max(worst, 3 * big + sum(inter[1:3]))
        return worst + float(sum(math.prod(sh) for sh in shapes))

    @property
    def contracted(self) -> tuple[bool, ...]:
        """Per node: whether its table is too large to build and each message through it is one
        contraction of its factors and messages instead (``contract_above``)."""
        return tuple(self._big)

    def memory_estimate(self, task: str = "MAR", k: int = 1, log_domain: bool = False):
        """Peak bytes the engine allocates for ``task`` beyond the model itself, from the plan
        alone (no table is built): a :class:`~qfg.inference.memory.MemoryEstimate`.

        ``"MAR"``/``"PR"``: one calibration. Linear pass: the scaled copies of the factor
        tables, every clique table it materializes (kept from the upward to the downward pass),
        the messages, the (n, max card) result, plus the largest transient of one node (the
        product being built and its broadcast successor: two clique tables; a contracted node:
        its operands' copies and about four of its largest intermediates). ``log_domain=True``
        (or the log-domain retry): every clique table is built, plus four clique-sized
        temporaries. ``"MAP"``: one calibration (for
        ``log Z``), then max-product: every clique table kept for decoding. ``"KBEST"``: that,
        and Lawler-Murty's queue: up to ``1 + (k - 1) n`` subproblems of an (n, max card) mask
        each.
        """
        from .memory import MemoryEstimate

        task = str(task).upper()
        if task not in ("MAR", "PR", "MAP", "MPE", "KBEST"):
            raise ValueError(f"task: expected MAR, PR, MAP or KBEST, got {task!r}")
        model = self.model
        n = model.n
        nn = len(self.nodes)
        cmax = max(model.cards) if n else 0
        seen, tables = set(), 0.0
        for t in model.tables:
            if id(t) not in seen:
                seen.add(id(t))
                tables += t.size
        sizes = [float(math.prod(sh)) for sh in self._shape]
        live = [not f for f in self._free]
        msgs = sum(float(math.prod(self.model.cards[x] for x in self._sep[c])) for c in range(nn))
        result = float(n * cmax)
        # Python objects: a fixed part, then array headers, lists and tuples per node
        overhead = 65536.0 + 2000.0 * nn
        # linear pass: (contiguous transposes of shared tables: at most 6 per table)
        lin_persist = sum(sz for kk, sz in enumerate(sizes)
                          if live[kk] and self._fast[kk] is None and not self._big[kk])
        lin_trans = 0.0
        for kk in range(nn):
            if not live[kk] or self._fast[kk] is not None:
                continue
            # building a table: the product so far and its broadcast successor coexist
            lin_trans = max(lin_trans, self._big_peak(kk) if self._big[kk] else 2 * sizes[kk])
        linear = 8 * (2 * tables + lin_persist + lin_trans + 2 * msgs + result)
        logd = 8 * (tables + sum(sz for kk, sz in enumerate(sizes) if live[kk])
                    + 4 * max((sz for kk, sz in enumerate(sizes) if live[kk]), default=0.0)
                    + 2 * msgs + result)
        cal = logd if log_domain else linear
        parts = {"tables": 8 * tables, "linear_pass": linear, "log_pass": logd}
        if task in ("MAR", "PR"):
            total = cal
        else:
            mp = 8 * (tables + sum(sz for kk, sz in enumerate(sizes) if live[kk])
                      + 2 * max((sz for kk, sz in enumerate(sizes) if live[kk]), default=0.0)
                      + msgs + n)
            queue = 0.0
            if task == "KBEST":
                entries = 1.0 + (float(k) - 1.0) * n
                queue = entries * (n * cmax + 8 * n + 300) + float(k) * (8 * n + 100)
            parts.update(max_product=mp, queue=queue)
            total = max(cal, mp + queue)
        return MemoryEstimate(bytes=float(total + overhead), task=task, parts=parts)

    def _check(self, task, k=1, log_domain=False):
        from .memory import check_memory

        est = self.memory_estimate(task, k=k, log_domain=log_domain)
        check_memory(est.bytes, self.budget, f"{task} on this junction tree",
                     ", ".join(f"{a} {b:.3g}" for a, b in est.parts.items()),
                     entries=self.estimate.entries, width=self.estimate.width)
        return est

    # ------------------------------------------------------------------ helpers
    def _components(self):
        root = [0] * self.model.n
        parent = self.parent.tolist()
        for v in self.order[::-1].tolist():
            p = parent[v]
            root[v] = v if p < 0 else root[p]
        return np.asarray(root, dtype=np.intp)

    def _scaled_tables(self, log: bool):
        """Factor tables rescaled to max 1 (linear) or their logs minus the max, and the total log
        of the scales removed."""
        tabs, scale = [], 0.0
        cache = {}
        # the unary tables (priors) of one length in one batch: one max and one division
        by_len: dict[int, list] = {}
        for t in self.model.tables:
            if t.ndim == 1 and id(t) not in cache:
                cache[id(t)] = None
                by_len.setdefault(len(t), []).append(t)
        cache.clear()
        for group in by_len.values():
            S = np.stack(group)
            mx = S.max(axis=1)
            pos = mx > 0
            with np.errstate(divide="ignore"):
                lmx = np.log(np.where(pos, mx, 1.0))
                if log:
                    R = np.where(pos[:, None], np.log(S) - lmx[:, None], -np.inf)
                else:
                    R = S / np.where(pos, mx, 1.0)[:, None]   # zero rows stay zero
            for t, r, ls in zip(group, R, lmx.tolist(), strict=True):
                cache[id(t)] = (r, ls)
        for t in self.model.tables:
            key = id(t)
            if key not in cache:
                mx = float(t.max())
                if not mx > 0:
                    cache[key] = (np.full(t.shape, -np.inf) if log else np.zeros(t.shape), 0.0)
                else:
                    with np.errstate(divide="ignore"):
                        cache[key] = ((np.log(t) - math.log(mx)) if log else t / mx, math.log(mx))
            tt, s = cache[key]
            tabs.append(tt)
            scale += s
        return tabs, scale

    def _zero_mass(self, v):
        comp = np.flatnonzero(self._comp == self._comp[v])
        names = self.model.names
        trip = [names[u] for u in comp] if names else [int(u) for u in comp]
        local = []
        unary = {s[0]: t for s, t in zip(self.model.scopes, self.model.tables, strict=True)
                 if len(s) == 1}
        for s, t in zip(self.model.scopes, self.model.tables, strict=True):
            if len(s) < 2 or not set(s) <= set(comp.tolist()):
                continue
            w = t
            for ax, u in enumerate(s):
                if u in unary:
                    shp = [1] * len(s)
                    shp[ax] = -1
                    w = w * unary[u].reshape(shp)
            if not w.max() > 0:
                local.append(tuple(names[u] for u in s) if names else s)
        why = (f"{len(local)} factor(s) contradict the priors of their own triplets, e.g. "
               f"{local[0]}" if local else
               "no single factor contradicts its priors: the contradiction runs through a loop "
               "or a chain of factors")
        return ZeroMassError(
            f"g: the product of the factors has no mass on the connected component of "
            f"{len(comp)} variable(s) containing {trip[0] if trip else v}: the priors contradict "
            f"the tensor's support ({why})", triplets=trip, local_factors=local)

    # ------------------------------------------------------------------ sum-product
    def _calibrate(self, log: bool):
        """Returns (marginals (n, card_max) padded, log Z) or None if linear arithmetic lost the
        mass (caller retries in the log domain)."""
        model = self.model
        n = model.n
        nn = len(self.nodes)
        tabs, log_scale = self._scaled_tables(log)
        e_psi = [0.0] * nn         # linear: absolute error bounds (values scaled to max 1)
        e_up = [0.0] * nn
        e_down = [0.0] * nn
        psi_store = [None] * nn
        up = [None] * nn
        logz = log_scale
        children = self._node_children
        contiguous = {}  # a table shared by many factors (the tensor) transposed once per order

        def expand(f, ex):
            perm, shp = ex
            t = tabs[f]
            if perm != tuple(range(len(perm))):
                key = (id(t), perm)
                if key not in contiguous:
                    contiguous[key] = np.ascontiguousarray(t.transpose(perm))
                t = contiguous[key]
            return t.reshape(shp)

        fast = self._fast if not log else [None] * nn
        for k in range(nn):
            shape = self._shape[k]
            if self._free[k]:          # uniform: sum of ones = the table size, message 1
                logz += sum(math.log(c) for c in shape)
                up[k] = np.zeros(()) if log else np.ones(())
                continue
            if fast[k] is not None:
                f, ex, unary, kids = fast[k]
                Tk = expand(f, ex)
                w = [np.ones(c) for c in shape]
                for i, g in unary:
                    w[i] = w[i] * tabs[g]
                for i, c in kids:
                    w[i] = w[i] * up[c]
                A, B, Cc = shape
                if self.owned[k] == 3:
                    u = np.asarray(((w[0] @ Tk.reshape(A, B * Cc)).reshape(B, Cc) @ w[2]) @ w[1])
                else:
                    u = ((w[0] @ Tk.reshape(A, B * Cc)).reshape(B, Cc).T @ w[1]) * w[2]
                e_psi[k] = (len(self._assigned[k]) + len(kids)) * _TAU + sum(
                    e_up[c] for _, c in kids)
                umx = float(u.max())
                if not umx > 0:
                    return None
                u = u / umx
                e_up[k] = self._n_owned[k] * e_psi[k] / umx
                logz += math.log(umx)
                psi_store[k] = (Tk, w)
                up[k] = u
                continue
            if not log and self._big[k]:
                ops, terms = self._big_parts(k, tabs, up)
                u, ls = contract_scaled(f"{','.join(terms)}->{self._letters(k, self._sep[k])}",
                                        ops)
                e_psi[k] = (len(ops) + 1) * _TAU + sum(e_up[c] for c in children[k])
                umx = float(u.max()) * math.exp(ls) if ls > -math.inf else 0.0
                if not umx > 0:
                    return None
                u = u / float(u.max())
                e_up[k] = self._n_owned[k] * e_psi[k] / umx
                logz += math.log(umx)
                psi_store[k] = (ops, terms)
                up[k] = u
                continue
            if self._fac_ex[k] is None:
                self._expanders([k])
            psi = None
            parts = [expand(f, ex) for f, ex in self._fac_ex[k]]
            parts += [_expand(up[c], ex) for c, ex in self._child_ex[k]]
            if len(parts) >= 2:  # the first product allocates; the rest are in place
                psi = parts[0] + parts[1] if log else parts[0] * parts[1]
                parts = parts[2:]
            for t in parts:
                if psi is None:
                    psi = t.copy() if t.shape == shape else np.broadcast_to(t, shape).copy()
                elif log:
                    psi = psi + t if psi.shape != shape else np.add(psi, t, out=psi)
                else:
                    psi = psi * t if psi.shape != shape else np.multiply(psi, t, out=psi)
            if psi is None:
                psi = np.zeros(shape) if log else np.ones(shape)
            elif psi.shape != shape:
                psi = np.broadcast_to(psi, shape).copy()
            own = self._own_axes[k]
            if log:
                mx = float(psi.max())
                if mx == -np.inf:
                    raise self._zero_mass(self.nodes[k][0])
                psi -= mx
                logz += mx
                with np.errstate(divide="ignore"):
                    u = np.log(np.exp(psi).sum(axis=own))
                umx = float(u.max())
                u -= umx
            else:
                e_psi[k] = (len(self._fac_ex[k]) + len(self._child_ex[k])) * _TAU + sum(
                    e_up[c] for c in children[k])
                u = psi.sum(axis=own)
                umx = float(u.max())
                if not umx > 0:
                    return None  # underflow or no mass: the log domain decides
                u /= umx
                e_up[k] = self._n_owned[k] * e_psi[k] / umx
            logz += math.log(umx) if not log else umx
            psi_store[k] = psi
            up[k] = u
        P = np.zeros((n, max(model.cards) if n else 0))
        down = [None] * nn
        for k in range(nn - 1, -1, -1):
            if self._free[k]:
                for v in self.nodes[k]:
                    c = model.cards[v]
                    P[v, :c] = 1.0 / c
                continue
            beta = psi_store[k]
            psi_store[k] = None
            if fast[k] is not None:
                if not self._fast_down(k, beta, down, up, P, e_psi, e_up, e_down):
                    return None
                continue
            if not log and self._big[k]:
                if not self._big_down(k, beta, down, up, P, e_psi, e_up, e_down):
                    return None
                continue
            if self._node_parent[k] >= 0:
                d = down[k]
                if log:
                    beta += d
                else:
                    beta *= d
                down[k] = None
            vs = self.nodes[k]
            no = self.owned[k]
            other = tuple(range(no, beta.ndim))
            if log:
                # relative to the clique's largest entry: what underflows here is < 1e-308 of it
                mo = np.exp(beta - beta.max())
                mo = mo.sum(axis=other) if other else mo
            else:
                mo = beta.sum(axis=other) if other else beta.copy()
            s = mo.sum()
            if not log:
                e_beta = e_psi[k] + e_down[k] + _TAU
                if not (s > 0 and beta.size * e_beta <= _REL_TOL * s):
                    return None  # the bound is not small against the mass: log domain
            if not s > 0:
                raise self._zero_mass(vs[0])
            mo = mo / s
            if no == 1:
                P[vs[0], :len(mo)] = mo
            else:
                for i in range(no):
                    mv = mo.sum(axis=tuple(j for j in range(no) if j != i))
                    P[vs[i], :len(mv)] = mv
            for c in children[k]:
                axes, perm = self._down[c]
                pad = (None,) * self.owned[c]
                if log:
                    bm = beta.max(axis=axes, keepdims=True)
                    bm = np.where(np.isfinite(bm), bm, 0.0)
                    with np.errstate(divide="ignore"):
                        red = np.log(np.exp(beta - bm).sum(axis=axes)) + bm.squeeze(axes)
                    red = red.transpose(perm) if perm is not None else red
                    uc = up[c]
                    dc = np.where(uc > -np.inf, red - np.where(uc > -np.inf, uc, 0.0), -np.inf)
                    dm = dc.max()
                    down[c] = (dc - dm if dm > -np.inf else dc)[pad]
                else:
                    red = beta.sum(axis=axes)
                    red = red.transpose(perm) if perm is not None else red
                    msg = self._separator_message(c, red, up, beta.size, e_beta, e_psi, e_up)
                    if msg is None:
                        return None
                    dc, dm, err = msg
                    down[c] = dc[pad]
                    e_down[c] = err / dm
        return P, logz

    def _separator_message(self, c, red, up, size, e_beta, e_psi, e_up):
        """Child ``c``'s downward message from ``red`` (the node's belief summed to the
        separator, ``size`` entries before the sum): ``(red / mu_c rescaled to max 1, its max,
        error bound)``, or None when it has no mass.

        Error bound of beta_c = psi_c * delta_c from this step: delta_c(x) has the error of r_c
        summed entries of beta_k divided by mu_c(x), but psi_c(., x) <= mu_c(x) (each of its n_c
        owned entries) cancels the division; where mu_c underflowed to zero, the true delta is
        at most r_c and psi_c at most its bound. The caller divides the bound by the max."""
        uc = up[c]
        pos = uc > 0
        dc = np.divide(red, uc, out=np.zeros_like(red), where=pos)
        dm = dc.max()
        if not dm > 0:
            return None
        dc /= dm
        r_c = size // red.size
        card_c = self._n_owned[c]
        err = r_c * card_c * e_beta
        if e_up[c] > 0 and not pos.all():
            err += r_c * card_c * e_psi[c]
        return dc, dm, err

    def _letters(self, k, vs) -> str:
        import opt_einsum as oe

        where = {x: i for i, x in enumerate(self.nodes[k])}
        return "".join(oe.get_symbol(where[x]) for x in vs)

    def _big_parts(self, k, tabs, up):
        """(operands, their index strings) of a large node: factors and child messages."""
        scopes = self.model.scopes
        ops, terms = [], []
        for f in self._assigned[k]:
            ops.append(tabs[f])
            terms.append(self._letters(k, scopes[f]))
        for c in self._node_children[k]:
            ops.append(up[c])
            terms.append(self._letters(k, self._sep[c]))
        return ops, terms

    def _big_down(self, k, parts, down, up, P, e_psi, e_up, e_down) -> bool:
        """Downward step of a large node: the mass, every owned marginal and every child's
        separator sum, each one contraction (same error bound as a materialized node)."""
        ops, terms = list(parts[0]), list(parts[1])
        if self._node_parent[k] >= 0:
            ops.append(np.asarray(down[k]).reshape([self.model.cards[x] for x in self._sep[k]]))
            terms.append(self._letters(k, self._sep[k]))
            down[k] = None
        lhs = ",".join(terms)
        C = self.nodes[k]
        size = math.prod(self._shape[k])
        e_beta = e_psi[k] + e_down[k] + _TAU
        s_abs = None
        for i in range(self.owned[k]):
            mv, ls = contract_scaled(f"{lhs}->{self._letters(k, (C[i],))}", ops)
            tot = float(mv.sum())
            if s_abs is None:
                s_abs = tot * math.exp(ls) if ls > -math.inf else 0.0
                if not (s_abs > 0 and size * e_beta <= _REL_TOL * s_abs):
                    return False
            P[C[i], :len(mv)] = mv / tot
        for c in self._node_children[k]:
            red, ls = contract_scaled(f"{lhs}->{self._letters(k, self._sep[c])}", ops)
            msg = self._separator_message(c, red, up, size, e_beta, e_psi, e_up)
            if msg is None or not ls > -math.inf:
                return False
            dc, dm, err = msg
            down[c] = dc[(None,) * self.owned[c]]
            dm_abs = dm * math.exp(ls)           # red was rescaled: the bound is absolute
            if not dm_abs > 0:
                return False
            e_down[c] = err / dm_abs
        return True

    def _fast_down(self, k, tw, down, up, P, e_psi, e_up, e_down) -> bool:
        """Downward step of a fast node (see ``_fast``): marginals and child messages from
        matrix-vector products; False when the linear pass must give way to the log domain."""
        Tk, w = tw
        A, B, Cc = self._shape[k]
        if self._node_parent[k] >= 0:
            w = [w[0], w[1], w[2] * down[k].ravel()]
            down[k] = None
        X = (Tk.reshape(A * B, Cc) @ w[2]).reshape(A, B)
        Z = (w[0] @ Tk.reshape(A, B * Cc)).reshape(B, Cc)
        ms = (w[0] * (X @ w[1]), w[1] * (w[0] @ X), w[2] * (w[1] @ Z))
        s = float(ms[0].sum())
        size = A * B * Cc
        e_beta = e_psi[k] + e_down[k] + _TAU
        if not (s > 0 and size * e_beta <= _REL_TOL * s):
            return False
        C = self.nodes[k]
        for i in range(self.owned[k]):
            P[C[i], :len(ms[i])] = ms[i] / s
        for i, c in self._fast[k][3]:
            red = ms[i]
            msg = self._separator_message(c, red, up, size, e_beta, e_psi, e_up)
            if msg is None:
                return False
            dc, dm, err = msg
            down[c] = dc[(None,) * self.owned[c]]
            e_down[c] = err / dm
        return True

    def marginals(self, log_domain: bool = False) -> np.ndarray:
        """(n, max card) marginal of every variable, one calibration (rows padded with zeros
        when cardinalities differ). ``log_domain=True`` skips the linear attempt."""
        return self.calibrate(log_domain)[0]

    def calibrate(self, log_domain: bool = False):
        """(marginals, log Z, domain used: "linear" or "log") of the (clamped) model.

        Checked against the memory budget first (:meth:`memory_estimate`); the log-domain retry,
        which builds every clique table, is checked again before it starts."""
        self._check("MAR", log_domain=bool(log_domain))
        if not log_domain:
            out = self._calibrate(log=False)
            if out is not None:
                return self._expand(out[0]), out[1], "linear"
            self._check("MAR", log_domain=True)
        P, logz = self._calibrate(log=True)
        return self._expand(P), logz, "log"

    def _expand(self, P):
        if not self.evidence:
            return P
        from .evidence import expand_marginals

        return expand_marginals(P, self.source, self.evidence)

    def log_partition(self) -> float:
        """``log Z`` (``log Z(e)`` with evidence): the log of the sum over all joint assignments
        (consistent with the evidence) of the factor product."""
        return self.calibrate()[1]

    # ------------------------------------------------------------------ max-product
    def _max_product(self, tabs, mask=None):
        """(assignment (n,), unnormalized log value) or (None, -inf) if no assignment has mass."""
        self._expanders([k for k in range(len(self.nodes)) if not self._free[k]])
        model = self.model
        n = model.n
        nn = len(self.nodes)
        store = [None] * nn
        up = [None] * nn
        total = 0.0
        for k in range(nn):
            shape = self._shape[k]
            if self._free[k]:     # no factor: any allowed state, the lowest one
                for v in self.nodes[k]:
                    if mask is not None and not mask[v, :model.cards[v]].any():
                        return None, -np.inf
                up[k] = np.zeros(())
                continue
            psi = np.zeros(shape)
            for f, ex in self._fac_ex[k]:
                psi += _expand(tabs[f], ex)
            for c, ex in self._child_ex[k]:
                psi += _expand(up[c], ex)
            if mask is not None:
                for i in range(self.owned[k]):
                    shp = [1] * len(shape)
                    shp[i] = shape[i]
                    v = self.nodes[k][i]
                    psi += np.where(mask[v, :shape[i]], 0.0, -np.inf).reshape(shp)
            u = psi.max(axis=self._own_axes[k])
            mx = float(u.max())
            if mx == -np.inf:
                return None, -np.inf
            store[k] = psi
            up[k] = u - mx
            total += mx
        x = np.zeros(n, dtype=np.intp)
        for k in range(nn - 1, -1, -1):
            C = self.nodes[k]
            if self._free[k]:
                for v in C:
                    x[v] = 0 if mask is None else int(np.argmax(mask[v, :model.cards[v]]))
                continue
            no = self.owned[k]
            col = store[k][(slice(None),) * no + tuple(int(x[u]) for u in C[no:])]
            best = np.unravel_index(int(np.argmax(col)), col.shape)
            for i in range(no):
                x[C[i]] = int(best[i])
        return x, total

    def _log_tables(self):
        tabs = []
        cache = {}
        with np.errstate(divide="ignore"):
            for t in self.model.tables:
                if id(t) not in cache:
                    cache[id(t)] = np.log(t)
                tabs.append(cache[id(t)])
        return tabs

    def map_assignment(self):
        """(x (n,) most probable joint assignment, log p(x) under the normalized joint).

        Ties are broken towards the lower state of the variable decoded first."""
        X, lp = self.k_best(1)
        return X[0], float(lp[0])

    def k_best(self, k: int):
        """The ``k`` most probable joint assignments: ((K, n) states, (K,) log probabilities),
        best first, K <= k (fewer when fewer assignments have non-zero probability).

        Lawler-Murty partitioning: after the best assignment ``x`` of a subspace (states allowed
        per variable), the rest of that subspace splits into the subspaces "first i - 1 variables
        as in x, variable i not as in x" (variables in elimination order reversed), each solved by
        one max-product pass; a heap yields the next best."""
        from .._validate import positive_int

        k = positive_int("k", k)
        self._check("KBEST" if k > 1 else "MAP", k=k)
        model = self.model
        n = model.n
        logz = self.log_partition()
        tabs = self._log_tables()
        if n == 0:
            return np.zeros((1, 0), dtype=np.intp), np.array([0.0 - logz])
        cmax = max(model.cards)
        mask0 = np.zeros((n, cmax), dtype=bool)
        for v, c in enumerate(model.cards):
            mask0[v, :c] = True
        x, val = self._max_product(tabs, None)
        if x is None:
            raise self._zero_mass(0)
        heap = [(-val, 0, x, mask0)]
        counter = 1
        seq = self.order[::-1].tolist()
        out_x, out_v = [], []
        while heap and len(out_x) < k:
            negv, _, x, mask = heapq.heappop(heap)
            out_x.append(x)
            out_v.append(-negv)
            if len(out_x) == k:
                break
            m = mask.copy()
            for v in seq:
                child = m.copy()
                child[v, x[v]] = False
                if child[v].any():
                    y, yv = self._max_product(tabs, child)
                    if y is not None:
                        heapq.heappush(heap, (-yv, counter, y, child))
                        counter += 1
                m[v] = False
                m[v, x[v]] = True
        X = np.array(out_x, dtype=np.intp).reshape(-1, n)
        # exact log values from the original tables (not the running max-product sums)
        lp = model.log_value(X) - logz
        for v, x_v in self.evidence.items():     # clamped variables kept their one state
            X[:, v] = x_v
        return X, lp
