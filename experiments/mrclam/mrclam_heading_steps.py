"""The odometry's direction of travel over one step against motion capture, and the per-step
heading model fitted to it (``qfg mrclam --heading-walk measured``,
:data:`qfg.harness.studies.mrclam.HEADING_WALK`).

For the study's histories (120-s passes, ``k`` views spread evenly over each, steps of at least
2 cm by odometry, every view covered by the capture), each step's heading error ``psi_odometry
- psi_capture`` (one per unordered history and step). Prints, per ``k``, the steps' count,
median duration and length and the robust std of the error; the maximum-likelihood fit of
``sigma(dt) = b sqrt(dt)`` (a random walk of the odometry's heading; a constant term is fitted
too); and the mean log-likelihood per step of the models the solvers can be given: the loader's
one sigma, one sigma per history from its longest step (``--heading-drift``), the random walk
at the history's longest step (one sigma per history) and per step (``--heading-walk``).

    QFG_MRCLAM_DIR=... python experiments/mrclam/mrclam_heading_steps.py [--dataset 6] [--views 2 3 5 8]

Backs docs/mrclam.md, "The odometry's heading over a step". Run from the repository root as
above (``QFG_MRCLAM_DIR``: the directory holding the MRCLAM_Dataset* directories).
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import minimize
from scipy.stats import norm, spearmanr

from qfg.datasets import mrclam
from qfg.geometry import motion_heading, wrap_angle
from qfg.harness.studies import mrclam as study

MIN_STEP = 0.02


def heading_steps(ds, views: int) -> dict:
    """Per step: error (rad), duration (s), odometry length (m), the history's longest step
    (s) and its heading-drift sigma (rad), and the loader's sigma (rad); and ``pairs`` (P, 2)
    the errors over sqrt(duration) of consecutive steps of one history (both kept)."""
    seen, rows, pairs = set(), [], []
    for r, h in study.histories(ds, None, spread_views=views, max_gap=120.0):
        key = (r, tuple(np.asarray(h.views).tolist()))
        t = h.truth
        if key in seen or t.poses_world is None or not h.has_motion or (
                h.groundtruth_valid is not None and not np.all(h.groundtruth_valid)):
            continue
        seen.add(key)
        P = np.asarray(t.poses_world, dtype=float)
        err = wrap_angle(np.asarray(h.headings) - motion_heading(P[:-1], P[1:, :2]))
        dt = np.diff(np.asarray(h.views, dtype=float))
        n = err.size
        z = np.where(np.asarray(h.distances) >= MIN_STEP, err / np.sqrt(np.maximum(dt, 1e-3)),
                     np.nan)
        pairs.append(np.stack([z[:-1], z[1:]], axis=1))
        rows.append(np.stack([err, dt, np.asarray(h.distances, dtype=float),
                              np.full(n, dt.max()),
                              np.full(n, study.drift_sigma_heading(h, h.sigma_heading)),
                              np.full(n, float(h.sigma_heading))], axis=1))
    a = np.concatenate(rows) if rows else np.zeros((0, 6))
    a = a[a[:, 2] >= MIN_STEP]
    out = dict(zip(("err", "dt", "length", "longest", "drift", "loader"), a.T, strict=True))
    pr = np.concatenate(pairs) if pairs else np.zeros((0, 2))
    out["pairs"] = pr[np.all(np.isfinite(pr), axis=1)]
    return out


def fit_walk(err, dt) -> tuple[float, float]:
    """Maximum-likelihood (a, b) of ``sigma = sqrt(a^2 + b^2 dt)``, radians and rad/sqrt(s)."""
    def nll(p):
        a, b = np.exp(p)
        return -np.sum(norm.logpdf(err, scale=np.sqrt(a * a + b * b * dt)))

    r = minimize(nll, x0=[np.log(0.02), np.log(0.02)], method="Nelder-Mead",
                 options={"xatol": 1e-8, "fatol": 1e-10, "maxiter": 4000})
    a, b = np.exp(r.x)
    return float(a), float(b)


def walk_tail_loglik(err, dt, b, share, scale, floor=0.0) -> np.ndarray:
    """Log density of the heading errors under the walk (never below ``floor``) with the
    solvers' two-normal tail."""
    s = np.maximum(floor, b * np.sqrt(dt))
    return np.logaddexp(np.log1p(-share) + norm.logpdf(err, scale=s),
                        np.log(share) + norm.logpdf(err, scale=scale * s))


def fit_walk_tail(err, dt) -> tuple[float, float, float]:
    """Maximum-likelihood (b rad/sqrt(s), share, scale >= 1) of :func:`walk_tail_loglik`."""
    def nll(p):
        return -np.sum(walk_tail_loglik(err, dt, np.exp(p[0]), 1.0 / (1.0 + np.exp(-p[1])),
                                        1.0 + np.exp(p[2])))

    r = minimize(nll, x0=[np.log(0.015), -3.0, 1.0], method="Nelder-Mead",
                 options={"xatol": 1e-8, "fatol": 1e-10, "maxiter": 8000})
    return float(np.exp(r.x[0])), 1.0 / (1.0 + np.exp(-r.x[1])), 1.0 + float(np.exp(r.x[2]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dataset", type=int, default=6)
    ap.add_argument("--views", type=int, nargs="+", default=[2, 3, 5, 8])
    a = ap.parse_args(argv)
    ds = mrclam.load(mrclam.data_root() / f"MRCLAM_Dataset{a.dataset}")
    per_k = {k: heading_steps(ds, k) for k in a.views}
    allk = {c: np.concatenate([v[c] for v in per_k.values()]) for c in next(iter(per_k.values()))}
    for k, v in per_k.items():
        pr = v["pairs"]
        if pr.shape[0] < 3:
            continue
        print(f"{k} views: consecutive steps' errors over sqrt(duration), Spearman correlation "
              f"{spearmanr(pr[:, 0], pr[:, 1])[0]:.2f} ({pr.shape[0]} pairs)")
    a0, b0 = fit_walk(allk["err"], allk["dt"])
    print(f"{allk['err'].size} steps: sigma = sqrt(a^2 + b^2 dt), a {np.degrees(a0):.2f} deg, "
          f"b {np.degrees(b0):.2f} deg/sqrt(s) (the harness: b {study.HEADING_WALK})\n")
    bt, share, scale = fit_walk_tail(allk["err"], allk["dt"])
    print(f"with the two-normal tail: b {np.degrees(bt):.2f} deg/sqrt(s), share {share:.3f}, "
          f"scale {scale:.2f} (the harness: {study.HEADING_WALK_TAIL})\n")
    walk = np.deg2rad(study.HEADING_WALK)
    wt, (ts, tk) = np.deg2rad(study.HEADING_WALK_TAIL[0]), study.HEADING_WALK_TAIL[1]
    print("| views per pass | steps | median duration | median length | robust std of the "
          "error | loader's sigma | heading drift | walk, longest step | walk, per step | "
          "walk with tail, per step |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for k, v in [*per_k.items(), ("all", allk)]:
        e = v["err"]

        def ll(s, e=e):
            return np.mean(norm.logpdf(e, scale=s))

        print(f"| {k} | {e.size} | {np.median(v['dt']):.1f} s | {np.median(v['length']):.2f} m | "
              f"{np.degrees(1.4826 * np.median(np.abs(e))):.2f} deg | {ll(v['loader']):.2f} | "
              f"{ll(v['drift']):.2f} | "
              f"{ll(np.maximum(v['loader'], walk * np.sqrt(v['longest']))):.2f} | "
              f"{ll(np.maximum(v['loader'], walk * np.sqrt(v['dt']))):.2f} | "
              f"{np.mean(walk_tail_loglik(e, v['dt'], wt, ts, tk, v['loader'])):.2f} |")


if __name__ == "__main__":
    main()
