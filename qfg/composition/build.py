"""Offline build of composition tensors (paper section 5a, "semi-sample-based").

Definition (conventions.md): with t1 = AB:C, t2 = BC:D, t3 = AB:D,

    T[i, j, k]  proportional to  E_{C uniform in state i of AB:C (in the window)}
                  area{ D in the AB window : AB:D = k, BC:D = j, D in the BC window }

normalized to sum 1, every state i weighted equally.

How it is computed. In the AB frame (A = (0, 0), B = (0, 1)) the AB-frame state polygons are
clipped to the window once. For one C, the BC-frame state polygons (already clipped to the window
in their own frame, so "D in the BC window" is built in) are carried to the AB frame by the
similarity :func:`qfg.geometry.from_frame` with frame points B and C, applied to their coordinates
(one vectorized transform for a whole batch of C), and every (j, k) intersection area is computed
exactly by shapely 2's vectorized ``intersection``/``area`` with broadcasting: an (S, m, 1) array of
moved BC polygons against the (1, 1, m) AB polygons, no Python loop per polygon or per pair.
Batches of C go to a process pool.

Sampling C. The expectation over C is estimated with the same number of samples per state:

* ``samples`` *weight* samples per state: a scrambled Sobol (low-discrepancy) sequence over the
  state's bounding box, kept where it falls in the state (rejection keeps the points uniform and
  well spread). Each carries weight 1 / samples: an equal-weight estimate of the mean.
* ``support_samples`` *support* samples per state near the state's corners (polygon vertices
  where the boundary turns, which is where rare combinations live: C close to A or B, to a
  window corner, to a crossing of a circle and a line). They are there to find every (j, k)
  that is feasible for some C in the state; they enter T with a total weight of
  ``support_weight`` (default 1e-9) of the state's mass, far below anything the weight samples
  resolve, so T stays the uniform-C estimate to that precision while its support is complete.
  docs/composition.md explains the choice and which entries need these samples.

Only real regions count: an entry enters the support when some intersection behind it has area
>= :data:`MIN_AREA` and a point on it passes the exact lookups (:func:`witnessed`); this drops
slivers between the polygons' straight-segment circles and the true circles, and rounding slivers
at B. A mirror-symmetric partition (:func:`mirror_permutation`) is sampled in half its states and
the rest mirrored.

Example (a quick, coarse tensor; the shipped ones use many more samples):

>>> from qfg.composition.build import build
>>> t = build("lr", samples=64, support_samples=0, progress=False)
>>> t.shape, t.nnz
((2, 2, 2), 8)
"""

from __future__ import annotations

import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import shapely
from scipy.stats import qmc

from .. import partitions as _partitions
from .._validate import as_rng, as_seed_sequence, non_negative, positive_int
from .._version import __version__
from ..geometry import from_frame, to_frame
from .store import CompositionTensor, checksum

__all__ = ["build", "compare", "random_configurations", "sample_state", "support_sample_points",
           "corner_points", "mirror_permutation", "intersection_areas", "witnessed",
           "SHIPPED_SAMPLES", "DEFAULT_SUPPORT_WEIGHT", "MIN_AREA"]

#: Share of a state's mass given to its support samples (see module docstring).
DEFAULT_SUPPORT_WEIGHT = 1e-9

#: Weight samples per state of the shipped tensors (``qfg tensors build`` defaults to these, so
#: that the rebuild command in an error message reproduces the shipped file). docs/composition.md
#: shows that doubling them changes no support entry and moves T by well under 1%.
SHIPPED_SAMPLES = {"edc": 16384, "fdc": 16384, "lr": 4096, "tpcc": 16384}

#: Threshold above which an entry counts as non-negligible in :func:`compare`.
COMPARE_THRESHOLD = 1e-4

#: Batch of C samples per task sent to a worker.
_BATCH = 64

_B = np.array([0.0, 1.0])


def sample_state(partition, state: int, n: int, seed) -> np.ndarray:
    """``n`` points (n, 2) uniform in one state of a partition, within its window; low-discrepancy.

    A scrambled Sobol sequence over the state polygon's bounding box (widened by 1e-6 |AB| so that
    the exact state, whose circular edges bulge past the inscribed polygon, is covered) is kept
    where :meth:`~qfg.partitions.Partition.state_of` says ``state`` and the point is in the window,
    taking more of the sequence until ``n`` are kept. A prefix of a Sobol sequence restricted to a
    region is still evenly spread over it (stratified, unlike i.i.d. points).

    >>> pts = sample_state("fdc", 0, 8, np.random.default_rng(0))
    >>> pts.shape, bool((pts[:, 0] < 0).all() and (pts[:, 1] >= 1).all())
    ((8, 2), True)
    """
    part = _partitions.get(partition)
    n = positive_int("n", n)
    state = positive_int("state", state, minimum=0)
    if state >= part.n_states:
        raise ValueError(f"state: expected 0..{part.n_states - 1}, got {state}")
    x0, y0, x1, y1 = shapely.bounds(part.polygons[state])
    w = part.window
    x0, y0 = max(x0 - 1e-6, w[0]), max(y0 - 1e-6, w[2])
    x1, y1 = min(x1 + 1e-6, w[1]), min(y1 + 1e-6, w[3])
    frac = part.areas[state] / ((x1 - x0) * (y1 - y0))
    sob = qmc.Sobol(d=2, scramble=True, seed=as_rng(seed))
    kept = np.empty((0, 2))
    total = 0
    while kept.shape[0] < n:
        want = int(np.ceil(1.3 * (n - kept.shape[0]) / frac)) + 16
        m = 1 << int(np.ceil(np.log2(max(want, 2))))  # Sobol is balanced in powers of two
        u = sob.random(m)
        total += m
        pts = np.column_stack([x0 + u[:, 0] * (x1 - x0), y0 + u[:, 1] * (y1 - y0)])
        inside = (part.state_of(pts) == state) & part.in_window(pts)
        kept = np.concatenate([kept, pts[inside]])
        if total > 1e4 * n / frac:  # pragma: no cover - only for a degenerate state
            raise ValueError(f"state: could not sample inside state {state} of {part.name}")
    return kept[:n]


def corner_points(poly, min_turn_deg: float = 5.0) -> np.ndarray:
    """Corners (k, 2) of a polygon: vertices where the boundary turns by at least ``min_turn_deg``.

    Circle arcs are drawn with many short segments that turn by 360 / (4 quad_segs) degrees each;
    a true corner (two lines, a line and a circle, a window corner) turns by much more.
    """
    out = []
    for ring in _rings(poly):
        xy = np.asarray(ring.coords)[:-1]
        if xy.shape[0] < 3:
            continue
        d_in = xy - np.roll(xy, 1, axis=0)
        d_out = np.roll(xy, -1, axis=0) - xy
        a = np.arctan2(d_out[:, 1], d_out[:, 0]) - np.arctan2(d_in[:, 1], d_in[:, 0])
        turn = np.abs(np.angle(np.exp(1j * a)))
        out.append(xy[turn >= np.deg2rad(min_turn_deg)])
    return np.concatenate(out) if out else np.empty((0, 2))


def _rings(geom):
    for g in getattr(geom, "geoms", [geom]):
        if g.is_empty:
            continue
        yield g.exterior
        yield from g.interiors


def support_sample_points(partition, state: int, n: int, seed,
                          radii=(1e-1, 1e-2, 1e-3, 1e-4)) -> np.ndarray:
    """``n`` points (n, 2) in one state, concentrated at the corners of its polygon, at many scales.

    Each point picks a corner (:func:`corner_points`) and a radius from ``radii`` (units of |AB|)
    at random and is drawn uniformly in the disc of that radius around the corner; it is kept if
    the exact lookup puts it in ``state`` and inside the window (so the polygons' inscribed
    circles never let a point of a neighbouring state in). Returns an empty array if ``n`` is 0.
    """
    part = _partitions.get(partition)
    if n == 0:
        return np.empty((0, 2))
    corners = corner_points(part.polygons[state])
    if corners.shape[0] == 0:  # pragma: no cover - every built-in state has corners
        return np.empty((0, 2))
    radii = np.asarray(radii, dtype=float)
    rng = as_rng(seed)
    kept = np.empty((0, 2))
    for _ in range(1000):
        want = 4 * (n - kept.shape[0]) + 16
        c = corners[rng.integers(corners.shape[0], size=want)]
        r = radii[rng.integers(radii.size, size=want)] * np.sqrt(rng.random(want))
        th = rng.uniform(0, 2 * np.pi, want)
        pts = c + np.column_stack([r * np.cos(th), r * np.sin(th)])
        inside = (part.state_of(pts) == state) & part.in_window(pts)
        kept = np.concatenate([kept, pts[inside]])
        if kept.shape[0] >= n:
            return kept[:n]
    raise ValueError(f"state: could not place {n} corner samples in state {state} of "
                     f"{part.name}")  # pragma: no cover


def mirror_permutation(partition, tol: float = 1e-9):
    """The state permutation of the reflection x -> -x of the AB frame, or None.

    Returns sigma (m,) int with polygon ``sigma[i]`` the mirror image of polygon i (symmetric
    difference below ``tol`` of its area) when the window is symmetric about x = 0 and every state
    has such a partner; None otherwise. Reflecting a whole configuration A, B, C, D about line AB
    reflects the BC frame too, so then ``T[sigma i, sigma j, sigma k] = T[i, j, k]`` exactly (the
    ties on x = 0 have measure zero). EDC, FDC, LR and TPCC are all mirror-symmetric.

    >>> mirror_permutation("fdc").tolist()
    [1, 0, 3, 2, 5, 4]
    """
    part = _partitions.get(partition)
    xmin, xmax, _, _ = part.window
    if not np.isclose(xmin, -xmax, rtol=0, atol=1e-12):
        return None
    polys = np.asarray(part.polygons, dtype=object)
    mirrored = shapely.transform(polys, lambda xy: xy * np.array([-1.0, 1.0]))
    overlap = shapely.area(shapely.intersection(mirrored[:, None], polys[None, :]))
    sigma = np.argmax(overlap, axis=1)
    n = len(polys)
    rest = part.areas + part.areas[sigma] - 2 * overlap[np.arange(n), sigma]
    if (np.any(rest > tol * part.areas) or not np.array_equal(np.sort(sigma), np.arange(n))
            or not np.array_equal(sigma[sigma], np.arange(n))):
        return None
    return sigma


def _moved_polygons(polys: np.ndarray, C: np.ndarray) -> np.ndarray:
    """BC-frame polygons (m,) carried to the AB frame for each C (S, 2): (S, m) geometries."""
    S, m = C.shape[0], polys.shape[0]
    geoms = np.tile(polys, S)
    counts = shapely.get_num_coordinates(geoms)
    owner = np.repeat(np.repeat(np.arange(S), m), counts)  # sample index of every coordinate
    # B is the BC frame's origin and C its (0, 1): from_frame(points, B, C) is BC -> AB.
    moved = shapely.transform(geoms, lambda xy: from_frame(xy, _B, C[owner]))
    return moved.reshape(S, m)


def intersection_areas(polys: np.ndarray, C, *, return_geometries: bool = False):
    """Areas (S, m, m) of BC state j (carried by C) intersected with AB state k, per C (S, 2).

    ``polys`` (m,) are the partition's state polygons clipped to its window (the same polygons
    serve as the AB-frame states and, in their own frame, as the BC-frame states). Entry
    [s, j, k] = area(BC_j(C_s) cap AB_k). With ``return_geometries`` also the (S, m, m) object
    array of the intersections (None where the bounding boxes are apart).

    >>> import qfg.partitions as qp
    >>> P = np.asarray(qp.get("lr").polygons, dtype=object)
    >>> a = intersection_areas(P, [[0.0, 2.0]])   # C straight above B: the BC frame is the AB one
    >>> a[0].round(6).tolist()                      # shifted by one, so left meets left only
    [[2.0, 0.0], [0.0, 2.0]]
    """
    C = np.asarray(C, dtype=float).reshape(-1, 2)
    polys = _clean(polys)
    moved = _moved_polygons(polys, C)
    # A similarity transform can round a nearly straight run of vertices into a tiny
    # self-intersection; repair those few so that the overlay sees valid input.
    bad = ~shapely.is_valid(moved)
    if bad.any():
        moved[bad] = shapely.make_valid(moved[bad])
    # Pairs whose bounding boxes are apart cannot intersect: skip them cheaply.
    mb = shapely.bounds(moved)[:, :, None, :]      # (S, m, 1, 4)
    ab = shapely.bounds(polys)[None, None, :, :]   # (1, 1, m, 4)
    overlap = ((mb[..., 0] <= ab[..., 2]) & (ab[..., 0] <= mb[..., 2])
               & (mb[..., 1] <= ab[..., 3]) & (ab[..., 1] <= mb[..., 3]))
    s, j, k = np.nonzero(overlap)
    try:
        geoms = shapely.intersection(moved[s, j], polys[k])
    except shapely.errors.GEOSException:
        geoms = np.array([_robust_intersection(a, b) for a, b in zip(moved[s, j], polys[k],
                                                                      strict=True)], dtype=object)
    out = np.zeros(overlap.shape)
    out[s, j, k] = shapely.area(geoms)
    if not return_geometries:
        return out
    full = np.full(overlap.shape, None, dtype=object)
    full[s, j, k] = geoms
    return out, full


def witnessed(partition, C, j, k, geoms) -> np.ndarray:
    """Whether intersection geometries really hold a point of the states they stand for.

    For n intersections: C (n, 2) in the AB frame, BC state ``j`` (n,), AB state ``k`` (n,) and
    the geometry ``geoms`` (n,) of BC_j(C) cap AB_k. A point on the geometry's surface D is
    checked with the exact lookups: AB:D = k, BC:D = j, and D inside both windows. This separates
    real (if thin) regions from slivers made by the polygons' straight-segment circles.
    Returns (n,) bool.
    """
    part = _partitions.get(partition)
    pts = shapely.point_on_surface(geoms)
    ok = ~shapely.is_empty(pts)
    D = np.zeros((len(pts), 2))
    if ok.any():
        D[ok] = shapely.get_coordinates(pts[ok])
    ok &= np.isfinite(D).all(axis=1)
    D = np.where(ok[:, None], D, 0.0)
    Dbc = to_frame(D, _B, C)
    return (ok & (part.state_of(D) == k) & (part.state_of(Dbc) == j) & part.in_window(D)
            & part.in_window(Dbc))


#: Least intersection area (|AB|^2) that counts as a real region. Rounding makes slivers of
#: 1e-40 .. 1e-20 where edges meet at B (every BC-frame polygon has B on an edge, every AB one
#: has it as a vertex); every real entry of the shipped partitions reaches 1e-4 or more for
#: some C (docs/composition.md shows the gap).
MIN_AREA = 1e-12

#: Vertices closer than this (|AB| units) are merged before any overlay: where a sector's ray meets
#: a circle, the computed crossing lands within rounding of a circle vertex and the two make a
#: degenerate edge that GEOS's overlay can reject.
CLEAN_TOLERANCE = 1e-9


def _clean(polys: np.ndarray) -> np.ndarray:
    return shapely.remove_repeated_points(np.asarray(polys, dtype=object), CLEAN_TOLERANCE)


def _robust_intersection(a, b):
    """One intersection when the vectorized overlay raised: make both valid, then snap-round."""
    a, b = shapely.make_valid(a), shapely.make_valid(b)
    for grid in (None, 1e-12, 1e-10):
        try:
            return shapely.intersection(a, b) if grid is None else \
                shapely.intersection(a, b, grid_size=grid)
        except shapely.errors.GEOSException:
            continue
    raise ValueError("C: shapely could not intersect two state polygons for this frame "
                     "(even with snap rounding to 1e-10)")  # pragma: no cover


# Worker state: the partition, sent once per process by the pool initializer.
_PART = None
_POLYS: np.ndarray | None = None


def _init_worker(part):
    global _PART, _POLYS
    _PART = part
    _POLYS = np.asarray(part.polygons, dtype=object)


def _work(C: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For a batch of C (S, 2) with weights (S,): the weighted sum (m, m) of the intersection
    areas, the largest area (m, m), and whether that largest intersection is real: at least
    MIN_AREA and with a witness point confirmed by the exact lookups."""
    areas, geoms = intersection_areas(_POLYS, C, return_geometries=True)
    m = areas.shape[1]
    biggest = areas.max(axis=0)
    j, k = np.nonzero(biggest >= MIN_AREA)
    best = np.argmax(areas[:, j, k], axis=0)
    ok = witnessed(_PART, C[best], j, k, geoms[best, j, k])
    confirmed = np.zeros((m, m), dtype=bool)
    confirmed[j[ok], k[ok]] = True
    return np.einsum("s,sjk->jk", w, areas), biggest, confirmed


def build(partition, samples: int = 4096, *, seed=0, support_samples: int | None = None,
          support_weight: float = DEFAULT_SUPPORT_WEIGHT, symmetric: bool = True,
          workers: int = 1, progress: bool = True) -> CompositionTensor:
    """Compute the composition tensor of a partition (module docstring gives the method).

    Args:
        partition: name or :class:`~qfg.partitions.Partition`; its window and polygons are used.
        samples: weight samples of C per state (low-discrepancy, uniform in the state).
        seed: seeds every random stream (same seed, same tensor, whatever ``workers``).
        support_samples: corner samples per state (default ``min(samples // 4, 1024)``); 0 for
            none.
        support_weight: share of each state's mass carried by its support samples.
        symmetric: use the partition's mirror symmetry (:func:`mirror_permutation`) if it has one:
            sample half the states, mirror the rest.
        workers: processes (1: in this process).
        progress: show a tqdm progress bar.

    Returns:
        a :class:`~qfg.composition.CompositionTensor` (``path`` None; see
        :func:`qfg.composition.save`). ``meta`` records the method, support samples and weight,
        how many entries only the support samples found, how many polygon-only slivers were
        dropped, workers and build time.
    """
    part = _partitions.get(partition)
    samples = positive_int("samples", samples)
    support_samples = (min(samples // 4, 1024) if support_samples is None
                       else positive_int("support_samples", support_samples, minimum=0))
    support_weight = non_negative("support_weight", support_weight)
    if support_weight >= 1:
        raise ValueError(f"support_weight: expected a share below 1, got {support_weight}")
    workers = positive_int("workers", workers)
    m = part.n_states
    streams = as_seed_sequence(seed).spawn(2 * m)

    # With a mirror symmetry sigma, only one state of each pair {i, sigma i} is sampled and the
    # other's slice is its mirror image: half the work, an exactly symmetric T.
    sigma = mirror_permutation(part) if symmetric else None
    todo = [i for i in range(m) if sigma is None or i <= sigma[i]]

    # Jobs: (state, kind 0 weight / 1 support, C batch, weights). Weight samples share
    # 1 - support_weight of the state's unit mass, support samples the rest.
    jobs = []
    for i in todo:
        Cw = sample_state(part, i, samples, np.random.default_rng(streams[i]))
        Cs = support_sample_points(part, i, support_samples, np.random.default_rng(streams[m + i]))
        share = support_weight if Cs.shape[0] else 0.0
        for kind, C, w in ((0, Cw, (1.0 - share) / samples), (1, Cs, share / max(Cs.shape[0], 1))):
            for a in range(0, C.shape[0], _BATCH):
                batch = C[a:a + _BATCH]
                jobs.append((i, kind, batch, np.full(batch.shape[0], w)))

    acc = np.zeros((2, m, m, m))
    biggest = np.zeros((2, m, m, m))
    confirmed = np.zeros((m, m, m), dtype=bool)
    t0 = time.perf_counter()
    bar = _progress(len(jobs), f"tensor {part.name}", progress)

    def collect(results):
        for (i, kind, _, _), (s, big, conf) in zip(jobs, results, strict=True):
            acc[kind, i] += s
            np.maximum(biggest[kind, i], big, out=biggest[kind, i])
            confirmed[i] |= conf
            bar.update(1)

    if workers == 1:
        _init_worker(part)
        collect(_work(C, w) for _, _, C, w in jobs)
    else:
        with ProcessPoolExecutor(workers, initializer=_init_worker, initargs=(part,)) as ex:
            collect(ex.map(_work, [job[2] for job in jobs], [job[3] for job in jobs],
                           chunksize=4))
    bar.close()
    seconds = time.perf_counter() - t0
    if sigma is not None:
        ix = np.ix_(sigma, sigma)
        for i in todo:
            if sigma[i] != i:
                acc[:, sigma[i]] = acc[:, i][(slice(None),) + ix]
                biggest[:, sigma[i]] = biggest[:, i][(slice(None),) + ix]
                confirmed[sigma[i]] = confirmed[i][ix]
    # Entries whose only positive areas are rounding slivers (below MIN_AREA) or slivers between
    # the polygons' straight-segment circles and the exact boundaries (no witness point) are not
    # feasible: drop them.
    total = np.where(confirmed, acc.sum(axis=0), 0.0)
    T = total / total.sum()
    support = T > 0
    positive = biggest > 0
    from_weights = (biggest[0] >= MIN_AREA) & confirmed
    meta = {"method": "semi-sample-based: scrambled-Sobol C per state (weights) + corner C "
                      "samples (support), exact shapely intersection areas, witness-checked",
            "support_samples_per_state": support_samples, "support_weight": support_weight,
            "nnz_weight_samples": int(np.count_nonzero(from_weights)),
            "nnz_support_only": int(np.count_nonzero(support & ~from_weights)),
            "dropped_unwitnessed": int(np.count_nonzero(positive.any(axis=0) & ~confirmed)),
            "max_area": biggest.max(axis=0),
            "mirror_symmetry": sigma is not None, "workers": workers,
            "build_seconds": round(seconds, 3)}
    return CompositionTensor(partition=part.name, table=T, support=support, window=part.window,
                             samples_per_state=samples, seed=seed, quad_segs=part.quad_segs,
                             version=__version__, sha256=checksum(T), meta=meta)


def random_configurations(partition, n: int, seed, *, batch: int = 2_000_000):
    """Counts (m, m, m) of the states (AB:C, BC:D, AB:D) of ``n`` random configurations.

    In the AB frame (A = (0, 0), B = (0, 1)): C and D uniform in the window, kept when D is also
    inside the BC window (so ``n`` is the number drawn, the counts sum to the number kept). The
    states come from the exact lookups (:meth:`~qfg.partitions.Partition.state_of`, with
    :func:`qfg.geometry.to_frame` for the BC frame), not from the polygons: an independent check
    of a tensor's support (``qfg tensors check``).
    """
    part = _partitions.get(partition)
    n = positive_int("n", n)
    rng = as_rng(seed)
    m = part.n_states
    x0, x1, y0, y1 = part.window
    counts = np.zeros(m ** 3, dtype=np.int64)
    done = 0
    while done < n:
        k = min(batch, n - done)
        C = rng.uniform([x0, y0], [x1, y1], (k, 2))
        D = rng.uniform([x0, y0], [x1, y1], (k, 2))
        Dbc = to_frame(D, _B, C)
        ok = part.in_window(Dbc)
        i, j, kk = part.state_of(C[ok]), part.state_of(Dbc[ok]), part.state_of(D[ok])
        counts += np.bincount((i * m + j) * m + kk, minlength=m ** 3)
        done += k
    return counts.reshape(m, m, m)


def compare(a, b, threshold: float = COMPARE_THRESHOLD) -> dict:
    """How far two tensors of the same partition are apart (e.g. a build and its double).

    Returns a dict:
        l1: sum |T_a - T_b| (twice the total-variation distance; both sum to 1).
        max_rel: max |T_a - T_b| / T_a over the non-negligible entries, those with
            T_a >= ``threshold``; ``mass_above``: the share of T_a's mass they hold;
            ``n_above``: how many there are.
        support_only_a, support_only_b: entries in one support and not the other; ``support_equal``.
    """
    from .online import as_table
    Ta, Tb = as_table(a), as_table(b)
    if Ta.shape != Tb.shape:
        raise ValueError(f"b: shape {Tb.shape} differs from a's {Ta.shape}")
    threshold = non_negative("threshold", threshold)
    big = Ta >= threshold
    rel = np.abs(Tb - Ta)[big] / Ta[big]
    sa, sb = Ta > 0, Tb > 0
    return {"l1": float(np.abs(Ta - Tb).sum()), "max_rel": float(rel.max()) if rel.size else 0.0,
            "threshold": threshold, "n_above": int(big.sum()), "mass_above": float(Ta[big].sum()),
            "support_only_a": int(np.count_nonzero(sa & ~sb)),
            "support_only_b": int(np.count_nonzero(sb & ~sa)),
            "support_equal": bool(np.array_equal(sa, sb))}


class _NoBar:
    def update(self, n):
        pass

    def close(self):
        pass


def _progress(total, desc, enabled):
    if not enabled:
        return _NoBar()
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit="batch", dynamic_ncols=True)
