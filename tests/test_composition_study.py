"""The composition study (qfg.harness.studies.composition) on a small LR tensor built here."""

import numpy as np
import pytest

from qfg import composition as qc
from qfg import partitions as qp
from qfg.composition import build as qb
from qfg.geometry import bearing, wrap_angle
from qfg.harness.runner import run_study
from qfg.harness.studies import composition as study


@pytest.fixture(scope="module")
def lr_tensors(tmp_path_factory):
    d = tmp_path_factory.mktemp("tensors")
    qc.save(d / "lr.npz", qb.build("lr", 64, seed=0, progress=False))
    return d


def test_simulated_views_see_their_triplets():
    rng = np.random.default_rng(0)
    s = study.simulate(rng, 3, 0.0, 0.0)
    assert s.visible[:3].tolist() == [[True, True, True, False]] * 3
    assert s.visible[3:].tolist() == [[False, True, True, True]] * 3
    # noise-free bearings are the geometry's
    np.testing.assert_allclose(s.bearings[0, :3], bearing(s.poses[0], s.landmarks[:3]))
    d = np.linalg.norm(np.concatenate([s.landmarks, s.poses[:, :2]])[:, None]
                       - np.concatenate([s.landmarks, s.poses[:, :2]])[None], axis=-1)
    assert d[~np.eye(10, dtype=bool)].min() >= 0.01
    assert np.allclose(wrap_angle(s.bearings), s.bearings)


def test_truth_priors_make_composition_the_oracle(lr_tensors, monkeypatch):
    monkeypatch.setenv(qc.ENV_VAR, str(lr_tensors))
    tasks = study.tasks({"n_per_level": 6, "sigma_bearing_deg": [1.0], "partition": "lr",
                         "prior": "truth"})
    assert len(tasks) == 6 and tasks[0]["sigma_heading_deg"] == 2.5
    m = qp.get("lr").n_states
    for t in tasks:
        (row,) = study.run_task(t, np.random.default_rng(t["index"]))
        assert row["prior"] == "truth"
        assert row["composition_dmse"] == row["oracle_dmse"]
        assert row["uniform_dmse"] == pytest.approx(np.sqrt((1 - 1 / m) ** 2 + (m - 1) / m**2))
        if row["c_in_window"] and row["d_in_window"] and row["d_in_bc_window"]:
            assert row["oracle_gt_likelihood"] > 0  # a geometric configuration is feasible


def test_run_study_writes_summary_and_figures(lr_tensors, monkeypatch, tmp_path):
    monkeypatch.setenv(qc.ENV_VAR, str(lr_tensors))
    params = {"n_per_level": 3, "sigma_bearing_deg": [0.0, 4.0], "partition": "lr"}
    rows = run_study(study.STUDY, params, tmp_path / "out", seed=1, progress=False)
    assert len(rows) == 6
    assert {r["prior"] for r in rows} == {"fast"}
    out = tmp_path / "out"
    for f in ("summary.csv", "summary.json", "figures/composition_dmse.png",
              "figures/composition_gmd.png", "figures/composition_gt_rating.png"):
        assert (out / f).exists(), f
    with pytest.raises(ValueError, match="prior"):
        study.tasks({"prior": "magic"})
    with pytest.raises(ValueError, match="unknown"):
        study.tasks({"n_scenarios": 3})
