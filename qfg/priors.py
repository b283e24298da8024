"""Priors over AB-frame configurations ``[C, X_1, ..., X_n]`` (the points a triplet solver
reasons about), as objects.

Every prior has a ``name``, ``log_density(points)`` and ``sample(seed, n_cameras, size)``:

* :class:`WorldBoxPrior` (``"world"``): exact for the simulator's world, every object (the three
  landmarks and every camera position) i.i.d. uniform in a W x H box, every pair at least
  ``d_min`` apart. Seen from the AB frame, the shared unknown scale and rotation of AB couple C
  and the cameras; the density integrates them out (derivation: ``docs/priors.md``).
* :class:`WindowPrior` (``"uniform"``): independent points uniform in an AB-frame window.
* :class:`ProductPrior` (``"world-product"``): the former ``"world"`` prior, a product of
  independent heavy-tailed per-point densities fitted to the world's AB-frame marginal. It is an
  *approximation*: it ignores the coupling, which costs about 0.1 nats of log score (issue 10).
* :class:`CallablePrior`: a user's own density (and optionally sampler).

Camera headings are uniform in every prior here (a uniform world heading is uniform in any
frame), so priors are densities over positions only. Units: AB-frame lengths (|AB| = 1).

>>> import numpy as np
>>> p = get("world")
>>> x = p.sample(np.random.default_rng(0), n_cameras=2, size=4)
>>> x.shape, bool(np.all(np.isfinite(p.log_density(x))))
((4, 3, 2), True)
"""

from __future__ import annotations

import numpy as np

from ._validate import as_float_array, as_rng, non_negative, positive_int

__all__ = ["Prior", "WorldBoxPrior", "TravelPrior", "TrajectoryPrior", "MixturePrior",
           "WindowPrior", "ProductPrior", "CallablePrior", "get", "sample_measurements", "NAMES",
           "DEFAULT_WINDOW"]

#: Names :func:`get` accepts.
NAMES = ("world", "world-product", "uniform")

#: Default AB-frame window of :class:`WindowPrior` (the solvers' former ``prior_window``).
DEFAULT_WINDOW = (-6.0, 6.0, -5.5, 6.5)

# The simulator's defaults (qfg.simulation.SimulationConfig), repeated here so that this module
# does not import the simulator at import time; a test checks that they agree.
_SIM_WIDTH, _SIM_HEIGHT, _SIM_DMIN = 6.0, 7.0, 0.01

# Accepted parameter ranges, checked at construction so that no solver meets an overflow later.
#: Lengths (box sides, the product prior's scale, window sides): squares and products of two of
#: them (W H, s^2, window areas) must be finite, non-zero normal floats with room left for sums
#: (s^2 + |P|^2) and powers taken in log space: 1e-100 <= length <= 1e100 keeps every such
#: product within [1e-200, 1e200] (float64 spans [2.2e-308, 1.8e308]).
LENGTH_RANGE = (1e-100, 1e100)
#: Least side of WorldBoxPrior's box (world units): geometry.to_frame calls two points closer than
#: 1e-9 coincident (COINCIDENT_EPS = 1e-18 on |AB|^2), which two points uniform in a box of side L
#: are with probability about pi 1e-18 / L^2: 3e-12 per pair at L = 1e-3, so sampling never fails.
MIN_BOX_SIDE = 1e-3
#: Window coordinates: |v| <= 1e100, so that xmax - xmin is finite (<= 2e100).
COORD_LIMIT = 1e100
#: Window aspect ratio (long side / short side): the baseline solver lays candidates on a grid of
#: about sqrt(n * aspect) by n / that cells, which for a more elongated window has more cells
#: than candidates asked for; an AB-frame window that elongated (|AB| = 1) is not a region the
#: solvers reason in.
MAX_WINDOW_ASPECT = 1e3
#: Most rho quadrature points of WorldBoxPrior: time is linear in n_rho (2000 configurations of
#: 4 points: 40 ms at 128, 1.0 s at 4096, 16 s at 65536) while the error falls as n_rho^-2
#: (max |log p - log p(16384)|: 1.2e-3 at 128, 1.2e-6 nats at 4096); measured with the loop of
#: WorldBoxPrior(n_rho=n).log_density over WorldBoxPrior().sample(default_rng(0), 3, 2000).
MAX_N_RHO = 4096


def _length(name: str, value, lo: float = LENGTH_RANGE[0]) -> float:
    """``value`` as a float in [lo, LENGTH_RANGE[1]], or a ValueError naming ``name`` and the
    range."""
    v = non_negative(name, value)
    hi = LENGTH_RANGE[1]
    if not lo <= v <= hi:
        raise ValueError(f"{name}: expected a length in [{lo:g}, {hi:g}] (products of lengths "
                         f"must stay finite and non-zero, points distinguishable), got {value!r}")
    return v


#: (configurations x rho points) per evaluation block of :meth:`WorldBoxPrior.log_density`: its
#: (N, n_rho) temporaries then stay in the core's cache (and memory stays bounded).
_CHUNK_ELEMENTS = 1 << 16


def _int_power(x, p: int) -> np.ndarray:
    """x ** p for an integer p >= 1 by repeated squaring (exact to rounding, no exp/log)."""
    out, base = None, x
    while True:
        if p & 1:
            # (base is rebound, never written: out may alias it unless it is x itself)
            out = (base.copy() if base is x else base) if out is None else out * base
        p >>= 1
        if not p:
            return out
        base = base * base


def _points(points) -> np.ndarray:
    p = as_float_array("points", points, min_ndim=2, last_dim=2)
    if p.shape[-2] < 1:
        raise ValueError(f"points: expected at least one point (shape (..., k, 2), k >= 1), "
                         f"got shape {p.shape}")
    return p


def _sample_args(n_cameras, size):
    return positive_int("n_cameras", n_cameras, minimum=0), positive_int("size", size, minimum=0)


class Prior:
    """Base class: a prior over AB-frame configurations ``[C, X_1, ..., X_n]``.

    Subclasses implement:

    * ``log_density(points)``: points (..., k, 2), k = n + 1 >= 1, AB-frame positions in the order
      [C, X_1, ..., X_n]; returns (...,) the log density up to an additive constant that depends
      only on k. Finite wherever the density is positive; -inf only where it is truly 0.
    * ``sample(seed, n_cameras, size)``: (size, 1 + n_cameras, 2) configurations drawn exactly from
      the prior.
    """

    name: str = "prior"

    def log_density(self, points) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def __repr__(self):
        return f"{type(self).__name__}(name={self.name!r})"


class WorldBoxPrior(Prior):
    """Exact AB-frame prior of the simulator's world: A, B and the k = n + 1 points C, X_1..X_n
    i.i.d. uniform in a ``width`` x ``height`` box, conditioned on every pair being at least
    ``d_min`` apart.

    Writing world points as complex numbers ``P = t + z q`` (``q_A = 0``, ``q_B = i``, ``z = s
    e^{i rho}``), ``dA dB dP_1..dP_k = s^(2k+1) dt ds drho dq_1..dq_k``, so

        prior(q_1..q_k) = c_k ∫_0^π dρ ∫_{s0}^{s1} s^(2k+1) (W - s xr(ρ)) (H - s yr(ρ)) ds,

    with xr, yr the x and y extents of {0, i, q_1..q_k} rotated by ρ, ``s1 = min(W/xr, H/yr)``
    (the scaled, rotated configuration must fit in the box; the t-volume where it fits is the
    product term) and ``s0 = d_min / delta`` (delta the least pairwise distance among A, B and the
    q_j). The inner integral is done in closed form, the outer by the trapezoid rule on ``n_rho``
    equally spaced angles (periodic, so the rule converges fast; ``n_rho`` must be even since
    ``yr(ρ) = xr(ρ - π/2)``). With ``c_k = 2 / (W H)^(k+2)`` (ρ over [0, 2π) covers [0, π) twice)
    the density is normalized up to the factor P(all pairs >= d_min) = 1 - O(k^2 d_min^2 / (W H)).

    Exactness: the density is exact (up to the quadrature) for the joint-rejection model above,
    which :meth:`sample` draws from. ``qfg.simulation.sample_positions`` redraws only the
    offending points instead of the whole configuration; the two models differ by
    O(k^2 π d_min^2 / (W H)) in total variation (about 1e-5 at the defaults). A triplet from a
    scenario (``triplet_histories``) also has its views among other objects that keep d_min from
    them, a coupling of the same negligible order. Evaluating the prior on a subset of the points
    is, likewise, its marginal up to O(d_min^2).

    **The pair's scale** (``scale_power`` p, default 0). With p = 0, B is uniform in the box
    like every other point, so the distance s = |AB| has density about ∝ s (the area of a ring):
    a small pair is improbable, and with it every configuration that puts C or a camera many
    |AB| away (the density falls as the extent^-(2k+2)). Where landmarks stand in clusters (a
    pair 0.3 m apart in an 8 m arena) that prior decides C's depth against the data. With p ≠ 0
    B is drawn at distance s from A with density ∝ s^(1+p) on [d_min, the box's diagonal] (p =
    -2: s log-uniform, every scale of the pair equally likely), in a uniform direction, redrawn
    while outside the box; the others as before. Only the power of s changes:

        prior(q_1..q_k) ∝ ∫_0^π dρ ∫_{s0}^{s1} s^(2k+1+p) (W - s xr(ρ)) (H - s yr(ρ)) ds,

    normalized up to a constant of k and p (the density of s and the redraws). p is an integer
    in [-2, 2]; p < 0 needs d_min > 0 (s^(1+p) is not integrable at 0 otherwise).

    >>> p = WorldBoxPrior()
    >>> q = np.array([[[0.4, 0.5]], [[-0.4, 0.5]]])        # C and its mirror image
    >>> a, b = p.log_density(q)
    >>> bool(np.isclose(a, b))
    True
    >>> far = np.array([[[8.0, 0.5]]])                     # C 8 |AB| from the pair
    >>> bool(WorldBoxPrior(scale_power=-2).log_density(far)[0] - WorldBoxPrior().log_density(far)[0]
    ...      > WorldBoxPrior(scale_power=-2).log_density(q[:1])[0] - p.log_density(q[:1])[0])
    True
    """

    name = "world"

    def __init__(self, width: float = _SIM_WIDTH, height: float = _SIM_HEIGHT,
                 d_min: float = _SIM_DMIN, n_rho: int = 128, scale_power: int = 0):
        self.width = _length("width", width, MIN_BOX_SIDE)
        self.height = _length("height", height, MIN_BOX_SIDE)
        self.d_min = non_negative("d_min", d_min)
        if self.d_min >= min(self.width, self.height):
            # every object keeps d_min from every other: with d_min as large as the box's short
            # side at most a handful of objects fit and the world cannot be sampled
            raise ValueError(f"d_min: expected a number in [0, {min(self.width, self.height):g}) "
                             f"(less than the box's shorter side), got {d_min!r}")
        n_rho = positive_int("n_rho", n_rho, minimum=4)
        if n_rho % 2 or n_rho > MAX_N_RHO:
            raise ValueError(f"n_rho: expected an even integer in [4, {MAX_N_RHO}] (yr(ρ) = "
                             f"xr(ρ - π/2) needs it even; beyond {MAX_N_RHO} the quadrature "
                             f"error is below 1e-6 nats and time grows linearly), got {n_rho}")
        self.n_rho = n_rho
        if isinstance(scale_power, (bool, np.bool_)) or not isinstance(
                scale_power, (int, np.integer)) or not -2 <= scale_power <= 2:
            raise ValueError(f"scale_power: expected an integer in [-2, 2], got {scale_power!r}")
        if scale_power < 0 and self.d_min == 0:
            raise ValueError(f"scale_power: {scale_power} needs d_min > 0 (the pair's distance "
                             f"s has density ∝ s^{1 + scale_power}, not integrable at 0)")
        self.scale_power = int(scale_power)
        rho = np.pi * np.arange(n_rho) / n_rho
        self._cos, self._sin = np.cos(rho), np.sin(rho)

    def __repr__(self):
        return (f"WorldBoxPrior(width={self.width:g}, height={self.height:g}, "
                f"d_min={self.d_min:g}, n_rho={self.n_rho}"
                + (f", scale_power={self.scale_power}" if self.scale_power else "") + ")")

    def replace(self, **changes) -> "WorldBoxPrior":
        """The same prior with some parameters changed (``width``, ``height``, ``d_min``,
        ``n_rho``, ``scale_power``): the solvers' coarser quadratures keep the rest.

        >>> WorldBoxPrior(width=4.0, height=8.0, scale_power=-2).replace(n_rho=16)
        WorldBoxPrior(width=4, height=8, d_min=0.01, n_rho=16, scale_power=-2)
        """
        bad = sorted(set(changes) - {"width", "height", "d_min", "n_rho", "scale_power"})
        if bad:
            raise ValueError(f"replace: {bad[0]!r} is not a WorldBoxPrior parameter")
        kw = {"width": self.width, "height": self.height, "d_min": self.d_min,
              "n_rho": self.n_rho, "scale_power": self.scale_power}
        return WorldBoxPrior(**{**kw, **changes})

    def log_density(self, points) -> np.ndarray:
        """Log prior of AB-frame configurations (..., k, 2) -> (...,), up to a constant of k.

        -inf only where the density is 0: two points closer than d_min at every admissible scale
        (coinciding points with d_min > 0), or a configuration too spread out to fit in the box
        at a scale that keeps d_min.
        """
        p = _points(points)
        lead, k = p.shape[:-2], p.shape[-2]
        flat = p.reshape(-1, k, 2)
        out = np.empty(flat.shape[0])
        step = max(1, _CHUNK_ELEMENTS // self.n_rho)
        for i in range(0, flat.shape[0], step):
            out[i:i + step] = self._log_density_flat(flat[i:i + step])
        return out.reshape(lead)

    def _log_density_flat(self, q):
        # work on the configuration {A, B, q_1..q_k} (A = 0, B = i) scaled by c >= 1 so that huge
        # inputs cannot overflow; only s1 scales (s1 = s1' / c), the ratios alpha, beta, u0
        # below are scale-free
        c = np.maximum(1.0, np.max(np.abs(q), axis=(1, 2)))
        hi, lo, d2 = self._extents(q, c)
        return self._from_extents(np.subtract(hi, lo, out=hi), d2, c, q.shape[1])

    def _extents(self, q, c):
        """The x extents over the rotations rho, hi and lo (M, N), and the least squared pairwise
        distance d2 (N,) of the configurations {A, B, q_1..q_k} (``q`` (N, k, 2), k >= 0)
        scaled by ``1 / c`` (N,)."""
        N, k = q.shape[:2]
        qx, qy = q[..., 0] / c[:, None], q[..., 1] / c[:, None]
        by = 1.0 / c
        # x coordinate after rotation by rho: x cos - y sin; extents over the points, accumulated
        # point by point on (M, N) arrays (rho first: the sums and maxima over rho below are then
        # elementwise over rows, much faster than reductions over a short trailing axis)
        cs, sn = self._cos[:, None], self._sin[:, None]
        pb = -by[None, :] * sn                                        # A projects to 0
        hi, lo = np.maximum(0.0, pb), np.minimum(0.0, pb)
        pj = np.empty_like(hi)
        for j in range(k):
            np.multiply(qx[:, j], cs, out=pj)
            pj -= qy[:, j] * sn
            np.maximum(hi, pj, out=hi)
            np.minimum(lo, pj, out=lo)
        # least pairwise distance among A, B and the q_j (A-B is 1), in the scaled configuration
        px = [np.zeros(N), np.zeros(N)] + [qx[:, j] for j in range(k)]
        py = [np.zeros(N), by] + [qy[:, j] for j in range(k)]
        d2 = np.full(N, np.inf)
        for i in range(k + 2):
            for j in range(i + 1, k + 2):
                dx, dy = px[i] - px[j], py[i] - py[j]
                np.minimum(d2, dx * dx + dy * dy, out=d2)
        return hi, lo, d2

    def log_density_extended(self, base, extra, rows=None, with_base: bool = False):
        """``log_density`` of configurations that add one point to a shared base: configuration
        i is ``base[rows[i]]`` (k points) plus ``extra[i]``, (K,) from ``base`` (U, k, 2),
        ``extra`` (K, 2) and ``rows`` (K,) ints into U (default ``arange(K)``, K = U). The
        base's extents over the rotations are computed once per base row, so K configurations
        cost O(U k + K k) elementwise work on the rotations' axis instead of O(K k) (the SIS
        solvers' final weights: several C draws per camera trajectory; the joint camera prior:
        several children per parent trajectory). Equal to ``log_density`` of the stacked
        configurations up to rounding (the density is symmetric in the points). With
        ``with_base`` also returns ``log_density(base)`` (U,) from the same extents (k >= 1).

        ``extra`` (U, r, 2) without ``rows`` gives r points per base row, (U, r): the same as
        ``rows = repeat(arange(U), r)`` on ``extra.reshape(-1, 2)``, without gathering the
        base's extents per point.

        >>> p = WorldBoxPrior()
        >>> base = np.array([[[1.0, 0.5], [0.2, -1.0]]])
        >>> extra = np.array([[0.4, 0.5], [3.0, 2.0]])
        >>> a = p.log_density_extended(base, extra, [0, 0])
        >>> b = p.log_density(np.concatenate([np.repeat(base, 2, axis=0), extra[:, None]], 1))
        >>> bool(np.allclose(a, b, rtol=0, atol=1e-12))
        True
        >>> bool(np.allclose(p.log_density_extended(base, extra[None]), a, rtol=0, atol=1e-12))
        True
        """
        b = as_float_array("base", base, min_ndim=3, last_dim=2)
        if b.ndim != 3:
            raise ValueError(f"base: expected shape (U, k, 2), got {b.shape}")
        U, k = b.shape[:2]
        e = as_float_array("extra", extra, min_ndim=2, last_dim=2)
        grouped = rows is None and e.ndim == 3
        if grouped and e.shape[0] != U:
            raise ValueError(f"extra: expected shape ({U}, r, 2) (r points per base row) or "
                             f"(K, 2), got {e.shape}")
        if not grouped and e.ndim != 2:
            raise ValueError(f"extra: expected shape (K, 2), or (U, r, 2) without rows, got "
                             f"{e.shape}")
        if not grouped:
            r = np.arange(e.shape[0]) if rows is None else np.asarray(rows)
            if r.shape != (e.shape[0],) or not np.issubdtype(r.dtype, np.integer) or (
                    r.size and (r.min() < 0 or r.max() >= U)):
                raise ValueError(f"rows: expected {e.shape[0]} integers in [0, {U}) (one base "
                                 f"row per extra point), got shape {r.shape}")
        if with_base and not k:
            raise ValueError("base: with_base needs at least one base point (k >= 1)")
        cb = np.maximum(1.0, np.max(np.abs(b), axis=(1, 2))) if k else np.ones(U)
        hb, lb, db = self._extents(b, cb)                              # (M, U), (U,)
        own = self._from_extents(hb - lb, db, cb, k) if with_base else None
        out = np.empty(e.shape[:-1])
        if grouped:
            step = max(1, _CHUNK_ELEMENTS // (self.n_rho * max(1, e.shape[1])))
            for i in range(0, U, step):
                s = slice(i, i + step)
                out[s] = self._add_point(hb[:, s, None], lb[:, s, None], db[s, None],
                                         cb[s, None], b[s, None], e[s])
        else:
            step = max(1, _CHUNK_ELEMENTS // self.n_rho)
            for i in range(0, e.shape[0], step):
                rr = r[i:i + step]
                out[i:i + step] = self._add_point(hb[:, rr], lb[:, rr], db[rr], cb[rr], b[rr],
                                                  e[i:i + step])
        return (out, own) if with_base else out

    def _add_point(self, hb, lb, db, cb, b, e):
        """The log density of base configurations plus one point ``e`` (*S, 2) from the bases'
        scaled extents ``hb``, ``lb`` (M, *S), least squared distances ``db`` (*S), scales
        ``cb`` (*S) and points ``b`` (*S, k, 2) (any of them broadcast along S)."""
        k = b.shape[-2]
        # the configuration's scale covers the new point too; the base's extents rescale
        c = np.maximum(cb, np.max(np.abs(e), axis=-1))
        f = cb / c
        ex, ey = e[..., 0] / c, e[..., 1] / c
        rot = (-1,) + (1,) * c.ndim
        pe = ex * self._cos.reshape(rot) - ey * self._sin.reshape(rot)      # (M, *S)
        hi = np.maximum(hb * f, pe)
        lo = np.minimum(lb * f, pe)
        # the new point's least squared distance to A, B and the base points
        d2 = np.minimum(db * (f * f), ex * ex + ey * ey)
        np.minimum(d2, ex * ex + (ey - 1.0 / c) ** 2, out=d2)
        for j in range(k):
            dx = (e[..., 0] - b[..., j, 0]) / c
            dy = (e[..., 1] - b[..., j, 1]) / c
            np.minimum(d2, dx * dx + dy * dy, out=d2)
        xr = np.subtract(hi, lo, out=hi).reshape(self.n_rho, -1)
        return self._from_extents(xr, d2.ravel(), c.ravel(), k + 1).reshape(c.shape)

    def _least_scale(self, d2):
        """s0 = d_min / delta (N,): the least scale that keeps every pair d_min apart, from the
        least squared pairwise distance ``d2`` (N,) of the configurations (inf where points
        coincide and d_min > 0)."""
        delta = np.sqrt(d2)
        with np.errstate(divide="ignore"):
            return np.where(delta > 0, self.d_min / np.where(delta > 0, delta, 1.0),
                            0.0 if self.d_min == 0 else np.inf)

    def _from_extents(self, xr, d2, c, k):
        """The log density from the scaled configurations' x extents ``xr`` (M, N) over the
        rotations rho (overwritten), their least squared pairwise distance ``d2`` (N,) and scale
        ``c`` (N,), for k points besides A and B."""
        W, H, M = self.width, self.height, self.n_rho
        yr = np.roll(xr, -M // 2, axis=0)                             # xr(rho + pi/2) = yr(rho)
        # s1 = min(W / xr, H / yr) = H / mx with mx = max(κ xr, yr), κ = H / W (mx > 0: A and B
        # are 1 / c apart, so xr and yr never vanish together); then α = s1 xr / W = κ xr / mx
        # and β = s1 yr / H = yr / mx: one of them is 1, the other q = min(κ xr, yr) / mx
        u = np.multiply(xr, H / W, out=xr)
        mx = np.maximum(u, yr)
        q = np.minimum(u, yr, out=u)
        q /= mx
        # ∫_{s0}^{s1} s^a (W - s xr)(H - s yr) ds = s1^(a+1) W H ∫_{u0}^1 u^a (1 - αu)(1 - βu) du
        # (u = s / s1, u0 = s0 / s1) = s1^(a+1) W H (G(1) - u0^(a+1) G(u0)) with
        # G(u) = 1 / (a + 1) - (α + β) u / (a + 2) + α β u^2 / (a + 3), and with α + β = 1 + q,
        # α β = q: G(1) = A0 - A1 q, A0 = 1/(a+1) - 1/(a+2) > A1 = 1/(a+2) - 1/(a+3) > 0
        a = 2 * k + 1 + self.scale_power
        inner = np.multiply(q, -(1.0 / (a + 2) - 1.0 / (a + 3)), out=yr)
        inner += 1.0 / (a + 1) - 1.0 / (a + 2)                        # G(1) > 0
        s0 = self._least_scale(d2)                                    # (N,)
        # u0^(a+1) by repeated squaring (it underflows to 0 for the usual tiny u0: d_min much
        # smaller than the scale, and then the G(u0) term is skipped: first checked at each
        # configuration's largest u0, which bounds the others, on (N,) instead of (M, N))
        with np.errstate(under="ignore", divide="ignore", invalid="ignore", over="ignore"):
            top = np.minimum(s0 * np.max(mx, axis=0) / H, 1.0)
            need = bool(np.any(_int_power(top, a + 1) > 0))
        if need:
            with np.errstate(under="ignore", invalid="ignore", over="ignore"):
                u0 = np.multiply(mx, (s0 / H)[None, :])
                np.minimum(u0, 1.0, out=u0)                           # u0 = min(s0 / s1, 1)
                g = (1.0 / (a + 1)) - (1.0 + q) * u0 / (a + 2) + q * u0 * u0 / (a + 3)
                g *= _int_power(u0, a + 1)                            # u0^(a+1) G(u0)
                inner -= g
            np.maximum(inner, 0.0, out=inner)
            inner[u0 >= 1.0] = 0.0        # an empty interval (G(1) - G(1) may round above 0)
        # the sum over rho of s1^(a+1) inner, with s1 relative to its largest value per
        # configuration, s1 / s1max = mxmin / mx: max s1 / min s1 over rho is at most
        # sqrt(2) max(W, H) / min(W, H) (every rotation has an extent >= diameter / sqrt(2)),
        # so the powers cannot underflow for a sane box
        mxmin = np.min(mx, axis=0)
        okm = np.isfinite(mxmin) & (mxmin > 0)
        mxmin = np.where(okm, mxmin, 1.0)
        rel = np.divide(mxmin, mx, out=mx)
        with np.errstate(under="ignore"):
            relp = _int_power(rel, a + 1)
            relp *= inner
            ssum = np.sum(relp, axis=0)
        ok = okm & (ssum > 0)
        # trapezoid weight pi / M; the joint density of the k + 2 world points is (W H)^-(k+2)
        # and rho in [0, 2 pi) covers [0, pi) twice: normalized up to P(all pairs >= d_min)
        const = np.log(2.0 * np.pi / M) + np.log(W * H) - (k + 2) * np.log(W * H)
        with np.errstate(divide="ignore"):
            return np.where(ok, (a + 1) * (np.log(H / mxmin) - np.log(c))
                            + np.log(np.where(ok, ssum, 1.0)) + const, -np.inf)

    def sample_world(self, seed, n_points: int, size: int) -> np.ndarray:
        """(size, n_points, 2) world points i.i.d. uniform in [0, W] x [0, H], every pair of a
        configuration at least d_min apart (whole configurations rejected and redrawn)."""
        rng = as_rng(seed)
        n_points = positive_int("n_points", n_points)
        size = positive_int("size", size, minimum=0)
        out = rng.uniform((0.0, 0.0), (self.width, self.height), size=(size, n_points, 2))
        if self.d_min == 0 or n_points < 2:
            return out
        iu = np.triu_indices(n_points, k=1)
        d2min = self.d_min ** 2
        todo = np.arange(size)
        for _ in range(10_000):
            d = out[todo][:, iu[0]] - out[todo][:, iu[1]]
            bad = np.any(np.sum(d * d, axis=-1) < d2min, axis=-1)
            todo = todo[bad]
            if todo.size == 0:
                return out
            out[todo] = rng.uniform((0.0, 0.0), (self.width, self.height),
                                    size=(todo.size, n_points, 2))
        raise ValueError(f"d_min: could not place {n_points} points {self.d_min} apart in a "
                         f"{self.width} x {self.height} box")

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        """Exact draws: simulate worlds [A, B, C, X_1..X_n] and map them to the AB frame."""
        from .geometry import to_frame

        n_cameras, size = _sample_args(n_cameras, size)
        if self.scale_power:
            w = self._sample_scaled(seed, n_cameras + 3, size)
        else:
            w = self.sample_world(seed, n_cameras + 3, size)
        return to_frame(w[:, 2:], w[:, :1], w[:, 1:2])

    def _sample_scaled(self, seed, n_points: int, size: int) -> np.ndarray:
        """(size, n_points, 2) worlds of the ``scale_power`` model (class docstring): A uniform,
        B at distance s ∝ s^(1+p) on [d_min, diagonal] from A in a uniform direction (redrawn
        while outside the box), the rest uniform; whole configurations with a pair closer than
        d_min redrawn."""
        rng = as_rng(seed)
        W, H, e = self.width, self.height, 2 + self.scale_power
        lo, hi = self.d_min, float(np.hypot(W, H))
        iu = np.triu_indices(n_points, k=1)
        out = np.empty((size, n_points, 2))
        todo = np.arange(size)
        for _ in range(100_000):
            if todo.size == 0:
                return out
            n = todo.size
            A = rng.uniform((0.0, 0.0), (W, H), size=(n, 2))
            u = rng.uniform(size=n)
            # inverse CDF of s^(1+p) on [lo, hi]
            s = lo * (hi / lo) ** u if e == 0 else (lo ** e + u * (hi ** e - lo ** e)) ** (1 / e)
            t = rng.uniform(0.0, 2 * np.pi, n)
            B = A + s[:, None] * np.column_stack([np.cos(t), np.sin(t)])
            rest = rng.uniform((0.0, 0.0), (W, H), size=(n, n_points - 2, 2))
            w = np.concatenate([A[:, None], B[:, None], rest], axis=1)
            d = w[:, iu[0]] - w[:, iu[1]]
            ok = np.all((B >= 0) & (B <= (W, H)), axis=1) \
                & ~np.any(np.sum(d * d, axis=-1) < lo * lo, axis=-1)
            out[todo[ok]] = w[ok]
            todo = todo[~ok]
        raise ValueError(f"d_min: could not place {n_points} points {self.d_min} apart in a "
                         f"{self.width} x {self.height} box")


class TravelPrior(Prior):
    """A :class:`WorldBoxPrior` joined with one measured length in metres: the odometry's
    travelled distance ``distance`` of camera step ``step`` (from X_{step+1} to X_{step+2}).

    In the AB frame a configuration has no scale; the world box has one (its sides are metres),
    so the pair's length s = |AB| is integrated over inside the box prior, and the step's
    length in metres is s b with b = |X_{step+2} - X_{step+1}| in |AB| units. With the log
    error of the measured distance distributed as ``f`` (a normal of ``sigma``, plus a wider
    normal of ``tail = (share, scale)`` times ``sigma``),

        prior(q_1..q_k, d) = c_k ∫_0^π dρ ∫ s^(2k+1+p) (W - s xr(ρ))_+ (H - s yr(ρ))_+
                              1[s >= s0] f(log d - log s - log b) ds

    (the box's integrand, class :class:`WorldBoxPrior`), done on a grid in log s about
    ``log d - log b`` per normal (``nodes`` points over +-5 of its sigmas) and the box's ``n_rho``
    angles. Integrated over log d it is the box's density, so it is a joint density of the
    configuration and the measurement; the solvers take it as the prior of one history (their
    answers are then the posterior given the distance too). The odometry's ratios of
    consecutive step lengths (the solvers' ``distances``) carry no scale; this is the scale.
    Where the box's metric scale does not describe the robot's world, neither does this prior.

    ``detection = (near, far, near_width, far_width)`` (metres; None: off) also weighs every
    camera's range r to each of A, B and C by the chance that the camera detects a landmark
    there,

        D(r) = sigmoid((r - near) / near_width) sigmoid((far - r) / far_width),

    inside the integral over s (the ranges in metres are s times the AB-frame ranges). The box
    places landmarks and cameras independently, so its ranges are those of two uniform points;
    a real camera reads its landmarks only between a least and a greatest range. The answers
    are then the posterior given that every landmark of every view was detected (the factor's
    normalizer does not depend on the configuration).

    On configurations with fewer points than the step needs (the solvers' intermediate targets)
    it is the box's own density.

    >>> box = WorldBoxPrior(width=6.0, height=11.0)
    >>> near = np.array([[0.5, 0.5], [2.0, 0.5], [2.0, 0.6]])     # C, X_1, X_2 0.1 |AB| apart
    >>> far = np.array([[0.5, 0.5], [2.0, 0.5], [2.0, 1.5]])      # X_2 1 |AB| from X_1
    >>> t = TravelPrior(box, distance=0.2)                         # the robot moved 0.2 m
    >>> bool(t.log_density(near) - t.log_density(far) > box.log_density(near) - box.log_density(far))
    True
    """

    name = "travel"

    def __init__(self, box: WorldBoxPrior, distance: float, *, step: int = 0,
                 sigma: float = 0.07, tail: tuple = (0.1, 5.0), nodes: int = 41,
                 detection: tuple | None = None):
        if not isinstance(box, WorldBoxPrior):
            raise ValueError(f"box: expected a WorldBoxPrior, got {box!r}")
        d = float(distance)
        if not (np.isfinite(d) and d > 0):
            raise ValueError(f"distance: expected metres > 0, got {distance!r}")
        if isinstance(step, (bool, np.bool_)) or not isinstance(step, (int, np.integer)) \
                or step < 0:
            raise ValueError(f"step: expected an integer >= 0, got {step!r}")
        sg = float(sigma)
        if not (np.isfinite(sg) and sg > 0):
            raise ValueError(f"sigma: expected a log-error standard deviation > 0, got {sigma!r}")
        try:
            share, scale = (float(x) for x in tail)
        except (TypeError, ValueError):
            raise ValueError(f"tail: expected (share, scale), got {tail!r}") from None
        if not (0 <= share < 1 and scale >= 1):
            raise ValueError(f"tail: expected share in [0, 1) and scale >= 1, got {tail!r}")
        if detection is not None:
            try:
                near, far, wn, wf = (float(x) for x in detection)
            except (TypeError, ValueError):
                raise ValueError(f"detection: expected (near, far, near_width, far_width) in "
                                 f"metres, got {detection!r}") from None
            if not (np.isfinite([near, far, wn, wf]).all() and 0 <= near < far
                    and wn > 0 and wf > 0):
                raise ValueError(f"detection: expected 0 <= near < far and widths > 0 "
                                 f"(metres), got {detection!r}")
            detection = (near, far, wn, wf)
        self.detection = detection
        self.box, self.distance, self.step, self.sigma = box, d, int(step), sg
        self.tail = (share, scale)
        self.nodes = positive_int("nodes", nodes, minimum=5)
        self._z = np.linspace(-5.0, 5.0, self.nodes)

    def __repr__(self):
        det = "" if self.detection is None else f", detection={self.detection}"
        return (f"TravelPrior({self.box!r}, distance={self.distance:g}, step={self.step}, "
                f"sigma={self.sigma:g}, tail={self.tail}{det})")

    def log_density(self, points) -> np.ndarray:
        p = _points(points)
        lead, k = p.shape[:-2], p.shape[-2]
        j = self.step + 1                                  # X_{step+1} is point j (C is 0)
        if k < j + 2:
            return self.box.log_density(p)
        flat = p.reshape(-1, k, 2)
        out = np.empty(flat.shape[0])
        # (nodes, n_rho, chunk) arrays of about 8 MB: the grid in log s multiplies the box's work
        step = max(1, (_CHUNK_ELEMENTS << 4) // (self.box.n_rho * self.nodes))
        for i in range(0, flat.shape[0], step):
            out[i:i + step] = self._flat(flat[i:i + step], j)
        return out.reshape(lead)

    def _flat(self, q, j):
        box = self.box
        N, k = q.shape[:2]
        hi, lo, d2 = box._extents(q, np.ones(N))
        xr = hi - lo                                                   # (M, N)
        yr = np.roll(xr, -box.n_rho // 2, axis=0)
        W, H, a = box.width, box.height, 2 * k + 1 + box.scale_power
        s0 = box._least_scale(d2)
        b = np.hypot(*(q[:, j + 1] - q[:, j]).T)
        with np.errstate(divide="ignore"):
            mu = np.log(self.distance) - np.log(b)                     # log s where d = s b
        share, scale = self.tail
        ranges = None if self.detection is None else self._ab_ranges(q)   # (3 (k - 1), N)
        terms = []
        for w, sg in ((1.0 - share, self.sigma), (share, self.sigma * scale)):
            if w == 0:
                continue
            u = mu[None, :] + sg * self._z[:, None]                    # (G, N) log s
            sv = np.exp(u)
            f = np.maximum(W - sv[:, None, :] * xr[None], 0.0)
            f *= np.maximum(H - sv[:, None, :] * yr[None], 0.0)
            g = f.mean(axis=1) * (sv >= s0[None, :])                   # mean over rho (G, N)
            if ranges is not None:
                g *= np.exp(self._log_detection(sv[:, None, :] * ranges[None]).sum(axis=1))
            # s^a ds = e^((a+1) u) du, and the normal's density in u; trapezoid in z (the
            # integrand vanishes at +-5 sigma to 1e-6 of its peak)
            lw = (a + 1) * u - 0.5 * self._z[:, None] ** 2
            m = np.max(lw, axis=0)
            with np.errstate(divide="ignore", invalid="ignore"):
                tot = np.sum(g * np.exp(lw - m), axis=0) * (self._z[1] - self._z[0])
                terms.append(np.log(w) + m + np.log(tot) - 0.5 * np.log(2 * np.pi))
        with np.errstate(invalid="ignore"):
            t = np.logaddexp.reduce(np.stack(terms), axis=0)
        # c_k pi: the box's constant (rho over [0, 2 pi) covers [0, pi) twice)
        out = t + np.log(2.0 * np.pi) - (k + 2) * np.log(W * H)
        return np.where(np.isfinite(out) & (b > 0), out, -np.inf)

    @staticmethod
    def _ab_ranges(q):
        """(3 (k - 1), N) every camera's AB-frame range to A, B and C (q: (N, k, 2), C first)."""
        cams = q[:, 1:]                                                # (N, k - 1, 2)
        marks = np.stack([np.zeros_like(q[:, 0]), np.broadcast_to([0.0, 1.0], q[:, 0].shape),
                          q[:, 0]], axis=1)                            # (N, 3, 2): A, B, C
        r = np.hypot(*np.moveaxis(cams[:, :, None] - marks[:, None], -1, 0))
        return r.reshape(q.shape[0], -1).T

    def _log_detection(self, r):
        """log D(r) for ranges ``r`` in metres (class docstring), elementwise."""
        near, far, wn, wf = self.detection
        # log sigmoid(x) = -logaddexp(0, -x): no overflow at any range
        return -np.logaddexp(0.0, -(r - near) / wn) - np.logaddexp(0.0, -(far - r) / wf)

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        raise ValueError("sample: a TravelPrior is a posterior-side prior of one history "
                         "(the box given a measured distance) and has no sampler")


class TrajectoryPrior(Prior):
    """One robot's cameras: ``first`` places C and the first ``n_first`` cameras, and every
    later camera is one step from the camera before it, in a uniform direction, its length
    ``b`` (|AB| units) log-uniform on ``steps = (lo, hi)``:

        prior(q_1..q_k) = first(q_1..q_(1+n_first)) prod_(j > n_first) 1[lo <= b_j <= hi] /
                          (2 π b_j^2 log(hi / lo)),   b_j = |X_j - X_(j-1)|.

    A box prior (:class:`WorldBoxPrior`) makes every camera an independent point of the box, so
    for k cameras on a path of one shape, the first fixed, the density of the path's scale λ
    grows as λ^(2k - 3) (the later cameras' area element) until the path nears the box's size:
    the more views, the longer it expects the robot's path, however short it was. Scale-free
    steps add views without that pull; the odometry's ratios and headings (the solvers'
    likelihood) give the path its shape. With ``first`` a :class:`TravelPrior`
    (``n_first=2``: its step 0 joins the box with the first step's metres) the path has a
    scale too.

    >>> box = WorldBoxPrior(width=6.0, height=11.0)
    >>> p = TrajectoryPrior(box)
    >>> q = np.array([[0.5, 0.5], [2.0, 0.5], [2.0, 0.6], [2.0, 0.8]])  # C, X_1, X_2, X_3
    >>> step = -np.log(2 * np.pi * np.log(1e6))                # each step's normalizer
    >>> want = box.log_density(q[:2]) + step - 2 * np.log(0.1) + step - 2 * np.log(0.2)
    >>> bool(np.isclose(p.log_density(q), want))
    True
    """

    name = "trajectory"

    def __init__(self, first: Prior, *, n_first: int = 1, steps: tuple = (1e-4, 1e2)):
        if not isinstance(first, Prior):
            raise ValueError(f"first: expected a qfg.priors.Prior, got {first!r}")
        self.first = first
        self.n_first = positive_int("n_first", n_first, minimum=0)
        try:
            lo, hi = (float(x) for x in steps)
        except (TypeError, ValueError):
            raise ValueError(f"steps: expected (lo, hi) in |AB| units, got {steps!r}") from None
        if not (np.isfinite([lo, hi]).all() and 0 < lo < hi):
            raise ValueError(f"steps: expected 0 < lo < hi (|AB| units), got {steps!r}")
        self.steps = (lo, hi)
        self._c = -np.log(2.0 * np.pi * np.log(hi / lo))

    def __repr__(self):
        return f"TrajectoryPrior({self.first!r}, n_first={self.n_first}, steps={self.steps})"

    def log_density(self, points) -> np.ndarray:
        p = _points(points)
        m = 1 + min(p.shape[-2] - 1, self.n_first)
        out = np.asarray(self.first.log_density(p[..., :m, :]), dtype=float)
        if p.shape[-2] > m:
            v = np.diff(p[..., m - 1:, :], axis=-2)
            b2 = np.sum(v * v, axis=-1)
            lo, hi = self.steps
            with np.errstate(divide="ignore"):
                lp = np.where((b2 >= lo * lo) & (b2 <= hi * hi), self._c - np.log(b2), -np.inf)
            out = out + lp.sum(axis=-1)
        return out

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        n_cameras, size = _sample_args(n_cameras, size)
        rng = as_rng(seed)
        m = min(n_cameras, self.n_first)
        head = np.asarray(self.first.sample(rng, m, size), dtype=float)
        n = n_cameras - m
        lo, hi = self.steps
        b = np.exp(rng.uniform(np.log(lo), np.log(hi), (size, n)))
        th = rng.uniform(-np.pi, np.pi, (size, n))
        walk = head[:, -1:, :] + np.cumsum(b[..., None] * np.stack([np.cos(th), np.sin(th)],
                                                                   axis=-1), axis=1)
        return np.concatenate([head, walk], axis=1)


class MixturePrior(Prior):
    """A weighted mixture of priors over the same configurations:

        prior(q) = sum_i w_i prior_i(q),   w_i >= 0, sum_i w_i = 1.

    The posterior under it is the posterior under each component weighted by its evidence,
    ``w_i Z_i / sum_j w_j Z_j`` (Bayesian model averaging), so any solver that takes a prior
    averages over the components without computing any evidence. That holds only when every
    component is a normalized density of the configurations (:class:`WorldBoxPrior` with
    ``scale_power=0``, :class:`TrajectoryPrior` over one, :class:`WindowPrior`); a component
    known only up to a constant would carry an arbitrary weight.

    >>> box = WorldBoxPrior()
    >>> m = MixturePrior([box, TrajectoryPrior(box)])
    >>> q = np.array([[0.5, 0.5], [2.0, 0.5], [2.1, 0.5]])
    >>> want = np.logaddexp(box.log_density(q), TrajectoryPrior(box).log_density(q)) - np.log(2)
    >>> bool(np.isclose(m.log_density(q), want))
    True
    """

    name = "mixture"

    def __init__(self, components, weights=None):
        comps = list(components)
        if len(comps) < 1 or not all(isinstance(c, Prior) for c in comps):
            raise ValueError(f"components: expected one or more qfg.priors.Prior, got "
                             f"{components!r}")
        w = np.full(len(comps), 1.0 / len(comps)) if weights is None else \
            np.asarray(weights, dtype=float)
        if w.shape != (len(comps),) or not np.all(np.isfinite(w)) or np.any(w < 0) \
                or w.sum() <= 0:
            raise ValueError(f"weights: expected {len(comps)} finite weights >= 0 with a "
                             f"positive sum, got {weights!r}")
        self.components, self.weights = comps, w / w.sum()

    def __repr__(self):
        return f"MixturePrior({self.components!r}, weights={np.round(self.weights, 6).tolist()})"

    def log_density(self, points) -> np.ndarray:
        p = _points(points)
        with np.errstate(divide="ignore"):
            terms = [np.log(w) + np.asarray(c.log_density(p), dtype=float)
                     for c, w in zip(self.components, self.weights, strict=True) if w > 0]
        return np.logaddexp.reduce(np.stack(terms), axis=0)

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        n_cameras, size = _sample_args(n_cameras, size)
        rng = as_rng(seed)
        pick = rng.choice(len(self.components), size=size, p=self.weights)
        out = np.empty((size, n_cameras + 1, 2))
        for i, c in enumerate(self.components):
            rows = np.flatnonzero(pick == i)
            if rows.size:
                out[rows] = c.sample(rng, n_cameras, rows.size)
        return out


class WindowPrior(Prior):
    """Independent points uniform in an AB-frame window ``(xmin, xmax, ymin, ymax)``.

    ``log_density = -k log(area)`` inside (every point in the window), -inf outside.

    >>> p = WindowPrior((-1.0, 1.0, 0.0, 2.0))
    >>> p.log_density([[[0.0, 0.5]], [[3.0, 0.5]]]).tolist() == [-np.log(4.0), -np.inf]
    True
    """

    name = "uniform"

    def __init__(self, window=DEFAULT_WINDOW):
        w = tuple(float(v) for v in as_float_array("window", window).ravel())
        if len(w) != 4 or not (w[0] < w[1] and w[2] < w[3]):
            raise ValueError(f"window: expected (xmin, xmax, ymin, ymax) with xmin < xmax and "
                             f"ymin < ymax, got {window!r}")
        if max(abs(v) for v in w) > COORD_LIMIT:
            raise ValueError(f"window: expected coordinates within ±{COORD_LIMIT:g} (the sides "
                             f"must be finite), got {window!r}")
        sides = (w[1] - w[0], w[3] - w[2])
        lo = LENGTH_RANGE[0]
        if min(sides) < lo:
            raise ValueError(f"window: expected sides >= {lo:g} (the area must stay a non-zero "
                             f"float), got sides {sides[0]:g} x {sides[1]:g}")
        if max(sides) / min(sides) > MAX_WINDOW_ASPECT:
            raise ValueError(f"window: expected an aspect ratio (long side / short side) <= "
                             f"{MAX_WINDOW_ASPECT:g}, got sides {sides[0]:g} x {sides[1]:g}")
        self.window = w
        self.area = (w[1] - w[0]) * (w[3] - w[2])

    def __repr__(self):
        return f"WindowPrior(window={self.window})"

    def log_density(self, points) -> np.ndarray:
        p = _points(points)
        xmin, xmax, ymin, ymax = self.window
        inside = np.all((p[..., 0] >= xmin) & (p[..., 0] <= xmax) & (p[..., 1] >= ymin)
                        & (p[..., 1] <= ymax), axis=-1)
        return np.where(inside, -p.shape[-2] * np.log(self.area), -np.inf)

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        n_cameras, size = _sample_args(n_cameras, size)
        xmin, xmax, ymin, ymax = self.window
        return as_rng(seed).uniform((xmin, ymin), (xmax, ymax), size=(size, n_cameras + 1, 2))


class ProductPrior(Prior):
    """APPROXIMATE world prior: independent points, each with the heavy-tailed density

        p(P) = (s^2 / π) (s^2 + |P - (0, 1/2)|^2)^-2,  i.e.  P(|P - (0, 1/2)| <= R) = R^2 / (s^2 + R^2),

    fitted (s = 0.85) to the AB-frame marginal of one uniformly placed object. The exact joint
    (:class:`WorldBoxPrior`) couples the points through AB's unknown scale and rotation; this
    product ignores that and is kept only to reproduce earlier results.

    >>> p = ProductPrior()
    >>> bool(np.isclose(p.log_density([[[0.0, 0.5]]])[()], np.log(1 / (np.pi * 0.85**2))))
    True
    """

    name = "world-product"
    CENTRE = np.array([0.0, 0.5])

    def __init__(self, scale: float = 0.85):
        self.scale = _length("scale", scale)

    def __repr__(self):
        return f"ProductPrior(scale={self.scale:g})"

    def log_density(self, points) -> np.ndarray:
        p = _points(points)
        d = p - self.CENTRE
        s2 = self.scale ** 2
        return np.sum(np.log(s2 / np.pi) - 2.0 * np.log(s2 + np.sum(d * d, axis=-1)), axis=-1)

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        n_cameras, size = _sample_args(n_cameras, size)
        rng = as_rng(seed)
        u = rng.random((size, n_cameras + 1))
        r = self.scale * np.sqrt(u / (1.0 - u))          # inverse of R^2 / (s^2 + R^2)
        th = rng.uniform(-np.pi, np.pi, size=u.shape)
        return self.CENTRE + np.stack([r * np.cos(th), r * np.sin(th)], axis=-1)


class CallablePrior(Prior):
    """A user's prior: ``log_density_fn(points (..., k, 2)) -> (...,)`` and optionally
    ``sample_fn(rng, n_cameras, size) -> (size, 1 + n_cameras, 2)`` (``rng`` a numpy Generator).

    The log density may be unnormalized by a constant that depends only on k. Solvers need only
    ``log_density``; ``sample`` (calibration checks, baselines drawing from the prior) raises a
    ValueError naming ``sample_fn`` when none was given.

    >>> gauss = CallablePrior(lambda x: -0.5 * np.sum(x**2, axis=(-2, -1)), name="gauss")
    >>> float(gauss.log_density([[0.0, 1.0], [1.0, 1.0]]))
    -1.5
    """

    def __init__(self, log_density_fn, sample_fn=None, name: str = "custom"):
        if not callable(log_density_fn):
            raise ValueError(f"log_density_fn: expected a callable, got {log_density_fn!r}")
        if sample_fn is not None and not callable(sample_fn):
            raise ValueError(f"sample_fn: expected a callable or None, got {sample_fn!r}")
        self._ld, self._sample, self.name = log_density_fn, sample_fn, str(name)

    def log_density(self, points) -> np.ndarray:
        p = _points(points)
        out = np.asarray(self._ld(p), dtype=float)
        if out.shape != p.shape[:-2]:
            raise ValueError(f"log_density_fn: returned shape {out.shape}, expected {p.shape[:-2]}")
        if np.any(np.isnan(out)) or np.any(out == np.inf):
            raise ValueError("log_density_fn: returned NaN or +inf")
        return out

    def sample(self, seed, n_cameras: int, size: int) -> np.ndarray:
        n_cameras, size = _sample_args(n_cameras, size)
        if self._sample is None:
            raise ValueError(f"sample_fn: prior {self.name!r} was built without a sampler")
        out = as_float_array("sample_fn", self._sample(as_rng(seed), n_cameras, size))
        if out.shape != (size, n_cameras + 1, 2):
            raise ValueError(f"sample_fn: returned shape {out.shape}, expected "
                             f"{(size, n_cameras + 1, 2)}")
        return out


def get(prior) -> Prior:
    """A :class:`Prior` from a Prior (returned as is) or a name: ``"world"`` (the exact
    :class:`WorldBoxPrior` of the simulator's box), ``"world-product"`` (:class:`ProductPrior`,
    approximate), ``"uniform"`` (:class:`WindowPrior` on :data:`DEFAULT_WINDOW`).

    ``"arc"`` (the solvers' former "uniform in the angle along each locus arc") is not a density
    over configurations (it depends on the measurements), so it is not a prior here.

    >>> get("uniform").window
    (-6.0, 6.0, -5.5, 6.5)
    """
    if isinstance(prior, Prior):
        return prior
    if prior == "world":
        return WorldBoxPrior()
    if prior == "world-product":
        return ProductPrior()
    if prior == "uniform":
        return WindowPrior()
    raise ValueError(f"prior: expected a qfg.priors.Prior or one of {NAMES}, got {prior!r}")


def sample_measurements(prior, seed, n_views: int, sigma_bearing: float, sigma_heading: float,
                        size: int):
    """Configurations drawn from ``prior`` and measurements made from them by the solvers' model
    (calibration checks: a correct posterior is calibrated on these).

    Configurations ``[C, X_1..X_n]`` from ``prior.sample``, headings uniform, bearings
    ``phi_{j,L} = wrap(f(L, X_j, alpha_j) + sigma_bearing N(0, 1))`` for L in (A, B, C), headings
    ``psi_j = wrap(g(X_j, alpha_j, X_{j+1}) + sigma_heading N(0, 1))``.

    Returns ``(bearings (size, n, 3), headings (size, n - 1), configs (size, n + 1, 2),
    alphas (size, n))``; radians, AB frame.

    >>> b, h, x, a = sample_measurements("world", np.random.default_rng(0), 3, 0.01, 0.02, 5)
    >>> b.shape, h.shape, x.shape, a.shape
    ((5, 3, 3), (5, 2), (5, 4, 2), (5, 3))
    """
    from .geometry import bearing, motion_heading, wrap_angle

    pr = get(prior)
    rng = as_rng(seed)
    n = positive_int("n_views", n_views)
    size = positive_int("size", size)
    sb = non_negative("sigma_bearing", sigma_bearing)
    sh = non_negative("sigma_heading", sigma_heading)
    conf = pr.sample(rng, n, size)
    alpha = rng.uniform(-np.pi, np.pi, size=(size, n))
    poses = np.concatenate([conf[:, 1:], alpha[..., None]], axis=-1)          # (size, n, 3)
    L = np.concatenate([np.zeros((size, 1, 2)), np.tile([[[0.0, 1.0]]], (size, 1, 1)),
                        conf[:, :1]], axis=1)                                  # (size, 3, 2)
    phi = bearing(poses[:, :, None, :], L[:, None, :, :])
    phi = wrap_angle(phi + sb * rng.standard_normal(phi.shape))
    psi = motion_heading(poses[:, :-1], poses[:, 1:, :2])
    psi = wrap_angle(psi + sh * rng.standard_normal(psi.shape))
    return phi, psi, conf, alpha
