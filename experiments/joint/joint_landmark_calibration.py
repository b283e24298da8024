"""Are the joint map's landmark positions calibrated? (docs/joint.md, "The landmarks' positions")

For each MRCLAM dataset (ground truth fixed as the mrclam study fixes it), the default joint map
(`joint_map.mrclam_runs`, `joint.solve`, seed 0), its landmarks' gauge-free means and covariances
(`joint.landmark_moments`, 2,000 samples), mapped onto the landmarks' ground truth by the best
similarity (`joint.aligned_errors`); per landmark the squared Mahalanobis distance z^2 of the
truth (chi-square with 2 dof for a calibrated map: median 1.39, 95 % under 5.99). Printed as
a table row: the landmarks in the map, the median error and the median standard deviation along
the ellipse's major axis (cm), the median z^2, how many truths lie inside their 95 % ellipse,
the robots' scatter about the map (`post.info["overdispersion"]`, no ground truth) and how many
lie inside the ellipse widened by it. ``--calibrated``: the bearings first corrected by each
robot's bias and scale measured on dataset 6 (`qfg.datasets.mrclam.DEFAULT_BEARING_CALIBRATION`).

Run from the repository root (MRCLAM data: ``--root DIR`` or ``$QFG_MRCLAM_DIR``)::

    python experiments/joint/joint_landmark_calibration.py 6 1 2 3 4 5
    python experiments/joint/joint_landmark_calibration.py 6 1 2 3 4 --calibrated
"""

from __future__ import annotations

import argparse

import numpy as np

from qfg import joint
from qfg.datasets import mrclam as data
from qfg.datasets.mrclam.joint_map import mrclam_runs
from qfg.harness.studies.mrclam import prepare

CHI2_95 = 5.991464547107979


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("datasets", nargs="+", type=int)
    ap.add_argument("--calibrated", action="store_true")
    ap.add_argument("--root", default=None,
                    help="directory holding the MRCLAM_Dataset* directories (default: $QFG_MRCLAM_DIR)")
    a = ap.parse_args(argv)
    try:
        root = data.data_root(a.root)
    except ValueError:
        ap.error("--root: no MRCLAM data directory; pass --root DIR or set QFG_MRCLAM_DIR")
    print("| dataset | bearings | landmarks | error median (cm) | sd median (cm) | z^2 median | "
          "inside 95 % | robots' scatter | inside, widened by it | map already widened |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for d in a.datasets:
        ds, _ = prepare(root / f"MRCLAM_Dataset{d}")
        if a.calibrated:
            ds = data.calibrate_bearings(ds, data.DEFAULT_BEARING_CALIBRATION)
        post = joint.solve(mrclam_runs(ds), seed=0)
        mu, cov = joint.landmark_moments(post, 2000, 0)
        truth = ds.landmark_position(list(post.landmark_ids))
        ok = np.isfinite(mu).all(axis=1)
        err, C, z2, _ = joint.aligned_errors(mu[ok], cov[ok], truth[ok])
        kappa = float(post.info.get("overdispersion", np.nan))
        scale = float(post.info.get("covariance_scale", 1.0))
        print(f"| {d} | {'calibrated' if a.calibrated else 'as recorded'} | {int(ok.sum())} | "
              f"{100 * np.median(np.hypot(*err.T)):.1f} | "
              f"{100 * np.median(np.sqrt(np.linalg.eigvalsh(C)[:, 1])):.1f} | "
              f"{np.median(z2):.2f} | {int((z2 <= CHI2_95).sum())} | {kappa:.2f} | "
              f"{int((z2 <= CHI2_95 * kappa).sum())} | "
              f"{'x' + format(scale, '.2f') if scale != 1 else 'no'} |", flush=True)


if __name__ == "__main__":
    main()
