"""Loopy belief propagation on a :class:`~qfg.graph.QualitativeFactorGraph`: damped synchronous
sum-product on the seen triplets' priors and the composition factors (:func:`loopy_bp`), its
memory estimate (:func:`loopy_bp_memory`) and its warnings, for maps whose factors overlap too
much for BP (:class:`DenseMapWarning`) and for messages that did not converge
(:class:`NotConvergedWarning`).

It returns the labelled :class:`~qfg.inference.Marginals` of the exact engines; exact on trees,
an approximation on loopy graphs.
"""

from __future__ import annotations

import numpy as np

from .results import Marginals

__all__ = ["loopy_bp", "loopy_bp_memory", "NotConvergedWarning", "DenseMapWarning",
           "BP_OVERLAP_WARN", "BP_DEGREE_WARN", "role_matrices"]


def _normalize_rows(a: np.ndarray) -> np.ndarray:
    s = a.sum(axis=-1, keepdims=True)
    m = a.shape[-1]
    ok = s > np.finfo(float).tiny
    return np.where(ok, a / np.where(ok, s, 1.0), 1.0 / m)


def role_matrices(T: np.ndarray) -> list[np.ndarray]:
    """Per role r, T with axis r first, flattened to (m, m*m) over the other two (in order):
    the factor-to-variable message of role r is ``(q_x outer q_y) @ M_r.T``, one matrix product
    for all factors."""
    m = T.shape[0]
    return [np.ascontiguousarray(np.moveaxis(T, r, 0).reshape(m, m * m)) for r in range(3)]


#: :func:`loopy_bp` warns (:class:`DenseMapWarning`) when at least this share of the composition
#: factors share two triplets with another factor and the triplets are in at least
#: :data:`BP_DEGREE_WARN` factors on average (:func:`qfg.graph.factor_overlap`). Chosen on
#: development graphs; measured in docs/graph.md ("Loopy BP on dense maps").
BP_OVERLAP_WARN = 0.25
BP_DEGREE_WARN = 2.5


class DenseMapWarning(UserWarning):
    """Loopy BP on a graph whose composition factors overlap so much that its marginals are
    typically worse than uniform (see :data:`BP_OVERLAP_WARN`, :data:`BP_DEGREE_WARN`)."""


class NotConvergedWarning(UserWarning):
    """Loopy BP stopped at ``max_iters`` before its messages converged."""


def loopy_bp_memory(n: int, F: int, m: int) -> float:
    """Peak bytes of :func:`loopy_bp`: the messages and their update ((F, 3, m) each), the
    per-chunk temporaries and the (n, m) beliefs (twice: the log and the exponent)."""
    chunk = max(1, (1 << 22) // (m * m))
    per_chunk = min(F, chunk) * (3 * m * m + 12 * m)   # outer products: a new one and the last
    return 8.0 * (2 * 3 * F * m + 3 * n * m + per_chunk) + 64.0 * F


def loopy_bp(g, damping: float = 0.0, max_iters: int = 100, tol: float = 1e-9, *,
             memory=None, warn: bool = True) -> Marginals:
    """Damped synchronous sum-product on the priors and composition factors.

    Messages (all normalized): variable -> factor ``q_{v->f} propto prior_v prod_{f' != f}
    r_{f'->v}``; factor -> variable ``r_{f->v}(s) propto sum over the other two states of
    T(...) q q`` (per role one (F, m^2) x (m^2, m) matrix product), then
    ``r <- (1 - damping) r_new + damping r_old``. Stops when the largest change of an ``r`` is
    below ``tol`` (converged) or after ``max_iters``. Beliefs: ``prior prod r``. Exact on trees
    (once the iterations exceed the tree's diameter).

    Dense maps: when composition factors overlap (:func:`qfg.graph.factor_overlap`: a share of at
    least :data:`BP_OVERLAP_WARN` of the factors share two triplets with another, and triplets are
    in :data:`BP_DEGREE_WARN` factors or more on average), BP counts evidence around the 4-loops
    of factor pairs sharing two triplets and its marginals are confidently wrong (docs/graph.md);
    it warns
    (:class:`DenseMapWarning`), and warns (:class:`NotConvergedWarning`) when it stops unconverged.
    ``warn=False`` silences both (the result's ``info`` still says). ``memory``: budget in bytes
    (:func:`~qfg.inference.memory.memory_budget`); the messages over it ->
    :class:`~qfg.inference.memory.MemoryBudgetError` before any work.

    Returns a :class:`~qfg.inference.Marginals` (``method="loopy-bp"``; ``info``: ``converged``,
    ``iterations``, ``max_change`` (last largest message change), ``damping``, ``overlap``).

    >>> import numpy as np
    >>> from qfg.graph import QualitativeFactorGraph
    >>> T = np.zeros((2, 2, 2)); T[0, 0, 0] = T[1, 1, 1] = 1
    >>> g = QualitativeFactorGraph("lr", tensor=T)
    >>> for t, p in [((0, 1, 2), [0.9, 0.1]), ((1, 2, 3), None), ((0, 1, 3), None)]:
    ...     _ = g.add_triplet(t, p)
    >>> _ = g.discover_compositions()
    >>> r = loopy_bp(g)
    >>> r.probabilities.round(2).tolist(), r.converged
    ([[0.9, 0.1], [0.9, 0.1], [0.9, 0.1]], True)
    """
    import warnings

    from ..graph import factor_overlap
    from .memory import check_memory, memory_budget

    if isinstance(damping, bool) or not isinstance(damping, (int, float, np.integer, np.floating)):
        raise ValueError(f"damping: expected a number in [0, 1), got {damping!r}")
    damping = float(damping)
    if not 0.0 <= damping < 1.0:
        raise ValueError(f"damping: expected 0 <= damping < 1, got {damping!r}")
    if isinstance(max_iters, bool) or not isinstance(max_iters, (int, np.integer)) or max_iters < 1:
        raise ValueError(f"max_iters: expected a positive integer, got {max_iters!r}")
    if isinstance(tol, bool) or not isinstance(tol, (int, float, np.integer, np.floating)):
        raise ValueError(f"tol: expected a positive number, got {tol!r}")
    tol = float(tol)
    if not tol > 0:
        raise ValueError(f"tol: expected a positive number, got {tol!r}")
    budget = memory_budget(memory)
    m = g.m
    n = g.n_triplets
    fv = g.factor_vars
    F = len(fv)
    check_memory(loopy_bp_memory(n, F, m), budget, "loopy_bp",
                 f"messages of {F} factors x 3 roles x {m} states, twice")
    ov = factor_overlap(g)
    if warn and ov["overlap"] >= BP_OVERLAP_WARN and ov["mean_degree"] >= BP_DEGREE_WARN:
        warnings.warn(
            f"loopy_bp: {ov['overlap']:.0%} of the composition factors share two triplets with "
            f"another factor (mean {ov['mean_degree']:.1f} factors per triplet): on maps this "
            f"dense BP's marginals are typically worse than uniform (docs/graph.md); prefer "
            f"exact_marginals() where it fits, or propagate()", DenseMapWarning, stacklevel=2)
    T = g.table
    T = T / T.max()
    mats = role_matrices(T)
    logp = np.log(np.maximum(g.prior_matrix(), 1e-300))
    r = np.full((F, 3, m), 1.0 / m)
    tiny = 1e-300
    converged, it, change = F == 0, 0, 0.0
    # incidence (n, 3F): beliefs sum the log messages into their variables with one sparse product
    from scipy import sparse

    # CSC: the columns of one chunk of factors are one cheap slice
    inc = sparse.csc_matrix((np.ones(3 * F), (fv.ravel(), np.arange(3 * F))), shape=(n, 3 * F))
    others = ((1, 2), (0, 2), (0, 1))
    chunk = max(1, (1 << 22) // (m * m))     # bound the (chunk, m^2) outer products (32 MiB)

    def beliefs(rr):
        B = logp.copy()
        for lo in range(0, F, chunk):         # in chunks: no (F, 3, m) temporary of logs
            hi = min(F, lo + chunk)
            B += inc[:, 3 * lo:3 * hi] @ np.log(np.maximum(rr[lo:hi], tiny)).reshape(-1, m)
        return B

    new = np.empty_like(r)
    while not converged and it < max_iters:
        it += 1
        B = beliefs(r)
        change = 0.0
        for lo in range(0, F, chunk):     # per chunk: no (F, 3, m) temporaries
            rs = r[lo:lo + chunk]
            lq = B[fv[lo:lo + chunk]] - np.log(np.maximum(rs, tiny))  # exclude own message
            q = _normalize_rows(np.exp(lq - lq.max(axis=-1, keepdims=True)))
            out = new[lo:lo + chunk]
            for role, (x, y) in enumerate(others):
                outer = (q[:, x, :, None] * q[:, y, None, :]).reshape(len(q), m * m)
                np.matmul(outer, mats[role].T, out=out[:, role])
            msg = _normalize_rows(out)
            if damping:
                msg = (1 - damping) * msg + damping * rs
            change = max(change, float(np.abs(msg - rs).max()) if len(msg) else 0.0)
            out[...] = msg
        r, new = new, r
        converged = change < tol
    lb = beliefs(r)
    b = np.exp(lb - lb.max(axis=-1, keepdims=True))
    if warn and not converged:
        warnings.warn(f"loopy_bp: not converged after {it} iterations (largest message change "
                      f"{change:.3g} > tol={tol:g}); raise max_iters or damping",
                      NotConvergedWarning, stacklevel=2)
    return Marginals(tuple(g.triplets), g.partition, _normalize_rows(b), "loopy-bp",
                     {"converged": bool(converged), "iterations": it, "max_change": change,
                      "damping": damping, "overlap": ov["overlap"]})

