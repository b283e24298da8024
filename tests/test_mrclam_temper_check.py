"""The model check over histories (``qfg mrclam --temper auto``): the tempering power under
which the histories of one ordered triplet agree best, on a discrete model where the posteriors
are exact (it must keep them, power 1) or sharpened (it must widen them)."""

import numpy as np

from qfg.harness.studies.mrclam import AUTO_TEMPERS, choose_power, cross_pass_agreement
from qfg.metrics import clustered_se


def _posteriors(rng, sharpen, n_triplets=600, passes=3, m=5, right=0.6):
    # each pass reports the true state with probability `right`, else another state uniformly:
    # its exact posterior under a uniform prior is right / ((1 - right) / (m - 1)) on the report
    q = np.full(m, 1.0 / m)
    lik_right, lik_wrong = right, (1.0 - right) / (m - 1)
    P, groups = [], {}
    for t in range(n_triplets):
        s = rng.integers(m)
        for _ in range(passes):
            y = s if rng.random() < right else rng.choice([k for k in range(m) if k != s])
            p = np.full(m, lik_wrong)
            p[y] = lik_right
            p = p ** sharpen
            groups.setdefault((t, 0, 0), []).append(len(P))
            P.append(p / p.sum())
    return np.array(P), groups, q


def _best(P, groups, q):
    scores = {t: cross_pass_agreement(P, groups, q, t)[0] for t in AUTO_TEMPERS}
    return max(scores, key=scores.get)


def test_exact_posteriors_are_kept_and_overconfident_ones_widened():
    rng = np.random.default_rng(0)
    assert _best(*_posteriors(rng, 1.0)) >= 0.9
    tau = _best(*_posteriors(rng, 3.0))
    # the sharpened posteriors are the exact ones to the power 3: tempering by about 1/3 undoes it
    assert 0.2 <= tau <= 0.5


def test_no_pairs_no_check():
    P = np.array([[0.5, 0.5]])
    assert cross_pass_agreement(P, {(0, 1, 2): [0]}, np.array([0.5, 0.5]), 0.5) == (0.0, 0)


def test_one_standard_error_rule_is_at_most_the_best_and_still_widens_sharpened_ones():
    rng = np.random.default_rng(1)
    for sharpen in (1.0, 3.0):
        P, groups, q = _posteriors(rng, sharpen)
        best, table = choose_power(P, groups, q, rule="auto")
        cautious, _ = choose_power(P, groups, q, rule="auto-1se")
        assert best == _best(P, groups, q)
        top = max(table, key=lambda r: r[1])
        chosen = dict((r[0], r[1]) for r in table)[cautious]
        # the rule's promise: no worse than one standard error below the best agreement
        assert cautious <= best and chosen >= top[1] - top[3]
        # and the smallest such power
        assert all(r[1] < top[1] - top[3] for r in table if r[0] < cautious)
    assert cautious <= 0.5       # the cubed posteriors stay widened


def test_clustered_se_matches_the_plain_se_for_singletons_and_grows_with_dependence():
    rng = np.random.default_rng(2)
    v = rng.standard_normal(400)
    plain = v.std(ddof=0) / np.sqrt(v.size)
    assert np.isclose(clustered_se(v, np.arange(v.size)), plain)
    # each value repeated 4 times in its cluster: 4 x the values, the same information
    rep = np.repeat(v, 4)
    assert np.isclose(clustered_se(rep, np.repeat(np.arange(v.size), 4)), plain)
    assert clustered_se(rep, np.arange(rep.size)) < 0.6 * plain
