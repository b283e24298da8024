"""The experiment runner every study goes through.

A :class:`Study` is three plain functions: ``tasks(params)`` lists the scenarios, ``run_task(task,
rng)`` runs one and returns rows, ``summarize(outdir, rows, params)`` writes tables and figures.
:func:`run_study` runs the scenarios and guarantees:

* one seeded random stream per scenario, ``SeedSequence(seed, spawn_key=(index,))``, so the numbers
  do not depend on the worker count or the order scenarios finish in;
* a record per scenario appended to ``records.jsonl`` as it finishes; ``resume=True`` skips finished
  scenarios, and a partial last line left by a kill is detected and dropped, not read as data;
* a scenario that raises is recorded with its index, seed and traceback, and the run goes on;
* a progress bar with rate and time left;
* execution behind an :class:`Executor` (in-process, a local process pool, or a cluster), so that
  studies never see how they are run.

Outputs in the output directory: ``run.json`` (study, params, seed, command, version),
``records.jsonl`` (raw, completion order), ``rows.csv`` (sorted by scenario, no timing columns:
identical for identical inputs), ``timings.csv`` (columns whose name starts with ``time``),
``errors.json`` when any scenario failed, then whatever ``summarize`` writes.
"""

from __future__ import annotations

import csv
import io
import json
import os
import sys
import traceback
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator, Protocol

import numpy as np

from qfg._version import __version__

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - 3.10
    import tomli as tomllib

__all__ = [
    "Study",
    "Executor",
    "SerialExecutor",
    "ProcessExecutor",
    "make_executor",
    "scenario_rng",
    "run_study",
    "read_records",
    "load_presets",
    "RunnerError",
    "write_table",
    "TIMING_PREFIX",
]

#: Row columns whose name starts with this are timings: written to timings.csv, not rows.csv.
TIMING_PREFIX = "time"


class RunnerError(ValueError):
    """A study or an output directory that cannot be run as asked."""


@dataclass(frozen=True)
class Study:
    """A study: what its scenarios are, how one runs, and how results are summarized.

    Attributes:
        name: command-line name (``"single-triplet"``).
        tasks: ``params -> list[dict]``: one JSON-serializable description per scenario.
        run_task: ``(task, rng) -> list[dict]``: rows of scalars (str, int, float, bool) for one
            scenario. Must be a module-level function (it is pickled to worker processes).
        summarize: ``(outdir, rows, params) -> None``: tables, figures, summary.json.
        description: one line for ``qfg experiment list``.
    """

    name: str
    tasks: Callable[[dict], list]
    run_task: Callable[[dict, np.random.Generator], list]
    summarize: Callable[[Path, list, dict], None] | None = None
    description: str = ""


def scenario_rng(seed: int, index: int) -> np.random.Generator:
    """The random stream of scenario ``index`` of a run seeded ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(index),)))


def _execute(run_task, task, seed, index):
    """Run one scenario in whatever process the executor chose; never raises."""
    try:
        rows = run_task(task, scenario_rng(seed, index))
        rows = [dict(r) for r in rows]
        return {"index": index, "seed": [seed, index], "rows": rows}
    except Exception as exc:  # recorded, the run goes on
        return {"index": index, "seed": [seed, index], "error": f"{type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc()}


class Executor(Protocol):
    """Runs calls ``fn(*args)`` and yields their results as they complete (any order)."""

    def map_unordered(self, fn, arglists: Iterable[tuple]) -> Iterator: ...

    def close(self) -> None: ...


class SerialExecutor:
    """Everything in this process, in order (``--workers 1``)."""

    def map_unordered(self, fn, arglists):
        for args in arglists:
            yield fn(*args)

    def close(self):
        pass


class ProcessExecutor:
    """A local process pool (``--workers N``), at most ``2 N`` calls in flight."""

    def __init__(self, workers: int):
        if workers < 1:
            raise RunnerError(f"workers: expected >= 1, got {workers}")
        self.workers = workers
        self._pool = ProcessPoolExecutor(max_workers=workers)

    def map_unordered(self, fn, arglists):
        it = iter(arglists)
        pending = set()
        for args in it:
            pending.add(self._pool.submit(fn, *args))
            if len(pending) >= 2 * self.workers:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in done:
                    yield f.result()
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for f in done:
                yield f.result()

    def close(self):
        self._pool.shutdown(wait=True, cancel_futures=True)


def make_executor(workers: int = 1, scheduler: str | None = None) -> Executor:
    """The executor for ``--workers`` / ``--scheduler``: serial, process pool, or a cluster."""
    if scheduler:
        from qfg.harness import cluster  # optional extra: dask.distributed

        return cluster.DaskExecutor(scheduler)
    return SerialExecutor() if workers <= 1 else ProcessExecutor(workers)


# ----------------------------------------------------------------------------------------------
# records.jsonl


def read_records(path: Path) -> tuple[list[dict], int]:
    """Complete records of a records file, and the byte length of its complete part.

    A last line without its newline (a kill mid-write) or that is not valid JSON is not data: it
    is left out and the returned length stops before it, so the caller can truncate it away.
    """
    path = Path(path)
    if not path.exists():
        return [], 0
    data = path.read_bytes()
    records, good = [], 0
    pos = 0
    while pos < len(data):
        nl = data.find(b"\n", pos)
        if nl < 0:
            break  # partial last line
        line = data[pos:nl]
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            if data.find(b"\n", nl + 1) >= 0:
                lineno = data.count(b"\n", 0, pos) + 1
                raise RunnerError(f"{path}:{lineno}: corrupt record in the middle of the file; "
                                  "not resuming over it") from None
            break  # garbled last line
        if not isinstance(rec, dict) or "index" not in rec:
            lineno = data.count(b"\n", 0, pos) + 1
            raise RunnerError(f"{path}:{lineno}: not a runner record")
        records.append(rec)
        pos = nl + 1
        good = pos
    return records, good


def _jsonable(obj):
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"row value of type {type(obj).__name__} is not a scalar")


def _dump(rec) -> str:
    return json.dumps(rec, default=_jsonable, separators=(",", ":")) + "\n"


def _write_csv(path: Path, rows: list[dict], columns: list[str]):
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: r.get(k, "") for k in columns})
    path.write_text(buf.getvalue())


def write_table(path, recs: list[dict]) -> None:
    """Write summary records (dicts) as CSV: columns in first-seen order, floats to 6 digits."""
    keys = list(dict.fromkeys(k for r in recs for k in r))
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in recs:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def _columns(rows):
    cols = {}
    for r in rows:
        for k in r:
            cols.setdefault(k, None)
    return list(cols)


def run_study(study: Study, params: dict, output, *, seed: int = 0, workers: int = 1,
              resume: bool = False, overwrite: bool = False, executor: Executor | None = None,
              progress: bool = True, command: str | None = None) -> list[dict]:
    """Run every scenario of ``study`` with ``params``; return all rows sorted by scenario.

    Rows get a ``scenario`` column (the index). ``resume`` continues a run in ``output`` with the
    same study, params and seed; ``overwrite`` starts afresh in a used directory.
    """
    out = Path(output)
    out.mkdir(parents=True, exist_ok=True)
    rec_path = out / "records.jsonl"
    meta = {"study": study.name, "params": params, "seed": int(seed)}
    run_json = out / "run.json"
    if rec_path.exists() and not (resume or overwrite):
        raise RunnerError(f"output: {out} already holds a run; pass --resume to continue it or "
                          "--overwrite to start again")
    if resume and run_json.exists():
        old = json.loads(run_json.read_text())
        old_meta = {k: old.get(k) for k in meta}
        if json.loads(json.dumps(old_meta)) != json.loads(json.dumps(meta, default=_jsonable)):
            raise RunnerError(f"output: {out} holds a run with different study/params/seed "
                              f"({old_meta}); resume needs the same ones")
    if overwrite or not resume:
        rec_path.unlink(missing_ok=True)
    records, good = read_records(rec_path)
    if rec_path.exists() and good < rec_path.stat().st_size:
        print(f"runner: dropping a partial last record in {rec_path}", file=sys.stderr)
        with open(rec_path, "r+b") as fh:
            fh.truncate(good)
    run_json.write_text(json.dumps({**meta, "version": __version__,
                                    "command": command or " ".join(sys.argv)},
                                   indent=2, default=_jsonable) + "\n")

    tasks = study.tasks(params)
    done = {r["index"] for r in records if "rows" in r}
    # failed scenarios are tried again on resume
    records = [r for r in records if "rows" in r]
    todo = [i for i in range(len(tasks)) if i not in done]

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(tasks), initial=len(done), desc=study.name, unit="scn",
                   mininterval=1.0, file=sys.stderr, dynamic_ncols=True)
    own = executor is None
    ex = make_executor(workers) if own else executor
    errors = []
    try:
        with open(rec_path, "a", encoding="utf-8") as fh:
            arglists = ((study.run_task, tasks[i], int(seed), i) for i in todo)
            for rec in ex.map_unordered(_execute, arglists):
                fh.write(_dump(rec))
                fh.flush()
                if "rows" in rec:
                    records.append(rec)
                else:
                    errors.append(rec)
                if bar is not None:
                    bar.update(1)
                    if errors:
                        bar.set_postfix(failed=len(errors))
    finally:
        if own:
            ex.close()
        if bar is not None:
            bar.close()

    records.sort(key=lambda r: r["index"])
    rows = []
    for rec in records:
        for r in rec["rows"]:
            rows.append({"scenario": rec["index"], **r})
    cols = _columns(rows)
    _write_csv(out / "rows.csv", rows, [c for c in cols if not c.startswith(TIMING_PREFIX)])
    tcols = [c for c in cols if c.startswith(TIMING_PREFIX)]
    if tcols:
        _write_csv(out / "timings.csv", rows, ["scenario", *tcols])
    err_path = out / "errors.json"
    if errors:
        errors.sort(key=lambda r: r["index"])
        err_path.write_text(json.dumps(errors, indent=2) + "\n")
        print(f"runner: {len(errors)} scenario(s) failed; see {err_path} "
              f"(first: scenario {errors[0]['index']}: {errors[0]['error']})", file=sys.stderr)
    else:
        err_path.unlink(missing_ok=True)
    if study.summarize is not None and rows:
        study.summarize(out, rows, params)
    return rows


# ----------------------------------------------------------------------------------------------
# presets and discovery


def experiments_dir() -> Path:
    """Where study presets live: $QFG_EXPERIMENTS, else the repository's ``experiments/``."""
    env = os.environ.get("QFG_EXPERIMENTS")
    return Path(env) if env else Path(__file__).resolve().parents[2] / "experiments"


def load_presets(name: str) -> dict[str, dict]:
    """Presets of a study from ``experiments/<name>.toml`` (``-`` in the name read as ``_``)."""
    path = experiments_dir() / f"{name.replace('-', '_')}.toml"
    if not path.exists():
        raise RunnerError(f"study {name!r}: no preset file {path}")
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise RunnerError(f"{path}: {exc}") from None
    return {k: v for k, v in data.items() if isinstance(v, dict)}
