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
