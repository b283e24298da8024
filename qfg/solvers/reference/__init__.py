"""``method="reference"``: the exact posterior P(S^{AB:C} | H) and P(S^{AB:X}_i | H) under a given
prior by adaptive importance sampling, with its Monte Carlo error: the yardstick the other
methods are measured against (seconds per triplet).

* :mod:`.staged`: :func:`solve_reference` (the entry point, :data:`REFERENCE_DEFAULTS`) and the
  staged sampler (views added in stages, proposals adapted from round to round);
* :mod:`.conditional`: the conditional sampler (C from a fitted 2-D mixture, the trajectory
  given C by a particle filter twisted by its Laplace approximation; time linear in the views),
  which ``sampler="auto"`` takes beyond :data:`.staged.AUTO_STAGED_VIEWS` views, with
  :mod:`.trajectory`: the trajectory given C (resection, its conditional Gaussian in arc
  coordinates, the Laplace marginal of C);
* :mod:`.weights`: what both share: the wrapped-normal density, the summary of a weighted sample
  and the flags.
"""

from .staged import REFERENCE_DEFAULTS, solve_reference

__all__ = ["solve_reference", "REFERENCE_DEFAULTS"]
