"""Labelled inference results and the errors of the exact engines.

Every method (exact junction tree, per-variable contraction, GTSAM, Algorithm 2, pooled
composition, loopy BP, configuration inference) returns a :class:`Marginals`: the triplets, the
partition name, its state names and the (n, m) array, so a result can be read without the
(mutable) graph that produced it. Rows follow ``triplets`` (the graph's variable order at the
time of the call); lookups go by triplet, ``res[(0, 1, 3)]``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

__all__ = ["Marginals", "Assignment", "GraphTooLargeError", "ZeroMassError", "MissingKeyError"]


class GraphTooLargeError(ValueError):
    """Raised before any work when exact inference would build a table above ``max_table``.

    Attributes: ``entries`` (estimated largest table, a float: may exceed any int a table could
    hold), ``width`` (number of triplets in that table), ``max_table``.
    """

    def __init__(self, message: str, *, entries: float = float("nan"), width: int = 0,
                 max_table: int = 0):
        super().__init__(message)
        self.entries = entries
        self.width = width
        self.max_table = max_table


class ZeroMassError(ValueError):
    """Raised when the product of a graph's factors is zero everywhere (the priors contradict the
    tensor's support): the exact marginals are undefined.

    Attributes: ``triplets`` (the variables of the connected component without mass) and
    ``local_factors`` (composition factors ``(i, j, k, s)`` whose own table has no mass under the
    priors of their seen triplets: a contradiction visible at one factor; empty when only the
    combination of several factors contradicts the priors).
    """

    def __init__(self, message: str, *, triplets=(), local_factors=()):
        super().__init__(message)
        self.triplets = tuple(triplets)
        self.local_factors = tuple(local_factors)


class MissingKeyError(KeyError, ValueError):
    """A triplet or variable that a result does not hold. A ``KeyError`` (the mapping rule) and,
    for code written against the older results, a ``ValueError``."""

    def __str__(self) -> str:  # KeyError would quote the whole message
        return str(self.args[0]) if self.args else ""


def _is_int(x) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def _row_of(rows: dict, n: int, key) -> int:
    """One indexing rule for labelled results: a triplet ``(i, j, k)`` of ints, or a variable
    index ``0 <= v < n`` (no negative wrap-around, no slices or masks)."""
    if _is_int(key):
        if 0 <= key < n:
            return int(key)
        raise MissingKeyError(f"variable: {int(key)} is not in this result (it has {n} "
                              f"variables, 0..{n - 1})")
    if isinstance(key, tuple) and len(key) == 3 and all(_is_int(x) for x in key):
        t = tuple(int(x) for x in key)
        if t in rows:
            return rows[t]
        raise MissingKeyError(f"triplet: {t} is not in this result")
    raise TypeError(f"key: expected a triplet (i, j, k) of ints or a variable index, got "
                    f"{key!r}; for array indexing use .probabilities")


def _state_names(partition, m: int) -> tuple:
    """The state names of ``partition`` (its ``labels``, :func:`qfg.partitions.get`); for no
    partition, one it does not know or one with another number of states: ``"1"`` .. ``"m"``,
    the numbering the partitions use by default."""
    if partition is not None:
        from ..partitions import get

        try:
            labels = tuple(str(x) for x in get(partition).labels)
        except ValueError:
            labels = ()
        if len(labels) == m:
            return labels
    return tuple(str(i + 1) for i in range(m))


#: rows :meth:`Marginals.__str__` prints before it elides the rest
STR_ROWS = 10


def _frozen_array(a) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Marginals:
    """(n, m) marginal distributions labelled by triplet.

    Attributes:
        triplets: tuple of ``(i, j, k)``, the row labels.
        partition: partition name of the states (columns), or None for an unlabelled tensor.
        probabilities: (n, m) float array, rows sum to 1 (read-only).
        method: which method made it, the string its function's ``method=`` takes
            (``"junction"``, ``"contract"``, ``"gtsam"``, ``"best"``, ``"pooled"``,
            ``"loopy-bp"``, ``"config-state"``, ``"config-metric"``, ``"joint"``).
        info: read-only mapping of method-specific extras (e.g. ``log_partition``,
            ``largest_table``, ``converged``, ``iterations``, ``isc``, ``reached``).
        states: (m,) tuple of str, the column labels: the partition's state names
            (``qfg.partitions.get(partition).labels``; ``"1"`` .. ``"m"`` without one). Given
            by the partition unless passed.

    One indexing rule: ``res[(i, j, k)]`` is that triplet's (m,) row and ``res[v]`` (an int,
    ``0 <= v < n``) row ``v``; an absent key raises :class:`MissingKeyError` (a ``KeyError``),
    anything else (slices, masks, negative indices) a ``TypeError`` or ``KeyError``: array work
    goes through ``res.probabilities``. ``key in res`` follows the same rule. ``len(res)``,
    ``iter(res)`` (triplets), ``res.to_dict()``, ``np.asarray(res)``. Extras are also
    attributes: ``res.converged`` = ``res.info["converged"]``. ``str(res)`` is a table with
    the state names as columns.

    >>> r = Marginals(((0, 1, 2), (1, 2, 3)), "lr", [[0.9, 0.1], [0.5, 0.5]], "junction")
    >>> r[(1, 2, 3)].tolist(), r[0].tolist(), len(r), np.asarray(r).shape, list(r)
    ([0.5, 0.5], [0.9, 0.1], 2, (2, 2), [(0, 1, 2), (1, 2, 3)])
    >>> (0, 1, 2) in r, 1 in r, 2 in r, (0, 1, 3) in r
    (True, True, False, False)
    >>> r.states
    ('L', 'R')
    >>> print(r)
    Marginals(method='junction', partition='lr', n=2, m=2)
    triplet        L      R
    (0, 1, 2)  0.900  0.100
    (1, 2, 3)  0.500  0.500
    """

    triplets: tuple
    partition: str | None
    probabilities: np.ndarray
    method: str = ""
    info: Mapping = field(default_factory=dict)
    states: tuple | None = None

    def __post_init__(self):
        ts = tuple(tuple(int(x) for x in t) for t in self.triplets)
        P = _frozen_array(self.probabilities)
        if P.ndim != 2 or P.shape[0] != len(ts):
            raise ValueError(f"probabilities: expected ({len(ts)}, m) rows for {len(ts)} triplets, "
                             f"got shape {P.shape}")
        if self.states is None:
            states = _state_names(self.partition, P.shape[1])
        else:
            states = tuple(str(x) for x in self.states)
            if len(states) != P.shape[1]:
                raise ValueError(f"states: expected {P.shape[1]} names (one per column), got "
                                 f"{len(states)}")
        object.__setattr__(self, "triplets", ts)
        object.__setattr__(self, "probabilities", P)
        object.__setattr__(self, "states", states)
        info = {}
        for k, v in dict(self.info).items():
            if isinstance(v, np.ndarray):
                v = v.copy()
                v.setflags(write=False)
            info[k] = v
        object.__setattr__(self, "info", MappingProxyType(info))
        object.__setattr__(self, "_rows", {t: v for v, t in enumerate(ts)})

    def __reduce__(self):  # picklable (processes, Dask): the read-only views are rebuilt
        return (type(self), (self.triplets, self.partition, np.asarray(self.probabilities),
                             self.method, dict(self.info), self.states))

    # ------------------------------------------------------------- mapping-like
    def row(self, key) -> int:
        """Row index of ``key``: a triplet ``(i, j, k)`` or a variable index ``v`` (an int,
        ``0 <= v < n``). :class:`MissingKeyError` (a ``KeyError``) naming it when absent."""
        return _row_of(self._rows, len(self.triplets), key)

    def __getitem__(self, key) -> np.ndarray:
        """The (m,) row of a triplet ``(i, j, k)`` or of variable ``v`` (one rule for every key;
        for array work use :attr:`probabilities`)."""
        return self.probabilities[self.row(key)]

    def __contains__(self, key) -> bool:
        try:
            self.row(key)
        except (KeyError, TypeError):
            return False
        return True

    def __len__(self) -> int:
        return len(self.triplets)

    def __iter__(self):
        return iter(self.triplets)

    def __array__(self, dtype=None, copy=None):
        a = self.probabilities
        if dtype is not None:
            a = a.astype(dtype)
        return a.copy() if copy else a

    def to_dict(self) -> dict:
        """``{triplet: (m,) row}`` (copies)."""
        return {t: self.probabilities[v].copy() for v, t in enumerate(self.triplets)}

    # ------------------------------------------------------------- shape
    @property
    def shape(self) -> tuple:
        return self.probabilities.shape

    @property
    def m(self) -> int:
        return int(self.probabilities.shape[1])

    def __getattr__(self, name):
        # extras of the engines (converged, isc, order, ...) read as attributes
        if name.startswith("_"):
            raise AttributeError(name)
        if name == "marginals":
            raise AttributeError("Marginals.marginals was removed: use .probabilities or "
                                 "np.asarray(res) (CHANGELOG.md, 0.6.0)")
        info = object.__getattribute__(self, "info")
        if name in info:
            return info[name]
        raise AttributeError(f"{type(self).__name__} has no attribute {name!r} "
                             f"(extras: {sorted(info)})")

    def __repr__(self) -> str:
        return (f"Marginals(method={self.method!r}, partition={self.partition!r}, "
                f"n={len(self)}, m={self.probabilities.shape[1]}, states={self.states!r}, "
                f"info={sorted(self.info)})")

    def __str__(self) -> str:
        """A table: one row per triplet (the first :data:`STR_ROWS`), one column per state."""
        n, m = self.probabilities.shape
        head = (f"Marginals(method={self.method!r}, partition={self.partition!r}, n={n}, "
                f"m={m})")
        names = [str(t) for t in self.triplets[:STR_ROWS]]
        w0 = max([len("triplet"), *map(len, names)])
        ws = [max(5, len(s)) for s in self.states]
        lines = [head, "  ".join(["triplet".ljust(w0), *(s.rjust(w) for s, w in
                                                          zip(self.states, ws, strict=True))])]
        for name, row in zip(names, self.probabilities, strict=False):
            lines.append("  ".join([name.ljust(w0), *(f"{p:.3f}".rjust(w) for p, w in
                                                       zip(row, ws, strict=True))]))
        if n > STR_ROWS:
            lines.append(f"... ({n - STR_ROWS} more rows)")
        return "\n".join(lines)


@dataclass(frozen=True, eq=False)
class Assignment:
    """Joint assignments of all triplet states with their probabilities (MAP and K-best).

    Attributes:
        triplets: tuple of ``(i, j, k)`` (column labels of ``states``).
        partition: partition name, or None.
        states: (K, n) int: row r is the r-th most probable joint assignment.
        probabilities: (K,) their probabilities under the normalized joint (non-increasing).
        log_probabilities: (K,) natural logs of ``probabilities`` (finite even when those
            underflow to 0).

    ``res[(i, j, k)]`` (or ``res[v]``) is that triplet's column (K,), by the rule of
    :class:`Marginals`; ``res.best`` the best assignment as a dict.

    >>> a = Assignment(((0, 1, 2),), "lr", [[1], [0]], [0.7, 0.3], np.log([0.7, 0.3]))
    >>> a[(0, 1, 2)].tolist(), a.best, len(a)
    ([1, 0], {(0, 1, 2): 1}, 2)
    """

    triplets: tuple
    partition: str | None
    states: np.ndarray
    probabilities: np.ndarray
    log_probabilities: np.ndarray

    def __post_init__(self):
        ts = tuple(tuple(int(x) for x in t) for t in self.triplets)
        S = np.array(self.states, dtype=np.intp)
        # no variables: (K, 0) states, K from the probabilities (reshape(-1, 0) is ambiguous)
        S = S.reshape(np.size(self.probabilities), 0) if not ts else S.reshape(-1, len(ts))
        S.setflags(write=False)
        object.__setattr__(self, "triplets", ts)
        object.__setattr__(self, "states", S)
        object.__setattr__(self, "probabilities", _frozen_array(self.probabilities))
        object.__setattr__(self, "log_probabilities", _frozen_array(self.log_probabilities))
        object.__setattr__(self, "_rows", {t: v for v, t in enumerate(ts)})
        if self.probabilities.shape != (len(S),) or self.log_probabilities.shape != (len(S),):
            raise ValueError(f"probabilities: expected ({len(S)},) values for {len(S)} assignments")

    def __getitem__(self, key) -> np.ndarray:
        """The (K,) column of a triplet ``(i, j, k)`` or of variable ``v``."""
        return self.states[:, _row_of(self._rows, len(self.triplets), key)]

    def __contains__(self, key) -> bool:
        try:
            _row_of(self._rows, len(self.triplets), key)
        except (KeyError, TypeError):
            return False
        return True

    def __len__(self) -> int:
        return len(self.states)

    def __repr__(self) -> str:
        K, n = self.states.shape
        top = f", best p={float(self.probabilities[0]):.3g}" if K else ""
        return f"Assignment(partition={self.partition!r}, K={K}, n={n}{top})"

    @property
    def best(self) -> dict:
        """The most probable assignment as ``{triplet: state}``."""
        return {t: int(s) for t, s in zip(self.triplets, self.states[0], strict=True)}

    def to_dicts(self) -> list[dict]:
        """One ``{triplet: state}`` dict per assignment, best first."""
        return [{t: int(s) for t, s in zip(self.triplets, row, strict=True)} for row in self.states]
