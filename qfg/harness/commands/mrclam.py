"""``qfg mrclam PATH``: the MRCLAM study on one dataset directory (paper section 6d)."""

from __future__ import annotations


def _int_list(text: str) -> list[int]:
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"--robots: expected comma-separated robot numbers, got {text!r}") from None


def register(sub):
    p = sub.add_parser("mrclam", help="solve, map, propagate and score one MRCLAM dataset",
                       description="Every triplet history of the dataset solved, histories of one "
                                   "ordered triplet combined, the full qualitative map propagated, "
                                   "everything scored against the landmark ground truth "
                                   "(docs/results/mrclam.md).")
    p.add_argument("path", help="an MRCLAM_DatasetN directory")
    p.add_argument("--robots", default="", help="comma-separated robot numbers (default: all)")
    p.add_argument("--method", default="fast", choices=("fast", "full", "baseline"),
                   help="single-triplet solver (robots without odometry: baseline; default fast)")
    p.add_argument("--combine", default="product", choices=("product", "mean", "best"),
                   help="how several histories of one ordered triplet combine (default product)")
    p.add_argument("--tensor", default=None,
                   help="composition tensor .npz (default: the shipped tensor of the partition)")
    p.add_argument("--no-fix-landmarks", action="store_true",
                   help="score against the landmark ground truth as shipped (no swap check)")
    p.add_argument("--seed", type=int, default=0, help="solver seed (default 0)")
    p.add_argument("--output", default=None, help="output directory (default results/mrclam-<name>)")
    p.add_argument("--no-figures", action="store_true", help="skip the figures")
    p.set_defaults(func=_main)


def _main(args):
    from pathlib import Path

    from qfg.harness.studies import mrclam as study

    robots = _int_list(args.robots)
    T = study._load_tensor("edc", args.tensor) if args.tensor else None
    rows, det = study.run_dataset(args.path, robots=robots or None, method=args.method,
                                  combine=args.combine, tensor=T,
                                  fix_landmarks=not args.no_fix_landmarks, seed=args.seed,
                                  return_details=True)
    out = Path(args.output or f"results/mrclam-{Path(args.path).name}")
    summ = study.write_outputs(out, rows, figures=not args.no_figures,
                               figure_robot=robots[0] if robots else None, details=det)
    if det["swaps"]:
        print(f"landmark ground truth corrected: swapped {det['swaps']} (check_landmarks)")
    print("\n".join(study.table_lines(summ)))
    print(f"{summ['n_triplets']} triplets ({summ['n_seen']} seen, {summ['n_propagated']} "
          f"propagated, {summ['n_reached']} reached) -> {out}")
    return 0
