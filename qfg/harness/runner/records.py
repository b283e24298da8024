"""What a run writes: ``records.jsonl`` read back (:func:`read_records`, :func:`dedupe_records`)
and appended to, outputs written through a temporary file and a rename (:func:`write_text`), and
the one table writer and formatter of every study (:func:`write_table`, :func:`format_table`,
:func:`print_table`)."""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

import numpy as np

from qfg.files import atomic_write_text, atomic_writer
from qfg.harness.runner.errors import RunnerError


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


def _replacing(path):
    """A binary file object whose content replaces ``path`` when the block ends without error:
    :func:`qfg.files.atomic_writer` (a temporary file in the same folder, fsynced, renamed over
    ``path``; a link there is replaced, never written through; on error ``path`` is as it was)."""
    return atomic_writer(path, "wb")


def write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (:func:`qfg.files.atomic_write_text`).
    Returns the path."""
    atomic_write_text(path, text)
    return Path(path)


_atomic_write = write_text


def _append(fd: int, data: bytes) -> None:
    """All of ``data`` to ``fd`` (os.write may write part of it)."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


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
