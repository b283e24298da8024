"""The solvers' fast elementwise helpers (:mod:`qfg.solvers.common.arcs`) against the plain formulas
they replace: numpy's sine and cosine, :func:`qfg.geometry.wrap_angle`, and the locus circle's
ray intersection and change of variables of :mod:`qfg.geometry` and
:func:`qfg.solvers.common.arcs.log_ray_jacobian`."""

from __future__ import annotations

import numpy as np

from qfg.geometry import locus_circle, ray_circle_intersection, wrap_angle
from qfg.solvers.common import arcs as _arcs


def test_cos_sin_equal_numpy_to_rounding():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.uniform(-30.0, 30.0, 200_000), rng.normal(0.0, 1e-3, 1000),
                        [0.0, -0.0, 1e-300, np.pi, -np.pi, np.pi / 2, -np.pi / 2, 2 * np.pi,
                         3 * np.pi, np.nextafter(np.pi, 0.0)]])
    c, s = _arcs.cos_sin(x)
    assert np.max(np.abs(c - np.cos(x))) <= 4.5e-16
    assert np.max(np.abs(s - np.sin(x))) <= 4.5e-16
    with np.errstate(invalid="ignore"):
        c, s = _arcs.cos_sin(np.array([np.nan, np.inf]))
    assert np.all(np.isnan(c)) and np.all(np.isnan(s))


def test_wrap_equals_wrap_angle_to_rounding():
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.uniform(-40.0, 40.0, 200_000), [0.0, 1e-300, 2 * np.pi, -7.0]])
    w = _arcs.wrap(x)
    assert np.all(np.abs(w) <= np.pi)
    d = np.abs(w - wrap_angle(x))
    # equal but at the two ends of the range (-pi and pi: the same angle)
    assert np.all((d <= 1e-14) | (np.abs(d - 2 * np.pi) <= 1e-14))
    assert np.max(np.abs(np.cos(w) - np.cos(wrap_angle(x)))) <= 1e-14


def _rays(rng, n):
    O = rng.uniform(-4.0, 4.0, (n, 2))
    th = rng.uniform(-10.0, 10.0, n)
    pa = rng.uniform(-np.pi, np.pi, n)
    pb = pa + rng.uniform(-3.2, 3.2, n)
    pb[:20] = pa[:20]                                   # degenerate circles: no point
    return O, th, pa, pb


def test_ray_locus_equals_ray_circle_intersection_on_the_locus_circle():
    rng = np.random.default_rng(2)
    O, th, pa, pb = _rays(rng, 100_000)
    pts, ok, (ux, uy) = _arcs.ray_locus(O, th, pa, pb)
    circ = locus_circle(pa, pb)
    ref, ref_ok = ray_circle_intersection(O, th, circ.center, circ.radius, circ.side)
    # the same points where the ray does not (nearly) graze the circle
    q = O - circ.center
    b = np.cos(th) * q[:, 0] + np.sin(th) * q[:, 1]
    disc = b * b - (np.sum(q * q, axis=1) - np.where(np.isfinite(circ.radius),
                                                    circ.radius, 0.0) ** 2)
    clear = np.abs(disc) > 1e-8 * np.maximum(1.0, b * b)
    assert np.array_equal(ok[clear], ref_ok[clear])
    assert np.max(np.abs(pts - ref)[clear]) < 1e-9
    assert ok.sum() > 10_000 and not ok[:20].any()
    assert np.all(pts[~ok] == np.repeat(O[:, None, :], 2, axis=1)[~ok])
    assert np.max(np.abs(ux - np.cos(th))) < 1e-15 and np.max(np.abs(uy - np.sin(th))) < 1e-15


def test_log_ray_jacobian_u_equals_log_ray_jacobian():
    rng = np.random.default_rng(3)
    O, th, pa, pb = _rays(rng, 50_000)
    pts, ok, (ux, uy) = _arcs.ray_locus(O, th, pa, pb)
    j, k = np.nonzero(ok)
    X = pts[j, k]
    got = _arcs.log_ray_jacobian_u(X, O[j], ux[j], uy[j])
    ref = _arcs.log_ray_jacobian(X, O[j], th[j])
    fin = np.isfinite(ref)
    assert np.array_equal(np.isfinite(got), fin) and fin.mean() > 0.99
    assert np.max(np.abs(got - ref)[fin]) < 1e-9
    # a ray starting on its point (t = 0) has none
    assert _arcs.log_ray_jacobian_u(X[:1], X[:1], ux[j[:1]], uy[j[:1]])[0] == -np.inf


def test_segment_max_equals_maximum_at():
    from qfg.solvers.sis.resampling import segment_max

    rng = np.random.default_rng(4)
    for _ in range(300):
        T, n = int(rng.integers(1, 8)), int(rng.integers(0, 30))
        tid = np.sort(rng.integers(0, T, n))
        x = rng.normal(size=n)
        x[rng.random(n) < 0.2] = -np.inf
        for t, v in ((tid, x), (tid[::-1].copy(), x[::-1].copy())):     # sorted, and not
            ref = np.full(T, -np.inf)
            np.maximum.at(ref, t, v)
            assert np.array_equal(segment_max(t, v, T), ref)
            base = rng.normal(size=T)
            ref = base.copy()
            np.maximum.at(ref, t, v)
            assert np.array_equal(segment_max(t, v, T, out=base), ref)


def test_logaddexp_equals_numpy():
    from qfg.solvers.common.likelihood import logaddexp

    rng = np.random.default_rng(5)
    a, b = rng.normal(0.0, 30.0, (2, 100_000))
    special = np.array([-np.inf, np.inf, 0.0, -745.0, 700.0])
    a = np.concatenate([a, np.repeat(special, 5)])
    b = np.concatenate([b, np.tile(special, 5)])
    with np.errstate(invalid="ignore"):
        ref = np.logaddexp(a, b)
    got = logaddexp(a, b)
    assert np.array_equal(np.isfinite(got), np.isfinite(ref))
    assert np.array_equal(got[~np.isfinite(ref)], ref[~np.isfinite(ref)])
    fin = np.isfinite(ref)
    assert np.max(np.abs(got[fin] - ref[fin]) / np.maximum(1.0, np.abs(ref[fin]))) < 1e-15
    assert np.isnan(logaddexp(np.nan, 1.0))


def test_logsumexp_over_a_few_columns_equals_the_reduction():
    from qfg.solvers.common.likelihood import logsumexp

    rng = np.random.default_rng(6)
    for k in range(1, 10):
        a = rng.normal(0.0, 5.0, (500, k))
        a[rng.random(a.shape) < 0.2] = -np.inf
        mx = np.max(a, axis=1, keepdims=True)
        ok = np.isfinite(mx)
        with np.errstate(divide="ignore"):
            ref = np.where(ok, mx + np.log(np.sum(np.exp(a - np.where(ok, mx, 0.0)), axis=1,
                                                  keepdims=True)), -np.inf)[:, 0]
        got = logsumexp(a, axis=1)
        assert np.array_equal(got, ref) if k < 8 else np.allclose(got, ref, rtol=1e-15)


def test_weighted_state_errors_equal_the_delta_method_per_sample():
    """The batched Monte Carlo error of the finish step against the delta-method sum written
    out per group and state: sqrt(sum_i w_i^2 (1[s_i = s] - p_s)^2), the largest over s."""
    from qfg.solvers.common.histograms import weighted_state_errors
    rng = np.random.default_rng(3)
    G, m = 6, 5
    g = np.sort(rng.integers(0, G - 1, 400))                    # group G - 1 stays empty
    s = rng.integers(0, m, g.size)
    w = rng.random(g.size) ** 3
    w[g == 2] = 0.0                                              # a group of zero weights
    tot = np.bincount(g, weights=w, minlength=G)
    w = np.where(tot[g] > 0, w / np.where(tot > 0, tot, 1.0)[g], 0.0)
    got = weighted_state_errors(s, w, g, G, m)
    for k in range(G):
        wk, sk = w[g == k], s[g == k]
        if not np.any(wk > 0):
            assert np.isnan(got[k])
            continue
        p = [wk[sk == j].sum() for j in range(m)]
        want = max(np.sqrt(sum(wi * wi * ((si == j) - p[j]) ** 2
                               for wi, si in zip(wk, sk, strict=True))) for j in range(m))
        assert abs(got[k] - want) < 1e-12
