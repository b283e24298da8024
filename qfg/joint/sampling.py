"""Samples of a :class:`qfg.joint.JointPosterior`: :func:`sample_landmarks` draws the landmark
positions the qualitative states are read from (modes by weight, Gaussian within a mode, weak
landmarks from their exact conditional by sampling-importance-resampling);
:func:`reference_samples` runs random-walk Metropolis chains on the exact robust posterior, to
check those approximations against on small problems.

Samples are (n, L, 2) arrays in the map frame (metres), landmarks in the order of
``posterior.landmark_ids``, NaN for unconstrained landmarks.
"""

from __future__ import annotations

import numpy as np

from .. import nonlinear as _nl
from .._validate import as_rng, positive_int
from ..geometry import wrap_angle
from ._laplace import _points_cov
from .posterior import JointPosterior

__all__ = ["sample_landmarks", "reference_samples"]


def _huber(r, k):
    a = np.abs(r)
    return np.where(a <= k, 0.5 * r * r, k * a - 0.5 * k * k) if k > 0 else 0.5 * r * r


def sample_landmarks(posterior: JointPosterior, n: int = 2000, seed=0, *,
                     proposals: int = 64) -> np.ndarray:
    """``n`` joint samples (n, L, 2) of the landmark positions (NaN for unconstrained ones):
    modes chosen by weight, Gaussian within a mode; weak landmarks of the best mode resampled
    from their exact conditional given the sampled poses (``proposals`` Student-t draws per
    sample and landmark, one kept by its importance weight)."""
    n = positive_int("n", n)
    rng = as_rng(seed)
    L = len(posterior.landmark_ids)
    out = np.full((n, L, 2), np.nan)
    if posterior.method == "none" or not posterior.modes:
        return out
    ok = np.flatnonzero(posterior.constrained)
    counts = rng.multinomial(n, [m.weight for m in posterior.modes])
    start = 0
    for k, (mode, c) in enumerate(zip(posterior.modes, counts, strict=False)):
        if c == 0:
            continue
        sl = slice(start, start + c)
        start += c
        wk = posterior._weak if k == 0 else None
        if wk is None:
            z = _nl.sample_gaussian(mode.points[ok].ravel(), mode.covariance, int(c), rng)
            out[sl, ok] = z.reshape(c, ok.size, 2)
            continue
        mu = np.concatenate([mode.points[ok].ravel(), wk["pose_mean"].ravel()])
        z = _nl.sample_gaussian(mu, wk["cov"], int(c), rng)
        pts = z[:, :2 * ok.size].reshape(c, ok.size, 2)
        # GTSAM's pose tangent (x, y in the pose's own axes) -> world perturbation
        d = z[:, 2 * ok.size:].reshape(c, -1, 3) - wk["pose_mean"][None]
        th = wk["pose_mean"][None, :, 2]
        poses = wk["pose_mean"][None] + np.stack(
            [np.cos(th) * d[..., 0] - np.sin(th) * d[..., 1],
             np.sin(th) * d[..., 0] + np.cos(th) * d[..., 1], d[..., 2]], -1)
        pos_of = {int(p): i for i, p in enumerate(wk["poses"].tolist())}
        for col in wk["cols"].tolist():
            m = wk["ray_point"] == col
            pi = np.array([pos_of[int(p)] for p in wk["ray_pose"][m]])
            # proposal: the Gaussian conditional of this landmark given the sampled poses
            # (regression on the pose block), widened x2 in sd, Student t with 4 dof
            # (a landmark is tied to the other poses only through the ones that see it, so
            # conditioning on those is conditioning on all)
            jj = np.arange(2 * col, 2 * col + 2)
            up = np.unique(pi)
            xx = (2 * ok.size + 3 * up[:, None] + np.arange(3)[None, :]).ravel()
            Cxx = wk["cov"][np.ix_(xx, xx)]
            Cxx = (Cxx + Cxx.T) / 2 + np.eye(xx.size) * 1e-12 * max(np.trace(Cxx), 1e-30)
            Bm = np.linalg.solve(Cxx, wk["cov"][np.ix_(xx, jj)]).T          # (2, 3 |up|)
            Cj = (wk["cov"][np.ix_(jj, jj)] - Bm @ wk["cov"][np.ix_(xx, jj)]) * 4.0
            Cj = (Cj + Cj.T) / 2 + np.eye(2) * 1e-12
            mu_j = mode.points[ok][col] + d[:, up].reshape(c, -1) @ Bm.T   # (c, 2)
            prop = mu_j[:, None, :] + _nl.sample_gaussian(
                np.zeros(2), Cj, int(c) * proposals, rng, df=4).reshape(c, proposals, 2)
            X = poses[:, pi]                                       # (c, R, 3)
            dxy = prop[:, :, None, :] - X[:, None, :, :2]          # (c, K, R, 2)
            pred = np.arctan2(dxy[..., 1], dxy[..., 0]) - X[:, None, :, 2]
            r = wrap_angle(wk["ray_bearing"][m] - pred) / wk["ray_sigma"][m]
            # a point behind a camera has a residual near pi / sigma: ruled out by the likelihood
            loglik = -_huber(r, wk["robust"]).sum(-1)
            logq = _t_logpdf(prop, mu_j[:, None, :], Cj, 4)
            lw = loglik - logq
            lw -= lw.max(axis=1, keepdims=True)
            w = np.exp(lw)
            w /= w.sum(axis=1, keepdims=True)
            u = rng.random((c, 1))
            pick = np.minimum((np.cumsum(w, axis=1) < u).sum(axis=1), proposals - 1)
            pts[:, col] = prop[np.arange(c), pick]
        out[sl, ok] = pts
    return out


def reference_samples(posterior: JointPosterior, n: int = 1000, *, steps: int = 2000,
                      seed=0) -> np.ndarray:
    """Long-run sampling of the exact (robust, nonlinear) posterior of a solved problem, to check
    the approximations against: ``n`` random-walk Metropolis chains over every pose and
    landmark, started from the Laplace approximation, proposals ``N(0, 2.38^2 / d Sigma)``
    (Sigma the Laplace covariance of everything, poses turned to world coordinates), ``steps``
    steps each; returns the chains' last states' landmarks (n, L, 2) (NaN where unconstrained).
    Cost grows with the number of variables: meant for small problems (tests, development)."""
    n = positive_int("n", n)
    steps = positive_int("steps", steps)
    rng = as_rng(seed)
    L = len(posterior.landmark_ids)
    out = np.full((n, L, 2), np.nan)
    if posterior.method == "none":
        return out
    pr, fit = posterior._problem, posterior._fit
    C = _points_cov(posterior.info["marginals"], pr, np.arange(pr.n_points),
                    np.arange(pr.n_poses))
    J = np.eye(C.shape[0])
    for i, th in enumerate(fit.poses[:, 2]):
        a = 2 * pr.n_points + 3 * i
        J[a:a + 2, a:a + 2] = [[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]]
    C = J @ C @ J.T
    x0 = np.concatenate([fit.points.ravel(), fit.poses.ravel()])
    dim = x0.size
    cut = 2 * pr.n_points

    def logp(x):
        return -_nl.robust_cost(pr, x[:, cut:].reshape(len(x), -1, 3),
                                x[:, :cut].reshape(len(x), -1, 2))

    x = _nl.sample_gaussian(x0, C, n, rng)
    lp = logp(x)
    F = _nl.gaussian_factor(C) * (2.38 / np.sqrt(dim))
    for _ in range(steps):
        y = x + rng.standard_normal((n, dim)) @ F.T
        ly = logp(y)
        acc = np.log(rng.random(n)) < ly - lp
        x[acc], lp[acc] = y[acc], ly[acc]
    out[:, posterior.constrained] = x[:, :cut].reshape(n, -1, 2)
    return out


def _t_logpdf(x, mu, C, df):
    """Log density (up to a constant) of a 2-D Student t with scale ``C``."""
    Ci = np.linalg.inv(C)
    d = x - mu
    q = np.einsum("...i,ij,...j->...", d, Ci, d)
    return -0.5 * (df + 2) * np.log1p(q / df)

