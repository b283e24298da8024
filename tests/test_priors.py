"""Priors against simulated worlds (histograms), closed forms and symmetries."""

import numpy as np
import pytest
from scipy import stats
from scipy.stats import qmc

from qfg import priors
from qfg.simulation import SimulationConfig, random_triplet_history

MID = np.array([0.0, 0.5])


def test_defaults_match_the_simulator():
    cfg = SimulationConfig()
    p = priors.get("world")
    assert isinstance(p, priors.WorldBoxPrior)
    assert p.width == cfg.xlim[1] - cfg.xlim[0] and p.height == cfg.ylim[1] - cfg.ylim[0]
    assert p.d_min == cfg.min_distance


def test_k1_marginal_matches_histogram_of_simulated_worlds():
    # 8 x 8 cells on [-2, 2] x [-1.5, 2.5]; expected cell masses by a 16 x 16 midpoint rule of the
    # density (its error is far below the counting noise: 1e-4 relative, measured with 64 x 64)
    p = priors.get("world")
    x = p.sample(np.random.default_rng(11), n_cameras=0, size=200_000)[:, 0]
    edges_x, edges_y = np.linspace(-2, 2, 9), np.linspace(-1.5, 2.5, 9)
    obs, _, _ = np.histogram2d(x[:, 0], x[:, 1], bins=(edges_x, edges_y))
    f = 16
    gx = edges_x[0] + (np.arange(8 * f) + 0.5) * (4 / (8 * f))
    gy = edges_y[0] + (np.arange(8 * f) + 0.5) * (4 / (8 * f))
    G = np.stack(np.meshgrid(gx, gy, indexing="ij"), axis=-1)[:, :, None, :]
    dens = np.exp(p.log_density(G)) * (4 / (8 * f)) ** 2
    E = dens.reshape(8, f, 8, f).sum(axis=(1, 3))
    n = obs.sum()
    # the density is normalized: the cells' mass equals the fraction of draws that fall in them
    assert E.sum() == pytest.approx(n / x.shape[0], rel=0.01)
    Eexp = E / E.sum() * n
    chi2 = float(np.sum((obs - Eexp) ** 2 / Eexp))
    assert chi2 < stats.chi2.ppf(1 - 1e-3, 63), chi2
    # the approximate product prior (a fit of this marginal) is rejected on the same data
    Pd = np.exp(priors.ProductPrior().log_density(G)).reshape(8, f, 8, f).sum(axis=(1, 3))
    Pexp = Pd / Pd.sum() * n
    assert float(np.sum((obs - Pexp) ** 2 / Pexp)) > stats.chi2.ppf(1 - 1e-9, 63)


def _cells(x, R=2.0):
    r = np.linalg.norm(x - MID, axis=-1)
    inside = np.all(r < R, axis=-1)
    rb = np.minimum((r / R * 3).astype(int), 2)
    same = (np.sign(x[..., 0, 0]) == np.sign(x[..., 1, 0])).astype(int)
    return inside, rb[..., 0] * 6 + rb[..., 1] * 2 + same


def _expected_cells(prior, seeds, m=2**13, R=2.0):
    """Cell masses of the joint (C, X) in the disk pair, by scrambled Sobol quadrature; one
    estimate per seed so that their spread gives the quadrature's standard error."""
    est = []
    for s in seeds:
        u = qmc.Sobol(4, seed=s).random(m)
        r, th = R * np.sqrt(u[:, :2]), 2 * np.pi * u[:, 2:]
        X = MID + np.stack([r * np.cos(th), r * np.sin(th)], axis=-1)
        w = np.exp(prior.log_density(X))
        _, c = _cells(X, R)
        e = np.bincount(c, weights=w, minlength=18)
        est.append(e / e.sum())
    est = np.array(est)
    return est.mean(axis=0), est.std(axis=0, ddof=1) / np.sqrt(len(seeds))


def _cell_z(samples, prior):
    """(18,) z-scores of the (C, X) cell counts of ``samples`` (N, 2, 2) against ``prior``'s
    cell masses (:func:`_expected_cells`)."""
    inside, c = _cells(samples)
    obs = np.bincount(c[inside], minlength=18)
    n = obs.sum()
    E, se = _expected_cells(prior, seeds=range(6))
    return (obs / n - E) / np.sqrt(E * (1 - E) / n + se**2)


def test_k2_joint_matches_histogram_of_simulated_worlds():
    # C and one camera: cells = radial bin of each (3 x 3) x same side of AB or not. The coupling
    # through AB's scale is what the product prior misses.
    p = priors.get("world")
    S = p.sample(np.random.default_rng(12), n_cameras=1, size=200_000)
    z = _cell_z(S, p)
    assert np.max(np.abs(z)) < 4.0, z          # 18 cells: P(max |z| > 4) ~ 1e-3
    assert np.max(np.abs(_cell_z(S, priors.ProductPrior()))) > 20


@pytest.mark.parametrize("k", [1, 2])
def test_normalized(k):
    # E_q[p / q] = 1 for the proposal q = the product prior (same |x|^-4 tails, bounded ratio)
    q = priors.ProductPrior()
    x = q.sample(np.random.default_rng(k), n_cameras=k - 1, size=40_000)
    w = np.exp(priors.get("world").log_density(x) - q.log_density(x))
    se = w.std() / np.sqrt(w.size)
    assert abs(w.mean() - 1) < 4 * se + 1e-3, (w.mean(), se)


def test_triplet_histories_come_from_the_prior():
    # the simulator's own triplets vs the prior's sampler, compared on the log density statistic
    p = priors.get("world")
    rng = np.random.default_rng(13)
    hist = [random_triplet_history(rng, n_views=2) for _ in range(1500)]
    conf = np.array([np.vstack([h.truth.C_ab, h.truth.poses_ab[:, :2]]) for h in hist])
    ref = p.sample(np.random.default_rng(14), n_cameras=2, size=4000)
    for stat in (lambda a: p.log_density(a), lambda a: np.linalg.norm(a[:, 0] - a[:, 1], axis=-1)):
        assert stats.ks_2samp(stat(conf), stat(ref)).pvalue > 1e-3


def test_symmetries_and_exchangeability():
    p = priors.get("world")
    x = p.sample(np.random.default_rng(3), n_cameras=3, size=200)
    ref = p.log_density(x)
    mirror = x * [-1, 1]                          # reflection in line AB
    swap = np.array([0.0, 1.0]) - x * [1, 1]      # A <-> B: point reflection about (0, 1/2)
    swap_mirror = x * [1, -1] + [0.0, 1.0]        # reflection in the perpendicular bisector
    perm = x[:, ::-1]
    for y in (mirror, swap, swap_mirror, perm):
        np.testing.assert_allclose(p.log_density(y), ref, rtol=0, atol=1e-9)


def test_quadrature_and_chunking():
    x = priors.get("world").sample(np.random.default_rng(4), n_cameras=2, size=300)
    a = priors.WorldBoxPrior(n_rho=128).log_density(x)
    b = priors.WorldBoxPrior(n_rho=2048).log_density(x)
    assert np.max(np.abs(a - b)) < 3e-3
    old = priors.box._CHUNK_ELEMENTS
    try:
        priors.box._CHUNK_ELEMENTS = 1000
        np.testing.assert_array_equal(priors.WorldBoxPrior(n_rho=128).log_density(x), a)
    finally:
        priors.box._CHUNK_ELEMENTS = old
    assert priors.WorldBoxPrior().log_density(x.reshape(3, 100, 3, 2)).shape == (3, 100)


def test_zero_density_only_where_truly_zero():
    p = priors.get("world")
    with np.errstate(over="raise", invalid="raise"):
        v = p.log_density(np.array([[[1e6, 1e6]], [[0.0, 0.0]], [[0.0, 1.0 + 1e-4]],
                                    [[0.0, 300.0]], [[0.0, 0.5]], [[0.0, -3.0]]]))
    # too spread to fit in the box at a scale that keeps d_min / closer than d_min to A or B at
    # any admissible scale / collinear with AB but fine
    assert np.isneginf(v[:3]).all() and np.isfinite(v[3:]).all()
    free = priors.WorldBoxPrior(d_min=0.0)
    with np.errstate(over="raise", invalid="raise"):
        w = free.log_density(np.array([[[1e8, -1e8], [0.0, 0.0]], [[0.3, 0.3], [0.3, 0.3]]]))
    assert np.isfinite(w).all()
    assert not np.isnan(p.log_density(np.full((2, 2), 1e300))).any()


def test_window_and_product_priors():
    rng = np.random.default_rng(5)
    wp = priors.WindowPrior((-1.0, 2.0, 0.0, 1.0))
    s = wp.sample(rng, 2, 1000)
    assert s.shape == (1000, 3, 2) and np.all(np.isfinite(wp.log_density(s)))
    assert wp.log_density(s)[0] == pytest.approx(-3 * np.log(3.0))
    pp = priors.ProductPrior(scale=0.85)
    r = np.linalg.norm(pp.sample(rng, 0, 20_000)[:, 0] - MID, axis=-1)
    assert stats.kstest(r, lambda t: t**2 / (0.85**2 + t**2)).pvalue > 1e-3
    # the density integrates to 1 (polar: 2 pi r p(r) dr)
    t = np.linspace(0, 2000, 400_001)
    d = np.exp(pp.log_density(np.stack([np.zeros_like(t), 0.5 + t], -1)[:, None, :]))
    assert np.trapezoid(2 * np.pi * t * d, t) == pytest.approx(1.0, abs=1e-3)


def test_get_and_custom_prior():
    assert priors.get("world-product").name == "world-product"
    assert priors.get("uniform").window == priors.DEFAULT_WINDOW
    p = priors.WorldBoxPrior(width=10, height=10)
    assert priors.get(p) is p
    for bad in ("arc", "nope", 3):
        with pytest.raises(ValueError, match="prior"):
            priors.get(bad)
    c = priors.CallablePrior(lambda x: -np.sum(x**2, axis=(-2, -1)))
    assert c.log_density(np.zeros((4, 2, 2))).shape == (4,)
    with pytest.raises(ValueError, match="sample_fn"):
        c.sample(np.random.default_rng(0), 1, 3)
    bad_shape = priors.CallablePrior(lambda x: np.zeros(3))
    with pytest.raises(ValueError, match="log_density_fn"):
        bad_shape.log_density(np.zeros((4, 2, 2)))
    ok = priors.CallablePrior(lambda x: np.zeros(x.shape[:-2]),
                              lambda rng, n, size: rng.random((size, n + 1, 2)))
    assert ok.sample(np.random.default_rng(0), 2, 5).shape == (5, 3, 2)


def test_bad_input():
    p = priors.get("world")
    with pytest.raises(ValueError, match="points"):
        p.log_density(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="points"):
        p.log_density([[np.nan, 0.0]])
    with pytest.raises(ValueError, match="n_rho"):
        priors.WorldBoxPrior(n_rho=127)
    with pytest.raises(ValueError, match="window"):
        priors.WindowPrior((1.0, 0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="n_cameras"):
        p.sample(np.random.default_rng(0), -1, 3)


# ------------------------------------------------------------------ issue 18 item 11
@pytest.mark.parametrize("make, name", [
    (lambda: priors.ProductPrior(scale=1e200), r"scale: expected a length in \[1e-100, 1e\+100\]"),
    (lambda: priors.ProductPrior(scale=1e-200), r"scale: expected a length in \[1e-100"),
    (lambda: priors.ProductPrior(scale=0.0), "scale"),
    (lambda: priors.WorldBoxPrior(width=1e308, height=1e308), r"width: expected a length in"),
    (lambda: priors.WorldBoxPrior(width=6.0, height=1e308), r"height: expected a length in"),
    (lambda: priors.WorldBoxPrior(width=1e-6, height=1.0, d_min=0.0), r"width: .*\[0.001"),
    (lambda: priors.WorldBoxPrior(d_min=6.5), r"d_min: expected a number in \[0, 6\)"),
    (lambda: priors.WorldBoxPrior(n_rho=10**6), r"n_rho: expected an even integer in \[4, 4096\]"),
    (lambda: priors.WindowPrior((-1e308, 1e308, -1e308, 1e308)), r"window: .*±1e\+100"),
    (lambda: priors.WindowPrior((0.0, 1e-200, 0.0, 1e-200)), r"window: expected sides >= 1e-100"),
    (lambda: priors.WindowPrior((0.0, 1e4, 0.0, 1.0)), r"window: expected an aspect ratio"),
])
def test_extreme_prior_parameters_are_refused_at_construction(make, name):
    with pytest.raises(ValueError, match=name):
        make()


def test_priors_at_the_edges_of_their_ranges_stay_finite():
    # the accepted ranges are where the math holds: at their edges, log densities of the prior's
    # own draws are finite (no overflow, no NaN) and a solver runs
    from qfg.simulation import random_triplet_history
    from qfg.solvers import solve_triplet

    edge = [priors.ProductPrior(1e100), priors.ProductPrior(1e-100),
            priors.WorldBoxPrior(width=1e100, height=1e100), priors.WorldBoxPrior(1e-3, 1e-3, 0.0),
            priors.WorldBoxPrior(n_rho=4096),
            priors.WindowPrior((-1e100, 1e100, -1e100, 1e100)),
            priors.WindowPrior((0.0, 1e-100, 0.0, 1e-100)), priors.WindowPrior((0.0, 1e3, 0.0, 1.0))]
    rng = np.random.default_rng(0)
    for p in edge:
        x = p.sample(rng, n_cameras=2, size=4)
        assert np.all(np.isfinite(x)), p
        assert np.all(np.isfinite(p.log_density(x))), p
    h = random_triplet_history(np.random.default_rng(1), 2, np.deg2rad(2), np.deg2rad(5))
    for p in (priors.ProductPrior(1e100), priors.WindowPrior((-1e100, 1e100, -1e100, 1e100))):
        for method in ("fast", "baseline"):
            est = solve_triplet(h, method=method, prior=p, seed=0)
            assert np.all(np.isfinite(est.landmark)) and abs(est.landmark.sum() - 1) < 1e-9


def test_pair_scale_prior_matches_its_sampler():
    # scale_power=-2 (|AB| log-uniform): the density against draws of its own generative model,
    # in radial bins of C over two decades of |AB| (where the power of s matters) and in the
    # joint (C, X) cells of the i.i.d. test above
    p = priors.WorldBoxPrior(width=4.0, height=8.0, d_min=0.01, scale_power=-2, n_rho=32)
    x = p.sample(np.random.default_rng(21), n_cameras=0, size=100_000)[:, 0]
    edges = np.array([0.25, 0.5, 1, 2, 4, 8, 16, 32])
    obs = np.histogram(np.linalg.norm(x, axis=1), edges)[0]
    rr = np.exp(np.linspace(np.log(edges[0]), np.log(edges[-1]), 701))
    rc = np.sqrt(rr[1:] * rr[:-1])
    th = np.linspace(-np.pi, np.pi, 360, endpoint=False)
    R, T = np.meshgrid(rc, th, indexing="ij")
    G = np.stack([R * np.cos(T), R * np.sin(T)], -1).reshape(-1, 1, 2)
    f = np.exp(p.log_density(G)).reshape(R.shape) * R ** 2     # dA = r^2 dlog r dtheta
    mass = f.sum(axis=1) * (th[1] - th[0]) * np.log(rr[1] / rr[0])
    E = np.array([mass[(rc >= a) & (rc < b)].sum() for a, b in
                  zip(edges[:-1], edges[1:], strict=True)])
    n = obs.sum()
    Eexp = E / E.sum() * n
    assert float(np.sum((obs - Eexp) ** 2 / Eexp)) < stats.chi2.ppf(1 - 1e-3, 6)
    # the i.i.d. box puts C within a few |AB|; the pair-scale prior spreads it over the decades
    iid = priors.WorldBoxPrior(width=4.0, height=8.0, d_min=0.01, n_rho=32)
    E0 = np.exp(iid.log_density(G)).reshape(R.shape) * R ** 2
    m0 = E0.sum(axis=1)
    assert m0[rc > 8].sum() / m0.sum() < 0.1 < mass[rc > 8].sum() / mass.sum()
    z = _cell_z(p.sample(np.random.default_rng(22), n_cameras=1, size=200_000), p)
    assert np.max(np.abs(z)) < 4.0, z


def test_pair_scale_prior_parameters():
    p = priors.WorldBoxPrior(width=4.0, height=8.0, d_min=0.01, scale_power=-2)
    q = p.replace(n_rho=16)
    assert (q.width, q.height, q.d_min, q.n_rho, q.scale_power) == (4.0, 8.0, 0.01, 16, -2)
    assert "scale_power=-2" in repr(q) and "scale_power" not in repr(priors.WorldBoxPrior())
    for bad in (-3, 3, 0.5, True):
        with pytest.raises(ValueError, match="scale_power: expected an integer"):
            priors.WorldBoxPrior(scale_power=bad)
    with pytest.raises(ValueError, match="needs d_min > 0"):
        priors.WorldBoxPrior(d_min=0.0, scale_power=-1)
    with pytest.raises(ValueError, match="not a WorldBoxPrior parameter"):
        p.replace(depth=2)
    # configuration inference draws every landmark i.i.d.: a pair-scale prior is refused
    from qfg.configurations import infer_configurations, summarize_position

    with pytest.raises(ValueError, match="pair-scale prior"):
        infer_configurations({(0, 1, 2): np.full(20, 1 / 20)}, prior=p)
    # a per-triplet summary divides by this triplet's prior: it takes it
    xy = np.random.default_rng(0).normal([3.0, 0.5], 0.1, size=(200, 2))
    s0 = summarize_position((xy, np.full(200, 1 / 200)), prior=p.replace(scale_power=0))
    s2 = summarize_position((xy, np.full(200, 1 / 200)), prior=p)
    assert np.allclose(s2.centres, s0.centres) and not np.allclose(s2.log_weights, s0.log_weights)


@pytest.mark.parametrize("kw", [{}, {"scale_power": -2}, {"width": 4.0, "height": 9.0,
                                                          "d_min": 0.3, "n_rho": 16}])
def test_extended_density_equals_the_stacked_configurations(kw):
    """A point added to a shared base (the solvers' C draws per trajectory, a child's camera
    per parent) gives the density of the stacked configuration: every base size, scales from
    1e-3 to 40 |AB|, points closer than d_min (-inf in both), a point far outside the base's
    scale (the configuration's rescaling)."""
    p = priors.WorldBoxPrior(**kw)
    rng = np.random.default_rng(5)
    for k in (0, 1, 3):
        U, r = 7, 3
        base = rng.normal(size=(U, k, 2)) * rng.choice([1e-3, 1.0, 30.0], (U, 1, 1))
        rows = np.repeat(np.arange(U), r)
        extra = rng.normal(size=(U * r, 2)) * rng.choice([0.5, 5.0, 40.0], (U * r, 1))
        if k:
            extra[0] = base[0, 0] + 1e-9                         # on a base point
        extra[1] = [0.0, 1.0 + 1e-9]                             # on B
        got = p.log_density_extended(base, extra, rows)
        want = p.log_density(np.concatenate([base[rows], extra[:, None]], axis=1))
        fin = np.isfinite(want)
        np.testing.assert_array_equal(np.isfinite(got), fin)
        np.testing.assert_allclose(got[fin], want[fin], rtol=1e-10, atol=1e-9)
        # r points per base row, grouped: the same numbers
        grouped = p.log_density_extended(base, extra.reshape(U, r, 2)).ravel()
        np.testing.assert_array_equal(np.isfinite(grouped), fin)
        np.testing.assert_allclose(grouped[fin], want[fin], rtol=1e-10, atol=1e-9)
        if kw.get("d_min", 0.01) > 0:
            assert not fin[1] and (k == 0 or not fin[0])
        assert fin.sum() >= 4                                   # something to compare


def test_extended_density_bad_input():
    p = priors.WorldBoxPrior()
    with pytest.raises(ValueError, match="rows"):
        p.log_density_extended(np.zeros((2, 1, 2)), np.ones((3, 2)), [0, 1, 2])
    with pytest.raises(ValueError, match="base"):
        p.log_density_extended(np.zeros((1, 2)), np.ones((1, 2)))
    with pytest.raises(ValueError, match="extra"):
        p.log_density_extended(np.zeros((1, 1, 2)), np.ones((2, 1, 2)))   # 2 groups, 1 base row
    with pytest.raises(ValueError, match="extra"):
        p.log_density_extended(np.zeros((1, 1, 2)), np.ones((1, 1, 2)), [0])


@pytest.mark.parametrize("kw", [{}, {"width": 3.0, "height": 8.0, "d_min": 0.5},
                                {"d_min": 2.0, "scale_power": -1}])
def test_density_equals_its_double_integral(kw):
    """The closed-form inner integral against the docstring's double integral done by scipy's
    quad over the scale s and the rotation rho, from the rotated points' extents: prior =
    2 / (W H)^(k+2) ∫_0^π dρ ∫_{s0}^{s1} s^(2k+1+p) (W - s xr)(H - s yr) ds, including
    configurations where d_min's lower limit s0 cuts the interval (large d_min)."""
    from scipy import integrate

    p = priors.WorldBoxPrior(n_rho=4096, **kw)
    W, H, dmin = p.width, p.height, p.d_min
    rng = np.random.default_rng(8)
    finite = 0
    for k in (1, 2):
        for _ in range(3):
            q = rng.normal(size=(k, 2)) * rng.choice([0.3, 1.0, 3.0])
            pts = np.vstack([[0.0, 0.0], [0.0, 1.0], q])
            dist = [np.hypot(*(pts[i] - pts[j])) for i in range(k + 2) for j in range(i)]
            s0 = dmin / min(dist)
            a = 2 * k + 1 + p.scale_power

            def over_s(rho, pts=pts, s0=s0, a=a):
                c, s = np.cos(rho), np.sin(rho)
                x = pts[:, 0] * c - pts[:, 1] * s
                y = pts[:, 0] * s + pts[:, 1] * c
                xr, yr = np.ptp(x), np.ptp(y)
                s1 = min(W / xr if xr > 0 else np.inf, H / yr if yr > 0 else np.inf)
                if s1 <= s0:
                    return 0.0
                return integrate.quad(lambda t: t ** a * (W - t * xr) * (H - t * yr), s0, s1,
                                      epsabs=0, epsrel=1e-11)[0]

            # the extents have kinks where two points' projections cross (in x or in y)
            d = pts[:, None] - pts[None]
            kinks = np.mod(np.concatenate([np.arctan2(d[..., 0], d[..., 1]).ravel(),
                                           np.arctan2(-d[..., 1], d[..., 0]).ravel()]), np.pi)
            val = integrate.quad(over_s, 0.0, np.pi, points=np.unique(kinks)[1:-1], limit=400,
                                 epsabs=0, epsrel=1e-9)[0]
            got = p.log_density(q[None])[0]
            if val == 0.0:                      # no admissible scale at any rotation
                assert got == -np.inf
                continue
            finite += 1
            want = np.log(2.0 * val) - (k + 2) * np.log(W * H)
            assert abs(got - want) < 2e-5, (k, q, got, want)
    assert finite >= 4
