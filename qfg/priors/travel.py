"""A world box joined with one measured length in metres (:class:`TravelPrior`): the
odometry's travelled distance of one camera step gives the AB frame a scale."""

from __future__ import annotations

import numpy as np

from .._validate import positive_int
from .base import Prior, _points
from .box import _CHUNK_ELEMENTS, WorldBoxPrior

__all__ = ["TravelPrior"]


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
