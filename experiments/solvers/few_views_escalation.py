"""Time for a few views: can a small 3-view budget for ``full``, escalated to the full budget
only where its own diagnostics say the answer is unreliable, stay within 0.03 nats of the
reference at about 1.0 workload per triplet?

    python experiments/solvers/few_views_escalation.py run LO HI OUT [--replicate R] [--views N]
        NAME=JSON ...
    python experiments/solvers/few_views_escalation.py report OUT [OUT ...] --ref REF [--small NAME ...]
        [--esc NAME ...] [--sets NAME=JSON ...] [--dev LO:HI] [--test LO:HI] [--costs JSON]
        [--target KL] [--views N]
    python experiments/solvers/few_views_escalation.py noise SV,SW [--n 150] [--seeds 6] [--cache DIR]
        [--threshold 0.15]

(docs/solvers.md, "Accuracy, calibration and speed": the few-views budget and its escalation,
gives the commands and what they measured. Run from the repository root as above.)

``run``: the run-seed-2 development geometries LO..HI-1 of the views20 preset at 3 views
(:func:`sis_rejuvenation.geometry`, its solver seeds; ``--replicate R`` another seed
of each geometry), every option set NAME=JSON of ``full`` solved in one batched call per set.
A set with ``few_views_populations`` K > 1 is solved population by population (each with its
share of the budget and its seed, as :mod:`qfg.solvers.sis.populations` runs them, and merged by
:func:`qfg.solvers.sis.populations.merge`), so that each population's answer is kept. One JSON
line per geometry: ``{"g", "gt", "rep", NAME: {"p", "ess", "mc", "flag", "pops"}}``.
Option sets whose NAME ends in ``@esc`` are solved with the seed an escalation would use
(the triplet's seed's child :data:`ESCALATE_KEY`), i.e. independent of the other sets' draws.

``report``: the mean KL(reference || answer) of every set (answer clipped at 1e-4, as
``sis_rejuvenation report``; the reference lines of REF with ``--views`` views), paired against
the full budget (the mean of sets ``full`` and ``full@esc`` per solve; SE over geometries);
then for each small set (``--small``) and escalation set (``--esc``, default ``full@esc``) and
each diagnostic of :func:`diagnostics`, when the triplets whose diagnostic is at least a
threshold take the escalated answer (``replace``) or the budget-weighted mean of both
(``pool``; ``--sets`` names the option sets so that their budgets are known): the threshold
chosen on ``--dev`` geometries (the least escalation whose mean KL there is at most
``--target``, default the full budget's own dev KL), the share, KL and paired difference it
gives on ``--test``, and the held-out KL at costs of 1.0-1.5 workloads over all thresholds
(cost ``small + share x escalation``; ``--costs``: {NAME: workloads} measured by batched timing).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

# the sibling scripts (sis_rejuvenation, solver_defaults) are imported where they are used
sys.path.insert(0, str(Path(__file__).resolve().parent))

#: Spawn key (under a triplet's seed) of an escalated re-solve's seed in this script.
ESCALATE_KEY = 2_000_003


def _solve(metas, roots, opts_json):
    """(estimate, [per-population landmark]) per triplet, batched."""
    from qfg.partitions import get as get_partition
    from qfg.solvers.common import options as _options
    from qfg.solvers.sis import populations as _populations
    from qfg.solvers.solve import solve_sis_batch

    part = get_partition("edc")
    opts = _options.resolve_options("full", dict(opts_json))
    K = _populations.count(opts, 3)
    if K == 1 or opts.get("few_views_escalate") is not None:
        # the library's own path (an escalating set is measured as the library answers)
        return [(e, []) for e in solve_sis_batch("full", metas, roots, part, opts)]
    one = dict(opts_json, few_views_populations=1, populations=1)
    split = _populations.split_options(opts, K)
    # each population's options as the engine receives them (budget already split)
    one.update({k: split[k] for k in _populations.SPLIT_KEYS})
    if split.get("few_views_budget"):
        one["few_views_budget"] = split["few_views_budget"]
    o1 = _options.resolve_options("full", one)
    per = [solve_sis_batch("full", metas, [_populations.roots(r, K)[k] for r in roots], part,
                            o1, hypotheses=True) for k in range(K)]
    out = []
    for t in range(len(metas)):
        pairs = [per[k][t] for k in range(K)]
        est, _ = _populations.merge(pairs, opts)
        out.append((est, [p[0].landmark for p in pairs]))
    return out


def run(lo, hi, out, sets, replicate=0, views=3):
    from sis_rejuvenation import geometry, solver_seed

    from qfg.solvers.common import input as _input
    from qfg.solvers.common import seeds as _seeds

    metas, roots, gts = [], [], []
    for i in range(lo, hi):
        h, root, _ = geometry(i, views)
        metas.append(_input.measurements(h, None, None, None, None, None))
        roots.append(solver_seed(root, views, "full", replicate))
        gts.append(int(h.truth.state))
    recs = [{"g": i, "gt": g, "rep": replicate, "n": views} for i, g in zip(range(lo, hi), gts, strict=True)]
    times = {}
    for name, o in sets:
        rs = [_seeds.child_seed(r, ESCALATE_KEY) for r in roots] if name.endswith("@esc") \
            else roots
        t0 = time.process_time()
        res = _solve(metas, rs, o)
        times[name] = (time.process_time() - t0) / len(metas)
        for rec, (e, pops) in zip(recs, res, strict=True):
            rec[name] = {"p": np.asarray(e.landmark).tolist(), "ess": float(e.ess),
                         "mc": float(e.mc_error), "flag": bool(e.degenerate),
                         "pops": [np.asarray(p).tolist() for p in pops]}
        print(f"{name}: {1e3 * times[name]:.2f} ms per triplet (process time, batched)",
              flush=True)
    with open(out, "a") as fh:
        for rec in recs:
            fh.write(json.dumps(rec) + "\n")


#: The first stage the escalation was measured with (docs/solvers.md).
FIRST_STAGE = {"few_views_populations": 2,
               "few_views_budget": {"n_samples": 400, "motion_samples": 6, "max_hypotheses": 2000}}


def noise(sv, sw, n=150, seeds=6, cache=None, threshold=0.15):
    """``noise``: on ``solver_defaults``' development scenarios (``SeedSequence(555)``,
    3 views) at sigma_v, sigma_w = ``sv``, ``sw`` degrees, the defaults, :data:`FIRST_STAGE`
    alone and with ``few_views_escalate=threshold``, each with solver seeds 7, 8, ...; the mean
    KL(reference || answer) per set and the paired differences against the defaults (per
    scenario, averaged over the seeds; SE over scenarios), and the share escalated."""
    from pathlib import Path

    from solver_defaults import histories, reference

    from qfg.solvers import solve_triplets

    hs = histories(n, sv, sw)
    R = reference(hs, Path(cache) if cache else None, f"{n}_{sv:g}_{sw:g}")
    sets = {"defaults": {}, "first stage": FIRST_STAGE,
            "escalated": dict(FIRST_STAGE, few_views_escalate=threshold)}
    k = {name: [] for name in sets}
    share = []
    for seed in range(7, 7 + seeds):
        for name, o in sets.items():
            es = solve_triplets(hs, method="full", seed=seed, **o)
            k[name].append(kl(R, np.array([e.landmark for e in es])))
            if name == "first stage":
                share.append(np.mean([not (e.mc_error <= threshold) for e in es]))
    k = {name: np.array(v) for name, v in k.items()}
    out = f"{sv:g}/{sw:g} deg, {n} scenarios x {seeds} seeds: defaults {k['defaults'].mean():.4f}"
    for name in ("first stage", "escalated"):
        d = (k[name] - k["defaults"]).mean(axis=0)
        out += (f", {name} {k[name].mean():.4f} (paired {d.mean():+.4f} +- "
                f"{d.std(ddof=1) / np.sqrt(d.size):.4f})")
    return out + f"; escalated share {np.mean(share):.3f}"


def kl(r, q):
    """KL(r || q), q clipped at 1e-4 (the answers' floor in ``sis_rejuvenation report``)."""
    r, q = np.asarray(r, float), np.asarray(q, float)
    return np.sum(r * (np.log(np.clip(r, 1e-12, 1)) - np.log(np.clip(q, 1e-4, 1))), axis=-1)


def diagnostics(v):
    """Scores an escalation rule may threshold (large: escalate), from the answer alone."""
    p = np.asarray(v["p"])
    d = {"1/ess": 1.0 / max(v["ess"], 1e-9), "mc_error": v["mc"],
         "entropy": float(-(p * np.log(np.clip(p, 1e-300, 1))).sum()),
         "1-p_max": 1.0 - float(p.max())}
    if v["pops"]:
        P = np.asarray(v["pops"])
        d["pop_tv"] = max(0.5 * float(np.abs(P[i] - P[j]).sum())
                          for i in range(len(P)) for j in range(i + 1, len(P)))
    return d


def curve(recs, ref, small, esc, rule, weight, rows):
    """Per-row KL of the small answer (ks) and of the escalated one (km), and the rule's score
    per row: escalated rows take ``esc``'s answer (``weight`` None) or
    ``weight * small + (1 - weight) * esc``."""
    R = np.array([ref[recs[i]["g"]] for i in rows])
    ps = np.array([recs[i][small]["p"] for i in rows])
    pe = np.array([recs[i][esc]["p"] for i in rows])
    pm = pe if weight is None else weight * ps + (1 - weight) * pe
    s = np.array([diagnostics(recs[i][small])[rule] for i in rows])
    return kl(R, ps), kl(R, pm), s


def escalated(ks, km, s, threshold):
    """Per-row KL when the rows whose score is at least ``threshold`` are escalated."""
    return np.where(s >= threshold, km, ks)


def _pick(ks, km, s, target):
    """The largest threshold (least escalation) whose mean KL is at most ``target``; None if
    none is."""
    order = np.argsort(-s, kind="stable")
    k = (ks.sum() + np.concatenate([[0.0], np.cumsum((km - ks)[order])])) / len(ks)
    thr = np.concatenate([[np.inf], s[order]])
    ok = np.flatnonzero(k <= target)
    return None if ok.size == 0 else float(thr[ok[0]])


def _paired(d, groups):
    """Mean of d and its standard error over groups (the solves of one geometry are not
    independent: their mean is the unit)."""
    u = np.unique(groups)
    m = np.array([d[groups == g].mean() for g in u])
    return float(d.mean()), float(m.std(ddof=1) / np.sqrt(len(u)))


def report(files, ref_file, smalls, dev, test, costs, target="base", escs=("full@esc",),
           base=("full", "full@esc"), views=3):
    """Text report (module docstring). ``base``: the full budget's option sets, whose mean KL
    per solve is the yardstick (dev: the target when ``target`` is "base"; held-out: the
    paired differences)."""
    recs: dict = {}
    for f in files:
        for line in open(f):
            r = json.loads(line)
            if r.get("n", 3) == views:
                recs.setdefault((r["g"], r["rep"]), {}).update(r)
    ref = {r["g"]: np.asarray(r["p"]) for r in map(json.loads, open(ref_file))
           if r["n"] == views}
    recs = [r for _, r in sorted(recs.items()) if r["g"] in ref]
    rows = {"dev": [i for i, r in enumerate(recs) if dev[0] <= r["g"] < dev[1]],
            "test": [i for i, r in enumerate(recs) if test[0] <= r["g"] < test[1]]}
    base_kl = {k: np.array([np.mean([kl(ref[recs[i]["g"]], recs[i][b]["p"]) for b in base])
                            for i in v]) for k, v in rows.items()}
    lines = []
    for part, (lo, hi) in (("dev", dev), ("test", test)):
        if not rows[part]:
            continue
        names = [k for k in recs[rows[part][0]] if k not in ("g", "gt", "rep", "n")
                 and all(k in recs[i] for i in rows[part])]
        line = ", ".join(f"{k} {np.mean([kl(ref[recs[i]['g']], recs[i][k]['p']) for i in rows[part]]):.4f}"
                         for k in names)
        groups = np.array([recs[i]["g"] for i in rows[part]])
        b, se = _paired(base_kl[part], groups)
        lines.append(f"{part} geometries {lo}-{hi - 1} ({len(rows[part])} solves): mean KL {line}; "
                     f"full budget ({' and '.join(base)}) {b:.4f} +- {se:.4f} (SE over geometries)")
        for k in names:
            if k in base:
                continue
            d = np.array([kl(ref[recs[i]["g"]], recs[i][k]["p"]) for i in rows[part]]) \
                - base_kl[part]
            m, e = _paired(d, groups)
            lines.append(f"    {k}: paired against the full budget {m:+.4f} +- {e:.4f}")
    goal = float(np.mean(base_kl["dev"])) if target == "base" else float(target)
    lines.append(f"threshold chosen on dev: the least escalation with mean KL <= {goal:.4f} "
                 f"({'the full budget on dev' if target == 'base' else 'given'}); cost = small + "
                 "share x escalation (workloads); paired: held-out KL minus the full budget's, "
                 "per solve, SE over geometries")
    groups = np.array([recs[i]["g"] for i in rows["test"]])
    for esc in escs:
        ce = costs.get(esc.split("@")[0], np.nan)
        for small in smalls:
            cs = costs.get(small, np.nan)
            for rule in sorted(diagnostics(recs[rows["dev"][0]][small])):
                for how, w in (("replace", None), ("pool", _pool_weight(small, esc))):
                    th = _pick(*curve(recs, ref, small, esc, rule, w, rows["dev"]), goal)
                    ks, km, s = curve(recs, ref, small, esc, rule, w, rows["test"])
                    if th is None:
                        head = "never reaches it on dev"
                    else:
                        k = escalated(ks, km, s, th)
                        d, se = _paired(k - base_kl["test"], groups)
                        share = float(np.mean(s >= th))
                        head = (f"threshold {th:.4g}: held-out share {share:.3f}, KL {k.mean():.4f}"
                                f" (paired {d:+.4f} +- {se:.4f}), cost {cs + share * ce:.2f}")
                    # by cost, any threshold (the best case for the rule on held-out)
                    cpts = []
                    for c in (1.0, 1.1, 1.2, 1.3, 1.5):
                        q = (c - cs) / ce
                        if 0 <= q <= 1:
                            t = np.inf if q == 0 else np.quantile(s, 1 - q)
                            cpts.append(f"{c:.1f}:{escalated(ks, km, s, t).mean():.4f}")
                    lines.append(f"{small} -> {esc} | {rule} | {how} (w {0 if w is None else w:.2f})"
                                 f": {head}\n    held-out KL at workloads {' '.join(cpts)}")
    return "\n".join(lines)


def _pool_weight(small, esc):
    """Budget weight of the small answer when pooled with the escalated one: its share of
    first-view samples x motion samples (each answer's Monte Carlo variance ~ 1 / budget)."""
    from qfg.solvers import DEFAULTS

    def budget(name):
        o = dict(DEFAULTS["full"])
        o.update(_SETS.get(name.split("@")[0], {}))
        o.update(o.get("few_views_budget") or {})
        return o["n_samples"] * o["motion_samples"]

    bs, be = budget(small), budget(esc)
    return bs / (bs + be)


#: option sets by name, filled by ``run`` / ``report`` arguments NAME=JSON
_SETS: dict = {}


def _named(args):
    out = []
    for a in args:
        name, _, js = a.partition("=")
        _SETS[name] = json.loads(js)
        out.append((name, _SETS[name]))
    return out


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in ("run", "report", "noise"):
        raise SystemExit(__doc__)

    def take(flag, default, conv=str, many=False):
        nonlocal rest
        if flag not in rest:
            return default
        j = rest.index(flag)
        if many:
            k = j + 1
            while k < len(rest) and not rest[k].startswith("--"):
                k += 1
            vals, rest = rest[j + 1:k], rest[:j] + rest[k:]
            return vals
        v, rest = conv(rest[j + 1]), rest[:j] + rest[j + 2:]
        return v

    cmd, rest = argv[0], argv[1:]
    if cmd == "noise":
        n, seeds = take("--n", 150, int), take("--seeds", 6, int)
        cache, thr = take("--cache", None), take("--threshold", 0.15, float)
        sv, sw = (float(v) for v in rest[0].split(","))
        print(noise(sv, sw, n, seeds, cache, thr))
    elif cmd == "run":
        rep = take("--replicate", 0, int)
        views = take("--views", 3, int)
        run(int(rest[0]), int(rest[1]), rest[2], _named(rest[3:]), rep, views)
    else:
        ref = take("--ref", None)
        smalls = take("--small", [], many=True)
        dev = tuple(int(x) for x in take("--dev", "0:200").split(":"))
        test = tuple(int(x) for x in take("--test", "200:400").split(":"))
        costs = json.loads(take("--costs", "{}"))
        target = take("--target", "base")
        escs = take("--esc", ["full@esc"], many=True)
        sets = take("--sets", [], many=True)
        _named(sets)
        views = take("--views", 3, int)
        print(report(rest, ref, smalls, dev, test, costs, target, escs, views=views))


if __name__ == "__main__":
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        sys.exit(0)
    main()
