"""The SIS engine's per-view work does not grow with the views (issue 20, item 2): C's integral
carried as a Gaussian summary updated by each new line of sight, trajectories kept as ancestry.
Checked against the batch Laplace fit, a grid integral, a naive gather, and by counting the
pose-views handed to the batch fit (never by timing)."""

from __future__ import annotations

import numpy as np
import pytest

from qfg.geometry import wrap_angle
from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplets
from qfg.solvers.common import laplace as _laplace
from qfg.solvers.common import options as _options
from qfg.solvers.common import seeds as _seeds
from qfg.solvers.sis import c_integral as _c_integral
from qfg.solvers.sis import engine as _engine
from qfg.solvers.sis import motion as _motion
from qfg.solvers.sis import state as _state


def _lines(rng, n, sig, spread=1.5):
    """n cameras (no heading) looking at C with noisy bearings: poses (n, 3), angles (n,)."""
    C = rng.uniform(-0.5, 0.5, 2) + [0.0, 2.5]
    X = rng.uniform(-spread, spread, (n, 2)) + [0.0, -0.5]
    th = np.arctan2(C[1] - X[:, 1], C[0] - X[:, 0]) + sig * rng.standard_normal(n)
    return np.concatenate([X, np.zeros((n, 1))], axis=1), th


def _grid_log_z(X, th, sig, centre, half=1.0, m=601):
    g = np.linspace(-half, half, m)
    G0, G1 = np.meshgrid(centre[0] + g, centre[1] + g, indexing="ij")
    ll = np.zeros_like(G0)
    for t in range(X.shape[0]):
        r = wrap_angle(np.arctan2(G1 - X[t, 1], G0 - X[t, 0]) - th[t])
        ll += -0.5 * r * r / sig ** 2 - np.log(sig) - 0.5 * np.log(2 * np.pi)
    mx = ll.max()
    return mx + np.log(np.exp(ll - mx).sum() * (g[1] - g[0]) ** 2)


def _incremental(poses, th, sig, start=2):
    """Summary after ``start`` views by the batch fit, then one view at a time."""
    lz, _, _, parts = _laplace.laplace_landmark(poses[None, :start], th[None, :start],
                                                np.array([sig]), parts=True)
    s = _laplace.summary_from_parts(lz, parts, np.array([True]))
    for t in range(start, poses.shape[0]):
        s, spread = _laplace.update_landmark(s, poses[None, t, :2], th[t:t + 1], np.array([sig]))
    return s[0], spread[0]


def _map_laplace(poses, th, sig, L0):
    """The batch Laplace fit about the exact mode (scipy least squares over every view): mode,
    H = sum_t g_t g_t^T there, and log Z."""
    from scipy.optimize import least_squares

    X = poses[:, :2]

    def res(L):
        return wrap_angle(np.arctan2(L[1] - X[:, 1], L[0] - X[:, 0]) - th)

    L = least_squares(res, L0, xtol=1e-14, ftol=1e-14, gtol=1e-14).x
    d = L - X
    r2 = np.sum(d * d, axis=1)
    g = np.stack([-d[:, 1], d[:, 0]], axis=1) / r2[:, None]
    H = g.T @ g
    r = res(L)
    lz = (np.sum(-0.5 * r * r / sig ** 2 - np.log(sig) - 0.5 * np.log(2 * np.pi))
          + np.log(2 * np.pi * sig ** 2) - 0.5 * np.log(np.linalg.det(H)))
    return L, H, lz


def test_incremental_summary_equals_the_batch_laplace_fit_for_nearly_linear_lines():
    # small noise: the lines of sight are nearly linear in L over C's posterior, where the
    # Laplace fit over all views (about the exact mode) and the chain of one-view updates agree
    rng = np.random.default_rng(3)
    sig = np.deg2rad(0.1)
    done = 0
    for _ in range(40):
        poses, th = _lines(rng, 8, sig)
        lz2, L2, sp2 = _laplace.laplace_landmark(poses[None, :2], th[None, :2], np.array([sig]))
        if not sp2[0] < 0.05:
            continue
        L, H, lz = _map_laplace(poses, th, sig, L2[0])
        s, spread = _incremental(poses, th, sig)
        e = s[:2] - L
        assert np.sqrt(e @ H @ e) / sig < 0.2          # within a fifth of C's posterior sd
        # the earlier lines keep the gradients of where they were added: H within 3%
        dH = np.array([[s[2], s[3]], [s[3], s[4]]]) - H
        assert np.linalg.norm(dH) < 0.03 * np.linalg.norm(H)
        assert abs(s[5] - lz) < 0.15                   # log Z: a tenth of a nat or so
        done += 1
    assert done >= 10


def test_incremental_summary_is_as_close_to_the_integral_as_the_batch_fit():
    # at the headline noise (2 deg) both are Laplace approximations of the same integral: the
    # incremental one no further from a grid integral than the batch fit, on average
    rng = np.random.default_rng(4)
    sig = np.deg2rad(2.0)
    err_inc, err_batch = [], []
    for _ in range(60):
        poses, th = _lines(rng, 5, sig)
        lz2, _, sp2 = _laplace.laplace_landmark(poses[None, :4], th[None, :4], np.array([sig]))
        lzb, Lb, spb = _laplace.laplace_landmark(poses[None], th[None], np.array([sig]))
        if not (sp2[0] < 0.25 and spb[0] < 0.1):
            continue
        s, _ = _incremental(poses, th, sig, start=4)
        truth = _grid_log_z(poses, th, sig, Lb[0])
        err_inc.append(abs(s[5] - truth))
        err_batch.append(abs(lzb[0] - truth))
    assert len(err_inc) >= 20
    assert np.median(err_inc) < np.median(err_batch) + 0.1
    assert np.median(err_inc) < 0.5


def test_trajectories_walk_the_ancestry_like_a_naive_gather():
    rng = np.random.default_rng(5)
    # naive: whole trajectories copied at every step, as the engine did before
    full = rng.standard_normal((7, 1, 3))
    levels = ((full[:, 0].copy(), np.zeros(7, dtype=np.int64)),)
    for _ in range(6):
        up = rng.integers(0, full.shape[0], size=9)
        new = rng.standard_normal((9, 3))
        full = np.concatenate([full[up], new[:, None]], axis=1)
        levels = levels + ((new, up),)
        keep = rng.permutation(9)[:5]           # a resampling keeps some of them
        full = full[keep]
        levels = _state.take_last(levels, keep)
    np.testing.assert_array_equal(_state.trajectories(levels), full)
    np.testing.assert_array_equal(_state.trajectories(levels, [4, 0]), full[[4, 0]])
    np.testing.assert_array_equal(_state.trajectories(levels, [3], last=2), full[[3], -2:])


def test_refits_take_at_most_the_window_of_views(monkeypatch):
    # a child without a usable C summary is refitted over the latest REFIT_VIEWS views only,
    # so its cost stays bounded however many views came before; the final weights still use
    # every view
    widths = []
    real = _laplace.laplace_landmark

    def recording(poses, *a, **kw):
        widths.append(poses.shape[1])
        return real(poses, *a, **kw)

    monkeypatch.setattr(_laplace, "laplace_landmark", recording)
    monkeypatch.setattr(_motion, "REFIT_VIEWS", 4)
    # a bearing tail: every child is refitted at every view
    hs = _histories(2, 9, seed=814000)
    # (the engine's refits: the rejuvenation fits whole trajectories at its own views,
    # tests/test_sis_rejuvenation.py)
    es = solve_triplets(hs, method="full", seed=2, bearing_tail=(0.1, 5.0, 0.0),
                        max_hypotheses=300, n_samples=100, rejuvenate=0)
    assert widths and max(widths) == 4
    assert all(np.isfinite(e.landmark).all() and abs(e.landmark.sum() - 1) < 1e-9 for e in es)


def test_gather_equals_concatenate_then_index():
    rng = np.random.default_rng(6)
    parts = [rng.standard_normal((m, 3)) for m in (4, 0, 7, 2)]
    full = np.concatenate(parts)
    for rows in (np.arange(13), np.array([12, 0, 5, 5, 3]), np.array([], dtype=int)):
        np.testing.assert_array_equal(_motion._gather(parts, rows), full[rows])


def _histories(n, k, seed=810000):
    return [random_triplet_history(np.random.default_rng(seed + i), k, np.deg2rad(2.0),
                                   np.deg2rad(5.0)) for i in range(n)]


def _run(h, k, opts=None):
    from qfg.solvers.common import options as _options
    from qfg.solvers.common.input import get_partition

    opts = _options.resolve_options("full", opts or {})
    roots = [np.random.SeedSequence(11)]
    st = _engine.start(h.bearings[None, 0], np.array([h.sigma_bearing]),
                    np.array([h.sigma_heading]), roots, opts, get_partition("edc"), "full",
                    n_views=k)
    states = [st]
    for i in range(1, k):
        st = _engine.step(st, h.bearings[None, i], np.array([h.headings[i - 1]]))
        states.append(st)
    return states


def test_the_carried_c_weights_are_as_close_to_the_integral_as_a_batch_refit():
    # the integral of C for the state's trajectories, estimated without bias by importance
    # sampling with many draws: the carried summaries' log Z no further from it than the batch
    # Laplace fit over the same views (the batch fit sits at the lines' unweighted
    # least-squares point, not at the mode)
    from qfg.solvers.sis import landmarks as _landmarks

    h = _histories(2, 8)[1]
    st = _run(h, 8)[-1]
    rows = np.flatnonzero(np.isfinite(st.c_sum[:, 0]))[:300]
    assert rows.size >= 100
    P = st.poses[rows]
    phi = st.bearings[0, :, 2]
    sig = st.sigma_v()[0]
    L, log_q, log_lik, _ = _landmarks.sample_landmarks(np.random.default_rng(0), P, phi, sig,
                                                       4000, 0.25)
    from qfg.solvers.common.likelihood import logsumexp

    is_lz = logsumexp(log_lik - log_q, axis=1) - np.log(4000)
    batch, _, _ = _laplace.laplace_landmark(P, phi, sig)
    inc = st.c_sum[rows, 5]
    # relative to each other is what the weights use
    e_inc = np.abs((inc - is_lz) - np.median(inc - is_lz))
    e_batch = np.abs((batch - is_lz) - np.median(batch - is_lz))
    assert np.median(e_inc) < np.median(e_batch) + 0.05
    assert np.median(e_inc) < 0.2


def _pose_views_per_step(monkeypatch, incremental, k=16, options=None):
    """Pose-views handed to the batch C fit at each step of one 16-view history, and the
    hypotheses alive after each step; checks on the way that no step copies earlier poses."""
    seen = []
    real = _laplace.laplace_landmark

    def counting(poses, *a, **kw):
        seen[-1] += poses.shape[0] * poses.shape[1]
        return real(poses, *a, **kw)

    monkeypatch.setattr(_laplace, "laplace_landmark", counting)
    monkeypatch.setattr(_motion, "_INCREMENTAL_C", incremental)
    h = _histories(1, k, seed=811000)[0]
    # the engine's own steps: the rejuvenation (rebuilding the levels flat at its views) is
    # counted in tests/test_sis_rejuvenation.py
    opts = _options.resolve_options("full", {"rejuvenate": 0, **(options or {})})
    from qfg.solvers.common.input import get_partition

    # (n_views: as solve_triplets, no few-views budget to solve again at view 4)
    st = _engine.start(h.bearings[None, 0], np.array([h.sigma_bearing]),
                    np.array([h.sigma_heading]), [np.random.SeedSequence(2)], opts,
                    get_partition("edc"), "full", n_views=k)
    alive = []
    for i in range(1, k):
        seen.append(0)
        prev = st
        st = _engine.step(st, h.bearings[None, i], np.array([h.headings[i - 1]]))
        # earlier levels are shared, not copied
        assert all(a[0] is b[0] for a, b in zip(st.levels[:-1], prev.levels, strict=True))
        alive.append(st.tid.size)
    return np.array(seen), np.array(alive)


def test_per_view_work_does_not_grow_with_the_views(monkeypatch):
    # pose-views handed to the batch C fit per step stay a small share of what refitting every
    # child over all views costs (the old engine's, which the same count shows growing), except
    # at the anchor views (4, 8, 16), whose refits amortize to a bounded share
    inc, alive = _pose_views_per_step(monkeypatch, True, options={"c_anchors": True})
    batch, _ = _pose_views_per_step(monkeypatch, False)
    views = np.arange(2, 17)
    anchor = np.array([_motion._anchor(v) for v in views])
    assert views[anchor].tolist() == [4, 8, 16]
    assert np.mean(alive[8:]) > 1000               # the sampler kept many hypotheses here
    # the refit of every child: O(views) each (with 1000s of hypotheses, each with children)
    late = views >= 10
    assert batch[late].sum() > 10_000 * views[late].sum()
    assert inc[late & ~anchor].sum() < 0.05 * batch[late & ~anchor].sum()
    assert np.max(inc[late & ~anchor]) < 0.1 * 3000 * 8 * 16
    # anchors included: (4 + 8 + 16) of the 135 pose-views per child the old engine refitted
    assert inc.sum() < 0.35 * batch.sum()


def test_same_seed_same_answer():
    hs = _histories(3, 7, seed=812000)
    a = solve_triplets(hs, method="full", seed=5)
    b = solve_triplets(hs, method="full", seed=5)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.landmark, y.landmark)


def test_both_c_paths_answer_within_monte_carlo_error(monkeypatch):
    # the intermediate C weights only steer the sampler: the final weights use every view
    # exactly, so the answers with and without the carried summary differ by about what two
    # seeds of one of them do
    hs = _histories(6, 6, seed=813000)

    def answers(incremental, seed):
        monkeypatch.setattr(_motion, "_INCREMENTAL_C", incremental)
        return np.array([e.landmark for e in solve_triplets(hs, method="full", seed=seed)])

    def tv(a, b):
        return 0.5 * np.abs(a - b).sum(axis=1).mean()

    runs = {(inc, seed): answers(inc, seed) for inc in (True, False) for seed in (3, 4)}
    cross = np.mean([tv(runs[True, a], runs[False, b]) for a in (3, 4) for b in (3, 4)])
    within = np.mean([tv(runs[x, 3], runs[x, 4]) for x in (True, False)])
    assert cross < 1.3 * within + 0.02


def test_the_final_c_proposal_centres_nearer_the_mode_than_the_least_squares_point():
    # the final C draws centre on the carried summary's mode: nearer the posterior's mode (scipy
    # least squares over every view's bearing residual) than the lines' unweighted
    # least-squares point, in units of C's posterior standard deviation
    h = _histories(2, 8)[1]
    st = _run(h, 8)[-1]
    rows = np.flatnonzero(np.isfinite(st.c_sum[:, 0]))[:40]
    P = st.poses[rows]
    sig = float(st.sigma_v()[0])
    at_mode = _engine._final_proposal(st, rows, P)[0]
    th = P[..., 2] + st.bearings[0, :, 2]
    lsq = _laplace.triangulate(P[..., :2], th)[0]
    d_mode, d_lsq = [], []
    for j in range(rows.size):
        L, H, _ = _map_laplace(P[j], th[j], sig, lsq[j])
        for c, out in ((at_mode[j], d_mode), (lsq[j], d_lsq)):
            e = c - L
            out.append(np.sqrt(e @ H @ e) / sig)
    assert np.median(d_mode) < 0.5 * np.median(d_lsq)
    assert np.median(d_mode) < 0.5


def test_final_draws_at_the_mode_raise_the_effective_sample_size(monkeypatch):
    hs = _histories(8, 8, seed=815000)
    ess = {}
    for at_mode in (True, False):
        monkeypatch.setattr(_engine, "_FINAL_AT_MODE", at_mode)
        ess[at_mode] = np.array([e.ess for e in solve_triplets(hs, method="full", seed=4)])
    assert np.median(ess[True]) > 1.5 * np.median(ess[False])


@pytest.mark.parametrize("moves", [0, 1])
def test_a_retried_triplet_is_merged_with_its_own_ancestry(monkeypatch, moves):
    # a triplet whose hypotheses all die is proposed again (step's retry) and merged back: the
    # merged trajectories are those of the retry for it and those of the first proposal for the
    # other triplet, with the earlier levels still shared (rebuilt flat when moves rewrote the
    # trajectories)
    from qfg.solvers.common.input import get_partition

    hs = _histories(2, 3, seed=816000)
    opts = _options.resolve_options("full", {"max_hypotheses": 200, "n_samples": 100,
                                                     "move_steps": moves})
    st = _engine.start(np.stack([h.bearings[0] for h in hs]), np.full(2, hs[0].sigma_bearing),
                    np.full(2, hs[0].sigma_heading),
                    [np.random.SeedSequence(3, spawn_key=(t,)) for t in range(2)], opts,
                    get_partition("edc"), "full")
    real = _motion.extend
    made = {}

    def extend(state, phi, psi, spread, purpose):
        out = real(state, phi, psi, spread, purpose)
        if purpose == _seeds.STREAM_CAMERAS and state.n_triplets == 2:
            out = _state.take(out, np.flatnonzero(out.tid == 1))   # triplet 0 dies
        made[purpose] = out
        return out

    monkeypatch.setattr(_motion, "extend", extend)
    nxt = _engine.step(st, np.stack([h.bearings[1] for h in hs]),
                    np.array([h.headings[0] for h in hs]))
    assert _seeds.STREAM_RETRY in made and nxt.lost[0] == 0
    first, retry = made[_seeds.STREAM_CAMERAS], made[_seeds.STREAM_RETRY]
    np.testing.assert_array_equal(nxt.poses[nxt.tid == 0], retry.poses)
    np.testing.assert_array_equal(nxt.poses[nxt.tid == 1], first.poses[first.tid == 1])
    assert (nxt.levels[0][0] is st.levels[0][0]) == (moves == 0)
    np.testing.assert_array_equal(nxt.lw_c[nxt.tid == 0], retry.lw_c)


def test_refits_at_the_mode_equal_the_exact_laplace_fit():
    # c_anchors' refits: the Laplace approximation about C's mode over all views, as scipy's
    # least squares finds it, from the lines' least-squares point in two Gauss-Newton steps
    rng = np.random.default_rng(7)
    sig = np.deg2rad(2.0)
    P, TH = [], []
    while len(P) < 12:
        poses, th = _lines(rng, 6, sig)
        _, _, sp = _laplace.laplace_landmark(poses[None], th[None], np.array([sig]))
        if sp[0] < 0.1:
            P.append(poses)
            TH.append(th)
    P, TH = np.array(P), np.array(TH)
    s = np.full(len(P), sig)
    lz, Ls, spread, parts = _laplace.laplace_landmark(P, TH, s, parts=True)
    lzm, Lm, _, _ = _c_integral._at_mode(P, TH, s, lz, spread, parts)
    for j in range(len(P)):
        L, H, z = _map_laplace(P[j], TH[j], sig, Ls[j])
        e = Lm[j] - L
        assert np.sqrt(e @ H @ e) / sig < 0.05
        assert abs(lzm[j] - z) < 0.01
