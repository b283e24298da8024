"""qfg: probabilistic qualitative localization and mapping.

A reference implementation of Mor and Indelman, "Probabilistic Qualitative Localization and
Mapping": qualitative space partitions, a scenario simulator, single-triplet solvers, composition
tensors and the qualitative factor graph on GTSAM.

Modules, in the order data flows through them:
``partitions``, ``geometry`` -> ``simulation`` -> ``solvers`` -> ``composition`` -> ``graph`` ->
``propagation`` -> ``metrics`` -> ``plotting``.
"""

from . import geometry, metrics, partitions, simulation
from ._version import __version__

__all__ = ["__version__", "geometry", "metrics", "partitions", "simulation"]
