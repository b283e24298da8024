"""The qualitative factor graph (paper section 5b; conventions.md, "Qualitative factor graph").

Variables are ordered landmark triplets ``(i, j, k)`` = ``S^{ij:k}``, each with m states (m from
the composition tensor). Factors:

* unary: for a seen triplet, its single-triplet estimate ``P(S | H)`` (an (m,) vector);
* composition: for landmarks ``(i, j, k, s)`` with ``(i, j, k)``, ``(j, k, s)``, ``(i, j, s)`` all in
  the map, the tensor ``T[a, b, c]`` over the states of those three triplets, in that order
  (t1 = AB:C, t2 = BC:D, t3 = AB:D with A, B, C, D = i, j, k, s).

The joint is the normalized product of all factors. Inference is a layer above this module (the
graph imports none of it): :func:`qfg.inference.exact_marginals` (one junction-tree calibration),
:func:`qfg.inference.map_assignment`, :func:`qfg.propagation.propagate` (the paper's
label-correcting Algorithm 2), :func:`qfg.inference.loopy_bp` (sum-product).

Key scheme. Triplet ``(i, j, k)`` is the GTSAM DiscreteKey ``(triplet_key(i, j, k), m)`` with
``triplet_key(i, j, k) = (i << 40) | (j << 20) | k`` (:data:`KEY_BITS` = 20 bits per landmark id,
ids in ``[0, 2**20)``): injective, and independent of which other triplets are in the map, so a
triplet keeps its key as the map grows. Inside the graph, variables are numbered in insertion
order (``g.triplets[v]``), factors in the order they were added (``g.factors[f]`` = ``(i, j, k, s)``,
``g.factor_vars[f]`` = the three variable indices); :meth:`discover_compositions` adds new factors
in lexicographic ``(i, j, k, s)`` order, so the same calls give the same graph.

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> T = rng.random((3, 3, 3))
>>> g = full_map(4, partition=None, tensor=T)        # None: an unlabelled 3-state tensor
>>> g.n_triplets, g.n_factors
(24, 24)
>>> g.to_gtsam().size()
24
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from .composition import as_table

__all__ = ["QualitativeFactorGraph", "triplet_key", "full_map", "map_from_triplets",
           "map_from_histories", "truth_states", "KEY_BITS", "brute_force_compositions",
           "factor_overlap"]

#: Bits per landmark id in :func:`triplet_key`.
KEY_BITS = 20
_MAX_ID = 1 << KEY_BITS


def triplet_key(i: int, j: int, k: int) -> int:
    """GTSAM key of triplet ``(i, j, k)``: ``(i << 40) | (j << 20) | k``.

    The ids must be distinct integers in ``[0, 2**20)`` (ValueError naming ``triplet``
    otherwise): outside that range two triplets would share a key.

    >>> triplet_key(0, 1, 2) == (1 << 20) + 2
    True
    """
    i, j, k = _as_triplet((i, j, k))
    return (i << (2 * KEY_BITS)) | (j << KEY_BITS) | k


def _as_triplet(triplet) -> tuple[int, int, int]:
    try:
        t = tuple(triplet)
    except TypeError:
        raise ValueError(f"triplet: expected three landmark ids (i, j, k), got {triplet!r}") from None
    if len(t) != 3:
        raise ValueError(f"triplet: expected three landmark ids (i, j, k), got {triplet!r}")
    out = []
    for x in t:
        if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, np.integer)):
            raise ValueError(f"triplet: landmark ids must be integers, got {triplet!r}")
        if not 0 <= int(x) < _MAX_ID:
            raise ValueError(f"triplet: landmark ids must be in [0, {_MAX_ID}), got {triplet!r}")
        out.append(int(x))
    if len(set(out)) != 3:
        raise ValueError(f"triplet: landmark ids must be distinct, got {triplet!r}")
    return out[0], out[1], out[2]


def _as_prior(prior, m: int) -> np.ndarray | None:
    """(m,) normalized prior from a vector or a TripletEstimate-like object (``.landmark``)."""
    if prior is None:
        return None
    if hasattr(prior, "landmark") and not isinstance(prior, np.ndarray):
        prior = prior.landmark
    try:
        p = np.asarray(prior, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"prior: expected an ({m},) vector or a TripletEstimate, "
                         f"got {type(prior).__name__}") from None
    if p.shape != (m,):
        raise ValueError(f"prior: expected shape ({m},), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("prior: non-finite values (NaN or inf)")
    if np.any(p < 0):
        raise ValueError("prior: expected non-negative values")
    top = p.max() if p.size else 0.0
    if not top > 0:
        raise ValueError("prior: all zero, cannot be normalized")
    # divide by the largest entry first: the sum of entries near 1e308 would overflow to inf
    p = p / top
    return p / p.sum()


def _check_partition(partition, tensor) -> str | None:
    """The lower-cased partition name (one :func:`qfg.partitions.available` knows), or None for
    an unlabelled model (then ``tensor`` is required)."""
    if partition is None:
        if tensor is None:
            raise ValueError("partition: None (an unlabelled model) needs a tensor")
        return None
    from .partitions import available

    if not isinstance(partition, str) or partition.lower() not in available():
        raise ValueError(f"partition: unknown name {partition!r}; known: "
                         f"{', '.join(available())} (or None for an unlabelled tensor)")
    return partition.lower()


def _check_tensor(tensor, partition) -> np.ndarray:
    """(m, m, m) table of ``tensor``; with a partition name, m must be its number of states and
    a CompositionTensor must be that partition's."""
    name = getattr(tensor, "partition", None)
    if partition is not None and isinstance(name, str) and name.lower() != partition:
        raise ValueError(f"tensor: a {name!r} composition tensor, but the graph's partition is "
                         f"{partition!r}")
    try:
        T = as_table(tensor)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"tensor: expected an (m, m, m) table or a CompositionTensor ({exc})"
                         ) from None
    if T.ndim != 3 or len(set(T.shape)) != 1 or T.shape[0] < 1:
        raise ValueError(f"tensor: expected shape (m, m, m), got {T.shape}")
    if not np.all(np.isfinite(T)) or np.any(T < 0) or not T.max() > 0:
        raise ValueError("tensor: expected finite non-negative entries, not all zero")
    if partition is not None:
        from .partitions import get

        m = len(get(partition).labels)
        if T.shape[0] != m:
            raise ValueError(f"tensor: shape {T.shape}, but partition {partition!r} has {m} "
                             f"states (pass partition=None for an unlabelled tensor)")
    return T


class QualitativeFactorGraph:
    """A qualitative map as a discrete factor graph.

    Args:
        partition: partition name (``"edc"``, ``"fdc"``, ``"lr"``, ``"tpcc"`` or a registered
            one; ValueError naming it otherwise); labels the states and names the shipped
            tensor. None: an unlabelled model over any ``tensor`` (tests, custom models).
        tensor: (m, m, m) composition tensor or a :class:`~qfg.composition.CompositionTensor`,
            m = the partition's number of states; None loads
            ``qfg.composition.tensor(partition)`` on first use.

    Attributes (read-only views):
        triplets: list of ``(i, j, k)`` in insertion order (variable index v).
        priors: list of (m,) normalized priors or None (unseen), per variable.
        factors: list of ``(i, j, k, s)`` composition factors; ``factor_vars`` (F, 3) int array
            of variable indices (t1, t2, t3) = ((i,j,k), (j,k,s), (i,j,s)).

    >>> import numpy as np
    >>> g = QualitativeFactorGraph("lr", tensor=np.ones((2, 2, 2)) / 8)     # LR: 2 states
    >>> for t in [(0, 1, 2), (1, 2, 3), (0, 1, 3)]:
    ...     _ = g.add_triplet(t, prior=[0.9, 0.1] if t != (0, 1, 3) else None)
    >>> g.discover_compositions()
    1
    >>> g.factors, g.seen.tolist()
    ([(0, 1, 2, 3)], [True, True, False])
    """

    def __init__(self, partition: str | None = "edc", tensor=None):
        self.partition = _check_partition(partition, tensor)
        self._table = None if tensor is None else _check_tensor(tensor, self.partition)
        self._triplets: list[tuple[int, int, int]] = []
        self._index: dict[tuple[int, int, int], int] = {}
        self._priors: list[np.ndarray | None] = []
        # Factors in numpy blocks (a full 50-landmark map has 5.5 million): landmark ids (k, 4)
        # and variable indices (k, 3), consolidated on first use. A factor (i, j, k, s) is keyed
        # by (index of (i, j, k)) << KEY_BITS | s; keys of factors added one at a time live in a
        # dict, those added by discovery in a sorted array.
        self._fl_parts: list[np.ndarray] = []
        self._fv_parts: list[np.ndarray] = []
        self._pending: list[tuple] = []          # (key, ids, vars) added one at a time
        self._composed = False                   # discover_compositions or add_composition ran
        self._single: dict[int, int] = {}
        self._bulk_keys = np.zeros(0, dtype=np.int64)
        self._bulk_idx = np.zeros(0, dtype=np.int64)
        self._F = 0
        self._cache = None                       # (fl (F, 4), fv (F, 3)) read-only, or None
        self._csr = None                         # incidence (indptr, indices), or None

    # ----------------------------------------------------------------- tensor
    @property
    def table(self) -> np.ndarray:
        """The (m, m, m) composition tensor (loaded lazily from the partition name)."""
        if self._table is None:
            from .composition import tensor as load_tensor
            self._table = _check_tensor(load_tensor(self.partition), self.partition)
        return self._table

    @property
    def m(self) -> int:
        """Number of states per triplet."""
        return int(self.table.shape[0])

    # -------------------------------------------------------------- building
    def add_triplet(self, triplet, prior=None, *, replace: bool = False) -> int:
        """Add triplet ``(i, j, k)`` (ordered, distinct landmark ids); returns its variable index.

        ``prior``: (m,) non-negative vector (normalized here), an object with a ``.landmark`` (m,)
        attribute (:class:`~qfg.solvers.TripletEstimate`), or None for an unseen triplet. A
        triplet already in the map that has no prior gets this one (``full_map`` then priors is
        the usual way to build a map); one that has a prior is refused, since a second estimate
        would silently drop the first (combine the estimates first, :mod:`qfg.combine`), unless
        ``replace=True``, which replaces it.
        """
        t = _as_triplet(triplet)
        p = None if prior is None else _as_prior(prior, self.m)
        v = self._index.get(t)
        if v is not None:
            if self._priors[v] is not None and not replace:
                raise ValueError(f"triplet: {t} already has a prior (variable {v}); combine its "
                                 f"estimates first (qfg.combine), or pass replace=True")
            self._priors[v] = p
            return v
        v = len(self._triplets)
        self._triplets.append(t)
        self._index[t] = v
        self._priors.append(p)
        return v

    def add_composition(self, ijks) -> int:
        """Add the composition factor of landmarks ``(i, j, k, s)``; its three triplets must exist.

        Returns the factor index (an existing factor is not added twice).
        """
        try:
            i, j, k, s = (int(x) for x in ijks)
        except (TypeError, ValueError):
            raise ValueError(f"ijks: expected four landmark ids (i, j, k, s), got {ijks!r}") from None
        key = (i, j, k, s)
        self._composed = True
        vs = []
        for t in ((i, j, k), (j, k, s), (i, j, s)):
            if t not in self._index:
                raise ValueError(f"ijks: triplet {t} of factor {key} is not in the map")
            vs.append(self._index[t])
        fk = (vs[0] << KEY_BITS) | s
        f = self._find(fk)
        if f >= 0:
            return f
        f = self._F
        self._pending.append((key, tuple(vs)))
        self._single[fk] = f
        self._F += 1
        self._cache = None
        self._csr = None
        return f

    def _find(self, fk: int) -> int:
        """Index of the factor with key ``fk``, or -1."""
        f = self._single.get(fk)
        if f is not None:
            return f
        if len(self._bulk_keys):
            p = int(np.searchsorted(self._bulk_keys, fk))
            if p < len(self._bulk_keys) and int(self._bulk_keys[p]) == fk:
                return int(self._bulk_idx[p])
        return -1

    def _flush(self):
        if self._pending:
            self._fl_parts.append(np.array([k for k, _ in self._pending], dtype=np.int64))
            self._fv_parts.append(np.array([v for _, v in self._pending], dtype=np.intp))
            self._pending = []

    def _arrays(self):
        """(landmark ids (F, 4) int64, variable indices (F, 3) intp), read-only."""
        if self._cache is None:
            self._flush()
            fl = (np.concatenate(self._fl_parts) if self._fl_parts
                  else np.zeros((0, 4), dtype=np.int64)).reshape(-1, 4)
            fv = (np.concatenate(self._fv_parts) if self._fv_parts
                  else np.zeros((0, 3), dtype=np.intp)).reshape(-1, 3)
            self._fl_parts, self._fv_parts = [fl], [fv]
            fl.setflags(write=False)
            fv.setflags(write=False)
            self._cache = (fl, fv)
        return self._cache

    def discover_compositions(self) -> int:
        """Add every composition factor ``(i j:k, j k:s, i j:s)`` whose triplets are all in the map.

        Vectorized join on landmark pairs: for each triplet (i, j, k), the candidates s are the
        third ids of the triplets (j, k, s) (a sorted pair index and one ``searchsorted``), kept
        when (i, j, s) is in the map (a sorted triplet index) -- cost O(sum over triplets of the
        triplets sharing their last pair), not a scan of all triples of triplets. New factors
        are added in lexicographic ``(i, j, k, s)`` order. Returns the number of factors added.
        """
        self._composed = True
        n = len(self._triplets)
        if n == 0:
            return 0
        T = np.array(self._triplets, dtype=np.int64).reshape(-1, 3)
        B = np.int64(KEY_BITS)
        pair = (T[:, 0] << B) | T[:, 1]                      # (a, b) of every triplet
        po = np.argsort(pair, kind="stable")
        ps = pair[po]
        want = (T[:, 1] << B) | T[:, 2]                      # (j, k) of every triplet (i, j, k)
        lo = np.searchsorted(ps, want, side="left")
        hi = np.searchsorted(ps, want, side="right")
        cnt = hi - lo
        a = np.repeat(np.arange(n, dtype=np.int64), cnt)     # candidate t1 = (i, j, k)
        start = np.repeat(lo - np.cumsum(cnt) + cnt, cnt)
        b = po[start + np.arange(len(a), dtype=np.int64)]    # candidate t2 = (j, k, s)
        i, j, k, sx = T[a, 0], T[a, 1], T[a, 2], T[b, 2]
        ok = sx != i
        a, b, i, j, k, sx = a[ok], b[ok], i[ok], j[ok], k[ok], sx[ok]
        tkey = (T[:, 0] << (2 * B)) | (T[:, 1] << B) | T[:, 2]
        to = np.argsort(tkey)
        tk = tkey[to]
        ckey = (i << (2 * B)) | (j << B) | sx
        p = np.minimum(np.searchsorted(tk, ckey), n - 1)
        ok = tk[p] == ckey
        a, b, c = a[ok], b[ok], to[p[ok]]
        i, j, k, sx = i[ok], j[ok], k[ok], sx[ok]
        fk = (a << B) | sx
        if self._F:
            old = np.fromiter(self._single.keys(), dtype=np.int64, count=len(self._single))
            known = np.isin(fk, old) | np.isin(fk, self._bulk_keys)
            keep = ~known
            a, b, c, i, j, k, sx, fk = (x[keep] for x in (a, b, c, i, j, k, sx, fk))
        if len(a) == 0:
            return 0
        order = np.lexsort((sx, k, j, i))
        fl = np.stack([i, j, k, sx], axis=1)[order]
        fv = np.stack([a, b, c], axis=1)[order].astype(np.intp)
        fk = fk[order]
        self._arrays()
        self._fl_parts.append(fl)
        self._fv_parts.append(fv)
        idx = np.arange(self._F, self._F + len(fk), dtype=np.int64)
        keys = np.concatenate([self._bulk_keys, fk])
        ko = np.argsort(keys, kind="stable")
        self._bulk_keys = keys[ko]
        self._bulk_idx = np.concatenate([self._bulk_idx, idx])[ko]
        self._F += len(fk)
        self._cache = None
        self._csr = None
        return int(len(fk))

    # ------------------------------------------------------------ accessors
    @property
    def triplets(self) -> list[tuple[int, int, int]]:
        return list(self._triplets)

    @property
    def priors(self) -> list[np.ndarray | None]:
        return [None if p is None else p.copy() for p in self._priors]

    @property
    def factors(self) -> list[tuple[int, int, int, int]]:
        return [tuple(r) for r in self._arrays()[0].tolist()]

    @property
    def factor_vars(self) -> np.ndarray:
        """(F, 3) int variable indices of each composition factor (t1, t2, t3) (read-only)."""
        return self._arrays()[1]

    @property
    def n_triplets(self) -> int:
        return len(self._triplets)

    @property
    def compositions_asked(self) -> bool:
        """Whether :meth:`discover_compositions` or :meth:`add_composition` ran on this map:
        propagation refuses a map with unseen triplets that never asked for a composition."""
        return self._composed

    @property
    def n_factors(self) -> int:
        return self._F

    @property
    def seen(self) -> np.ndarray:
        """(n,) bool: True for triplets with a prior (unary factor)."""
        return np.array([p is not None for p in self._priors], dtype=bool)

    def index(self, triplet) -> int:
        """Variable index of ``triplet``."""
        t = _as_triplet(triplet)
        if t not in self._index:
            raise ValueError(f"triplet: {t} is not in the map")
        return self._index[t]

    def key(self, triplet) -> int:
        """GTSAM key of ``triplet`` (see :func:`triplet_key`)."""
        return triplet_key(*self._triplets[self.index(triplet)])

    def prior_matrix(self) -> np.ndarray:
        """(n, m) priors, uniform rows for unseen triplets."""
        m = self.m
        out = np.full((self.n_triplets, m), 1.0 / m)
        for v, p in enumerate(self._priors):
            if p is not None:
                out[v] = p
        return out

    def incidence(self) -> list[list[int]]:
        """For each variable, the factor indices that touch it (ascending)."""
        indptr, indices = self.incidence_csr()
        flat = indices.tolist()
        return [flat[indptr[v]:indptr[v + 1]] for v in range(self.n_triplets)]

    def incidence_csr(self) -> tuple[np.ndarray, np.ndarray]:
        """The incidence as arrays: the factors of variable v are
        ``indices[indptr[v]:indptr[v + 1]]`` (ascending, each once)."""
        if self._csr is None:
            fv = self._arrays()[1]
            F = len(fv)
            var = fv.ravel().astype(np.int64)
            fac = np.repeat(np.arange(F, dtype=np.int64), 3)
            o = np.lexsort((fac, var))
            var, fac = var[o], fac[o]
            keep = np.ones(len(var), dtype=bool)
            keep[1:] = (var[1:] != var[:-1]) | (fac[1:] != fac[:-1])
            var, fac = var[keep], fac[keep]
            indptr = np.zeros(self.n_triplets + 1, dtype=np.int64)
            np.cumsum(np.bincount(var, minlength=self.n_triplets), out=indptr[1:])
            fac.setflags(write=False)
            indptr.setflags(write=False)
            self._csr = (indptr, fac)
        return self._csr

    # ------------------------------------------------------------ exports
    def to_gtsam(self):
        """The ``gtsam.DiscreteFactorGraph``: one DecisionTreeFactor per prior and per composition.

        Composition factors have keys in the order (t1, t2, t3) and table ``T.ravel()`` (C order:
        GTSAM's first key varies slowest -- checked against a numpy product in the tests).
        """
        import gtsam

        m = self.m
        graph = gtsam.DiscreteFactorGraph()
        dkeys = [(triplet_key(*t), m) for t in self._triplets]
        for v, p in enumerate(self._priors):
            if p is not None:
                graph.push_back(gtsam.DecisionTreeFactor([dkeys[v]], p.tolist()))
        flat = self.table.ravel().tolist()
        for (a, b, c) in self._arrays()[1].tolist():
            graph.push_back(gtsam.DecisionTreeFactor([dkeys[a], dkeys[b], dkeys[c]], flat))
        return graph

    def to_networkx(self, isc=None):
        """Bipartite ``networkx.Graph``: variable nodes ``("v", i, j, k)``, factor nodes
        ``("u", i, j, k)`` (unary) and ``("c", i, j, k, s)`` (composition).

        Node attributes: ``bipartite`` (0 variables, 1 factors), ``kind`` ("variable", "unary",
        "composition"); variables also ``seen``, ``prior`` ((m,) or None), ``isc`` (the prior's
        information score, 0 for unseen; or ``isc[v]`` if an (n,) array is given, e.g. from a
        propagation result), ``index`` (variable index). Composition edges carry ``role`` 1..3.
        """
        import networkx as nx

        from .metrics import information_score

        P = self.prior_matrix()
        scores = (information_score(P) if isc is None
                  else np.asarray(isc, dtype=float).reshape(self.n_triplets))
        G = nx.Graph()
        for v, t in enumerate(self._triplets):
            p = self._priors[v]
            G.add_node(("v",) + t, bipartite=0, kind="variable", index=v, seen=p is not None,
                       prior=None if p is None else p.copy(), isc=float(scores[v]))
            if p is not None:
                G.add_node(("u",) + t, bipartite=1, kind="unary")
                G.add_edge(("u",) + t, ("v",) + t)
        for key, vs in zip(self.factors, self._arrays()[1].tolist(), strict=True):
            G.add_node(("c",) + key, bipartite=1, kind="composition")
            for role, v in enumerate(vs, start=1):
                G.add_edge(("c",) + key, ("v",) + self._triplets[v], role=role)
        return G

    def __repr__(self) -> str:
        return (f"QualitativeFactorGraph(partition={self.partition!r}, triplets={self.n_triplets}, "
                f"seen={int(self.seen.sum())}, factors={self.n_factors})")


def full_map(n_landmarks: int, partition: str | None = "edc", tensor=None, priors: Mapping | None = None
             ) -> QualitativeFactorGraph:
    """Every ordered triplet of landmarks ``0..n_landmarks-1`` and every composition factor.

    ``n (n-1) (n-2)`` triplets and ``n (n-1) (n-2) (n-3)`` factors (15 landmarks: 2730, 32760).
    ``priors``: optional mapping triplet -> prior for the seen ones.
    """
    from ._validate import positive_int

    n = positive_int("n_landmarks", n_landmarks, minimum=3)
    g = QualitativeFactorGraph(partition, tensor)
    priors = dict(priors or {})
    for i in range(n):
        for j in range(n):
            for k in range(n):
                if i != j and j != k and i != k:
                    g.add_triplet((i, j, k), priors.pop((i, j, k), None))
    if priors:
        raise ValueError(f"priors: triplets not in the map: {sorted(priors)[:5]}")
    g.discover_compositions()
    return g


def map_from_triplets(seen: Mapping, unseen: Iterable = (), partition: str = "edc", tensor=None,
                      discover: bool = True) -> QualitativeFactorGraph:
    """The map of the triplets some views saw (``seen``: triplet -> prior vector or
    TripletEstimate) plus chosen unseen ones, with every composition factor among them.

    Seen triplets are added first (sorted), then the unseen ones (sorted, skipping seen ones).
    """
    g = QualitativeFactorGraph(partition, tensor)
    for t in sorted(seen, key=lambda x: tuple(x)):
        g.add_triplet(t, seen[t])
    for t in sorted({_as_triplet(t) for t in unseen}):
        if t not in g._index:
            g.add_triplet(t, None)
    if discover:
        g.discover_compositions()
    return g


def map_from_histories(histories, unseen: Iterable = (), partition: str = "edc", tensor=None, *,
                       method: str = "fast", seed=0, **solver_options) -> QualitativeFactorGraph:
    """The map of the triplets a set of views saw, with solver priors, plus chosen unseen ones.

    ``histories``: :class:`~qfg.simulation.TripletHistory` objects (e.g. from
    :func:`qfg.simulation.triplet_histories`), solved with :func:`qfg.solvers.solve_triplets`
    (``method``, ``seed``, options passed on); each becomes a seen triplet keyed by its
    ``landmarks``. Every composition factor among all the triplets is added.
    """
    from .solvers import solve_triplets

    histories = list(histories)
    ests = solve_triplets(histories, method=method, partition=partition, seed=seed,
                          **solver_options) if histories else []
    seen = {tuple(h.landmarks): e for h, e in zip(histories, ests, strict=True)}
    return map_from_triplets(seen, unseen, partition=partition, tensor=tensor)


def truth_states(triplets: Iterable, landmarks, partition: str = "edc") -> np.ndarray:
    """(n,) ground-truth state of each triplet ``(i, j, k)``: the state of landmark k in the frame
    of (i, j) (:func:`qfg.geometry.to_frame`, :meth:`qfg.partitions.Partition.state_of`).

    ``landmarks``: (L, 2) world positions, row = landmark id.

    >>> truth_states([(0, 1, 2)], [[0.0, 0.0], [0.0, 1.0], [0.0, 3.0]], "lr").shape
    (1,)
    """
    from ._validate import as_float_array
    from .geometry import to_frame
    from .partitions import get

    L = as_float_array("landmarks", landmarks, ndim=2, last_dim=2)
    ts = np.array([_as_triplet(t) for t in triplets], dtype=np.intp).reshape(-1, 3)
    if ts.size and ts.max() >= len(L):
        raise ValueError(f"landmarks: {len(L)} rows, but a triplet uses landmark {int(ts.max())}")
    if len(ts) == 0:
        return np.zeros(0, dtype=np.intp)
    c = to_frame(L[ts[:, 2]], L[ts[:, 0]], L[ts[:, 1]])
    return np.asarray(get(partition).state_of(c), dtype=np.intp)


def factor_overlap(g) -> dict:
    """How much the composition factors of ``g`` overlap: the structure that makes loopy BP
    count evidence twice.

    Two factors sharing two triplets (e.g. ``(i, j, k, s)`` and ``(i, j, s, k)``, which share
    ``(i, j, k)`` and ``(i, j, s)``) close a loop of length 4 in the factor graph, the shortest
    one it can have; every full map has all of them. Returns a dict:

    * ``overlap``: share of the composition factors that share two or more triplets with
      another factor (0 with no factors);
    * ``mean_degree``: mean number of composition factors per triplet among triplets in any
      factor (a full map of L landmarks: ``3 (L - 3)``);
    * ``factors``, ``triplets``: the counts.

    >>> import numpy as np
    >>> factor_overlap(full_map(5, partition=None, tensor=np.ones((2, 2, 2))))["overlap"]
    1.0
    """
    fv = np.asarray(g.factor_vars, dtype=np.int64).reshape(-1, 3)
    F, n = len(fv), g.n_triplets
    if F == 0:
        return {"overlap": 0.0, "mean_degree": 0.0, "factors": 0, "triplets": n}
    # each factor's three pairs of variables, as one int64 key per (unordered) pair
    keys = []
    for a, b in ((0, 1), (0, 2), (1, 2)):
        lo = np.minimum(fv[:, a], fv[:, b])
        hi = np.maximum(fv[:, a], fv[:, b])
        keys.append(lo * (n + 1) + hi)
    K = np.concatenate(keys)
    _, inv, counts = np.unique(K, return_inverse=True, return_counts=True)
    shared = (counts[inv] > 1).reshape(3, F).any(axis=0)
    deg = np.bincount(fv.ravel(), minlength=n)
    return {"overlap": float(shared.mean()), "mean_degree": float(deg[deg > 0].mean()),
            "factors": int(F), "triplets": int(n)}


def brute_force_compositions(triplets: Iterable) -> list[tuple[int, int, int, int]]:
    """Every ``(i, j, k, s)`` with ``(i,j,k), (j,k,s), (i,j,s)`` among ``triplets``, by scanning all
    ordered triples of triplets (cubic; for tests on small maps)."""
    ts = [tuple(t) for t in triplets]
    out = set()
    for a in ts:
        for b in ts:
            for c in ts:
                if a[1:] == b[:2] and c[:2] == a[:2] and c[2] == b[2]:
                    out.add((a[0], a[1], a[2], b[2]))
    return sorted(out)
