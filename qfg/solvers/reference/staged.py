"""Reference solver: the exact posterior P(S^{AB:C} | H) and P(S^{AB:X}_i | H) under a given prior,
by adaptive importance sampling, with its Monte Carlo error estimated and reported.

Two samplers of the same target (option ``sampler``): the staged sampler of this module
(described below; its ESS collapses from about 8-10 views) and the conditional sampler of
:mod:`.conditional` (C from a fitted 2-D mixture, the trajectory given C by a particle filter
twisted by its Laplace approximation; time linear in the views). ``"auto"`` (default) takes the
staged one up to :data:`AUTO_STAGED_VIEWS` views and the conditional one beyond
(docs/priors.md).

Model (AB frame; the same as the other solvers, ``docs/priors.md``): configuration
``theta = (C, X_1, alpha_1, ..., X_n, alpha_n)``, prior ``prior(C, X_1..X_n) (2 pi)^-n`` (headings
uniform), bearings ``phi_{j,L} ~ WN(f(L, X_j, alpha_j), sigma_v^2)`` for L in {A, B, C} and
headings ``psi_j ~ WN(g(X_j, alpha_j, X_{j+1}), sigma_w^2)`` (WN: the wrapped normal, which for
sigma below ~20 deg is the normal of the wrapped residual).
With the odometry's distances ``d`` the target also carries the SIS solvers' factor on each
ratio of consecutive step lengths, ``N(log(s_j / s_(j-1)) - log(d_j / d_(j-1)); sigma_d)``
(staged sampler only).

Sampling variables ``u`` (a bijection with theta wherever the target is positive):

* the true bearings of A and B in every view, ``phi~ = phi + sigma_v eps`` (eps standard
  normal: this absorbs their likelihood exactly) and, between views, the true heading
  ``psi~ = psi + sigma_w eps``;
* view 1 (every view without an incoming heading): the angle at A along the locus arc of
  ``gamma = phi~_B - phi~_A``, through the arc parameter w in (0, 1) (``common.arcs.arc_parameter``);
  ``dX dalpha = |x| / sin^2(gamma) dphi~_A dphi~_B da``;
* later views: the point where the motion ray from X_{j-1} at ``alpha_{j-1} + psi~`` meets the
  locus arc, root r_j among the valid intersections; ``dX = t / |grad Gamma . u| dpsi~ dgamma``;
* C given the cameras: a mixture of a multivariate t about the triangulated point (Laplace
  covariance of the C-bearing likelihood) and, defensively, a heavy-tailed draw along one view's
  line of sight (``dC = t dt dbeta``).

Round 1 draws w uniformly and eps from N(0, 1) (likelihood-absorbing, "sequential" proposal).
Later rounds draw from ``lam * sequential + (1 - lam) * sum_k pi_k t_k(u)``, t-distributions in
``(logit w, eps)`` fitted to the previous rounds' weighted draws, one per cluster (root pattern,
separated values of w); the defensive share keeps every weight at most 1/lam times the
sequential weight. A cluster with too few effective draws for its dimension gets a Laplace
component instead (Newton on the target with C integrated out by Laplace), split in two where
the curvature at its mean shows two modes. Views are added in stages (the first three, then one
at a time); each stage is a complete importance sampler whose fitted proposal carries over.

The answer combines the final stage's rounds weighted by their ESS. Its error per state is the
delta-method standard deviation of the self-normalized estimator,
``sqrt(sum_i wbar_i^2 (1[s_i = s] - P_s)^2)``, floored at the binomial error of ESS draws.
Answers with ESS < ``min_ess`` are flagged: their error estimate is not reliable. Measured ESS,
time and calibration: ``docs/priors.md``.
"""

from __future__ import annotations

import numpy as np

from ... import partitions as _partitions
from ... import priors as _priors
from ..._validate import as_rng, non_negative, positive_int
from ...geometry import (
    heading_on_locus,
    locus_circle,
    locus_point,
    ray_circle_intersection,
    triangulate_lsq,
    wrap_angle,
)
from ..common.arcs import arc_parameter, log_ray_jacobian
from ..common.input import DISTANCE_RATIO_FLOOR, check_bearings, check_distances, check_headings
from ..common.likelihood import logsumexp
from ..common.odometry import log_distance_factor
from .conditional import RB_DEFAULTS as _RB_DEFAULTS
from .weights import (  # noqa: F401  (_log_wn: part of this module's interface)
    _log_wn,
    _summaries,
    final_answer,
)

__all__ = ["solve_reference", "REFERENCE_DEFAULTS"]

#: Options of :func:`solve_reference` (angles in radians). Chosen on development seeds
#: (benchmarks/bench_reference.py): ESS per triplet in docs/priors.md.
REFERENCE_DEFAULTS = {
    "n_samples": 10_000,          # draws per round
    "rounds": 3,                  # rounds of the first stage (1 = sequential proposal only)
    "first_stage": 3,             # views in the first stage
    "stage_rounds": 1,            # least rounds of every later stage (one view added per stage)
    "max_rounds": 5,              # most rounds of a stage
    "ess_target": 0.1,            # a stage ends once ESS >= ess_target * n_samples
    "grow": 4,                    # after a round with ESS < 1% of its draws, double the draws
                                  # (at most grow x n_samples)
    "defensive": 0.2,             # share of the sequential proposal in adapted rounds
    "c_defensive": 0.1,           # share of the line-of-sight draw for C
    "max_components": 8,          # t components of the adapted proposal
    "t_dof": 10.0,                # degrees of freedom of the t components
    "inflate": 1.1,               # scale factor on the fitted standard deviations
    "bearing_floor": np.deg2rad(0.05),   # sigmas used are max(sigma, floor): zero noise works
    "heading_floor": np.deg2rad(0.05),
    "min_ess": 50.0,              # below this the answer is flagged
    "laplace": True,              # refine poorly sampled components by Newton (Laplace; the
                                  # four heaviest clusters, split where the curvature says two modes)
    # the sampler: "conditional" (C drawn from a fitted 2-D mixture, the trajectory given C by a
    # particle filter twisted by its Laplace approximation: .conditional, cost linear in the
    # views), "staged" (the adaptive importance sampler above, views added in stages) or "auto"
    # (staged up to AUTO_STAGED_VIEWS views, conditional beyond: docs/priors.md); the options
    # above this line are the staged sampler's, those below the conditional sampler's
    "sampler": "auto",
    **{k: v for k, v in _RB_DEFAULTS.items()},
}

_LOG2PI = np.log(2 * np.pi)
_LOG_FMAX = np.log(np.finfo(float).max)

#: ``sampler="auto"`` uses the staged sampler up to this many (distinct) views and the
#: conditional one beyond (development seeds, docs/priors.md: at 3-5 views the staged sampler
#: reaches a larger ESS in less time; from 8 views on its ESS collapses while the conditional
#: sampler's cost grows linearly).
AUTO_STAGED_VIEWS = 5

#: Largest noise sigma used (radians); the wrapped normal is uniform beyond it.
SIGMA_CAP = 10.0

#: Scale factor on the Laplace standard deviations of C's proposal (2-D: inflating is cheap).
C_INFLATE = 1.3


# ---------------------------------------------------------------------------------------------
# densities


def _log_std_normal(e):
    return -0.5 * e * e - 0.5 * _LOG2PI


def _log_t(x, mean, chol, dof):
    """Log density of the multivariate t (location mean, scale L L^T, dof) at x (N, d)."""
    d = mean.shape[-1]
    z = np.linalg.solve(chol, (x - mean).T).T if d else np.zeros((x.shape[0], 0))
    q = np.sum(z * z, axis=-1)
    from math import lgamma

    c = (lgamma((dof + d) / 2) - lgamma(dof / 2) - 0.5 * d * np.log(dof * np.pi)
         - np.sum(np.log(np.abs(np.diag(chol)))))
    return c - 0.5 * (dof + d) * np.log1p(q / dof)


def _draw_t(rng, n, mean, chol, dof):
    d = mean.shape[-1]
    z = rng.standard_normal((n, d))
    g = rng.chisquare(dof, size=n) / dof
    return mean + (z @ chol.T) / np.sqrt(g)[:, None]


# ---------------------------------------------------------------------------------------------
# the model's layout


class Layout:
    """The sampling variables of the first ``n`` views: one block of 3 per view, ``[logit w_j,
    eps_A, eps_B]`` for an anchor view (drawn on its arc: view 1, or every view without motion)
    and ``[eps_psi_{j-1}, eps_A, eps_B]`` for a view reached along the motion ray."""

    def __init__(self, bearings, headings, sv, sw, distances=None, sd=0.0):
        self.phi = bearings                      # (n, 3)
        self.psi = headings                      # (n - 1,) or None
        self.dist = distances                    # (n - 1,) odometry's distances, or None
        self.sd = sd                             # width of their ratio factor (floored)
        self.n = bearings.shape[0]
        self.sv, self.sw = sv, sw
        self.anchor = np.ones(self.n, bool) if headings is None else np.r_[True, np.zeros(
            self.n - 1, bool)]
        self.n_psi = 0 if headings is None else self.n - 1
        self.dim = 3 * self.n

    def first(self, k):
        return Layout(self.phi[:k], None if self.psi is None else self.psi[:k - 1],
                       self.sv, self.sw, None if self.dist is None else self.dist[:k - 1],
                       self.sd)

    def log_distances(self, X) -> np.ndarray:
        """(N,) the odometry's step-length-ratio factors of camera positions X (N, n, 2)
        (:func:`.odometry.log_distance_factor`; 0 without distances)."""
        if self.dist is None or self.n < 3:
            return np.zeros(X.shape[0])
        d = np.diff(X, axis=1)
        step = np.hypot(d[..., 0], d[..., 1])
        return np.sum(log_distance_factor(step[:, 1:], step[:, :-1], self.dist[1:],
                                          self.dist[:-1], self.sd), axis=1)


def _construct(L, v, r=None, u=None):
    """Cameras from sampling variables. v (N, 3n) continuous; r (N, n) root indices, or u (N, n)
    uniforms that pick a root uniformly among the valid ones (the sequential proposal: the count
    at view j depends on the camera at j - 1) where r is -1 or None. Returns X (N, n, 2),
    alpha (N, n), logjac (N,), lseq (N, n) the sequential proposal's log density per view block
    (root choice included), valid (N,), r (N, n)."""
    N = v.shape[0]
    # r = -1: pick the root with u (uniformly among the valid ones)
    r = np.full((N, L.n), -1, dtype=np.int64) if r is None else np.array(r, dtype=np.int64)
    first, eA, eB = v[:, 0::3], v[:, 1::3], v[:, 2::3]
    pa = L.phi[None, :, 0] + L.sv * eA
    pb = L.phi[None, :, 1] + L.sv * eB
    X = np.zeros((N, L.n, 2))
    alpha = np.zeros((N, L.n))
    logjac = np.zeros(N)
    lseq = _log_std_normal(eA) + _log_std_normal(eB)
    valid = np.ones(N, bool)
    for j in range(L.n):
        gamma = wrap_angle(pb[:, j] - pa[:, j])
        s2 = np.sin(gamma) ** 2
        if L.anchor[j]:
            lg = first[:, j]
            # exp(-lg) overflows for lg < -log(max float) = -709.78, where w = 1/(1 + e^-lg) is
            # below 6e-309: 0 there, as 1/(1 + inf) gave, without the overflow
            big = lg < -_LOG_FMAX
            wj = np.where(big, 0.0, 1.0 / (1.0 + np.exp(-np.where(big, 0.0, lg))))
            # uniform w in logit space: dw = w (1 - w) dlogit (in the target and the proposal)
            lwj = -np.logaddexp(0.0, -lg) - np.logaddexp(0.0, lg)
            a, log_dadw = arc_parameter(gamma, wj)
            Xj = locus_point(gamma, a)
            ax = np.abs(Xj[:, 0])
            ok = (s2 > 1e-300) & (ax > 0) & np.isfinite(log_dadw)
            with np.errstate(divide="ignore"):
                lj = (np.log(np.where(ok, ax, 1.0)) - np.log(np.where(ok, s2, 1.0))
                      + np.where(ok, log_dadw, 0.0)) + lwj
            lseq[:, j] += lwj
            r[:, j] = 0
        else:
            origin = X[:, j - 1]
            theta = alpha[:, j - 1] + L.psi[j - 1] + L.sw * first[:, j]
            circ = locus_circle(pa[:, j], pb[:, j])
            rad = np.where(circ.degenerate, np.inf, circ.radius)
            pts, vr = ray_circle_intersection(origin, theta, circ.center, rad, circ.side)
            nr = vr.sum(axis=-1)
            pick = r[:, j] < 0
            if np.any(pick):
                r[pick, j] = np.minimum((u[pick, j] * nr[pick]).astype(np.int64),
                                        np.maximum(nr[pick] - 1, 0))
            # r indexes the valid roots in order of distance along the ray
            idx = np.where(r[:, j] == 0, np.where(vr[:, 0], 0, 1), 1)
            ok = (r[:, j] < nr) & ~circ.degenerate
            Xj = np.take_along_axis(pts, idx[:, None, None], axis=1)[:, 0]
            lj = log_ray_jacobian(Xj, origin, theta)
            ok &= np.isfinite(lj)
            lj = np.where(ok, lj, 0.0)
            lseq[:, j] += _log_std_normal(first[:, j]) - np.log(np.maximum(nr, 1))
        X[:, j] = Xj
        alpha[:, j] = heading_on_locus(Xj, pa[:, j])
        logjac += lj
        valid &= ok
    return X, alpha, logjac, lseq, valid, r


def _draw_seq(L, rng, N, d0=0):
    """Sequential-proposal values of the dims from d0 on: v (N, 3n - d0), root uniforms."""
    v = rng.standard_normal((N, L.dim - d0))
    for j in range(d0 // 3, L.n):
        if L.anchor[j]:
            w = rng.random(N) if j or N < 2 else (rng.permutation(N) + rng.random(N)) / N
            w = np.clip(w, 1e-12, 1 - 1e-12)
            v[:, 3 * j - d0] = np.log(w) - np.log1p(-w)
    return v, rng.random((N, L.n))


# ---------------------------------------------------------------------------------------------
# C given the cameras


def _c_laplace(L, X, alpha):
    """Laplace approximation of the C-bearing likelihood given cameras (N, n >= 2): centre
    (least-squares intersection of the lines of sight, one Gauss-Newton step on the angular
    residuals), unscaled information ``H = sum_j g_j g_j^T`` (precision H / sigma_v^2) and
    whether it is usable (every direction pinned to within 1e3 |AB|)."""
    beta = alpha + L.phi[None, :, 2]
    c0, okt = triangulate_lsq(X, beta)
    d = c0[:, None, :] - X
    r2 = np.maximum(np.sum(d * d, -1), 1e-300)
    g = np.stack([-d[..., 1], d[..., 0]], -1) / r2[..., None]
    res = wrap_angle(beta - np.arctan2(d[..., 1], d[..., 0]))
    Hm = np.einsum("nji,njk->nik", g, g)
    det = Hm[:, 0, 0] * Hm[:, 1, 1] - Hm[:, 0, 1] ** 2
    tr = Hm[:, 0, 0] + Hm[:, 1, 1]
    lmin = 0.5 * (tr - np.sqrt(np.maximum(tr * tr - 4 * det, 0.0)))
    good = okt & (lmin > (L.sv / 1e3) ** 2) & np.isfinite(det) & (det > 0)
    sdet = np.where(good, det, 1.0)
    gr = np.einsum("nji,nj->ni", g, res)
    step = np.stack([Hm[:, 1, 1] * gr[:, 0] - Hm[:, 0, 1] * gr[:, 1],
                     -Hm[:, 0, 1] * gr[:, 0] + Hm[:, 0, 0] * gr[:, 1]], -1) / sdet[:, None]
    mu = c0 + np.where(good[:, None], step, 0.0)
    return mu, Hm, good


def _c_terms(L, X, alpha, rng, lam_ray):
    """Draw C given cameras; returns C (N, 2) and log [prod_j L_jC(C) / q_C(C | cameras)]."""
    N, n = alpha.shape
    sv = L.sv
    beta = alpha + L.phi[None, :, 2]                    # measured lines of sight (AB frame)
    tau = 0.5 + np.linalg.norm(X - np.array([0.0, 0.5]), axis=-1)     # (N, n)
    # defensive: along one view's line of sight, direction noise absorbed, Lomax distance
    jv = rng.integers(0, n, size=N)
    bj = np.take_along_axis(beta, jv[:, None], 1)[:, 0] + sv * rng.standard_normal(N)
    tj = np.take_along_axis(tau, jv[:, None], 1)[:, 0]
    q = rng.random(N)
    t = tj * q / (1.0 - q)
    Xj = np.take_along_axis(X, jv[:, None, None], 1)[:, 0]
    c_ray = Xj + t[:, None] * np.stack([np.cos(bj), np.sin(bj)], -1)
    use_lap = np.zeros(N, bool)
    c = c_ray
    if n >= 2:
        mu, Hm, good = _c_laplace(L, X, alpha)
        det = Hm[:, 0, 0] * Hm[:, 1, 1] - Hm[:, 0, 1] ** 2
        sdet = np.where(good, det, 1.0)
        Hinv = np.stack([np.stack([Hm[:, 1, 1], -Hm[:, 0, 1]], -1),
                         np.stack([-Hm[:, 0, 1], Hm[:, 0, 0]], -1)], -2) / sdet[:, None, None]
        cov = Hinv * (sv * C_INFLATE) ** 2
        # 2 x 2 Cholesky by hand: rows that are not numerically positive definite lose the
        # Laplace component
        l00 = np.sqrt(np.maximum(cov[:, 0, 0], 0.0))
        l10 = cov[:, 0, 1] / np.where(l00 > 0, l00, 1.0)
        d11 = cov[:, 1, 1] - l10 * l10
        good &= (l00 > 0) & (d11 > 1e-12 * np.maximum(cov[:, 1, 1], 1e-300)) & np.isfinite(d11)
        l11 = np.sqrt(np.where(good, d11, 1.0))
        chol = np.zeros((N, 2, 2))
        chol[:, 0, 0] = np.where(good, l00, 1.0)
        chol[:, 1, 0] = np.where(good, l10, 0.0)
        chol[:, 1, 1] = l11
        mu = np.where(good[:, None], mu, 0.0)
        dof = REFERENCE_DEFAULTS["t_dof"]
        z = rng.standard_normal((N, 2))
        gsc = np.sqrt(rng.chisquare(dof, size=N) / dof)
        c_lap = mu + np.einsum("nik,nk->ni", chol, z) / gsc[:, None]
        pick_lap = good & (rng.random(N) >= lam_ray)
        c = np.where(pick_lap[:, None], c_lap, c_ray)
        use_lap = good
    # mixture density at c
    dd = c[:, None, :] - X
    dist = np.maximum(np.linalg.norm(dd, axis=-1), 1e-300)
    ang = np.arctan2(dd[..., 1], dd[..., 0])
    lq_rays = (_log_wn(ang - beta, sv) + np.log(tau) - 2 * np.log(tau + dist) - np.log(dist))
    lq_ray = logsumexp(lq_rays, axis=-1) - np.log(n)
    if n >= 2:
        dz = c - mu
        z0 = dz[:, 0] / chol[:, 0, 0]
        z1 = (dz[:, 1] - chol[:, 1, 0] * z0) / chol[:, 1, 1]
        qf = z0 * z0 + z1 * z1
        from math import lgamma

        lq_lap = (lgamma((dof + 2) / 2) - lgamma(dof / 2) - np.log(dof * np.pi)
                  - np.log(np.abs(chol[:, 0, 0] * chol[:, 1, 1])) - 0.5 * (dof + 2) * np.log1p(
                      qf / dof))
        lq = np.where(use_lap, np.logaddexp(np.log(lam_ray) + lq_ray,
                                            np.log1p(-lam_ray) + lq_lap), lq_ray)
    else:
        lq = lq_ray
    lik = np.sum(_log_wn(L.phi[None, :, 2] - (ang - alpha), sv), axis=-1)
    return c, lik - lq


# ---------------------------------------------------------------------------------------------
# adapted proposal


class _Mixture:
    """Sequential proposal (share lam) plus t components. A component fits the first ``d`` dims
    (the blocks of the views seen when it was fitted) with a fixed root pattern there; later
    views' dims and roots are drawn by the sequential proposal."""

    def __init__(self, L, comps, lam, dof):
        self.L, self.comps, self.lam, self.dof = L, comps, lam, dof

    def draw(self, rng, N):
        L = self.L
        nseq = rng.binomial(N, self.lam) if self.comps else N
        v1, u1 = _draw_seq(L, rng, nseq)
        out = [(v1, None, u1)]
        if self.comps:
            pis = np.array([c[0] for c in self.comps])
            counts = rng.multinomial(N - nseq, pis / pis.sum())
            for (_, mean, chol, roots), k in zip(self.comps, counts, strict=True):
                if k:
                    d = mean.shape[0]
                    head = _draw_t(rng, k, mean, chol, self.dof)
                    tail, u = _draw_seq(L, rng, k, d)
                    rr = np.full((k, L.n), -1, dtype=np.int64)
                    rr[:, :roots.shape[0]] = roots
                    out.append((np.concatenate([head, tail], 1), rr, u))
        return out

    def log_density(self, v, r, lseq):
        ls = lseq.sum(axis=1)
        if not self.comps:
            return ls
        pis = np.array([c[0] for c in self.comps])
        pis = pis / pis.sum()
        cum = np.cumsum(lseq[:, ::-1], axis=1)[:, ::-1]   # cum[:, j] = sum of blocks j..n-1
        cum = np.concatenate([cum, np.zeros((cum.shape[0], 1))], axis=1)
        parts = [np.log(self.lam) + ls]
        for pi, (_, mean, chol, roots) in zip(pis, self.comps, strict=True):
            d, jf = mean.shape[0], roots.shape[0]
            same = np.all(r[:, :jf] == roots[None, :], axis=1)
            lt = np.where(same, _log_t(v[:, :d], mean, chol, self.dof), -np.inf) + cum[:, jf]
            parts.append(np.log1p(-self.lam) + np.log(pi) + lt)
        return logsumexp(np.stack(parts, -1), axis=-1)


def _fit(L, v, r, wn, max_components, inflate, refine=None):
    """t components fitted to a weighted sample: one per root pattern and separated w_1
    cluster (gaps wider than 0.5 in logit w_1)."""
    keep = wn > 1e-6 * wn.max()
    v, r, wn = v[keep], r[keep], wn[keep]
    groups: dict = {}
    for i, k in enumerate(map(tuple, r)):
        groups.setdefault(k, []).append(i)
    clusters = []
    for k, idx in groups.items():
        idx = np.asarray(idx)
        o = idx[np.argsort(v[idx, 0])]
        for p in np.split(o, np.flatnonzero(np.diff(v[o, 0]) > 0.5) + 1):
            clusters.append((wn[p].sum(), p, np.asarray(k)))
    clusters.sort(key=lambda c: -c[0])
    clusters = [c for c in clusters[:max_components] if c[0] > 1e-3]
    comps = []
    d = v.shape[1]
    is_w = np.zeros(d, bool)
    is_w[0::3] = L.anchor
    for mass, p, roots in clusters:
        ww = wn[p] / wn[p].sum()
        mean = ww @ v[p]
        dv = v[p] - mean
        S = (dv * ww[:, None]).T @ dv
        ess = 1.0 / np.sum(ww ** 2)
        # variances floored (eps: 1e-4 of the proposal's N(0, 1)); correlations shrunk towards 0
        # with weight 2 / (ess + 2), so that a cluster with few effective draws still gives a
        # usable covariance (more shrinkage would destroy the posterior's narrow directions)
        var = np.maximum(np.diag(S), np.where(is_w, 1e-10, 1e-4))
        sd = np.sqrt(var)
        sS = np.sqrt(np.maximum(np.diag(S), 1e-300))
        R = S / np.outer(sS, sS)
        R = (ess * R + 2.0 * np.eye(d)) / (ess + 2.0)
        np.fill_diagonal(R, 1.0)
        cov = R * np.outer(sd, sd)
        if refine is not None and ess < 20 * d and len(comps) < 4:
            # too few effective draws for a d-dimensional covariance: Laplace at the mode(s)
            parts = refine(mean, cov, roots, v[p], ww)
        else:
            parts = [(1.0, mean, cov)]
        for share, mu, cv in parts:
            cv = cv * inflate ** 2
            chol = np.linalg.cholesky(cv + 1e-12 * np.diag(np.diag(cv)))
            comps.append((mass * share, mu, chol, roots))
    return comps


# ---------------------------------------------------------------------------------------------
# one round


def _round(L, prior, part, rng, mix, N, lam_ray):
    parts = [_construct(L, vv, rr, uu) + (vv,) for vv, rr, uu in mix.draw(rng, N)]
    X, alpha, logjac, lseq, valid, r, v = (np.concatenate(z) for z in zip(*parts, strict=True))
    lq = mix.log_density(v, r, lseq)
    c, lc = _c_terms(L, X, alpha, rng, lam_ray)
    lw = np.full(N, -np.inf)
    ok = valid & np.isfinite(lc) & np.isfinite(lq)
    if np.any(ok):
        pts = np.concatenate([c[ok, None, :], X[ok]], axis=1)
        lp = prior.log_density(pts)
        vo = v[ok]
        # the likelihoods of the true bearings of A, B and of the true headings, in eps units
        lik = (np.sum(_log_std_normal(vo[:, 1::3]) + _log_std_normal(vo[:, 2::3]), axis=1)
               + np.sum(np.where(L.anchor[None, :], 0.0, _log_std_normal(vo[:, 0::3])), axis=1))
        lw[ok] = lp - L.n * _LOG2PI + logjac[ok] + lc[ok] + lik - lq[ok] \
            + L.log_distances(X[ok])
    lw = np.where(np.isnan(lw), -np.inf, lw)
    return v, r, X, c, lw


def _fit_pool(L, pool, opts, prior=None):
    if not pool:
        return []
    v = np.concatenate([p[0] for p in pool])
    r = np.concatenate([p[1] for p in pool])
    w = np.concatenate([p[2] for p in pool])
    refine = None
    if opts["laplace"] and L.n >= 2 and prior is not None:
        def refine(mean, cov, roots, vs, ws):
            return _laplace_split(L, prior, mean, cov, roots, vs, ws)
    return _fit(L, v, r, w / w.sum(), int(opts["max_components"]), float(opts["inflate"]),
                refine)


def _log_marginal(L, prior, v, r):
    """log of the target with C integrated out by Laplace, at camera variables v (N, 3n) with
    root pattern r (N, n): the objective whose mode and curvature refine a component."""
    X, alpha, logjac, _, valid, _ = _construct(L, v, r)
    mu, Hm, good = _c_laplace(L, X, alpha)
    d = mu[:, None, :] - X
    res = L.phi[None, :, 2] - (np.arctan2(d[..., 1], d[..., 0]) - alpha)
    det = Hm[:, 0, 0] * Hm[:, 1, 1] - Hm[:, 0, 1] ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        lc = (np.sum(_log_wn(res, L.sv), axis=1) + np.log(2 * np.pi * L.sv ** 2)
              - 0.5 * np.log(np.where(good, det, 1.0)))
    lik = (np.sum(_log_std_normal(v[:, 1::3]) + _log_std_normal(v[:, 2::3]), axis=1)
           + np.sum(np.where(L.anchor[None, :], 0.0, _log_std_normal(v[:, 0::3])), axis=1))
    out = np.full(v.shape[0], -np.inf)
    ok = valid & good & np.isfinite(lc)
    if np.any(ok):
        pts = np.concatenate([mu[ok, None, :], X[ok]], axis=1)
        out[ok] = prior.log_density(pts) - L.n * _LOG2PI + logjac[ok] + lc[ok] + lik[ok] \
            + L.log_distances(X[ok])
    return np.where(np.isnan(out), -np.inf, out)


def _laplace_split(L, prior, mean, cov, roots, vs, ws, depth=3):
    """Laplace components for a cluster of weighted draws ``vs`` (K, d), ``ws`` (K,) (sum 1):
    where the curvature at the cluster's mean points up along some direction, the cluster holds
    two modes: split its draws by the side of that direction and recurse (``depth`` times at
    most). Returns [(share, mean, cov)]."""
    res = _laplace(L, prior, mean, cov, roots)
    if res[0] != "split" or depth == 0 or vs.shape[0] < 4:
        return [(1.0, res[1], res[2])] if res[0] != "split" else [(1.0, mean, cov)]
    side = (vs - mean) @ res[1] > 0
    out = []
    for sel in (side, ~side):
        w = ws[sel]
        if w.sum() <= 1e-9 or sel.sum() < 2:
            continue
        wn = w / w.sum()
        m = wn @ vs[sel]
        dv = vs[sel] - m
        S = (dv * wn[:, None]).T @ dv
        # keep the parent's spread where the half has too few draws to say
        ess = 1.0 / np.sum(wn ** 2)
        C = (ess * S + 2.0 * cov) / (ess + 2.0)
        for sh, mu, cv in _laplace_split(L, prior, m, C, roots, vs[sel], wn, depth - 1):
            out.append((w.sum() * sh, mu, cv))
    tot = sum(o[0] for o in out)
    return [(o[0] / tot, o[1], o[2]) for o in out] if out else [(1.0, mean, cov)]


def _laplace(L, prior, mean, cov, roots, iters=4):
    """Newton ascent of :func:`_log_marginal` from ``mean`` (finite differences with steps of
    0.2 of the current standard deviations, line search), then the inverse of the negative
    Hessian as covariance: ("ok", mean, cov). ("split", direction, None) when the curvature at
    the start points up (the start lies between modes); ("keep", mean, cov) with the inputs if
    anything is not finite or not negative definite later."""
    d = mean.shape[0]
    rr = np.zeros((1, L.n), dtype=np.int64)
    rr[0, :roots.shape[0]] = roots
    iu, ju = np.triu_indices(d, k=1)
    x, C = mean.copy(), cov
    for it in range(iters + 1):
        h = 0.2 * np.sqrt(np.maximum(np.diag(C), 1e-12))
        E = np.diag(h)
        # centre, +-e_i, and the four corners (+-e_i +-e_j) for every pair i < j
        pts = [x[None, :], x + E, x - E,
               x + E[iu] + E[ju], x + E[iu] - E[ju], x - E[iu] + E[ju], x - E[iu] - E[ju]]
        F = _log_marginal(L, prior, np.concatenate(pts), np.repeat(rr, sum(len(p) for p in pts),
                                                                   axis=0))
        if not np.all(np.isfinite(F)):
            return "keep", mean, cov
        f0 = F[0]
        fp, fm = F[1:1 + d], F[1 + d:1 + 2 * d]
        k = 1 + 2 * d
        npair = iu.size
        fpp, fpm = F[k:k + npair], F[k + npair:k + 2 * npair]
        fmp, fmm = F[k + 2 * npair:k + 3 * npair], F[k + 3 * npair:]
        g = (fp - fm) / (2 * h)
        Hs = np.zeros((d, d))
        Hs[np.arange(d), np.arange(d)] = (fp - 2 * f0 + fm) / h ** 2
        off = (fpp - fpm - fmp + fmm) / (4 * h[iu] * h[ju])
        Hs[iu, ju] = off
        Hs[ju, iu] = off
        lam, V = np.linalg.eigh(-Hs)
        if not np.all(np.isfinite(lam)):
            return "keep", mean, cov
        if lam.min() <= 0:
            if it == 0:
                return "split", V[:, int(np.argmin(lam))], None
            return "keep", mean, cov
        C = (V / lam) @ V.T
        if it == iters:
            break
        step = C @ g
        ts = np.array([1.0, 0.5, 0.25, 0.0])
        cand = x[None, :] + ts[:, None] * step[None, :]
        Fc = _log_marginal(L, prior, cand, np.repeat(rr, ts.size, axis=0))
        x = cand[int(np.argmax(np.where(np.isfinite(Fc), Fc, -np.inf)))]
    return "ok", x, C


def _weights(lw):
    mx = np.max(lw) if lw.size else -np.inf
    if not np.isfinite(mx):
        return None
    w = np.exp(lw - mx)
    return w / w.sum()


def solve_reference(bearings, headings, sigma_bearing, sigma_heading, partition="edc",
                    prior="world", seed=0, distances=None, sigma_distance_ratio=None,
                    **options) -> dict:
    """Exact posterior of the states of C and of the cameras, up to a reported Monte Carlo error.

    Args:
        bearings: (n, 3) radians [phi_A, phi_B, phi_C] per view, n >= 1.
        headings: (n - 1,) radians (direction of travel relative to the heading), or None (no
            motion model: views independent given C).
        sigma_bearing, sigma_heading: noise standard deviations (radians, >= 0); the model uses
            ``max(sigma, floor)`` (``bearing_floor``, ``heading_floor``) so that 0 works.
        partition: partition name or object.
        prior: a :class:`qfg.priors.Prior` or a name for :func:`qfg.priors.get`.
        seed: an int (default 0), a SeedSequence, a numpy Generator, or None (fresh entropy).
        distances: (n - 1,) the odometry's travelled distance between consecutive views (any
            unit, >= 0; 0 = unknown), or None: each ratio of consecutive steps is a factor
            ``N(log(s_i / s_(i-1)) - log(d_i / d_(i-1)); sigma_distance_ratio)`` of the target
            (:func:`.odometry.log_distance_factor`, as in the SIS solvers). The staged sampler only;
            the conditional one refuses them.
        sigma_distance_ratio: the noise of that log ratio (>= 0, floored at
            :data:`.input.DISTANCE_RATIO_FLOOR`); required with distances.
        **options: see :data:`REFERENCE_DEFAULTS`.

    Returns a dict: ``landmark`` (m,), ``cameras`` (n, m), ``mc_error`` (m,) and
    ``cameras_mc_error`` (n, m) (standard deviations of the probabilities), ``ess`` (effective
    sample size of the final round), ``ess_rounds`` (per round), ``n_samples`` (draws in all
    rounds), ``log_evidence`` (log p(measurements), radians as the unit of every angle; None when
    nothing had weight), ``degenerate`` (bool), ``reason`` (str), ``pareto_k`` (Pareto k-hat of
    the final rounds' weights, :func:`qfg.solvers.common.diagnostics.pareto_k`) and ``sampler`` (the
    sampler used: ``options["sampler"]``, "auto" resolved by the number of views).

    >>> import numpy as np
    >>> from qfg.simulation import random_triplet_history
    >>> h = random_triplet_history(np.random.default_rng(1), 3, np.deg2rad(2), np.deg2rad(5))
    >>> out = solve_reference(h.bearings, h.headings, h.sigma_bearing, h.sigma_heading,
    ...                       seed=0, n_samples=4000)
    >>> bool(np.isclose(out["landmark"].sum(), 1.0)), out["landmark"].shape, out["ess"] > 30
    (True, (20,), True)
    """
    opts = dict(REFERENCE_DEFAULTS)
    unknown = sorted(set(options) - set(opts))
    if unknown:
        raise ValueError(f"{unknown[0]}: not an option of the reference solver; known: "
                         f"{', '.join(sorted(opts))}")
    opts.update(options)
    N = positive_int("n_samples", opts["n_samples"], minimum=16)
    rounds = positive_int("rounds", opts["rounds"])
    lam = float(opts["defensive"])
    lam_ray = float(opts["c_defensive"])
    if not (0 < lam <= 1):
        raise ValueError(f"defensive: expected a share in (0, 1], got {lam}")
    if not (0 < lam_ray <= 1):
        raise ValueError(f"c_defensive: expected a share in (0, 1], got {lam_ray}")
    b = check_bearings(bearings)
    h = check_headings(headings, b.shape[0])
    sv = max(non_negative("sigma_bearing", sigma_bearing),
              non_negative("bearing_floor", opts["bearing_floor"]))
    sw = max(non_negative("sigma_heading", sigma_heading),
             non_negative("heading_floor", opts["heading_floor"]))
    # a wrapped normal with sigma >= 10 rad is uniform to within 2 exp(-50): cap there so that
    # absurd sigmas (1e285) mean "uninformative" instead of overflowing
    sv, sw = min(sv, SIGMA_CAP), min(sw, SIGMA_CAP)
    if sv == 0:
        raise ValueError("bearing_floor: must be > 0 when sigma_bearing is 0")
    if h is not None and h.size and sw == 0:
        raise ValueError("heading_floor: must be > 0 when sigma_heading is 0")
    part = _partitions.get(partition)
    pr = _priors.get(prior)
    rng = as_rng(seed)
    dist, sd = None, 0.0
    if distances is not None:
        dist = check_distances(distances, b.shape[0])
        if sigma_distance_ratio is None:
            raise ValueError("sigma_distance_ratio: required when distances are given")
        sd = max(non_negative("sigma_distance_ratio", sigma_distance_ratio),
                 DISTANCE_RATIO_FLOOR)
        if h is None or not h.size or not np.any(dist > 0):
            dist = None
    L = Layout(b, h if (h is not None and h.size) else None, sv, sw, dist, sd)
    if opts["sampler"] not in ("auto", "conditional", "staged"):
        raise ValueError(f"sampler: expected 'auto', 'conditional' or 'staged', got "
                         f"{opts['sampler']!r}")
    sampler = opts["sampler"]
    if sampler == "auto":
        sampler = "staged" if L.n <= AUTO_STAGED_VIEWS else "conditional"

    if sampler == "conditional" and L.dist is not None:
        raise ValueError(f"distances: the conditional sampler (sampler='conditional', or "
                         f"'auto' beyond {AUTO_STAGED_VIEWS} views) takes no odometry distances; "
                         f"use sampler='staged' or leave the distances out")

    def run(prior):
        if sampler == "conditional":
            from .conditional import solve_rb

            return solve_rb(L, prior, part, rng, opts)
        return _solve(L, prior, part, rng, opts, N, rounds, lam, lam_ray)

    out = run(pr)
    out["sampler"] = sampler
    if out["log_evidence"] is None and isinstance(pr, _priors.WorldBoxPrior) and pr.d_min > 0:
        # e.g. every view at one pose with zero noise: cameras closer than d_min are impossible
        # under the prior, so nothing has weight; answer under the same box without d_min
        # (a negative scale_power needs some d_min: keep a vanishing one)
        free = pr.replace(d_min=0.0 if pr.scale_power >= 0 else 1e-9 * pr.d_min)
        out = run(free)
        out["sampler"] = sampler
        out["n_samples"] *= 2
        out["degenerate"] = True
        out["reason"] = "; ".join(x for x in (
            "no configuration keeps d_min between the objects: answered with d_min = 0",
            out["reason"]) if x)
    return out


def _solve(L, pr, part, rng, opts, N, rounds, lam, lam_ray):
    # views are added in stages (the first stage has min(n, first_stage) views): every stage is
    # a complete importance sampler of the posterior given its views, whose fitted proposal
    # carries over to the next stage, where the new view's variables are drawn by the
    # likelihood-absorbing sequential proposal and then refitted
    dof = float(opts["t_dof"])
    n = L.n
    j0 = min(n, positive_int("first_stage", opts["first_stage"]))
    plan = [(j0, rounds)] + [(j, positive_int("stage_rounds", opts["stage_rounds"]))
                             for j in range(j0 + 1, n + 1)]
    # a stage ends after its minimum number of rounds once the ESS reaches ess_target * N, or
    # after max_rounds
    target = float(opts["ess_target"]) * N
    max_rounds = positive_int("max_rounds", opts["max_rounds"])
    # Every round of the final stage is an importance sampler of the full posterior: the answer
    # combines their estimates with weights proportional to their ESS (the variances combine
    # accordingly). Fits use the pooled rounds of the current stage, each round's normalized
    # weights scaled by its ESS, so that a poor round does not starve the next fit.
    comps, ess_rounds, finals, total, final_lws = [], [], [], 0, []
    for si, (j, nr) in enumerate(plan):
        Lj = L if j == n else L.first(j)
        final = si == len(plan) - 1
        pool = []
        Nr = N
        for k in range(max(nr, max_rounds)):
            v, r, X, c, lw = _round(Lj, pr, part, rng, _Mixture(Lj, comps, lam, dof), Nr, lam_ray)
            total += Nr
            wn = _weights(lw)
            ess = 0.0 if wn is None else 1.0 / np.sum(wn ** 2)
            if ess < 0.01 * Nr:
                # a poor round: more draws for the next fit (up to grow x n_samples)
                Nr = min(2 * Nr, int(opts["grow"]) * N)
            ess_rounds.append(float(ess))
            if wn is not None:
                pool.append((v, r, wn * ess))
                if final:
                    finals.append(_summaries(part, X, c, lw) + (X, c))
                    final_lws.append(lw)
            if k + 1 >= max(nr, max_rounds) or (k + 1 >= nr and ess >= target):
                if not final:
                    comps = _fit_pool(Lj, pool[-3:], opts, pr)
                break
            comps = _fit_pool(Lj, pool[-3:], opts, pr)
    # the weights are densities in eps units, where the likelihood of the true bearings (1/sv
    # per factor) and the change of variables phi~ = phi + sv eps (sv per factor) cancel: their
    # mean is p(measurements) itself (the conditional sampler's estimate of the same quantity
    # agrees: tests/test_reference_conditional.py)
    return final_answer(L, part, finals, N, opts["min_ess"], final_lws, ess_rounds, total)
