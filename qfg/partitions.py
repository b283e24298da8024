"""Qualitative space partitions of the AB frame (A = (0, 0), B = (0, 1)).

A partition splits the plane into ``m`` states. Each has a vectorized numpy lookup
(:meth:`Partition.state_of`, no shapely per point) and shapely polygons clipped to an integration
window (used for areas, centroids, pictures and the composition tensors). State indices are
0-based in code and shown 1-based in tables and figures (conventions.md).

Built in: ``edc`` (extended double cross, 20), ``fdc`` (Freksa's double cross, 6), ``lr``
(left/right, 2), ``tpcc`` (ternary point configuration calculus, 16). Define your own with
:meth:`Partition.from_polygons` and :func:`register`.

>>> import qfg.partitions as qp
>>> edc = qp.get("edc")
>>> edc.n_states, edc.state_of([[0.5, 2.5], [-0.1, -0.1]]).tolist()
(20, [1, 16])
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import shapely
from shapely.geometry import Point, Polygon, box

from ._validate import as_float_array
from .geometry import to_frame

__all__ = ["Partition", "get", "register", "available", "state_of_triplet", "DEFAULT_QUAD_SEGS"]

#: Segments per quarter circle for circle boundaries: 1024 per circle, so a polygon departs from
#: its circle by at most r (1 - cos(pi / 1024)) ~ 4.7e-6 |AB|.
DEFAULT_QUAD_SEGS = 256

Window = tuple[float, float, float, float]


@dataclass(frozen=True, eq=False)
class Partition:
    """A qualitative partition of the AB frame.

    Attributes:
        name: short lower-case name (``"edc"``).
        labels: (m,) display labels, 1-based numbering by default.
        descriptions: (m,) what each state is, in words.
        window: (xmin, xmax, ymin, ymax) integration window in the AB frame (units of |AB|).
        polygons: (m,) shapely geometries of the states clipped to the window.
        areas: (m,) polygon areas within the window.
        centroids: (m, 2) polygon centroids within the window.
        quad_segs: segments per quarter circle used for circular boundaries.
    """

    name: str
    labels: tuple[str, ...]
    descriptions: tuple[str, ...]
    window: Window
    polygons: tuple
    lookup: Callable[[np.ndarray], np.ndarray] | None = field(repr=False, default=None)
    quad_segs: int = DEFAULT_QUAD_SEGS
    areas: np.ndarray = field(init=False, repr=False)
    centroids: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        m = len(self.polygons)
        if m < 2:
            raise ValueError(f"polygons: a partition needs at least 2 states, got {m}")
        if len(self.labels) != m or len(self.descriptions) != m:
            raise ValueError(f"labels, descriptions: expected {m} each (one per polygon), got "
                             f"{len(self.labels)} and {len(self.descriptions)}")
        xmin, xmax, ymin, ymax = self.window
        if not (xmin < xmax and ymin < ymax):
            raise ValueError(f"window: expected xmin < xmax and ymin < ymax, got {self.window}")
        polys = np.asarray(self.polygons, dtype=object)
        areas = shapely.area(polys).astype(float)
        if np.any(areas <= 0):
            empty = [self.labels[i] for i in np.flatnonzero(areas <= 0)]
            raise ValueError(f"polygons: states {empty} have no area inside window {self.window}")
        cents = shapely.centroid(polys)
        object.__setattr__(self, "areas", areas)
        object.__setattr__(self, "centroids",
                           np.stack([shapely.get_x(cents), shapely.get_y(cents)], axis=-1))

    @property
    def n_states(self) -> int:
        """Number of states m."""
        return len(self.polygons)

    @property
    def window_area(self) -> float:
        xmin, xmax, ymin, ymax = self.window
        return (xmax - xmin) * (ymax - ymin)

    @property
    def window_box(self) -> Polygon:
        xmin, xmax, ymin, ymax = self.window
        return box(xmin, ymin, xmax, ymax)

    def state_of(self, points) -> np.ndarray:
        """States (0-based int) of AB-frame points (..., 2); output shape (...).

        Points outside the window still get the state their region extends to.
        """
        p = as_float_array("points", points, last_dim=2)
        if self.lookup is not None:
            return np.asarray(self.lookup(p), dtype=np.int64)
        return self._lookup_by_containment(p)

    def _lookup_by_containment(self, p: np.ndarray) -> np.ndarray:
        # Fallback for partitions defined by polygons alone: shapely's vectorized contains_xy, one
        # call per state (not per point). Points outside every polygon get -1.
        flat = p.reshape(-1, 2)
        out = np.full(flat.shape[0], -1, dtype=np.int64)
        for i, poly in enumerate(self.polygons):
            hit = shapely.contains_xy(poly, flat[:, 0], flat[:, 1]) & (out < 0)
            out[hit] = i
        return out.reshape(p.shape[:-1])

    def in_window(self, points) -> np.ndarray:
        """True where AB-frame points (..., 2) lie inside the window (closed box)."""
        p = as_float_array("points", points, last_dim=2)
        xmin, xmax, ymin, ymax = self.window
        return (p[..., 0] >= xmin) & (p[..., 0] <= xmax) & (p[..., 1] >= ymin) & (p[..., 1] <= ymax)

    def table(self) -> str:
        """A text table of the states: label, area, centroid, description."""
        rows = [f"{'state':>5}  {'area':>8}  {'centroid x':>10}  {'centroid y':>10}  region"]
        for i in range(self.n_states):
            cx, cy = self.centroids[i]
            rows.append(f"{self.labels[i]:>5}  {self.areas[i]:8.4f}  {cx:10.4f}  {cy:10.4f}  "
                        f"{self.descriptions[i]}")
        rows.append(f"{'sum':>5}  {self.areas.sum():8.4f}  window {self.window} "
                    f"area {self.window_area:.4f}")
        return "\n".join(rows)

    @classmethod
    def from_polygons(cls, name: str, polygons: Sequence, window: Window, *,
                      labels: Sequence[str] | None = None,
                      descriptions: Sequence[str] | None = None,
                      lookup: Callable[[np.ndarray], np.ndarray] | None = None,
                      quad_segs: int = DEFAULT_QUAD_SEGS) -> "Partition":
        """Define a partition from shapely polygons (clipped here to ``window``).

        ``lookup`` maps an (..., 2) float array of AB-frame points to (...) 0-based states; without
        it, :meth:`state_of` falls back to shapely's vectorized containment (slower, -1 outside
        every polygon). The polygons must not overlap.
        """
        win = tuple(float(v) for v in window)
        if len(win) != 4:
            raise ValueError(f"window: expected (xmin, xmax, ymin, ymax), got {window!r}")
        clip = box(win[0], win[2], win[1], win[3])
        polys = tuple(shapely.intersection(np.asarray(list(polygons), dtype=object), clip))
        m = len(polys)
        labels = tuple(labels) if labels is not None else tuple(str(i + 1) for i in range(m))
        descriptions = tuple(descriptions) if descriptions is not None else labels
        part = cls(name=name.lower(), labels=labels, descriptions=descriptions, window=win,
                   polygons=polys, lookup=lookup, quad_segs=quad_segs)
        overlap = part.areas.sum() - shapely.area(shapely.union_all(np.asarray(polys, dtype=object)))
        if overlap > 1e-9 * part.window_area:
            raise ValueError(f"polygons: states overlap by a total area of {overlap:.3g}")
        return part


# ---------------------------------------------------------------------------------------------
# Built-in partitions. Each is written once as a small table of predicates; both the numpy lookup
# and the polygons come from the same primitives, so they cannot drift apart.

_BIG = 1e3  # half-planes as boxes this large, then clipped to the window


def _disk(cx, cy, r, quad_segs):
    return Point(cx, cy).buffer(r, quad_segs=quad_segs)


def _edc_lookup(p):
    x, y = p[..., 0], p[..., 1]
    right = x >= 0
    # A square beyond float64 (|x| > 1e154) is inf, which correctly reads as "far".
    with np.errstate(over="ignore"):
        x2 = x * x
        near_a = x2 + y * y <= 1.0
        near_b = x2 + (y - 1.0) ** 2 <= 1.0
    band = 3 - ((y >= 0).astype(np.int8) + (y >= 0.5) + (y >= 1.0))
    code = band * 8 + right * 4 + near_a * 2 + near_b
    return _EDC_LUT[code]


def _edc_lut():
    # code = band * 8 + right * 4 + nearA * 2 + nearB; band 0: y >= 1, 1: [0.5, 1), 2: [0, .5), 3: y < 0
    lut = np.zeros(32, dtype=np.int64)
    for band in range(4):
        for right in (0, 1):
            for na in (0, 1):
                for nb in (0, 1):
                    if band == 0:
                        s = (2 if nb else 0) + right
                    elif band == 1:
                        # y >= 0.5 means |p - A| >= |p - B|: near A implies near B; the other
                        # combination only arises from rounding at the circles' crossing.
                        if right:
                            s = 7 if na else (8 if nb else 9)
                        else:
                            s = 6 if na else (5 if nb else 4)
                    elif band == 2:
                        # y < 0.5: near B implies near A (rounding case as above)
                        if right:
                            s = 13 if nb else (14 if na else 15)
                        else:
                            s = 12 if nb else (11 if na else 10)
                    else:
                        s = (16 if na else 18) + right
                    lut[band * 8 + right * 4 + na * 2 + nb] = s
    return lut


_EDC_LUT = _edc_lut()

_EDC_DESCRIPTIONS = (
    "y>=1, far B, left", "y>=1, far B, right", "y>=1, near B, left", "y>=1, near B, right",
    "0.5<=y<1, left, far A, far B", "0.5<=y<1, left, far A, near B",
    "0.5<=y<1, left, near A, near B", "0.5<=y<1, right, near A, near B",
    "0.5<=y<1, right, far A, near B", "0.5<=y<1, right, far A, far B",
    "0<=y<0.5, left, far A, far B", "0<=y<0.5, left, near A, far B",
    "0<=y<0.5, left, near A, near B", "0<=y<0.5, right, near A, near B",
    "0<=y<0.5, right, near A, far B", "0<=y<0.5, right, far A, far B",
    "y<0, near A, left", "y<0, near A, right", "y<0, far A, left", "y<0, far A, right",
)


def _edc_polygons(quad_segs):
    # Predicates as geometries: (band, right, nearA, nearB) -> intersection; None = don't care.
    bands = [box(-_BIG, 1.0, _BIG, _BIG), box(-_BIG, 0.5, _BIG, 1.0),
             box(-_BIG, 0.0, _BIG, 0.5), box(-_BIG, -_BIG, _BIG, 0.0)]
    sides = [box(-_BIG, -_BIG, 0.0, _BIG), box(0.0, -_BIG, _BIG, _BIG)]
    da, db = _disk(0, 0, 1, quad_segs), _disk(0, 1, 1, quad_segs)

    def region(band, right, na, nb):
        g = bands[band].intersection(sides[right])
        if na is not None:
            g = g.intersection(da) if na else g.difference(da)
        if nb is not None:
            g = g.intersection(db) if nb else g.difference(db)
        return g

    spec = [(0, 0, None, 0), (0, 1, None, 0), (0, 0, None, 1), (0, 1, None, 1),
            (1, 0, 0, 0), (1, 0, 0, 1), (1, 0, 1, 1), (1, 1, 1, 1), (1, 1, 0, 1), (1, 1, 0, 0),
            (2, 0, 0, 0), (2, 0, 1, 0), (2, 0, 1, 1), (2, 1, 1, 1), (2, 1, 1, 0), (2, 1, 0, 0),
            (3, 0, 1, None), (3, 1, 1, None), (3, 0, 0, None), (3, 1, 0, None)]
    return [region(*s) for s in spec]


def _fdc_lookup(p):
    x, y = p[..., 0], p[..., 1]
    band = 2 - ((y >= 0).astype(np.int64) + (y >= 1.0))
    return band * 2 + (x >= 0)


def _fdc_polygons():
    out = []
    for y0, y1 in ((1.0, _BIG), (0.0, 1.0), (-_BIG, 0.0)):
        out += [box(-_BIG, y0, 0.0, y1), box(0.0, y0, _BIG, y1)]
    return out


def _lr_lookup(p):
    return (p[..., 0] >= 0).astype(np.int64)


_TPCC_SECTORS = ("fl", "lf", "lb", "bl", "br", "rb", "rf", "fr")


def _tpcc_lookup(p):
    vx, vy = p[..., 0], p[..., 1] - 1.0
    # angle of C - B counter-clockwise from the direction B - A = +y
    theta = np.mod(np.arctan2(-vx, vy), 2.0 * np.pi)
    sector = np.minimum((theta * (4.0 / np.pi)).astype(np.int64), 7)
    with np.errstate(over="ignore"):  # inf (|v| > 1e154) correctly reads as "far"
        far = (vx * vx + vy * vy) >= 1.0
    return sector + 8 * far


def _tpcc_polygons(quad_segs):
    near = _disk(0, 1, 1, quad_segs)
    out_near, out_far = [], []
    for k in range(8):
        t0, t1 = k * np.pi / 4, (k + 1) * np.pi / 4
        tm = 0.5 * (t0 + t1)
        # direction at angle t ccw from +y is (-sin t, cos t)
        pts = [(0.0, 1.0)] + [(-_BIG * np.sin(t), 1.0 + _BIG * np.cos(t)) for t in (t0, tm, t1)]
        wedge = Polygon(pts)
        out_near.append(wedge.intersection(near))
        out_far.append(wedge.difference(near))
    return out_near + out_far


def _build(name: str, quad_segs: int = DEFAULT_QUAD_SEGS) -> Partition:
    if name == "edc":
        return Partition.from_polygons(
            "edc", _edc_polygons(quad_segs), (-2.0, 2.0, -2.0, 3.0),
            descriptions=_EDC_DESCRIPTIONS, lookup=_edc_lookup, quad_segs=quad_segs)
    if name == "fdc":
        desc = [f"{b}, {s}" for b in ("y>=1", "0<=y<1", "y<0") for s in ("left", "right")]
        return Partition.from_polygons("fdc", _fdc_polygons(), (-1.0, 1.0, -1.0, 2.0),
                                       descriptions=desc, lookup=_fdc_lookup)
    if name == "lr":
        return Partition.from_polygons(
            "lr", [box(-_BIG, -_BIG, 0.0, _BIG), box(0.0, -_BIG, _BIG, _BIG)],
            (-1.0, 1.0, -1.0, 2.0), labels=("L", "R"), descriptions=("left (x<0)", "right (x>=0)"),
            lookup=_lr_lookup)
    if name == "tpcc":
        # A square centred on B whose 8 axis/diagonal triangles each hold a near and a far sector of
        # equal area: near pi/8, far (4 h^2 - pi)/8, equal for h = sqrt(2 pi) / 2.
        h = float(np.sqrt(2.0 * np.pi) / 2.0)
        labels = tuple(f"{d}{s}" for d in ("c", "d") for s in _TPCC_SECTORS)
        desc = tuple(f"{'near' if d == 'c' else 'far'}, {45 * k}-{45 * (k + 1)} deg ccw from B-A"
                     for d in ("c", "d") for k in range(8))
        return Partition.from_polygons("tpcc", _tpcc_polygons(quad_segs), (-h, h, 1.0 - h, 1.0 + h),
                                       labels=labels, descriptions=desc, lookup=_tpcc_lookup,
                                       quad_segs=quad_segs)
    raise KeyError(name)


_REGISTRY: dict[str, Partition] = {}
_BUILTIN = ("edc", "fdc", "lr", "tpcc")


def available() -> tuple[str, ...]:
    """Names :func:`get` knows: the built-ins and any registered partitions."""
    return tuple(sorted(set(_BUILTIN) | set(_REGISTRY)))


def register(partition: Partition) -> None:
    """Make a user-defined partition available to :func:`get` (and so to the solvers)."""
    if not isinstance(partition, Partition):
        raise ValueError(f"partition: expected a Partition, got {type(partition).__name__}")
    if partition.name in _BUILTIN:
        raise ValueError(f"partition: the name {partition.name!r} is a built-in partition")
    _REGISTRY[partition.name] = partition


@functools.lru_cache(maxsize=None)
def _get_builtin(name: str) -> Partition:
    return _build(name)


def get(name) -> Partition:
    """The partition called ``name`` (case-insensitive), or ``name`` itself if it is a Partition."""
    if isinstance(name, Partition):
        return name
    if not isinstance(name, str):
        raise ValueError(f"partition: expected a name or a Partition, got {name!r}")
    key = name.lower()
    if key in _REGISTRY:
        return _REGISTRY[key]
    if key in _BUILTIN:
        return _get_builtin(key)
    raise ValueError(f"partition: unknown name {name!r}; known: {', '.join(available())}")


def state_of_triplet(A, B, C, partition="edc") -> np.ndarray:
    """States of C in the AB frame for world points A, B, C (..., 2) each; output shape (...).

    >>> state_of_triplet([0, 0], [0, 2], [1, 4]).tolist()   # C = (0.5, 2) in the AB frame
    1
    """
    return get(partition).state_of(to_frame(C, A, B))
