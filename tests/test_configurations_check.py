"""The leave-one-out check of configuration inference (ConfigurationPosterior.loo_check): each
seen triplet's conditional predictive ordinate against brute-force importance sampling from the
prior, and the widening it chooses on evidence that agrees and on evidence that contradicts."""

from __future__ import annotations

import numpy as np

from qfg.combine import temper
from qfg.configurations import CHECK_GRID, TEMPER, infer_configurations, prior_states
from qfg.geometry import to_frame
from qfg.partitions import get
from qfg.priors import WorldBoxPrior

M, FLOOR = 20, 0.01


def _vec(state, p):
    v = np.full(M, (1 - p) / (M - 1))
    v[state] = p
    return v


def _states(X, ts):
    ts = np.array(ts)
    return get("edc").state_of(to_frame(X[:, ts[:, 2]], X[:, ts[:, 0]], X[:, ts[:, 1]]))


def _evidence_from(X, triplets, p):
    """Estimates putting p on the states of configuration X (1, n, 2)."""
    return {t: _vec(int(s), p) for t, s in zip(triplets, _states(X, triplets)[0], strict=True)}


def _brute_force_log_cpo(evidence, n, draws=200_000, seed=0):
    """log m_t = log E_prior[prod_all L] - log E_prior[prod_(-t) L], from prior draws."""
    pr = WorldBoxPrior()
    q = prior_states(pr, "edc")
    X = pr.sample_world(np.random.default_rng(seed), n, draws)
    logL = []
    for t, v in evidence.items():
        s = _states(X, [t])[:, 0]
        vt = temper(v, q, TEMPER["config-state"])
        logL.append(np.log((1 - FLOOR) * vt[s] / q[s] + FLOOR))
    logL = np.array(logL)
    tot = logL.sum(axis=0)
    mx = tot.max()
    log_all = mx + np.log(np.mean(np.exp(tot - mx)))
    out = []
    for r in range(len(logL)):
        rest = tot - logL[r]
        mr = rest.max()
        out.append(log_all - (mr + np.log(np.mean(np.exp(rest - mr)))))
    return np.array(out)


def test_predictive_ordinates_match_brute_force_importance_sampling():
    truth = WorldBoxPrior().sample_world(np.random.default_rng(7), 4, 1)
    ts = [(0, 1, 2), (1, 2, 3), (0, 2, 3)]
    ev = _evidence_from(truth, ts, 0.8)
    post = infer_configurations(ev, seed=1, n_particles=8000, n_groups=4, floor=FLOOR)
    chk = post.loo_check()
    assert chk.triplets == tuple(ts)
    ref = _brute_force_log_cpo(ev, 4)
    assert np.all(np.abs(chk.log_cpo - ref) < 0.15), (chk.log_cpo, ref)
    # evidence drawn from one configuration predicts itself better than the prior does, on
    # average (one triplet may be predicted a little worse)
    assert ref.mean() > 0.2 and chk.widen < 0.1


def test_contradicting_evidence_is_noticed_and_the_marginals_widened():
    pr = WorldBoxPrior()
    rng = np.random.default_rng(3)
    ts = [(0, 1, 2), (1, 2, 3), (0, 2, 3), (0, 1, 3)]
    # every estimate sure (0.97) of the state of its own random configuration: they disagree
    ev = {t: _vec(int(_states(pr.sample_world(rng, 4, 1), [t])[0, 0]), 0.97) for t in ts}
    post = infer_configurations(ev, seed=2, n_particles=4000, n_groups=4, floor=FLOOR)
    chk = post.loo_check()
    assert chk.contradicted and chk.widen > 0.2
    assert chk.agreement[1] >= chk.agreement[0] and chk.widen in CHECK_GRID
    q = prior_states(pr, "edc")
    plain = post.marginals([(0, 1, 2), (2, 1, 0)])
    checked = post.marginals([(0, 1, 2), (2, 1, 0)], check=True)
    assert np.allclose(checked.probabilities,
                       (1 - chk.widen) * plain.probabilities + chk.widen * q)
    assert checked.info["check"].widen == chk.widen
