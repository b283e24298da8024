"""The solvers' entry points: :func:`solve_triplet`, :func:`solve_triplets` (many triplets, the
SIS and fast-paper methods batched in numpy), :class:`TripletSolver` (one triplet view by view)
and :func:`add_view`. They check the measurements and options (:mod:`.common`), choose the
model actually solved (no headings: the baseline's), check the time and memory bounds
(:mod:`.budget`) and hand the triplet to its method: :mod:`.sis` (``full``, ``fast``),
:mod:`.fast_paper`, :mod:`.baseline` or :mod:`.reference`. Every name here is exported by
:mod:`qfg.solvers`, where the methods are described.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from . import baseline as _baseline
from . import budget as _budget
from . import fast_paper as _fast_paper
from .common import degenerate as _degenerate
from .common import estimate as _estimate
from .common import input as _input
from .common import options as _options
from .common import seeds as _seeds
from .common.estimate import Hypotheses, TripletEstimate
from .common.options import DEFAULTS, METHODS
from .sis import engine as _sis
from .sis import escalation as _escalation
from .sis import populations as _populations

__all__ = ["solve_triplet", "solve_triplets", "TripletSolver", "TripletEstimate", "Hypotheses",
           "add_view", "DEFAULTS", "METHODS"]


def _model(method, meas):
    """The model actually solved: without headings the motion factors are absent (the
    reference solver handles that case itself)."""
    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    if method not in ("baseline", "reference") and meas.headings is None and meas.n_views > 1:
        return "baseline"
    if meas.step_sigma_heading is not None and method in ("fast-paper", "reference"):
        raise ValueError(f"sigma_heading: one sigma per step is taken by 'full' and 'fast' "
                         f"(and ignored by 'baseline'), not by {method!r}; give one number")
    return method


def _model_options(method, model, options):
    opts = _resolve(method, options)   # validates against the requested method
    if model == method:
        return opts
    shared = {k: v for k, v in opts.items() if k in DEFAULTS[model]}
    return _resolve(model, shared)


def _resolve(method, options):
    """:func:`.options.resolve_options`, with the reference solver's own defaults."""
    if method == "reference":
        from .reference.staged import REFERENCE_DEFAULTS

        return _options.resolve_options(method, options, dict(REFERENCE_DEFAULTS, prior="world"))
    return _options.resolve_options(method, options)


def solve_triplet(bearings, headings=None, *, method: str = "full", partition="edc",
                  sigma_bearing=None, sigma_heading=None, seed=0, distances=None,
                  sigma_distance_ratio=None, **options) -> TripletEstimate:
    """Estimate the qualitative states of C and of the cameras of one triplet AB:C.

    Args:
        bearings: (n, 3) radians, [phi_A, phi_B, phi_C] per view in time order; or a
            :class:`qfg.simulation.TripletHistory` (then ``headings`` must be None and the sigmas
            default to the history's).
        headings: (n - 1,) radians, direction of travel from view i to view i+1 relative to the
            heading at view i. None (or a history with ``has_motion=False``): no motion model, the
            ``baseline`` model is solved whatever ``method`` says (the result's ``method`` tells).
        method: ``"full"``, ``"fast"``, ``"fast-paper"``, ``"baseline"`` or ``"reference"``.
        partition: partition name or :class:`qfg.partitions.Partition`.
        sigma_bearing, sigma_heading: noise standard deviations (radians, >= 0; zero works: the
            likelihood widths have floors, see ``bearing_floor``). ``sigma_heading`` may also be
            (n - 1,), one per step (all > 0 or all 0): ``full`` and ``fast`` take it,
            ``baseline`` ignores headings, ``reference`` and ``fast-paper`` raise ValueError.
        seed: an int (default 0), SeedSequence or Generator; None draws fresh entropy. Same
            seed, same estimate.
        distances: (n - 1,) the odometry's travelled distance from view i to view i+1 (any
            unit, finite, >= 0; 0 = unknown), or None; a history's own ``distances`` are used
            when present. Only ``full`` and ``fast`` use them: a scale-free factor
            ``N(log(s_i / s_(i-1)) - log(d_i / d_(i-1)); sigma_distance_ratio)`` on the ratio of
            consecutive step lengths s (views 3..n); the other methods ignore them.
        sigma_distance_ratio: noise of that log ratio (>= 0, floored at 0.01; required with
            distances; default the history's).
        **options: method options (``qfg.solvers.DEFAULTS[method]``), e.g. ``n_samples``.

    Returns:
        :class:`TripletEstimate`: ``landmark`` (m,), ``cameras`` (n, m), diagnostics, flags
        (the hypotheses behind it: :class:`TripletSolver`).

    The model (AB frame, paper eqs. MsrLkl, MotionModel): ``phi ~ N(f(L, X), sigma_v^2)``,
    ``psi_i ~ N(g(X_{i+1}, X_i), sigma_w^2)``, uniform headings and ``prior`` (option; default the
    exact world prior) over the configuration [C, X_1..X_n]; the
    state probabilities integrate ``P(X_{1:n}, L_C | H)`` over each state (eqs. slam1/2).

    >>> est = solve_triplet([[0.3, 1.2, 0.8]], sigma_bearing=0.02, method="fast")
    >>> est.cameras.shape, est.method
    ((1, 20), 'fast')
    """
    meas = _input.measurements(bearings, headings, sigma_bearing, sigma_heading, distances,
                               sigma_distance_ratio)
    part = _input.get_partition(partition)
    model = _model(method, meas)
    opts = _model_options(method, model, options)
    _budget.check(model, opts, 1, meas.n_views)
    root = _seeds.root_seed(seed)
    if model == "fast-paper":
        return _solve_fast_batch([meas], part, opts)[0]
    if model in _SIS:
        return solve_sis_batch(model, [meas], [root], part, opts)[0]
    return _solve(model, meas, part, opts, root)[0]


#: Methods solved by the batched SIS engine (:mod:`.sis`).
_SIS = ("full", "fast")


def _solve(model, meas, part, opts, root):
    """(estimate, hypotheses) of one triplet: the same start/step/finish path as
    :class:`TripletSolver`, so that incremental and batch solves agree exactly."""
    if model == "reference":
        return _reference_estimate(meas, part, opts, root), None
    solver = TripletSolver._from_parts(model, part, opts, root, meas.sigma_bearing,
                                       meas.sigma_heading)
    for i in range(meas.n_views):
        solver.add_view(meas.bearings[i], None if i == 0 or meas.headings is None
                        else meas.headings[i - 1])
    return solver._finish()


def _solve_fast_batch(metas, part, opts, hypotheses=False):
    b = np.stack([m.bearings for m in metas])
    n = b.shape[1]
    sv = np.array([m.sigma_bearing for m in metas])
    sh = np.array([m.sigma_heading for m in metas])
    st = _fast_paper.start(b[:, 0], sv, sh, opts, part)
    for i in range(1, n):
        st = _fast_paper.step(st, b[:, i], np.array([m.headings[i - 1] for m in metas]))
    out = _fast_paper.finish(st, hypotheses=hypotheses)
    return out if hypotheses else [e for e, _ in out]


def _reference_estimate(meas, part, opts, root) -> TripletEstimate:
    """``method="reference"``: :func:`qfg.solvers.reference.staged.solve_reference` as an estimate
    (``mc_error`` the largest standard error of the landmark probabilities). A view repeating the
    previous view's bearings is the same camera (not moved, as the other methods take it): the
    distinct views are solved, the repeated view's camera row is its predecessor's, and the
    answer is flagged."""
    from .reference.staged import solve_reference

    rep = _degenerate.repeated_views(meas.bearings)
    keep = np.flatnonzero(~rep)
    # the heading into a repeated view is dropped; the one out of it then leaves its
    # predecessor's pose (the same pose)
    headings = None if meas.headings is None else meas.headings[keep[1:] - 1]
    o = {k: v for k, v in opts.items() if k != "prior"}
    # the odometry's distances likewise (0 where unknown: no factor)
    dist = None if meas.distances is None or headings is None else meas.distances[keep[1:] - 1]
    out = solve_reference(meas.bearings[keep], headings, meas.sigma_bearing, meas.sigma_heading,
                          part, opts["prior"], np.random.default_rng(root), distances=dist,
                          sigma_distance_ratio=meas.sigma_distance_ratio, **o)
    reasons = [out["reason"]] if out["degenerate"] and out["reason"] else (
        ["reference solver flagged the answer"] if out["degenerate"] else [])
    if rep.any():
        reasons.append(_degenerate.repeated_reason(rep))
    cameras = np.asarray(out["cameras"], dtype=float)[np.cumsum(~rep) - 1]
    return TripletEstimate(
        landmark=np.asarray(out["landmark"], dtype=float), cameras=cameras,
        n_hypotheses=int(out["n_samples"]), degenerate=bool(reasons), reason="; ".join(reasons),
        method="reference", partition=part.name, n_views=meas.n_views, ess=float(out["ess"]),
        mc_error=float(np.max(out["mc_error"])), pareto_k=float(out.get("pareto_k", np.nan)),
        log_evidence=np.nan if out["log_evidence"] is None else float(out["log_evidence"]),
        prior=_estimate.prior_name(opts),
        options=_estimate.public_options(opts))


def solve_sis_batch(model, metas, roots, part, opts, hypotheses=False):
    """The SIS engine (method ``"full"`` or ``"fast"``, :mod:`qfg.solvers.sis`) on a batch of
    checked measurements ``metas`` with their seed ``roots`` and resolved options ``opts``;
    one estimate per triplet (with its hypotheses when asked). The step below
    :func:`solve_triplets`, for experiments that drive the populations themselves."""
    # each triplet K times in the batch, once per independent population (_populations)
    K = _populations.count(opts, metas[0].n_views)
    n = len(metas)
    given = (metas, roots)
    metas = [m for m in metas for _ in range(K)]
    roots = [r for root in roots for r in _populations.roots(root, K)]
    b = np.stack([m.bearings for m in metas])
    sv = np.array([m.sigma_bearing for m in metas])
    sh = np.array([m.sigma_heading for m in metas])
    d = sd = hs = None
    if any(m.step_sigma_heading is not None for m in metas):
        # one heading sigma per step (triplets with one sigma repeat it)
        hs = np.stack([np.full(b.shape[1] - 1, m.sigma_heading) if m.step_sigma_heading is None
                       else m.step_sigma_heading for m in metas])
    if any(m.distances is not None for m in metas):
        # triplets without distances get zeros: no factor
        d = np.stack([np.zeros(b.shape[1] - 1) if m.distances is None else m.distances
                      for m in metas])
        sd = np.array([m.sigma_distance_ratio or 0.0 for m in metas])
    st = _sis.start(b[:, 0], sv, sh, roots, _populations.split_options(opts, K), part, model,
                    sd, n_views=b.shape[1])
    for i in range(1, b.shape[1]):
        st = _sis.step(st, b[:, i], np.array([m.headings[i - 1] for m in metas]),
                       None if d is None else d[:, i - 1], None if hs is None else hs[:, i - 1])
    out = _sis.finish(st, hypotheses=hypotheses)
    out = [_populations.merge(out[t * K:(t + 1) * K], opts) for t in range(n)]
    if _escalation.applies(opts, b.shape[1]):
        # the answers the populations disagree on, solved again with the whole budget in one
        # batched call and pooled with the few-views answers (_escalation)
        idx = [t for t in range(n) if _escalation.needed(out[t][0], opts)]
        if idx:
            whole = solve_sis_batch(model, [given[0][t] for t in idx],
                                     [_escalation.seed(given[1][t]) for t in idx], part,
                                     _escalation.whole_options(opts), hypotheses=True)
            for t, pair in zip(idx, whole, strict=True):
                out[t] = _escalation.pool(out[t], pair, opts)
    return out if hypotheses else [e for e, _ in out]


def solve_triplets(histories, headings=None, *, method: str = "full", partition="edc",
                   sigma_bearing=None, sigma_heading=None, seed=0, distances=None,
                   sigma_distance_ratio=None, hypotheses: bool = False,
                   **options) -> list[TripletEstimate]:
    """Solve many triplets in one call; returns one :class:`TripletEstimate` per triplet
    (``hypotheses=True``: one ``(estimate, Hypotheses)`` pair per triplet, the weighted samples
    behind it as :meth:`TripletSolver.hypotheses` gives them; None for the reference solver,
    which keeps none).

    ``histories`` is a sequence of TripletHistory objects (their ``distances`` used when
    present), or bearings (T, n, 3) with ``headings`` (T, n - 1), optional ``distances``
    (T, n - 1) and the sigmas (scalars, or (T,) arrays; :func:`solve_triplet`). Triplet t is solved with
    seed ``SeedSequence(seed).spawn``-style child ``t``, so
    ``solve_triplets(hs, seed=s)[t]`` equals ``solve_triplet(hs[t], seed=child)`` with
    ``child = SeedSequence(entropy, spawn_key=(t,))``. The fast variant is vectorized over all
    triplets with the same number of views; the other methods loop over triplets.

    >>> import numpy as np
    >>> from qfg.simulation import random_triplet_history
    >>> rng = np.random.default_rng(1)
    >>> hs = [random_triplet_history(rng, 3, 0.01, 0.02) for _ in range(4)]
    >>> [e.landmark.shape for e in solve_triplets(hs, method="fast")]
    [(20,), (20,), (20,), (20,)]
    """
    metas = _batch_measurements(histories, headings, sigma_bearing, sigma_heading, distances,
                                sigma_distance_ratio)
    part = _input.get_partition(partition)
    root = _seeds.root_seed(seed)
    out: list = [None] * len(metas)
    groups: dict = {}
    for meas in metas:
        model = _model(method, meas)
        _budget.check(model, _model_options(method, model, options), 1, meas.n_views)
    for t, meas in enumerate(metas):
        model = _model(method, meas)
        if model in ("fast-paper",) + _SIS:
            groups.setdefault((model, meas.n_views), []).append(t)
        else:
            pair = _solve(model, meas, part, _model_options(method, model, options),
                          _seeds.child_seed(root, t))
            out[t] = tuple(pair) if hypotheses else pair[0]
    for (model, _), idx in groups.items():
        opts = _model_options(method, model, options)
        ms = [metas[t] for t in idx]
        if model == "fast-paper":
            ests = _solve_fast_batch(ms, part, opts, hypotheses)
        else:
            ests = solve_sis_batch(model, ms, [_seeds.child_seed(root, t) for t in idx], part,
                                    opts, hypotheses)
        for t, est in zip(idx, ests, strict=True):
            out[t] = est
    return out


def _per_triplet_sigma(name, value, T):
    """(T,) list of a sigma given as None, a scalar or (T,) values (None entries: unset)."""
    if value is None:
        return [None] * T
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected numbers, got {value!r}") from None
    if v.ndim > 1 or (v.ndim == 1 and v.shape[0] != T):
        raise ValueError(f"{name}: expected a number or shape ({T},), got shape {v.shape}")
    return [float(x) for x in np.broadcast_to(v, (T,))]


def _batch_measurements(histories, headings, sigma_bearing, sigma_heading, distances=None,
                        sigma_distance_ratio=None):
    from ..simulation import TripletHistory

    if isinstance(histories, TripletHistory):
        raise ValueError("histories: expected a sequence of TripletHistory objects or an "
                         "(T, n, 3) array; for one triplet use solve_triplet")
    if isinstance(histories, Sequence) and histories and all(
            isinstance(h, TripletHistory) for h in histories):
        if headings is not None:
            raise ValueError("headings: pass either TripletHistory objects or bearings and "
                             "headings, not both")
        if distances is not None:
            raise ValueError("distances: pass either TripletHistory objects (with their "
                             "distances) or bearings and distances, not both")
        sds = _per_triplet_sigma("sigma_distance_ratio", sigma_distance_ratio, len(histories))
        return [_input.measurements(h, None, sigma_bearing, sigma_heading, None, sd)
                for h, sd in zip(histories, sds, strict=True)]
    b = np.asarray(histories, dtype=float) if not isinstance(histories, Sequence) or histories \
        else np.zeros((0, 1, 3))
    if b.ndim != 3 or b.shape[-1] != 3:
        raise ValueError(f"histories: expected TripletHistory objects or bearings of shape "
                         f"(T, n, 3), got shape {b.shape}")
    T, n = b.shape[:2]

    def per_step(name, values):
        # (T, n - 1) per-step inputs as T rows, or T Nones
        if values is None:
            return [None] * T
        v = np.asarray(values, dtype=float)
        if v.shape != (T, n - 1):
            raise ValueError(f"{name}: expected shape ({T}, {n - 1}) for bearings {b.shape}, "
                             f"got {v.shape}")
        return list(v)

    hs = per_step("headings", headings)
    sb = np.broadcast_to(np.asarray(sigma_bearing if sigma_bearing is not None else np.nan,
                                    dtype=float), (T,))
    sh = np.broadcast_to(np.asarray(sigma_heading if sigma_heading is not None else np.nan,
                                    dtype=float), (T,))
    ds = per_step("distances", distances)
    sds = _per_triplet_sigma("sigma_distance_ratio", sigma_distance_ratio, T)
    return [_input.measurements(b[t], hs[t], None if np.isnan(sb[t]) else sb[t],
                                None if np.isnan(sh[t]) else sh[t], ds[t], sds[t]) for t in range(T)]


def add_view(solver, bearings, heading=None) -> TripletEstimate:
    """``solver.add_view(bearings, heading)`` then ``solver.estimate()`` for a
    :class:`TripletSolver`. A :class:`TripletEstimate` holds only the answer and cannot be
    updated: ValueError naming :class:`TripletSolver`.

    >>> s = TripletSolver("fast", sigma_bearing=0.02, sigma_heading=0.05)
    >>> add_view(s, [0.3, 1.2, 0.8]).n_views
    1
    """
    if not isinstance(solver, TripletSolver):
        raise ValueError(_estimate.ADD_VIEW_MOVED)
    return solver.add_view(bearings, heading).estimate()


class TripletSolver:
    """Incremental solver of one triplet AB:C: views are added one at a time and the estimate is
    available after each. The answer after views 1..n equals :func:`solve_triplet` of those views
    with the same seed, exactly (every view draws from its own random stream).

    Args:
        method: one of :data:`METHODS` (as :func:`solve_triplet`).
        partition: partition name or :class:`qfg.partitions.Partition`.
        sigma_bearing, sigma_heading: noise standard deviations (radians, >= 0).
        seed: an int (default 0), SeedSequence or Generator; None draws fresh entropy.
        sigma_distance_ratio: noise of the log ratio of consecutive travelled distances
            (required before a ``distance`` is added; :func:`solve_triplet`).
        **options: method options (``qfg.solvers.DEFAULTS[method]``), ``prior`` included.

    >>> import numpy as np
    >>> from qfg.simulation import random_triplet_history
    >>> h = random_triplet_history(np.random.default_rng(3), 3, 0.02, 0.05)
    >>> s = TripletSolver("full", sigma_bearing=h.sigma_bearing, sigma_heading=h.sigma_heading,
    ...                   seed=1)
    >>> for i in range(3):
    ...     _ = s.add_view(h.bearings[i], None if i == 0 else h.headings[i - 1])
    >>> e = s.estimate()
    >>> bool(np.array_equal(e.landmark, solve_triplet(h, method="full", seed=1).landmark))
    True
    >>> s.hypotheses().camera_samples.shape[0]
    3
    """

    def __init__(self, method: str = "full", *, partition="edc", sigma_bearing=0.0,
                 sigma_heading=0.0, seed=0, sigma_distance_ratio=None, **options):
        if method not in METHODS:
            raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
        part = _input.get_partition(partition)
        opts = _resolve(method, options)
        self._init(method, part, opts, _seeds.root_seed(seed),
                   _input.check_sigma("sigma_bearing", sigma_bearing),
                   _input.check_sigma("sigma_heading", sigma_heading),
                   _input.check_distance_sigma(sigma_distance_ratio, None))

    @classmethod
    def solve(cls, bearings, headings=None, *, method: str = "full", partition="edc",
              sigma_bearing=None, sigma_heading=None, seed=0, distances=None,
              sigma_distance_ratio=None, **options) -> "TripletSolver":
        """A solver with every view of a history added; the arguments and the model chosen are
        those of :func:`solve_triplet` (``.estimate()`` equals its result). Use it when the
        hypotheses are wanted too (``.hypotheses()``)."""
        meas = _input.measurements(bearings, headings, sigma_bearing, sigma_heading, distances,
                                   sigma_distance_ratio)
        part = _input.get_partition(partition)
        model = _model(method, meas)
        solver = cls._from_parts(model, part, _model_options(method, model, options),
                                 _seeds.root_seed(seed), meas.sigma_bearing, meas.sigma_heading,
                                 meas.sigma_distance_ratio)
        for i in range(meas.n_views):
            first = i == 0 or meas.headings is None
            solver.add_view(meas.bearings[i], None if first else meas.headings[i - 1],
                            None if first or meas.distances is None else meas.distances[i - 1],
                            None if first or meas.step_sigma_heading is None
                            else meas.step_sigma_heading[i - 1])
        return solver

    @classmethod
    def _from_parts(cls, method, part, opts, root, sigma_bearing, sigma_heading,
                    sigma_distance_ratio=None):
        self = cls.__new__(cls)
        self._init(method, part, opts, root, sigma_bearing, sigma_heading, sigma_distance_ratio)
        return self

    def _init(self, method, part, opts, root, sb, sh, sd=None):
        self.method, self.partition, self.options = method, part, opts
        self._root, self._sb, self._sh, self._sd = root, float(sb), float(sh), sd
        self._state = None
        self._cache = None
        self._views: list = []          # (bearings, heading, distance) per view (SIS methods)
        self._populations = 0           # K of the SIS state (_populations.count)

    @property
    def n_views(self) -> int:
        if self._state is None:
            return 0
        if self.method == "baseline":
            return self._state.meas.n_views
        return self._state.n_views

    def add_view(self, bearings, heading=None, distance=None,
                 sigma_heading=None) -> "TripletSolver":
        """Add one view: ``bearings`` (3,) [phi_A, phi_B, phi_C] radians, ``heading`` psi
        (radians) from the previous view (None for the first view, required after it except for
        the baseline, which ignores it) and optionally ``distance``, travelled from the
        previous view by odometry (>= 0; 0 or None: unknown; needs ``sigma_distance_ratio``;
        used by ``full`` and ``fast`` only), and ``sigma_heading``, this step's heading sigma
        (radians, > 0 when the solver's is; None: the solver's; ``full`` and ``fast`` only).
        Returns the solver (for chaining)."""
        phi = _input.check_bearings(bearings)
        if phi.shape[0] != 1:
            raise ValueError(f"bearings: expected one view (3,), got shape {phi.shape}")
        phi = phi[0]
        first = self._state is None
        if heading is not None:
            # checked for every method, the baseline included (which then ignores it)
            heading = _input.check_heading(heading)
        if distance is not None:
            distance = _input.check_distance(distance)
            if first:
                raise ValueError("distance: the first view has no previous view (pass None)")
            if self._sd is None:
                raise ValueError("sigma_distance_ratio: required when distances are given "
                                 "(TripletSolver(..., sigma_distance_ratio=...))")
        if sigma_heading is not None:
            sigma_heading = _input.check_sigma("sigma_heading", sigma_heading)
            if first:
                raise ValueError("sigma_heading: the first view has no step (pass None)")
            if self.method in ("fast-paper", "reference"):
                raise ValueError(f"sigma_heading: one sigma per step is taken by 'full' and "
                                 f"'fast', not by {self.method!r}")
            if (sigma_heading > 0) != (self._sh > 0):
                raise ValueError(f"sigma_heading: a step's sigma must be > 0 exactly when the "
                                 f"solver's is ({self._sh}), got {sigma_heading}")
        if first:
            if heading is not None and self.method != "baseline":
                raise ValueError("heading: the first view has no previous view (pass None)")
        elif self.method != "baseline" and heading is None:
            raise ValueError(f"heading: method {self.method!r} needs the heading from the "
                             "previous view")
        part, opts = self.partition, self.options
        _budget.check(self.method, opts, 1, self.n_views + 1)
        if self.method == "reference":
            # solved from scratch at estimate(): keep the measurements
            b = phi[None, :] if first else np.vstack([self._state.bearings, phi])
            h = None if first or heading is None else np.append(
                self._state.headings if self._state.headings is not None else [], heading)
            self._state = _input.Measurements(b, h, self._sb, self._sh)
        elif self.method in _SIS:
            self._views.append((phi, heading, distance, sigma_heading))
            K = _populations.count(opts, len(self._views))
            if first or K != self._populations:
                # K changed (few_views_populations): the views again from the first, as a
                # batch solve of this many views would run them
                self._populations = K
                self._state = None
                views = self._views
            else:
                views = self._views[-1:]
            for ph, hd, ds, sh in views:
                # one row per independent population, as solve_triplets batches them
                rows = np.repeat(ph[None, :], K, axis=0)
                if self._state is None:
                    self._state = _sis.start(
                        rows, np.full(K, self._sb), np.full(K, self._sh),
                        tuple(_populations.roots(self._root, K)),
                        _populations.split_options(opts, K), part, self.method,
                        None if self._sd is None else np.full(K, self._sd))
                else:
                    self._state = _sis.step(self._state, rows, np.full(K, hd),
                                            None if ds is None else np.full(K, ds),
                                            None if sh is None else np.full(K, sh))
        elif self.method == "fast-paper":
            if first:
                self._state = _fast_paper.start(phi[None, :], np.array([self._sb]),
                                          np.array([self._sh]), opts, part)
            else:
                self._state = _fast_paper.step(self._state, phi[None, :], np.array([heading]))
        else:
            if first:
                meas = _input.Measurements(phi[None, :], None, self._sb, self._sh)
                self._state = _baseline.start(meas, self._root, opts, part)
            else:
                self._state = _baseline.step(self._state, phi, heading)
        self._cache = None
        return self

    def _finish(self):
        if self._state is None:
            raise ValueError("bearings: no view added yet (call add_view first)")
        if self._cache is None:
            if self.method == "reference":
                self._cache = (_reference_estimate(self._state, self.partition, self.options,
                                                   self._root), None)
            elif self.method in _SIS:
                pair = _populations.merge(_sis.finish(self._state, hypotheses=True),
                                          self.options)
                if _escalation.applies(self.options, len(self._views)) \
                        and _escalation.needed(pair[0], self.options):
                    # the views so far again with the whole budget, as a batch solve does
                    whole = TripletSolver._from_parts(
                        self.method, self.partition, _escalation.whole_options(self.options),
                        _escalation.seed(self._root), self._sb, self._sh, self._sd)
                    for view in self._views:
                        whole.add_view(*view)
                    pair = _escalation.pool(pair, whole._finish(), self.options)
                self._cache = pair
            elif self.method == "fast-paper":
                self._cache = _fast_paper.finish(self._state, hypotheses=True)[0]
            else:
                self._cache = _baseline.finish(self._state)
        return self._cache

    def estimate(self) -> TripletEstimate:
        """The :class:`TripletEstimate` of the views so far."""
        return self._finish()[0]

    def hypotheses(self) -> _estimate.Hypotheses:
        """The weighted hypotheses behind :meth:`estimate` (:class:`Hypotheses`); ValueError for
        ``method="reference"``, which keeps none."""
        hyp = self._finish()[1]
        if hyp is None:
            raise ValueError("method: the reference solver keeps no hypotheses")
        return hyp

    def __repr__(self) -> str:
        return (f"TripletSolver(method={self.method!r}, partition={self.partition.name!r}, "
                f"n_views={self.n_views}, prior={_estimate.prior_name(self.options)!r})")
