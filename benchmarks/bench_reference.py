"""Reference solver: ESS, time per triplet and calibration on data drawn from its own prior.

``run()`` (the benchmark suite's entry) times 3-view triplets at sigma_v = 2 deg, sigma_w = 5 deg.
Run as a script for the full table (ESS per noise level and view count, calibration):

    python -m benchmarks.bench_reference --triplets 40 --views 3 5 10 --seed 7

Views, on development histories ``random_triplet_history(default_rng(700000 + i),
n, 2 deg, 5 deg)``: median ESS, share flagged ESS < 50, Pareto k and time per sampler, the time
also in units of a fixed numpy workload run in the same process (:func:`yardstick`), so that runs
under different loads compare:

    python -m benchmarks.bench_reference --views-dev 3 5 10 20 --triplets 8 --samplers auto staged conditional

and the conditional sampler against the staged one on the same triplets (``--agreement 3 4 5``):
per state z = difference / combined reported error, total variation, log evidence difference.

Calibration: configurations from ``qfg.priors.sample_measurements`` (the solver's own model and
prior), solved by the reference; a calibrated posterior has ``E[1(top = truth)] = E[p_top]``, so
``z_top = sum(1(top = truth) - p_top) / sqrt(sum p_top (1 - p_top))`` is about N(0, 1); likewise
per probability bin over every state (``z_bin``, variance ``sum P_bin (1 - P_bin)`` per triplet,
P_bin the triplet's total probability in the bin's states).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from qfg import metrics, partitions, priors
from qfg.solvers.reference import solve_reference

NOISE = ((0.5, 2.0), (2.0, 5.0), (4.0, 10.0))
BINS = (0.0, 0.05, 0.2, 0.5, 0.8, 0.95, 1.0 + 1e-9)


def evaluate(n_views, sb_deg, sh_deg, n_triplets, seed, **options):
    """Solve ``n_triplets`` triplets drawn from the world prior; per-triplet rows."""
    part = partitions.get("edc")
    sb, sh = np.deg2rad(sb_deg), np.deg2rad(sh_deg)
    rng = np.random.default_rng(seed)
    phi, psi, conf, _ = priors.sample_measurements("world", rng, n_views, sb, sh, n_triplets)
    truth = part.state_of(conf[:, 0])
    rows = []
    for i in range(n_triplets):
        t = time.perf_counter()
        out = solve_reference(phi[i], psi[i], sb, sh, seed=np.random.default_rng([seed, i]),
                              **options)
        rows.append({"p": out["landmark"], "truth": int(truth[i]), "ess": out["ess"],
                     "ess_final": out["ess_rounds"][-1], "err": float(out["mc_error"].max()),
                     "time": time.perf_counter() - t, "degenerate": out["degenerate"]})
    return rows


def calibration(rows):
    P = np.array([r["p"] for r in rows])
    g = np.array([r["truth"] for r in rows])
    top = P.argmax(axis=1)
    pt = P.max(axis=1)
    z_top = float(np.sum((top == g) - pt) / np.sqrt(max(np.sum(pt * (1 - pt)), 1e-12)))
    onehot = np.arange(P.shape[1])[None, :] == g[:, None]
    zb = []
    for lo, hi in zip(BINS[:-1], BINS[1:], strict=True):
        inb = (P >= lo) & (P < hi)
        pb = np.sum(P * inb, axis=1)
        hit = np.sum(onehot & inb, axis=1)
        var = np.sum(pb * (1 - pb))
        zb.append(float(np.sum(hit - pb) / np.sqrt(var)) if var > 0 else 0.0)
    return {"z_top": z_top, "z_bins": zb, "log_score": float(np.mean(metrics.log_score(P, g))),
            "brier": float(np.mean(metrics.brier(P, g))), "top1": float(np.mean(top == g))}


def run():
    """Benchmark-suite rows: median seconds per 3-view triplet at 2/5 deg (default options)."""
    rows = evaluate(3, 2.0, 5.0, 10, seed=2024)
    ts = np.array([r["time"] for r in rows])
    return [{"name": "reference, single call (3 views, 2/5 deg)", "value": float(np.median(ts)),
             "unit": "s/triplet", "target": "seconds",
             "note": f"median of 10, p90 {np.percentile(ts, 90):.1f} s, median ESS "
                     f"{np.median([r['ess'] for r in rows]):.0f}"}]


def prior_check(seed=11, size=200_000):
    """The world prior against simulated worlds: k = 1 Pearson chi-square on 8 x 8 cells (the
    same check as tests/test_priors.py, other seeds), normalization by importance sampling,
    quadrature error of n_rho = 128 against 2048, and time per evaluation."""
    from scipy import stats

    p = priors.get("world")
    rng = np.random.default_rng(seed)
    x = p.sample(rng, n_cameras=0, size=size)[:, 0]
    ex, ey = np.linspace(-2, 2, 9), np.linspace(-1.5, 2.5, 9)
    obs, _, _ = np.histogram2d(x[:, 0], x[:, 1], bins=(ex, ey))
    f = 16
    gx = ex[0] + (np.arange(8 * f) + 0.5) * (4 / (8 * f))
    gy = ey[0] + (np.arange(8 * f) + 0.5) * (4 / (8 * f))
    G = np.stack(np.meshgrid(gx, gy, indexing="ij"), axis=-1)[:, :, None, :]
    out = {}
    for name, pr in (("world", p), ("world-product", priors.ProductPrior())):
        E = (np.exp(pr.log_density(G)) * (4 / (8 * f)) ** 2).reshape(8, f, 8, f).sum(axis=(1, 3))
        Ee = E / E.sum() * obs.sum()
        chi2 = float(np.sum((obs - Ee) ** 2 / Ee))
        out[name] = (chi2, float(stats.chi2.sf(chi2, 63)))
    q = priors.ProductPrior()
    norm = {}
    for k in (1, 2, 3):
        xs = q.sample(rng, k - 1, 100_000)
        w = np.exp(p.log_density(xs) - q.log_density(xs))
        norm[k] = (float(w.mean()), float(w.std() / np.sqrt(w.size)))
    xs = p.sample(rng, 2, 2000)
    quad = float(np.max(np.abs(priors.WorldBoxPrior(n_rho=128).log_density(xs)
                               - priors.WorldBoxPrior(n_rho=2048).log_density(xs))))
    xs = p.sample(rng, 3, 20_000)
    t = time.perf_counter()
    p.log_density(xs)
    us = 1e6 * (time.perf_counter() - t) / xs.shape[0]
    print(f"k=1 chi-square on 64 cells (df 63), {int(obs.sum())} of {size} draws in the cells:")
    for name, (c, pv) in out.items():
        print(f"  {name}: chi2 = {c:.1f}, p = {pv:.3g}")
    for k, (m, se) in norm.items():
        print(f"normalization, k={k}: E_q[p/q] = {m:.4f} +- {se:.4f}")
    print(f"quadrature: max |log p(n_rho=128) - log p(n_rho=2048)| = {quad:.2e} (k = 3, 2000 draws)")
    print(f"time: {us:.1f} us per 4-point configuration (20000 batched)")


def compare(n_triplets=60, sb_deg=2.0, sh_deg=5.0, seed=909):
    """Every method of ``qfg.solvers.solve_triplet`` on the same 3-view triplets of the paper's
    generative model (``random_triplet_history``): mean clipped log score, Brier, top-1, truths
    under 1%, ECE, seconds per triplet."""
    from qfg.simulation import random_triplet_history
    from qfg.solvers import solve_triplet

    ss = np.random.SeedSequence(seed)
    hs = [random_triplet_history(np.random.default_rng(c), 3, np.deg2rad(sb_deg),
                                 np.deg2rad(sh_deg)) for c in ss.spawn(n_triplets)]
    g = np.array([h.truth.state for h in hs])
    print(f"{n_triplets} triplets, 3 views, {sb_deg:g}/{sh_deg:g} deg, seed {seed}")
    for method in ("reference", "full", "fast", "baseline"):
        t = time.perf_counter()
        P = np.array([solve_triplet(h, method=method, seed=k).landmark for k, h in enumerate(hs)])
        ls = metrics.log_score(P, g)
        print(f"| {method} | {ls.mean():.3f} ± {ls.std() / np.sqrt(len(g)):.3f} "
              f"| {metrics.brier(P, g).mean():.3f} | {np.mean(P.argmax(1) == g):.2f} "
              f"| {metrics.truth_under(P, g).mean():.2f} "
              f"| {metrics.expected_calibration_error(P, g):.3f} "
              f"| {(time.perf_counter() - t) / len(g):.2f} |", flush=True)


def seed_check(n_views, sb_deg, sh_deg, n_triplets, seed=31):
    """Two seeds per triplet: z = difference / combined reported error over every state with an
    error above 1e-4; a faithful error gives std(z) about 1."""
    sb, sh = np.deg2rad(sb_deg), np.deg2rad(sh_deg)
    phi, psi, _, _ = priors.sample_measurements("world", np.random.default_rng(seed), n_views,
                                                sb, sh, n_triplets)
    zs, flagged = [], 0
    for i in range(n_triplets):
        a = solve_reference(phi[i], psi[i], sb, sh, seed=np.random.default_rng([1, i]))
        b = solve_reference(phi[i], psi[i], sb, sh, seed=np.random.default_rng([2, i]))
        flagged += a["degenerate"] or b["degenerate"]
        sd = np.sqrt(a["mc_error"] ** 2 + b["mc_error"] ** 2)
        ok = sd > 1e-4
        zs += ((a["landmark"] - b["landmark"])[ok] / sd[ok]).tolist()
    zs = np.array(zs)
    print(f"{n_views} views, {sb_deg:g}/{sh_deg:g} deg, {n_triplets} triplets ({flagged} flagged): "
          f"{zs.size} probabilities, std(z) = {zs.std():.2f}, |z| > 3: {np.mean(np.abs(zs) > 3):.3f}, "
          f"max |z| = {np.abs(zs).max():.2f}")


def yardstick(repeats=5):
    """Seconds of a fixed numpy workload (elementwise transcendental functions and small
    reductions on 10^6 floats, the solvers' kind of work): the median of ``repeats`` runs."""
    x = np.random.default_rng(0).standard_normal(1_000_000)
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        y = np.arctan2(np.sin(x), np.cos(x)) * np.exp(-0.5 * x * x)
        float(np.sum(y * y) + np.log1p(np.abs(y)).mean())
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def _dev_history(n, i):
    from qfg.simulation import random_triplet_history

    return random_triplet_history(np.random.default_rng(700000 + i), n, np.deg2rad(2),
                                  np.deg2rad(5))


def views_dev(views, n_triplets, samplers):
    """ESS, flags, Pareto k and time per number of views and sampler on development histories."""
    import os

    y0 = yardstick()
    print(f"load {os.getloadavg()[0]:.1f}; yardstick {y0 * 1e3:.1f} ms")
    print("| views | sampler | n | median ESS | min ESS | ESS < 50 | median Pareto k | median s "
          "| median time / yardstick |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in views:
        for smp in samplers:
            ess, ks, ts, ys = [], [], [], []
            for i in range(n_triplets):
                h = _dev_history(n, i)
                t = time.perf_counter()
                out = solve_reference(h.bearings, h.headings, h.sigma_bearing, h.sigma_heading,
                                      seed=1, sampler=smp)
                ts.append(time.perf_counter() - t)
                ys.append(yardstick(1))
                ess.append(out["ess"])
                ks.append(out["pareto_k"])
            ess, ts = np.array(ess), np.array(ts)
            print(f"| {n} | {smp} | {n_triplets} | {np.median(ess):.0f} | {ess.min():.0f} "
                  f"| {np.mean(ess < 50):.2f} | {np.nanmedian(ks):.2f} | {np.median(ts):.1f} "
                  f"| {np.median(ts / np.array(ys)):.0f} |", flush=True)


def agreement(views, n_triplets):
    """The conditional sampler against the staged one on the same development histories."""
    print("| views | triplet | ESS staged / conditional | max abs z | total variation "
          "| log evidence difference |")
    print("|---|---|---|---|---|---|")
    zs = []
    for n in views:
        for i in range(n_triplets):
            h = _dev_history(n, i)
            args = (h.bearings, h.headings, h.sigma_bearing, h.sigma_heading)
            a = solve_reference(*args, seed=1, sampler="staged")
            b = solve_reference(*args, seed=1, sampler="conditional")
            sd = np.sqrt(a["mc_error"] ** 2 + b["mc_error"] ** 2)
            z = (a["landmark"] - b["landmark"]) / np.maximum(sd, 1e-12)
            zs += z[sd > 1e-4].tolist()
            print(f"| {n} | {i} | {a['ess']:.0f} / {b['ess']:.0f} | {np.abs(z).max():.1f} "
                  f"| {0.5 * np.abs(a['landmark'] - b['landmark']).sum():.3f} "
                  f"| {b['log_evidence'] - a['log_evidence']:+.2f} |", flush=True)
    zs = np.array(zs)
    print(f"all: {zs.size} probabilities, std(z) = {zs.std():.2f}, |z| > 3: "
          f"{np.mean(np.abs(zs) > 3):.3f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--triplets", type=int, default=40)
    ap.add_argument("--views", type=int, nargs="+", default=[3, 5, 10])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--n-samples", type=int, default=None)
    ap.add_argument("--prior-check", action="store_true", help="check the world prior instead")
    ap.add_argument("--compare", action="store_true",
                    help="every solver method on the same triplets instead")
    ap.add_argument("--seed-check", nargs=3, type=float, metavar=("VIEWS", "SB", "SH"),
                    help="two seeds per triplet against the reported error instead")
    ap.add_argument("--views-dev", type=int, nargs="+", default=None,
                    help="ESS and time per number of views on development histories instead")
    ap.add_argument("--samplers", nargs="+", default=["auto"])
    ap.add_argument("--agreement", type=int, nargs="+", default=None,
                    help="conditional against staged sampler at these view counts instead")
    args = ap.parse_args(argv)
    if args.views_dev:
        views_dev(args.views_dev, args.triplets, args.samplers)
        return
    if args.agreement:
        agreement(args.agreement, args.triplets)
        return
    if args.seed_check:
        seed_check(int(args.seed_check[0]), args.seed_check[1], args.seed_check[2], args.triplets)
        return
    if args.prior_check:
        prior_check()
        return
    if args.compare:
        compare(args.triplets)
        return
    opts = {} if args.n_samples is None else {"n_samples": args.n_samples}
    print("| views | sigma_v/sigma_w (deg) | median ESS | 10th pct ESS | ESS<50 | median max MC err "
          "| median s | z_top | z per bin | log score | Brier | top-1 |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for n in args.views:
        for sb, sh in NOISE:
            rows = evaluate(n, sb, sh, args.triplets, args.seed, **opts)
            ess = np.array([r["ess"] for r in rows])
            c = calibration(rows)
            print(f"| {n} | {sb:g}/{sh:g} | {np.median(ess):.0f} | {np.percentile(ess, 10):.0f} "
                  f"| {np.sum(ess < 50)} | {np.median([r['err'] for r in rows]):.4f} "
                  f"| {np.median([r['time'] for r in rows]):.1f} | {c['z_top']:+.2f} "
                  f"| {' '.join(f'{z:+.1f}' for z in c['z_bins'])} | {c['log_score']:.3f} "
                  f"| {c['brier']:.3f} | {c['top1']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
