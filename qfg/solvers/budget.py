"""Time and memory bounds of the solvers for any number of views, checked up front (a
ValueError naming the way out instead of a machine out of memory or a call that never returns).

Every method keeps at most a fixed number of hypotheses per triplet (``max_hypotheses``,
``n_landmark_samples``, the reference's draws), each holding one pose per view: memory grows
linearly with the number of views (:func:`working_bytes`, refused above
:data:`MEMORY_BUDGET`). Time grows linearly for ``fast-paper`` and ``baseline``, and for the
SIS methods too (each child updates its parent's C summary with one line of sight and the
trajectories are kept as ancestry: docs/solvers.md, "More views"), except that a child without
a usable C summary is refitted over up to ``sis.motion.REFIT_VIEWS`` views and Metropolis-Hastings
moves (``move_steps``) take whole trajectories. :func:`work_units` counts the pose-views the
worst case processes (every child refitted at every view, moves over whole trajectories) and
:data:`WORK_BUDGET` caps them at what the old engine, which refitted every child over all
views, processed for 100 views with full's defaults (then 15 s per triplet under a load of 11;
now about 10 times fewer pose-views are refitted in the common case, and the bound admits about
153 views for full at its defaults, 262 with ``rejuvenate=0``, and 5900 for fast).
The reference solver takes at most :data:`REFERENCE_MAX_VIEWS` views (beyond, its time and
its ESS are not measured to stay useful).
"""

from __future__ import annotations

#: Largest working memory a call may need (bytes); above it the call is refused up front.
MEMORY_BUDGET = 2 * 2**30

#: Most views the reference solver takes. Its conditional sampler (beyond 5 views) evaluates the
#: world-box prior on every point seen so far at each filter step, so
#: its cost per round grows about quadratically with the views: 27.1 s median per triplet at 30
#: views on 2 development histories (load 3.0), ESS 272 and 532 (``python -m
#: benchmarks.bench_reference --views-dev 30 --triplets 2 --samplers conditional``,
#: docs/priors.md). Before that change its ESS at 30 and 40 views was 65-165 and 33-37 (every
#: 40-view answer flagged), and the staged sampler alone took 46-157 s with an ESS of 5-7 at 20
#: views. The cap bounds a call (about half a minute at 30 views in that measurement).
REFERENCE_MAX_VIEWS = 30

#: Most pose-views one triplet may process (:func:`work_units`): what the engine that refitted
#: every child over all views processed with full's defaults at 100 views.
WORK_BUDGET = 3000 * 8 * 100 * 101 // 2

#: Cost of one pose-view of a rejuvenation evaluation (the chart, the world prior's quadrature
#: over the whole configuration, C's mode) in pose-views of a C refit: 2.2 us against 0.17 us
#: (ratio 12.9) timed on 3000 trajectories of 16 views of one development triplet
#: (``sis.c_integral.log_intermediate_c`` without ``c_anchors`` against ``sis.rejuvenation.poses_of`` plus
#: ``sis.moves._joint_target``, best of 3, load 5).
REJUVENATION_COST = 13

#: Copies of the hypotheses' poses alive at once (children, resampling, the C weights), a
#: generous multiple.
_COPIES = 4


def working_bytes(method: str, opts: dict, n_triplets: int, n_views: int) -> int:
    """Estimated peak working memory (bytes) of solving ``n_triplets`` triplets of ``n_views``
    views in one call: the per-triplet hypotheses (each a pose (x, y, alpha) per view, float64)
    times the copies alive at once.

    >>> from qfg.solvers import DEFAULTS
    >>> working_bytes("full", DEFAULTS["full"], 1, 3) < 2**24
    True
    """
    return int(n_triplets) * _rows(method, opts, n_views) * int(n_views) * 3 * 8 * _COPIES


def work_units(method: str, opts: dict, n_views: int) -> int:
    """Pose-views one triplet of ``n_views`` views processes at worst: for the SIS methods every
    child refitted over min(i, ``sis.motion.REFIT_VIEWS``) views at view i (linear in the views beyond
    that window), plus ``move_steps`` moves of every hypothesis over all i views (quadratic:
    moves are off by default), plus the ``rejuvenate`` sweeps' evaluations over whole
    trajectories at the views of :func:`.rejuvenation.schedule` (linear); hypotheses x views
    for the others (linear).

    >>> from qfg.solvers import DEFAULTS
    >>> work_units("full", DEFAULTS["full"], 150) < WORK_BUDGET < work_units("full", DEFAULTS["full"], 160)
    True
    """
    from .sis.motion import REFIT_VIEWS
    from .sis.rejuvenation import KINDS, work_views

    n = int(n_views)
    if method in ("full", "fast"):
        w = min(n, REFIT_VIEWS)
        refit = w * (w + 1) // 2 + (n - w) * REFIT_VIEWS
        rows = _rows(method, opts, n)
        moves = opts.get("move_steps", 0) * (rows // opts["motion_samples"]) * n * (n + 1) // 2
        # rejuvenation: at its scheduled views (geometric: linear in all), the target over whole
        # trajectories once and once per proposal of each sweep
        sweeps = opts.get("rejuvenate", 0)
        rejuv = REJUVENATION_COST * (1 + sweeps * len(KINDS)) \
            * (rows // opts["motion_samples"]) * work_views(n) if sweeps else 0
        return rows * refit + moves + rejuv
    return _rows(method, opts, n) * n


def _rows(method, opts, n_views) -> int:
    """Hypotheses (rows) alive per triplet at once."""
    if method in ("full", "fast"):
        # hypotheses alive: the first view's samples times the motion draws of every later view,
        # capped at max_hypotheses; each draws motion_samples children
        ms = opts["motion_samples"]
        alive = min(opts["max_hypotheses"], opts["n_samples"] * ms ** min(max(n_views - 1, 0), 60))
        return alive * ms
    if method == "fast-paper":
        return 2 * opts["max_hypotheses"]
    if method == "baseline":
        # candidates x resected poses per view, plus the (candidates, states) camera shares, plus
        # the joint prior's tuples (a pose per view each, and their stacked positions)
        return opts["n_landmark_samples"] * (opts["noise_samples"] + 8
                                             + 2 * opts.get("joint_samples", 0))
    # the reference: the staged sampler's draws per round (up to grow x n_samples), or the
    # conditional sampler's particles (rb_samples x particles, each a pose per view, plus its
    # per-C Gauss-Newton blocks of 3 x 3 per view, about 4 particles' worth each)
    staged = opts.get("n_samples", 10_000) * opts.get("grow", 4)
    conditional = opts.get("rb_samples", 1000) * (opts.get("particles", 16) + 4)
    return max(staged, conditional)


def check(method: str, opts: dict, n_triplets: int, n_views: int) -> None:
    """ValueError up front when a call would exceed the bounds (naming what to change)."""
    if method == "reference" and n_views > REFERENCE_MAX_VIEWS:
        raise ValueError(f"bearings: the reference solver takes at most {REFERENCE_MAX_VIEWS} "
                         f"views (got {n_views}): beyond that its effective sample size falls "
                         "below 50 after minutes per triplet; use method='full' or fewer views "
                         "(e.g. the latest ones)")
    work = work_units(method, opts, n_views)
    if work > WORK_BUDGET:
        raise ValueError(f"bearings: {n_views} views would take method {method!r} about "
                         f"{work / WORK_BUDGET:.1f}x the time budget at worst "
                         "(qfg.solvers.budget.WORK_BUDGET); solve fewer views (e.g. the latest "
                         "ones) or smaller budgets (max_hypotheses, n_samples, move_steps, rejuvenate)")
    need = working_bytes(method, opts, n_triplets, n_views)
    if need > MEMORY_BUDGET:
        raise ValueError(f"bearings: {n_triplets} triplet(s) of {n_views} views would need about "
                         f"{need / 2**30:.1f} GiB with method {method!r} (budget "
                         f"{MEMORY_BUDGET / 2**30:.0f} GiB, qfg.solvers.budget.MEMORY_BUDGET); "
                         "solve fewer triplets per call, fewer views, or smaller budgets "
                         "(max_hypotheses, n_samples)")
