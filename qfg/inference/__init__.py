"""Inference on qualitative factor graphs: exact marginals (one junction-tree calibration), MAP and
K-best joint assignments, loopy BP (:mod:`qfg.inference.loopy`), the labelled result types, and
the UAI model format.

Label-correcting propagation (Algorithms 2 and 3) lives in :mod:`qfg.propagation` and returns the
same :class:`Marginals` type.

>>> import numpy as np
>>> from qfg.graph import full_map
>>> g = full_map(4, partition=None, tensor=np.ones((2, 2, 2)))
>>> exact_marginals(g)[(0, 1, 2)].tolist()
[0.5, 0.5]
"""

from .evidence import clamp, read_evid
from .exact import METHODS as EXACT_METHODS
from .exact import elimination_estimate, exact_marginals, k_best, map_assignment
from .junction import MAX_TABLE, FactorModel, JunctionTree, SizeEstimate, size_estimate
from .loopy import (
    BP_DEGREE_WARN,
    BP_OVERLAP_WARN,
    DenseMapWarning,
    NotConvergedWarning,
    loopy_bp,
    loopy_bp_memory,
)
from .memory import MemoryBudgetError, MemoryEstimate, memory_budget
from .results import Assignment, GraphTooLargeError, Marginals, MissingKeyError, ZeroMassError
from .tasks import TaskResult, query, read_result, solve_task, write_result
from .uai import read_uai, read_uai_graph, write_uai


def __getattr__(name):
    if name == "ENGINES":
        raise AttributeError(f"ENGINES was removed from {__name__}: use EXACT_METHODS "
                             "(CHANGELOG.md, 0.6.0)")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = ["exact_marginals", "map_assignment", "k_best", "elimination_estimate", "EXACT_METHODS",
           "FactorModel", "JunctionTree", "SizeEstimate", "size_estimate", "MAX_TABLE",
           "Marginals", "Assignment", "GraphTooLargeError", "ZeroMassError", "MissingKeyError",
           "write_uai", "read_uai", "read_uai_graph", "read_evid", "clamp", "MemoryBudgetError",
           "MemoryEstimate", "memory_budget", "query", "solve_task", "write_result",
           "read_result", "TaskResult", "loopy_bp", "loopy_bp_memory", "NotConvergedWarning",
           "DenseMapWarning", "BP_OVERLAP_WARN", "BP_DEGREE_WARN"]
