"""Methods, their documented default options (chosen by measurement: docs/solvers.md) and the
checks of user options.
"""

from __future__ import annotations

import numpy as np

from ... import priors as _priors
from ..._validate import non_negative, positive_int
from .likelihood import as_normal_tail, as_tail
from .prior import resolve_prior

#: Methods :func:`qfg.solvers.solve_triplet` knows.
METHODS = ("full", "fast", "fast-paper", "baseline", "reference")


#: Prior names the solvers accept (besides any :class:`qfg.priors.Prior` object): see
#: :func:`qfg.priors.get`. ``"world"`` (default) is the exact prior of the simulator's world.
PRIORS = _priors.NAMES


#: The cameras' prior in the SIS solvers' intermediate weights (``camera_prior``).
CAMERA_PRIORS = ("point", "joint")


#: Triangulation used in the resection step.
RESECTIONS = ("centroid", "lsq")


#: Documented defaults (chosen by measurement: docs/solvers.md). Angles in radians.
DEFAULTS = {
    "full": {
        "n_samples": 600,            # first-view camera samples per triplet (x motion_samples
                                     # when both sigmas are 0)
        "motion_samples": 8,         # noise draws per hypothesis and view (motion step)
        "motion_spread": 1.0,        # noise drawn this many times wider (weights corrected)
        "max_hypotheses": 3000,      # cap after pruning (systematic resampling down to it)
        "prune_ratio": 1e-6,         # drop hypotheses lighter than this x the heaviest
        "landmark_samples": 4,       # C samples per trajectory (intermediate and final weights)
        "ray_fraction": 0.25,        # share of C samples drawn along a line of sight
        "posterior_samples": 512,    # trajectories resampled for the exact-prior final weights
        "one_view_samples": 16,      # C samples per trajectory with a single view
        "bearing_floor": np.deg2rad(0.05),
        "move_steps": 0,             # Metropolis-Hastings moves per hypothesis after resampling
                                     # (resample-move; measured not to help: docs/solvers.md)
        "rejuvenate": 1,             # sweeps of Metropolis-Hastings moves (resample-move) at
                                     # views 4, 6, 9, 14, 20, 30, ... (sis.moves._rejuvenate; 0: off;
                                     # docs/solvers.md, "More views": closer to the reference
                                     # and fewer confidently wrong at 10-20 views, 2.5-2.9x the
                                     # time there, nothing at 3 views)
        "mc_shrinkage": 1.0,         # pseudo-draws of the uniform added to the ESS draws
                                     # (shrink_to_uniform)
        "bearing_tail": None,        # heavy-tailed bearing noise (common.likelihood.BearingTail, or
                                     # (share, scale, outlier)); None: the normal
        "distance_tail": None,       # heavy-tailed noise of the step-length ratios' log
                                     # ((share, scale): (1 - share) N(sigma) + share N(scale
                                     # sigma), sigma the history's sigma_distance_ratio); None:
                                     # the normal
        "heading_tail": None,        # the same for the motion headings (sigma each step's
                                     # heading sigma); the motion step draws from it
        "model_check": 0.0,          # level of the bearing/heading model check: an answer whose
                                     # posterior predictive p is below it is widened toward the
                                     # prior's state distribution and flagged (0: report only)
        "min_ess": 2.0,              # an answer whose final landmark weights have a smaller
                                     # ESS is flagged: it rests on about one trajectory (1st
                                     # percentile on 80 development triplets at 2/5 deg, 3
                                     # views: 13; 5 of 120 answers at 6 and 10 views have 3-5)
        "populations": 1,            # independent SIS populations, each with 1/K of the budget
                                     # (n_samples, max_hypotheses, posterior_samples), answers
                                     # averaged (sis.populations; docs/solvers.md)
        # Up to sis.engine.FEW_VIEWS = 3 views (the next view solves them again with the budget
        # above): a smaller budget split between two independent populations, and the
        # triplets whose populations disagree (mc_error above few_views_escalate) solved again
        # with the whole budget and pooled (sis.escalation). About 1.0 workload per 3-view triplet
        # instead of 1.6-1.8, as close to the reference as the whole budget, paired on 400
        # development geometries x 6 seeds (docs/results/solvers_options.md, "The few-views package"). A call
        # that sets a budget option or a population count itself gets exactly that budget
        # (the package steps aside: FEW_VIEWS_OFF).
        "few_views_populations": 2,
        "few_views_budget": {"n_samples": 400, "motion_samples": 6, "max_hypotheses": 2000},
        "few_views_escalate": 0.15,
        "c_anchors": False,          # C refitted about its mode at views 4, 8, 16, 32, ...
                                     # instead of updated (docs/solvers.md, "More views": +0.03
                                     # at 10 views on development geometries; off: two tail and
                                     # model-check tests not yet squared with it)
        "camera_prior": "point",     # the cameras' prior in the intermediate weights: "point"
                                     # (a product of per-point priors) or "joint" (the prior
                                     # of the cameras so far together; sis.target.log_camera_prior)
        "prior": "world",
    },
    "fast": {
        "n_samples": 64,
        "motion_samples": 4,
        "motion_spread": 1.0,
        "max_hypotheses": 256,
        "prune_ratio": 1e-6,
        "landmark_samples": 2,
        "ray_fraction": 0.5,
        "posterior_samples": 32,
        "one_view_samples": 8,
        "bearing_floor": np.deg2rad(0.5),   # wider than full's: with its small budget the
                                            # noiseless posterior's narrow peaks are missed
        "move_steps": 0,
        "rejuvenate": 0,
        "mc_shrinkage": 1.0,
        "bearing_tail": None,
        "distance_tail": None,
        "heading_tail": None,
        "model_check": 0.0,
        "min_ess": 1.5,              # less than about one effective draw: flagged (its 1st
                                     # percentile on the same triplets: 1.9)
        "c_anchors": False,
        "populations": 1,
        "few_views_populations": 1,
        "few_views_budget": None,
        "camera_prior": "point",
        "prior": "world",
    },
    "fast-paper": {
        "n_samples": 128,            # camera positions on the first view's arc (coarse grid)
        "refine_levels": 1,          # adaptive refinement of the first camera's arc parameter:
        "refine_cells": 16,          #   the heaviest cells, split into
        "refine_factor": 8,          #   this many sub-cells, this many times
        "jacobian": True,            # weight positions by the motion step's change of variables
        "kernel": "bearing",         # C-bearing likelihood width: "bearing" = sigma_v,
                                     # "combined" = hypot(sigma_v, sigma_w)
        "max_hypotheses": 8192,
        "bearing_floor": np.deg2rad(0.05),
        "one_view_samples": 16,
        "resection": "lsq",
        "landmark_volume": False,
        "prior": "world",
    },
    "baseline": {
        "n_landmark_samples": 4096,  # C candidates drawn from the prior (stratified)
        "noise_samples": 16,         # measurement-noise draws per view (1 when sigma = 0)
        "jacobian_cap": 30.0,        # cap on 1/|det J| relative to the median candidate
        "bearing_tail": None,        # as full's: the noise draws come from the mixture
        "joint_samples": 16,         # tuples of the views' draws per candidate for the prior of
                                     # the whole configuration (0: a product of per-point
                                     # priors, the paper's model; baseline, docs/solvers.md)
        "prior": "world",
    },
}


#: Options ``few_views_budget`` may set.
FEW_VIEWS_KEYS = ("n_samples", "motion_samples", "max_hypotheses", "landmark_samples",
                  "posterior_samples")

#: The few-views options switched off (the solver's budget at every number of views). Their
#: defaults come as one package: a call that sets any of them, a budget option or a population
#: count gets the package off, with its own settings on top (so a call that sets its budget
#: gets exactly that budget, and ``few_views_budget=...`` alone means what it meant when the
#: package was off by default).
FEW_VIEWS_OFF = {"few_views_budget": None, "few_views_populations": 1,
                 "few_views_escalate": None}
FEW_VIEWS_OVERRIDES = tuple(FEW_VIEWS_OFF) + FEW_VIEWS_KEYS + ("populations",)


#: The options that set the SIS solvers' sampling budget (scaled together by
#: :func:`scaled_budget`).
BUDGET_KEYS = ("n_samples", "max_hypotheses", "posterior_samples")


def scaled_budget(method: str, factor: float) -> dict:
    """The budget options of ``method`` ("full" or "fast") at ``factor`` times their defaults
    (:data:`BUDGET_KEYS`, each at least 1): more hypotheses for about ``factor`` times the time,
    where the default budget is measured not to resolve the posterior (docs/solvers.md,
    "The budget"). ``factor`` 1 gives ``{}``: the defaults, the few-views package included
    (any budget option given switches it off, :data:`FEW_VIEWS_OFF`).

    >>> scaled_budget("full", 4.0)
    {'n_samples': 2400, 'max_hypotheses': 12000, 'posterior_samples': 2048}
    >>> scaled_budget("full", 1.0)
    {}
    """
    if method not in ("full", "fast"):
        raise ValueError(f"budget: the {method} solver has no budget factor (full, fast)")
    f = float(factor)
    if not (np.isfinite(f) and f > 0):
        raise ValueError(f"budget: expected a factor > 0, got {factor!r}")
    if f == 1.0:
        return {}
    d = DEFAULTS[method]
    return {k: max(1, int(round(d[k] * f))) for k in BUDGET_KEYS}


def _few_views_budget(value):
    """``few_views_budget``: None, or a dict of :data:`FEW_VIEWS_KEYS` to positive ints."""
    if value is None or (isinstance(value, dict) and not value):
        return None
    if not isinstance(value, dict):
        raise ValueError(f"few_views_budget: expected None or a dict of budget options "
                         f"({', '.join(FEW_VIEWS_KEYS)}), got {value!r}")
    bad = sorted(set(value) - set(FEW_VIEWS_KEYS))
    if bad:
        raise ValueError(f"few_views_budget: {bad[0]!r} is not a budget option; known: "
                         f"{', '.join(FEW_VIEWS_KEYS)}")
    return {k: positive_int(f"few_views_budget[{k!r}]", v) for k, v in value.items()}


def _few_views_escalate(value, opts):
    """``few_views_escalate``: None, or a threshold in (0, 1) on the few-views answer's
    ``mc_error``, with ``few_views_populations >= 2`` (:mod:`.escalation`)."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        raise ValueError(f"few_views_escalate: expected None or a number in (0, 1), got "
                         f"{value!r}")
    v = float(value)
    if not 0 < v < 1:
        raise ValueError(f"few_views_escalate: expected None or a number in (0, 1), got {v}")
    if int(opts.get("few_views_populations", 1)) < 2:
        raise ValueError("few_views_escalate: needs few_views_populations >= 2 (its test is "
                         "the populations' disagreement), got few_views_populations = "
                         f"{opts.get('few_views_populations', 1)}")
    return v


def resolve_options(method: str, options: dict, defaults: dict | None = None) -> dict:
    """Defaults of ``method`` (or ``defaults``, e.g. the reference solver's) updated with
    ``options``; unknown or bad options raise ValueError."""
    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    opts = dict(DEFAULTS[method] if defaults is None else defaults)
    unknown = sorted(set(options) - set(opts))
    if unknown:
        raise ValueError(f"{unknown[0]}: not an option of method {method!r}; "
                         f"known: {', '.join(sorted(opts))}")
    opts.update(options)
    if "motion" in opts and opts["motion"] not in ("sample", "match"):
        raise ValueError(f"motion: expected 'sample' or 'match', got {opts['motion']!r}")
    if "joint_samples" in opts:
        opts["joint_samples"] = positive_int("joint_samples", opts["joint_samples"], minimum=0)
    for k in ("n_samples", "max_hypotheses", "one_view_samples", "n_landmark_samples",
              "motion_samples", "noise_samples", "refine_cells", "refine_factor",
              "posterior_samples", "landmark_samples"):
        if k in opts:
            opts[k] = positive_int(k, opts[k])
    if "move_steps" in opts:
        opts["move_steps"] = positive_int("move_steps", opts["move_steps"], minimum=0)
    if "rejuvenate" in opts:
        opts["rejuvenate"] = positive_int("rejuvenate", opts["rejuvenate"], minimum=0)
    for k in ("populations", "few_views_populations"):
        if k in opts:
            opts[k] = positive_int(k, opts[k])
    if "refine_levels" in opts:
        opts["refine_levels"] = positive_int("refine_levels", opts["refine_levels"], minimum=0)
    if "motion_spread" in opts:
        ms = non_negative("motion_spread", opts["motion_spread"])
        if ms < 1:
            raise ValueError(f"motion_spread: expected a number >= 1, got {ms}")
        opts["motion_spread"] = ms
    for k in ("bearing_floor", "heading_floor", "match_sigmas", "jacobian_cap", "mc_shrinkage",
              "min_ess"):
        if k in opts:
            opts[k] = non_negative(k, opts[k])
            if k in ("match_sigmas", "jacobian_cap") and opts[k] == 0:
                raise ValueError(f"{k}: expected a number > 0, got 0")
    for k in ("jacobian", "landmark_volume", "c_anchors"):
        if k in opts and not isinstance(opts[k], (bool, np.bool_)):
            raise ValueError(f"{k}: expected True or False, got {opts[k]!r}")
    if "prune_ratio" in opts:
        pr = non_negative("prune_ratio", opts["prune_ratio"])
        if pr >= 1:
            raise ValueError(f"prune_ratio: expected a number in [0, 1), got {pr}")
        opts["prune_ratio"] = pr
    if opts.get("camera_prior", "point") not in CAMERA_PRIORS:
        raise ValueError(f"camera_prior: expected one of {CAMERA_PRIORS}, "
                         f"got {opts['camera_prior']!r}")
    if opts.get("kernel", "bearing") not in ("bearing", "combined"):
        raise ValueError(f"kernel: expected 'bearing' or 'combined', got {opts['kernel']!r}")
    if opts.get("resection", "centroid") not in RESECTIONS:
        raise ValueError(f"resection: expected one of {RESECTIONS}, got {opts['resection']!r}")
    if "few_views_budget" in opts and any(k in options for k in FEW_VIEWS_OVERRIDES):
        # the call manages its budget: the default few-views package steps aside
        opts.update({k: v for k, v in FEW_VIEWS_OFF.items() if k not in options})
    if "few_views_budget" in opts:
        opts["few_views_budget"] = _few_views_budget(opts["few_views_budget"])
    if "few_views_escalate" in opts:
        opts["few_views_escalate"] = _few_views_escalate(opts["few_views_escalate"], opts)
    opts["prior"] = resolve_prior(opts["prior"])
    if "bearing_tail" in opts:
        opts["bearing_tail"] = as_tail(opts["bearing_tail"])
    if "distance_tail" in opts:
        opts["distance_tail"] = as_normal_tail(opts["distance_tail"], "distance_tail")
    if "heading_tail" in opts:
        opts["heading_tail"] = as_normal_tail(opts["heading_tail"], "heading_tail")
    if "model_check" in opts:
        mc = non_negative("model_check", opts["model_check"])
        if mc >= 1:
            raise ValueError(f"model_check: expected a level in [0, 1), got {mc}")
        opts["model_check"] = mc
    if "ray_fraction" in opts:
        rf = non_negative("ray_fraction", opts["ray_fraction"])
        if rf > 1:
            raise ValueError(f"ray_fraction: expected a number in [0, 1], got {rf}")
        opts["ray_fraction"] = rf
    return opts


def effective_sigma(sigma, floor):
    """Likelihood width actually used: ``max(sigma, floor)`` (so that zero noise still works)."""
    return np.maximum(np.asarray(sigma, dtype=float), floor)
