"""The MRCLAM study's parameters: the names each option accepts (:data:`METHODS`,
:data:`MODES`, :data:`PRIORS`, :data:`COMBINE`, ...), their defaults (:data:`DEFAULTS`) and
:func:`checked_params`, which fills them in and refuses an unknown key or value by name."""

from __future__ import annotations

COMBINE = ("prior-once", "geometric", "product")
#: single-triplet solvers; ``"none"``: no solver, every history's estimate the prior alone (for
#: map methods that work from the raw measurements, e.g. ``--map joint``)
METHODS = ("fast", "full", "baseline", "none")
MODES = ("honest", "paper")
PRIORS = ("arena", "world", "arena-logscale")
KINDS = ("seen", "propagated", "camera")
#: Scores of every row, each also with the ``uniform_`` and ``prior_`` baselines.
SCORES = ("p_truth", "log_score", "brier", "gt_rating", "truth_under_1pct")
#: Samples behind each prior's state distribution (standard error <= 1.2e-3 per state).
PRIOR_SAMPLES = 200_000

DEFAULTS = {
    "data": "",                            # directory holding MRCLAM_Dataset* ("": $QFG_MRCLAM_DIR)
    "datasets": [],                        # dataset numbers (empty: every one found)
    "robots": [],                          # robot numbers (empty: every robot)
    "method": "full",
    "mode": "honest",
    "prior": "arena",
    "combine": "geometric",
    "partition": "edc",
    "fix_landmarks": True,                 # swap back landmark pairs found by check_landmarks
    "tensor": "",                          # .npz file; "" = the shipped tensor of the partition
    "min_travel": 0.02,                    # m between kept views (0.02: every view with motion)
    "max_gap": 120.0,                      # s unseen that ends a pass
    "max_views": 0,                        # first views of each pass kept (0: all)
    "propagate": True,                     # map and propagate (False: seen triplets only)
    "propagation": "mean",                 # "mean": pooled composition; "best": Algorithm 2
    "map": "",                             # map method by name (maps.py; "": from the two
                                           # above: "seen", "pooled" or "best")
    "sigma_bearing_deg": 0.0,              # bearing sigma the solver assumes (0: loader default)
    "sigma_heading_deg": 0.0,              # heading sigma the solver assumes (0: loader default)
    "temper": 1.0,                         # power on each estimate's likelihood part (1: none)
    "spread_views": 3,                     # views spread over each pass (0: all)
    "distances": True,                     # odometry's travelled distances in the motion model
                                           # (off: no gain on dataset 6, docs/mrclam.md)
    "sigma_distance_ratio": 0.0,           # their log-ratio noise (0: loader default, 0.074)
    "bearing_tail": "normal",              # bearing-noise model (BEARING_TAILS)
    "model_check": 0.0,                    # level of the solvers' model check (0: report only)
    "heading_drift": False,                # heading sigma from each history's longest step
    "distance_tail": "normal",             # step-length-ratio noise model (DISTANCE_TAILS)
    "heading_walk": 0.0,                   # per-step heading sigma b sqrt(step duration), b in
                                           # deg / sqrt(s) (0: off; HEADING_WALK measured)
    "heading_tail": "normal",              # "measured": the headings' two-normal tail
                                           # (HEADING_WALK_TAIL), for the solvers
    "budget": 1.0,                         # the full/fast solvers' budget (n_samples,
                                           # max_hypotheses, posterior_samples) times this
    "bearing_calibration": "none",         # "measured": each robot's bearing bias and scale
                                           # measured on dataset 6 undone first (every dataset)
    "camera_prior": "point",               # the solvers' camera_prior ("joint": the cameras'
                                           # joint prior in the intermediate weights)
    "populations": 1,                      # the full/fast solvers' independent SIS
                                           # populations (their populations option)
}

#: Bearing calibrations of ``--bearing-calibration``: none, or each robot's bias and scale
#: measured against motion capture on dataset 6 (:mod:`qfg.datasets.mrclam._calibration`).
BEARING_CALIBRATIONS = ("none", "measured")

#: Options added after runs were recorded without them: a run's params leave them out at their
#: defaults, so that those runs resume (``qfg mrclam --resume``) as before.
LATER_KEYS = ("bearing_tail", "model_check", "heading_drift", "distance_tail", "heading_walk",
              "heading_tail", "camera_prior", "budget", "populations", "bearing_calibration")


def checked_params(params: dict) -> dict:
    """``params`` over :data:`DEFAULTS`, every key known and every named choice (method, combine,
    mode, propagation, prior, map) checked; ValueError naming the first bad one."""
    unknown = set(params) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"params: unknown keys {sorted(unknown)}; known: {sorted(DEFAULTS)}")
    p = {**DEFAULTS, **params}
    for key, allowed in (("method", METHODS), ("combine", COMBINE), ("mode", MODES),
                         ("propagation", ("mean", "best")),
                         ("prior", PRIORS)):
        if p[key] not in allowed:
            raise ValueError(f"{key}: expected one of {allowed}, got {p[key]!r}")
    if p["map"]:
        from qfg.harness.studies.mrclam.maps import MAP_METHODS

        if p["map"] not in MAP_METHODS:
            raise ValueError(f"map: expected one of {tuple(MAP_METHODS)}, got {p['map']!r}")
    return p
