"""Does a slowly varying odometry error explain the joint map's camera misses? (docs/joint.md,
"What it does not do"; a prototype outside the library.)

One robot of MRCLAM dataset 6 is localised against the landmarks of the default joint map (held
fixed: their error is centimetres), its keyframes and the views of its histories as poses, with
two odometry models:

* ``independent``: the joint map's own (``BetweenFactorPose2`` per step, ``ODOMETRY_NOISE``);
* ``drift``: each step ``X_k^-1 X_k+1 = u_k Exp(d_k beta_k) + noise`` with the same noise and a
  drift rate ``beta`` (per metre travelled; x, y, heading) that walks from step to step,
  ``beta_k+1 - beta_k ~ N(0, q^2 d_k)`` per component, ``beta_0 ~ N(0, q0^2)`` (GTSAM
  ``CustomFactor``s: the ternary odometry factor and the walk).

Printed per model: the camera poses' position error against motion capture (after the
landmarks' best similarity), the share of poses whose error is beyond the 99 % ellipse of their
marginal covariance (position, 2 dof: z^2 > 9.21), and the camera states of the robot's
histories: mean log p(truth) and truth under 1 % (from 300 samples of each pose's marginal).
Then, for every robot, the default map's keyframe poses against motion capture: the mean offset
along and across the heading (m, across positive to the left), and the median position error
with the capture's clock shifted by -1 ... +1 s.

    python experiments/joint/joint_odometry_drift.py --robot 1 --q 0.05 0.2 1.0 --q0 0.2

Run from the repository root as above (MRCLAM data: ``$QFG_MRCLAM_DIR`` or ``--data DIR``).
"""

from __future__ import annotations

import argparse

import gtsam
import numpy as np

from qfg import joint
from qfg.combine import prior_state_distribution
from qfg.datasets.mrclam.joint_map import mrclam_runs
from qfg.geometry import to_frame
from qfg.harness.studies import mrclam as study
from qfg.joint.start import apply_similarity, similarity
from qfg.partitions import get as get_partition

PX = 1_000_000  # keys: poses k, drift rates PX + k, landmarks 2 PX + j


def _ternary(u, d):
    u = gtsam.Pose2(*u)

    def error(this, values, H):
        ka, kb, kr = this.keys()
        Xa, Xb, beta = values.atPose2(ka), values.atPose2(kb), values.atVector(kr)
        He = np.zeros((3, 3), order="F")
        B = gtsam.Pose2.Expmap(d * beta, He)
        Hu, Hb = np.zeros((3, 3), order="F"), np.zeros((3, 3), order="F")
        m = u.compose(B, Hu, Hb)
        H1, H2 = np.zeros((3, 3), order="F"), np.zeros((3, 3), order="F")
        r = Xa.between(Xb, H1, H2)
        Hm, Hr = np.zeros((3, 3), order="F"), np.zeros((3, 3), order="F")
        dd = m.between(r, Hm, Hr)
        HL = np.zeros((3, 3), order="F")
        e = gtsam.Pose2.Logmap(dd, HL)
        if H is not None:
            H[0] = HL @ Hr @ H1
            H[1] = HL @ Hr @ H2
            H[2] = HL @ Hm @ Hb @ He * d
        return e
    return error


def _walk(this, values, H):
    a, b = this.keys()
    if H is not None:
        H[0] = -np.eye(3)
        H[1] = np.eye(3)
    return values.atVector(b) - values.atVector(a)


def localise(run, points, landmark_ids, X0, *, drift_q=None, q0=0.05):
    """Poses (P, 3) and their marginal covariances (P, 3, 3) of ``run`` against fixed ``points``."""
    g = gtsam.NonlinearFactorGraph()
    v = gtsam.Values()
    col = {int(x): j for j, x in enumerate(landmark_ids)}
    for j, p in enumerate(points):
        if np.isfinite(p).all():
            g.add(gtsam.PriorFactorPoint2(2 * PX + j, p, gtsam.noiseModel.Isotropic.Sigma(2, 1e-4)))
            v.insert(2 * PX + j, p)
    huber = gtsam.noiseModel.mEstimator.Huber.Create(1.345)
    for i, lm, b in zip(run.bearing_pose.tolist(), run.bearing_landmark.tolist(),
                        run.bearing.tolist(), strict=True):
        j = col[int(lm)]
        if np.isfinite(points[j]).all():
            n = gtsam.noiseModel.Robust.Create(
                huber, gtsam.noiseModel.Isotropic.Sigma(1, run.sigma_bearing))
            g.add(gtsam.BearingFactor2D(i, 2 * PX + j, gtsam.Rot2(b), n))
    d = np.hypot(run.odometry[:, 0], run.odometry[:, 1])
    for k, (u, s) in enumerate(zip(run.odometry, run.odometry_sigma, strict=True)):
        n = gtsam.noiseModel.Diagonal.Sigmas(np.asarray(s, float))
        if drift_q is None:
            g.add(gtsam.BetweenFactorPose2(k, k + 1, gtsam.Pose2(*u), n))
        else:
            g.add(gtsam.CustomFactor(n, [k, k + 1, PX + k], _ternary(u, float(d[k]))))
            if k + 1 < len(run.odometry):
                w = gtsam.noiseModel.Isotropic.Sigma(3, drift_q * np.sqrt(d[k] + 1e-4))
                g.add(gtsam.CustomFactor(w, [PX + k, PX + k + 1], _walk))
            v.insert(PX + k, np.zeros(3))
    if drift_q is not None:
        g.add(gtsam.PriorFactorVector(PX, np.zeros(3), gtsam.noiseModel.Isotropic.Sigma(3, q0)))
    for k, x in enumerate(X0):
        v.insert(k, gtsam.Pose2(*x))
    res = gtsam.LevenbergMarquardtOptimizer(g, v).optimize()
    marg = gtsam.Marginals(g, res)
    X = np.array([[res.atPose2(k).x(), res.atPose2(k).y(), res.atPose2(k).theta()]
                  for k in range(run.n_poses)])
    C = np.array([marg.marginalCovariance(k) for k in range(run.n_poses)])
    return X, C


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", type=int, default=1)
    ap.add_argument("--q", type=float, nargs="+", default=[0.05])
    ap.add_argument("--q0", type=float, default=0.05)
    ap.add_argument("--data", default="")
    a = ap.parse_args(argv)
    part = get_partition("edc")
    ds, _ = study.prepare(study.dataset_dirs(a.data, [6])[0])
    pr = study.make_prior(ds, "arena")
    qx = prior_state_distribution(pr, part, point=1, n_cameras=1, samples=study.PRIOR_SAMPLES,
                                  seed=2)
    rh = study.histories(ds, [a.robot], mode="honest", spread_views=3, partition=part,
                         min_travel=0.02, max_gap=120.0)
    hs = [h for _, h in rh]
    keep = {a.robot: {float(t) for h in hs for t in h.views}}
    meas = mrclam_runs(ds, keep_times=keep)
    post = joint.solve(meas, seed=0)
    run = meas.run(a.robot)
    P = post.modes[0].points
    # the landmarks' best similarity onto the ground truth (states are similarity-free)
    ok = np.isfinite(P[:, 0])
    sc, R, t0 = similarity(P[ok], ds.landmark_xy[ok])
    gt, gok = ds.robot(a.robot).groundtruth_poses(run.times)
    X0 = post.poses[a.robot]
    idx_l = {int(x): j for j, x in enumerate(ds.landmark_ids)}
    rng = np.random.default_rng(0)
    print("| model | q | position error median / p90 (m) | beyond the 99 % ellipse | "
          "cameras: log p(truth) | truth < 1 % |")
    print("|---|---|---|---|---|---|")
    for q in [None, *a.q]:
        X, C = localise(run, P, ds.landmark_ids, X0, drift_q=q, q0=a.q0)
        W = apply_similarity(X[:, :2], (sc, R, t0))
        err = (W - gt[:, :2])[gok]
        Cw = (R @ C[:, :2, :2] @ R.T * sc ** 2)[gok]
        z2 = np.einsum("ni,nij,nj->n", err, np.linalg.inv(Cw), err)
        lp, under = [], []
        for h in hs:
            g = np.asarray(h.truth.camera_states)
            pi = np.searchsorted(run.times, np.asarray(h.views, float))
            ia, ib = idx_l[int(h.landmarks[0])], idx_l[int(h.landmarks[1])]
            for v, k in enumerate(pi.tolist()):
                if g[v] < 0:
                    continue
                xs = rng.multivariate_normal(X[k, :2], C[k, :2, :2], 300)
                s = part.state_of(to_frame(xs, P[ia], P[ib]))
                p = np.bincount(s[s >= 0], minlength=part.n_states)[:part.n_states] / 300
                p = 0.999 * p + 0.001 * qx
                lp.append(np.log(max(p[g[v]], 1e-4)))
                under.append(p[g[v]] < 0.01)
        e = np.hypot(*err.T)
        print(f"| {'independent' if q is None else 'drift'} | {'' if q is None else q} | "
              f"{np.median(e):.3f} / {np.percentile(e, 90):.3f} | {100 * np.mean(z2 > 9.21):.1f} % | "
              f"{np.mean(lp):.2f} | {100 * np.mean(under):.1f} % |", flush=True)
    print("\n| robot | along (mean) | across (mean) | median error at clock shift -1, -0.5, "
          "-0.25, 0, 0.25, 0.5, 1 s |")
    print("|---|---|---|---|")
    for r in meas.runs:
        Wr = apply_similarity(post.poses[r.robot][:, :2], (sc, R, t0))
        med = []
        for dt in (-1.0, -0.5, -0.25, 0.0, 0.25, 0.5, 1.0):
            g2, k2 = ds.robot(r.robot).groundtruth_poses(r.times + dt)
            med.append(f"{np.median(np.hypot(*(Wr - g2[:, :2])[k2].T)):.3f}")
        g0, k0 = ds.robot(r.robot).groundtruth_poses(r.times)
        e0, th = (Wr - g0[:, :2])[k0], g0[k0, 2]
        along = e0[:, 0] * np.cos(th) + e0[:, 1] * np.sin(th)
        across = -e0[:, 0] * np.sin(th) + e0[:, 1] * np.cos(th)
        print(f"| {r.robot} | {along.mean():+.3f} | {across.mean():+.3f} | {', '.join(med)} |",
              flush=True)


if __name__ == "__main__":
    main()
