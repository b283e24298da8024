"""The MRCLAM study in the runner: ``qfg experiment mrclam`` (one task per dataset directory,
:data:`STUDY`) and ``qfg mrclam`` (one task per piece of one dataset's histories,
:func:`piece_tasks`, :func:`run_piece`)."""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from qfg.datasets import mrclam as _mrclam
from qfg.harness.runner import Study, param_spec
from qfg.harness.studies.mrclam.outputs import write_outputs
from qfg.harness.studies.mrclam.params import DEFAULTS, FIELDS, SOLVE_KEYS, MrclamParams
from qfg.harness.studies.mrclam.pipeline import (
    Prepared,
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


def params_of(record: dict) -> MrclamParams:
    """The :class:`MrclamParams` of a run's record or task (``path``, ``seed``, ``index`` and
    the options it holds; the others at their defaults)."""
    return MrclamParams.from_dict({k: v for k, v in record.items() if k in FIELDS})


def run_record(path, params: MrclamParams, seed: int) -> dict:
    """The identity of a ``qfg mrclam`` run (its ``run.json`` params, what fixes the solved
    estimates): ``path``, the later options (:data:`LATER_KEYS`) that differ from their
    defaults, the other solve options (:data:`SOLVE_KEYS`), ``seed``."""
    d = params.to_dict()
    fields = {f.name: f for f in dataclasses.fields(MrclamParams)}
    later = {k: d[k] for k in SOLVE_KEYS[1:] if fields[k].metadata["later"]
             and d[k] != DEFAULTS[k]}
    rest = {k: d[k] for k in SOLVE_KEYS[1:] if not fields[k].metadata["later"]}
    return {"path": str(path), **later, **rest, "seed": int(seed)}


def _prep_key(params: dict) -> str:
    p = params_of(params).to_dict()
    return json.dumps({"path": params.get("path"),
                       **{k: p[k] for k in SOLVE_KEYS[1:] if k not in ("method", "piece")}},
                      sort_keys=True, default=str)


def remember(params: dict, prep: Prepared) -> None:
    """Keep ``prep`` for the pieces of the run with ``params`` (one dataset at a time)."""
    _PREPARED.clear()
    _PREPARED[_prep_key(params)] = prep


def prepared(params: dict) -> Prepared:
    """The prepared dataset of a run's params (:func:`run_record`), made once per process."""
    key = _prep_key(params)
    if key not in _PREPARED:
        remember(params, prepare_run(params["path"], params_of(params)))
    return _PREPARED[key]


def piece_tasks(params: dict) -> list[dict]:
    """One task per piece of ``piece`` histories (the params of ``qfg mrclam``:
    :func:`run_record`)."""
    piece = params_of(params).piece
    return [{"index": c, **params} for c in range(n_pieces(prepared(params), piece))]


def run_piece(task: dict, rng) -> list[dict]:
    """Solve one piece (:func:`solve_piece`, with the command's seed, not the runner's stream:
    piece c gets child c of ``SeedSequence(seed)`` as the in-memory :func:`run_dataset` does)."""
    prep = prepared(task)
    t0 = time.perf_counter()
    p = params_of(task)
    ests = solve_piece(prep, task["index"], method=p.method, seed=task["seed"], piece=p.piece)
    rows = piece_rows(prep, task["index"], ests, p.piece)
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


def experiment_params(params: dict) -> tuple[str, list, MrclamParams]:
    """The parameters of ``qfg experiment mrclam`` (:data:`DEFAULTS`): (``data``,
    ``datasets``, the run's :class:`MrclamParams`); ValueError naming the first bad one."""
    rest = {k: v for k, v in params.items() if k not in ("data", "datasets")}
    return params.get("data", ""), list(params.get("datasets", [])), MrclamParams.from_dict(rest)


def tasks(params: dict) -> list[dict]:
    """One task per dataset directory: its path and every option (:meth:`MrclamParams.to_dict`)."""
    data, datasets, p = experiment_params(params)
    return [{"index": i, "path": str(d), **p.to_dict()}
            for i, d in enumerate(dataset_dirs(data, datasets))]


def run_task(task: dict, rng: np.random.Generator) -> list[dict]:
    p = params_of(task)
    return run_dataset(task["path"], p, seed=int(rng.integers(2**63)))


def summarize(outdir: Path, rows: list[dict], params: dict) -> None:
    print("\n".join(table_lines(write_outputs(outdir, rows))))
    print(TABLE_KEY)


STUDY = Study(name="mrclam", tasks=tasks, run_task=run_task, summarize=summarize,
              description="MRCLAM datasets: triplet estimates, full map, propagation (paper 6d), "
                          "scored with log score, Brier and both baselines",
              params=param_spec(DEFAULTS, partition={"choices": ("edc",)}))
