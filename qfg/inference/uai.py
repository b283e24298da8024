"""The UAI model format (the format of the UAI inference competitions), with the triplet mapping
in a sidecar file.

A ``.uai`` file is whitespace-separated text::

    MARKOV                 (or BAYES: tables are then conditional probabilities, same product)
    n                      number of variables
    c_0 c_1 ... c_{n-1}    cardinalities
    F                      number of factors
    k v_1 ... v_k          per factor: scope size and variables (F lines)
    t                      per factor, in the same order: number of entries,
    x_1 ... x_t            then the table, the LAST scope variable changing fastest (C order)

A factor graph is written as one unary factor per seen triplet (its normalized prior) and one
factor per composition ``(t1, t2, t3)`` with ``T.ravel()``. Variables are numbered as the graph
numbers them (``g.triplets``). The sidecar ``<file>.json`` records what the format cannot: the
partition name, each variable's triplet and each factor's role (prior of variable v, or
composition ``(i, j, k, s)``). Numbers are written with 17 significant digits, so a round trip is
exact.

>>> import numpy as np, tempfile, os
>>> from qfg.graph import QualitativeFactorGraph
>>> g = QualitativeFactorGraph(None, tensor=np.full((2, 2, 2), 0.125))
>>> for t, p in [((0, 1, 2), [0.9, 0.1]), ((1, 2, 3), None), ((0, 1, 3), None)]:
...     _ = g.add_triplet(t, p)
>>> _ = g.discover_compositions()
>>> d = tempfile.mkdtemp(); path = os.path.join(d, "g.uai")
>>> write_uai(g, path)
>>> h = read_uai_graph(path)
>>> h.triplets == g.triplets, h.factors == g.factors
(True, True)
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..files import atomic_write_text
from .junction import FactorModel

__all__ = ["write_uai", "read_uai", "read_uai_graph", "sidecar_path"]

_SIDECAR = "qfg-uai-sidecar"


def sidecar_path(path) -> Path:
    """``model.uai`` -> ``model.uai.json``."""
    p = Path(path)
    return p.with_name(p.name + ".json")


def _fmt(x: float) -> str:
    return format(float(x), ".17g")


def write_uai(g, path, *, sidecar: bool = True) -> None:
    """Write a :class:`~qfg.graph.QualitativeFactorGraph` (or a
    :class:`~qfg.inference.junction.FactorModel`) as a UAI MARKOV file, and the sidecar JSON with
    the triplets (``sidecar=False``: the ``.uai`` only). Each file is replaced whole
    (:func:`qfg.files.atomic_write_text`): a failed write leaves the old one as it was."""
    path = Path(path)
    if isinstance(g, FactorModel):
        model, roles, partition, names = g, None, g.partition, list(g.names)
    else:
        model = FactorModel.from_graph(g)
        seen = np.flatnonzero(g.seen).tolist()
        roles = ([{"prior": int(v)} for v in seen]
                 + [{"composition": list(f)} for f in g.factors])
        partition, names = g.partition, [list(t) for t in g.triplets]
    lines = ["MARKOV", str(model.n), " ".join(str(c) for c in model.cards), str(len(model.scopes))]
    lines += [" ".join([str(len(s))] + [str(v) for v in s]) for s in model.scopes]
    lines.append("")
    cache: dict[int, str] = {}
    for t in model.tables:
        if id(t) not in cache:  # the shared composition tensor is formatted once
            cache[id(t)] = " ".join(_fmt(x) for x in np.asarray(t, dtype=float).ravel())
        lines += [str(t.size), cache[id(t)], ""]
    atomic_write_text(path, "\n".join(lines))
    if sidecar:
        meta = {"format": _SIDECAR, "version": 1, "uai": path.name, "partition": partition,
                "triplets": [list(t) for t in names] if names else None, "factors": roles}
        atomic_write_text(sidecar_path(path), json.dumps(meta, indent=1) + "\n")


def _is_int(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _read_text(path: Path) -> str:
    try:
        return path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"path: cannot read {path}: {exc}") from None


def _line_of_token(text: str, index: int) -> tuple[int, int, int]:
    """(line number from 1, tokens on that line, position of the token on it) of the
    whitespace-separated token ``index`` of ``text``."""
    seen = 0
    for number, line in enumerate(text.splitlines(), start=1):
        k = len(line.split())
        if seen + k > index:
            return number, k, index - seen
        seen += k
    return 0, 0, 0


def _card_line_error(path: Path, text: str, first: int, n: int, exc: ValueError):
    """The cardinalities are one line in the format (every UAI competition file writes them so):
    when reading failed after a cardinality line of the wrong length, that line is the error,
    not the mismatch it causes further down. None when the line is not to blame."""
    number, k, at = _line_of_token(text, first)
    if number == 0 or at != 0 or k == n:
        return None
    header = _line_of_token(text, first - 1)[0]
    return ValueError(f"path: {path}, line {number}: the cardinality line lists {k} "
                      f"cardinalit{'y' if k == 1 else 'ies'}, but line {header} declares {n} "
                      f"variable{'s' if n != 1 else ''} (read on as one stream of numbers, the "
                      f"file then fails: {str(exc).removeprefix(f'path: {path}: ')})")


def read_uai(path) -> FactorModel:
    """Read a UAI MARKOV/BAYES file as a :class:`~qfg.inference.junction.FactorModel` (names and
    partition from the sidecar when present). Malformed files -> ValueError naming the file."""
    path = Path(path)
    text = _read_text(path)
    tok = text.split()
    pos = 0

    def take(what):
        nonlocal pos
        if pos >= len(tok):
            raise ValueError(f"path: {path}: file ends before {what}")
        pos += 1
        return tok[pos - 1]

    def integer(what, minimum=0):
        s = take(what)
        # plain decimal digits only: int() would also take "1_0" (10), "+3" or "٣"
        if not (s.isascii() and s.lstrip("-").isdigit() and s.count("-") <= int(s[:1] == "-")):
            raise ValueError(f"path: {path}: expected an integer for {what}, got {s!r}")
        v = int(s)
        if v < minimum:
            raise ValueError(f"path: {path}: {what} must be >= {minimum}, got {v}")
        return v

    kind = take("the header").upper()
    if kind not in ("MARKOV", "BAYES"):
        raise ValueError(f"path: {path}: expected MARKOV or BAYES, got {kind!r}")
    n = integer("the number of variables")
    first_card = pos

    def tables_part():
        cards = [integer(f"the cardinality of variable {v}", 1) for v in range(n)]
        F = integer("the number of factors")
        scopes = []
        for f in range(F):
            k = integer(f"the scope size of factor {f}")
            s = tuple(integer(f"a variable of factor {f}") for _ in range(k))
            if any(v >= n for v in s) or len(set(s)) != k:
                raise ValueError(f"path: {path}: factor {f} has scope {s} (expected distinct "
                                 f"variables below {n})")
            scopes.append(s)
        tables = []
        for f, s in enumerate(scopes):
            size = integer(f"the table size of factor {f}")
            want = math.prod(cards[v] for v in s)       # Python ints: no int64 wrap-around
            if size != want:
                raise ValueError(f"path: {path}: factor {f} declares {size} entries, its scope "
                                 f"needs {want}")
            if size > len(tok) - pos:
                raise ValueError(f"path: {path}: file ends before entry {len(tok) - pos} of "
                                 f"factor {f} (it declares {size} entries)")
            vals = [take(f"entry {i} of factor {f}") for i in range(size)]
            try:
                t = np.array(vals, dtype=float)
            except ValueError:
                raise ValueError(f"path: {path}: factor {f} has a non-numeric entry") from None
            if not np.all(np.isfinite(t)) or np.any(t < 0):
                raise ValueError(f"path: {path}: factor {f} has negative or non-finite "
                                 f"entries")
            tables.append(t.reshape([cards[v] for v in s]))
        if pos != len(tok):
            raise ValueError(f"path: {path}: {len(tok) - pos} unexpected token(s) after the "
                             f"tables")
        return cards, scopes, tables

    try:
        cards, scopes, tables = tables_part()
    except ValueError as exc:
        blame = _card_line_error(path, text, first_card, n, exc)
        if blame is None:
            raise
        raise blame from None
    names, partition = (), None
    meta = _sidecar(path)
    if meta is not None:
        sp = sidecar_path(path)
        trips = meta.get("triplets")
        if trips is not None:
            if not isinstance(trips, list) or not all(
                    isinstance(t, list) and len(t) == 3 and all(_is_int(x) for x in t)
                    for t in trips):
                raise ValueError(f"path: sidecar {sp}: 'triplets' must be a list of [i, j, k] "
                                 f"integer lists")
            if len(trips) != n:
                raise ValueError(f"path: {sp} lists {len(trips)} triplets for {n} variables")
            names = tuple(tuple(t) for t in trips)
        partition = meta.get("partition")
        if partition is not None:
            from ..partitions import available

            if not isinstance(partition, str) or partition.lower() not in available():
                raise ValueError(f"path: sidecar {sp}: 'partition' must be one of "
                                 f"{', '.join(available())} or null, got {partition!r}")
            partition = partition.lower()
    return FactorModel(cards=cards, scopes=scopes, tables=tables, names=names,
                       partition=partition)


def _sidecar(path: Path):
    sp = sidecar_path(path)
    if not sp.exists():
        return None
    try:
        meta = json.loads(sp.read_text())
    except (OSError, ValueError) as exc:
        raise ValueError(f"path: sidecar {sp} is not readable JSON: {exc}") from None
    if not isinstance(meta, dict) or meta.get("format") != _SIDECAR:
        raise ValueError(f"path: sidecar {sp} is not a {_SIDECAR} file")
    return meta


def read_uai_graph(path):
    """Read a UAI file written by :func:`write_uai` back into a
    :class:`~qfg.graph.QualitativeFactorGraph` (needs the sidecar: the triplets and factor roles;
    every composition factor must carry the same table, the graph's tensor)."""
    from ..graph import QualitativeFactorGraph

    path = Path(path)
    model = read_uai(path)
    meta = _sidecar(path)
    if meta is None or meta.get("triplets") is None or meta.get("factors") is None:
        raise ValueError(f"path: {path} has no sidecar {sidecar_path(path).name} with the "
                         f"triplets and factor roles; read it with read_uai() instead")
    roles = meta["factors"]
    sp = sidecar_path(path)
    if not isinstance(roles, list) or not all(isinstance(r, dict) for r in roles):
        raise ValueError(f"path: sidecar {sp}: 'factors' must be a list of role objects")
    if len(roles) != len(model.scopes):
        raise ValueError(f"path: sidecar lists {len(roles)} factor roles for "
                         f"{len(model.scopes)} factors")
    index = {t: v for v, t in enumerate(model.names)}
    T = None
    priors: dict[int, np.ndarray] = {}
    comps = []
    for f, (role, s, t) in enumerate(zip(roles, model.scopes, model.tables, strict=True)):
        if "prior" in role:
            if not _is_int(role["prior"]) or s != (int(role["prior"]),):
                raise ValueError(f"path: {sp}: factor {f} is a prior of {role['prior']!r} but "
                                 f"has scope {s}")
            priors[s[0]] = t
        elif "composition" in role:
            c = role["composition"]
            if not (isinstance(c, list) and len(c) == 4 and all(_is_int(x) for x in c)):
                raise ValueError(f"path: {sp}: factor {f}: composition must be [i, j, k, s] "
                                 f"integers, got {c!r}")
            i, j, k, q = c
            want = tuple(index.get(x, -1) for x in ((i, j, k), (j, k, q), (i, j, q)))
            if s != want:
                raise ValueError(f"path: {sp}: factor {f} is composition {(i, j, k, q)} but has "
                                 f"scope {s} (its triplets are variables {want}; -1: absent)")
            if T is None:
                T = t
            elif not np.array_equal(T, t):
                raise ValueError(f"path: composition factor {f} has a different table than the "
                                 f"first one (a factor graph has one tensor)")
            comps.append((i, j, k, q))
        else:
            raise ValueError(f"path: {sp}: factor {f}: role {role!r} is neither prior nor "
                             f"composition")
    m = model.cards[0] if model.n else 0
    if T is None:  # no composition factor: the partition's tensor (lazily), or a placeholder
        T = None if model.partition else np.ones((m,) * 3)
    g = QualitativeFactorGraph(model.partition, tensor=T)
    for v, t in enumerate(model.names):
        g.add_triplet(t, priors.get(v))
        if v in priors:       # validated above; kept bit for bit (add_triplet re-normalizes)
            g._priors[v] = np.array(priors[v], dtype=float)
    for c in comps:
        g.add_composition(c)
    return g
