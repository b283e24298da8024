"""The model check with the cameras' residuals computed once per trajectory (``per_pose``, as the
SIS engine's final sample holds several C draws per trajectory) against the check of the
repeated poses."""

import numpy as np
import pytest

from qfg.solvers.sis import model_check as _model_check


@pytest.mark.parametrize("tail", [None, (0.1, 5.0, 0.01)])
def test_model_check_per_pose_equals_repeated_poses(tail):
    from qfg.solvers.common.likelihood import as_tail

    rng = np.random.default_rng(3)
    n, J, r = 3, 40, 4
    P = np.concatenate([rng.normal(size=(n, J, 2)) * 2, rng.uniform(-3, 3, (n, J, 1))], axis=2)
    L = rng.normal(size=(J * r, 2)) * 2
    b = rng.uniform(-np.pi, np.pi, (n, 3)) * 0.3
    w = rng.random(J * r)
    w[::7] = 0.0
    w /= w.sum()
    t = as_tail(tail)
    want = _model_check.posterior_predictive_p(b, [0.3, -0.2], np.repeat(P, r, axis=1), L, w,
                                               0.5, 0.4, t)
    got = _model_check.posterior_predictive_p(b, [0.3, -0.2], P, L, w, 0.5, 0.4, t, per_pose=r)
    assert 0 < want < 1
    assert got == pytest.approx(want, abs=1e-12)
