"""Online probabilistic composition: joint and marginals from a composition tensor.

For three triplets sharing landmarks pairwise, t1 = AB:C, t2 = BC:D, t3 = AB:D, with the offline
tensor ``T[i, j, k]`` (conventions.md, "Composition tensor") and per-triplet estimates
``V_t = P(S^t | H^t)`` (vectors of length m):

* joint (paper eq. specificComposition):
  ``P(i, j, k)  proportional to  V1(i) V2(j) V3(k) T(i, j, k)``
* marginal of t3 (paper eq. marginalComposition):
  ``P(k)  proportional to  V3(k) sum_{i, j} V1(i) V2(j) T(i, j, k)``, likewise for t1 and t2.
  The target's own vector is optional: without it (a triplet never seen) it is uniform, which is
  the paper's "inferred by composition alone"; with it, the marginal is the joint's marginal.
* deterministic composition (McClelland et al.): the same with ``T`` replaced by its support
  ``T > 0`` (:func:`marginal` with ``deterministic=True``), or as sets of feasible states
  (:func:`feasible`).

Everything is batched over F factors: a vector argument is (m,) or (F, m), broadcast together;
results are (F, m) (or (F, m, m, m) for the joint), squeezed back to (m,) when every input was a
single vector; an empty batch (F = 0) gives (0, m). Inputs need not be normalized; they must be
finite and non-negative.

Scale. Every vector row (and the table) is divided by its maximum before any product, so the
answer depends only on ratios within a row: ``V`` and ``c V`` give the same result for every
``c > 0`` representable in float64 (``1e308``, ``1e-200``, a one-hot scaled to ``5e-324``), with
no overflow to inf/NaN and no underflow to a false zero mass. What cannot be represented is an
entry below about ``1e-308`` times its own row's maximum, which counts as zero.

Zero mass. When the inputs are inconsistent with the tensor (e.g. one-hot vectors of a triple that
the tensor calls infeasible), the unnormalized result is all zeros. Rather than dividing by zero,
such a row is returned as the uniform distribution (all-True for :func:`feasible`) and flagged in
``zero_mass``; a caller that must not lose information can test the flag.

>>> import numpy as np
>>> T = np.zeros((2, 2, 2)); T[0, 0, 0] = T[1, 1, 1] = T[0, 1, 1] = 1 / 3
>>> r = marginal(T, [1, 0], [0, 1])          # t1 in state 0, t2 in state 1: t3 must be state 1
>>> r.p.tolist(), bool(r.zero_mass)
([0.0, 1.0], False)
>>> bool(marginal(T, [0, 1], [1, 0]).zero_mass)  # (1, 0, *) is infeasible: uniform, flagged
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Marginal", "Joint", "Feasible", "marginal", "joint", "feasible", "as_table"]

_ROLES = (1, 2, 3)

#: Size (elements) of the per-chunk intermediate in :func:`marginal` (8 MB of float64).
_CHUNK_ELEMENTS = 1 << 20


@dataclass(frozen=True)
class Marginal:
    """Composed marginal of one triplet.

    Attributes:
        p: (F, m) or (m,) probabilities, rows sum to 1 (uniform where ``zero_mass``).
        zero_mass: (F,) or () bool, True where the inputs had no mass under the tensor.
        role: which triplet the marginal is of (1: AB:C, 2: BC:D, 3: AB:D).
    """

    p: np.ndarray
    zero_mass: np.ndarray
    role: int


@dataclass(frozen=True)
class Joint:
    """Composed joint over (i, j, k) = (S^{AB:C}, S^{BC:D}, S^{AB:D}).

    Attributes:
        p: (F, m, m, m) or (m, m, m), each slice sums to 1 (uniform where ``zero_mass``).
        zero_mass: (F,) or () bool.
    """

    p: np.ndarray
    zero_mass: np.ndarray


@dataclass(frozen=True)
class Feasible:
    """Deterministic composition: the states of one triplet compatible with the others' sets.

    Attributes:
        states: (F, m) or (m,) bool; all True where ``zero_mass`` (no consistent combination).
        zero_mass: (F,) or () bool.
        role: 1, 2 or 3.
    """

    states: np.ndarray
    zero_mass: np.ndarray
    role: int


def as_table(T) -> np.ndarray:
    """The (m, m, m) float array of a :class:`~qfg.composition.CompositionTensor` or an array.

    Checks that it is cubic, finite, non-negative and has some mass.
    """
    try:
        arr = np.asarray(T, dtype=float)  # a CompositionTensor converts to its table
    except (TypeError, ValueError):
        raise ValueError(f"T: expected an (m, m, m) array or a CompositionTensor, got "
                         f"{type(T).__name__}") from None
    if arr.ndim != 3 or not (arr.shape[0] == arr.shape[1] == arr.shape[2]) or arr.shape[0] < 1:
        raise ValueError(f"T: expected shape (m, m, m), got {arr.shape}")
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ValueError("T: expected finite, non-negative entries")
    if not np.any(arr > 0):
        raise ValueError("T: all entries are zero")
    return arr


def _scaled_table(T, deterministic: bool) -> np.ndarray:
    """The checked table divided by its maximum (or its 0/1 support), for overflow-free products."""
    table = as_table(T)
    if deterministic:
        return (table > 0).astype(float)
    return table / table.max()


def _vectors(m: int, named: dict[str, object]) -> tuple[dict[str, np.ndarray | None], int, bool]:
    """Validate the V arguments: (m,) or (F, m), finite, >= 0; broadcast F. None stays None."""
    out: dict[str, np.ndarray | None] = {}
    batch = None
    single = True
    for name, v in named.items():
        if v is None:
            out[name] = None
            continue
        try:
            a = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: expected numbers, got {type(v).__name__}") from None
        if a.ndim not in (1, 2) or a.shape[-1] != m:
            raise ValueError(f"{name}: expected shape ({m},) or (F, {m}), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name}: non-finite values (NaN or inf)")
        if np.any(a < 0):
            raise ValueError(f"{name}: expected non-negative values")
        if a.ndim == 2:
            single = False
            if batch is None or batch == 1:
                batch = a.shape[0]
            elif a.shape[0] not in (1, batch):
                raise ValueError(f"{name}: {a.shape[0]} rows, but another vector has {batch}")
        out[name] = _unit_max(a)
    return out, (batch if batch is not None else 1), single


def _unit_max(a: np.ndarray) -> np.ndarray:
    """``a`` divided by the maximum of each row along the last axis (all-zero rows stay zero).

    The results are ratios, so this changes nothing mathematically; it keeps every later product
    within float64 whatever the scale of the input (1e308 would overflow, 1e-200 underflow).
    """
    peak = a.max(axis=-1, keepdims=True) if a.size else np.ones(a.shape[:-1] + (1,))
    return a / np.where(peak > 0, peak, 1.0)


def _role(role) -> int:
    if isinstance(role, bool) or role not in _ROLES:
        raise ValueError(f"role: expected 1 (AB:C), 2 (BC:D) or 3 (AB:D), got {role!r}")
    return int(role)


def _rows(a: np.ndarray | None, F: int, m: int) -> np.ndarray:
    if a is None:
        return np.ones((F, m))
    return np.broadcast_to(np.atleast_2d(a), (F, m))


def _normalize(unnorm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalize over all but the first axis; zero-mass rows become uniform and are flagged."""
    F = unnorm.shape[0]
    total = unnorm.sum(axis=tuple(range(1, unnorm.ndim)))
    # Inputs are scaled to a maximum of 1, so a consistent combination has mass far above this;
    # mass below the smallest normal double has lost its precision: treat it as zero.
    zero = total <= np.finfo(float).tiny
    shape = (F,) + (1,) * (unnorm.ndim - 1)
    p = unnorm / np.where(zero, 1.0, total).reshape(shape)
    if zero.any():
        p[zero] = 1.0 / np.prod(unnorm.shape[1:])
    return p, zero


def marginal(T, V1=None, V2=None, V3=None, *, role: int = 3, deterministic: bool = False
             ) -> Marginal:
    """Marginal of triplet ``role`` (1: AB:C, 2: BC:D, 3: AB:D) by composition.

    ``P(s_role)  proportional to  V_role(s) * sum over the other two indices of
    V_a(a) V_b(b) T(..)`` with T indexed (i, j, k) = (AB:C, BC:D, AB:D). The two other vectors are
    required; ``V_role`` is optional (None: uniform, i.e. the triplet has no estimate of its own).

    Args:
        T: (m, m, m) tensor or a :class:`~qfg.composition.CompositionTensor`.
        V1, V2, V3: (m,) or (F, m) non-negative vectors (need not sum to 1).
        role: which triplet to return.
        deterministic: use the 0/1 support ``T > 0`` instead of T (McClelland's composition,
            normalized: every feasible combination counts equally).

    Returns:
        :class:`Marginal` with ``p`` (F, m) (or (m,) if every input was 1-D).

    Example: a triplet never seen, inferred from the other two.

    >>> import numpy as np
    >>> T = np.ones((3, 3, 3)) / 27
    >>> marginal(T, [1, 0, 0], [0, 1, 0]).p.round(3).tolist()
    [0.333, 0.333, 0.333]
    """
    role = _role(role)
    table = _scaled_table(T, deterministic)
    m = table.shape[0]
    vecs, F, single = _vectors(m, {"V1": V1, "V2": V2, "V3": V3})
    names = ("V1", "V2", "V3")
    others = [r for r in _ROLES if r != role]
    for r in others:
        if vecs[names[r - 1]] is None:
            raise ValueError(f"{names[r - 1]}: required to compose the marginal of role {role} "
                             f"(the other two triplets' vectors must be given)")
    # Reorder T to (a, b, target) with a < b the other two roles, then two contractions.
    Tr = np.moveaxis(table, role - 1, -1)
    Va = _rows(vecs[names[others[0] - 1]], F, m)
    Vb = _rows(vecs[names[others[1] - 1]], F, m)
    # (F, a) @ (a, b*target) is one BLAS call; then contract b per row. In row chunks so that
    # the (rows, m, m) intermediate stays small for large batches.
    flat = Tr.reshape(m, m * m)
    unnorm = np.empty((F, m))
    step = max(1, _CHUNK_ELEMENTS // (m * m))
    for a in range(0, F, step):
        partial = (Va[a:a + step] @ flat).reshape(-1, m, m)
        unnorm[a:a + step] = np.einsum("fb,fbk->fk", Vb[a:a + step], partial)
    own = vecs[names[role - 1]]
    if own is not None:
        unnorm = unnorm * _rows(own, F, m)
    p, zero = _normalize(unnorm)
    if single:
        return Marginal(p=p[0], zero_mass=zero[0], role=role)
    return Marginal(p=p, zero_mass=zero, role=role)


def joint(T, V1=None, V2=None, V3=None, *, deterministic: bool = False) -> Joint:
    """Joint ``P(i, j, k)  proportional to  V1(i) V2(j) V3(k) T(i, j, k)``, batched.

    Missing vectors are uniform. Returns :class:`Joint` with ``p`` (F, m, m, m) (or (m, m, m)).

    >>> import numpy as np
    >>> T = np.zeros((2, 2, 2)); T[0, 1, 1] = T[1, 0, 0] = 0.5
    >>> joint(T, [1, 1]).p[0, 1, 1].item()
    0.5
    """
    table = _scaled_table(T, deterministic)
    m = table.shape[0]
    vecs, F, single = _vectors(m, {"V1": V1, "V2": V2, "V3": V3})
    v1, v2, v3 = (_rows(vecs[n], F, m) for n in ("V1", "V2", "V3"))
    unnorm = np.einsum("fi,fj,fk,ijk->fijk", v1, v2, v3, table, optimize=True)
    p, zero = _normalize(unnorm)
    if single:
        return Joint(p=p[0], zero_mass=zero[0])
    return Joint(p=p, zero_mass=zero)


def feasible(support, S1=None, S2=None, S3=None, *, role: int = 3) -> Feasible:
    """Deterministic composition on sets: states of ``role`` consistent with the others' sets.

    ``out(k) = S3(k) and exists (i, j): S1(i) and S2(j) and support(i, j, k)`` (for role 3; likewise
    for 1 and 2). Sets are boolean (or 0/1) vectors (m,) or (F, m); ``support`` is a boolean
    (m, m, m) array, a real tensor (its ``> 0``) or a CompositionTensor. The target's own set is
    optional (None: every state).

    >>> import numpy as np
    >>> sup = np.zeros((2, 2, 2), bool); sup[0, 1, 1] = sup[0, 1, 0] = True
    >>> feasible(sup, [1, 0], [0, 1]).states.tolist()
    [True, True]
    """
    role = _role(role)
    sup = getattr(support, "support", support)
    sup = as_table(np.asarray(sup, dtype=float)) > 0
    sets, _, _ = _vectors(sup.shape[0], {"S1": S1, "S2": S2, "S3": S3})
    r = marginal(sup.astype(float),
                 *(None if s is None else (s > 0).astype(float) for s in sets.values()),
                 role=role)
    states = r.p > 0
    return Feasible(states=states, zero_mass=r.zero_mass, role=role)
