"""The UAI competition tasks on a factor model, and a query interface on graphs and models.

* :func:`solve_task` -- ``PR`` (``log10 Z(e)``), ``MAR`` (every variable's marginal given the
  evidence) or ``MAP`` (the most probable joint assignment given the evidence; ``MPE`` is the same
  task under its older name), as a :class:`TaskResult`; :func:`write_result` /
  :meth:`TaskResult.to_text` give the competition's result file (first line the task, then the
  solution line), and ``qfg uai MODEL --evid FILE --task PR|MAR|MAP --output FILE`` does both
  from the command line.
* :func:`query` -- the marginals of chosen variables (triplets of a graph, or variable indices of
  a model) given evidence, labelled.

All of them run the junction tree with the evidence clamped before planning, and are bounded
by the memory budget (:mod:`qfg.inference.memory`).

>>> import numpy as np
>>> from qfg.inference.junction import FactorModel
>>> model = FactorModel([2, 2], [(0, 1)], [[[0.9, 0.1], [0.2, 0.8]]])
>>> r = solve_task(model, "MAR", evidence={1: 1})
>>> print(r.to_text(), end="")                       # x0 given x1 = 1: 0.1 / 0.9, 0.8 / 0.9
MAR
2 2 0.111111111111111 0.888888888888889 2 0 1
>>> query(model, [0], evidence={1: 1})[0].round(3).tolist()
[0.111, 0.889]
"""

from __future__ import annotations

import errno
import math
import time
from collections.abc import Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..files import atomic_write_text
from .junction import FactorModel, JunctionTree

__all__ = ["TASKS", "TaskResult", "solve_task", "write_result", "read_result", "query"]

#: Tasks of :func:`solve_task` (``MPE`` is accepted as another name of ``MAP``).
TASKS = ("PR", "MAR", "MAP")


@dataclass(frozen=True)
class TaskResult:
    """The answer to one task on one model.

    Attributes:
        task: ``"PR"``, ``"MAR"`` or ``"MAP"``.
        log10_z: ``log10 Z(e)`` (every task computes it).
        marginals: MAR: tuple of (card_v,) arrays, one per variable (observed ones one-hot);
            else ().
        assignment: MAP: (n,) int states (observed variables at their observed states);
            else ().
        log10_p: MAP: log10 of the assignment's probability given the evidence; else nan.
        evidence: ``{variable: state}`` applied.
        seconds: wall time of the solve (planning included, reading excluded).
    """

    task: str
    log10_z: float
    marginals: tuple = ()
    assignment: tuple = ()
    log10_p: float = float("nan")
    evidence: Mapping = field(default_factory=dict)
    seconds: float = 0.0

    def to_text(self) -> str:
        """The competition's result file: the task on the first line, the solution on the next
        (PR: ``log10 Z(e)``; MAR: ``n`` then per variable its cardinality and probabilities;
        MAP: ``n`` then the states), 15 significant digits."""
        if self.task == "PR":
            sol = format(self.log10_z, ".15g")
        elif self.task == "MAR":
            parts = [str(len(self.marginals))]
            for p in self.marginals:
                parts.append(str(len(p)))
                parts += [format(float(x), ".15g") for x in p]
            sol = " ".join(parts)
        else:
            sol = " ".join([str(len(self.assignment))] + [str(int(x)) for x in self.assignment])
        return f"{self.task}\n{sol}\n"

    def __repr__(self) -> str:
        extra = {"MAR": f", variables={len(self.marginals)}",
                 "MAP": f", variables={len(self.assignment)}, log10_p={self.log10_p:.6g}",
                 "PR": ""}[self.task]
        return (f"TaskResult(task={self.task!r}, log10_z={self.log10_z:.6g}{extra}, "
                f"evidence={len(self.evidence)} variables, seconds={self.seconds:.3g})")


def _task(task) -> str:
    t = str(task).upper()
    if t == "MPE":
        t = "MAP"
    if t not in TASKS:
        raise ValueError(f"task: expected one of {', '.join(TASKS)} (or MPE), got {task!r}")
    return t


def _model(model) -> FactorModel:
    if isinstance(model, FactorModel):
        return model
    if isinstance(model, (str, Path)):
        from .uai import read_uai

        return read_uai(model)
    return FactorModel.from_graph(model)


def solve_task(model, task: str, evidence=None, *, memory=None) -> TaskResult:
    """Solve one UAI task exactly.

    Args:
        model: a :class:`~qfg.inference.junction.FactorModel`, a ``.uai`` path, or a factor graph.
        task: ``"PR"``, ``"MAR"`` or ``"MAP"`` (``"MPE"``).
        evidence: ``{variable: state}``, a ``.evid`` path (either layout), or None.
        memory: the memory budget: bytes, a size (``"2G"``), a share of the machine's memory
            (``"50%"``) or unlimited (``math.inf``, ``"inf"``); default
            :func:`~qfg.inference.memory.memory_budget` (:mod:`qfg.budget`).

    Raises :class:`~qfg.inference.memory.MemoryBudgetError` before any work when the estimate
    exceeds the budget, :class:`~qfg.inference.results.ZeroMassError` when the evidence has
    probability zero. An evidence file whose variable the model does not have ->
    :class:`~qfg.inference.results.MissingKeyError` (a KeyError and a ValueError) naming the file
    and line.
    """
    task = _task(task)
    model = _model(model)
    evidence, source = _evidence(model, evidence)
    t0 = time.perf_counter()
    jt = JunctionTree(model, evidence=evidence, memory=memory)
    with _zero_mass_named(jt, source):
        return _solve(jt, model, task, t0)


def _solve(jt, model, task, t0) -> TaskResult:
    ln10 = math.log(10)
    if task == "MAP":
        X, lp = jt.k_best(1)
        Xc = X.copy()
        Xc[:, list(jt.evidence)] = 0            # the clamped model's one state
        logz = float(jt.model.log_value(Xc)[0] - lp[0])
        return TaskResult("MAP", logz / ln10, assignment=tuple(int(x) for x in X[0]),
                          log10_p=float(lp[0]) / ln10, evidence=dict(jt.evidence),
                          seconds=time.perf_counter() - t0)
    P, logz, _ = jt.calibrate()
    marg = ()
    if task == "MAR":
        marg = tuple(np.array(P[v, :c]) for v, c in enumerate(model.cards))
    return TaskResult(task, logz / ln10, marginals=marg, evidence=dict(jt.evidence),
                      seconds=time.perf_counter() - t0)


def _evidence(model, evidence):
    """(evidence for the junction tree, where it came from for messages). A ``.evid`` file is
    read here and checked against the model, so that a variable or state the model does not
    have is named with the file and line: a :class:`~qfg.inference.results.MissingKeyError`
    (a KeyError and a ValueError) or a ValueError."""
    if not isinstance(evidence, (str, Path)):
        return evidence, None
    from .evidence import read_evid
    from .results import MissingKeyError

    path = Path(evidence)
    ev = read_evid(path)
    lines = None
    for v, x in ev.items():
        if v < model.n and x < model.cards[v]:
            continue
        lines = lines or _evid_lines(path)
        where = f"evidence: {path}, line {lines.get(v, '?')}"
        if v >= model.n:
            raise MissingKeyError(f"{where}: variable {v} is not in the model (it has "
                                  f"{model.n} variable{'s' if model.n != 1 else ''}, numbered "
                                  f"from 0)")
        raise ValueError(f"{where}: state {x} of variable {v} is outside 0..{model.cards[v] - 1}")
    return ev, path


def _evid_lines(path: Path) -> dict[int, int]:
    """``{variable: line number from 1}`` of an evidence file that
    :func:`~qfg.inference.evidence.read_evid` accepted (the same layouts)."""
    toks = [(int(t), number) for number, line in enumerate(path.read_text().splitlines(), 1)
            for t in line.split()]
    vals = [t for t, _ in toks]
    start = 1 if len(vals) == 1 + 2 * vals[0] else 2
    return {vals[i]: toks[i][1] for i in range(start, len(vals) - 1, 2)}


@contextmanager
def _zero_mass_named(jt, source):
    """A ZeroMassError of a model given evidence said in the words of evidence (the
    qualitative-map wording, priors against a tensor's support, is for factor graphs with no
    evidence); of a plain model without evidence, in the words of a model."""
    from .results import ZeroMassError

    try:
        yield
    except ZeroMassError as exc:
        named = bool(jt.source.names) and all(len(t) == 3 for t in jt.source.names)
        if jt.evidence:
            where = f"{source}: " if source is not None else ""
            msg = (f"evidence: {where}the evidence ({len(jt.evidence)} observed "
                   f"variable{'s' if len(jt.evidence) != 1 else ''}) has probability zero under "
                   f"the model: every assignment that agrees with it has a factor of value 0, "
                   f"so Z(e) = 0 and nothing given it is defined")
        elif not named:
            msg = ("model: the product of the factors is 0 for every assignment (Z = 0): the "
                   "model defines no distribution")
        else:
            raise
        raise ZeroMassError(msg, triplets=exc.triplets, local_factors=exc.local_factors) from None


def write_result(result: TaskResult, path) -> Path:
    """Write ``result.to_text()`` to ``path`` (folders created); returns the path.

    The file is replaced whole (:func:`qfg.files.atomic_write_text`): a write that fails (no
    space, a file size limit) leaves an existing result as it was. Errors are OSError naming the
    file: ``path`` a folder, its folder a file, no permission, no space."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except FileExistsError:   # mkdir says "File exists" of the folder that is a file
        raise NotADirectoryError(errno.ENOTDIR, f"its folder {path.parent} is a file",
                                 str(path)) from None
    atomic_write_text(path, result.to_text())
    return path


def read_result(path):
    """A competition result file (``PR``: log10 Z, a float; ``MAR``: a list of (card,) arrays, one
    per variable), e.g. the reference answers shipped with the instances, or what
    :func:`write_result` wrote. ValueError naming the file when it is not one.

    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "x.MAR")
    >>> _ = open(p, "w").write("MAR 2  2 0.25 0.75  1 1.0")
    >>> [a.tolist() for a in read_result(p)]
    [[0.25, 0.75], [1.0]]
    """
    tok = Path(path).read_text().split()
    try:
        if tok[0] == "PR":
            return float(tok[1])
        if tok[0] != "MAR":
            raise ValueError(f"expected PR or MAR first, got {tok[0]!r}")
        n, pos, out = int(tok[1]), 2, []
        for _ in range(n):
            c = int(tok[pos])
            if len(tok) < pos + 1 + c:
                raise ValueError("fewer values than the cardinalities announce")
            out.append(np.array(tok[pos + 1:pos + 1 + c], dtype=float))
            pos += 1 + c
    except (IndexError, ValueError) as exc:
        raise ValueError(f"{path}: not a PR or MAR result file ({exc})") from None
    return out


def query(g_or_model, variables=None, evidence=None, *, memory=None):
    """Marginals of ``variables`` given ``evidence``, exact (one junction-tree calibration).

    Args:
        g_or_model: a :class:`~qfg.graph.QualitativeFactorGraph`, a
            :class:`~qfg.inference.junction.FactorModel` or a ``.uai`` path.
        variables: triplets ``(i, j, k)`` (graph) or variable indices (model); None: all.
        evidence: ``{triplet or variable: state}`` or a ``.evid`` path.
        memory: the memory budget, as for :func:`solve_task`.

    Returns, for a graph (or a model whose variables are named by triplets): a
    :class:`~qfg.inference.results.Marginals` over the queried triplets, in the order asked
    (``info``: ``log_partition`` = ``log Z(e)``, ``evidence``); for a model without names: a
    dict ``{variable: (card,) array}``. A variable not in the model -> KeyError.

    >>> import numpy as np
    >>> from qfg.graph import QualitativeFactorGraph
    >>> g = QualitativeFactorGraph(None, tensor=np.eye(2)[:, :, None] * np.eye(2)[None])
    >>> for t in [(0, 1, 2), (1, 2, 3), (0, 1, 3)]:
    ...     _ = g.add_triplet(t)
    >>> _ = g.discover_compositions()
    >>> r = query(g, [(0, 1, 3)], evidence={(0, 1, 2): 1})   # the factor makes all three equal
    >>> r[(0, 1, 3)].tolist(), r.triplets
    ([0.0, 1.0], ((0, 1, 3),))
    """
    from .results import Marginals

    graph = None
    if not isinstance(g_or_model, (FactorModel, str, Path)):
        graph = g_or_model
    model = _model(g_or_model)
    evidence, source = _evidence(model, evidence)
    jt = JunctionTree(model, evidence=evidence, memory=memory)
    rows = _rows(model, variables)
    with _zero_mass_named(jt, source):
        P, logz, _ = jt.calibrate()
    named = bool(model.names) and all(len(t) == 3 for t in model.names)
    if named:
        m = max(model.cards) if model.n else 0
        part = graph.partition if graph is not None else model.partition
        ev = {model.names[v]: x for v, x in jt.evidence.items()}
        return Marginals(tuple(model.names[v] for v in rows), part, P[rows, :m].reshape(-1, m),
                         "junction", {"log_partition": logz, "evidence": ev})
    return {v: np.array(P[v, :model.cards[v]]) for v in rows}


def _rows(model, variables) -> list[int]:
    if variables is None:
        return list(range(model.n))
    names = {tuple(t): v for v, t in enumerate(model.names)} if model.names else {}
    if isinstance(variables, (int, np.integer)) or (
            isinstance(variables, tuple) and len(variables) == 3 and names
            and all(isinstance(x, (int, np.integer)) for x in variables)):
        variables = [variables]
    out = []
    for x in variables:
        if isinstance(x, (int, np.integer)) and not isinstance(x, bool):
            if not 0 <= int(x) < model.n:
                raise KeyError(f"variables: {int(x)} is not a variable of the model "
                               f"(0..{model.n - 1})")
            out.append(int(x))
            continue
        try:
            out.append(names[tuple(int(a) for a in x)])
        except (KeyError, TypeError, ValueError):
            raise KeyError(f"variables: {x!r} is not in the model") from None
    return out
