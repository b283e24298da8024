"""How the single-triplet solvers' defaults were chosen: accuracy and time of option variants.

    python -m benchmarks.solver_defaults [--quick] [--output out/solver_defaults.md]

Scenarios come from a development seed (``SeedSequence(99991)``), never from the single-triplet
study's seeds: 200 noiseless 3-view scenarios (the acceptance criterion: the true state of C and
of the cameras most probable) and 100 at the headline noise sigma_v = 2 deg, sigma_w = 5 deg
(median DMSE, top-1 rate, mean log p(truth)). Times are per triplet, single calls, on whatever
else the machine was doing: compare within one run only.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from qfg import metrics
from qfg.simulation import random_triplet_history
from qfg.solvers import DEFAULTS, solve_triplet

DEV_SEED = 99991

VARIANTS = {
    "full": [
        {},
        {"n_samples": 300},
        {"n_samples": 1200},
        {"motion_samples": 4},
        {"motion_samples": 16},
        {"max_hypotheses": 1000},
        {"max_hypotheses": 10000},
        {"bearing_floor": np.deg2rad(0.1)},
        {"bearing_floor": np.deg2rad(0.5)},
        {"motion": "match", "n_samples": 300},
        {"prior": "uniform"},
        {"prior": "arc"},
        {"resection": "centroid"},
        {"landmark_volume": True},
    ],
    "fast": [
        {},
        {"n_samples": 64},
        {"n_samples": 256},
        {"refine_levels": 0},
        {"refine_levels": 2},
        {"refine_factor": 16},
        {"refine_levels": 0, "n_samples": 1024},
        {"bearing_floor": np.deg2rad(0.1)},
        {"bearing_floor": np.deg2rad(0.5)},
        {"jacobian": False},
        {"kernel": "combined"},
        {"prior": "uniform"},
        {"prior": "arc"},
        {"resection": "centroid"},
        {"landmark_volume": True},
    ],
    "baseline": [
        {},
        {"n_landmark_samples": 1024},
        {"n_landmark_samples": 16384},
        {"noise_samples": 4},
        {"noise_samples": 64},
        {"jacobian_cap": 3.0},
        {"jacobian_cap": 1e9},
        {"prior": "uniform"},
    ],
}


def _histories(n, sb, sh):
    ss = np.random.SeedSequence([DEV_SEED, int(round(np.rad2deg(sb) * 100)),
                                 int(round(np.rad2deg(sh) * 100))])
    return [random_triplet_history(np.random.default_rng(c), 3, sb, sh) for c in ss.spawn(n)]


def _fmt(opts):
    if not opts:
        return "defaults"
    out = []
    for k, v in opts.items():
        if k.endswith("floor"):
            v = f"{np.rad2deg(v):.2g} deg"
        out.append(f"{k}={v}")
    return ", ".join(out)


def evaluate(method, opts, noiseless, noisy):
    row = {"method": method, "options": _fmt(opts)}
    for tag, hs in (("noiseless", noiseless), ("noisy", noisy)):
        P, Cm, dt = [], [], []
        for k, h in enumerate(hs):
            t = time.perf_counter()
            e = solve_triplet(h, method=method, seed=k, **opts)
            dt.append(time.perf_counter() - t)
            P.append(e.landmark)
            Cm.append(e.cameras)
        P, Cm = np.array(P), np.array(Cm)
        g = np.array([h.truth.state for h in hs])
        gc = np.array([h.truth.camera_states for h in hs])
        if tag == "noiseless":
            row["top1 C (0,0)"] = np.mean(metrics.gt_rating(P, g) == 1)
            row["top1 cams (0,0)"] = np.mean(metrics.gt_rating(Cm, gc) == 1)
        else:
            d = metrics.dmse(P, g)
            row["DMSE q25/50/75 (2,5)"] = "/".join(f"{v:.2f}" for v in np.quantile(d, [.25, .5, .75]))
            row["top1 C (2,5)"] = np.mean(metrics.gt_rating(P, g) == 1)
            row["mean log p(truth) (2,5)"] = np.mean(np.log(np.maximum(metrics.gt_likelihood(P, g),
                                                                      1e-9)))
        row[f"ms ({'0,0' if tag == 'noiseless' else '2,5'})"] = 1e3 * np.median(dt)
    return row


def calibration(method, hs):
    """Reliability of the landmark estimates: predicted probability (binned) against how often
    the state is the true one, over every (scenario, state) pair."""
    P = np.array([solve_triplet(h, method=method, seed=k).landmark for k, h in enumerate(hs)])
    g = np.array([h.truth.state for h in hs])
    pr = P.ravel()
    hit = (np.arange(P.shape[1])[None, :] == g[:, None]).ravel()
    bins = [0, 0.05, 0.2, 0.4, 0.6, 0.8, 0.95, 1.0 + 1e-9]
    out = []
    for a, b in zip(bins[:-1], bins[1:], strict=True):
        sel = (pr >= a) & (pr < b)
        if sel.any():
            out.append((a, min(b, 1.0), int(sel.sum()), float(pr[sel].mean()),
                        float(hit[sel].mean())))
    return out


def world_prior_fit(n_draws=60000, seed=DEV_SEED):
    """The AB-frame distribution of a point placed uniformly in the world (with A and B also
    uniform, the simulator's placement) against the ``"world"`` prior's CDF R^2 / (s^2 + R^2)."""
    from qfg.geometry import to_frame
    from qfg.simulation import sample_positions
    from qfg.solvers import _common as C

    rng = np.random.default_rng(seed)
    pts = np.concatenate([to_frame(p[2:], p[0], p[1])
                          for p in (sample_positions(rng, 4) for _ in range(n_draws))])
    r = np.linalg.norm(pts - C.WORLD_CENTRE, axis=1)
    radii = np.array([0.25, 0.5, 0.75, 1, 1.5, 2, 3, 4, 6, 10, 20])
    emp = np.array([np.mean(r <= x) for x in radii])
    model = radii**2 / (C.WORLD_SCALE**2 + radii**2)
    return radii, emp, model, pts.shape[0]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="20 + 10 scenarios, defaults only")
    ap.add_argument("--output", default="out/solver_defaults.md")
    ap.add_argument("--methods", default="full,fast,baseline")
    ap.add_argument("--prior-fit", action="store_true",
                    help="only print the world prior's fit to the simulator and exit")
    args = ap.parse_args(argv)
    if args.prior_fit:
        radii, emp, model, n = world_prior_fit()
        print(f"{n} points; radius, empirical CDF, model CDF, difference")
        for x, e, m in zip(radii, emp, model, strict=True):
            print(f"{x:6.2f}  {e:.4f}  {m:.4f}  {m - e:+.4f}")
        return
    n0, n1 = (20, 10) if args.quick else (200, 100)
    noiseless = _histories(n0, 0.0, 0.0)
    noisy = _histories(n1, np.deg2rad(2.0), np.deg2rad(5.0))
    rows = []
    for method in args.methods.split(","):
        for opts in VARIANTS[method][:1] if args.quick else VARIANTS[method]:
            r = evaluate(method, opts, noiseless, noisy)
            print(r, flush=True)
            rows.append(r)
    cols = list(rows[0])
    lines = [
        "# Solver option sweep",
        "",
        f"Command: `python -m benchmarks.solver_defaults{' --quick' if args.quick else ''}`. "
        f"Development scenarios (seed {DEV_SEED}), {n0} noiseless and {n1} at sigma_v = 2 deg, "
        "sigma_w = 5 deg, 3 views, EDC. Times: median per single call, machine shared.",
        "",
        "Defaults: " + "; ".join(f"**{m}** " + ", ".join(f"{k}={v}" for k, v in d.items())
                                 for m, d in DEFAULTS.items()),
        "",
        "| " + " | ".join(cols) + " |",
        "|" + "---|" * len(cols),
    ]
    for r in rows:
        lines.append("| " + " | ".join(f"{r[c]:.3f}" if isinstance(r[c], float) else str(r[c])
                                       for c in cols) + " |")
    if not args.quick:
        lines += ["", "Calibration at (2, 5) with the defaults: predicted probability of a state "
                  "(binned) against the frequency with which it is the true state.", "",
                  "| method | bin | n | mean predicted | frequency true |", "|---|---|---|---|---|"]
        for method in args.methods.split(","):
            for a, b, n, pm, fr in calibration(method, noisy):
                lines.append(f"| {method} | [{a:.2f}, {b:.2f}) | {n} | {pm:.2f} | {fr:.2f} |")
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    Path(args.output).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
