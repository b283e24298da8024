"""The reference's conditional sampler (``sampler="conditional"``): the exact posterior by
importance sampling of ``(C, trajectory)``, Rao-Blackwellised around C, at a cost linear in the
number of views.

Model (the same as :mod:`.staged`, AB frame): configuration ``(C, X_1, alpha_1, ..,
X_n, alpha_n)``, prior ``prior(C, X_1..X_n) (2 pi)^-n`` (headings uniform), bearings
``phi_{j,P} ~ WN(atan2(P - X_j) - alpha_j, sigma_v^2)`` for P in {A, B, C}, headings
``psi_j ~ WN(atan2(X_{j+1} - X_j) - alpha_j, sigma_w^2)``.

Given C every pose is fixed by its three bearings (a resection: the second intersection of the
locus circles of AB and AC, both through A, in closed form by inversion about A), and the
headings chain consecutive poses. So, for a draw of C:

* the trajectory's conditional ``p(X, alpha | C, z)`` is approximated by a Gaussian about its
  mode in *arc coordinates* ``t_j = (a_j, g_j, alpha_j)`` (the angle at A along the view's AB
  locus arc, the angle AB subtends, the heading: the A and B bearings are linear in them, so a
  camera that its own bearings leave spread along its locus circle, near the circle through
  A, B and C, is a straight line there, not a banana; views with a camera near line AB keep
  (x, y)). The mode is found by Levenberg-Marquardt from the resection (or, where a heading
  leads in, the heading ray's points on the locus circle); the information ``J^T J`` is
  block-tridiagonal (3 x 3 blocks: the bearings of a view on the diagonal, each heading coupling
  views j and j + 1) and factored by a block Cholesky (a forward filter pass): all in
  :mod:`.trajectory`;
* trajectories are drawn by a particle filter backwards along the views, K particles per C,
  each step drawing ``t_j`` from the Gaussian's conditional given ``t_{j+1}`` (backward
  sampling) and weighting by the exact factors of view j and its outgoing heading, twisted by
  the Gaussian message of the earlier views; resampling after every view keeps the error of the
  Gaussian from compounding over views. The targets carry the prior of the points seen so far
  (:func:`intermediate_prior`), the last one the exact prior of the whole configuration, so the
  world box's coupling of every point (its scale) is corrected view by view, with resampling;
  the filter's evidence estimate Z (unbiased) over q(C) is an exact importance weight;
* C is drawn from a 2-D mixture of t components fitted by weighted EM to draws weighted by the
  Laplace marginal ``p(C, X*, alpha*, z) (2 pi)^(3n/2) det(J^T J)^(-1/2)`` (arc Jacobians
  included), reached from the heavy-tailed product prior by adaptive tempering over stages of
  3, 6, 12, .. views (the tempered target ``q_ref^(1 - b) p^b``, b raised while 30% of the draws
  where p > 0 stay effective), with defensive shares of a widened mixture and of the product prior
  (support everywhere);
* draws outside the arc domain or with a heading outside ``(alpha*_j - pi, alpha*_j + pi]``
  get weight 0 (a defective proposal: still exact, the window covers the circle once).

Whatever the quality of the approximations, this is an importance sampler of the exact
posterior; their quality shows in the ESS and the Pareto k. Rounds of final draws are added
until the ESS reaches ``ess_goal`` (at most ``final_rounds``) and combined by ESS
(:func:`.weights._combine`).
"""

from __future__ import annotations

from math import lgamma

import numpy as np

from ... import priors as _priors
from ..common.likelihood import logsumexp
from .trajectory import (
    _LOG2PI,
    _blocks,
    _bwd3,
    _pose,
    _quiet,
    fit_trajectories,
    laplace_marginal,
)
from .weights import _log_wn, _summaries, final_answer

__all__ = ["RB_DEFAULTS", "solve_rb"]

#: Options of the conditional-Laplace sampler (keys of the reference solver's options).
RB_DEFAULTS = {
    "rb_samples": 1000,        # C draws per final round (and per tempering round)
    "particles": 16,           # trajectories per C draw (the particle filter given C)
    "final_rounds": 6,         # most final rounds (stops once the ESS reaches ess_goal)
    "ess_goal": 500.0,         # total ESS wanted from the final rounds
    "tempering_rounds": 12,    # most rounds of the adaptive tempering of C's proposal
    "tempering_samples": 500,  # C draws per tempering round
    "tempering_ess": 0.3,      # share of effective draws kept when the temperature is raised
    "gn_iters": 40,            # most Levenberg-Marquardt iterations of the conditional mode
    "components": 6,           # components of C's mixture
    "refit": False,            # refit half of C's mixture to each final round's weighted draws
}

#: Degrees of freedom and scale inflation of C's t components; defensive shares of the widened
#: (x WIDE in standard deviation) mixture and of the product prior.
C_DOF, C_INFLATE, WIDE, P_WIDE, P_PRIOR = 5.0, 1.3, 4.0, 0.05, 0.02


# ---------------------------------------------------------------------------------------------
# C's proposal: a 2-D t mixture


class _CMix:
    """Mixture over C: shares ``pis`` of t components (means (K, 2), scale Cholesky factors
    (K, 2, 2), dof), optionally plus defensive shares of the same components widened by WIDE and
    of the product prior."""

    def __init__(self, pis, means, chols, defensive=True):
        self.pis = np.asarray(pis, float) / np.sum(pis)
        self.means, self.chols = means, chols
        self.defensive = defensive

    def _parts(self):
        if not self.defensive:
            return [(1.0, 1.0)]
        return [(1.0 - P_WIDE - P_PRIOR, 1.0), (P_WIDE, WIDE)]

    def draw(self, rng, N):
        shares = [s for s, _ in self._parts()] + ([P_PRIOR] if self.defensive else [])
        counts = rng.multinomial(N, np.array(shares) / np.sum(shares))
        out = []
        for (_, scale), k in zip(self._parts(), counts[:len(self._parts())], strict=True):
            if not k:
                continue
            comp = rng.choice(self.pis.size, size=k, p=self.pis)
            z = rng.standard_normal((k, 2))
            gsc = np.sqrt(rng.chisquare(C_DOF, size=k) / C_DOF)
            out.append(self.means[comp] + scale * np.einsum("kij,kj->ki", self.chols[comp], z)
                       / gsc[:, None])
        if self.defensive and counts[-1]:
            out.append(_PRODUCT.sample(rng, 0, int(counts[-1]))[:, 0])
        x = np.concatenate(out) if out else np.zeros((0, 2))
        return x[rng.permutation(x.shape[0])]

    def log_density(self, x):
        terms = []
        for s, scale in self._parts():
            lt = _log_t2(x, self.means, self.chols * scale, C_DOF) + np.log(self.pis)[None, :]
            terms.append(np.log(s) + logsumexp(lt, axis=1))
        if self.defensive:
            terms.append(np.log(P_PRIOR) + _PRODUCT.log_density(x[:, None, :]))
        return logsumexp(np.stack(terms, -1), axis=-1)


_PRODUCT = _priors.ProductPrior()


class _ProductDensity:
    """The product prior's one-point density as a C density (log_density of (N, 2))."""

    @staticmethod
    def log_density(x):
        return _PRODUCT.log_density(x[:, None, :])


def _log_t2(x, means, chols, dof):
    """Log densities (N, K) of 2-D t components at x (N, 2)."""
    d = x[:, None, :] - means[None]
    z0 = d[..., 0] / chols[None, :, 0, 0]
    z1 = (d[..., 1] - chols[None, :, 1, 0] * z0) / chols[None, :, 1, 1]
    q = z0 * z0 + z1 * z1
    c = lgamma((dof + 2) / 2) - lgamma(dof / 2) - np.log(dof * np.pi)
    return (c - np.log(np.abs(chols[None, :, 0, 0] * chols[None, :, 1, 1]))
            - 0.5 * (dof + 2) * np.log1p(q / dof))


def _fit_mixture(x, w, K, rng, iters=25):
    """Weighted EM for a K-component Gaussian mixture in 2-D: (pis, means, chols) with the
    covariances inflated by C_INFLATE^2 (the proposal's scale)."""
    keep = w > 1e-10 * w.max()
    x, w = x[keep], w[keep] / w[keep].sum()
    ess = 1.0 / np.sum(w * w)
    K = int(max(1, min(K, ess // 10)))
    mean_all = w @ x
    dx = x - mean_all
    cov_all = (dx * w[:, None]).T @ dx
    floor = 1e-10 * max(np.trace(cov_all), 1e-20) * np.eye(2)
    # start: K draws by weight (systematic), each with the overall covariance
    u = (rng.random() + np.arange(K)) / K
    idx = np.minimum(np.searchsorted(np.cumsum(w), u), x.shape[0] - 1)
    mus = x[idx].copy()
    covs = np.repeat((cov_all / max(K, 1) + floor)[None], K, axis=0)
    pis = np.full(K, 1.0 / K)
    for _ in range(iters):
        ch = np.linalg.cholesky(covs)
        d = x[:, None, :] - mus[None]
        z0 = d[..., 0] / ch[None, :, 0, 0]
        z1 = (d[..., 1] - ch[None, :, 1, 0] * z0) / ch[None, :, 1, 1]
        lg = -0.5 * (z0 * z0 + z1 * z1) - np.log(ch[None, :, 0, 0] * ch[None, :, 1, 1])
        lg = lg + np.log(np.maximum(pis, 1e-300))[None]
        resp = np.exp(lg - logsumexp(lg, axis=1)[:, None])
        rw = resp * w[:, None]
        nk = rw.sum(axis=0)
        live = nk > 1e-6
        if not np.all(live):
            mus, covs, pis, rw, nk = mus[live], covs[live], pis[live], rw[:, live], nk[live]
        pis = nk / nk.sum()
        mus = (rw.T @ x) / nk[:, None]
        d = x[:, None, :] - mus[None]
        covs = np.einsum("nk,nki,nkj->kij", rw, d, d) / nk[:, None, None] + floor
    chols = np.linalg.cholesky(covs * C_INFLATE ** 2)
    return pis, mus, chols


def effective_sample_size(lw):
    lw = lw[np.isfinite(lw)]
    if lw.size == 0:
        return 0.0
    w = np.exp(lw - lw.max())
    return float(w.sum() ** 2 / np.sum(w * w))


def _stages(n):
    """Views of the successive targets of C's adaptation: 3 (or n), then doubling up to n."""
    out = [min(n, 3)]
    while out[-1] < n:
        out.append(min(n, 2 * out[-1]))
    return out


@_quiet
def adapt_c_proposal(L, prior, rng, opts):
    """C's proposal: adaptive tempering from the product prior to the Laplace marginal of the
    first 3 views, then from each stage's marginal to that of twice as many views, up to n
    (each step a geometric bridge ``q_ref^(1 - b) p_k^b`` from the proposal the previous stage
    ended with, or the product prior, to the Laplace marginal p_k of k views, b raised while
    a share ``tempering_ess`` of the draws where p_k > 0 stays effective, the t mixture
    refitted to the weighted draws after every round).
    Returns the mixture and the number of C draws spent."""
    M = int(opts["tempering_samples"])
    keep = float(opts["tempering_ess"])
    K = int(opts["components"])
    iters = int(opts["gn_iters"])
    max_rounds = int(opts["tempering_rounds"])
    spent, rounds = 0, 0
    mix = None
    ref = _ProductDensity()
    for k in _stages(L.n):
        Lk = L if k == L.n else L.first(k)
        if mix is not None:
            ref = mix           # the bridge starts from the proposal the last stage ended with
        beta = 0.0
        while rounds < max_rounds:
            rounds += 1
            if mix is None:
                C = _PRODUCT.sample(rng, 0, M)[:, 0]
                lq = _PRODUCT.log_density(C[:, None, :])
            else:
                C = mix.draw(rng, M)
                lq = mix.log_density(C)
            spent += M
            l0 = ref.log_density(C)
            l1 = laplace_marginal(Lk, prior, C, iters)
            ok = np.isfinite(l1) & np.isfinite(lq) & np.isfinite(l0)
            if not np.any(ok):
                continue
            C, l0, l1, lq = C[ok], l0[ok], l1[ok], lq[ok]
            # the share of effective draws among those where the Laplace marginal is positive:
            # draws of C that no configuration in the world box admits (up to 80% of the
            # product prior's) have weight 0 at every temperature above 0, and counted against
            # all M they held the temperature at 0 for every round (development seeds, 10 views)
            need = keep * C.shape[0]

            def lw_at(b, l0=l0, l1=l1, lq=lq):
                return b * l1 + (1.0 - b) * l0 - lq

            if effective_sample_size(lw_at(1.0)) >= need:
                beta_new = 1.0
            elif effective_sample_size(lw_at(beta)) < need:
                beta_new = beta          # refit at the same temperature
            else:
                lo, hi = beta, 1.0
                for _ in range(25):
                    mid = 0.5 * (lo + hi)
                    lo, hi = (mid, hi) if effective_sample_size(lw_at(mid)) >= need else (lo, mid)
                beta_new = lo
            lw = lw_at(beta_new)
            w = np.exp(lw - lw.max())
            mix = _CMix(*_fit_mixture(C, w, K, rng), defensive=True)
            done = beta == 1.0 and beta_new == 1.0
            beta = beta_new
            if done or (beta == 1.0 and k < L.n):
                break
    if mix is None:
        mix = _CMix([1.0], np.array([[0.0, 0.5]]), np.eye(2)[None], defensive=True)
    return mix, spent


@_quiet
def solve_rb(L, prior, part, rng, opts):
    """The reference's answer by the conditional-Laplace sampler (the dict of
    :func:`qfg.solvers.reference.staged.solve_reference`)."""
    mix, spent = adapt_c_proposal(L, prior, rng, opts)
    M = int(opts["rb_samples"])
    iters = int(opts["gn_iters"])
    finals, ess_rounds, lws = [], [], []
    total = spent
    for _ in range(int(opts["final_rounds"])):
        C = mix.draw(rng, M)
        lqc = mix.log_density(C)
        # the prior inside the filter: Z estimates the integral of the whole target given C
        logz, X, alpha = particle_trajectories(L, C, rng, int(opts["particles"]), iters,
                                               prior=prior)
        lw = np.full(M, -np.inf)
        ok = np.isfinite(logz) & np.isfinite(lqc)
        lw[ok] = logz[ok] - lqc[ok]
        lw = np.where(np.isnan(lw), -np.inf, lw)
        total += M
        s = _summaries(part, X, C, lw)
        ess_rounds.append(0.0 if s is None else s[4])
        if s is not None:
            finals.append(s + (X, C))
            lws.append(lw)
        if sum(ess_rounds) >= float(opts["ess_goal"]):
            break
        if opts["refit"] and s is not None:
            # population Monte Carlo: half of the next proposal refitted to this round's draws
            # weighted by the exact target (the Laplace marginal that fitted C's mixture can
            # miss where the trajectory's conditional is far from Gaussian)
            w = np.exp(lw - np.max(lw))
            pis, mus, chols = _fit_mixture(C, w, int(opts["components"]), rng)
            mix = _CMix(np.r_[0.5 * mix.pis, 0.5 * pis], np.concatenate([mix.means, mus]),
                        np.concatenate([mix.chols, chols]), defensive=True)
    return final_answer(L, part, finals, M, opts["min_ess"], lws, ess_rounds, total)


# ---------------------------------------------------------------------------------------------
# the trajectory given C: a particle filter twisted by the Laplace approximation


def intermediate_prior(prior):
    """The prior the particle filter's intermediate targets use on the points seen so far (C and
    the views j..n), or None (no prior before the last step). For the priors whose density on a
    subset of the points is (up to a constant) its marginal there (:class:`~qfg.priors.WorldBoxPrior`,
    exchangeable points; the independent :class:`~qfg.priors.ProductPrior` and
    :class:`~qfg.priors.WindowPrior`), that density, the world box's on ``INTER_N_RHO`` angles
    (cheaper than 128 by about 10x; only the last target, which carries the exact prior, makes
    the answer: at 20 views with C at the truth 16 angles gave the ESS of 32 within its
    scatter between seeds and the filter 25-50% faster, development seed 2, geometries 0-7).
    Any positive intermediate target keeps the filter exact; a closer one keeps its weights even.
    """
    if isinstance(prior, _priors.WorldBoxPrior):
        if prior.n_rho <= INTER_N_RHO:
            return prior
        return prior.replace(n_rho=INTER_N_RHO)
    if isinstance(prior, (_priors.ProductPrior, _priors.WindowPrior)):
        return prior
    return None


#: Quadrature angles of the world box prior in the particle filter's intermediate targets.
INTER_N_RHO = 16


@_quiet
def particle_trajectories(L, C, rng, K=8, iters=40, prior=None):
    """Trajectories given C (M, 2) by sequential Monte Carlo backwards along the views (n down
    to 1), K particles per C, using the conditional Laplace approximation in arc coordinates
    both as proposal and as twisting function: the step of view j draws t_j from the Gaussian's
    conditional ``q(t_j | t_{j+1})`` (the backward-sampling pass) and targets
    ``gamma_j = [exact factors of views j..n and the headings between them, arc Jacobians,
    headings' uniform prior] x phi_j(t_j)``, where ``phi_j`` is the Gaussian message of the
    views before j about the mode (the forward pass's information minus view j's own and
    outgoing factors); ``phi_1 = 1``, so the last target is exact. Particles are resampled (systematic,
    per C) after every step. Were the Gaussian exact, every weight would be equal; where it is
    not, resampling stops the error from compounding over the views (the plain Laplace proposal
    multiplies n such errors).

    With ``prior`` given, the targets also carry it: ``gamma_j`` times the prior of C and the
    views j..n (:func:`intermediate_prior`; none before the last step for other priors), the
    last target times ``prior(C, X_1..X_n)`` exactly. Its coupling of every point (the world
    box's scale: a density of about extent^-(2n + 4)) is then corrected view by view with
    resampling, instead of on one trajectory drawn without it, whose log prior had a standard
    deviation of 1.0-2.8 nats at 20 views with C at the truth (development seed 2,
    ``python -m benchmarks.reference_views20 --seed 2 --scenarios 0 6 --views 20 --at-truth``).

    Returns log Z (M,), the filter's unbiased estimate of ``int prod factors dX dalpha`` (times
    the prior when given), and one trajectory per C drawn from the final particles: X (M, n,
    2), alpha (M, n). ``Z / q(C)`` with the prior (``Z prior(C, X) / q(C)`` without) is an
    importance weight of the exact target (the expectation of Z f(X) is the integral of the
    target times f)."""
    M, n = C.shape[0], L.n
    tm, _, (Ld, Lo), ok = fit_trajectories(L, C, iters)
    _, _, _, _, (Down, _) = _blocks(L, C, tm, parts=True)
    Ld = np.where(ok[:, None, None, None], Ld, np.eye(3))
    Lo = np.where(ok[:, None, None, None], Lo, 0.0) if Lo.size else Lo
    # the past's message at the mode: information S_j - own_j (S_j = Ld_j Ld_j^T), gradient g_j -
    # own gradient (the full gradient is ~0 at the mode)
    S = np.einsum("mjik,mjlk->mjil", Ld, Ld)
    # the message is kept a bounded function (phi <= 1): its information clipped to positive
    # semi-definite and centred at the mode (without the linear term, which where the
    # information is nearly singular would let phi grow without bound and the weights' variance
    # with it). Any positive phi keeps the filter exact; a closer one keeps its weights even.
    lam_, vec = np.linalg.eigh(S - Down)
    Lam = np.einsum("mjik,mjk,mjlk->mjil", vec, np.maximum(lam_, 0.0), vec)
    Lam = np.where(np.isfinite(Lam), Lam, 0.0)
    P = M * K
    grp = np.repeat(np.arange(M), K)
    T = np.zeros((n, P, 3))
    anc = np.zeros((n, P), dtype=np.int64)
    logZ = np.where(ok, 0.0, -np.inf)
    base = (np.arange(M) * K)[:, None]
    nxt = None            # (t_{j+1}, X_{j+1}, log phi_{j+1}, log prior_{j+1}) of the particles
    lw = None
    inter = intermediate_prior(prior) if prior is not None else None
    path = np.zeros((P, n, 2)) if prior is not None else None   # positions of views j..n
    Cg = C[grp][:, None, :]
    for j in range(n - 1, -1, -1):
        mj = tm[grp, j]
        Lj = Ld[grp, j]
        z = rng.standard_normal((P, 3))
        rhs = z if nxt is None else z - np.einsum("pji,pj->pi", Lo[grp, j], nxt[0] - tm[grp, j + 1])
        dt = _bwd3(Lj, rhs)
        tj = mj + dt
        lq = (-0.5 * np.sum(z * z, -1) - 1.5 * _LOG2PI
              + np.sum(np.log(np.diagonal(Lj, axis1=-2, axis2=-1)), axis=1))
        X, _, _, logdet, valid = _pose(L, tj[:, 0], tj[:, 1], j)
        X = np.where(valid[:, None], X, 0.0)
        al = tj[:, 2]
        f = logdet - _LOG2PI
        for k, Pt in enumerate((np.zeros((1, 2)), np.array([[0.0, 1.0]]), C[grp])):
            d = Pt - X
            f = f + _log_wn(L.phi[j, k] - np.arctan2(d[:, 1], d[:, 0]) + al, L.sv)
        if nxt is not None and L.psi is not None:
            d = nxt[1] - X
            f = f + _log_wn(L.psi[j] - np.arctan2(d[:, 1], d[:, 0]) + al, L.sw)
        if j > 0:
            lphi = -0.5 * np.einsum("pi,pik,pk->p", dt, Lam[grp, j], dt)
        else:
            lphi = np.zeros(P)
        lwp = f + lphi - lq - (0.0 if nxt is None else nxt[2])
        lpr = np.zeros(P)
        if prior is not None:
            path[:, j] = X
            pj = prior if j == 0 else inter
            if pj is not None:
                lpr = pj.log_density(np.concatenate([Cg, path[:, j:]], axis=1))
            lwp = lwp + lpr - (0.0 if nxt is None else nxt[3])
        good = valid & (np.abs(dt[:, 2]) < np.pi) & np.isfinite(lwp)
        lw = np.where(good, lwp, -np.inf).reshape(M, K)
        lse = logsumexp(lw, axis=1)
        logZ = logZ + lse - np.log(K)
        T[j] = tj
        if j > 0:
            fin = np.isfinite(lse)
            w = np.where(fin[:, None], np.exp(lw - np.where(fin, lse, 0.0)[:, None]), 1.0 / K)
            cw = np.cumsum(w, axis=1)
            cw[:, -1] = 1.0 + 1e-12
            u = (rng.random((M, 1)) + np.arange(K)[None, :]) / K
            a = (base + np.minimum(_rows_searchsorted(cw, u), K - 1)).ravel()
            anc[j] = a
            nxt = (tj[a], X[a], lphi[a], lpr[a])
            if path is not None:
                path = path[a]
    # one trajectory per C by the final weights, traced through the ancestors
    lse = logsumexp(lw, axis=1)
    fin = np.isfinite(lse)
    w = np.where(fin[:, None], np.exp(lw - np.where(fin, lse, 0.0)[:, None]), 1.0 / K)
    cw = np.cumsum(w, axis=1)
    u = rng.random((M, 1)) * cw[:, -1:]
    p = (np.arange(M) * K + np.minimum(_rows_searchsorted(cw, u)[:, 0], K - 1))
    t = np.zeros((M, n, 3))
    for j in range(n):
        t[:, j] = T[j][p]
        if j < n - 1:
            p = anc[j + 1][p]
    X, _, _, _, valid = _pose(L, t[..., 0], t[..., 1])
    X = np.where(valid[..., None], X, 0.0)
    return np.where(np.isfinite(logZ), logZ, -np.inf), X, t[..., 2]


def _rows_searchsorted(cw, u):
    """Per row r, ``searchsorted(cw[r], u[r])`` for non-decreasing rows with cw[r, -1] > 0:
    (R, k) indices."""
    R, K = cw.shape
    span = cw[:, -1:]
    off = np.arange(R)[:, None] * 4.0
    flat = (cw / span + off).ravel()
    q = (u / span + off).ravel()
    return (np.searchsorted(flat, q) - np.repeat(np.arange(R) * K, u.shape[1])).reshape(u.shape)
