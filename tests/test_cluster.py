"""DaskExecutor on a loopback LocalCluster: the same rows as a local run, byte for byte."""

import os
import sys
from pathlib import Path

import pytest

from qfg.harness import runner

distributed = pytest.importorskip("distributed")

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import toy_study  # noqa: E402


@pytest.fixture(scope="module")
def cluster():
    # worker processes must import toy_study (tests/) as the runner pickles its run_task by name
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join([str(HERE)] + ([old] if old else []))
    try:
        lc = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                      host="127.0.0.1", dashboard_address=None)
    finally:
        if old is None:
            os.environ.pop("PYTHONPATH", None)
        else:
            os.environ["PYTHONPATH"] = old
    yield lc
    lc.close()


def test_toy_study_on_local_cluster_equals_local_run(tmp_path, cluster):
    from qfg.harness.cluster import DaskExecutor

    params = {"n": 12, "fail": [5]}
    local = runner.run_study(toy_study.STUDY, params, tmp_path / "local", seed=11, progress=False)
    ex = DaskExecutor(cluster.scheduler_address, max_in_flight=3)
    try:
        remote = runner.run_study(toy_study.STUDY, params, tmp_path / "dask", seed=11, executor=ex,
                                  progress=False)
    finally:
        ex.close()
    def strip(rows):
        return [{k: v for k, v in r.items() if k != "time_s"} for r in rows]

    assert strip(remote) == strip(local)
    assert (tmp_path / "dask" / "rows.csv").read_bytes() == (tmp_path / "local" / "rows.csv").read_bytes()
    # the failing scenario is recorded by the runner, not lost on the worker
    assert (tmp_path / "dask" / "errors.json").exists()
    assert len({r["scenario"] for r in remote}) == 11


def test_propagation_study_on_local_cluster_equals_1_and_2_workers(tmp_path, cluster):
    from qfg.harness.cluster import DaskExecutor
    from qfg.harness.studies import propagation

    params = toy_study.PROPAGATION_SMALL
    st = propagation.STUDY
    runner.run_study(st, params, tmp_path / "w1", seed=3, workers=1, progress=False)
    runner.run_study(st, params, tmp_path / "w2", seed=3, workers=2, progress=False)
    ex = DaskExecutor(cluster.scheduler_address)
    try:
        runner.run_study(st, params, tmp_path / "dask", seed=3, executor=ex, progress=False)
    finally:
        ex.close()
    ref = (tmp_path / "w1" / "rows.csv").read_bytes()
    assert ref.count(b"\n") > 10
    assert (tmp_path / "w2" / "rows.csv").read_bytes() == ref
    assert (tmp_path / "dask" / "rows.csv").read_bytes() == ref
    assert (tmp_path / "dask" / "summary.json").read_bytes() != b""


def test_bad_address_is_a_clear_error():
    from qfg.harness.cluster import DaskExecutor

    with pytest.raises(ValueError, match="address"):
        DaskExecutor("")
    with pytest.raises(ValueError, match="cannot reach"):
        DaskExecutor("tcp://127.0.0.1:1", timeout=1)


def test_cli_scheduler_option_runs_on_the_cluster(tmp_path, cluster, monkeypatch):
    from qfg.harness import cli

    exp = tmp_path / "experiments"
    exp.mkdir()
    (exp / "propagation.toml").write_text(
        "[quick]\nn_graphs = 3\nrandom_tensor = true\nn_landmarks = 5\nn_fc_min = 2\n"
        "n_fc_max = 6\nn_candidates = 2\n")
    monkeypatch.setenv("QFG_EXPERIMENTS", str(exp))
    base = ["experiment", "propagation", "--no-progress", "--seed", "4"]
    assert cli.main(base + ["--output", str(tmp_path / "local")]) == 0
    assert cli.main(base + ["--output", str(tmp_path / "dask"),
                            "--scheduler", cluster.scheduler_address]) == 0
    assert ((tmp_path / "dask" / "rows.csv").read_bytes()
            == (tmp_path / "local" / "rows.csv").read_bytes())
