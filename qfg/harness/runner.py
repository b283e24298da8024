"""The experiment runner every study goes through.

A :class:`Study` is three plain functions: ``tasks(params)`` lists the scenarios, ``run_task(task,
rng)`` runs one and returns rows, ``summarize(outdir, rows, params)`` writes tables and figures;
optionally a parameter spec (:class:`Param`, :func:`param_spec`) so that bad parameters are
rejected, naming the parameter, before anything runs. :func:`run_study` runs the scenarios and
guarantees (``docs/runner.md``):

* one seeded random stream per scenario, ``SeedSequence(seed, spawn_key=(index,))``, so the numbers
  do not depend on the worker count or the order scenarios finish in;
* a record per scenario appended to ``records.jsonl`` as it finishes; ``resume=True`` skips finished
  scenarios, a partial last line left by a kill is detected and dropped, and records are
  de-duplicated by scenario index when read (the first complete record of a scenario counts);
* one run per output directory at a time: a lock file (``run.lock``: the holder's PID and host) is
  held while running; a lock whose holder is dead is taken over, a live one refuses the run. The
  lock is taken before the directory is inspected, so of two runs started together on a fresh
  directory exactly one proceeds;
* a scenario that raises is recorded with its index, seed and traceback, and the run goes on; a
  run in which every scenario failed raises :class:`ScenariosFailed`;
* nothing lost: a pool worker killed by a signal has its scenarios rerun one at a time (a
  scenario whose worker dies ``retries + 1`` times alone raises :class:`RunAborted`); a full disk
  or an unwritable records file cuts the file back to its last complete record and raises
  :class:`RunAborted` (one line; ``resume`` continues); records carry their seed and are checked
  (index, rows, seed) with the file and line when read;
* outputs are written to a temporary file in the folder and renamed (:func:`write_text`): a
  link planted at an output's name is replaced, never written through;
* worker processes exit when the main process dies (even by SIGKILL), and ignore Ctrl-C, which
  the main process turns into :class:`RunInterrupted` (finished scenarios are kept for
  ``resume``);
* a progress bar with rate and time left;
* execution behind an :class:`Executor` (in-process, a local process pool, or a cluster), so that
  studies never see how they are run.

Outputs in the output directory: ``run.json`` (study, params, seed, command, version),
``records.jsonl`` (raw, completion order), ``rows.csv`` (sorted by scenario, no timing columns:
identical for identical inputs), ``timings.csv`` (columns whose name starts with ``time``),
``errors.json`` when any scenario failed, then whatever ``summarize`` writes: tables
(:func:`write_table`), the headline table on stdout (:func:`print_table`) and figures in
``figures/`` (:func:`save_figure`, in the run's figure format).

>>> spec = param_spec({"n": 10, "sigma": [1.0, 2.0], "mode": "fast"}, n={"min": 1},
...                   sigma={"min": 0.0}, mode={"choices": ("fast", "full")})
>>> validate_params(spec, {"n": 3})
{'n': 3, 'sigma': [1.0, 2.0], 'mode': 'fast'}
>>> validate_params(spec, {"n": -1})
Traceback (most recent call last):
...
qfg.harness.runner.RunnerError: n: expected an integer >= 1, got -1
"""

from __future__ import annotations

import contextlib
import contextvars
import csv
import io
import json
import os
import signal
import socket
import sys
import tempfile
import threading
import time
import traceback
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator, Mapping, Protocol

import numpy as np

from qfg._version import __version__

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - 3.10
    import tomli as tomllib

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: the PID-file fallback below
    fcntl = None

__all__ = [
    "Study",
    "Param",
    "param_spec",
    "validate_params",
    "Executor",
    "SerialExecutor",
    "ProcessExecutor",
    "make_executor",
    "scenario_rng",
    "run_study",
    "read_records",
    "dedupe_records",
    "OutputLock",
    "check_output",
    "load_presets",
    "preset_path",
    "presets_dir",
    "RunnerError",
    "OutputInUse",
    "ScenariosFailed",
    "RunInterrupted",
    "RunAborted",
    "WorkerLost",
    "write_text",
    "write_table",
    "format_table",
    "print_table",
    "save_figure",
    "figure_format",
    "FIGURE_FORMATS",
    "TIMING_PREFIX",
    "LOCK_NAME",
]

#: Row columns whose name starts with this are timings: written to timings.csv, not rows.csv.
TIMING_PREFIX = "time"
#: The lock file a running study holds in its output directory.
LOCK_NAME = "run.lock"
#: Open flag that refuses to follow a symlink (0 where the platform has none).
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
#: Figure formats ``--format`` accepts.
FIGURE_FORMATS = ("png", "pdf", "svg")


class RunnerError(ValueError):
    """A study, its parameters or an output directory that cannot be run as asked (exit 2)."""


class OutputInUse(RunnerError):
    """The output directory is locked by another run that is still alive."""


class ScenariosFailed(RuntimeError):
    """Every scenario of a run failed (exit 1); the details are in ``errors.json``."""


class RunAborted(RuntimeError):
    """The run stopped for a reason outside the study (exit 1): a full disk or an unwritable
    output file, a worker process that dies every time it runs a scenario. Every scenario
    recorded before stays in ``records.jsonl`` (which ends at its last complete record) and
    ``resume`` continues from there."""


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C during a run: ``done`` of ``total`` scenarios are recorded and ``resume`` continues.

    A KeyboardInterrupt, so code that does not know the runner still stops.
    """

    def __init__(self, done: int, total: int, output: Path):
        super().__init__(f"interrupted after {done} of {total} scenarios; continue with --resume")
        self.done, self.total, self.output = done, total, Path(output)

    def __str__(self):
        return self.args[0]


# ----------------------------------------------------------------------------------------------
# studies and their parameters


@dataclass(frozen=True)
class Param:
    """What one study parameter accepts.

    Attributes:
        default: the value when the preset and ``--set`` do not give one; its type is the
            parameter's type (int, float, str, bool, list of those, dict).
        min, max: inclusive bounds for numbers (each element for a list of numbers).
        choices: the allowed values of a string (each element for a list of strings).
        nonempty: a list must have at least one element.
    """

    default: object
    min: float | None = None
    max: float | None = None
    choices: tuple | None = None
    nonempty: bool = False

    def check(self, name: str, value):
        """``value`` converted to the parameter's type (int -> float), or RunnerError naming it."""
        d = self.default
        if isinstance(d, list):
            if not isinstance(value, (list, tuple)):
                raise RunnerError(f"{name}: expected a list, got {value!r}")
            if self.nonempty and not value:
                raise RunnerError(f"{name}: expected a non-empty list")
            elem = Param(d[0] if d else None, self.min, self.max, self.choices)
            if not d:  # no element type to check against
                return list(value)
            return [elem.check(f"{name}[{i}]", v) for i, v in enumerate(value)]
        if isinstance(d, bool):
            if not isinstance(value, bool):
                raise RunnerError(f"{name}: expected true or false, got {value!r}")
            return value
        if isinstance(d, int):
            if isinstance(value, bool) or not isinstance(value, int):
                raise RunnerError(f"{name}: expected an integer{self._range()}, got {value!r}")
            self._bounds(name, value, "an integer")
            return value
        if isinstance(d, float):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise RunnerError(f"{name}: expected a number{self._range()}, got {value!r}")
            if not np.isfinite(value):
                raise RunnerError(f"{name}: expected a finite number, got {value!r}")
            self._bounds(name, value, "a number")
            return float(value)
        if isinstance(d, str):
            if not isinstance(value, str):
                raise RunnerError(f"{name}: expected a string, got {value!r}")
            if self.choices is not None and value not in self.choices:
                raise RunnerError(f"{name}: expected one of {', '.join(map(repr, self.choices))}, "
                                  f"got {value!r}")
            return value
        if isinstance(d, dict):
            if not isinstance(value, dict):
                raise RunnerError(f"{name}: expected a table (dict), got {value!r}")
            return value
        return value  # None default: anything

    def _range(self):
        lo = f" >= {self.min:g}" if self.min is not None else ""
        hi = f" <= {self.max:g}" if self.max is not None else ""
        return lo + ("," if lo and hi else "") + hi

    def _bounds(self, name, value, what):
        if (self.min is not None and value < self.min) or (self.max is not None and value > self.max):
            raise RunnerError(f"{name}: expected {what}{self._range()}, got {value!r}")


def param_spec(defaults: Mapping, **constraints) -> dict[str, Param]:
    """A parameter spec from a study's defaults: each parameter's type is its default's;
    ``constraints`` add bounds or choices, e.g. ``n_per_level={"min": 1}``."""
    unknown = set(constraints) - set(defaults)
    if unknown:
        raise ValueError(f"constraints: not parameters: {sorted(unknown)}")
    return {k: Param(v, **constraints.get(k, {})) for k, v in defaults.items()}


def validate_params(spec: Mapping[str, Param], params: Mapping) -> dict:
    """``params`` merged over the spec's defaults, every value checked; RunnerError naming the
    first bad or unknown parameter."""
    unknown = sorted(set(params) - set(spec))
    if unknown:
        raise RunnerError(f"params: unknown {', '.join(unknown)}; known: {', '.join(sorted(spec))}")
    out = {}
    for name, p in spec.items():
        out[name] = p.check(name, params[name]) if name in params else p.default
    return out


@dataclass(frozen=True)
class Study:
    """A study: what its scenarios are, how one runs, and how results are summarized.

    Attributes:
        name: command-line name (``"single-triplet"``).
        tasks: ``params -> list[dict]``: one JSON-serializable description per scenario.
        run_task: ``(task, rng) -> list[dict]``: rows of scalars (str, int, float, bool) for one
            scenario. Must be a module-level function (it is pickled to worker processes).
        summarize: ``(outdir, rows, params) -> None``: tables, figures, summary.json, and the
            headline table printed (:func:`print_table`).
        description: one line for ``qfg experiment list``.
        params: the parameter spec (:func:`param_spec`); given, parameters are checked before the
            run (:func:`validate_params`) and ``tasks`` receives them as given.
    """

    name: str
    tasks: Callable[[dict], list]
    run_task: Callable[[dict, np.random.Generator], list]
    summarize: Callable[[Path, list, dict], None] | None = None
    description: str = ""
    params: Mapping[str, Param] | None = None

    def check_params(self, params: Mapping) -> None:
        """RunnerError naming the first bad parameter (nothing without a spec)."""
        if self.params is not None:
            validate_params(self.params, params)


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


# ----------------------------------------------------------------------------------------------
# executors


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


def _pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this host (True when it cannot be told)."""
    if os.name != "posix":  # pragma: no cover - os.kill(pid, 0) would terminate it on Windows
        return True
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True
    return True


def _die_with(main_pid: int, parent_pid: int, poll: float = 0.5):
    """Exit this worker as soon as the main process or the direct parent is gone."""
    while True:
        time.sleep(poll)
        if os.getppid() != parent_pid or not _pid_alive(main_pid):
            os._exit(1)


def _worker_init(main_pid: int):
    """Pool worker set-up: ignore Ctrl-C (the main process handles it for the whole run) and
    exit when the main process dies, even by SIGKILL: Linux's parent-death signal, and a
    watcher thread everywhere (reparenting changes ``getppid``)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = os.getppid()
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG = 1
        except (OSError, AttributeError):  # pragma: no cover - no libc: the thread still works
            pass
    if parent != main_pid and not _pid_alive(main_pid) or parent == 1:
        os._exit(1)  # the parent died before the signal was armed
    threading.Thread(target=_die_with, args=(main_pid, parent), daemon=True,
                     name="qfg-parent-watch").start()


class WorkerLost(RuntimeError):
    """A call whose worker process died (a signal, ``os._exit``) every time it ran, alone in the
    pool, ``retries + 1`` times. ``args`` is the call's argument tuple, ``reason`` how the
    worker died (``"killed by SIGKILL"``)."""

    def __init__(self, args: tuple, reason: str, attempts: int):
        super().__init__(f"a worker process died {attempts} times running the same call "
                         f"({reason})")
        self.call_args, self.reason, self.attempts = args, reason, attempts


def _death_reason(procs) -> str:
    """How the dead ones of ``procs`` (multiprocessing Processes) ended, e.g. "killed by
    SIGKILL". The pool terminates the survivors of a break with SIGTERM, so another cause wins."""
    codes = [p.exitcode for p in procs if p.exitcode not in (None, 0)]
    codes.sort(key=lambda c: c == -signal.SIGTERM)
    if not codes:
        return "exited"
    c = codes[0]
    if c < 0:
        with contextlib.suppress(ValueError):
            return f"killed by {signal.Signals(-c).name}"
        return f"killed by signal {-c}"
    return f"exited with status {c}"


_END = object()


class ProcessExecutor:
    """A local process pool (``--workers N``), at most ``2 N`` calls in flight. Workers ignore
    Ctrl-C and die with the main process (:func:`_worker_init`).

    A worker that dies (killed by a signal: the OOM killer, a segfault, ``kill -9``) breaks the
    whole pool and every call in flight is lost. The pool is then restarted and the lost calls
    are run again one at a time, so that a break while a call runs alone is that call's own
    doing: a call that kills its worker ``retries + 1`` times alone raises :class:`WorkerLost`.
    Calls that merely shared the pool with a dying worker are never blamed.
    """

    def __init__(self, workers: int, retries: int = 2):
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise RunnerError(f"workers: expected an integer >= 1, got {workers!r}")
        if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
            raise RunnerError(f"retries: expected an integer >= 0, got {retries!r}")
        self.workers, self.retries = workers, retries
        self.restarts = 0  # pool restarts after a worker died, for reports and tests
        self._procs: dict = {}
        self._pool = self._new_pool()

    def _new_pool(self):
        return ProcessPoolExecutor(max_workers=self.workers, initializer=_worker_init,
                                   initargs=(os.getpid(),))

    def _submit(self, pending, fn, args, attempts) -> bool:
        """Submit one call; False when the pool broke since the last look (nothing submitted)."""
        try:
            pending[self._pool.submit(fn, *args)] = (args, attempts)
        except BrokenProcessPool:
            return False
        # remember the worker processes: after a break the pool forgets them, and their exit
        # codes say how the worker died
        self._procs.update(getattr(self._pool, "_processes", None) or {})
        return True

    def map_unordered(self, fn, arglists):
        it = iter(arglists)
        pending: dict = {}    # future -> (args, times it ran alone and its worker died)
        suspects: list = []   # calls lost in a break, run again one at a time
        backlog: list = []    # calls not submitted because the pool had just broken
        fruitless = 0         # restarts in a row with no call finished: a pool that cannot start
        alone = False
        while True:
            broke = False
            if suspects:
                if not pending:
                    item = suspects.pop(0)
                    if self._submit(pending, fn, *item):
                        alone = True
                    else:
                        suspects.insert(0, item)
                        broke = True
            else:
                alone = False
                while len(pending) < 2 * self.workers:
                    args = backlog.pop(0) if backlog else next(it, _END)
                    if args is _END:
                        break
                    if not self._submit(pending, fn, args, 0):
                        backlog.insert(0, args)
                        broke = True
                        break
            if not pending and not broke:
                return
            lost = []
            first = True
            while pending:
                # after a break every call in flight fails at once (or finished just before)
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for f in done:
                    args, attempts = pending.pop(f)
                    try:
                        res = f.result()
                    except BrokenProcessPool:
                        lost.append((args, attempts))
                        continue
                    fruitless = 0
                    yield res
                if first and not lost and not broke:
                    break  # the usual case: refill
                first = False
            if not lost and not broke:
                continue
            reason = self._restart()
            fruitless += 1
            if alone and lost:
                (args, attempts), = lost
                if attempts + 1 > self.retries:
                    raise WorkerLost(args, reason, attempts + 1)
                suspects.insert(0, (args, attempts + 1))
            else:
                suspects.extend(lost)
            if fruitless > 3 * (self.retries + 1):
                raise WorkerLost(suspects[0][0] if suspects else (backlog[0] if backlog else ()),
                                 reason, fruitless)

    def _restart(self) -> str:
        """A fresh pool after a break; returns how the old pool's worker died."""
        old = list(self._procs.values())
        self._pool.shutdown(wait=False, cancel_futures=True)
        for p in old:
            with contextlib.suppress(Exception):
                p.join(5)
        reason = _death_reason(old)
        self._procs = {}
        self._pool = self._new_pool()
        self.restarts += 1
        return reason

    def worker_pids(self) -> list[int]:
        return [p.pid for p in (getattr(self._pool, "_processes", None) or {}).values()]

    def terminate(self):
        """Stop now: cancel what has not started and kill the workers (Ctrl-C)."""
        procs = list((getattr(self._pool, "_processes", None) or {}).values())
        self._pool.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            with contextlib.suppress(Exception):
                p.kill()
        for p in procs:
            with contextlib.suppress(Exception):
                p.join(5)

    def close(self):
        self._pool.shutdown(wait=True, cancel_futures=True)


def _check_workers(workers):
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise RunnerError(f"workers: expected an integer >= 1, got {workers!r}")
    return int(workers)


def make_executor(workers: int = 1, scheduler: str | None = None) -> Executor:
    """The executor for ``--workers`` / ``--scheduler``: serial, process pool, or a cluster."""
    if scheduler:
        from qfg.harness import cluster  # optional extra: dask.distributed

        try:
            return cluster.DaskExecutor(scheduler)
        except ImportError as exc:  # not installed: one line saying how to install it
            raise RunnerError(str(exc)) from None
    workers = _check_workers(workers)
    return SerialExecutor() if workers == 1 else ProcessExecutor(workers)


# ----------------------------------------------------------------------------------------------
# the output directory: checks and lock


def check_output(path) -> Path:
    """``path`` as a directory that exists or can be made (parents included); RunnerError when
    it, or a parent, is a file."""
    out = Path(path)
    for p in (out, *out.parents):
        if p.exists() and not p.is_dir():
            what = "is a file" if p == out else f"is inside {p}, which is a file"
            raise RunnerError(f"output: {out} {what}; give a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RunnerError(f"output: cannot create {out}: {exc.strerror or exc}") from None
    return out


def _host() -> str:
    return socket.gethostname()


class OutputLock:
    """The lock of one output directory: ``<dir>/run.lock`` holding the holder's PID and host.

    POSIX: the file is also ``flock``-ed, so the kernel releases it when the holder dies however
    it dies; a lock file left by a dead holder is taken over (and said so), after waiting up to
    ``stale_wait`` seconds for the holder's dying worker processes to let go. Elsewhere: the file
    is created exclusively and a holder whose PID is no longer running on this host is stale. A
    lock held from another host is never broken automatically (its PID cannot be checked here).
    Use as a context manager.
    """

    def __init__(self, directory, stale_wait: float = 10.0):
        self.path = Path(directory) / LOCK_NAME
        self.stale_wait = float(stale_wait)
        self._fd = None
        self.took_over: dict | None = None

    def _read(self) -> dict:
        try:
            text = self.path.read_text(encoding="utf-8", errors="replace")
            rec = json.loads(text) if text.strip() else {}
            return rec if isinstance(rec, dict) else {}
        except (OSError, json.JSONDecodeError):
            return {}

    def _busy(self, holder: dict) -> OutputInUse:
        who = (f"pid {holder.get('pid', '?')} on host {holder.get('host', '?')}"
               if holder else "another process")
        extra = ("" if holder.get("host", _host()) == _host() else
                 f"; if that run is over, delete {self.path}")
        return OutputInUse(f"output: {self.path.parent} is in use by {who} (lock file "
                           f"{self.path}){extra}")

    def _stale(self, holder: dict) -> bool:
        return bool(holder) and holder.get("host") == _host() and not _pid_alive(holder.get("pid", 0))

    def acquire(self) -> OutputLock:
        try:
            return self._acquire()
        except OSError as exc:  # e.g. a read-only directory: one line, not a traceback
            raise RunnerError(f"output: cannot lock {self.path}: {exc.strerror or exc}") from None

    def _acquire(self) -> OutputLock:
        me = {"pid": os.getpid(), "host": _host(), "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
        give_up = time.monotonic() + self.stale_wait
        for _ in range(1000):
            if fcntl is not None:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | _NOFOLLOW, 0o644)
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except OSError:
                    os.close(fd)
                    holder = self._read()
                    # a holder just killed leaves the lock to its dying workers for a moment
                    if self._stale(holder) and time.monotonic() < give_up:
                        time.sleep(0.1)
                        continue
                    raise self._busy(holder) from None
                try:  # a holder releasing unlinks the file: ours must still be the one named
                    same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
                except FileNotFoundError:
                    same = False
                if not same:
                    os.close(fd)
                    continue
                holder = self._read()
                if holder and holder.get("host") != _host():
                    os.close(fd)  # flock may not reach across hosts: do not guess
                    raise self._busy(holder)
                if holder:
                    self.took_over = holder  # flock was free: its holder is gone
                os.ftruncate(fd, 0)
                os.write(fd, (json.dumps(me) + "\n").encode())
                os.fsync(fd)
                self._fd = fd
                return self
            try:  # pragma: no cover - exercised on POSIX by monkeypatching fcntl away
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o644)
            except FileExistsError:
                holder = self._read()
                if not self._stale(holder):
                    raise self._busy(holder) from None
                grave = self.path.with_name(f"{LOCK_NAME}.stale-{os.getpid()}")
                try:
                    os.replace(self.path, grave)
                except FileNotFoundError:
                    continue
                try:
                    back = json.loads(grave.read_text())
                except (OSError, json.JSONDecodeError):
                    back = {}
                if back != holder:  # moved a fresh lock of someone else: put it back
                    os.replace(grave, self.path)
                    continue
                grave.unlink(missing_ok=True)
                self.took_over = holder
                continue
            os.write(fd, (json.dumps(me) + "\n").encode())
            os.fsync(fd)
            self._fd = fd
            return self
        raise OutputInUse(f"output: could not lock {self.path}")

    def release(self) -> None:
        if self._fd is None:
            return
        with contextlib.suppress(OSError):
            if os.fstat(self._fd).st_ino == os.stat(self.path).st_ino:
                self.path.unlink()
        os.close(self._fd)
        self._fd = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()


# ----------------------------------------------------------------------------------------------
# records.jsonl


def _record_problem(rec) -> str | None:
    """What makes ``rec`` not a runner record (None if it is one)."""
    if not isinstance(rec, dict):
        return f"expected a JSON object, got {type(rec).__name__}"
    i = rec.get("index")
    if isinstance(i, bool) or not isinstance(i, int) or i < 0:
        return f"index: expected an integer >= 0, got {i!r}"
    if "rows" in rec:
        rows = rec["rows"]
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            return f"rows: expected a list of objects, got {json.dumps(rows)[:60]}"
    elif not isinstance(rec.get("error"), str):
        return "expected rows or an error"
    return None


def read_records(path: Path, seed: int | None = None) -> tuple[list[dict], int]:
    """Complete records of a records file, and the byte length of its complete part.

    A last line without its newline (a kill mid-write) or that is not valid JSON is not data: it
    is left out and the returned length stops before it, so the caller can truncate it away.
    Records are returned as written (see :func:`dedupe_records`). A line that is not a record
    (an ``index`` that is not an integer >= 0, ``rows`` that are not a list of objects), a corrupt
    line before the last, or with ``seed`` given a record made with another seed, raises
    RunnerError naming the file and line.
    """
    path = Path(path)
    if not path.exists():
        return [], 0
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RunnerError(f"{path}: cannot read the records: {exc.strerror or exc}") from None
    records, good = [], 0
    pos = 0
    while pos < len(data):
        nl = data.find(b"\n", pos)
        if nl < 0:
            break  # partial last line
        line = data[pos:nl]
        lineno = data.count(b"\n", 0, pos) + 1
        try:
            rec = json.loads(line)
        except (json.JSONDecodeError, UnicodeDecodeError):
            if data.find(b"\n", nl + 1) >= 0:
                raise RunnerError(f"{path}:{lineno}: corrupt record in the middle of the file; "
                                  "not resuming over it") from None
            break  # garbled last line
        problem = _record_problem(rec)
        if problem:
            raise RunnerError(f"{path}:{lineno}: not a runner record ({problem})")
        if seed is not None and rec.get("seed") != [seed, rec["index"]]:
            # the records carry the seed, so a resume with another seed is refused even when
            # run.json is gone
            raise RunnerError(f"{path}:{lineno}: scenario {rec['index']} was recorded with seed "
                              f"{rec.get('seed')!r}, not [{seed}, {rec['index']}]: resume with "
                              "the run's own seed, or --overwrite to start again")
        records.append(rec)
        pos = nl + 1
        good = pos
    return records, good


def dedupe_records(records: list[dict]) -> tuple[list[dict], list[dict]]:
    """(successful, failed) records, one per scenario index: the first successful record of a
    scenario wins, and a scenario counts as failed only if it never succeeded (its last
    failure). Both sorted by index."""
    ok, failed = {}, {}
    for rec in records:
        i = rec["index"]
        if "rows" in rec:
            ok.setdefault(i, rec)
        else:
            failed[i] = rec
    return ([ok[i] for i in sorted(ok)],
            [failed[i] for i in sorted(failed) if i not in ok])


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


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def _replacing(path):
    """A binary file object whose content replaces ``path`` when the block ends without error.

    Written to a new temporary file in the same folder (created exclusively, so a link planted
    there is never followed), then renamed over ``path``: a symlink at ``path`` is replaced, its
    target untouched, and a reader never sees half a file. On error the temporary file is
    removed and ``path`` is as it was.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp's 0600 would hide outputs from others
        with os.fdopen(fd, "wb") as fh:
            yield fh
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically, replacing a link there instead of writing
    through it (see :func:`_replacing`). Returns the path."""
    with _replacing(path) as fh:
        fh.write(text.encode("utf-8"))
    return Path(path)


_atomic_write = write_text


def _append(fd: int, data: bytes) -> None:
    """All of ``data`` to ``fd`` (os.write may write part of it)."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


# ----------------------------------------------------------------------------------------------
# tables and figures (one implementation for every study)


def _cell(v, digits) -> str:
    if isinstance(v, (float, np.floating)) and digits is not None:
        return f"{v:.{digits}g}"
    return "" if v is None else str(v)


def _columns(rows):
    cols = {}
    for r in rows:
        for k in r:
            cols.setdefault(k, None)
    return list(cols)


def write_table(path, recs: list[dict], columns: list[str] | None = None, *,
                digits: int | None = 6) -> Path:
    """Write records (dicts) as CSV: columns in first-seen order (or ``columns``), floats to
    ``digits`` significant digits (None: every digit, as for ``rows.csv``), missing cells empty.
    Returns the path."""
    cols = list(columns) if columns is not None else _columns(recs)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in recs:
        w.writerow([_cell(r.get(k), digits) for k in cols])
    return write_text(path, buf.getvalue())


def format_table(recs: list[dict], columns: list[str] | None = None, *, digits: int = 3) -> str:
    """Records as an aligned plain-text table (floats to ``digits`` significant digits).

    >>> print(format_table([{"method": "fast", "dmse": 0.21234}, {"method": "full", "dmse": 0.16}]))
    method   dmse
    fast    0.212
    full     0.16
    """
    cols = list(columns) if columns is not None else _columns(recs)

    def cell(v):
        if isinstance(v, float):
            return f"{v:.{digits}g}"
        return "" if v is None else str(v)

    cells = [[cell(r.get(k)) for k in cols] for r in recs]
    width = [max([len(c), *(len(row[i]) for row in cells)]) for i, c in enumerate(cols)]
    num = [all(_numeric(row[i]) for row in cells) for i in range(len(cols))]

    def line(vals):
        return "  ".join(v.rjust(w) if n else v.ljust(w)
                         for v, w, n in zip(vals, width, num, strict=True)).rstrip()

    return "\n".join([line(cols), *(line(row) for row in cells)])


def _numeric(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return s == ""
    return True


def print_table(recs: list[dict], columns: list[str] | None = None, *, title: str | None = None,
                digits: int = 3) -> str:
    """Print a study's headline table (and its title) to stdout; returns the text."""
    text = format_table(recs, columns, digits=digits)
    if title:
        text = f"{title}\n{text}"
    print(text)
    return text


_FORMAT: contextvars.ContextVar[str] = contextvars.ContextVar("qfg_figure_format", default="png")


def figure_format() -> str:
    """The figure format of the run in progress (``--format``; default png)."""
    return _FORMAT.get()


@contextlib.contextmanager
def use_figure_format(fmt: str):
    """Within the block, :func:`save_figure` writes ``fmt`` (png, pdf or svg)."""
    if fmt not in FIGURE_FORMATS:
        raise RunnerError(f"format: expected one of {', '.join(FIGURE_FORMATS)}, got {fmt!r}")
    token = _FORMAT.set(fmt)
    try:
        yield fmt
    finally:
        _FORMAT.reset(token)


def save_figure(fig, outdir, name: str, *, dpi: int = 130, fmt: str | None = None) -> Path:
    """Write ``fig`` as ``<outdir>/figures/<name>.<format>`` (the run's format unless ``fmt``),
    creating the folder; close it; return the path. Every study's figures go through here."""
    fmt = fmt or figure_format()
    if fmt not in FIGURE_FORMATS:
        raise RunnerError(f"format: expected one of {', '.join(FIGURE_FORMATS)}, got {fmt!r}")
    figdir = Path(outdir) / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    path = figdir / f"{name}.{fmt}"
    import matplotlib.pyplot as plt

    try:
        with _replacing(path) as fh:
            fig.savefig(fh, dpi=dpi, format=fmt)
    finally:
        plt.close(fig)
    return path


# ----------------------------------------------------------------------------------------------
# running


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


# ----------------------------------------------------------------------------------------------
# presets


def presets_dir():
    """Where study presets live: ``$QFG_EXPERIMENTS`` if set, else the package data
    ``qfg/_presets`` (in a checkout: the top-level ``experiments/``)."""
    env = os.environ.get("QFG_EXPERIMENTS")
    if env:
        return Path(env)
    from importlib.resources import files

    return Path(str(files("qfg") / "_presets")).resolve()


#: Former name, kept importable.
experiments_dir = presets_dir


def preset_path(name: str) -> Path:
    """The preset file of study ``name``: ``<presets_dir>/<name>.toml`` (``-`` read as ``_``); an
    absolute path, so that messages name a file a pip user has."""
    return (presets_dir() / f"{name.replace('-', '_')}.toml").absolute()


def load_presets(name: str) -> dict[str, dict]:
    """Presets of a study from its preset file (:func:`preset_path`)."""
    path = preset_path(name)
    if not path.exists():
        raise RunnerError(f"study {name!r}: no preset file {path}")
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise RunnerError(f"{path}: {exc}") from None
    return {k: v for k, v in data.items() if isinstance(v, dict)}
