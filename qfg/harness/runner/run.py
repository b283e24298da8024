"""The run itself: :func:`run_study` checks the seed, the parameters and the output directory,
takes the directory's lock and runs the scenarios left, each with its own seeded stream
(:func:`scenario_rng`), appending a record per scenario as it finishes; then ``rows.csv``,
``timings.csv``, ``errors.json`` and the study's summary (the guarantees: :mod:`qfg.harness.runner`)."""

from __future__ import annotations

import contextlib
import json
import os
import sys
import traceback
from pathlib import Path

import numpy as np

from qfg._version import __version__
from qfg.harness.runner.errors import RunAborted, RunInterrupted, RunnerError, ScenariosFailed
from qfg.harness.runner.executors import Executor, WorkerLost, _check_workers, make_executor
from qfg.harness.runner.figures import FIGURE_FORMATS, use_figure_format
from qfg.harness.runner.lock import _NOFOLLOW, OutputLock, check_output
from qfg.harness.runner.params import Study
from qfg.harness.runner.records import (
    _append,
    _atomic_write,
    _columns,
    _dump,
    _jsonable,
    dedupe_records,
    read_records,
    write_table,
    write_text,
)

#: Row columns whose name starts with this are timings: written to timings.csv, not rows.csv.
TIMING_PREFIX = "time"


def scenario_rng(seed: int, index: int) -> np.random.Generator:
    """The random stream of scenario ``index`` of a run seeded ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(index),)))


def _execute(run_task, task, seed, index):
    """Run one scenario in whatever process the executor chose; never raises (but Ctrl-C)."""
    try:
        rows = run_task(task, scenario_rng(seed, index))
        rows = [dict(r) for r in rows]
        return {"index": index, "seed": [seed, index], "rows": rows}
    except Exception as exc:  # recorded, the run goes on
        return {"index": index, "seed": [seed, index], "error": f"{type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc()}


def _check_seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise RunnerError(f"seed: expected an integer >= 0, got {seed!r}")
    return int(seed)


def run_study(study: Study, params: dict, output, *, seed: int = 0, workers: int = 1,
              resume: bool = False, overwrite: bool = False, executor: Executor | None = None,
              progress: bool = True, command: str | None = None,
              figure_format: str = "png") -> list[dict]:
    """Run every scenario of ``study`` with ``params``; return all rows sorted by scenario.

    Rows get a ``scenario`` column (the index). ``resume`` continues a run in ``output`` with the
    same study, params and seed; ``overwrite`` starts afresh in a used directory. Raises
    RunnerError (bad seed, workers, parameters or output; output in use: :class:`OutputInUse`)
    before running anything, :class:`RunInterrupted` on Ctrl-C and :class:`ScenariosFailed`
    when no scenario succeeded.
    """
    seed = _check_seed(seed)
    if executor is None:
        workers = _check_workers(workers)
    if figure_format not in FIGURE_FORMATS:
        raise RunnerError(f"format: expected one of {', '.join(FIGURE_FORMATS)}, "
                          f"got {figure_format!r}")
    study.check_params(params)
    tasks = study.tasks(params)
    if not tasks:
        raise RunnerError(f"params: {study.name} with these parameters has no scenarios to run")
    out = check_output(output)
    lock = OutputLock(out)
    with lock:
        if lock.took_over:
            print(f"runner: took over the lock of pid {lock.took_over.get('pid')}, which is no "
                  "longer running", file=sys.stderr)
        return _run_locked(study, params, tasks, out, seed, workers, resume, overwrite, executor,
                           progress, command, figure_format)


def _read_run_json(path: Path) -> dict:
    try:
        old = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        why = exc.strerror if isinstance(exc, OSError) else f"not JSON: {exc}"
        raise RunnerError(f"{path}: cannot read this run's description ({why}); restore it, or "
                          "--overwrite to start again") from None
    if not isinstance(old, dict):
        raise RunnerError(f"{path}: expected a JSON object (study, params, seed), got a "
                          f"{type(old).__name__}; restore it, or --overwrite to start again")
    return old


def _run_locked(study, params, tasks, out, seed, workers, resume, overwrite, executor, progress,
                command, fig_format):
    rec_path = out / "records.jsonl"
    meta = {"study": study.name, "params": params, "seed": int(seed)}
    run_json = out / "run.json"
    if rec_path.is_symlink():
        raise RunnerError(f"output: {rec_path} is a symbolic link; the runner does not write "
                          "through links (remove it)")
    if rec_path.exists() and not (resume or overwrite):
        raise RunnerError(f"output: {out} already holds a run; pass --resume to continue it or "
                          "--overwrite to start again")
    if resume and run_json.exists():
        old = _read_run_json(run_json)
        old_meta = {k: old.get(k) for k in meta}
        if json.loads(json.dumps(old_meta)) != json.loads(json.dumps(meta, default=_jsonable)):
            raise RunnerError(f"output: {out} holds a run with different study/params/seed "
                              f"({old_meta}); resume needs the same ones")
        if old.get("version") not in (None, __version__):
            # solver defaults change between versions: the records made by the other one stay,
            # the scenarios left are solved by this one
            print(f"runner: {out} was recorded by qfg {old.get('version')}, this is qfg "
                  f"{__version__}: its recorded scenarios are kept as they are, the rest are run "
                  "by this version (--overwrite to run them all again)", file=sys.stderr)
    if overwrite or not resume:
        try:
            rec_path.unlink(missing_ok=True)
        except OSError as exc:
            raise RunnerError(f"output: cannot remove {rec_path}: {exc.strerror or exc}") from None
    records, good = read_records(rec_path, seed=int(seed))
    if records and not run_json.exists():
        raise RunnerError(f"output: {run_json} is missing, so the study and parameters of the "
                          f"records in {rec_path} cannot be checked; restore it, or --overwrite "
                          "to start again")
    try:
        if rec_path.exists() and good < rec_path.stat().st_size:
            print(f"runner: dropping a partial last record in {rec_path}", file=sys.stderr)
            with open(rec_path, "r+b") as fh:
                fh.truncate(good)
        _atomic_write(run_json, json.dumps({**meta, "version": __version__,
                                            "command": command or " ".join(sys.argv)},
                                           indent=2, default=_jsonable) + "\n")
        # O_APPEND: every record lands at the end; O_NOFOLLOW: never through a planted link
        fd = os.open(rec_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | _NOFOLLOW, 0o666)
    except OSError as exc:
        raise RunnerError(f"output: cannot write {exc.filename or out}: "
                          f"{exc.strerror or exc}") from None
    size = good
    records = [r for r in records if r["index"] < len(tasks)]

    # failed scenarios are tried again on resume
    ok, _ = dedupe_records(records)
    done = {r["index"] for r in ok}
    todo = [i for i in range(len(tasks)) if i not in done]
    by_index = {r["index"]: r for r in ok}
    errors = {}

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(tasks), initial=len(done), desc=study.name, unit="scn",
                   mininterval=1.0, file=sys.stderr, dynamic_ncols=True)
    own = executor is None
    ex = make_executor(workers) if own else executor
    interrupted = False
    stop = None  # why the run stops early (not Ctrl-C): RunAborted
    results = None
    try:
        arglists = ((study.run_task, tasks[i], int(seed), i) for i in todo)
        results = ex.map_unordered(_execute, arglists)
        for rec in results:
            data = _dump(rec).encode("utf-8")
            try:
                _append(fd, data)
            except OSError as exc:  # a full disk, a file gone read-only: stop, keep what is in
                with contextlib.suppress(OSError):
                    os.ftruncate(fd, size)  # drop the partial record (resume would, too)
                stop = RunAborted(
                    f"cannot write {rec_path}: {exc.strerror or exc}; {len(by_index) + len(errors)}"
                    f" of {len(tasks)} scenarios are recorded there (the file ends at the last "
                    "complete record): make room and continue with --resume")
                break
            size += len(data)
            if "rows" in rec:
                by_index.setdefault(rec["index"], rec)
                errors.pop(rec["index"], None)
            elif rec["index"] not in by_index:
                errors[rec["index"]] = rec
            if bar is not None:
                bar.update(1)
                if errors:
                    bar.set_postfix(failed=len(errors))
    except KeyboardInterrupt:
        interrupted = True
    except WorkerLost as exc:
        i = exc.call_args[3] if len(exc.call_args) == 4 else "?"
        stop = RunAborted(
            f"scenario {i}: its worker process died {exc.attempts} times ({exc.reason}; out of "
            f"memory?); {len(by_index) + len(errors)} of {len(tasks)} scenarios are recorded in "
            f"{rec_path}: continue with --resume (--workers 1 shows the scenario's own error)")
    finally:
        os.close(fd)
        if results is not None and hasattr(results, "close"):
            with contextlib.suppress(Exception):
                results.close()
        if own and (interrupted or stop is not None) and hasattr(ex, "terminate"):
            ex.terminate()
        elif own:
            ex.close()
        elif interrupted or stop is not None:
            with contextlib.suppress(Exception):
                ex.close()
        if bar is not None:
            bar.close()
    if interrupted:
        raise RunInterrupted(len(by_index) + len(errors), len(tasks), out) from None
    if stop is not None:
        raise stop

    rows = []
    for i in sorted(by_index):
        for r in by_index[i]["rows"]:
            rows.append({"scenario": i, **r})
    cols = _columns(rows)
    err_path = out / "errors.json"
    errs = [errors[i] for i in sorted(errors)]
    try:
        write_table(out / "rows.csv", rows, [c for c in cols if not c.startswith(TIMING_PREFIX)],
                    digits=None)
        tcols = [c for c in cols if c.startswith(TIMING_PREFIX)]
        if tcols:
            write_table(out / "timings.csv", rows, ["scenario", *tcols], digits=None)
        if errs:
            write_text(err_path, json.dumps(errs, indent=2) + "\n")
        else:
            err_path.unlink(missing_ok=True)
    except OSError as exc:
        raise _outputs_failed(exc, out, rec_path) from None
    if errs:
        print(f"runner: {len(errs)} scenario(s) failed; see {err_path} "
              f"(first: scenario {errs[0]['index']}: {errs[0]['error']})", file=sys.stderr)
    if not by_index:
        raise ScenariosFailed(f"every scenario failed ({len(errs)} of {len(tasks)}); see "
                              f"{err_path} (first: {errs[0]['error'] if errs else '?'})")
    if study.summarize is not None and rows:
        try:
            with use_figure_format(fig_format):
                study.summarize(out, rows, params)
        except OSError as exc:
            raise _outputs_failed(exc, out, rec_path) from None
    return rows


def _outputs_failed(exc: OSError, out: Path, rec_path: Path) -> RunAborted:
    return RunAborted(f"writing the outputs: {exc.filename or out}: {exc.strerror or exc}; every "
                      f"scenario is recorded in {rec_path}: fix that and rerun with --resume to "
                      "write the outputs")
