"""experiments/joint/joint_odometry_stretches.py: the stretch statistic z^2 is checked against its own
distribution. On poses drawn from the odometry model with small noise the first-order covariance
is exact enough that z^2 is chi-square with 3 degrees of freedom (median 2.366, 1 % beyond 11.34)
over short and longer stretches; a model whose steps are noisier than it says is seen."""

from __future__ import annotations

import numpy as np
from _experiments import load_experiment

from qfg import joint

CHI2_3_MEDIAN = 2.366


def _module():
    return load_experiment("joint/joint_odometry_stretches")


def _run(rng, n=300, sigma=(0.004, 0.002, 0.01)):
    u = np.column_stack([rng.uniform(0.02, 0.1, n - 1), rng.normal(0, 0.005, n - 1),
                         rng.normal(0, 0.05, n - 1)])
    return joint.RobotRun(robot=1, times=np.arange(n, dtype=float), bearing_pose=np.zeros(0, int),
                          bearing_landmark=np.zeros(0, int), bearing=np.zeros(0),
                          sigma_bearing=0.01, odometry=u,
                          odometry_sigma=np.tile(np.asarray(sigma, float), (n - 1, 1)))


def test_stretches_of_the_model_s_own_draws_are_chi_square_and_a_wider_truth_is_seen():
    mod = _module()
    rng = np.random.default_rng(0)
    runs = [_run(rng) for _ in range(12)]
    for n in (1, 10, 40):
        z2 = np.concatenate([mod.stretch_z2(r, mod.model_poses(r, rng), np.ones(r.n_poses, bool),
                                            n) for r in runs])
        assert abs(np.median(z2) - CHI2_3_MEDIAN) < 0.35, (n, np.median(z2))
        assert np.mean(z2 > mod.CHI2_3_99) < 0.03, n
    # the same steps, the truth drawn with twice the noise the model assumes: z^2 about 4x
    said, wider = _run(np.random.default_rng(7)), _run(np.random.default_rng(7),
                                                         sigma=(0.008, 0.004, 0.02))
    z2 = mod.stretch_z2(said, mod.model_poses(wider, rng), np.ones(said.n_poses, bool), 10)
    assert np.median(z2) > 2.5 * CHI2_3_MEDIAN, np.median(z2)
