"""More views help: a correct posterior's expected log score cannot fall when a view is added.
On a small paired set of development geometries (``default_rng(900000 + i)``, 2/5 deg), the full
solver's mean log p(truth) at 6 views beats its own at 3 views, paired by geometry."""

from dataclasses import replace

import numpy as np
import pytest

from qfg.simulation import random_triplet_history
from qfg.solvers import solve_triplets

DEV_SEED = 900000


@pytest.fixture(scope="module")
def geometries():
    return [random_triplet_history(np.random.default_rng(DEV_SEED + i), 6, np.deg2rad(2),
                                   np.deg2rad(5)) for i in range(40)]


def _first(h, n):
    return replace(h, bearings=h.bearings[:n], headings=h.headings[:n - 1], views=h.views[:n])


@pytest.mark.parametrize("method", ["full", "fast"])
def test_six_views_beat_three(method, geometries):
    g = np.array([h.truth.state for h in geometries])
    scores = {}
    for n in (3, 6):
        est = solve_triplets([_first(h, n) for h in geometries], method=method, seed=1)
        p = np.array([e.landmark[t] for e, t in zip(est, g, strict=True)])
        scores[n] = np.log(np.clip(p, 1e-4, 1.0))
    d = scores[6] - scores[3]
    se = d.std(ddof=1) / np.sqrt(d.size)
    # the paired gain is positive by more than two standard errors (measured on these 40
    # geometries: full +0.39 +- 0.12, fast +0.46 +- 0.18)
    assert d.mean() > 2 * se, (d.mean(), se)
    assert d.mean() > 0.1
