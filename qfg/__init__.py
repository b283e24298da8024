"""qfg: probabilistic qualitative localization and mapping.

A reference implementation of Mor and Indelman, "Probabilistic Qualitative Localization and
Mapping": qualitative space partitions, a scenario simulator, single-triplet solvers, composition
tensors and the qualitative factor graph on GTSAM.

Library modules, in the order data flows through them:
``partitions``, ``geometry`` -> ``simulation``, ``datasets`` -> ``solvers`` -> ``composition`` ->
``graph`` -> ``inference`` -> ``propagation`` -> ``metrics``. Figures, studies, the experiment
runner and the ``qfg`` command are the harness above it, ``qfg.harness`` (docs/modules.md).

The main entry points are importable from the top level; modules load on first use, so
``import qfg`` stays fast:

>>> import qfg
>>> qfg.QualitativeFactorGraph.__module__
'qfg.graph'
"""

# no `from __future__ import annotations`, and importlib under a private name: dir(qfg) lists
# qfg's own names only (tests/test_surface.py)
import importlib as _importlib

from ._version import __version__

_MODULES = ("geometry", "partitions", "simulation", "datasets", "solvers", "composition", "graph",
            "inference", "propagation", "configurations", "metrics", "nonlinear", "joint")

#: top-level name -> module that defines it
_NAMES = {
    "solve_triplet": "solvers",
    "solve_triplets": "solvers",
    "TripletEstimate": "solvers",
    "QualitativeFactorGraph": "graph",
    "full_map": "graph",
    "map_from_triplets": "graph",
    "map_from_histories": "graph",
    "truth_states": "graph",
    "triplet_key": "graph",
    "exact_marginals": "propagation",
    "propagate": "propagation",
    "topology_scores": "propagation",
    "composition_levels": "propagation",
    "loopy_bp": "inference",
    "compare_unseen": "propagation",
    "GraphTooLargeError": "propagation",
    "ZeroMassError": "propagation",
    "infer_configurations": "configurations",
    "configuration_marginals": "configurations",
    "Marginals": "inference",
    "Assignment": "inference",
    "MissingKeyError": "inference",
    "map_assignment": "inference",
    "k_best": "inference",
    "write_uai": "inference",
    "read_uai": "inference",
    "TripletHistory": "simulation",
    "random_triplet_history": "simulation",
    "random_scenario": "simulation",
    "triplet_histories": "simulation",
    "random_trajectory_run": "simulation",
    "JointMeasurements": "joint",
    "RobotRun": "joint",
}

#: harness modules that lived at the top level before 0.2: a clear pointer instead of a bare miss
_MOVED = ("runner", "studies", "cluster", "results_doc", "demo", "commands", "cli", "plotting",
          "plotting_mrclam")

__all__ = ["__version__", *_MODULES, *_NAMES]


def __getattr__(name):
    if name in _MODULES:
        return _importlib.import_module(f".{name}", __name__)
    if name in _NAMES:
        mod = _importlib.import_module(f".{_NAMES[name]}", __name__)
        return getattr(mod, name)
    if name in _MOVED:
        raise AttributeError(f"qfg.{name} moved to qfg.harness.{name} (the experiment harness, "
                             "above the library; see docs/modules.md)")
    raise AttributeError(f"module 'qfg' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
