"""The no-motion baseline: the paper's model without motion factors (eqs. slamInd1/2), the
stand-in for the previous state of the art in Table 1.

Views are independent given C, so

    P(L_C | Z) ~ prior(L_C) prod_i  integral P(Z_i | X_i, L_C) p(X_i) dX_i.

It is evaluated by samples: C candidates drawn from the prior (stratified), and for each view
``noise_samples`` draws of the measurement noise. The integral over the camera pose has a closed
form per noise draw: with ``u = f(X, L)`` the three bearings a pose sees,

    integral N(phi - f(X, L); sigma) p(X) dX = E_{u ~ N(phi, sigma^2)} [ p(X*(u, L)) / |det df/dX| ]

where ``X*(u, L)`` is the 3-point resection (the pose that sees A, B and L at bearings u: the
second intersection of the locus circles of chords AB and AL). So

    density_i(L) = mean_k  p(X*_k) / |det J(X*_k)|,   J = d(phi_A, phi_B, phi_C) / d(x, y, alpha),

with zero noise exact (one draw). ``1 / |det J|`` is singular (integrably) where A, B, L and the
camera are concyclic; a candidate that happens to fall next to that circle is capped at
``jacobian_cap`` x the median over candidates, so that no single candidate dominates.

**The prior of the whole configuration.** The product above holds when the prior is a product
of per-point priors. A world prior is not: C and the cameras share one frame (A, B and every point
placed in one world box), so a configuration whose cameras stand many |AB| away is unlikely
*once* (|AB| must then be small against the box), not once per view. With ``joint_samples`` =
M > 0 (the default) the answer is the posterior under the prior's joint density
``prior.log_density([C, X_1..X_n])``, by importance sampling on the product's terms:

    P(L | Z) ~ prior_1(L) prod_i density_i(L) * E_{k_i ~ pi_i}[ r(L, X*_{1,k_1}, .., X*_{n,k_n}) ]

with ``pi_i(k) ~ p_1(X*_k) / |det J(X*_k)|`` (view i's noise draws as weighted above),
``r = prior(L, X_1..X_n) / (prior_1(L) prod_i prior_1(X_i))`` and the expectation estimated by M
tuples of draws per candidate (unbiased: the product's terms are the importance proposal). With
``joint_samples=0`` the product of per-point priors is used (the paper's model, eqs. slamInd1/2).
On tight landmark clusters seen from afar (MRCLAM dataset 5) the product counts the small-|AB|
penalty once per view and pulls every camera, and C with them, toward A and B.

The camera-state posterior of view i is ``sum_L P(L | Z) R_i(L, s)``, ``R_i(L, s)`` the share of
density_i(L) whose resected camera is in state s (with the joint prior: of the tuples, weighted
by r). Headings are never read. A view with a
degenerate locus (camera on line AB with zero noise) has no resection; it is ignored and flagged.
A view repeating the previous view's bearings is taken as the same camera (not moved): it adds
no evidence and is flagged.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np

from .. import priors as _priors
from ..geometry import LOCUS_EPS, wrap_angle
from .common import degenerate as _degenerate
from .common import estimate as _estimate
from .common import histograms as _histograms
from .common import input as _input
from .common import likelihood as _likelihood
from .common import prior as _prior
from .common import seeds as _seeds

_PRODUCT = _priors.ProductPrior()

#: Largest relative bearing residual accepted for a resected pose (radians).
_RESECTION_TOL = 1e-6


@dataclass(frozen=True, eq=False)
class BaselineState:
    meas: _input.Measurements
    root: np.random.SeedSequence
    opts: dict
    part: object
    candidates: np.ndarray     # (N, 2) C candidates (drawn from the prior)
    lw: np.ndarray             # (N,) sum over views of log density_i
    shares: tuple              # per view: (N, m) R_i, or None for an ignored view
    cameras: tuple             # per view: ((N, K, 3) resected poses, (N, K) contributions)
    reasons: tuple
    source: tuple = ()         # per view: the counted view whose camera it is (itself when it
                               # entered lw; a repeat: the view it repeats), or None (ignored)
    point_lp: tuple = ()       # per view: (N, K) per-point log prior of the resected poses


def _candidates(rng, n, prior):
    """n C candidates drawn by a jittered grid in inverse-CDF coordinates: from the per-point
    world fit (world priors and any prior without a window), or uniform in a WindowPrior's
    window. Returns (candidates (N, 2), log proposal density (N,))."""
    if not isinstance(prior, _priors.WindowPrior):
        # p(P) = (s^2/pi)(s^2 + r^2)^-2 about the centre: P(radius <= r) = r^2 / (s^2 + r^2)
        gx = max(1, int(round(np.sqrt(n / 4))))
        gy = max(1, int(np.ceil(n / gx)))
        ix, iy = np.meshgrid(np.arange(gx), np.arange(gy), indexing="ij")
        u = rng.random((gx * gy, 2))
        U = (ix.ravel() + u[:, 0]) / gx
        ang = 2 * np.pi * (iy.ravel() + u[:, 1]) / gy
        r = _PRODUCT.scale * np.sqrt(U / (1.0 - U))
        pts = _PRODUCT.CENTRE + np.stack([r * np.cos(ang), r * np.sin(ang)], axis=-1)
        return pts, _prior.point_log_prior(_PRODUCT, pts)
    xmin, xmax, ymin, ymax = prior.window
    w, h = xmax - xmin, ymax - ymin
    gx = max(1, int(round(np.sqrt(n * w / h))))
    gy = max(1, int(np.ceil(n / gx)))
    ix, iy = np.meshgrid(np.arange(gx), np.arange(gy), indexing="ij")
    u = rng.random((gx * gy, 2))
    x = xmin + (ix.ravel() + u[:, 0]) * (w / gx)
    y = ymin + (iy.ravel() + u[:, 1]) * (h / gy)
    return np.stack([x, y], axis=-1), np.full(gx * gy, -np.log(w * h))


def resect(L, phi):
    """3-point resection in the AB frame: the poses that see A = (0, 0), B = (0, 1) and ``L``
    (N, 2) at bearings ``phi`` (K, 3). Returns ``(poses (N, K, 3), log|det J| (N, K), valid)``.

    The camera is the second intersection (besides A) of the locus circle of chord AB (angle
    ``phi_B - phi_A``) and that of chord AL (angle ``phi_C - phi_A``): the reflection of A in the
    line through the two centres. ``J = d(phi_A, phi_B, phi_C) / d(x, y, alpha)`` has rows
    ``(d_y / |d|^2, -d_x / |d|^2, -1)``, d from the camera to A, B, L. Invalid where a circle is
    degenerate, the circles coincide (the camera would be on the circle through A, B and L), or
    the pose would see a landmark at the supplementary angle (the other arc).
    """
    L = np.asarray(L, dtype=float)[:, None, :]
    pa, pb, pc = phi[None, :, 0], phi[None, :, 1], phi[None, :, 2]
    g1, g2 = wrap_angle(pb - pa), wrap_angle(pc - pa)
    s1, s2 = np.sin(g1), np.sin(g2)
    ok = (np.abs(s1) > LOCUS_EPS) & (np.abs(s2) > LOCUS_EPS)
    cot1 = np.cos(g1) / np.where(ok, s1, 1.0)
    cot2 = np.cos(g2) / np.where(ok, s2, 1.0)
    c1 = np.stack(np.broadcast_arrays(-0.5 * cot1, np.full_like(cot1, 0.5)), axis=-1)
    c2 = 0.5 * L + 0.5 * cot2[..., None] * np.stack([-L[..., 1], L[..., 0]], axis=-1)
    v = c2 - c1
    vv = np.sum(v * v, axis=-1)
    ok = ok & (vv > 1e-24)
    t = -np.sum(c1 * v, axis=-1) / np.where(ok, vv, 1.0)
    X = 2.0 * (c1 + t[..., None] * v)
    alpha = wrap_angle(np.arctan2(-X[..., 1], -X[..., 0]) - pa)
    rows = []
    for P, ph in (((0.0, 0.0), pa), ((0.0, 1.0), pb), (L, pc)):
        d = np.asarray(P) - X
        r2 = np.sum(d * d, axis=-1)
        ok = ok & (r2 > 1e-24)
        r2 = np.where(ok, r2, 1.0)
        res = wrap_angle(np.arctan2(d[..., 1], d[..., 0]) - alpha - ph)
        ok = ok & (np.abs(res) < _RESECTION_TOL)
        rows.append((d[..., 1] / r2, -d[..., 0] / r2))
    (a1, b1), (a2, b2), (a3, b3) = rows
    det = (a2 * b3 - a3 * b2) - (a1 * b3 - a3 * b1) + (a1 * b2 - a2 * b1)
    ok = ok & (np.abs(det) > 0)
    with np.errstate(divide="ignore"):
        logdet = np.where(ok, np.log(np.where(ok, np.abs(det), 1.0)), np.inf)
    return np.concatenate([X, alpha[..., None]], axis=-1), logdet, ok


def start(meas: _input.Measurements, root, opts, part) -> BaselineState:
    rng = _seeds.stream(root, 0, _seeds.STREAM_LANDMARKS)
    cand, lq = _candidates(rng, opts["n_landmark_samples"], opts["prior"])
    st = BaselineState(meas=_input.Measurements(meas.bearings[:0], np.zeros(0),
                                                meas.sigma_bearing, meas.sigma_heading),
                       root=root, opts=opts, part=part, candidates=cand,
                       lw=_prior.point_log_prior(opts["prior"], cand) - lq, shares=(), cameras=(),
                       reasons=())
    return step(st, meas.bearings[0])



def step(state: BaselineState, phi, heading=None) -> BaselineState:
    """Add one view's bearings ``phi`` (3,). The baseline has no motion model: a ``heading`` is
    kept only to flag degenerate geometry (travel along the line of sight to C)."""
    opts, part = state.opts, state.part
    i = state.meas.n_views
    h = state.meas.headings
    if i:
        h = np.append(h, np.nan if heading is None else heading)
    meas = replace(state.meas, bearings=np.vstack([state.meas.bearings, phi[None, :]]),
                   headings=h)
    if i and _degenerate.repeated_views(meas.bearings[-2:])[1]:
        # the same bearings again: the camera taken as not moved, one camera seen twice, so the
        # view adds no independent evidence (counting it again would square its likelihood)
        return replace(state, meas=meas, shares=state.shares + (state.shares[-1],),
                       cameras=state.cameras + (state.cameras[-1],),
                       source=state.source + (state.source[-1],),
                       point_lp=state.point_lp + (None,))
    sv = float(meas.sigma_bearing)
    k = 1 if sv == 0 else opts["noise_samples"]
    rng = _seeds.stream(state.root, i, _seeds.STREAM_CAMERAS)
    tail = opts.get("bearing_tail") if sv > 0 else None
    z = rng.standard_normal((k, 3))
    # with a bearing tail the draws come from its mixture (component choices drawn after z)
    draws = phi[None, :] + (sv * z if tail is None else _likelihood.bearing_noise(
        z, rng.random((k, 3)), rng.random((k, 3)), sv, tail))
    L = state.candidates
    poses, logdet, ok = resect(L, draws)
    lp = _prior.point_log_prior(opts["prior"], poses[..., :2])
    lc = lp - logdet
    lc = np.where(ok, lc, -np.inf)
    fin = np.isfinite(lc)
    if not np.any(fin):
        return replace(state, meas=meas, shares=state.shares + (None,),
                       cameras=state.cameras + ((poses, lc),), source=state.source + (None,),
                       point_lp=state.point_lp + (None,),
                       reasons=state.reasons + (f"view {i + 1}: no camera pose sees A, B and any "
                                                "candidate C at these bearings (ignored)",))
    # cap the integrable 1/|det J| singularity relative to the typical candidate
    cap = np.median(lc[fin]) + np.log(opts["jacobian_cap"])
    lc = np.minimum(lc, cap)
    ld = _likelihood.logsumexp(lc, axis=1) - np.log(k)
    shares = np.full((L.shape[0], part.n_states), 1.0 / part.n_states)
    good = np.isfinite(ld)
    if np.any(good):
        p = np.exp(lc[good] - (ld[good] + np.log(k))[:, None])      # (N', k), rows sum to 1
        s = part.state_of(poses[good][..., :2])                      # (N', k)
        idx = (np.arange(s.shape[0])[:, None] * part.n_states + s).ravel()
        shares[good] = np.bincount(idx, weights=p.ravel(),
                                   minlength=s.shape[0] * part.n_states).reshape(-1, part.n_states)
    return replace(state, meas=meas, lw=state.lw + ld, shares=state.shares + (shares,),
                   cameras=state.cameras + ((poses, lc),), source=state.source + (i,),
                   point_lp=state.point_lp + (lp,))


def _quadrature(prior):
    """The prior whose joint density the correction evaluates: a
    :class:`qfg.priors.WorldBoxPrior` with more than :data:`.prior.SOLVER_N_RHO` quadrature
    angles is evaluated with that many (the same box; the solvers' resolution for the world
    prior, within ~0.02 nats; N x M configurations per triplet at 128 angles cost 10x more)."""
    if isinstance(prior, _priors.WorldBoxPrior) and prior.n_rho > _prior.SOLVER_N_RHO:
        return _coarse_box(prior.width, prior.height, prior.d_min, prior.scale_power)
    return prior


@functools.lru_cache(maxsize=8)
def _coarse_box(width, height, d_min, scale_power=0):
    return _priors.WorldBoxPrior(width=width, height=height, d_min=d_min,
                                 n_rho=_prior.SOLVER_N_RHO, scale_power=scale_power)


def joint_correction(state: BaselineState, n_tuples: int):
    """The prior of the whole configuration against the product of per-point priors
    (module docstring): per candidate L, ``log mean_m r(L, X_{1,m}..X_{n,m})`` over ``n_tuples``
    tuples, view i's camera X_{i,m} drawn from its noise draws with probabilities ``pi_i``
    (its normalized contributions). Returns ``(correction (N,), {view: tuple poses (N, M, 3)},
    tuple weights (N, M))`` (the weights: r normalized per candidate); a candidate without weight
    gets correction 0 (its product weight is already 0)."""
    prior, L = state.opts["prior"], state.candidates
    N, M = L.shape[0], int(n_tuples)
    rng = _seeds.stream(state.root, 0, _seeds.STREAM_POSTERIOR)
    alive = np.isfinite(state.lw)
    logp1 = np.repeat(_prior.point_log_prior(prior, L)[:, None], M, axis=1)
    picks, X = {}, []
    for t, src in enumerate(state.source):
        if src != t:
            continue
        poses, lc = state.cameras[t]
        cum = np.cumsum(_likelihood.normalize_log(lc), axis=1)              # (N, K)
        u = rng.random((N, M)) * cum[:, -1:]
        idx = np.minimum((cum[:, None, :] <= u[..., None]).sum(axis=-1), cum.shape[1] - 1)
        Xt = np.take_along_axis(poses, idx[..., None], axis=1)             # (N, M, 3)
        Xt = np.where(alive[:, None, None], Xt, 0.0)    # a dead candidate's poses may be junk
        picks[t] = Xt
        X.append(Xt[..., :2])
        logp1 += np.take_along_axis(state.point_lp[t], idx, axis=1)
    if not X:
        return np.zeros(N), picks, np.full((N, M), 1.0 / M)
    lj = _prior.log_joint_prior(_quadrature(prior), np.broadcast_to(L[:, None, :], (N, M, 2)),
                                np.stack(X, axis=2))
    with np.errstate(invalid="ignore"):
        r = lj - logp1
    r = np.where(np.isfinite(logp1) & ~np.isnan(r), r, -np.inf)
    corr = np.where(alive, _likelihood.logsumexp(r, axis=1) - np.log(M), 0.0)
    return corr, picks, _likelihood.normalize_log(r)


def finish(state: BaselineState):
    """(estimate, hypotheses) from the candidates."""
    opts, part, meas = state.opts, state.part, state.meas
    n, m = meas.n_views, part.n_states
    reasons = list(state.reasons)
    known = meas.headings if n > 1 and not np.any(np.isnan(meas.headings)) else None
    reasons[:0] = _degenerate.geometry_reasons(meas.bearings, meas.sigma_bearing, known,
                                               meas.sigma_heading)
    rep = _degenerate.repeated_views(meas.bearings)
    if np.any(rep):
        reasons.append(_degenerate.repeated_reason(rep))
    M = int(opts.get("joint_samples", 0))
    joint = M > 0 and any(src == t for t, src in enumerate(state.source))
    lw = state.lw
    if joint:
        corr, picks, a = joint_correction(state, M)
        lw = lw + corr
    w = _likelihood.normalize_log(lw)
    landmark, ok = _histograms.state_histogram(part, state.candidates, w)
    N = state.candidates.shape[0]
    K = M if joint else max(c[0].shape[1] for c in state.cameras)
    cam_samples = np.zeros((n, N * K, 3))
    cam_w = np.zeros((n, N * K))
    if not ok:
        reasons.append("no C candidate is consistent with every view")
        cams = np.full((n, m), 1.0 / m)
    elif joint:
        # each view's camera from the tuples, weighted by the joint prior's ratio r
        cams = np.full((n, m), 1.0 / m)
        for t, src in enumerate(state.source):
            if src is None:
                continue
            Xt = picks[src]
            st = part.state_of(Xt[..., :2])                                  # (N, M)
            idx = (np.arange(N)[:, None] * m + st).ravel()
            R = np.bincount(idx, weights=a.ravel(), minlength=N * m).reshape(N, m)
            cams[t] = w @ R
            cam_samples[t] = Xt.reshape(-1, 3)
            cam_w[t] = (w[:, None] * a).ravel()
        cams = cams / cams.sum(axis=1, keepdims=True)
        s = cam_w.sum(axis=1, keepdims=True)
        cam_w = np.where(s > 0, cam_w / np.where(s > 0, s, 1.0), 0.0)
    else:
        cams = np.stack([np.full(m, 1.0 / m) if R is None else w @ R for R in state.shares])
        cams = cams / cams.sum(axis=1, keepdims=True)
        for t, (poses, lc) in enumerate(state.cameras):
            k = poses.shape[1]
            if state.shares[t] is None:
                continue
            # P(X = X*_{L,j} | Z) = P(L | Z) c_{L,j} / sum_j c_{L,j}
            cw = _likelihood.normalize_log(lc) * w[:, None]
            cam_samples[t, :N * k] = poses.reshape(-1, 3)
            cam_w[t, :N * k] = cw.ravel()
        s = cam_w.sum(axis=1, keepdims=True)
        cam_w = np.where(s > 0, cam_w / np.where(s > 0, s, 1.0), 0.0)
    hyp = _estimate.Hypotheses(landmark_samples=state.candidates, landmark_weights=w,
                               camera_samples=cam_samples, camera_weights=cam_w, joint=False)
    return _estimate.make_estimate("baseline", part, n, landmark, cams, hypotheses=hyp, reasons=reasons,
                                   opts=opts)
