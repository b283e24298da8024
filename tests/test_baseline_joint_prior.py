"""The baseline under the prior of the whole configuration (``joint_samples``, qfg/solvers/baseline.py).

A world prior couples C and the cameras through their common frame; the product of per-point
priors counts the small-|AB| penalty of a far camera once per view. Checked against the exact
posterior of the same model (the reference solver without headings) on a tight triplet seen
from afar, and against a prior that is a product (where the correction must vanish exactly).
"""

import numpy as np
import pytest

from qfg.geometry import bearing
from qfg.partitions import get as get_partition
from qfg.priors import WindowPrior, WorldBoxPrior
from qfg.solvers import solve_triplet
from qfg.solvers.baseline import joint_correction, start, step
from qfg.solvers.common import input as _input
from qfg.solvers.common import options as _options
from qfg.solvers.common import seeds as _seeds


def _far_views(C, cams, sigma, seed):
    """Bearings [phi_A, phi_B, phi_C] (n, 3) of A = (0, 0), B = (0, 1), C from cameras (n, 2)
    looking at A, with normal noise ``sigma``."""
    rng = np.random.default_rng(seed)
    L = np.array([[0.0, 0.0], [0.0, 1.0], C])
    out = []
    for x in cams:
        pose = np.array([x[0], x[1], np.arctan2(-x[1], -x[0])])
        out.append(bearing(pose[None, :], L)[0] + sigma * rng.standard_normal(3))
    return np.array(out)


#: C beside A and B, three cameras 5-9 |AB| away on one side: the bearings say little about
#: C's depth, so the prior over the cameras' distance decides much of the answer.
CASES = (
    (np.array([-0.9, 0.9]), np.array([[7.0, 4.0], [5.5, 3.5], [4.5, 3.0]]), 0),
    (np.array([-0.6, 0.5]), np.array([[-8.0, -2.0], [-7.0, -2.5], [-5.5, -2.0]]), 1),
)
ARENA = WorldBoxPrior(width=4.0, height=7.5, n_rho=32)


@pytest.fixture(scope="module")
def references():
    out = []
    sb = np.deg2rad(0.5)
    for C, cams, seed in CASES:
        b = _far_views(C, cams, sb, seed)
        ref = solve_triplet(b, method="reference", prior=ARENA, sigma_bearing=sb, seed=0,
                            n_samples=4000)
        out.append((b, sb, ref.landmark))
    return out


#: States of C far from A and B in the AB frame (EDC: y >= 1 far from B, y < 0 far from A):
#: where C sits when the cameras stand far away.
FAR = [0, 1, 18, 19]


def test_joint_prior_is_nearer_the_exact_posterior_than_the_product(references):
    """On tight triplets seen from 5-9 |AB| the baseline under the whole configuration's prior
    agrees with the exact posterior (the reference under the same prior, no headings; its own
    Monte Carlo error is a total variation of 0.1-0.15 between seeds here): C far from A and B
    gets the reference's mass (0.28-0.39) within 0.15, and the total variation is 0.17 on
    average. The product of per-point priors pulls the cameras, and C with them, toward A and B:
    under a tenth of the reference's far mass, a total variation of about 0.4."""
    tv_joint, tv_prod = [], []
    for b, sb, ref in references:
        kw = dict(method="baseline", prior=ARENA, sigma_bearing=sb, seed=1,
                  n_landmark_samples=2048)
        joint = solve_triplet(b, **kw).landmark
        prod = solve_triplet(b, joint_samples=0, **kw).landmark
        assert ref[FAR].sum() > 0.2
        assert abs(joint[FAR].sum() - ref[FAR].sum()) < 0.15, (joint[FAR], ref[FAR])
        assert prod[FAR].sum() < 0.1 * ref[FAR].sum(), (prod[FAR], ref[FAR])
        tv_joint.append(0.5 * np.abs(joint - ref).sum())
        tv_prod.append(0.5 * np.abs(prod - ref).sum())
    assert np.mean(tv_joint) < 0.22, tv_joint
    assert np.mean(tv_prod) > np.mean(tv_joint) + 0.15, (tv_joint, tv_prod)


def test_a_product_prior_needs_no_correction():
    """Independent points uniform in a window: the joint density is the product of the
    per-point ones, so the correction is exactly 0 and the answer that of ``joint_samples=0``."""
    win = WindowPrior((-12.0, 12.0, -12.0, 12.0))
    b = _far_views(np.array([-0.9, 0.9]), np.array([[7.0, 4.0], [5.5, 3.5]]), 0.01, 3)
    kw = dict(method="baseline", prior=win, sigma_bearing=0.01, seed=2, n_landmark_samples=512)
    a = solve_triplet(b, **kw)
    c = solve_triplet(b, joint_samples=0, **kw)
    np.testing.assert_allclose(a.landmark, c.landmark, atol=1e-12)
    np.testing.assert_allclose(a.cameras, c.cameras, atol=0.05)

    opts = _options.resolve_options("baseline", {"prior": win, "n_landmark_samples": 256})
    meas = _input.measurements(b, None, 0.01, 0.0)
    st = start(meas, _seeds.root_seed(0), opts, get_partition("edc"))
    st = step(st, b[1])
    corr, picks, w = joint_correction(st, 8)
    alive = np.isfinite(st.lw)
    np.testing.assert_allclose(corr[alive], 0.0, atol=1e-12)
    assert set(picks) == {0, 1} and picks[0].shape == (256, 8, 3)
    np.testing.assert_allclose(w[alive].sum(axis=1), 1.0)


def test_joint_samples_option_is_checked():
    with pytest.raises(ValueError, match="joint_samples"):
        solve_triplet(np.zeros((2, 3)) + [0.1, 0.3, 0.2], method="baseline", sigma_bearing=0.01,
                      joint_samples=-1)
