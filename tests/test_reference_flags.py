"""The reference solver flags degenerate measurements by the same rule, and in the same words, as
every other method (qfg.solvers.common.degenerate.geometry_reasons): views named 1-based, a camera
near line AB in one view of several not flagged when the others place it."""

import numpy as np

from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplet
from qfg.solvers.common import degenerate as _degenerate


def test_reference_names_the_view_on_line_ab_one_based():
    h = random_triplet_history(np.random.default_rng(4), 3, np.deg2rad(2), np.deg2rad(5))
    b = h.bearings.copy()
    b[1, 1] = b[1, 0]                      # the second view sees A and B in one direction
    est = solve_triplet(b, h.headings, method="reference", sigma_bearing=h.sigma_bearing,
                        sigma_heading=h.sigma_heading, seed=0)
    assert est.degenerate
    assert "camera on line AB" in est.reason and "view(s) 2" in est.reason
    assert _degenerate.geometry_reasons(b, h.sigma_bearing, h.headings,
                                        h.sigma_heading)[0] in est.reason


def test_reference_does_not_flag_one_view_near_line_ab_among_several():
    """Within a bearing sigma of line AB in one view of four: the other three place the camera
    (the full solver does not flag it either)."""
    h = random_triplet_history(np.random.default_rng(5), 4, np.deg2rad(2), np.deg2rad(5))
    b = h.bearings.copy()
    b[2, 1] = b[2, 0] + 0.5 * h.sigma_bearing
    for method in ("reference", "full"):
        est = solve_triplet(b, h.headings, method=method, sigma_bearing=h.sigma_bearing,
                            sigma_heading=h.sigma_heading, seed=0)
        assert "line AB" not in est.reason, (method, est.reason)
