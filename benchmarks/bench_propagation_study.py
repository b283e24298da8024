"""Propagation study (paper 6f, `qfg experiment propagation`): scenarios (graphs) per second with
the `paper` preset's parameters in one process, and the time of the whole `paper` preset (5400
graphs): measured from `results/propagation-paper` (run.json written at the start, the last record
appended to records.jsonl at the end) when that run exists, and extrapolated from the rate.
Uses the EDC tensor `qfg.composition.tensor("edc")` (`$QFG_TENSORS` to point elsewhere, e.g.
`QFG_TENSORS=DIR python -m benchmarks propagation_study` while tensors/edc.npz
does not exist): the tensor used is named in the notes."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

N_SCENARIOS = 60


def run():
    from qfg.composition import tensor
    from qfg.harness.runner import load_presets, scenario_rng
    from qfg.harness.studies import propagation as P

    t = tensor("edc")
    tname = f"{t.path} ({t.samples_per_state} samples/state)"
    params = load_presets("propagation")["paper"]
    tasks = P.tasks({**params, "n_graphs": N_SCENARIOS})
    P.run_task(tasks[0], scenario_rng(0, 0))  # warm-up: imports, tensor load
    times, n_trip = [], 0
    for i, task in enumerate(tasks):
        t0 = time.perf_counter()
        rows = P.run_task(task, scenario_rng(0, i))
        times.append(time.perf_counter() - t0)
        n_trip += len(rows)
    total = float(np.sum(times))
    rate = N_SCENARIOS / total
    out = [{"name": "propagation study, paper parameters, 1 process", "value": rate,
            "unit": "scenarios/s",
            "note": f"{N_SCENARIOS} graphs, {n_trip / N_SCENARIOS:.0f} triplets per graph on "
                    f"average, median {1e3 * np.median(times):.0f} ms per graph; tensor {tname}"},
           {"name": "propagation paper preset (5400 graphs), extrapolated, 1 process",
            "value": 5400 / rate / 60, "unit": "min", "note": "5400 / the rate above"}]
    run_dir = Path(__file__).resolve().parent.parent / "results" / "propagation-paper"
    rj, sj = run_dir / "run.json", run_dir / "records.jsonl"
    if rj.exists() and sj.exists() and sj.stat().st_mtime > rj.stat().st_mtime:
        meta = json.loads(rj.read_text())
        wall = sj.stat().st_mtime - rj.stat().st_mtime
        out.append({"name": "propagation paper preset, measured wall time", "value": wall / 60,
                    "unit": "min",
                    "note": f"`{meta.get('command')}` (run.json to last record mtimes; "
                            f"shared 2-core machine with other jobs running)"})
    return out
