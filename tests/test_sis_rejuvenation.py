"""Resample-move rejuvenation of the full solver (issue 20, item 2): the measurement chart, the
Metropolis-Hastings sweeps' invariance, recovery from a deliberately collapsed start against the
reference solver, seeds, the 3-view answer, and the budget."""

from dataclasses import replace

import numpy as np
import pytest

from qfg.simulation import random_triplet_history
from qfg.solvers import DEFAULTS, TripletSolver, solve_triplet, solve_triplets
from qfg.solvers import budget as _budget
from qfg.solvers.sis import engine as _engine
from qfg.solvers.sis import moves as _moves
from qfg.solvers.sis import rejuvenation as _rejuvenation


def _history(seed, n):
    return random_triplet_history(np.random.default_rng(seed), n, np.deg2rad(2.0), np.deg2rad(5.0))


def _coords(P):
    a1, _, pa, pb, rh, br = _rejuvenation.chart_of(P)
    return a1, pa, pb, rh, br


@pytest.mark.parametrize("seed", range(6))
def test_chart_round_trip_reproduces_the_trajectory(seed):
    P = _history(500 + seed, 7).truth.poses_ab[None]
    a1, pa, pb, rh, br = _coords(P)
    Q, lj, ok = _rejuvenation.poses_of(a1, pa, pb, rh, br)
    assert ok[0] and np.isfinite(lj[0])
    np.testing.assert_allclose(Q, P, atol=1e-9)
    np.testing.assert_allclose(_rejuvenation.log_jacobian(P), lj, rtol=0, atol=1e-9)


def test_chart_jacobian_equals_finite_differences():
    # log |d(x, y, alpha) / d(a1, pa, pb, rh)| of the forward map against central differences
    for seed in (11, 12, 13):
        P = _history(seed, 3).truth.poses_ab[None]
        a1, pa, pb, rh, br = _coords(P)
        c0 = np.concatenate([a1, pa[0], pb[0], rh[0]])

        def f(c, br=br):
            Q = _rejuvenation.poses_of(c[:1], c[None, 1:4], c[None, 4:7], c[None, 7:], br)[0]
            return Q[0].ravel()

        h = 1e-6
        Jm = np.column_stack([(f(c0 + h * e) - f(c0 - h * e)) / (2 * h) for e in np.eye(9)])
        lj = _rejuvenation.poses_of(a1, pa, pb, rh, br)[1][0]
        assert abs(np.log(abs(np.linalg.det(Jm))) - lj) < 1e-4


def _gaussian_case(J=4000, sd=0.02, seed=3):
    """J exact draws of a Gaussian over poses about a true 4-view trajectory, and its log
    density (a target the sweeps must keep)."""
    P0 = _history(31, 4).truth.poses_ab
    rng = np.random.default_rng(seed)
    draws = P0 + sd * rng.standard_normal((J,) + P0.shape)

    def target(rows, Q):
        return -0.5 * np.sum(((Q - P0) / sd) ** 2, axis=(1, 2)), ()

    return P0, draws, target


@pytest.mark.parametrize("kinds", [("walk",), ("ridge",), ("noise",), ("walk", "ridge", "noise")])
def test_sweeps_keep_a_known_target(kinds):
    """Exact draws of a Gaussian over poses stay distributed as it after the sweeps: means
    within 5.5 standard errors (the largest of 12 coordinates), standard deviations within 6%.
    Wide enough (sd 0.2 |AB|) for the chart's Jacobian to matter: without it the noise
    proposals shift the means by 8-11 standard errors."""
    sd = 0.2
    P0, draws, target = _gaussian_case(sd=sd)
    J = draws.shape[0]
    tid = np.zeros(J, dtype=int)
    gens = [np.random.default_rng(7)]
    Q, lp, _ = _rejuvenation.sweeps(draws, tid, np.array([True]), target, target(None, draws),
                                    gens, 4, np.array([0.03]), np.array([0.09]), kinds)
    moved = np.mean(np.any(Q != draws, axis=(1, 2)))
    assert moved > 0.5
    np.testing.assert_allclose(lp, target(None, Q)[0])
    d = (Q - P0).reshape(J, -1)
    assert np.all(np.abs(d.mean(axis=0)) < 5.5 * sd / np.sqrt(J))
    assert np.all(np.abs(d.std(axis=0) / sd - 1) < 0.06)


def test_sweeps_bring_a_collapsed_start_back():
    """Every hypothesis started at one trajectory, the Gaussian's centre with camera 1 moved
    4 sd along its arc: the ridge and noise moves (the walk cannot: the collapsed covariance is
    zero) bring the mean back within a fraction of an sd and spread the hypotheses again."""
    sd = 0.02
    P0, draws, target = _gaussian_case(J=2000, sd=sd)
    start = np.repeat(P0[None], draws.shape[0], axis=0)
    a1, pa, pb, rh, br = _coords(start)
    start = _rejuvenation.poses_of(a1 + 4 * sd * abs(np.sin(pb[:, 0] - pa[:, 0])), pa, pb, rh,
                                   br)[0]
    off0 = np.abs(start[0] - P0).max()
    Q, _, _ = _rejuvenation.sweeps(start, np.zeros(start.shape[0], dtype=int), np.array([True]),
                                   target, target(None, start), [np.random.default_rng(5)], 40,
                                   np.array([0.03]), np.array([0.09]), ("ridge", "noise"))
    assert np.abs(Q.mean(axis=0) - P0).max() < 0.25 * sd < off0
    assert np.median(Q.std(axis=0)) > 0.5 * sd


def test_only_movable_triplets_move():
    P0, draws, target = _gaussian_case(J=200)
    tid = np.repeat([0, 1], 100)
    gens = [np.random.default_rng(1), np.random.default_rng(2)]
    Q, _, _ = _rejuvenation.sweeps(draws, tid, np.array([True, False]), target,
                                   target(None, draws), gens, 2, np.array([0.03, 0.03]),
                                   np.array([0.09, 0.09]))
    assert np.array_equal(Q[100:], draws[100:])
    assert np.any(Q[:100] != draws[:100])


def _solver_state(h, **opts):
    s = TripletSolver("full", sigma_bearing=h.sigma_bearing, sigma_heading=h.sigma_heading,
                      seed=4, **opts)
    for j in range(h.n_views):
        s.add_view(h.bearings[j], None if j == 0 else h.headings[j - 1])
    return s._state


def _collapsed(st, row):
    """``st`` with every hypothesis a copy of hypothesis ``row`` (flat levels)."""
    P = np.repeat(st.poses[row:row + 1], st.tid.size, axis=0)
    flat = tuple((P[:, t].copy(), np.arange(P.shape[0])) for t in range(P.shape[1]))
    pick = np.full(st.tid.size, row)
    return replace(st, levels=flat, lw_base=st.lw_base[pick], lp_x=st.lp_x[pick],
                   lw_c=st.lw_c[pick], c_sum=st.c_sum[pick])


def test_rejuvenation_recovers_from_a_collapsed_start_toward_the_reference():
    """A 4-view triplet whose exact posterior splits C between two states (reference solver:
    about 0.73 / 0.27): every hypothesis set to one trajectory of the minority state (the
    answer is then that state alone), 60 sweeps of rejuvenation's moves take the landmark
    distribution back to within 0.15 total variation of the reference."""
    h = _history(700001, 4)
    ref = solve_triplet(h, method="reference", seed=1).landmark
    st = _solver_state(h, max_hypotheses=1500)
    st = replace(st, opts={**st.opts, "rejuvenate": 60})
    has = np.flatnonzero(np.isfinite(st.c_sum[:, 0]))
    minority = int(np.argsort(ref)[-2])
    rows = has[st.part.state_of(st.c_sum[has, :2]) == minority]
    assert rows.size
    col = _collapsed(st, int(rows[0]))
    before = _engine.finish(col)[0][0].landmark
    moved = _moves._rejuvenate(col, np.array([True]), np.zeros(1))
    after = _engine.finish(moved)[0][0].landmark
    tv_before = 0.5 * np.abs(before - ref).sum()
    tv_after = 0.5 * np.abs(after - ref).sum()
    assert tv_before > 0.5
    assert tv_after < 0.15
    # the trajectories spread again
    assert np.unique(moved.poses[:, 0, 0]).size > 100


def test_three_views_are_unchanged_and_same_seed_same_answer():
    hs = [_history(800 + i, 3) for i in range(2)]
    a = solve_triplets(hs, method="full", seed=9)
    b = solve_triplets(hs, method="full", seed=9, rejuvenate=2)
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x.landmark, y.landmark)
    h5 = [_history(900 + i, 5) for i in range(2)]
    c = solve_triplets(h5, method="full", seed=9, rejuvenate=1, max_hypotheses=500)
    d = solve_triplets(h5, method="full", seed=9, rejuvenate=1, max_hypotheses=500)
    for x, y in zip(c, d, strict=True):
        assert np.array_equal(x.landmark, y.landmark)


def test_a_triplet_alone_and_in_a_batch_gives_the_same_answer():
    h5 = [_history(950 + i, 5) for i in range(2)]
    batch = solve_triplets(h5, method="full", seed=3, rejuvenate=1, max_hypotheses=400)
    for t, (h, e) in enumerate(zip(h5, batch, strict=True)):
        child = np.random.SeedSequence(3, spawn_key=(t,))
        alone = solve_triplet(h, method="full", seed=child, rejuvenate=1, max_hypotheses=400)
        np.testing.assert_allclose(alone.landmark, e.landmark, rtol=0, atol=1e-12)


def test_schedule_is_geometric_and_the_budget_stays_linear():
    assert _rejuvenation.schedule(70, 2.0) == [4, 8, 16, 32, 64]
    assert _rejuvenation.schedule(70) == [v for v in range(1, 71) if _rejuvenation.scheduled(v)]
    g = _rejuvenation.GROWTH
    assert all(_rejuvenation.work_views(n) <= g / (g - 1) * n + _rejuvenation.FIRST_VIEW
               for n in range(1, 500))
    opts = {**DEFAULTS["full"], "rejuvenate": 2}
    # doubling the views at most about doubles the work (the geometric schedule's steps and
    # the refit window add a little at these n; without rejuvenation 2.05-2.17)
    for n in (64, 128, 200):
        assert _budget.work_units("full", opts, 2 * n) / _budget.work_units("full", opts, n) < 2.4
    assert _budget.work_units("full", opts, 100) > _budget.work_units("full", DEFAULTS["full"], 100)
    with pytest.raises(ValueError, match="views"):
        _budget.check("full", opts, 1, 10_000)


class _NoJointPrior:
    """A prior whose single points have a density but whose configurations of more than one
    point have none: the rejuvenation's joint target is nowhere finite."""

    name = "no-joint"

    def log_density(self, points):
        p = np.asarray(points, dtype=float)
        out = -0.5 * np.sum(p * p, axis=(-2, -1)) / 25.0
        return out if p.shape[-2] == 1 else np.full(p.shape[:-2], -np.inf)

    def sample(self, seed, n_cameras, size):
        return 5.0 * np.random.default_rng(seed).standard_normal((size, 1 + n_cameras, 2))


def test_a_triplet_with_no_finite_target_is_left_as_it_was():
    from qfg.priors import Prior

    prior = type("NoJoint", (_NoJointPrior, Prior), {})()
    h = _history(61, 4)
    st = _solver_state(h, rejuvenate=0, max_hypotheses=300, prior=prior)
    st = replace(st, opts={**st.opts, "rejuvenate": 2})
    moved = _moves._rejuvenate(st, np.array([True]), np.zeros(1))
    np.testing.assert_array_equal(moved.poses, st.poses)
    for a in ("lw_base", "lw_c", "lp_x"):
        np.testing.assert_array_equal(getattr(moved, a), getattr(st, a))
