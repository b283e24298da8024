"""Priors over AB-frame configurations ``[C, X_1, ..., X_n]`` (the points a triplet solver
reasons about), as objects.

Every prior has a ``name``, ``log_density(points)`` and ``sample(seed, n_cameras, size)``:

* :class:`WorldBoxPrior` (``"world"``): exact for the simulator's world, every object (the three
  landmarks and every camera position) i.i.d. uniform in a W x H box, every pair at least
  ``d_min`` apart. Seen from the AB frame, the shared unknown scale and rotation of AB couple C
  and the cameras; the density integrates them out (derivation: ``docs/priors.md``).
* :class:`WindowPrior` (``"uniform"``): independent points uniform in an AB-frame window.
* :class:`ProductPrior` (``"world-product"``): the former ``"world"`` prior, a product of
  independent heavy-tailed per-point densities fitted to the world's AB-frame marginal. It is an
  *approximation*: it ignores the coupling, which costs about 0.1 nats of log score.
* :class:`CallablePrior`: a user's own density (and optionally sampler).

Besides these, :class:`TravelPrior` joins a world box with one step's measured length in metres,
:class:`TrajectoryPrior` makes later cameras scale-free steps of a path, and
:class:`MixturePrior` averages priors. Modules, one job each: ``base`` (:class:`Prior`, the
shared argument checks), ``box``, ``travel``, ``trajectory``, ``mixture``, ``independent``
(window and product), ``custom`` (callables), ``names`` (:func:`get`) and ``measurements``
(:func:`sample_measurements`).

Camera headings are uniform in every prior here (a uniform world heading is uniform in any
frame), so priors are densities over positions only. Units: AB-frame lengths (|AB| = 1).

>>> import numpy as np
>>> p = get("world")
>>> x = p.sample(np.random.default_rng(0), n_cameras=2, size=4)
>>> x.shape, bool(np.all(np.isfinite(p.log_density(x))))
((4, 3, 2), True)
"""

from .base import LENGTH_RANGE as LENGTH_RANGE
from .base import Prior
from .box import MAX_N_RHO as MAX_N_RHO
from .box import MIN_BOX_SIDE as MIN_BOX_SIDE
from .box import WorldBoxPrior
from .custom import CallablePrior
from .independent import COORD_LIMIT as COORD_LIMIT
from .independent import DEFAULT_WINDOW, ProductPrior, WindowPrior
from .independent import MAX_WINDOW_ASPECT as MAX_WINDOW_ASPECT
from .measurements import sample_measurements
from .mixture import MixturePrior
from .names import NAMES, get
from .trajectory import TrajectoryPrior
from .travel import TravelPrior

# The accepted parameter ranges (LENGTH_RANGE, MIN_BOX_SIDE, MAX_N_RHO, COORD_LIMIT,
# MAX_WINDOW_ASPECT; imported "as" themselves above) are public too, each documented in its
# module, but stay out of __all__.
__all__ = ["Prior", "WorldBoxPrior", "TravelPrior", "TrajectoryPrior", "MixturePrior",
           "WindowPrior", "ProductPrior", "CallablePrior", "get", "sample_measurements", "NAMES",
           "DEFAULT_WINDOW"]
