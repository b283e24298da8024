"""The exact AB-frame prior of the simulator's world (:class:`WorldBoxPrior`): every object
i.i.d. uniform in a W x H box (world units), every pair at least ``d_min`` apart, the pair's
unknown scale and rotation integrated out."""

from __future__ import annotations

import numpy as np

from .._validate import as_float_array, as_rng, non_negative, positive_int
from .base import Prior, _length, _points, _sample_args

__all__ = ["WorldBoxPrior", "MIN_BOX_SIDE", "MAX_N_RHO"]

# The simulator's defaults (qfg.simulation.SimulationConfig), repeated here so that this module
# does not import the simulator at import time; a test checks that they agree.
_SIM_WIDTH, _SIM_HEIGHT, _SIM_DMIN = 6.0, 7.0, 0.01

#: Least side of WorldBoxPrior's box (world units): geometry.to_frame calls two points closer than
#: 1e-9 coincident (COINCIDENT_EPS = 1e-18 on |AB|^2), which two points uniform in a box of side L
#: are with probability about pi 1e-18 / L^2: 3e-12 per pair at L = 1e-3, so sampling never fails.
MIN_BOX_SIDE = 1e-3
#: Most rho quadrature points of WorldBoxPrior: time is linear in n_rho (2000 configurations of
#: 4 points: 40 ms at 128, 1.0 s at 4096, 16 s at 65536) while the error falls as n_rho^-2
#: (max |log p - log p(16384)|: 1.2e-3 at 128, 1.2e-6 nats at 4096); measured with the loop of
#: WorldBoxPrior(n_rho=n).log_density over WorldBoxPrior().sample(default_rng(0), 3, 2000).
MAX_N_RHO = 4096

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
        from ..geometry import to_frame

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
