"""Degenerate geometry seen in the measurements alone (cameras on line AB, travel along the line
of sight to C, a camera that has not moved): the flags every solver attaches.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians; lengths in |AB|.
"""

from __future__ import annotations

import numpy as np

from ...geometry import LOCUS_EPS, wrap_angle

#: A sampler's answer whose posterior weight has C's depth along its lines of sight unresolved
#: for more than this share is flagged (:data:`UNRESOLVED_REASON`).
UNRESOLVED_SHARE = 0.5
UNRESOLVED_REASON = ("lines of sight to C (nearly) coincide: its depth along them is set by the "
                     "prior")

#: Bearings of consecutive views equal within this (radians, all three): the camera is taken as
#: not having moved.
SAME_POSE_TOL = 1e-9


def repeated_views(bearings) -> np.ndarray:
    """(n,) True where view i repeats view i - 1's bearings within :data:`SAME_POSE_TOL` (all
    three): the camera is then taken as not having moved (view 1 is never a repeat).

    >>> repeated_views(np.array([[0.1, 0.5, 1.0], [0.1, 0.5, 1.0], [0.2, 0.5, 1.0]])).tolist()
    [False, True, False]
    """
    b = np.asarray(bearings, dtype=float)
    out = np.zeros(b.shape[0], dtype=bool)
    if b.shape[0] > 1:
        out[1:] = np.all(np.abs(wrap_angle(b[1:] - b[:-1])) <= SAME_POSE_TOL, axis=1)
    return out


def repeated_reason(repeated) -> str:
    """The flag for views taken as not moved ("" when there are none)."""
    sp = np.flatnonzero(repeated)
    if not sp.size:
        return ""
    return ("view(s) " + ", ".join(str(v + 1) for v in sp)
            + " repeat the previous view's bearings (camera taken as not moved)")


#: C's depth is called unresolved when its standard deviation along the least constrained
#: direction exceeds this fraction of its distance from the nearest camera.
DEPTH_SPREAD = 0.5


def geometry_reasons(bearings, sigma_bearing=0.0, headings=None, sigma_heading=0.0
                     ) -> list[str]:
    """Flags from the measurements alone: cameras on line AB (a locus that is degenerate, or
    within a tenth of the bearing noise of it in all but at most one view: fewer than two views
    then place the camera); travel along the line of sight to C between every pair of views
    (``psi_i`` equal to ``phi_C,i`` or opposite, within ``hypot(sigma_v, sigma_w)``): the lines
    of sight to C may then coincide, leaving C's depth to the prior.

    One noisy view near line AB among several is not flagged: its arc is only poorly known, and
    the other views place the camera (at 2/5 deg such single views flagged 9% of the 20-view
    answers of the views sweep, `docs/solvers.md`).

    >>> b = np.tile([0.3, 1.2, 0.8], (4, 1)); b[2, 1] = 0.3 + 1e-4   # view 3 near line AB
    >>> geometry_reasons(b, 0.035), len(geometry_reasons(b[2:3], 0.035))
    ([], 1)
    """
    out = []
    g = np.abs(np.sin(wrap_angle(bearings[:, 1] - bearings[:, 0])))
    # within a tenth of the bearing noise: the arc is then not known to be finite
    tol = max(LOCUS_EPS, float(np.sin(min(0.1 * float(sigma_bearing), np.pi / 2))))
    near = g < tol
    bad = [int(i) for i in np.flatnonzero(near)]
    if bad and (np.any(g < LOCUS_EPS) or np.count_nonzero(~near) < 2):
        out.append("camera on line AB (phi_A = phi_B or opposite, within the bearing noise) in "
                   "view(s) " + ", ".join(str(b + 1) for b in bad))
    if headings is not None and len(headings) >= 1:
        d = wrap_angle(np.asarray(headings) - bearings[:-1, 2])
        off = np.minimum(np.abs(d), np.pi - np.abs(d))
        # sigma_heading: one number or one per step
        if np.all(off <= np.maximum(1e-6, np.hypot(sigma_bearing, sigma_heading))):
            out.append("lines of sight to C may coincide: the camera travels along its line of "
                       "sight to C between every pair of views")
    return out
