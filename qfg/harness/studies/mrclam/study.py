"""The MRCLAM study in the runner: ``qfg experiment mrclam`` (one task per dataset directory,
:data:`STUDY`) and ``qfg mrclam`` (one task per piece of one dataset's histories,
:func:`piece_tasks`, :func:`run_piece`)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from qfg.datasets import mrclam as _mrclam
from qfg.harness.runner import Study, param_spec
from qfg.harness.studies.mrclam.outputs import write_outputs
from qfg.harness.studies.mrclam.params import (
    COMBINE,
    DEFAULTS,
    METHODS,
    MODES,
    PRIORS,
    checked_params,
)
from qfg.harness.studies.mrclam.pipeline import (
    SOLVE_KEYS,
    Prepared,
    load_tensor,
    n_pieces,
    piece_rows,
    prepare_run,
    run_dataset,
    solve_piece,
)
from qfg.harness.studies.mrclam.scoring import TABLE_KEY, table_lines

# ----------------------------------------------------------------------------- qfg mrclam: pieces
# ``qfg mrclam`` is a runner run whose scenarios are the pieces of one dataset's histories: a
# piece's record holds its histories' estimates (piece_rows), the runner's summary step makes
# the rest from them (estimates_from_rows, finish). The command prepares the dataset once
# (checking every file before anything is written) and hands it to the pieces through
# ``remember``; a worker process that was not handed it prepares it again from the params.

_PREPARED: dict[str, Prepared] = {}


def _prep_key(params: dict) -> str:
    return json.dumps({k: params.get(k, DEFAULTS.get(k)) for k in SOLVE_KEYS
                       if k not in ("method", "piece")},
                      sort_keys=True, default=str)


def remember(params: dict, prep: Prepared) -> None:
    """Keep ``prep`` for the pieces of the run with ``params`` (one dataset at a time)."""
    _PREPARED.clear()
    _PREPARED[_prep_key(params)] = prep


def prepared(params: dict) -> Prepared:
    """The prepared dataset of a run's params (:data:`SOLVE_KEYS`), made once per process."""
    key = _prep_key(params)
    if key not in _PREPARED:
        remember(params, prepare_run(
            params["path"], robots=params["robots"] or None,
            **{k: params.get(k, DEFAULTS[k]) for k in SOLVE_KEYS
               if k not in ("path", "robots", "method", "piece")}))
    return _PREPARED[key]


def piece_tasks(params: dict) -> list[dict]:
    """One task per piece of ``params["piece"]`` histories (the params of ``qfg mrclam``:
    :data:`SOLVE_KEYS` and ``seed``)."""
    return [{"index": c, **params} for c in range(n_pieces(prepared(params), params["piece"]))]


def run_piece(task: dict, rng) -> list[dict]:
    """Solve one piece (:func:`solve_piece`, with the command's seed, not the runner's stream:
    piece c gets child c of ``SeedSequence(seed)`` as the in-memory :func:`run_dataset` does)."""
    prep = prepared(task)
    t0 = time.perf_counter()
    ests = solve_piece(prep, task["index"], method=task["method"], seed=task["seed"],
                       piece=task["piece"])
    rows = piece_rows(prep, task["index"], ests, task["piece"])
    if rows:
        rows[0]["time_solve_s"] = time.perf_counter() - t0
    return rows


def dataset_dirs(data, numbers=()) -> list[Path]:
    """``MRCLAM_Dataset<N>`` directories under ``data`` (only ``numbers`` if given), by N. An empty
    ``data`` means the directory named by ``$QFG_MRCLAM_DIR`` (:func:`qfg.datasets.mrclam.data_root`)."""
    root = _mrclam.data_root(data or None)
    if not root.is_dir():
        raise ValueError(f"data: {root} is not a directory")
    found = {}
    for d in root.iterdir():
        if d.is_dir() and d.name.startswith("MRCLAM_Dataset") and d.name[14:].isdigit():
            found[int(d.name[14:])] = d
    want = [int(n) for n in numbers] if numbers else sorted(found)
    missing = [n for n in want if n not in found]
    if missing:
        raise ValueError(f"datasets: {missing} not found under {root} (has {sorted(found)})")
    return [found[n] for n in want]


_TASK_KEYS = ("method", "mode", "prior", "combine", "partition", "fix_landmarks", "tensor",
              "min_travel", "max_gap", "max_views", "propagate", "sigma_bearing_deg",
              "sigma_heading_deg", "temper", "spread_views", "propagation", "distances",
              "sigma_distance_ratio", "map")


def tasks(params: dict) -> list[dict]:
    """One task per dataset directory."""
    p = checked_params(params)
    return [{"index": i, "path": str(d), "robots": list(p["robots"]),
             **{k: p[k] for k in _TASK_KEYS}}
            for i, d in enumerate(dataset_dirs(p["data"], p["datasets"]))]


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    T = load_tensor(task["partition"], task["tensor"] or None) if task["propagate"] and \
        task.get("map", "") != "seen" else None
    opts = {k: task[k] for k in _TASK_KEYS if k not in ("tensor", "map")}
    return run_dataset(task["path"], robots=task["robots"] or None, tensor=T,
                       map_method=task.get("map", ""), seed=int(rng.integers(2**63)), **opts)


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    print("\n".join(table_lines(write_outputs(outdir, rows))))
    print(TABLE_KEY)


STUDY = Study(name="mrclam", tasks=tasks, run_task=run_task, summarize=summarize,
              description="MRCLAM datasets: triplet estimates, full map, propagation (paper 6d), "
                          "scored with log score, Brier and both baselines",
              params=param_spec(DEFAULTS, method={"choices": METHODS},
                                combine={"choices": COMBINE}, mode={"choices": MODES},
                                prior={"choices": PRIORS}, partition={"choices": ("edc",)}))
