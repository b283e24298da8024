"""``qfg mrclam PATH``: the MRCLAM study on one dataset directory (paper section 6d).

The dataset is one scenario of a run made by :func:`qfg.harness.runner.run_study`, so the output
directory follows the rules of ``qfg experiment``: a used directory needs ``--resume`` (a finished
run is then only summarized again) or ``--overwrite``; it is locked while running; Ctrl-C stops
with one line.
"""

from __future__ import annotations

import argparse

from qfg.harness.commands import add_format, seed_int


def _int_list(text: str, option: str = "--robots") -> list[int]:
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"{option}: expected comma-separated integers, got {text!r}") from None


def register(sub):
    p = sub.add_parser("mrclam", help="solve, map, propagate and score one MRCLAM dataset",
                       description="Every triplet history of the dataset solved, histories of one "
                                   "ordered triplet combined, the full qualitative map propagated, "
                                   "everything scored against the landmark ground truth "
                                   "(docs/results/mrclam.md).")
    p.add_argument("path", help="an MRCLAM_DatasetN directory")
    p.add_argument("--robots", default="", help="comma-separated robot numbers (default: all)")
    p.add_argument("--method", default="full", choices=("fast", "full", "baseline"),
                   help="single-triplet solver (robots without odometry: baseline; default full)")
    p.add_argument("--propagation", default="mean", choices=("mean", "best"),
                   help="unseen triplets: the mean of their compositions from the nearest "
                        "updated triplets (default), or the paper's Algorithm 2 (best "
                        "information score)")
    p.add_argument("--mode", default="honest", choices=("honest", "paper"),
                   help="honest: measured bearings and odometry (default); paper: bearings and "
                        "headings from motion capture (paper emulation; dataset 6)")
    p.add_argument("--prior", default="arena", choices=("arena", "world"),
                   help="world-box prior on the arena's extent (default) or the simulator's box")
    p.add_argument("--combine", default="geometric",
                   choices=("prior-once", "geometric", "product"),
                   help="how several histories of one ordered triplet combine, at the state level "
                        "with the prior counted once: by the geometric mean of their likelihoods "
                        "(default) or as independent passes (prior-once); or the plain product")
    p.add_argument("--min-travel", type=float, default=0.02,
                   help="metres between kept views of a pass (default 0.02: every view with motion)")
    p.add_argument("--max-gap", type=float, default=120.0,
                   help="seconds a triplet may go unseen within one pass (default 120)")
    p.add_argument("--max-views", type=int, default=0,
                   help="keep the first N views of each pass (default 0: all)")
    p.add_argument("--spread-views", type=int, default=3,
                   help="keep N views spread evenly over each pass (default 3; 0: all)")
    p.add_argument("--distances", action=argparse.BooleanOptionalAction, default=True,
                   help="use the odometry's travelled distances (a factor on ratios of "
                        "consecutive step lengths; default on: seen triplets of dataset 6 -1.16 vs -1.21)")
    p.add_argument("--sigma-distance-ratio", type=float, default=0.0,
                   help="noise of their log ratio (default 0: the loader's 0.074)")
    p.add_argument("--temper", type=float, default=1.0,
                   help="temper each estimate's likelihood part by this power in [0, 1] before "
                        "combining (default 1: none; docs/results/mrclam.md)")
    p.add_argument("--curve", default="",
                   help="comma-separated view caps (0 = all), e.g. 3,5,8,0: also score the seen "
                        "triplets with each pass cut to that many views (curve.csv, curve figure)")
    p.add_argument("--tensor", default=None,
                   help="composition tensor .npz (default: the shipped tensor of the partition)")
    p.add_argument("--no-fix-landmarks", action="store_true",
                   help="score against the landmark ground truth as shipped (no swap check)")
    p.add_argument("--seed", type=seed_int, default=0, help="solver seed (default 0)")
    p.add_argument("--output", default=None, help="output directory (default out/mrclam-<name>)")
    p.add_argument("--resume", action="store_true", help="continue (or re-summarize) a run in "
                                                         "--output")
    p.add_argument("--overwrite", action="store_true", help="start again in a used --output")
    p.add_argument("--no-figures", action="store_true", help="skip the figures")
    add_format(p)
    p.set_defaults(func=_main)


def run_one(task: dict, rng) -> list[dict]:
    """The runner's scenario: one dataset, solved with the seed given on the command line (not
    the scenario stream, so that ``--seed`` means what it meant before the runner)."""
    from qfg.harness.studies import mrclam as study

    T = study._load_tensor(task["partition"], task["tensor"]) if task["tensor"] else None
    return study.run_dataset(task["path"], robots=task["robots"] or None, method=task["method"],
                             mode=task["mode"], prior=task["prior"], combine=task["combine"],
                             partition=task["partition"], tensor=T,
                             fix_landmarks=task["fix_landmarks"], seed=task["seed"],
                             min_travel=task["min_travel"], max_gap=task["max_gap"],
                             max_views=task["max_views"], temper=task["temper"],
                             spread_views=task["spread_views"],
                             propagation=task.get("propagation", "mean"),
                             distances=task.get("distances", True),
                             sigma_distance_ratio=task.get("sigma_distance_ratio", 0.0))


def _main(args):
    import shlex
    import sys
    from pathlib import Path

    from qfg.harness import runner
    from qfg.harness.studies import mrclam as study

    robots = _int_list(args.robots)
    path = Path(args.path)
    if not path.is_dir():
        raise ValueError(f"path: {path} is not a directory")
    params = {"path": str(path.resolve()), "robots": robots, "method": args.method,
              "mode": args.mode, "prior": args.prior, "combine": args.combine,
              "min_travel": args.min_travel, "max_gap": args.max_gap, "max_views": args.max_views,
              "temper": args.temper, "spread_views": args.spread_views, "partition": "edc",
              "propagation": args.propagation, "distances": args.distances,
              "sigma_distance_ratio": args.sigma_distance_ratio,
              "tensor": args.tensor or "",
              "fix_landmarks": not args.no_fix_landmarks, "seed": args.seed,
              "figures": not args.no_figures}
    out = Path(args.output or f"out/mrclam-{path.resolve().name}")
    shown = {}

    def summarize(outdir, rows, _params):
        shown["summary"] = study.write_outputs(outdir, rows, figures=not args.no_figures,
                                               figure_robot=robots[0] if robots else None)

    one = runner.Study("mrclam", lambda p: [{"index": 0, **p}], run_one, summarize,
                       "one MRCLAM dataset")
    rows = runner.run_study(one, params, out, seed=args.seed, resume=args.resume,
                            overwrite=args.overwrite, progress=False,
                            command="qfg " + " ".join(shlex.quote(a) for a in sys.argv[1:]),
                            figure_format=args.format)
    summ = shown["summary"]
    swaps = rows[0].get("gt_swaps") if rows else ""
    if swaps:
        print(f"landmark ground truth corrected: swapped {swaps} (check_landmarks)")
    print("\n".join(study.table_lines(summ)))
    s = summ.get(args.mode, {})
    print(f"{s.get('seen', {}).get('n', 0)} seen, {s.get('propagated', {}).get('n', 0)} "
          f"propagated ({s.get('n_reached', 0)} reached), {s.get('camera', {}).get('n', 0)} "
          f"camera views scored -> {out}")
    if args.curve:
        caps = _int_list(args.curve, "--curve")
        recs = study.views_curve(path, caps, robots=robots or None, method=args.method,
                                 mode=args.mode, prior=args.prior, combine=args.combine,
                                 min_travel=args.min_travel, max_gap=args.max_gap,
                                 temper=args.temper, spread_views=args.spread_views,
                                 fix_landmarks=not args.no_fix_landmarks, seed=args.seed,
                                 distances=args.distances,
                                 sigma_distance_ratio=args.sigma_distance_ratio)
        study.write_curve(out, recs, figures=not args.no_figures)
        for line in study.curve_lines(recs):
            print(line)
    return 0
