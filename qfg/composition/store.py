"""Composition tensor files: where they live, how they are written, loaded and checked.

A tensor file ``tensors/<partition>.npz`` holds (all plain arrays, loadable without pickle):

* ``T`` (m, m, m) float64 (other dtypes are rejected), sums to 1; ``support`` (m, m, m) bool,
  ``T > 0``;
* ``partition`` (name), ``window`` (xmin, xmax, ymin, ymax), ``samples_per_state``, ``seed``,
  ``quad_segs`` (polygon resolution: segments per quarter circle), ``version`` (qfg's),
  ``sha256`` (hex digest of ``T`` as C-ordered little-endian float64 bytes);
* build details: ``method``, ``support_samples_per_state``, ``build_seconds``, ``workers``.

The directory is ``tensors/`` at the repository root (next to the ``qfg`` package), or the
directory named by the environment variable ``QFG_TENSORS``.

>>> from qfg.composition import tensor
>>> T = tensor("fdc")                                   # doctest: +SKIP
>>> T.shape, round(float(np.asarray(T).sum()), 12)       # doctest: +SKIP
((6, 6, 6), 1.0)
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import partitions as _partitions

__all__ = ["CompositionTensor", "TensorFileError", "tensors_dir", "tensor_path", "tensor", "load",
           "save", "checksum", "rebuild_command", "ENV_VAR"]

#: Environment variable that overrides the tensor directory.
ENV_VAR = "QFG_TENSORS"

_REQUIRED = ("T", "support", "partition", "window", "samples_per_state", "seed", "quad_segs",
             "version", "sha256")


class TensorFileError(ValueError):
    """A composition tensor file is missing, unreadable or does not match its partition.

    The message names the file and the command that rebuilds it.
    """


@dataclass(frozen=True, eq=False, init=False)
class CompositionTensor:
    """A composition tensor and how it was made; usable as the (m, m, m) array it holds.

    ``table[i, j, k]`` with i = state of AB:C, j = state of BC:D, k = state of AB:D (0-based).
    ``np.asarray(t)`` is the table (read-only for a loaded file; ``np.array(t)`` copies), and
    ``shape``, ``ndim`` and ``dtype`` are the table's, so a tensor can go wherever an array is
    expected. ``t.T`` is an alias of ``t.table`` kept for existing callers (it is *not* a
    transpose, unlike an ndarray's ``.T``); the constructor accepts ``T=`` in place of ``table=``.

    Attributes:
        partition: partition name (``"edc"``).
        table: (m, m, m) float64, non-negative, sums to 1.
        support: (m, m, m) bool, ``table > 0`` (the deterministic composition).
        window: (xmin, xmax, ymin, ymax) integration window, units of |AB|.
        samples_per_state: C samples per AB:C state that carry the weights.
        seed: seed of the build.
        quad_segs: segments per quarter circle of the polygons used.
        version: qfg version that built it.
        sha256: checksum of the table (see :func:`checksum`).
        meta: other build details (method, support samples, build time, ...).
        path: file it was loaded from (None if built in memory).

    >>> import numpy as np
    >>> T = np.full((2, 2, 2), 1 / 8)
    >>> t = CompositionTensor("lr", T, T > 0, (-2.0, 2.0, -2.0, 3.0), 1, 0, 8, "doc", checksum(T), {})
    >>> np.asarray(t).shape, t.shape, t.ndim, t.dtype, t.T is t.table
    ((2, 2, 2), (2, 2, 2), 3, dtype('float64'), True)
    """

    partition: str
    table: np.ndarray
    support: np.ndarray
    window: tuple[float, float, float, float]
    samples_per_state: int
    seed: int
    quad_segs: int
    version: str
    sha256: str
    meta: dict
    path: Path | None = None

    def __init__(self, partition, table=None, support=None, window=None, samples_per_state=None,
                 seed=None, quad_segs=None, version=None, sha256=None, meta=None, path=None, *,
                 T=None):
        if (table is None) == (T is None):
            raise ValueError("table: give the (m, m, m) table once, as table= (or its alias T=)")
        values = dict(partition=partition, table=table if T is None else T, support=support,
                      window=window, samples_per_state=samples_per_state, seed=seed,
                      quad_segs=quad_segs, version=version, sha256=sha256, meta=meta, path=path)
        missing = [k for k, v in values.items() if v is None and k != "path"]
        if missing:
            raise ValueError(f"{missing[0]}: required")
        for k, v in values.items():
            object.__setattr__(self, k, v)

    @property
    def T(self) -> np.ndarray:
        """Alias of :attr:`table` (the composition table, not a transpose)."""
        return self.table

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.table.shape

    @property
    def ndim(self) -> int:
        return self.table.ndim

    @property
    def dtype(self) -> np.dtype:
        return self.table.dtype

    def __array__(self, dtype=None, copy=None):
        """The table, for ``np.asarray``/``np.array`` (numpy 2 ``copy`` semantics)."""
        arr = self.table
        if dtype is not None and np.dtype(dtype) != arr.dtype:
            if copy is False:
                raise ValueError(f"dtype: converting the table to {np.dtype(dtype)} needs a copy, "
                                 f"but copy=False")
            return arr.astype(dtype)
        return arr.copy() if copy else arr

    @property
    def n_states(self) -> int:
        """m, the number of states of the partition."""
        return int(self.table.shape[0])

    @property
    def nnz(self) -> int:
        """Number of non-zero entries (feasible (i, j, k) combinations)."""
        return int(np.count_nonzero(self.support))

    def __repr__(self) -> str:
        return (f"CompositionTensor({self.partition!r}, m={self.n_states}, nnz={self.nnz}, "
                f"window={self.window}, samples_per_state={self.samples_per_state}, "
                f"seed={self.seed})")


def checksum(T: np.ndarray) -> str:
    """sha256 hex digest of T as C-ordered little-endian float64 bytes."""
    return hashlib.sha256(np.ascontiguousarray(T, dtype="<f8").tobytes()).hexdigest()


def tensors_dir() -> Path:
    """The tensor directory: ``$QFG_TENSORS`` if set, else the package data ``qfg/_tensors``
    (found with :mod:`importlib.resources`; in a checkout it is the top-level ``tensors/``)."""
    env = os.environ.get(ENV_VAR)
    if env:
        return Path(env)
    from importlib.resources import files

    return Path(str(files("qfg") / "_tensors")).resolve()


def tensor_path(name: str) -> Path:
    """Path of the tensor file of partition ``name``: ``<tensors_dir>/<name>.npz``."""
    return tensors_dir() / f"{str(name).lower()}.npz"


def rebuild_command(name: str) -> str:
    """The shell command that rebuilds the tensor of partition ``name``."""
    return f"qfg tensors build --partition {str(name).lower()}"


def _fail(path, name, what) -> TensorFileError:
    return TensorFileError(f"composition tensor file {path}: {what}. Rebuild it with "
                           f"`{rebuild_command(name)}` (see docs/composition.md).")


def save(path, tensor: CompositionTensor) -> Path:
    """Write ``tensor`` to ``path`` (.npz, compressed, no pickled objects). Returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {f"meta_{k}": np.asarray(v) for k, v in tensor.meta.items()}
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez_compressed(
        tmp, T=np.ascontiguousarray(tensor.table, dtype="<f8"), support=tensor.support.astype(bool),
        partition=np.asarray(tensor.partition), window=np.asarray(tensor.window, dtype=float),
        samples_per_state=np.asarray(tensor.samples_per_state), seed=np.asarray(tensor.seed),
        quad_segs=np.asarray(tensor.quad_segs), version=np.asarray(tensor.version),
        sha256=np.asarray(tensor.sha256), **meta)
    os.replace(tmp, path)  # atomic: a reader never sees half a file
    return path


#: Most members a tensor file holds (the required fields and the build's meta_* details).
_MAX_MEMBERS = 64
#: Room for a member's .npy header (numpy pads it to a multiple of 64 bytes; a few hundred in
#: practice) and for a small member (a scalar, a string, the window): 4 KiB.
_SMALL = 4096


def _member_limit(key: str, m: int) -> int:
    """Most bytes member ``key`` may inflate to for a partition of m states: (m, m, m) float64
    for T and the meta arrays a build records per (i, j, k), (m, m, m) bool for the support,
    a few KiB for the rest."""
    if key == "T" or key.startswith("meta_"):
        return 8 * m ** 3 + _SMALL
    if key == "support":
        return m ** 3 + _SMALL
    return _SMALL


def _read_members(path: Path, name: str, partition) -> dict:
    """The arrays of the .npz at ``path``, each member's name and declared (inflated) size checked
    against what a tensor file holds BEFORE anything is inflated: memory stays bounded by the
    partition's table size whatever the archive claims. zipfile stops inflating a member at its
    declared size (and fails its CRC), so a member lying about its size cannot grow past it."""
    with zipfile.ZipFile(path) as zf:
        infos = zf.infolist()
        if len(infos) > _MAX_MEMBERS:
            raise _fail(path, name, f"{len(infos)} members, more than the {_MAX_MEMBERS} a tensor "
                                    "file holds")
        keys = {}
        for info in infos:
            key = info.filename[:-4] if info.filename.endswith(".npy") else None
            if key is None or not (key in _REQUIRED or (key.startswith("meta_")
                                                        and key[5:].isidentifier())):
                raise _fail(path, name, f"unexpected member {info.filename!r} (a tensor file "
                                        f"holds {', '.join(_REQUIRED)} and meta_* details)")
            keys[key] = info
        # the partition, and so the table size, before the big members: from the caller, else
        # from the file's own (small) partition member
        m = None
        if partition is not None:
            m = _partitions.get(partition).n_states
        elif "partition" in keys and keys["partition"].file_size <= _SMALL:
            with zf.open(keys["partition"]) as fh:
                with contextlib.suppress(ValueError):
                    m = _partitions.get(str(np.lib.format.read_array(fh, allow_pickle=False)))\
                        .n_states
        if m is None:  # unknown partition: the largest shipped one bounds the sizes
            m = max(_partitions.get(n).n_states for n in _partitions.available())
        for key, info in keys.items():
            limit = _member_limit(key, m)
            if info.file_size > limit:
                raise _fail(path, name, f"member {info.filename!r} declares {info.file_size} bytes "
                                        f"inflated, more than the {limit} a tensor of {m} states "
                                        "needs (not inflated)")
        data = {}
        for key, info in keys.items():
            with zf.open(info) as fh:
                data[key] = np.lib.format.read_array(fh, allow_pickle=False)
    return data


def load(path, partition=None) -> CompositionTensor:
    """Load and check a tensor file.

    Checks: the file exists and is a readable .npz with every field; T is (m, m, m) with m the
    partition's number of states, finite, non-negative, sums to 1; its sha256 matches; ``support``
    equals ``T > 0``; the window equals the partition's window. ``partition`` (name or Partition)
    defaults to the one recorded in the file (or the file's stem if that is unreadable).

    Raises:
        TensorFileError (a ValueError) naming the file and the rebuild command.
    """
    path = Path(path)
    name = (_partitions.get(partition).name if partition is not None else path.stem)
    if not path.is_file():
        raise _fail(path, name, "not found")
    try:
        with open(path, "rb") as fh:
            head = fh.read(4)
    except OSError as exc:
        raise _fail(path, name, f"cannot be read ({type(exc).__name__}: {exc})") from None
    if head[:2] != b"PK":
        # np.load would call anything that is neither zip nor .npy "pickled (object) data"
        what = "an empty file" if not head else f"it starts with {head!r}, not a zip header"
        raise _fail(path, name, f"not an npz archive ({what})")
    try:
        data = _read_members(path, name, partition)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        if isinstance(exc, TensorFileError):
            raise
        raise _fail(path, name, f"cannot be read ({type(exc).__name__}: {exc})") from None
    missing = [k for k in _REQUIRED if k not in data]
    if missing:
        raise _fail(path, name, f"missing fields {missing}")
    try:
        recorded = str(data["partition"])
        window = tuple(float(v) for v in np.asarray(data["window"], dtype=float).ravel())
        samples = int(data["samples_per_state"])
        seed = int(data["seed"])
        quad_segs = int(data["quad_segs"])
        version = str(data["version"])
        sha = str(data["sha256"])
        raw_dtype = np.asarray(data["T"]).dtype
        T = np.asarray(data["T"], dtype=float)
        support = np.asarray(data["support"])
    except (TypeError, ValueError) as exc:
        raise _fail(path, name, f"malformed metadata ({exc})") from None
    if partition is None:
        name = recorded
    try:
        part = _partitions.get(name)
    except ValueError:
        raise _fail(path, name, f"unknown partition {name!r}") from None
    if recorded != part.name:
        raise _fail(path, part.name, f"built for partition {recorded!r}, expected {part.name!r}")
    m = part.n_states
    # The checksum is of the float64 values: a float32 table converted on load would match it
    # while holding fewer digits than the build computed.
    if raw_dtype.kind != "f" or raw_dtype.itemsize != 8:
        raise _fail(path, part.name, f"T has dtype {raw_dtype}, expected float64")
    if T.shape != (m, m, m):
        raise _fail(path, part.name, f"T has shape {T.shape}, expected {(m, m, m)} for "
                                     f"{part.name} ({m} states)")
    if checksum(T) != sha:
        raise _fail(path, part.name, "T does not match its sha256 checksum (corrupt or edited)")
    if not np.all(np.isfinite(T)) or np.any(T < 0) or not np.isclose(T.sum(), 1.0, atol=1e-9):
        raise _fail(path, part.name, "T must be finite, non-negative and sum to 1")
    if support.shape != T.shape or support.dtype != bool or not np.array_equal(support, T > 0):
        raise _fail(path, part.name, "support is not T > 0")
    if len(window) != 4 or not np.allclose(window, part.window, rtol=0, atol=1e-12):
        raise _fail(path, part.name, f"window {window} disagrees with the partition's window "
                                     f"{part.window}")
    meta = {k[5:]: (v.item() if v.ndim == 0 else v) for k, v in data.items()
            if k.startswith("meta_")}
    T.setflags(write=False)
    support.setflags(write=False)
    return CompositionTensor(partition=part.name, table=T, support=support, window=window,
                             samples_per_state=samples, seed=seed, quad_segs=quad_segs,
                             version=version, sha256=sha, meta=meta, path=path)


_CACHE: dict[tuple, CompositionTensor] = {}


def tensor(name) -> CompositionTensor:
    """The shipped composition tensor of partition ``name`` (``"edc"``, ``"fdc"``, ...), checked.

    Loads ``<tensors_dir>/<name>.npz`` (see :func:`tensors_dir`) once per file version (cached by
    path, size and modification time). Raises :class:`TensorFileError` if the file is missing,
    corrupt or does not match the partition.

    >>> tensor("edc").shape                                 # doctest: +SKIP
    (20, 20, 20)
    """
    part = _partitions.get(name)
    path = tensor_path(part.name)
    try:
        st = path.stat()
        key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    except OSError:
        raise _fail(path, part.name, "not found") from None
    hit = _CACHE.get(key)
    if hit is None:
        hit = load(path, part)
        _CACHE[key] = hit
    return hit
