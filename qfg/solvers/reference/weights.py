"""The reference samplers' shared pieces: the wrapped-normal density, the summary of a weighted
sample (state probabilities with their Monte Carlo errors, ESS, evidence), the ESS-weighted
combination of rounds, and the flags the geometry of the weighted sample calls for.

Everything is in the AB frame (A = (0, 0), B = (0, 1)); angles in radians.
"""

from __future__ import annotations

import numpy as np

from ...geometry import wrap_angle
from ..common.degenerate import geometry_reasons
from ..common.likelihood import logsumexp

_LOG2PI = np.log(2 * np.pi)


def _log_wn(r, sigma):
    """Log density of the wrapped normal WN(0, sigma^2) at angles r (any real values)."""
    r = wrap_angle(r)
    base = -0.5 * (r / sigma) ** 2 - np.log(sigma) - 0.5 * _LOG2PI
    if sigma < 0.3:          # the other wraps are below e^-50 of the nearest one
        return base
    terms = [-0.5 * ((r + 2 * np.pi * k) / sigma) ** 2 for k in (-3, -2, -1, 1, 2, 3)]
    extra = np.exp(np.stack(terms) + 0.5 * (r / sigma) ** 2).sum(axis=0)
    return base + np.log1p(extra)

def _combine(finals, N):
    """ESS-weighted combination of the final stage's round estimates (consistent estimators of
    the same posterior): probabilities, their standard deviations, total ESS, log evidence from
    the pooled weights."""
    if not finals:
        return None
    ess = np.array([f[4] for f in finals])
    cw = ess / ess.sum()
    land = sum(c * f[0] for c, f in zip(cw, finals, strict=True))
    err = np.sqrt(sum((c * f[1]) ** 2 for c, f in zip(cw, finals, strict=True)))
    cams = sum(c * f[2] for c, f in zip(cw, finals, strict=True))
    cam_err = np.sqrt(sum((c * f[3]) ** 2 for c, f in zip(cw, finals, strict=True)))
    log_mean = float(logsumexp(np.array([f[5] for f in finals]) + np.log(cw)))
    best = int(np.argmax(ess))
    return land, err, cams, cam_err, float(ess.sum()), log_mean, finals[best][6], \
        finals[best][7], finals[best][8]

def final_answer(L, part, finals, N, min_ess, final_lws, ess_rounds, total) -> dict:
    """The reference's answer from its final rounds (both samplers): the ESS-weighted
    combination (:func:`_combine`), flags (ESS under ``min_ess``, :func:`_geometry_flags`), the
    Pareto k-hat of the final log weights ``final_lws`` (list of arrays), and the uniform
    answer, flagged, when no sample had positive weight. ``L``: the sampler's layout of all
    views (``L.n`` views)."""
    from ..common.diagnostics import pareto_k

    summ = _combine(finals, N)
    m = part.n_states
    reasons, k_hat = [], float("nan")
    if summ is None:
        land, err = np.full(m, 1.0 / m), np.zeros(m)
        cams, cam_err = np.full((L.n, m), 1.0 / m), np.zeros((L.n, m))
        ess, log_ev = 0.0, None
        reasons.append("no sample had positive weight")
    else:
        land, err, cams, cam_err, ess, log_ev, wn, X, c = summ
        if final_lws:
            k_hat = pareto_k(np.concatenate(final_lws))
        if ess < float(min_ess):
            reasons.append(f"effective sample size {ess:.1f} < {min_ess:g}")
        reasons += _geometry_flags(L, X, c, wn)
    return {
        "landmark": land, "cameras": cams, "mc_error": err, "cameras_mc_error": cam_err,
        "ess": float(ess), "ess_rounds": ess_rounds, "n_samples": int(total),
        "log_evidence": log_ev, "degenerate": bool(reasons), "reason": "; ".join(reasons),
        "pareto_k": k_hat,
    }


def _binomial_floor(p, ess):
    pt = (p * ess + 1.0) / (ess + 2.0)
    return pt * (1.0 - pt) / ess


def _summaries(part, X, c, lw):
    m = part.n_states
    mx = np.max(lw) if lw.size else -np.inf
    if not np.isfinite(mx):
        return None
    w = np.exp(lw - mx)
    wn = w / w.sum()
    sc = part.state_of(c)
    sx = part.state_of(X)                                   # (N, n)
    okc = sc >= 0
    land = np.bincount(sc[okc], weights=wn[okc], minlength=m)[:m]
    land = land / max(land.sum(), 1e-300)
    ess = 1.0 / np.sum(wn ** 2)
    ind = (sc[:, None] == np.arange(m)[None, :]).astype(float)
    # delta-method error, but never below the binomial error of ESS independent draws with
    # p~ = (P ESS + 1) / (ESS + 2): with few heavy draws that all sit in one state the delta
    # method alone reports ~0 (measured: two seeds 0.30 apart at ESS 12, delta-method error 0.03)
    err = np.sqrt(np.maximum(np.sum(wn[:, None] ** 2 * (ind - land[None, :]) ** 2, axis=0),
                             _binomial_floor(land, ess)))
    n = X.shape[1]
    cams = np.zeros((n, m))
    cam_err = np.zeros((n, m))
    for j in range(n):
        okj = sx[:, j] >= 0
        h = np.bincount(sx[okj, j], weights=wn[okj], minlength=m)[:m]
        cams[j] = h / max(h.sum(), 1e-300)
        indj = (sx[:, j, None] == np.arange(m)[None, :]).astype(float)
        cam_err[j] = np.sqrt(np.maximum(
            np.sum(wn[:, None] ** 2 * (indj - cams[j][None, :]) ** 2, axis=0),
            _binomial_floor(cams[j], ess)))
    log_mean = mx + np.log(w.sum()) - np.log(lw.size)
    return land, err, cams, cam_err, float(ess), float(log_mean), wn

def _geometry_flags(L, X, c, wn):
    """Reasons the geometry leaves the answer spread: the measurement flags every solver
    attaches (:func:`qfg.solvers.common.degenerate.geometry_reasons`: cameras on line AB where fewer
    than two views place the camera, travel along the line of sight to C), and lines of sight to
    C that nearly coincide in the weighted posterior sample (``X`` (N, n, 2) cameras, ``c``
    (N, 2) C, ``wn`` (N,) normalized weights) when the measurements did not say so already."""
    out = geometry_reasons(L.phi, L.sv, L.psi, L.sw)
    if L.n >= 2 and not any("coincide" in r for r in out):
        d = c[:, None, :] - X
        ang = np.arctan2(d[..., 1], d[..., 0])
        ii, jj = np.triu_indices(L.n, k=1)
        spread = np.max(np.abs(np.sin(ang[:, ii] - ang[:, jj])), axis=1)
        med = _weighted_median(spread, wn)
        if med < 3 * L.sv:
            out.append(f"lines of sight to C nearly coincide (largest angle between them "
                       f"{np.rad2deg(np.arcsin(min(med, 1.0))):.2g} deg)")
    return out


def _weighted_median(x, w):
    o = np.argsort(x)
    cw = np.cumsum(w[o])
    return float(x[o][np.searchsorted(cw, 0.5 * cw[-1])])
