"""The odometry's factor: a scale-free likelihood of the ratio of consecutive step lengths given
the travelled distances, shared by the SIS solvers (``full``, ``fast``) and the reference.
"""

from __future__ import annotations

import numpy as np

from . import likelihood as _likelihood


def log_distance_factor(step, prev_step, distance, prev_distance, sigma, tail=None):
    """log of the odometry's scale-free factor on the ratio of consecutive step lengths,

        log N(log(s_i / s_(i-1)) - log(d_i / d_(i-1)); sigma),

    for steps ``s`` (AB units) of hypotheses and the measured distances ``d`` (any unit), all
    broadcast together; with ``tail`` (a :class:`.likelihood.BearingTail` without outliers,
    the option ``distance_tail``) the normal is the mixture ``(1 - share) N(r; sigma) + share
    N(r; scale sigma)`` instead: on MRCLAM 9% of the ratios are off by a factor of about 2
    (docs/mrclam.md, "The odometry's step-length ratios"). 0 (no factor) where a measured
    distance is 0 or a step is not > 0 (a view taken as "camera did not move"): the ratio says
    nothing there.

    >>> round(float(log_distance_factor(2.0, 1.0, 0.4, 0.2, 0.1)), 6)   # ratio matched: -log(sig sqrt(2 pi))
    1.383647
    >>> float(log_distance_factor(2.0, 1.0, 0.4, 0.0, 0.1))
    0.0
    >>> t = _likelihood.BearingTail(share=0.1, scale=5.0)     # a ratio off by a factor of 2
    >>> [round(float(log_distance_factor(2.0, 1.0, 0.8, 0.2, 0.1, k)), 2) for k in (None, t)]
    [-22.64, -3.49]
    """
    s, sp, d, dp, sig = np.broadcast_arrays(*(np.asarray(v, dtype=float)
                                              for v in (step, prev_step, distance,
                                                        prev_distance, sigma)))
    ok = (s > 0) & (sp > 0) & (d > 0) & (dp > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.log(s / sp) - np.log(d / dp)
        if tail is None:
            out = -0.5 * (r / sig) ** 2 - np.log(sig) - 0.5 * np.log(2.0 * np.pi)
        else:
            out = _likelihood.log_bearing(r, sig, tail)
    out = np.where(ok, out, 0.0)
    return np.where(np.isnan(out), -np.inf, out)
