"""Files replaced whole: a write that fails leaves the old file as it was.

:func:`atomic_write_text`, :func:`atomic_write_bytes` and the context manager
:func:`atomic_writer` write to a temporary file in the target's own folder (hidden,
``.NAME.<random>.tmp``), flush and ``fsync`` it, then ``os.replace`` it onto the target (one
rename: a reader, or a process killed at any moment, sees the old file or the new one, never a
part) and ``fsync`` the folder where the system allows it, so the rename itself survives a power
cut. On any failure (a full disk, a file size limit, an exception in the ``with`` block) the
temporary file is removed and the error raised; only a process killed outright (SIGKILL, power
loss) can leave a temporary file behind, never a damaged target.

What the target is decides how it is written:

* a regular file, or nothing yet: replaced as above. The new file keeps an existing file's
  permission bits; a new one gets the usual ``0o666`` less the umask (not the ``0o600`` of
  :func:`tempfile.mkstemp`).
* a symbolic link to a regular file, or to nothing: the link itself is replaced by the new file,
  its target untouched. Nothing is written through a link planted in an output folder.
* a character device or a pipe, named directly or through a link (``/dev/null``,
  ``/dev/stdout``, ``/dev/full``, a FIFO): written to in place, since replacing it would swap
  the device for a regular file rather than send it the data; a failing write (``/dev/full``: no
  space left) raises as usual. A block device is refused (``OSError``, EINVAL).

Errors are :class:`OSError` with the path: the target is a folder (``IsADirectoryError``), its
folder is missing or is a file, no permission, no space. The folder is never created here.

>>> import os, tempfile
>>> p = os.path.join(tempfile.mkdtemp(), "result.txt")
>>> atomic_write_text(p, "old\\n")
>>> try:
...     with atomic_writer(p) as f:
...         _ = f.write("half of the new")
...         raise RuntimeError("the writer failed")
... except RuntimeError:
...     pass
>>> open(p).read(), sorted(os.listdir(os.path.dirname(p)))
('old\\n', ['result.txt'])
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import stat
from pathlib import Path

__all__ = ["atomic_write_text", "atomic_write_bytes", "atomic_writer"]


def atomic_write_text(path, text: str, *, encoding: str = "utf-8", newline: str | None = None
                      ) -> None:
    """Replace ``path`` by a file holding ``text``, whole or not at all (module docstring)."""
    with atomic_writer(path, "w", encoding=encoding, newline=newline) as f:
        f.write(text)


def atomic_write_bytes(path, data: bytes) -> None:
    """Replace ``path`` by a file holding ``data``, whole or not at all (module docstring)."""
    with atomic_writer(path, "wb") as f:
        f.write(data)


@contextlib.contextmanager
def atomic_writer(path, mode: str = "w", *, encoding: str | None = "utf-8",
                  newline: str | None = None):
    """A file object (``mode`` ``"w"`` text or ``"wb"`` binary) whose content replaces ``path``
    when the ``with`` block ends without an exception; on an exception, or a failing write,
    flush or replace, ``path`` is left as it was and the temporary file removed."""
    if mode not in ("w", "wb"):
        raise ValueError(f"mode: expected 'w' or 'wb', got {mode!r}")
    kw = {} if mode == "wb" else {"encoding": encoding, "newline": newline}
    target = Path(path)
    own = _stat(target, follow=False)           # the name itself (a link is not followed)
    st = _stat(target, follow=True) if own is not None and stat.S_ISLNK(own.st_mode) else own
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise IsADirectoryError(errno.EISDIR, "Is a directory", str(path))
    if st is not None and stat.S_ISBLK(st.st_mode):
        raise OSError(errno.EINVAL, "a block device: not written to", str(path))
    if st is not None and (stat.S_ISCHR(st.st_mode) or stat.S_ISFIFO(st.st_mode)):
        # a device or a pipe: the data goes to it (see the module docstring)
        try:
            with open(target, mode, **kw) as f:
                yield f
                f.flush()
        except OSError as exc:
            named = _named(exc, target)
            if named is exc:
                raise
            raise named from exc
        return
    # a regular file keeps its permission bits; a replaced link does not pass on its target's
    fd, tmp = _create_beside(target, own if own is not None and stat.S_ISREG(own.st_mode)
                             else None)
    try:
        with os.fdopen(fd, mode, **kw) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        named = _named(exc, target) if isinstance(exc, OSError) else exc
        if named is exc:
            raise
        raise named from exc
    _fsync_folder(target.parent)


def _stat(path: Path, *, follow: bool):
    """``os.stat`` / ``os.lstat`` of ``path``, None when there is nothing (or a dangling link)
    there."""
    try:
        return os.stat(path) if follow else os.lstat(path)
    except FileNotFoundError:
        return None


def _named(exc: OSError, target: Path) -> OSError:
    """A failed write names no file: the same error naming the target (not the temporary
    file)."""
    if exc.filename is None and exc.errno is not None:
        return type(exc)(exc.errno, exc.strerror, str(target))
    return exc


def _create_beside(target: Path, st) -> tuple[int, str]:
    """A new, empty, hidden file in ``target``'s folder: (descriptor, path)."""
    folder = target.parent
    for _ in range(100):
        tmp = os.path.join(folder, f".{target.name}.{secrets.token_hex(4)}.tmp")
        try:
            # 0o666: the umask applies, as for a file opened with open(path, "w")
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0),
                         0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            # name the target, not the temporary file the user never asked for
            raise type(exc)(exc.errno, exc.strerror, str(target)) from None
        if st is not None:
            try:
                os.chmod(tmp, stat.S_IMODE(st.st_mode))
            except OSError:
                pass  # a folder that keeps no modes (some network or FAT mounts): keep the default
        return fd, tmp
    raise FileExistsError(errno.EEXIST, "no free temporary name beside it", str(target))


def _fsync_folder(folder: Path) -> None:
    """Make the rename durable where the system allows a folder to be synced (POSIX)."""
    flags = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0)
    try:
        fd = os.open(folder, flags)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass  # e.g. a file system without folder sync: the data itself is already synced
    finally:
        os.close(fd)
