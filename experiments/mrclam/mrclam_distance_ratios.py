"""The odometry's step-length ratios against motion capture, and the noise model fitted to them
(``qfg mrclam --distance-tail measured``, :data:`qfg.harness.studies.mrclam.DISTANCE_TAILS`).

For the study's histories (120-s passes, ``k`` views spread evenly over each, steps of at least
2 cm by odometry and by capture, every view covered by the capture), the error of each log ratio
of consecutive step lengths, ``log(d_i / d_(i-1)) - log(s_i / s_(i-1))`` (d: odometry, s:
capture), one per unordered history and step pair. Prints, per ``k``, the count, the robust
std (1.4826 x median |e|) and the share beyond 0.3; then the maximum-likelihood fit of the
solvers' mixture ``(1 - share) N(0, sigma) + share N(0, scale sigma)`` to all of them
(scipy.optimize) and the mean log-likelihood per ratio of normals of several widths beside it.

    QFG_MRCLAM_DIR=... python experiments/mrclam/mrclam_distance_ratios.py [--dataset 6] [--views 3 5 8]

Backs docs/mrclam.md, "The odometry's step-length ratios". Run from the repository root as
above (``QFG_MRCLAM_DIR``: the directory holding the MRCLAM_Dataset* directories).
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import minimize
from scipy.stats import norm

from qfg.datasets import mrclam
from qfg.harness.studies import mrclam as study

MIN_STEP = 0.02


def ratio_errors(ds, views: int) -> np.ndarray:
    """(N,) log-ratio errors of the odometry's consecutive step lengths against the capture."""
    seen, out = set(), []
    for r, h in study.histories(ds, None, spread_views=views, max_gap=120.0):
        key = (r, tuple(np.asarray(h.views).tolist()))
        t = h.truth
        if key in seen or t.poses_world is None or h.distances is None or (
                h.groundtruth_valid is not None and not np.all(h.groundtruth_valid)):
            continue
        seen.add(key)
        s = np.hypot(*np.diff(np.asarray(t.poses_world, float)[:, :2], axis=0).T)
        d = np.asarray(h.distances, float)
        ok = (s > MIN_STEP) & (d > MIN_STEP)
        if d.size > 1:
            m = ok[1:] & ok[:-1]
            e = np.diff(np.log(np.where(ok, d, 1.0))) - np.diff(np.log(np.where(ok, s, 1.0)))
            out.append(e[m])
    return np.concatenate(out) if out else np.zeros(0)


def mixture_loglik(x, share, sigma, scale) -> np.ndarray:
    """Log density of the solvers' two-normal mixture at ``x``."""
    return np.logaddexp(np.log1p(-share) + norm.logpdf(x, scale=sigma),
                        np.log(share) + norm.logpdf(x, scale=scale * sigma))


def fit_mixture(x) -> tuple[float, float, float]:
    """Maximum-likelihood (share, sigma, scale >= 1) of :func:`mixture_loglik`."""
    def nll(p):
        share = 1.0 / (1.0 + np.exp(-p[0]))
        return -np.sum(mixture_loglik(x, share, np.exp(p[1]), 1.0 + np.exp(p[2])))

    r = minimize(nll, x0=[-2.0, np.log(1.4826 * np.median(np.abs(x))), 1.0], method="Nelder-Mead",
                 options={"xatol": 1e-6, "fatol": 1e-9, "maxiter": 4000})
    return 1.0 / (1.0 + np.exp(-r.x[0])), float(np.exp(r.x[1])), 1.0 + float(np.exp(r.x[2]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dataset", type=int, default=6)
    ap.add_argument("--views", type=int, nargs="+", default=[3, 5, 8])
    a = ap.parse_args(argv)
    ds = mrclam.load(mrclam.data_root() / f"MRCLAM_Dataset{a.dataset}")
    xs = []
    print("| views per pass | ratios | robust std | beyond 0.3 |\n|---|---|---|---|")
    for k in a.views:
        x = ratio_errors(ds, k)
        xs.append(x)
        print(f"| {k} | {x.size} | {1.4826 * np.median(np.abs(x)):.3f} | "
              f"{np.mean(np.abs(x) > 0.3):.3f} |")
    x = np.concatenate(xs)
    share, sigma, scale = fit_mixture(x)
    print(f"\nall {x.size}: mixture share {share:.3f}, sigma {sigma:.3f}, scale {scale:.2f} "
          f"(tail sigma {scale * sigma:.3f}); mean log-likelihood per ratio:")
    print("| model | mean log-likelihood |\n|---|---|")
    for s in (0.074, 0.126, 0.15, 0.2):
        print(f"| normal {s} | {np.mean(norm.logpdf(x, scale=s)):.3f} |")
    for name, (sd, tail) in study.DISTANCE_TAILS.items():
        if tail is not None:
            print(f"| {name} ({sd}, {tail}) | "
                  f"{np.mean(mixture_loglik(x, tail[0], sd, tail[1])):.3f} |")
    print(f"| this fit | {np.mean(mixture_loglik(x, share, sigma, scale)):.3f} |")


if __name__ == "__main__":
    main()
