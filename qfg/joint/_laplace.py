"""The Laplace approximation at a fit of the joint solve: GTSAM's marginals
(:class:`qfg.nonlinear.Laplace`) and the covariance blocks the posterior keeps and samples from.

Variables are indexed as in :class:`qfg.nonlinear.BearingProblem`: points (landmarks) by their
row in the problem, poses by theirs; a point's block is (x, y) in metres, a pose's (x, y, theta)
in GTSAM's tangent at the pose (x, y in the pose's own axes).
"""

from __future__ import annotations

import numpy as np

from .. import nonlinear as _nl


def _marginals(pr, fit) -> _nl.Laplace:
    """The Laplace approximation at ``fit``. Where GTSAM's Cholesky fails near a landmark (its
    rays nearly parallel) the landmark is left out by the caller; near a pose (ill-conditioned:
    a pose fitted onto a landmark it sees) :class:`qfg.nonlinear.Laplace`'s sparse solve
    answers, and only a singular system is indeterminate."""
    lap = _nl.Laplace(pr, fit)
    if lap.error_key is not None and lap.error_key >= pr.n_poses:
        raise _nl.SingularInformation(lap.error[:200], lap.error_key)
    return lap


def _points_cov(marg: _nl.Laplace, pr, cols, poses=()):
    """Joint covariance of points ``cols`` then ``poses`` (raises
    :class:`qfg.nonlinear.SingularInformation`, whose ``key`` names the variable)."""
    return marg.joint([int(c) for c in cols], [int(p) for p in poses])


def _weak_info(pr, fit, marg, ok, lflags, inflate):
    """For weak landmarks: their rays and the joint covariance of (every point, the poses that
    see a weak landmark), for conditional resampling."""
    weak = [c for c, j in enumerate(ok.tolist()) if lflags[j] == "weak"]
    if not weak:
        return None
    m = np.isin(pr.bearing_point, weak)
    pidx = np.unique(pr.bearing_pose[m])
    C = _points_cov(marg, pr, np.arange(ok.size), pidx) * inflate
    return {"cols": np.array(weak), "poses": pidx, "cov": C,
            "ray_pose": pr.bearing_pose[m], "ray_point": pr.bearing_point[m],
            "ray_bearing": pr.bearing[m], "ray_sigma": pr.sigma_bearing[m],
            "pose_mean": fit.poses[pidx], "robust": pr.robust_bearing}

