"""The reference solver names views in its flags 1-based, as every other method does."""

import numpy as np

from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplet


def test_reference_names_the_view_on_line_ab_one_based():
    h = random_triplet_history(np.random.default_rng(4), 3, np.deg2rad(2), np.deg2rad(5))
    b = h.bearings.copy()
    b[1, 1] = b[1, 0]                      # the second view sees A and B in one direction
    est = solve_triplet(b, h.headings, method="reference", sigma_bearing=h.sigma_bearing,
                        sigma_heading=h.sigma_heading, seed=0)
    assert est.degenerate
    assert "camera on line AB in view(s) 2" in est.reason
