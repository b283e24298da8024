"""``python -m qfg.datasets.mrclam``: per-robot summaries, quirk counts, checks and noise."""

from __future__ import annotations

import sys

import numpy as np

from ._checks import bearing_residuals, check_landmarks, landmark_fixes, odometry_check, swap_landmarks
from ._constants import DATA_ENV, DEFAULT_MAX_GAP, DEFAULT_MIN_INTERVAL, DEFAULT_MIN_TRAVEL, DEFAULT_VIEW_GAP
from ._data import MRCLAMDataset
from ._histories import history_counts, summary_rows
from ._io import DataFormatError
from ._load import data_root, find_datasets, load

QUIRK_COLUMNS = ("measurement_rows", "views", "merged_stamps", "max_view_span", "repeated_views",
                 "duplicate_landmarks", "robot_rows", "unknown_rows", "unknown_barcodes",
                 "measurements_out_of_order", "odometry_out_of_order", "odometry_duplicate_stamps",
                 "views_outside_odometry", "groundtruth_rows", "groundtruth_out_of_order",
                 "groundtruth_duplicate_stamps", "views_outside_groundtruth",
                 "empty_measurement_files")


def quirk_table(datasets) -> str:
    """A markdown table of :meth:`LoadReport.totals` per dataset (``max_view_span`` in ms)."""
    lines = ["| dataset | " + " | ".join(QUIRK_COLUMNS) + " |", "|---" * (len(QUIRK_COLUMNS) + 1) + "|"]
    for ds in datasets:
        t = ds.report.totals()
        cells = []
        for c in QUIRK_COLUMNS:
            v = t[c]
            cells.append(f"{1000 * v:.0f}" if c == "max_view_span" else
                         " ".join(map(str, v)) if isinstance(v, tuple) else str(v))
        lines.append(f"| {ds.name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python -m qfg.datasets.mrclam",
                                 description="Per-robot summary of MRCLAM dataset directories.")
    ap.add_argument("paths", nargs="*",
                    help=f"dataset directories (MRCLAM_DatasetN) or a directory holding them "
                         f"(default: ${DATA_ENV})")
    ap.add_argument("--view-gap", type=float, default=DEFAULT_VIEW_GAP,
                    help="rows within this many seconds form one view (default %(default)s)")
    ap.add_argument("--min-views", type=int, default=3)
    ap.add_argument("--max-gap", type=float, default=DEFAULT_MAX_GAP)
    ap.add_argument("--min-travel", type=float, default=DEFAULT_MIN_TRAVEL)
    ap.add_argument("--min-interval", type=float, default=DEFAULT_MIN_INTERVAL)
    ap.add_argument("--max-views", type=int, default=None)
    ap.add_argument("--keep-repeated", action="store_true",
                    help="keep views that repeat the view before in histories")
    ap.add_argument("--quirks", action="store_true",
                    help="print what the loader found and did, per dataset")
    ap.add_argument("--check", action="store_true",
                    help="also check the data: landmark identities, bearing residuals, odometry drift")
    ap.add_argument("--noise", action="store_true",
                    help="measure the noise against motion capture (datasets with ground truth)")
    ap.add_argument("--calibration", action="store_true",
                    help="measure each robot's bearing calibration (bias, scale) against motion "
                         "capture (datasets with ground truth)")
    a = ap.parse_args(argv)
    try:
        roots = a.paths or [data_root()]
        paths = [d for r in roots for d in find_datasets(r)]
        datasets = [load(p, view_gap=a.view_gap) for p in paths]
    except (DataFormatError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    opts = dict(min_views=a.min_views, max_gap=a.max_gap, min_travel=a.min_travel,
                min_interval=a.min_interval, max_views=a.max_views,
                drop_repeated=not a.keep_repeated)
    cols = ["dataset", "robot", "has_odometry", "measurements", "landmark", "robot_meas", "unknown",
            "repeated_views", "views", "views_3plus", "triplets_raw", "triplets", "segments",
            "histories"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for ds in datasets:
        rows = summary_rows(ds, **opts)
        for r in rows:
            print("| " + " | ".join(str(r[c]) for c in cols) + " |")
        tot = history_counts(ds, **opts)["all"]
        print(f"| {ds.name} | all | | | | | | | {tot['views']} | {tot['views_3plus']} | "
              f"{tot['triplets_raw']} (distinct {tot['distinct_triplets_raw']}) | "
              f"{tot['triplets']} (distinct {tot['distinct_triplets']}) | "
              f"{tot['segments']} | {tot['histories']} |")
    if a.quirks:
        print()
        print(quirk_table(datasets))
        for ds in datasets:
            print(ds.report.describe())
    if a.check:
        for ds in datasets:
            _print_check(ds)
    if a.noise:
        from ._noise import measure_noise, noise_table

        with_gt = [ds for ds in datasets if any(rd.has_groundtruth for rd in ds.robots.values())]
        if not with_gt:
            print("\nno dataset with robot ground truth (RobotN_Groundtruth): no noise measured")
        for ds in with_gt:
            print()
            print(noise_table(measure_noise(ds)))
    if a.calibration:
        from ._calibration import measure_bearing_calibration

        for ds in datasets:
            if not any(rd.has_groundtruth for rd in ds.robots.values()):
                continue
            print(f"\n{ds.name}: bearing calibration, measured = bias + (1 + scale) captured")
            print("| robot | rows | bias (deg) | scale |\n|---|---|---|---|")
            for n, (b, sc, k) in measure_bearing_calibration(ds).items():
                print(f"| {n} | {k} | {np.rad2deg(b):+.3f} | {sc:+.4f} |")
    return 0


def _rng_str(vals, fmt="{:.2f}") -> str:
    vals = [v for v in vals if v is not None]
    return (fmt + ".." + fmt).format(min(vals), max(vals)) if vals else "-"


def _print_check(ds: MRCLAMDataset) -> None:
    rds = list(ds.robots.values())
    odo = [rd.odometry for rd in rds if rd.odometry is not None]
    span = _rng_str([np.ptp(rd.time) for rd in rds], "{:.0f}")
    gap = _rng_str([np.median(np.diff(rd.view_times)) for rd in rds])
    rich = _rng_str([100 * np.mean(rd.visible.sum(axis=1) >= 3) for rd in rds], "{:.1f}")
    lo, hi = _rng_str([rd.bearing.min() for rd in rds]), _rng_str([rd.bearing.max() for rd in rds])
    print(f"\n{ds.name}: measurement span per robot {span} s; median time between views {gap} s; "
          f"views with >= 3 landmarks {rich}%; bearings min {lo}, max {hi} rad")
    if odo:
        firsts = [rd.time[0] - rd.odometry.time[0] for rd in rds if rd.odometry is not None]
        lasts = [rd.odometry.time[-1] - rd.time[-1] for rd in rds if rd.odometry is not None]
        print(f"  odometry: median record interval "
              f"{_rng_str([np.median(np.diff(o.time)) for o in odo], '{:.3f}')} s, max gap "
              f"{_rng_str([o.max_gap for o in odo])} s, v min {_rng_str([o.v.min() for o in odo])} "
              f"max {_rng_str([o.v.max() for o in odo])} m/s, omega min "
              f"{_rng_str([o.omega.min() for o in odo])} max {_rng_str([o.omega.max() for o in odo])}"
              f" rad/s; starts {_rng_str(firsts)} s before the first measurement, ends "
              f"{_rng_str(lasts, '{:.3f}')} s after the last")
    chk = check_landmarks(ds)
    print(f"  landmark check: swaps {list(chk.swaps)}; distance of each landmark's "
          f"measured position to its ground truth (m): median {np.median(chk.error):.2f}, "
          f"max {chk.error.max():.2f} (subject {int(chk.landmark_ids[np.argmax(chk.error)])})")
    fixed = swap_landmarks(ds, chk.swaps)
    if chk.swaps:
        chk2 = check_landmarks(fixed)
        print(f"  after swapping {list(chk.swaps)}: swaps {list(chk2.swaps)}; median "
              f"{np.median(chk2.error):.2f} m, max {chk2.error.max():.2f} m")
    res_m = np.concatenate([landmark_fixes(fixed, n, min_landmarks=4).residual for n in ds.robots])
    print(f"  fix residual (>= 4 landmarks) median {np.median(res_m):.3f} m")
    res = np.degrees(np.concatenate([bearing_residuals(fixed, n) for n in ds.robots]))
    if res.size:
        mad = 1.4826 * np.median(np.abs(res - np.median(res)))
        print(f"  bearing residuals at fixes with >= 4 landmarks (after swaps): n {res.size}, "
              f"std {res.std():.2f} deg, robust std {mad:.2f} deg, mean {res.mean():.2f} deg")
    pooled: dict = {}
    for n in ds.robots:
        for row in odometry_check(fixed, n):
            pooled.setdefault((row["lo"], row["hi"]), []).append(row)
    for (lo, hi), rows in pooled.items():
        tot = sum(r["n"] for r in rows)
        meds = [r["median_abs_deg"] for r in rows if r["n"]]
        p90s = [r["p90_abs_deg"] for r in rows if r["n"]]
        if tot:
            print(f"  odometry turn error vs fixes, pairs {lo:g}-{hi:g} s apart: n {tot}, median |err| "
                  f"per robot {min(meds):.1f}-{max(meds):.1f} deg, 90th pct {min(p90s):.1f}-"
                  f"{max(p90s):.1f} deg")


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(_main())
