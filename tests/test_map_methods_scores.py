"""The studies' score table (qfg.harness.studies._map_methods.score_table): the standard error of
the mean log score is clustered by graph, checked against its closed form on rows whose graphs
each repeat one value."""

from __future__ import annotations

import numpy as np
import pytest

from qfg.harness.studies import _map_methods as mm


def _rows(values_by_graph):
    rows = []
    for g, vals in enumerate(values_by_graph):
        for v in vals:
            rows.append({"scenario": g, "seen": 0, "m_ls": v, "m_brier": 0.5, "m_under1": 0,
                         "m_top": 0.5, "m_tophit": 1, "m_pit": 0.5})
    return rows


def test_log_score_se_is_clustered_by_graph():
    a, b = -0.2, -1.4
    # two graphs, three triplets each, every triplet of a graph with the same score: as much
    # information as two values, so the SE is that of two, |a - b| / (2 sqrt 2), not of six
    (t,) = mm.score_table(_rows([[a] * 3, [b] * 3]), ["m"])
    assert t["log_score"] == pytest.approx((a + b) / 2)
    assert t["log_score_se"] == pytest.approx(abs(a - b) / (2 * np.sqrt(2)))
    six = np.array([a, b] * 3)
    assert t["log_score_se"] > six.std() / np.sqrt(six.size)
    # one triplet per graph: the plain standard error
    (u,) = mm.score_table(_rows([[x] for x in six]), ["m"])
    assert u["log_score_se"] == pytest.approx(six.std() / np.sqrt(six.size))
    assert f"{t['log_score']:.3f} ± {t['log_score_se']:.3f}" in mm.score_markdown([t])
