"""Online composition (qfg.composition.online) against brute force, on random tensors."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qfg import composition as qc


def _random_tensor(rng, m, density=0.3):
    T = rng.random((m, m, m)) * (rng.random((m, m, m)) < density)
    T[0, 0, 0] += 1e-3  # never all zero
    return T / T.sum()


def _brute_marginal(T, V, role):
    """P(s_role) by explicit loops over (i, j, k): sum of V1(i) V2(j) V3(k) T(i, j, k)."""
    m = T.shape[0]
    out = np.zeros(m)
    for i, j, k in itertools.product(range(m), repeat=3):
        w = T[i, j, k]
        for r, s in zip((1, 2, 3), (i, j, k), strict=True):
            if V[r - 1] is not None:
                w *= V[r - 1][s]
        out[(i, j, k)[role - 1]] += w
    return out / out.sum() if out.sum() > 0 else None


@settings(max_examples=40, deadline=None)
@given(m=st.integers(2, 6), F=st.integers(1, 4), seed=st.integers(0, 2**31 - 1),
       role=st.sampled_from([1, 2, 3]), with_own=st.booleans())
def test_marginal_equals_brute_force(m, F, seed, role, with_own):
    rng = np.random.default_rng(seed)
    T = _random_tensor(rng, m)
    V = [rng.random((F, m)) for _ in range(3)]
    if not with_own:
        V[role - 1] = None
    r = qc.marginal(T, *V, role=role)
    assert r.p.shape == (F, m) and r.zero_mass.shape == (F,)
    for f in range(F):
        want = _brute_marginal(T, [None if v is None else v[f] for v in V], role)
        if want is None:
            assert r.zero_mass[f] and np.allclose(r.p[f], 1 / m)
        else:
            assert not r.zero_mass[f]
            np.testing.assert_allclose(r.p[f], want, rtol=1e-10, atol=1e-14)


@settings(max_examples=25, deadline=None)
@given(m=st.integers(2, 5), seed=st.integers(0, 2**31 - 1))
def test_joint_equals_brute_force_and_marginalizes(m, seed):
    rng = np.random.default_rng(seed)
    T = _random_tensor(rng, m)
    V = [rng.random(m) for _ in range(3)]
    J = qc.joint(T, *V)
    want = np.zeros((m, m, m))
    for i, j, k in itertools.product(range(m), repeat=3):
        want[i, j, k] = V[0][i] * V[1][j] * V[2][k] * T[i, j, k]
    np.testing.assert_allclose(J.p, want / want.sum(), rtol=1e-10, atol=1e-15)
    for role in (1, 2, 3):
        axes = tuple(a for a in range(3) if a != role - 1)
        np.testing.assert_allclose(qc.marginal(T, *V, role=role).p, J.p.sum(axis=axes),
                                   rtol=1e-10, atol=1e-15)


def test_batched_rows_equal_single_calls():
    rng = np.random.default_rng(1)
    T = _random_tensor(rng, 7)
    V1, V2 = rng.random((50, 7)), rng.random(7)  # one batched, one shared vector
    r = qc.marginal(T, V1, V2, role=3)
    assert r.p.shape == (50, 7)
    for f in (0, 17, 49):
        np.testing.assert_allclose(r.p[f], qc.marginal(T, V1[f], V2, role=3).p, rtol=1e-12)


def test_deterministic_and_feasible_match_support_brute_force():
    rng = np.random.default_rng(2)
    m = 5
    T = _random_tensor(rng, m, density=0.2)
    S1, S2 = rng.random((30, m)) < 0.4, rng.random((30, m)) < 0.4
    fz = qc.feasible(T, S1, S2, role=3)
    det = qc.marginal(T, S1.astype(float), S2.astype(float), role=3, deterministic=True)
    for f in range(30):
        want = np.array([any(S1[f, i] and S2[f, j] and T[i, j, k] > 0
                             for i in range(m) for j in range(m)) for k in range(m)])
        if want.any():
            assert not fz.zero_mass[f]
            np.testing.assert_array_equal(fz.states[f], want)
            np.testing.assert_array_equal(det.p[f] > 0, want)
        else:
            assert fz.zero_mass[f] and fz.states[f].all()


def test_zero_mass_gives_uniform_with_flag_and_no_nan():
    T = np.zeros((3, 3, 3))
    T[0, 0, 0] = 1.0
    with np.errstate(all="raise"):
        r = qc.marginal(T, [0, 1, 0], [1, 0, 0], role=3)
        J = qc.joint(T, [0, 1, 0])
    assert bool(r.zero_mass) and np.allclose(r.p, 1 / 3)
    assert bool(J.zero_mass) and np.allclose(J.p, 1 / 27)
    r2 = qc.marginal(T, [1, 0, 0], [1, 0, 0], role=3)
    assert not bool(r2.zero_mass) and r2.p.tolist() == [1.0, 0.0, 0.0]


@pytest.mark.parametrize("kwargs, match", [
    ({"V1": np.ones(4), "V2": np.ones(3)}, "V1"),
    ({"V1": np.ones(3), "V2": -np.ones(3)}, "V2"),
    ({"V1": np.ones(3), "V2": [np.nan, 1, 1]}, "V2"),
    ({"V1": np.ones(3)}, "V2"),
    ({"V1": np.ones((2, 3)), "V2": np.ones((5, 3))}, "V2"),
    ({"V1": np.ones(3), "V2": np.ones(3), "role": 4}, "role"),
])
def test_bad_input_names_the_argument(kwargs, match):
    T = np.ones((3, 3, 3)) / 27
    with pytest.raises(ValueError, match=match):
        qc.marginal(T, **kwargs)


@pytest.mark.parametrize("T, match", [(np.ones((3, 3)), "shape"), (-np.ones((2, 2, 2)), "negative"),
                                      (np.zeros((2, 2, 2)), "zero")])
def test_bad_tensor_rejected(T, match):
    with pytest.raises(ValueError, match=match):
        qc.marginal(T, np.ones(T.shape[0]), np.ones(T.shape[0]))


# ------------------------------------------------------------------------------------------
# numeric range (issue 12 items 1-3)


@pytest.mark.parametrize("scale", [1e308, 1e200, 1e-200, 1e-300])
def test_scaled_inputs_give_the_normalized_answer(scale):
    # V and c V describe the same distribution: the answer must not depend on c (1e308 gave NaN,
    # 1e-200 was flagged zero_mass). Reference: the same vectors normalized, by brute force.
    rng = np.random.default_rng(5)
    m = 5
    T = _random_tensor(rng, m, density=0.6)
    V = [rng.random(m) for _ in range(3)]
    V[1][2] = 0.0
    scaled = [v / v.max() * scale for v in V]
    with np.errstate(all="raise"):
        for role in (1, 2, 3):
            r = qc.marginal(T, *scaled, role=role)
            assert not bool(r.zero_mass)
            np.testing.assert_allclose(r.p, _brute_marginal(T, V, role), rtol=1e-10, atol=1e-15)
        J = qc.joint(T, *scaled)
    want = np.einsum("i,j,k,ijk->ijk", *V, T)
    assert not bool(J.zero_mass)
    np.testing.assert_allclose(J.p, want / want.sum(), rtol=1e-10, atol=1e-15)


def test_uniform_and_one_hot_extremes_of_the_issue():
    T = np.ones((4, 4, 4)) / 64
    for v in (np.full(4, 1e308), np.full(4, 1e-200)):
        r = qc.marginal(T, v, v)
        assert not bool(r.zero_mass) and np.allclose(r.p, 0.25)
        J = qc.joint(T, v, v, v)
        assert not bool(J.zero_mass) and np.allclose(J.p, 1 / 64)
    one_hot = np.eye(4)[1] * 5e-324  # the smallest positive double
    r = qc.marginal(T, one_hot, one_hot, one_hot)
    assert not bool(r.zero_mass) and r.p.tolist() == [0.0, 1.0, 0.0, 0.0]
    J = qc.joint(T, one_hot, one_hot, one_hot)
    assert not bool(J.zero_mass) and J.p[1, 1, 1] == 1.0
    # a table with tiny entries is rescaled too
    r = qc.marginal(T * 1e-300, np.ones(4), np.ones(4))
    assert not bool(r.zero_mass) and np.allclose(r.p, 0.25)


def test_empty_batch_gives_empty_results():
    T = np.ones((3, 3, 3)) / 27
    r = qc.marginal(T, np.zeros((0, 3)), np.full(3, 1 / 3))
    assert r.p.shape == (0, 3) and r.zero_mass.shape == (0,)
    r = qc.marginal(T, np.zeros((0, 3)), np.ones((1, 3)), np.zeros((0, 3)), role=2)
    assert r.p.shape == (0, 3)
    J = qc.joint(T, np.zeros((0, 3)))
    assert J.p.shape == (0, 3, 3, 3) and J.zero_mass.shape == (0,)
    f = qc.feasible(T, np.zeros((0, 3), bool), np.ones(3, bool))
    assert f.states.shape == (0, 3)
    with pytest.raises(ValueError, match="V2"):  # 0 rows do not broadcast with 2 rows
        qc.marginal(T, np.zeros((0, 3)), np.ones((2, 3)))
