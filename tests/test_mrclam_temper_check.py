"""The model check over histories (``qfg mrclam --temper auto``): the tempering power under
which the histories of one ordered triplet agree best, on a discrete model where the posteriors
are exact (it must keep them, power 1) or sharpened (it must widen them)."""

import numpy as np

from qfg.harness.studies.mrclam import AUTO_TEMPERS, cross_pass_agreement


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
