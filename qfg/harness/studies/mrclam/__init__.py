"""MRCLAM study (paper section 6d, Table 2): qualitative mapping on real data, scored so that it
cannot flatter.

For one MRCLAM dataset directory (:func:`run_dataset`, its options one
:class:`MrclamParams`):

1. Load it (:func:`qfg.datasets.mrclam.load`); landmark pairs seen at each other's ground-truth
   position (:func:`~qfg.datasets.mrclam.check_landmarks`) are swapped back before scoring
   (dataset 1: subjects 11 and 17); the swaps are in every row (``gt_swaps``).
2. Histories (:func:`~qfg.datasets.mrclam.triplet_histories`): the views of a pass where the
   robot moved (``min_travel`` = 0.02 m), passes split where the triplet goes unseen for
   ``max_gap`` = 120 s; of each pass, ``spread_views`` = 3 views spread evenly over it, with the
   odometry's headings between them (wide baselines; chosen on dataset 6, docs/results/mrclam.md).
   ``spread_views=0`` keeps every view; ``max_views`` truncates each pass to its first views.
3. ``mode``: ``"honest"`` solves the measured bearings and odometry headings; ``"paper"``
   (paper emulation, needs motion capture: dataset 6) replaces them by the bearings and headings
   computed from the captured poses (:func:`paper_history`), to show what clean inputs give.
4. The prior (``prior``): ``"arena"`` (default) is :class:`qfg.priors.WorldBoxPrior` with the
   box of the arena (:func:`arena_extent`: the landmarks' and the robots' area); ``"world"`` the
   simulator's 6 x 7 m box. Every history is solved with :func:`qfg.solvers.solve_triplets`
   under it; robots without odometry get the baseline model (the row's ``method``).
5. Histories of one ordered triplet (separate passes, other robots) are combined at the state
   level with the prior counted once: ``combine="prior-once"`` (independent passes,
   :func:`qfg.combine.combine_posteriors`) or ``"geometric"`` (passes that repeat the same
   evidence, :func:`qfg.combine.geometric_pool`); ``"product"`` (the plain product of posteriors,
   the prior counted k times) is kept to measure the difference.
6. The whole qualitative map (:func:`qfg.graph.full_map`, every ordered triplet), the combined
   estimates as priors, the rest propagated by pooled composition (``qfg.propagate(g, method="pooled")``;
   ``propagation="best"``: the paper's Algorithm 2, :func:`qfg.propagation.propagate`).
7. Scores (:mod:`qfg.metrics`) against the landmark ground truth (:func:`qfg.graph.truth_states`)
   of seen and propagated triplets: the probability of the truth, log score (clip 1e-4), Brier,
   GT rating with ties split, truth under 1%, DMSE, entropy, flagged and uniform estimates; each
   beside two baselines: ``uniform_*`` and ``prior_*`` (the state distribution the prior alone
   gives, :func:`qfg.combine.prior_state_distribution`). With motion capture, every view of every
   history is also scored as a camera state (rows of kind ``"camera"``).

Rows: one per ordered triplet (``kind`` ``"seen"`` / ``"propagated"``) and one per scored camera
view (``"camera"``); ``probabilities`` holds the estimate (m numbers, ``;``-separated) so that
summaries and calibration figures are computed from the rows alone. :func:`write_outputs` writes
``triplets.csv``, ``cameras.csv``, ``summary.json``, ``table.md`` and figures.

Command: ``qfg mrclam PATH`` (one dataset); ``qfg experiment mrclam --preset paper`` (every
dataset under ``data``, one runner task each).

Modules, by job: :mod:`~qfg.harness.studies.mrclam.history` (steps 1-4: data, prior,
histories and their noise models), :mod:`~qfg.harness.studies.mrclam.pipeline` (prepare, solve
piece by piece, temper, combine, map: :func:`run_dataset`), :mod:`~qfg.harness.studies.mrclam.maps`
(the map methods, by name), :mod:`~qfg.harness.studies.mrclam.scoring` (step 7 and the
summaries), :mod:`~qfg.harness.studies.mrclam.outputs` (tables, figures, the views curve),
:mod:`~qfg.harness.studies.mrclam.params` (:class:`MrclamParams`: every option, its default
and its documentation),
:mod:`~qfg.harness.studies.mrclam.study` (the runner study and ``qfg mrclam``'s pieces) and
:mod:`~qfg.harness.studies.mrclam.compare` (every map method side by side, ``python -m
qfg.harness.studies.mrclam.compare``). The names of all but maps and compare are importable
from here.
"""

from __future__ import annotations

from qfg.harness.studies.mrclam.history import (
    BEARING_TAILS,
    DISTANCE_TAILS,
    HEADING_SIGMA_BY_STEP,
    HEADING_WALK,
    HEADING_WALK_TAIL,
    arena_extent,
    drift_sigma_heading,
    histories,
    make_prior,
    paper_history,
    prepare,
    spread,
    truncate,
    walk_sigma_heading,
)
from qfg.harness.studies.mrclam.outputs import (
    curve_lines,
    make_figures,
    temper_scores,
    views_curve,
    write_curve,
    write_outputs,
)
from qfg.harness.studies.mrclam.params import (
    BEARING_CALIBRATIONS,
    CHUNK,
    COMBINE,
    DEFAULTS,
    FIELDS,
    KINDS,
    LATER_KEYS,
    METHODS,
    MODES,
    PRIOR_SAMPLES,
    PRIORS,
    PROPAGATIONS,
    SCORES,
    SOLVE_KEYS,
    TEMPER_RULES,
    MrclamParams,
    ParamError,
)
from qfg.harness.studies.mrclam.pipeline import (
    AUTO_TEMPERS,
    LightEstimate,
    Prepared,
    choose_power,
    choose_temper,
    cross_pass_agreement,
    estimates_from_rows,
    finish,
    history_groups,
    load_tensor,
    map_name,
    n_pieces,
    piece_rows,
    prepare_run,
    run_dataset,
    say_map_info,
    seen_estimates,
    solve_piece,
)
from qfg.harness.studies.mrclam.scoring import (
    TABLE_KEY,
    decode,
    kind_summary,
    score_map,
    summary,
    table_lines,
)
from qfg.harness.studies.mrclam.study import (
    STUDY,
    dataset_dirs,
    experiment_params,
    params_of,
    piece_tasks,
    prepared,
    remember,
    run_piece,
    run_record,
    run_task,
    summarize,
    tasks,
)

__all__ = [
    "run_dataset",
    "MrclamParams",
    "ParamError",
    "FIELDS",
    "PROPAGATIONS",
    "experiment_params",
    "params_of",
    "run_record",
    "summary",
    "kind_summary",
    "write_outputs",
    "make_figures",
    "dataset_dirs",
    "tasks",
    "run_task",
    "summarize",
    "STUDY",
    "DEFAULTS",
    "prepare",
    "histories",
    "table_lines",
    "arena_extent",
    "make_prior",
    "paper_history",
    "truncate",
    "views_curve",
    "decode",
    "curve_lines",
    "write_curve",
    "temper_scores",
    "AUTO_TEMPERS",
    "BEARING_CALIBRATIONS",
    "BEARING_TAILS",
    "CHUNK",
    "COMBINE",
    "DISTANCE_TAILS",
    "HEADING_SIGMA_BY_STEP",
    "HEADING_WALK",
    "HEADING_WALK_TAIL",
    "KINDS",
    "LATER_KEYS",
    "LightEstimate",
    "METHODS",
    "MODES",
    "PRIORS",
    "PRIOR_SAMPLES",
    "Prepared",
    "SCORES",
    "SOLVE_KEYS",
    "TABLE_KEY",
    "TEMPER_RULES",
    "choose_power",
    "choose_temper",
    "cross_pass_agreement",
    "drift_sigma_heading",
    "estimates_from_rows",
    "finish",
    "history_groups",
    "load_tensor",
    "map_name",
    "n_pieces",
    "piece_rows",
    "piece_tasks",
    "prepare_run",
    "prepared",
    "remember",
    "run_piece",
    "say_map_info",
    "score_map",
    "seen_estimates",
    "solve_piece",
    "spread",
    "walk_sigma_heading",
]
