"""Gauge-free moments of a :class:`qfg.joint.JointPosterior` and the checks built on them.

* :func:`ab_frame_moments`: mean and covariance of C's position in the AB frame (A = (0, 0),
  B = (0, 1), units of |AB|) of landmark triplets, what a triplet's state depends on;
  :func:`ab_frame_z2`: a given configuration's squared Mahalanobis distance from them.
* :func:`landmark_moments`: each landmark's mean and covariance after every sample is mapped
  onto the map by its best similarity; :func:`aligned_errors`: such a map against the truth.
* :func:`overdispersion`: how far the robots' own maps scatter about the joint map against
  what its covariance allows (no ground truth); :func:`scale_covariance` widens a posterior.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._validate import as_float_array, as_rng, non_negative, positive_int
from ..geometry import to_frame
from . import start as _start
from .posterior import JointPosterior
from .sampling import sample_landmarks
from .states import _all_triplets

__all__ = ["ab_frame_moments", "ab_frame_z2", "landmark_moments", "aligned_errors",
           "overdispersion", "scale_covariance"]


def ab_frame_moments(posterior: JointPosterior, triplets, samples: int = 2000, seed=0):
    """Mean (T, 2) and covariance (T, 2, 2) of C's position in the AB frame (A = (0, 0),
    B = (0, 1), in units of |AB|) of each landmark-id triplet ``(A, B, C)`` under the posterior,
    from ``samples`` joint samples (:func:`sample_landmarks` with ``seed``): what a triplet's
    state depends on, free of the map's gauge and scale. Triplets with an unconstrained
    landmark get NaN.

    >>> import numpy as np
    >>> from qfg.joint import simulated_measurements, solve
    >>> from qfg.simulation import random_trajectory_run
    >>> run = random_trajectory_run(np.random.default_rng(0), n_landmarks=5, n_poses=30,
    ...                             fov_deg=360)
    >>> mu, cov = ab_frame_moments(solve(simulated_measurements(run)), [(0, 1, 2)], 500)
    >>> mu.shape, cov.shape, bool(np.all(np.linalg.eigvalsh(cov) > 0))
    ((1, 2), (1, 2, 2), True)
    """
    samples = positive_int("samples", samples, minimum=3)
    tl = [tuple(t) for t in triplets]
    if any(len(t) != 3 or len(set(t)) != 3 for t in tl):
        raise ValueError("triplets: expected (A, B, C) triplets of three distinct ids")
    tri = posterior.index([x for t in tl for x in t]).reshape(-1, 3)
    S = sample_landmarks(posterior, samples, seed)
    T = len(tri)
    mu, cov = np.full((T, 2), np.nan), np.full((T, 2, 2), np.nan)
    ok = np.asarray(posterior.constrained, bool)[tri].all(axis=1)
    if posterior.method == "none" or not ok.any():
        return mu, cov
    t = tri[ok]
    F = to_frame(S[:, t[:, 2]], S[:, t[:, 0]], S[:, t[:, 1]])         # (n, T', 2)
    mu[ok] = F.mean(axis=0)
    D = F - mu[ok]
    cov[ok] = np.einsum("nti,ntj->tij", D, D) / (samples - 1)
    return mu, cov


def landmark_moments(posterior: JointPosterior, samples: int = 2000, seed=0):
    """Mean (L, 2) and covariance (L, 2, 2) of each landmark in the map frame, free of the
    map's gauge: every joint sample (:func:`sample_landmarks` with ``seed``) is first mapped
    onto the best mode's landmarks by its best similarity (:func:`qfg.joint.start.similarity`,
    over the constrained landmarks). The covariances then describe the configuration's
    shape, on which every qualitative state depends, and not where the map's anchor put it:
    a landmark's uncertainty relative to the others, what an ellipse on a map should show.
    Unconstrained landmarks (and every landmark of a map with fewer than 3 constrained) get
    NaN.

    >>> import numpy as np
    >>> from qfg.joint import simulated_measurements, solve
    >>> from qfg.simulation import random_trajectory_run
    >>> run = random_trajectory_run(np.random.default_rng(0), n_landmarks=5, n_poses=30,
    ...                             fov_deg=360)
    >>> post = solve(simulated_measurements(run))
    >>> mu, cov = landmark_moments(post, 500)
    >>> mu.shape, cov.shape, bool(np.all(np.linalg.eigvalsh(cov) > 0))
    ((5, 2), (5, 2, 2), True)
    """
    samples = positive_int("samples", samples, minimum=3)
    L = len(posterior.landmark_ids)
    mu, cov = np.full((L, 2), np.nan), np.full((L, 2, 2), np.nan)
    ok = np.flatnonzero(np.asarray(posterior.constrained, bool)
                        & np.isfinite(posterior.points).all(axis=1))
    if posterior.method == "none" or ok.size < 3:
        return mu, cov
    S = sample_landmarks(posterior, samples, seed)[:, ok]              # (n, k, 2)
    F = _start.apply_similarity(S, _start.similarity(S, posterior.points[ok]))
    mu[ok] = F.mean(axis=0)
    D = F - mu[ok]
    cov[ok] = np.einsum("nki,nkj->kij", D, D) / (samples - 1)
    return mu, cov


def aligned_errors(mean, covariance, truth):
    """A map's landmarks against their true positions: ``mean`` (k, 2) and ``covariance``
    (k, 2, 2) (e.g. :func:`landmark_moments`' rows without NaN) mapped onto ``truth`` (k, 2)
    by the best similarity (a map's gauge is its own). Returns ``(errors (k, 2), covariances
    (k, 2, 2), z2 (k,), (s, R, t))`` in the truth's frame; ``z2`` is each truth's squared
    Mahalanobis distance, chi-square with 2 dof for a calibrated map (95 % under 5.99).

    >>> import numpy as np
    >>> truth = np.array([[0.0, 0], [2, 0], [0, 2], [2, 2]])
    >>> e = np.array([[1, 0], [-1, 0], [-1, 0], [1, 0]]) * 1e-3    # no similarity in it
    >>> err, C, z2, _ = aligned_errors(3 * (truth + e) + 1, np.tile(9e-6 * np.eye(2), (4, 1, 1)),
    ...                                truth)                       # map: x3, its sd 3e-3
    >>> np.round(z2, 2).tolist()
    [1.0, 1.0, 1.0, 1.0]
    """
    mu = as_float_array("mean", mean, ndim=2, last_dim=2)
    C = as_float_array("covariance", covariance, ndim=3)
    X = as_float_array("truth", truth, ndim=2, last_dim=2)
    if C.shape != (mu.shape[0], 2, 2) or X.shape != mu.shape:
        raise ValueError(f"covariance, truth: expected {(mu.shape[0], 2, 2)} and {mu.shape}, "
                         f"got {C.shape} and {X.shape}")
    if mu.shape[0] < 3:
        raise ValueError(f"mean: at least 3 landmarks to align, got {mu.shape[0]}")
    s, R, t = sim = _start.similarity(mu, X)
    err = _start.apply_similarity(mu, sim) - X
    Cw = s * s * np.einsum("ij,kjl,ml->kim", R, C, R)
    z2 = np.einsum("ki,kij,kj->k", err, np.linalg.inv(Cw), err)
    return err, Cw, z2, (s, R, t)


def overdispersion(posterior: JointPosterior, robots=None, *, triplets: int = 2000,
                   samples: int = 500, seed=0) -> float:
    """How far the robots' own maps scatter about the joint map, against what its covariance
    allows, in the AB frame (a Birge ratio; no ground truth).

    Each robot's own map (``posterior.info["robot_maps"]``, placed from its run alone) is
    compared with the joint map, triplet by triplet, where the comparison is free of the
    maps' gauge and scale: C's position in the frame A = (0, 0), B = (0, 1). With ``x_rt`` the
    robot's, ``mu_t`` and ``Sigma_t`` the joint posterior's mean and covariance of that
    position (from ``samples`` samples), and K robots that inform the map equally, the robot's
    deviation has covariance ``(K - 1) Sigma_t`` (the joint map holds the robot's own
    information), so

        kappa = median_{r, t} (x_rt - mu_t)' Sigma_t^-1 (x_rt - mu_t) / ((K - 1) chi2_2.median)

    is about 1 when the covariance accounts for the errors and grows with errors it does not
    model (shared by an image, a robot, a stretch of a run). ``robots``: the robots compared
    (default: every robot with a map, K >= 2 needed); ``triplets``: at most this many ordered
    triplets, drawn with ``seed`` when there are more. Returns NaN when fewer than two robots
    have maps or no triplet is placed by both.

    >>> import numpy as np
    >>> from qfg.joint import JointMeasurements, simulated_measurements, solve
    >>> from qfg.simulation import random_trajectory_run
    >>> rng = np.random.default_rng(0)
    >>> a = random_trajectory_run(rng, n_landmarks=6, n_poses=40, fov_deg=360)
    >>> b = random_trajectory_run(rng, n_poses=40, fov_deg=360, landmarks=a.landmarks)
    >>> runs = tuple(simulated_measurements(r, robot=k).runs[0] for k, r in enumerate((a, b)))
    >>> post = solve(JointMeasurements(runs, tuple(range(6))))
    >>> bool(0.2 < overdispersion(post) < 5)      # simulated with the model's own noise
    True
    """
    samples = positive_int("samples", samples, minimum=3)
    triplets = positive_int("triplets", triplets)
    maps = posterior.info.get("robot_maps", {})
    use = [r for r in (maps if robots is None else robots) if r in maps]
    if len(use) < 2 or posterior.method == "none":
        return float("nan")
    L = len(posterior.landmark_ids)
    ok = np.asarray(posterior.constrained, bool)
    rng = as_rng(seed)
    tri = np.flatnonzero(ok)[np.array(_all_triplets(int(ok.sum())), dtype=np.intp)
                             .reshape(-1, 3)]
    if len(tri) > triplets:
        tri = tri[np.sort(rng.choice(len(tri), triplets, replace=False))]
    if not len(tri):
        return float("nan")
    ids = np.asarray(posterior.landmark_ids)
    mu, cov = ab_frame_moments(posterior, ids[tri].tolist(), samples, rng)
    z2 = [z[np.isfinite(z)] for z in (_z2(np.asarray(maps[r], float).reshape(L, 2), tri, mu, cov)
                                      for r in use)]
    z2 = [z for z in z2 if z.size]
    if len(z2) < 2:
        return float("nan")
    return float(np.median(np.concatenate(z2)) / ((len(z2) - 1) * 2.0 * np.log(2.0)))


def _z2(P, tri, mu, cov) -> np.ndarray:
    """(T,) squared Mahalanobis distances of C's AB-frame position in the landmark positions
    ``P`` (L, 2) for index triplets ``tri`` (T, 3) from ``mu`` (T, 2) under ``cov`` (T, 2, 2);
    NaN where a position is missing or the covariance singular."""
    out = np.full(len(tri), np.nan)
    det = cov[:, 0, 0] * cov[:, 1, 1] - cov[:, 0, 1] * cov[:, 1, 0]
    have = np.isfinite(P[tri]).all(axis=(1, 2)) & (det > 0)
    if have.any():
        t = tri[have]
        e = to_frame(P[t[:, 2]], P[t[:, 0]], P[t[:, 1]]) - mu[have]
        c = cov[have]
        # e' C^-1 e for 2 x 2 C, without inverting T matrices
        out[have] = (c[:, 1, 1] * e[:, 0] ** 2 - 2 * c[:, 0, 1] * e[:, 0] * e[:, 1]
                     + c[:, 0, 0] * e[:, 1] ** 2) / det[have]
    return out


def ab_frame_z2(posterior: JointPosterior, positions, triplets, samples: int = 2000,
                seed=0) -> np.ndarray:
    """(T,) the squared Mahalanobis distance of C's AB-frame position in landmark ``positions``
    (L, 2, in the order of ``posterior.landmark_ids``; e.g. the ground truth, in any frame and
    scale) from the posterior's mean under its covariance (:func:`ab_frame_moments`), for each
    landmark-id triplet of ``triplets``; calibrated: chi-square with 2 dof (median 1.39). NaN
    where a landmark is unconstrained or its position missing."""
    try:
        P = np.asarray(positions, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"positions: expected numbers ({exc})") from None
    if P.shape != (len(posterior.landmark_ids), 2) or np.isinf(P).any():
        raise ValueError(f"positions: expected shape ({len(posterior.landmark_ids)}, 2), one "
                         f"finite position (or NaN: not placed) per landmark id, got shape "
                         f"{P.shape}")
    tl = [tuple(t) for t in triplets]
    mu, cov = ab_frame_moments(posterior, tl, samples, seed)
    tri = posterior.index([x for t in tl for x in t]).reshape(-1, 3)
    return _z2(P, tri, mu, cov)


def scale_covariance(posterior: JointPosterior, factor: float) -> JointPosterior:
    """The posterior with every covariance (modes and the weak landmarks' block) times
    ``factor`` (> 0); mode weights are unchanged by a common factor. ``solve``'s ``inflate``
    and ``inflate_kinematic`` do this at the solve; this does it afterwards (e.g. to compare
    factors on one solve)."""
    factor = non_negative("factor", factor)
    if factor <= 0:
        raise ValueError("factor: expected a factor > 0")
    wk = posterior._weak
    return dataclasses.replace(
        posterior, modes=tuple(dataclasses.replace(m, covariance=m.covariance * factor)
                               for m in posterior.modes),
        _weak=None if wk is None else {**wk, "cov": wk["cov"] * factor})

