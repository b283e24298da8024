"""Reading MRCLAM's text tables: plain or gzip, comments decoded leniently, every error located.

A table is read in three steps, each of which names the file and, where it can, the line:

1. bytes: a 0-byte file is an error (a real file always has its header; an empty file is a failed
   copy, not a robot that saw nothing); ``.gz`` files are inflated with :mod:`zlib` in chunks, so a
   corrupt or truncated stream is reported with the number of lines that decoded before it.
2. text: ``#`` starts a comment. Comments may hold any bytes (they are dropped); a data line must be
   ASCII, so an undecodable or non-ASCII byte there is an error naming the line.
3. numbers: one ``numpy.loadtxt`` call; on any failure a line-by-line pass finds the first offending
   line (column count, non-number, non-finite). Column constraints (:class:`Column`) are checked
   vectorized and the first violating row is mapped back to its line.
"""

from __future__ import annotations

import io
import math
import re
import warnings
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np


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


_CHUNK = 1 << 16
_NUMBER = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?|nan)", re.IGNORECASE)


def _inflate_until_error(data: bytes, good: int) -> bytes:
    """What a fresh decompressor yields from ``data`` before it fails, knowing ``data[:good]`` is
    fine: the rest is fed byte by byte, so no output decoded before the error is lost."""
    d = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)
    out = [d.decompress(data[:good])]
    try:
        for k in range(good, len(data)):
            out.append(d.decompress(data[k:k + 1]))
            if d.eof:
                break
        out.append(d.flush())
    except zlib.error:
        pass
    return b"".join(out)


def _gunzip(path: Path, raw: bytes) -> bytes:
    """Inflate every gzip member of ``raw``; DataFormatError at the line where decoding broke."""
    done = b""  # the members inflated so far
    data = raw
    while True:
        d = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)
        out: list[bytes] = []
        k = 0
        try:
            for k in range(0, len(data), _CHUNK):
                out.append(d.decompress(data[k:k + _CHUNK]))
                if d.eof:
                    break
            out.append(d.flush())
        except zlib.error as exc:
            n = done.count(b"\n") + _inflate_until_error(data, k).count(b"\n")
            raise DataFormatError(path, n + 1, f"corrupt gzip data at or after this line ({n} line(s) "
                                               f"decoded before it): {exc}") from None
        done += b"".join(out)
        if not d.eof:
            n = done.count(b"\n")
            raise DataFormatError(path, n + 1, f"truncated gzip file: the stream ends after {n} "
                                               f"line(s) without its end marker")
        data = d.unused_data
        if not data.strip(b"\0"):  # gzip tolerates zero padding after the last member
            return done


def read_bytes(path: Path) -> bytes:
    """The file's content, inflated for ``.gz``. DataFormatError for a 0-byte or unreadable file."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DataFormatError(path, None, f"could not read the file: {exc}") from None
    if not raw:
        raise DataFormatError(path, None, "empty file (0 bytes): a dataset file has at least its "
                                          "'#' header; the copy is probably incomplete")
    return _gunzip(path, raw) if path.name.endswith(".gz") else raw


def to_text(path: Path, raw: bytes) -> str:
    """ASCII text of ``raw`` with comments that hold non-ASCII bytes blanked (line count kept).

    A non-ASCII or undecodable byte before any ``#`` on its line is a DataFormatError naming the line.

    >>> to_text(Path("f.dat"), "# caf\\xe9 header\\n1 2\\n".encode("latin-1"))
    '\\n1 2\\n'
    """
    if raw.isascii():
        return raw.decode("ascii")
    lines = raw.split(b"\n")
    for no, line in enumerate(lines, start=1):
        if line.isascii():
            continue
        data, hash_, _ = line.partition(b"#")
        if not data.isascii():
            k = next(i for i, b in enumerate(data) if b > 127)
            raise DataFormatError(path, no, f"byte 0x{data[k]:02x} at column {k + 1} is not ASCII "
                                            f"(data lines hold only numbers; only '#' comments may "
                                            f"hold other bytes)")
        lines[no - 1] = data  # drop the comment: nothing in it is read
    return b"\n".join(lines).decode("ascii")


def data_lines(text: str):
    """Yield (1-based line number, fields) for every line that is not blank or a comment."""
    for no, line in enumerate(text.split("\n"), start=1):
        fields = line.split("#", 1)[0].split()
        if fields:
            yield no, fields


def _first_bad_line(text: str, columns: tuple[Column, ...]):
    """The first data line with the wrong number of columns or a non-number: (line, message)."""
    ncols = len(columns)
    for no, fields in data_lines(text):
        if len(fields) != ncols:
            names = ", ".join(c.name for c in columns)
            return no, f"expected {ncols} columns ({names}), got {len(fields)}: {' '.join(fields)!r}"
        for col, tok in zip(columns, fields, strict=True):
            # numpy's reader is stricter than float() (no '1_000', no ' 1 '): accept what both take
            if not _NUMBER.fullmatch(tok):
                return no, f"column '{col.name}': expected a number, got {tok!r}"
            val = float(tok)
            if not math.isfinite(val):
                return no, f"column '{col.name}': expected a finite number, got {tok!r}"
    return None


@dataclass(frozen=True, eq=False)
class Table:
    """A numeric table read from ``path``: ``data`` (rows, columns) and the text to locate rows."""

    path: Path
    data: np.ndarray
    text: str

    def line_of(self, row: int) -> int | None:
        """File line number (1-based) of the 0-based data row ``row``."""
        for k, (no, _) in enumerate(data_lines(self.text)):
            if k == row:
                return no
        return None  # pragma: no cover - rows always come from the text

    def error(self, row: int, message: str) -> DataFormatError:
        return DataFormatError(self.path, self.line_of(int(row)), message)


def read_table(path: Path, columns: tuple[Column, ...], *, min_rows: int = 0) -> Table:
    """Read a whitespace-separated numeric table; see the module docstring for the checks.

    Returns a :class:`Table` whose ``data`` has shape (rows, len(columns)) in file order.
    """
    path = Path(path)
    text = to_text(path, read_bytes(path))
    ncols = len(columns)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            data = np.loadtxt(io.StringIO(text), comments="#", dtype=float, ndmin=2)
    except (ValueError, IndexError) as exc:
        bad = _first_bad_line(text, columns)
        if bad is None:  # pragma: no cover - numpy failed on something the slow pass accepts
            raise DataFormatError(path, None, f"could not read the table: {exc}") from None
        raise DataFormatError(path, *bad) from None
    if data.size == 0:
        data = np.zeros((0, ncols))
    if data.shape[1] != ncols or not np.all(np.isfinite(data)):
        bad = _first_bad_line(text, columns)
        raise DataFormatError(path, *(bad or (None, f"expected {ncols} finite columns")))
    table = Table(path=path, data=data, text=text)
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
    """``stem.dat`` or ``stem.dat.gz`` in ``directory`` (plain first: the dataset's own format)."""
    for name in (f"{stem}.dat", f"{stem}.dat.gz"):
        p = directory / name
        if p.is_file():
            return p
    return None
