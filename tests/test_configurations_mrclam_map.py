"""The configuration maps of qfg mrclam (issue 21 (b)): a recorded map is reused only under the
options it was made with."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from qfg.harness.studies.mrclam import maps as mrclam_maps


def test_recorded_configuration_maps_depend_on_their_options(monkeypatch):
    seen = SimpleNamespace(triplets=np.array([[0, 1, 2]]), probabilities=np.full((1, 20), 0.05),
                           estimates=np.full((1, 20), 0.05))
    before = {m: mrclam_maps.inputs_digest(m, seen) for m in ("config-state", "seen-config",
                                                              "joint", "pooled")}
    monkeypatch.setitem(mrclam_maps.CONFIG_OPTIONS, "n_sweeps", 99)
    after = {m: mrclam_maps.inputs_digest(m, seen) for m in before}
    assert after["config-state"] != before["config-state"]
    assert after["seen-config"] != before["seen-config"]
    assert after["pooled"] == before["pooled"]
    monkeypatch.setattr(mrclam_maps, "CONFIG_UNLINKED", "sample")
    assert mrclam_maps.inputs_digest("config-state", seen) != after["config-state"]


def test_the_joint_maps_record_depends_on_its_fallback(monkeypatch):
    """Without odometry the joint map is its fallback's: its record changes with the fallback,
    and with the configuration options only when the fallback is a configuration map."""
    seen = SimpleNamespace(triplets=np.array([[0, 1, 2]]), probabilities=np.full((1, 20), 0.05),
                           estimates=np.full((1, 20), 0.05))
    monkeypatch.setattr(mrclam_maps, "JOINT_FALLBACK", "seen-prior")
    a = mrclam_maps.inputs_digest("joint", seen)
    monkeypatch.setitem(mrclam_maps.CONFIG_OPTIONS, "n_sweeps", 99)
    assert mrclam_maps.inputs_digest("joint", seen) == a
    monkeypatch.setattr(mrclam_maps, "JOINT_FALLBACK", "seen-config")
    b = mrclam_maps.inputs_digest("joint", seen)
    assert b != a
    monkeypatch.setitem(mrclam_maps.CONFIG_OPTIONS, "n_sweeps", 98)
    assert mrclam_maps.inputs_digest("joint", seen) != b


def test_seen_prior_keeps_the_solvers_rows_and_gives_the_prior_elsewhere():
    rng = np.random.default_rng(0)
    q = rng.dirichlet(np.ones(20))
    seen_t = np.array([[0, 1, 2], [3, 1, 0]])
    P = rng.dirichlet(np.ones(20), size=2)
    seen = SimpleNamespace(dataset=SimpleNamespace(landmark_ids=np.array([6, 7, 8, 9])),
                           triplets=seen_t, probabilities=P, prior_states=q)
    res = mrclam_maps.map_seen_prior(seen)
    assert len(res.triplets) == 4 * 3 * 2 and res.seen.sum() == 2
    rows = {tuple(t): v for v, t in enumerate(res.triplets.tolist())}
    for t, p in zip(seen_t.tolist(), P, strict=True):
        np.testing.assert_array_equal(res.probabilities[rows[tuple(t)]], p)
        assert res.seen[rows[tuple(t)]]
    others = res.probabilities[~res.seen]
    np.testing.assert_array_equal(others, np.tile(q, (len(others), 1)))
    assert np.array_equal(res.reached, ~res.seen)
