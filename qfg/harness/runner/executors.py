"""Executors: how a run's scenarios are executed, behind one protocol (:class:`Executor`):
in this process (:class:`SerialExecutor`), in a local process pool whose workers die with the
main process and whose lost calls are run again (:class:`ProcessExecutor`), or on a cluster
(:func:`make_executor` with a scheduler: :mod:`qfg.harness.cluster`)."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Iterable, Iterator, Protocol

import numpy as np

from qfg.harness.runner.errors import RunnerError
from qfg.harness.runner.lock import _pid_alive


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
