"""Random qualitative factor graphs: the propagation study's generator (paper section 6f), as a
library function so that inference benchmarks and the exact-vs-approximate study draw exactly the
graphs of ``qfg experiment propagation`` (same random stream, same draws, same order).

:func:`propagation_graph` reproduces steps 1-3 of the propagation study
(:mod:`qfg.harness.studies.propagation`): landmarks, ``n_candidates`` candidate factor sets (the one
with the highest connectivity score kept), then single-triplet solver priors for the seen
triplets. Given the study's scenario stream (``qfg.harness.runner.scenario_rng(seed, index)``) it
returns the study's graph of that scenario.

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> T = np.random.default_rng(1).random((20, 20, 20)) + 1e-6
>>> s = propagation_graph(rng, table=T, n_fc_min=3, n_fc_max=5, n_candidates=2)
>>> s.graph.n_factors in (3, 4, 5), s.landmarks.shape
(True, (6, 2))
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ._validate import as_rng
from .graph import QualitativeFactorGraph

__all__ = ["PropagationGraph", "propagation_graph", "candidate_graph", "connectivity_score",
           "factor_triplets", "band_graph"]


def factor_triplets(f) -> tuple[tuple, tuple, tuple]:
    """The triplets (AB:C, BC:D, AB:D) of composition factor ``f = (i, j, k, s)``."""
    i, j, k, s = f
    return (i, j, k), (j, k, s), (i, j, s)


def connectivity_score(g, n_bins: int = 10) -> float:
    """Entropy (nats) of the histogram of Algorithm 3 topology scores, seen triplets at 1, in
    ``n_bins`` equal bins on [0, 1]."""
    from .metrics import entropy
    from .propagation import topology_scores

    tsc = topology_scores(g, seen_score=1.0).scores
    counts, _ = np.histogram(tsc, bins=n_bins, range=(0.0, 1.0))
    return float(entropy(counts / counts.sum()))


def _build(triplets, seen, priors, factors, table, partition="edc"):
    g = QualitativeFactorGraph(partition, tensor=table)
    m = table.shape[0]
    it = iter(priors) if priors is not None else None
    for t, s in zip(triplets, seen, strict=True):
        g.add_triplet(t, (next(it) if it is not None else np.ones(m)) if s else None)
    for f in factors:
        g.add_composition(f)
    return g


def candidate_graph(seed, n_landmarks, n_fc, coverage_rate, table, partition="edc"):
    """A random candidate: factors, triplets (sorted), seen mask, graph with placeholder priors."""
    rng = as_rng(seed)
    all_f = list(itertools.permutations(range(n_landmarks), 4))
    pick = np.sort(rng.choice(len(all_f), size=n_fc, replace=False))
    factors = [all_f[i] for i in pick]
    triplets = sorted({t for f in factors for t in factor_triplets(f)})
    n_v = len(triplets)
    n_seen = int(min(max(round(coverage_rate * n_v), 1), n_v - 1))
    seen = np.zeros(n_v, dtype=bool)
    seen[rng.choice(n_v, size=n_seen, replace=False)] = True
    g = _build(triplets, seen, None, factors, table, partition)
    return factors, triplets, seen, g


@dataclass(frozen=True)
class PropagationGraph:
    """One drawn graph: ``graph`` (with solver priors), ``landmarks`` (L, 2) world positions,
    ``connectivity`` (score of the kept candidate), ``kept_candidate`` (its index),
    ``hypotheses`` ({seen triplet: the solver's :class:`~qfg.solvers.Hypotheses`} when asked
    for, else None)."""

    graph: QualitativeFactorGraph
    landmarks: np.ndarray
    connectivity: float
    kept_candidate: int
    hypotheses: dict | None = None


def propagation_graph(seed, table, *, n_landmarks: int = 6, n_fc_min: int = 5,
                      n_fc_max: int = 40, n_candidates: int = 10, coverage_rate: float = 0.5,
                      n_views: int = 3, sigma_bearing_deg: float = 2.0,
                      sigma_heading_deg: float = 5.0, solver: str = "fast",
                      partition: str = "edc", n_bins: int = 10,
                      hypotheses: bool = False) -> PropagationGraph:
    """Draw one graph as the propagation study does (defaults: its paper preset).

    ``table``: the (m, m, m) composition tensor (array or CompositionTensor). The draws, in
    order: per candidate ``n_fc``, the factors and the seen triplets; the kept candidate by
    connectivity score (first of equal ones); landmark and camera positions in one
    :func:`~qfg.simulation.sample_positions` call; bearing and heading noise; the solver seed.
    ``hypotheses=True`` also keeps each seen triplet's weighted samples (solved one by one with
    the same per-triplet seeds: the same estimates, without the batching).
    """
    from .composition import as_table
    from .geometry import bearing, motion_heading, wrap_angle
    from .simulation import SimulationConfig, sample_positions
    from .solvers import solve_triplets

    table = as_table(table)
    rng = as_rng(seed)
    n_l = int(n_landmarks)
    best = None
    for c in range(int(n_candidates)):
        n_fc = int(rng.integers(int(n_fc_min), int(n_fc_max) + 1))
        factors, triplets, seen, g = candidate_graph(rng, n_l, n_fc, float(coverage_rate), table,
                                                     partition)
        score = connectivity_score(g, int(n_bins))
        if best is None or score > best[0]:
            best = (score, c, factors, triplets, seen)
    conn, kept, factors, triplets, seen = best
    n_seen, nv = int(seen.sum()), int(n_views)
    sb, sh = np.deg2rad(float(sigma_bearing_deg)), np.deg2rad(float(sigma_heading_deg))
    pts = sample_positions(rng, n_l + n_seen * nv, SimulationConfig())
    L = pts[:n_l]
    poses = np.concatenate([pts[n_l:].reshape(n_seen, nv, 2),
                            rng.uniform(-np.pi, np.pi, size=(n_seen, nv, 1))], axis=-1)
    ids = np.array([t for t, s in zip(triplets, seen, strict=True) if s], dtype=np.intp)
    phi = bearing(poses[:, :, None, :], L[ids][:, None, :, :])             # (n_seen, nv, 3)
    phi = wrap_angle(phi + rng.normal(size=phi.shape) * sb)
    psi = motion_heading(poses[:, :-1], poses[:, 1:, :2])                     # (n_seen, nv - 1)
    psi = wrap_angle(psi + rng.normal(size=psi.shape) * sh)
    seed = int(rng.integers(2**63))
    hyp = None
    if hypotheses:
        from .solvers import TripletSolver

        # solve_triplets solves triplet t with the child SeedSequence(seed, spawn_key=(t,))
        solved = [TripletSolver.solve(phi[t], psi[t], method=solver, partition=partition,
                                      sigma_bearing=sb, sigma_heading=sh,
                                      seed=np.random.SeedSequence(seed, spawn_key=(t,)))
                  for t in range(n_seen)]
        est = [s.estimate() for s in solved]
        hyp = {tuple(int(x) for x in ids[t]): s.hypotheses() for t, s in enumerate(solved)}
    else:
        est = solve_triplets(phi, psi, method=solver, partition=partition,
                             sigma_bearing=sb, sigma_heading=sh, seed=seed)
    g = _build(triplets, seen, [e.landmark for e in est], factors, table, partition)
    return PropagationGraph(graph=g, landmarks=L, connectivity=conn, kept_candidate=kept,
                            hypotheses=hyp)


def band_graph(n_landmarks: int, window: int, m: int = 20, seed=0) -> QualitativeFactorGraph:
    """A random graph of bounded width for memory and engine checks: every triplet i < j < k
    with ``k - i < window``, about half of them seen with a random prior, a random positive
    (m, m, m) tensor, and every composition among them. The junction tree's width grows with
    ``window``, its length with ``n_landmarks``.

    >>> g = band_graph(6, 4, m=3)         # spans k - i of 2 (4 triplets) and 3 (6)
    >>> g.n_triplets, g.n_factors > 0
    (10, True)
    """
    rng = as_rng(seed)
    g = QualitativeFactorGraph(None, tensor=rng.random((m, m, m)) + 0.01)
    for t in itertools.combinations(range(int(n_landmarks)), 3):
        if max(t) - min(t) < window:
            g.add_triplet(t, rng.random(m) if rng.random() < 0.5 else None)
    g.discover_compositions()
    return g
