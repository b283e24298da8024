"""Frames and plane geometry, vectorized over leading array dimensions.

Conventions (``docs/conventions.md``):

* The AB frame is the similarity transform that sends A to (0, 0) and B to (0, 1).
* A pose is ``(x, y, alpha)``; ``alpha`` is the heading in radians, counter-clockwise from +x.
* Angles are wrapped to (-pi, pi].
* Bearing to landmark L from pose (x, y, alpha): ``wrap(atan2(Ly - y, Lx - x) - alpha)``.
* Motion heading from pose n to position n+1: ``wrap(atan2(y1 - y0, x1 - x0) - alpha0)``.

Every function here is the single implementation of its formula in the package; solvers, the
simulator and the datasets import them rather than writing them again.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import as_float_array

__all__ = [
    "wrap_angle",
    "to_frame",
    "from_frame",
    "poses_to_frame",
    "poses_from_frame",
    "frame_rotation",
    "bearing",
    "motion_heading",
    "LocusCircle",
    "locus_circle",
    "locus_point",
    "heading_on_locus",
    "ray_circle_intersection",
    "triangulate_lsq",
    "triangulate_pairwise_centroid",
]

#: Squared distance below which two points count as coinciding (A and B of a frame).
COINCIDENT_EPS = 1e-18


def wrap_angle(angle):
    """Wrap angles (radians) to (-pi, pi].

    >>> float(wrap_angle(3 * np.pi))
    3.141592653589793
    """
    a = np.asarray(angle, dtype=float)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def _frame(A, B):
    A = as_float_array("A", A, last_dim=2)
    B = as_float_array("B", B, last_dim=2)
    d = B - A
    with np.errstate(over="ignore"):  # |d|^2 = inf (coordinates ~1e200) is still "not coincident"
        n2 = np.sum(d * d, axis=-1)
    if np.any(n2 <= COINCIDENT_EPS):
        raise ValueError("A, B: A and B coincide, so they define no frame")
    return A, d, n2


def frame_rotation(A, B):
    """Rotation (radians) of the AB frame's axes in the world: the world angle of its +x axis.

    A heading transforms as ``alpha_AB = wrap(alpha_world - frame_rotation(A, B))``.
    """
    _, d, _ = _frame(A, B)
    return np.arctan2(d[..., 1], d[..., 0]) - np.pi / 2


def _pow2_exponent(values):
    """Exponent e (int array) with max |values| over the last axis in [2^(e-1), 2^e); 0 where all 0."""
    peak = np.max(np.abs(values), axis=-1)
    e = np.frexp(peak)[1]
    return np.where(peak > 0, e, 0)


def to_frame(points, A, B):
    """World points (..., 2) to the AB frame, where A = (0, 0) and B = (0, 1).

    The map is translate by -A, rotate so that B - A points along +y, scale by 1/|B - A|:
    ``p_AB = (cross(d, p - A), dot(d, p - A)) / |d|^2`` with ``d = B - A``.

    The formula is scale-invariant, so where it would overflow it is evaluated on copies scaled
    by powers of two (exact, hence the same bits as the plain formula where both work): first by
    the largest coordinate, so that ``p - A`` cannot overflow, then by ``|d|``, so that ``|d|^2``
    can neither overflow nor underflow. Any finite input (e.g. 1e200) works. Raises ValueError
    if A and B coincide (``|d|^2 <= COINCIDENT_EPS`` in the caller's units) or if the result
    itself is beyond float64 (``|p - A| / |d| > 1.8e308``).

    >>> to_frame([2.0, 1.0], [1.0, 1.0], [1.0, 3.0]).tolist()
    [0.5, 0.0]
    >>> to_frame([0.0, 5e199], [1e200, 0.0], [1e200, 1e200]).tolist()
    [-1.0, 0.5]
    """
    p = as_float_array("points", points, last_dim=2)
    A = as_float_array("A", A, last_dim=2)
    B = as_float_array("B", B, last_dim=2)
    # Ordinary magnitudes: the formula as written (the scaled path below gives the same bits).
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        q = p - A
        d = B - A
        n2 = np.sum(d * d, axis=-1)
        x = (q[..., 0] * d[..., 1] - q[..., 1] * d[..., 0]) / n2
        y = (q[..., 0] * d[..., 0] + q[..., 1] * d[..., 1]) / n2
    if np.all(np.isfinite(n2)):
        if np.any(n2 <= COINCIDENT_EPS):
            raise ValueError("A, B: A and B coincide, so they define no frame")
        out = np.stack([x, y], axis=-1)
        if np.all(np.isfinite(out)):
            return out
    e1 = _pow2_exponent(np.concatenate(np.broadcast_arrays(p, A, B), axis=-1))[..., None]
    q = np.ldexp(p, -e1) - np.ldexp(A, -e1)
    d = np.ldexp(B, -e1) - np.ldexp(A, -e1)
    e2 = _pow2_exponent(d)[..., None]
    d = np.ldexp(d, -e2)
    # |q| / |d| above the float64 range is a true overflow of the answer (reported below).
    with np.errstate(over="ignore", invalid="ignore"):
        q = np.ldexp(q, -e2)
        n2 = np.sum(d * d, axis=-1)
        # x axis of the frame is d rotated by -90 degrees: (dy, -dx)
        x = (q[..., 0] * d[..., 1] - q[..., 1] * d[..., 0]) / np.where(n2 > 0, n2, 1.0)
        y = (q[..., 0] * d[..., 0] + q[..., 1] * d[..., 1]) / np.where(n2 > 0, n2, 1.0)
    # |B - A|^2 in the caller's units is n2 * 4^(e1 + e2): compare in log2 to stay in range.
    with np.errstate(divide="ignore"):
        log2_n2 = np.log2(n2) + 2.0 * (e1[..., 0] + e2[..., 0])
    if np.any(log2_n2 <= np.log2(COINCIDENT_EPS)):
        raise ValueError("A, B: A and B coincide, so they define no frame")
    out = np.stack([x, y], axis=-1)
    if not np.all(np.isfinite(out)):
        raise ValueError("points: the AB-frame coordinates overflow float64 (a point is more than "
                         "1.8e308 times |B - A| away from A)")
    return out


def from_frame(points, A, B):
    """AB-frame points (..., 2) back to world coordinates; inverse of :func:`to_frame`."""
    p = as_float_array("points", points, last_dim=2)
    A, d, _ = _frame(A, B)
    x, y = p[..., 0], p[..., 1]
    wx = A[..., 0] + x * d[..., 1] + y * d[..., 0]
    wy = A[..., 1] - x * d[..., 0] + y * d[..., 1]
    return np.stack([wx, wy], axis=-1)


def poses_to_frame(poses, A, B):
    """World poses (..., 3) ``(x, y, alpha)`` to the AB frame (headings rotate, positions scale)."""
    P = as_float_array("poses", poses, last_dim=3)
    xy = to_frame(P[..., :2], A, B)
    alpha = wrap_angle(P[..., 2] - frame_rotation(A, B))
    return np.concatenate([xy, alpha[..., None]], axis=-1)


def poses_from_frame(poses, A, B):
    """AB-frame poses (..., 3) back to the world; inverse of :func:`poses_to_frame`."""
    P = as_float_array("poses", poses, last_dim=3)
    xy = from_frame(P[..., :2], A, B)
    alpha = wrap_angle(P[..., 2] + frame_rotation(A, B))
    return np.concatenate([xy, alpha[..., None]], axis=-1)


def bearing(poses, landmarks):
    """Bearing (radians) of landmarks (..., 2) from poses (..., 3), relative to the heading.

    ``phi = wrap(atan2(Ly - y, Lx - x) - alpha)``; invariant under similarity transforms.
    """
    P = as_float_array("poses", poses, last_dim=3)
    L = as_float_array("landmarks", landmarks, last_dim=2)
    return wrap_angle(np.arctan2(L[..., 1] - P[..., 1], L[..., 0] - P[..., 0]) - P[..., 2])


def motion_heading(poses_from, positions_to):
    """Direction of travel from poses (..., 3) to positions (..., 2), relative to the heading.

    ``psi = wrap(atan2(y1 - y0, x1 - x0) - alpha0)`` (the paper's action a_n).
    """
    P = as_float_array("poses_from", poses_from, last_dim=3)
    Q = as_float_array("positions_to", positions_to, min_ndim=1)
    if Q.shape[-1] not in (2, 3):
        raise ValueError(f"positions_to: expected last axis of size 2 or 3, got shape {Q.shape}")
    return wrap_angle(np.arctan2(Q[..., 1] - P[..., 1], Q[..., 0] - P[..., 0]) - P[..., 2])


@dataclass(frozen=True)
class LocusCircle:
    """The circle of camera positions, in the AB frame, that see A and B at given bearings.

    Attributes (arrays broadcast to the bearings' shape):
        center: (..., 2) circle centre, on the line y = 0.5.
        radius: (...,) radius in units of |AB|; ``inf`` where degenerate.
        gamma: (...,) subtended angle ``wrap(phi_B - phi_A)``; the camera is left of AB (x < 0)
            when gamma > 0 and right (x > 0) when gamma < 0.
        side: (...,) +1 for the left arc (x < 0), -1 for the right arc, 0 where degenerate.
        degenerate: (...,) True when the camera is on line AB (gamma = 0 or pi): no finite arc.
    """

    center: np.ndarray
    radius: np.ndarray
    gamma: np.ndarray
    side: np.ndarray
    degenerate: np.ndarray


#: |sin(gamma)| below which a locus circle counts as degenerate (camera on line AB).
LOCUS_EPS = 1e-9


def locus_circle(phi_a, phi_b) -> LocusCircle:
    """Locus circle of the camera from bearings to A and B (inscribed-angle theorem).

    With gamma = wrap(phi_B - phi_A) the angle AB subtends at the camera, the camera lies on the
    circle through A = (0, 0) and B = (0, 1) with centre ``(-cot(gamma) / 2, 1/2)`` and radius
    ``1 / (2 |sin gamma|)``, on the arc left of AB when gamma > 0, right when gamma < 0.

    >>> c = locus_circle(0.0, np.pi / 2)   # A straight ahead, B 90 degrees to the left
    >>> c.center.round(6).tolist(), float(c.radius)
    ([-0.0, 0.5], 0.5)
    """
    pa = as_float_array("phi_a", phi_a)
    pb = as_float_array("phi_b", phi_b)
    gamma = wrap_angle(pb - pa)
    s = np.sin(gamma)
    degenerate = np.abs(s) < LOCUS_EPS
    safe_s = np.where(degenerate, 1.0, s)
    cx = np.where(degenerate, 0.0, -0.5 * np.cos(gamma) / safe_s)
    center = np.stack([cx, np.full_like(cx, 0.5)], axis=-1)
    radius = np.where(degenerate, np.inf, 0.5 / np.abs(safe_s))
    side = np.where(degenerate, 0, np.sign(gamma)).astype(int)
    return LocusCircle(center=center, radius=radius, gamma=gamma, side=side, degenerate=degenerate)


def locus_point(gamma, angle_at_a):
    """Point of the locus arc of subtended angle ``gamma`` whose chord from A makes ``angle_at_a``
    with AB, in the AB frame.

    The valid arc is swept by ``angle_at_a`` in (0, pi - |gamma|): in triangle A B X the angle at X
    is |gamma| and at A is ``a``, so by the law of sines ``|AX| = sin(|gamma| + a) / sin|gamma|``,
    and X is AB rotated by ``a`` towards the camera's side. Returns (..., 2); degenerate gammas
    (|sin gamma| < LOCUS_EPS) give A.
    """
    g = as_float_array("gamma", gamma)
    a = as_float_array("angle_at_a", angle_at_a)
    sg = np.abs(np.sin(g))
    ok = sg >= LOCUS_EPS
    r = np.where(ok, np.sin(np.abs(g) + a) / np.where(ok, sg, 1.0), 0.0)
    side = np.sign(g)
    x = -side * r * np.sin(a)
    y = r * np.cos(a)
    return np.stack(np.broadcast_arrays(x, y), axis=-1)


def heading_on_locus(positions, phi_a, A=(0.0, 0.0)):
    """Camera heading at a position that sees A at bearing ``phi_a``: ``atan2(A - X) - phi_A``."""
    X = as_float_array("positions", positions, last_dim=2)
    A = as_float_array("A", A, last_dim=2)
    pa = as_float_array("phi_a", phi_a)
    return wrap_angle(np.arctan2(A[..., 1] - X[..., 1], A[..., 0] - X[..., 0]) - pa)


def ray_circle_intersection(origin, angle, center, radius, side=None):
    """Intersections of rays with circles: 0, 1 or 2 points, optionally only on one arc.

    Ray: ``origin + t (cos angle, sin angle)``, t > 0. Circle: ``|p - center| = radius``.
    ``side`` (AB frame): +1 keeps points with x < 0, -1 points with x > 0 (the valid arc of a
    locus circle, see :class:`LocusCircle`); None keeps both.

    Returns ``(points, valid)``: points (..., 2, 2) ordered by t, valid (..., 2) bool. Invalid slots
    hold the ray origin so that no NaN travels on.
    """
    o = as_float_array("origin", origin, last_dim=2)
    th = as_float_array("angle", angle)
    c = as_float_array("center", center, last_dim=2)
    r = np.asarray(radius, dtype=float)
    if np.any(np.isnan(r)) or np.any(r < 0):
        raise ValueError("radius: expected values >= 0 (inf allowed for a degenerate circle)")
    # x and y components as separate arrays: reductions over a trailing axis of length 2 are
    # several times slower than the elementwise sums (same values)
    shape = np.broadcast_shapes(th.shape, o.shape[:-1], c.shape[:-1], r.shape)
    side = None if side is None else np.asarray(side)
    ux = np.broadcast_to(np.cos(th), shape)
    uy = np.broadcast_to(np.sin(th), shape)
    ox, oy = np.broadcast_to(o[..., 0], shape), np.broadcast_to(o[..., 1], shape)
    r = np.broadcast_to(r, shape)
    finite = np.isfinite(r)
    rr = np.where(finite, r, 0.0)
    qx, qy = ox - c[..., 0], oy - c[..., 1]
    b = ux * qx + uy * qy
    cc = (qx * qx + qy * qy) - rr * rr
    disc = b * b - cc
    hit = finite & (disc >= 0)
    sq = np.sqrt(np.where(hit, disc, 0.0))
    pts = np.empty(shape + (2, 2))
    valid = np.empty(shape + (2,), dtype=bool)
    for k, t in enumerate((-b - sq, -b + sq)):
        v = hit & (t > 0)
        tv = np.where(v, t, 0.0)
        px, py = ox + tv * ux, oy + tv * uy
        if side is not None:
            v &= (side * px) < 0
            px, py = np.where(v, px, ox), np.where(v, py, oy)
        pts[..., k, 0], pts[..., k, 1], valid[..., k] = px, py, v
    return pts, valid


def _line_normals(angles):
    return np.stack([-np.sin(angles), np.cos(angles)], axis=-1)


#: Determinant below which rays count as parallel (no unique intersection).
PARALLEL_EPS = 1e-12


def triangulate_lsq(origins, angles):
    """Least-squares intersection of lines through ``origins`` (..., n, 2) at ``angles`` (..., n).

    Minimizes ``sum_i (n_i . (p - o_i))^2`` with ``n_i`` the unit normal of line i:
    ``p = (sum n n^T)^-1 sum n n^T o``. Returns ``(point (..., 2), ok (...))``; where all lines are
    parallel, ``ok`` is False and the point is the mean of the origins.
    """
    o = as_float_array("origins", origins, last_dim=2, min_ndim=2)
    th = as_float_array("angles", angles, min_ndim=1)
    if th.shape != o.shape[:-1]:
        raise ValueError(f"angles: expected shape {o.shape[:-1]} to match origins, got {th.shape}")
    n = _line_normals(th)
    M = np.einsum("...ni,...nj->...ij", n, n)
    v = np.einsum("...ni,...nj,...nj->...i", n, n, o)
    det = M[..., 0, 0] * M[..., 1, 1] - M[..., 0, 1] * M[..., 1, 0]
    ok = np.abs(det) > PARALLEL_EPS
    sdet = np.where(ok, det, 1.0)
    px = (M[..., 1, 1] * v[..., 0] - M[..., 0, 1] * v[..., 1]) / sdet
    py = (-M[..., 1, 0] * v[..., 0] + M[..., 0, 0] * v[..., 1]) / sdet
    p = np.stack([px, py], axis=-1)
    return np.where(ok[..., None], p, o.mean(axis=-2)), ok


def triangulate_pairwise_centroid(origins, angles):
    """Centroid of the pairwise intersections of lines of sight (the paper's resection step).

    For every pair (i, j) of lines ``o + t (cos a, sin a)`` the intersection point is computed; the
    result is the mean over pairs that are not parallel. Returns ``(point (..., 2), ok (...),
    ahead (...))``: ``ok`` False where every pair is parallel (then the mean of the origins);
    ``ahead`` True where every used intersection lies in front of both cameras (t > 0).
    """
    o = as_float_array("origins", origins, last_dim=2, min_ndim=2)
    th = as_float_array("angles", angles, min_ndim=1)
    if th.shape != o.shape[:-1]:
        raise ValueError(f"angles: expected shape {o.shape[:-1]} to match origins, got {th.shape}")
    n = th.shape[-1]
    ii, jj = np.triu_indices(n, k=1)
    u = np.stack([np.cos(th), np.sin(th)], axis=-1)
    ui, uj = u[..., ii, :], u[..., jj, :]
    oi, oj = o[..., ii, :], o[..., jj, :]
    cross = ui[..., 0] * uj[..., 1] - ui[..., 1] * uj[..., 0]
    good = np.abs(cross) > PARALLEL_EPS
    sc = np.where(good, cross, 1.0)
    w = oj - oi
    ti = (w[..., 0] * uj[..., 1] - w[..., 1] * uj[..., 0]) / sc
    tj = (w[..., 0] * ui[..., 1] - w[..., 1] * ui[..., 0]) / sc
    pts = oi + ti[..., None] * ui
    cnt = good.sum(axis=-1)
    ok = cnt > 0
    total = np.sum(np.where(good[..., None], pts, 0.0), axis=-2)
    p = np.where(ok[..., None], total / np.maximum(cnt, 1)[..., None], o.mean(axis=-2))
    ahead = ok & np.all(~good | ((ti > 0) & (tj > 0)), axis=-1)
    return p, ok, ahead
