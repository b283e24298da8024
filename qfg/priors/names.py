"""The priors by name (:data:`NAMES`, :func:`get`): ``"world"``, ``"world-product"`` and
``"uniform"``, or a :class:`~qfg.priors.Prior` as is."""

from __future__ import annotations

from .base import Prior
from .box import WorldBoxPrior
from .independent import ProductPrior, WindowPrior

__all__ = ["get", "NAMES"]

#: Names :func:`get` accepts.
NAMES = ("world", "world-product", "uniform")


def get(prior) -> Prior:
    """A :class:`Prior` from a Prior (returned as is) or a name: ``"world"`` (the exact
    :class:`WorldBoxPrior` of the simulator's box), ``"world-product"`` (:class:`ProductPrior`,
    approximate), ``"uniform"`` (:class:`WindowPrior` on :data:`DEFAULT_WINDOW`).

    ``"arc"`` (the solvers' former "uniform in the angle along each locus arc") is not a density
    over configurations (it depends on the measurements), so it is not a prior here.

    >>> get("uniform").window
    (-6.0, 6.0, -5.5, 6.5)
    """
    if isinstance(prior, Prior):
        return prior
    if prior == "world":
        return WorldBoxPrior()
    if prior == "world-product":
        return ProductPrior()
    if prior == "uniform":
        return WindowPrior()
    raise ValueError(f"prior: expected a qfg.priors.Prior or one of {NAMES}, got {prior!r}")
