"""Evidence: observed variables clamped into a factor model before any planning.

Observing ``x_v = e_v`` for v in E turns ``p(x) = prod_f phi_f(x_f) / Z`` into
``p(x_U | e) = prod_f phi_f(x_f \\ E, e_f) / Z(e)`` with ``Z(e) = sum_{x_U} prod_f phi_f(x_U, e)``
(the UAI competitions' PR task reports ``log10 Z(e)``). :func:`clamp` slices every table at the
observed states, so observed variables leave every scope (they cut the interaction graph: the
junction tree of the clamped model is planned without them) and keep one state each (cardinality
1, no factor, or a 1-entry factor carrying the constant of a table whose whole scope was
observed). Marginals of the clamped model are read back with the observed rows one-hot
(:func:`expand_marginals`).

Evidence files (``.evid``), whitespace-separated integers in either competition layout:

* UAI 2014: ``n v_1 x_1 ... v_n x_n`` (one line; ``0`` or an empty file: no evidence);
* older files: ``1`` (the number of evidence samples) then ``n v_1 x_1 ...``, the pairs on one
  line or one pair per line.

>>> import numpy as np
>>> from qfg.inference.junction import FactorModel, JunctionTree
>>> T = np.array([[0.9, 0.1], [0.2, 0.8]])                 # phi(x0, x1)
>>> model = FactorModel([2, 2], [(0, 1)], [T])
>>> c = clamp(model, {1: 1})                                # observe x1 = 1
>>> c.cards, c.scopes, [t.tolist() for t in c.tables]
((2, 1), ((0,),), [[0.1, 0.8]])
>>> round(JunctionTree(c).log_partition(), 6) == round(float(np.log(0.9)), 6)
True
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

__all__ = ["read_evid", "check_evidence", "clamp", "expand_marginals"]


def read_evid(path) -> dict[int, int]:
    """``{variable: observed state}`` from a ``.evid`` file (either layout, see the module
    docstring). Malformed files -> ValueError naming the file."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"path: cannot read {path}: {exc}") from None
    tok = text.split()
    vals = []
    for i, s in enumerate(tok):
        # int("1_0") is 10 in Python: the format has plain decimal integers only
        if not (s.isascii() and s.isdigit()):
            raise ValueError(f"path: {path}: token {i + 1} {s!r} is not a non-negative integer")
        vals.append(int(s))
    if not vals:
        return {}
    if len(vals) == 1 + 2 * vals[0]:
        pairs = vals[1:]
    elif vals[0] == 1 and len(vals) >= 2 and len(vals) == 2 + 2 * vals[1]:
        pairs = vals[2:]                                  # older layout: one sample
    else:
        raise ValueError(f"path: {path}: {len(vals)} integers fit neither layout ('n v x ...' "
                         f"with n = {vals[0]} needs {1 + 2 * vals[0]}; '1 n v x ...' needs "
                         f"2 + 2n)")
    ev: dict[int, int] = {}
    for v, x in zip(pairs[0::2], pairs[1::2], strict=True):
        if v in ev and ev[v] != x:
            raise ValueError(f"path: {path}: variable {v} observed twice ({ev[v]} and {x})")
        ev[v] = x
    return ev


def check_evidence(model, evidence) -> dict[int, int]:
    """``evidence`` (a mapping variable -> state, or a ``.evid`` path) checked against the
    model's cardinalities: ``{int variable: int state}``. Variables may also be named by the
    model's ``names`` (e.g. triplets). ValueError/KeyError naming ``evidence`` otherwise."""
    if evidence is None:
        return {}
    if isinstance(evidence, (str, Path)):
        evidence = read_evid(evidence)
    if not isinstance(evidence, Mapping):
        raise ValueError(f"evidence: expected a mapping variable -> state or a .evid path, got "
                         f"{type(evidence).__name__}")
    names = {t: v for v, t in enumerate(model.names)} if model.names else {}
    out: dict[int, int] = {}
    for key, x in evidence.items():
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
            v = int(key)
            if not 0 <= v < model.n:
                raise KeyError(f"evidence: variable {v} is not in the model (0..{model.n - 1})")
        else:
            try:
                v = names[tuple(int(a) for a in key)]
            except (KeyError, TypeError, ValueError):
                raise KeyError(f"evidence: {key!r} is not a variable of the model") from None
        if isinstance(x, bool) or not isinstance(x, (int, np.integer)):
            raise ValueError(f"evidence: state of {key!r} must be an integer, got {x!r}")
        if not 0 <= int(x) < model.cards[v]:
            raise ValueError(f"evidence: state {int(x)} of {key!r} is outside 0..{model.cards[v] - 1}")
        out[v] = int(x)
    return out


def clamp(model, evidence):
    """The model conditioned on ``evidence`` (see the module docstring): observed variables
    get cardinality 1 and leave every scope; tables are sliced at the observed states.

    The clamped model's ``log Z`` is ``log Z(e)``; its marginals (rows of observed variables
    are ``[1]``) expand back with :func:`expand_marginals`."""
    ev = check_evidence(model, evidence)
    if not ev:
        return model
    cards = tuple(1 if v in ev else c for v, c in enumerate(model.cards))
    scopes, tables = [], []
    sliced: dict = {}
    for s, t in zip(model.scopes, model.tables, strict=True):
        obs = [i for i, v in enumerate(s) if v in ev]
        if not obs:
            scopes.append(s)
            tables.append(t)
            continue
        key = (id(t), tuple((i, ev[s[i]]) for i in obs))
        if key not in sliced:
            idx = tuple(ev[v] if v in ev else slice(None) for v in s)
            sliced[key] = np.ascontiguousarray(t[idx])
        r = sliced[key]
        rest = tuple(v for v in s if v not in ev)
        if not rest:      # the whole scope observed: a constant, kept on one observed variable
            rest, r = (s[obs[0]],), np.reshape(r, (1,))
        scopes.append(rest)
        tables.append(r)
    # type(model): the FactorModel class, without importing the module that imports this one
    return type(model)(cards=cards, scopes=scopes, tables=tables, names=model.names,
                       partition=model.partition)


def expand_marginals(P, model, evidence) -> np.ndarray:
    """(n, max card) marginals of the original model from those of its clamped version:
    observed rows one-hot at the observed state, the other rows as they are."""
    ev = check_evidence(model, evidence)
    width = max(model.cards) if model.n else 0
    out = np.zeros((model.n, width))
    if P.size:
        out[:, :P.shape[1]] = P
    for v, x in ev.items():
        out[v] = 0.0
        out[v, x] = 1.0
    return out
