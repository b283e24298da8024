"""C's integral in the SIS engine's intermediate weights,
``∫ p1(L) prod_t N(phi_C,t - f(L, X_t); sigma_v) dL``: the Laplace approximation about the
triangulation where C's depth is resolved, a :func:`.landmarks.sample_landmarks` estimate
elsewhere (:func:`log_intermediate_c`), and the O(1) update of a parent's Gaussian summary with a
child's new line of sight (:func:`child_c`).
"""

from __future__ import annotations

import numpy as np

from ...geometry import bearing, wrap_angle
from ..common import laplace as _laplace
from ..common import likelihood as _likelihood
from ..common import prior as _prior
from ..common.seeds import per_triplet
from . import landmarks as _landmarks


def _landmark_draws(gens, tid, n, k, ray_fraction):
    kr = k if n == 1 else min(k, int(round(k * ray_fraction)))
    kg = k - kr
    counts = np.bincount(tid, minlength=len(gens))

    def draw(rng, m):
        return (rng.standard_normal((m, kg, 2)), rng.integers(0, n, size=(m, kr)),
                rng.standard_normal((m, kr)), rng.random((m, kr)))

    z, t, e, u = per_triplet(gens, counts, draw)
    return {"z": z, "t": t, "eps": e, "u": u}


def c_weight(state_like, tid, poses, bearings_c, gens, k, laplace=None):
    """(L, log q, log lik, spread) for hypotheses (N, i, 3) of triplets ``tid``."""
    n = poses.shape[1]
    draws = _landmark_draws(gens, tid, n, k, state_like.opts["ray_fraction"])
    return _landmarks.sample_landmarks(None, poses, bearings_c[tid], state_like.sigma_v()[tid], k,
                                       state_like.opts["ray_fraction"], draws=draws, laplace=laplace,
                                       tail=state_like.opts.get("bearing_tail"))


#: Depth spread below which the intermediate C weight uses the Laplace approximation; above it
#: (C's depth poorly resolved, e.g. lines of sight that nearly coincide) it is sampled.
_LAPLACE_SPREAD = 0.25


#: Depth spread below which a hypothesis keeps a C summary for the next views to update
#: (:func:`child_c`); above it C is refitted over the views at the next view.
_SUMMARY_SPREAD = _LAPLACE_SPREAD


def log_intermediate_c(state_like, tid, poses, bearings_c, gens):
    """log of C's integral with the per-point prior, for the intermediate weights: Laplace about
    the triangulation where C's depth is resolved, a :func:`.landmarks.sample_landmarks` estimate
    elsewhere. ``poses``: (N, n, 3), or a function of a row selection returning those rows (the
    motion step's children are then never gathered all at once). Returns (log integral (N,),
    summaries (N, 7)): the Laplace fit's :func:`.laplace.summary_from_parts` where it is used
    (the next view updates it, :func:`child_c`), NaN where C was sampled."""
    get = poses if callable(poses) else poses.__getitem__
    prior = state_like.opts["prior"]
    tail = state_like.opts.get("bearing_tail")
    sig = state_like.sigma_v()[tid]
    N = tid.size
    out, hard, lap = np.empty(N), [], []
    summ = np.empty((N, _laplace.SUMMARY_COLUMNS))
    for lo in range(0, N, _laplace.CHUNK_ROWS):
        sl = slice(lo, lo + _laplace.CHUNK_ROWS)
        P = get(sl)
        lz, Ls, spread, parts = _laplace.laplace_landmark(P, bearings_c[tid[sl]], sig[sl],
                                                          parts=True)
        if state_like.opts.get("c_anchors", False):
            # with the option c_anchors refits take the Laplace approximation about C's mode in
            # the bearing residuals (_at_mode) rather than about the lines' least-squares point
            # (a bearing tail's correction is then taken at the mode too)
            lz, Ls, spread, parts = _at_mode(P, bearings_c[tid[sl]], sig[sl], lz, spread, parts)
        out[sl] = lz + _prior.point_log_prior(prior, Ls)
        if tail is not None:
            out[sl] += _tail_correction(P, bearings_c[tid[sl]], sig[sl], Ls, tail)
        easy = spread < _LAPLACE_SPREAD
        summ[sl] = _laplace.summary_from_parts(lz, parts, spread < _SUMMARY_SPREAD)
        h = np.flatnonzero(~easy)
        hard.append(lo + h)
        lap.append(tuple(v[h] for v in parts))
    hard = np.concatenate(hard) if hard else np.zeros(0, dtype=int)
    if hard.size:
        k = state_like.opts["landmark_samples"]
        lap = tuple(np.concatenate(v) for v in zip(*lap, strict=True))
        L, log_q, log_lik, _ = c_weight(state_like, tid[hard], get(hard), bearings_c, gens, k,
                                         laplace=lap)
        lw = _prior.point_log_prior(prior, L) + log_lik - log_q
        lw = np.where(np.isnan(lw), -np.inf, lw)
        out[hard] = _likelihood.logsumexp(lw, axis=1) - np.log(k)
    return np.where(np.isnan(out), -np.inf, out), summ


def _at_mode(P, phi_c, sig, lz, spread, parts):
    """:func:`.laplace.laplace_landmark`'s outputs moved to C's mode over the views of ``P``
    (J, n, 3) where C's depth is resolved (:func:`.laplace.refine_mode` from the least-squares
    point): the Laplace value ``sum_t log N(r_t; sigma) + log(2 pi sigma^2 / sqrt(det H))`` there,
    as the carried summaries have it. Rows not resolved keep the least-squares values."""
    easy = np.flatnonzero(spread < _LAPLACE_SPREAD)
    if not easy.size:
        return lz, parts[0], spread, parts
    X, th = P[easy, :, :2], P[easy, :, 2] + phi_c[easy]
    L, ok, h00, h01, h11, det, r2min = _laplace.refine_mode(X, th, parts[0][easy])
    res = wrap_angle(bearing(P[easy], L[:, None, :]) - phi_c[easy])
    s = sig[easy]
    with np.errstate(divide="ignore", invalid="ignore"):
        lzm = _laplace.laplace_value(np.sum(res * res, axis=1), P.shape[1], s, det)
    good = ok & np.isfinite(lzm)
    e = easy[good]
    lz, spread = lz.copy(), spread.copy()
    new = [np.array(v, copy=True) for v in parts]
    for k, v in enumerate((L, ok, h00, h01, h11, det, r2min)):
        new[k][e] = v[good]
    lz[e] = lzm[good]
    spread[e] = _laplace.depth_spread(True, h00[good], h01[good], h11[good], det[good],
                                      r2min[good], s[good])
    return lz, new[0], spread, tuple(new)


def child_c(st, state, parent, pose, phi_c, has_sum):
    """Intermediate C weights of children (parents ``parent`` (K,), rows of ``state``; new poses
    ``pose`` (K, 3)) whose parents carry a C summary (``has_sum`` (N,)): the parent's summary
    updated with the new view's line of sight (:func:`.laplace.update_landmark`), plus the
    per-point prior at its mode. Returns (log integral (K,), summaries (K, 7)); NaN in both where
    C is to be refitted over all views (no summary, or the update leaves C's depth unresolved:
    spread >= :data:`_LAPLACE_SPREAD`)."""
    K = parent.size
    lw_c = np.full(K, np.nan)
    summ = np.full((K, _laplace.SUMMARY_COLUMNS), np.nan)
    rows = np.flatnonzero(has_sum[parent])
    if rows.size:
        ct = state.tid[parent[rows]]
        new, spread = _laplace.update_landmark(state.c_sum[parent[rows]], pose[rows, :2],
                                               pose[rows, 2] + phi_c[ct], st.sigma_v()[ct])
        ok = spread < _SUMMARY_SPREAD
        rows, new = rows[ok], new[ok]
        lw_c[rows] = new[:, 5] + _prior.point_log_prior(st.opts["prior"], new[:, :2])
        summ[rows] = new
    return lw_c, summ


def _tail_correction(poses, phi_c, sig, L, tail):
    """(J,) log of the tail model's C-bearing likelihood over the normal's at the triangulation
    ``L`` (J, 2): the Laplace value of C's integral (a normal likelihood) moved toward the tail
    model for the intermediate weights (the final weights use the tail model exactly)."""
    res = wrap_angle(bearing(poses, L[:, None, :]) - phi_c)
    s = sig[:, None]
    return np.sum(_likelihood.log_bearing(res, s, tail) - _likelihood.log_bearing(res, s), axis=1)
