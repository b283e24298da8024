"""Reading MRCLAM's text tables: plain or gzip, streamed and bounded, every error located.

A table is read in blocks of whole lines, each step naming the file and, where it can, the line:

1. the file: it must be a regular file (a directory, FIFO, device or symlink loop with a data
   file's name is refused before it is opened for reading), not 0 bytes (a real file always has
   its header; an empty file is a failed copy, not a robot that saw nothing) and at most
   :data:`~._constants.MAX_FILE_BYTES` on disk;
2. bytes: ``.gz`` files are inflated with :mod:`zlib` a bounded chunk at a time (gzip members one
   after another), so a gzip bomb stops at ``MAX_FILE_BYTES`` inflated bytes, and a corrupt or
   truncated stream is reported at the first line that did not decode; a file of more than
   :data:`~._constants.MAX_LINES` lines or with a line longer than
   :data:`~._constants.MAX_LINE_BYTES` is refused at that line;
3. text: ``#`` starts a comment. Comments may hold any bytes (they are dropped); a data line must be
   ASCII, so an undecodable or non-ASCII byte there is an error naming the line;
4. numbers: one ``numpy.loadtxt`` call per block; on any failure a line-by-line pass finds the first
   offending line (column count, non-number, non-finite). Column constraints (:class:`Column`)
   are checked vectorized and the first violating row is mapped back to its line.

Memory stays within the parsed table (8 bytes a number, plus a line number per row) and one block.
"""

from __future__ import annotations

import errno
import io
import math
import os
import re
import stat
import warnings
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import _constants as C


class DataFormatError(ValueError):
    """A dataset file is missing or malformed. ``path`` and ``line`` (1-based, or None) locate it.

    The message reads ``"<path>, line <n>: <what is wrong>"``.

    >>> str(DataFormatError("Robot1_Measurement.dat", 7, "column 'range': negative"))
    "Robot1_Measurement.dat, line 7: column 'range': negative"
    """

    def __init__(self, path, line, message):
        self.path = str(path)
        self.line = line
        where = self.path if line is None else f"{self.path}, line {line}"
        super().__init__(f"{where}: {message}")


@dataclass(frozen=True)
class Column:
    """A table column and the values it may hold.

    ``integer``: whole numbers only; ``lo``/``hi``: inclusive bounds (None: unbounded). Every column
    must be finite.
    """

    name: str
    integer: bool = False
    lo: float | None = None
    hi: float | None = None


_IN_CHUNK = 1 << 16      # bytes read from disk at a time
_OUT_CHUNK = 1 << 20     # most bytes one inflate call may produce
_NUMBER = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?|nan)", re.IGNORECASE)
_IS_SPACE = np.zeros(256, dtype=bool)
_IS_SPACE[list(b" \t\n\r\f\v")] = True


def _mib(n: int) -> str:
    return f"{n / 2**20:g} MiB"


def _kind(mode: int) -> str | None:
    """What a non-regular file is, in words (None: a regular file)."""
    if stat.S_ISREG(mode):
        return None
    for test, word in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device")):
        if test(mode):
            return word
    return "not a regular file"  # pragma: no cover - no other kinds on POSIX


def _open_regular(path: Path):
    """``path`` opened for binary reading, after checking it is a regular file of at most
    MAX_FILE_BYTES; DataFormatError naming it otherwise. A FIFO is never opened (that would
    wait for a writer)."""
    try:
        st = os.stat(path)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise DataFormatError(path, None, "a symbolic link loop, not a data file") from None
        raise DataFormatError(path, None, f"could not read the file: {exc.strerror or exc}") from None
    kind = _kind(st.st_mode)
    if kind is not None:
        raise DataFormatError(path, None, f"{kind} with a data file's name, not a data file")
    if st.st_size == 0:
        raise DataFormatError(path, None, "empty file (0 bytes): a dataset file has at least its "
                                          "'#' header; the copy is probably incomplete")
    if st.st_size > C.MAX_FILE_BYTES:
        raise DataFormatError(path, None, f"{st.st_size} bytes, more than an MRCLAM file can "
                                          f"plausibly hold ({_mib(C.MAX_FILE_BYTES)})")
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise DataFormatError(path, None, f"could not read the file: {exc.strerror or exc}") from None
    if _kind(os.fstat(fd).st_mode) is not None:  # replaced between the checks
        os.close(fd)
        raise DataFormatError(path, None, "not a regular file")
    return os.fdopen(fd, "rb")


def _plain_chunks(path: Path, fh):
    total = 0
    while True:
        try:
            b = fh.read(_IN_CHUNK)
        except OSError as exc:
            raise DataFormatError(path, None, f"could not read the file: {exc.strerror or exc}") from None
        if not b:
            return
        total += len(b)
        if total > C.MAX_FILE_BYTES:  # the file grew after it was checked
            raise DataFormatError(path, None, f"more than {_mib(C.MAX_FILE_BYTES)}, more than an "
                                              f"MRCLAM file can plausibly hold")
        yield b


def _inflate_bytewise(d, data: bytes) -> bytes:
    """What decompressor ``d`` yields from ``data`` before it fails, fed byte by byte so that
    no output decoded before the error is lost (bounded: at most ``_OUT_CHUNK`` bytes)."""
    out = []
    n = 0
    try:
        for k in range(len(data)):
            b = d.decompress(data[k:k + 1], _OUT_CHUNK - n)
            out.append(b)
            n += len(b)
            if d.eof or n >= _OUT_CHUNK:
                break
    except zlib.error:
        pass
    return b"".join(out)


def _gzip_chunks(path: Path, fh):
    """Inflated chunks of every gzip member of ``fh``, each at most ``_OUT_CHUNK`` bytes and at
    most MAX_FILE_BYTES in all; DataFormatError at the line where decoding broke."""
    lines = 0
    total = 0
    d = None           # the member being inflated (None: between members)
    members = 0        # members inflated to their end
    padding = False    # zero bytes after a member: gzip allows them, only at the very end
    pending = b""
    at_end = False
    last = None        # output of the last call once the file is read: b"" ends the draining
    while True:
        if not pending and not at_end:
            try:
                pending = fh.read(_IN_CHUNK)
            except OSError as exc:
                raise DataFormatError(path, None, f"could not read the file: {exc.strerror or exc}") from None
            at_end = not pending
        if at_end and not pending and (d is None or last == b""):
            break
        if d is None:
            if members and not pending.strip(b"\0"):
                padding, pending = True, b""
                continue
            if padding:
                raise DataFormatError(path, lines + 1, "corrupt gzip data: bytes after the zero "
                                                       "padding that ends the file")
            d = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)
        saved = d.copy()
        try:
            out = d.decompress(pending, _OUT_CHUNK)
        except zlib.error as exc:
            n = lines + _inflate_bytewise(saved, pending).count(b"\n")
            raise DataFormatError(path, n + 1, f"corrupt gzip data at or after this line ({n} "
                                               f"line(s) decoded before it): {exc}") from None
        if at_end:
            last = out
        if d.eof:
            pending, d, last = d.unused_data, None, None
            members += 1
        else:
            pending = d.unconsumed_tail
        if out:
            total += len(out)
            if total > C.MAX_FILE_BYTES:
                raise DataFormatError(path, lines + out.count(b"\n") + 1,
                                      f"inflates to more than {_mib(C.MAX_FILE_BYTES)}, more than "
                                      f"an MRCLAM file can plausibly hold (a gzip bomb?)")
            lines += out.count(b"\n")
            yield out
    if d is not None or not members:
        raise DataFormatError(path, lines + 1, f"truncated gzip file: the stream ends after {lines} "
                                               f"line(s) without its end marker")


def line_blocks(path):
    """Yield (1-based number of the block's first line, bytes of whole lines) for the file,
    inflated for ``.gz``; the last line need not end in a newline. Every bound of the module
    docstring is checked here."""
    path = Path(path)
    with _open_regular(path) as fh:
        chunks = _gzip_chunks(path, fh) if path.name.endswith(".gz") else _plain_chunks(path, fh)
        first = 1
        carry = b""
        for chunk in chunks:
            data = carry + chunk if carry else chunk
            cut = data.rfind(b"\n") + 1
            block, carry = data[:cut], data[cut:]
            if len(carry) > C.MAX_LINE_BYTES:
                raise DataFormatError(path, first + block.count(b"\n"),
                                      f"line longer than {C.MAX_LINE_BYTES} bytes: not a line "
                                      f"of an MRCLAM file")
            if not block:
                continue
            nl = np.flatnonzero(np.frombuffer(block, dtype=np.uint8) == 10)
            lengths = np.diff(nl, prepend=-1) - 1
            if lengths.size and lengths.max() > C.MAX_LINE_BYTES:
                raise DataFormatError(path, first + int(np.argmax(lengths > C.MAX_LINE_BYTES)),
                                      f"line longer than {C.MAX_LINE_BYTES} bytes: not a line "
                                      f"of an MRCLAM file")
            if first - 1 + nl.size > C.MAX_LINES:
                raise DataFormatError(path, C.MAX_LINES + 1, f"more than {C.MAX_LINES} lines, "
                                                             f"more than an MRCLAM file can "
                                                             f"plausibly hold")
            yield first, block
            first += nl.size
        if carry:
            yield first, carry


def to_text(path: Path, raw: bytes, first: int = 1) -> str:
    """ASCII text of ``raw`` (lines numbered from ``first``) with comments that hold non-ASCII
    bytes blanked (line count kept).

    A non-ASCII or undecodable byte before any ``#`` on its line is a DataFormatError naming the line.

    >>> to_text(Path("f.dat"), "# caf\\xe9 header\\n1 2\\n".encode("latin-1"))
    '\\n1 2\\n'
    """
    if raw.isascii():
        return raw.decode("ascii")
    lines = raw.split(b"\n")
    for no, line in enumerate(lines, start=first):
        if line.isascii():
            continue
        data, hash_, _ = line.partition(b"#")
        if not data.isascii():
            k = next(i for i, b in enumerate(data) if b > 127)
            raise DataFormatError(path, no, f"byte 0x{data[k]:02x} at column {k + 1} is not ASCII "
                                            f"(data lines hold only numbers; only '#' comments may "
                                            f"hold other bytes)")
        lines[no - first] = data  # drop the comment: nothing in it is read
    return b"\n".join(lines).decode("ascii")


def data_lines(text: str, first: int = 1):
    """Yield (line number, fields) for every line that is not blank or a comment, lines numbered
    from ``first``."""
    for no, line in enumerate(text.split("\n"), start=first):
        fields = line.split("#", 1)[0].split()
        if fields:
            yield no, fields


def _first_bad_line(text: str, columns: tuple[Column, ...], first: int = 1):
    """The first data line with the wrong number of columns or a non-number: (line, message)."""
    ncols = len(columns)
    for no, fields in data_lines(text, first):
        if len(fields) != ncols:
            names = ", ".join(c.name for c in columns)
            shown = " ".join(fields)
            shown = shown if len(shown) <= 80 else shown[:77] + "..."
            return no, f"expected {ncols} columns ({names}), got {len(fields)}: {shown!r}"
        for col, tok in zip(columns, fields, strict=True):
            # numpy's reader is stricter than float() (no '1_000', no ' 1 '): accept what both take
            if not _NUMBER.fullmatch(tok):
                tok = tok if len(tok) <= 40 else tok[:37] + "..."
                return no, f"column '{col.name}': expected a number, got {tok!r}"
            val = float(tok)
            if not math.isfinite(val):
                return no, f"column '{col.name}': expected a finite number, got {tok!r}"
    return None


def _parse_block(path: Path, first: int, raw: bytes, columns: tuple[Column, ...]):
    """(rows (k, ncols), their line numbers (k,)) of one block of whole lines."""
    text = to_text(path, raw, first)
    ncols = len(columns)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            data = np.loadtxt(io.StringIO(text), comments="#", dtype=float, ndmin=2)
    except (ValueError, IndexError) as exc:
        bad = _first_bad_line(text, columns, first)
        if bad is None:  # pragma: no cover - numpy failed on something the slow pass accepts
            raise DataFormatError(path, None, f"could not read the table: {exc}") from None
        raise DataFormatError(path, *bad) from None
    if data.size == 0:
        data = np.zeros((0, ncols))
    if data.shape[1] != ncols or not np.all(np.isfinite(data)):
        bad = _first_bad_line(text, columns, first)
        raise DataFormatError(path, *(bad or (None, f"expected {ncols} finite columns")))
    return data, _row_lines(text, data.shape[0], first)


def _row_lines(text: str, n_rows: int, first: int) -> np.ndarray:
    """The line number of each of the ``n_rows`` data rows read from ``text``: cheap when the
    lines that are not data all come first (a header), vectorized otherwise."""
    n_lines = text.count("\n") + (not text.endswith("\n"))
    k = n_lines - n_rows                           # lines loadtxt skipped
    if k == 0:
        return np.arange(first, first + n_rows, dtype=np.int64)
    if k <= 1000:
        head = text.split("\n", k)[:k]
        if not any(True for _ in data_lines("\n".join(head))):   # a header, then only data
            return np.arange(first + k, first + n_lines, dtype=np.int64)
    lines = _data_line_numbers(text.encode("ascii"), first)
    if lines.size != n_rows:  # pragma: no cover - the two readings of the block disagree
        lines = np.fromiter((no for no, _ in data_lines(text, first)), dtype=np.int64)
    return lines


def _data_line_numbers(raw: bytes, first: int) -> np.ndarray:
    """Numbers of the lines of ``raw`` (numbered from ``first``) that hold data: a byte other
    than whitespace before any ``#``. Vectorized over bytes.

    >>> _data_line_numbers(b"# head\\n1 2\\n\\n  # c\\n3 4 # x\\n5", 1).tolist()
    [2, 5, 6]
    """
    a = np.frombuffer(raw, dtype=np.uint8)
    nl = a == 10
    line = np.cumsum(nl) - nl                      # the line of each byte (its newline included)
    n_lines = int(line[-1]) + 1 if a.size else 0
    first_hash = np.full(n_lines, a.size, dtype=np.int64)
    hashes = np.flatnonzero(a == 35)
    if hashes.size:                                # line[hashes] is sorted: first of each run
        hl = line[hashes]
        start = np.concatenate([[True], hl[1:] != hl[:-1]])
        first_hash[hl[start]] = hashes[start]
    ink = np.flatnonzero(~_IS_SPACE[a])
    li = line[ink]
    li = li[ink < first_hash[li]]
    keep = np.concatenate([[True], li[1:] != li[:-1]]) if li.size else np.zeros(0, bool)
    return li[keep].astype(np.int64) + first


@dataclass(frozen=True, eq=False)
class Table:
    """A numeric table read from ``path``: ``data`` (rows, columns) in file order and ``lines``
    (rows,), the 1-based file line of each row."""

    path: Path
    data: np.ndarray
    lines: np.ndarray

    def line_of(self, row: int) -> int | None:
        """File line number (1-based) of the 0-based data row ``row``."""
        return int(self.lines[int(row)]) if 0 <= int(row) < self.lines.size else None

    def error(self, row: int, message: str) -> DataFormatError:
        return DataFormatError(self.path, self.line_of(int(row)), message)


def read_table(path: Path, columns: tuple[Column, ...], *, min_rows: int = 0) -> Table:
    """Read a whitespace-separated numeric table; see the module docstring for the checks.

    Returns a :class:`Table` whose ``data`` has shape (rows, len(columns)) in file order.
    """
    path = Path(path)
    ncols = len(columns)
    blocks, lines = [], []
    for first, raw in line_blocks(path):
        d, n = _parse_block(path, first, raw, columns)
        if d.shape[0]:
            blocks.append(d)
            lines.append(n)
    data = np.concatenate(blocks) if blocks else np.zeros((0, ncols))
    del blocks
    table = Table(path=path, data=data,
                  lines=np.concatenate(lines) if lines else np.zeros(0, np.int64))
    if data.shape[0] < min_rows:
        raise DataFormatError(path, None, f"expected at least {min_rows} data line(s), got "
                                          f"{data.shape[0]}")
    for j, col in enumerate(columns):
        vals = data[:, j]
        if col.integer:
            bad = np.flatnonzero(vals != np.round(vals))
            if bad.size:
                raise table.error(bad[0], f"column '{col.name}': expected an integer, got "
                                          f"{float(vals[bad[0]])!r}")
        for bound, bad in ((col.lo, None if col.lo is None else np.flatnonzero(vals < col.lo)),
                           (col.hi, None if col.hi is None else np.flatnonzero(vals > col.hi))):
            if bad is not None and bad.size:
                word = "below" if bound == col.lo else "above"
                raise table.error(bad[0], f"column '{col.name}': {float(vals[bad[0]])!r} is {word} "
                                          f"{bound:g}, impossible for this column")
    return table


def check_unique(table: Table, col: int, name: str) -> None:
    """DataFormatError at the second line holding a value of column ``col`` seen before."""
    ids = table.data[:, col]
    _, first, counts = np.unique(ids, return_index=True, return_counts=True)
    if np.any(counts > 1):
        dup_val = ids[first[counts > 1][0]]
        rows = np.flatnonzero(ids == dup_val)
        raise table.error(rows[1], f"{name} {int(dup_val)} appears more than once")


def find_file(directory: Path, stem: str) -> Path | None:
    """``stem.dat`` or ``stem.dat.gz`` in ``directory`` (plain first: the dataset's own format),
    whatever it is (a directory or a broken link of that name is returned, for the reader to
    refuse by name); None when neither name exists."""
    for name in (f"{stem}.dat", f"{stem}.dat.gz"):
        p = directory / name
        if os.path.lexists(p):
            return p
    return None
