"""Time and memory bounds of the solvers for any number of views: a working-memory estimate
checked up front (a ValueError naming the way out instead of a machine out of memory), and a
cap on the reference solver's views (its time grows much faster than linearly).

Every method keeps at most a fixed number of hypotheses per triplet (``max_hypotheses``,
``n_landmark_samples``, the reference's draws), each holding one pose per view: time and memory
grow linearly with the number of views, and :func:`check` refuses a call whose estimate exceeds
:data:`MEMORY_BUDGET`.
"""

from __future__ import annotations

#: Largest working memory a call may need (bytes); above it the call is refused up front.
MEMORY_BUDGET = 2 * 2**30

#: Most views the reference solver takes: at 20 views it answered in 46-157 s with an ESS of
#: 5-7 and gave no answer within 10 minutes at 50 (issue 20).
REFERENCE_MAX_VIEWS = 20

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
    per_view = 3 * 8 * _COPIES
    if method in ("full", "fast"):
        # hypotheses alive: the first view's samples times the motion draws of every later view,
        # capped at max_hypotheses; each draws motion_samples children
        ms = opts["motion_samples"]
        alive = min(opts["max_hypotheses"], opts["n_samples"] * ms ** min(max(n_views - 1, 0), 60))
        rows = alive * ms
    elif method == "fast-paper":
        rows = 2 * opts["max_hypotheses"]
    elif method == "baseline":
        # candidates x resected poses per view, plus the (candidates, states) camera shares
        rows = opts["n_landmark_samples"] * (opts["noise_samples"] + 8)
    else:
        rows = opts.get("n_samples", 10_000) * opts.get("grow", 4)
    return int(n_triplets) * int(rows) * int(n_views) * per_view


def check(method: str, opts: dict, n_triplets: int, n_views: int) -> None:
    """ValueError up front when a call would exceed the bounds (naming what to change)."""
    if method == "reference" and n_views > REFERENCE_MAX_VIEWS:
        raise ValueError(f"bearings: the reference solver takes at most {REFERENCE_MAX_VIEWS} "
                         f"views (got {n_views}): its time grows much faster than linearly; "
                         "use method='full' or fewer views")
    need = working_bytes(method, opts, n_triplets, n_views)
    if need > MEMORY_BUDGET:
        raise ValueError(f"bearings: {n_triplets} triplet(s) of {n_views} views would need about "
                         f"{need / 2**30:.1f} GiB with method {method!r} (budget "
                         f"{MEMORY_BUDGET / 2**30:.0f} GiB, qfg.solvers._budget.MEMORY_BUDGET); "
                         "solve fewer triplets per call, fewer views, or smaller budgets "
                         "(max_hypotheses, n_samples)")
