"""The output directory: :func:`check_output` (a directory that exists or can be made) and its
lock (:class:`OutputLock`, ``run.lock``: one run per output directory at a time)."""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
from pathlib import Path

from qfg.harness.runner.errors import OutputInUse, RunnerError

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: the PID-file fallback below
    fcntl = None


#: The lock file a running study holds in its output directory.
LOCK_NAME = "run.lock"
#: Open flag that refuses to follow a symlink (0 where the platform has none).
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


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


def this_host() -> str:
    """The name of the host this process runs on, as a lock file records it (its ``host``)."""
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
        extra = ("" if holder.get("host", this_host()) == this_host() else
                 f"; if that run is over, delete {self.path}")
        return OutputInUse(f"output: {self.path.parent} is in use by {who} (lock file "
                           f"{self.path}){extra}")

    def _stale(self, holder: dict) -> bool:
        return bool(holder) and holder.get("host") == this_host() and not _pid_alive(holder.get("pid", 0))

    def acquire(self) -> OutputLock:
        try:
            return self._acquire()
        except OSError as exc:  # e.g. a read-only directory: one line, not a traceback
            raise RunnerError(f"output: cannot lock {self.path}: {exc.strerror or exc}") from None

    def _acquire(self) -> OutputLock:
        me = {"pid": os.getpid(), "host": this_host(), "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
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
                if holder and holder.get("host") != this_host():
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
