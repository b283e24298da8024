"""The configuration maps of qfg mrclam (issue 21 (b)): a recorded map is reused only under the
options it was made with."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from qfg.harness.studies import mrclam_maps


def test_recorded_configuration_maps_depend_on_their_options(monkeypatch):
    seen = SimpleNamespace(triplets=np.array([[0, 1, 2]]), probabilities=np.full((1, 20), 0.05),
                           estimates=np.full((1, 20), 0.05))
    before = {m: mrclam_maps.inputs_digest(m, seen) for m in ("config-state", "seen-config",
                                                              "joint", "pooled")}
    monkeypatch.setitem(mrclam_maps.CONFIG_OPTIONS, "n_sweeps", 99)
    after = {m: mrclam_maps.inputs_digest(m, seen) for m in before}
    assert after["config-state"] != before["config-state"]
    assert after["seen-config"] != before["seen-config"]
    # the joint map falls back to seen-config without odometry: its record depends on them too
    assert after["joint"] != before["joint"]
    assert after["pooled"] == before["pooled"]
    monkeypatch.setattr(mrclam_maps, "CONFIG_UNLINKED", "sample")
    assert mrclam_maps.inputs_digest("config-state", seen) != after["config-state"]
