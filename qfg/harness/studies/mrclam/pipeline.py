"""The MRCLAM study's phases for one dataset: :func:`prepare_run` (data, prior, histories),
:func:`solve_piece` per piece of :data:`CHUNK` histories (recorded exactly by :func:`piece_rows`,
read back by :func:`estimates_from_rows`), then :func:`finish`: the tempering power (given, or
chosen by the check over histories, :func:`choose_temper`), the histories of each ordered triplet
combined (:func:`seen_estimates`), the map method, the scores. :func:`run_dataset` runs them all
in memory."""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from qfg import metrics
from qfg.combine import (
    combine_posteriors,
    geometric_pool,
    prior_state_distribution,
    product_of_posteriors,
    temper,
)
from qfg.configurations import PositionSummary, summarize_position
from qfg.datasets import mrclam as _mrclam
from qfg.harness.studies.mrclam.history import (
    BEARING_TAILS,
    DISTANCE_TAILS,
    HEADING_WALK_TAIL,
    drift_sigma_heading,
    histories,
    make_prior,
    prepare,
    walk_sigma_heading,
)
from qfg.harness.studies.mrclam.params import (
    CHUNK,
    COMBINE,
    FIELDS,
    METHODS,
    PRIOR_SAMPLES,
    PROPAGATIONS,
    TEMPER_RULES,
    MrclamParams,
)
from qfg.harness.studies.mrclam.scoring import _camera_rows, score_map
from qfg.partitions import get as get_partition


@dataclass(frozen=True)
class LightEstimate:
    """One history's solved estimate, light: only what the study keeps of a solver's answer.

    ``landmark`` (m,): P(S^{AB:C} | H); ``cameras`` (n_views, m): each view's camera state;
    ``method``: the solver that answered (``"none"``: the prior alone); ``degenerate``: the
    solver flagged it; ``model_check``: the solver's model-check value (nan: none);
    ``position``: C's AB-frame position (:class:`qfg.configurations.PositionSummary`) or None.
    """

    landmark: np.ndarray
    cameras: np.ndarray
    method: str
    degenerate: bool
    model_check: float = float("nan")
    # C's AB-frame position (qfg.configurations.PositionSummary), kept for the histories whose
    # landmarks are in ascending order (one ordering per set and pass: the metric configuration
    # map's evidence); None for the others and for runs recorded before summaries were kept
    position: object = None


# ----------------------------------------------------------------------------- the pipeline
# run_dataset and ``qfg mrclam`` run the same phases: prepare_run (load, prior, histories),
# solve_piece for each piece of PIECE histories (``qfg mrclam`` records each piece as it
# finishes), then finish: temper, combine, map (a named method, maps), score.


@dataclass(frozen=True, eq=False)
class Prepared:
    """One dataset ready to solve: what :func:`prepare_run` made.

    ``histories``: (robot, history) pairs in solving order (robot-major); piece c of a run is
    histories ``[c * piece, (c + 1) * piece)``, solved with ``SeedSequence(seed,
    spawn_key=(c,))``. ``prior_states`` / ``prior_camera_states``: the state distributions of C
    and of a camera the prior alone gives (the ``prior_`` baselines, and tempering).
    """

    path: str
    dataset: object
    swaps: tuple
    prior: object
    partition: object
    prior_states: np.ndarray
    prior_camera_states: np.ndarray
    histories: list
    mode: str
    prior_name: str
    solver_options: dict = dataclasses.field(default_factory=dict)


def prepare_run(path, params: MrclamParams | None = None, *, dataset=None) -> Prepared:
    """Load (or take ``dataset``, loaded from ``path``), fix the landmark ground truth, make the
    prior and its state distributions, and the histories to solve (module docstring, steps
    1-4), with the solve options of ``params`` (:class:`MrclamParams`, default: its defaults).
    Every data file is read and checked here, before anything is solved."""
    p = MrclamParams() if params is None else params
    if not isinstance(p, MrclamParams):
        raise TypeError(f"params: expected a MrclamParams, got {type(p).__name__}")
    robots = list(p.robots) or None
    mode, prior, partition, fix_landmarks = p.mode, p.prior, p.partition, p.fix_landmarks
    min_travel, max_gap, max_views, spread_views = (p.min_travel, p.max_gap, p.max_views,
                                                    p.spread_views)
    sigma_bearing_deg, sigma_heading_deg = p.sigma_bearing_deg, p.sigma_heading_deg
    distances, sigma_distance_ratio = p.distances, p.sigma_distance_ratio
    bearing_tail, model_check, heading_drift = p.bearing_tail, p.model_check, p.heading_drift
    distance_tail, heading_walk, heading_tail = p.distance_tail, p.heading_walk, p.heading_tail
    camera_prior, budget, populations = p.camera_prior, p.budget, p.populations
    bearing_calibration = p.bearing_calibration
    part = get_partition(partition)
    if dataset is None:
        ds, swaps = prepare(path, fix_landmarks=fix_landmarks)
    else:
        swaps = tuple(tuple(int(x) for x in s) for s in
                      (_mrclam.check_landmarks(dataset).swaps if fix_landmarks else ()))
        ds = _mrclam.swap_landmarks(dataset, swaps) if swaps else dataset
    if bearing_calibration == "measured":
        ds = _mrclam.calibrate_bearings(ds, _mrclam.DEFAULT_BEARING_CALIBRATION)
    pr = make_prior(ds, prior)
    q_c = prior_state_distribution(pr, part, samples=PRIOR_SAMPLES, seed=1)
    q_x = prior_state_distribution(pr, part, point=1, n_cameras=1, samples=PRIOR_SAMPLES, seed=2)
    tail_sb, tail_sh, tail = BEARING_TAILS[bearing_tail]
    tail_sd, dtail = DISTANCE_TAILS[distance_tail]
    htail = HEADING_WALK_TAIL[1] if heading_tail == "measured" else None
    budget = float(budget)
    sigma_distance_ratio = sigma_distance_ratio or tail_sd
    sig = {}
    if tail_sb and not sigma_bearing_deg:
        sig["sigma_bearing"] = np.deg2rad(tail_sb)
    if tail_sh and not sigma_heading_deg:
        sig["sigma_heading"] = np.deg2rad(tail_sh)
    if sigma_bearing_deg:
        sig["sigma_bearing"] = np.deg2rad(float(sigma_bearing_deg))
    if sigma_heading_deg:
        sig["sigma_heading"] = np.deg2rad(float(sigma_heading_deg))
    rh = histories(ds, robots, mode=mode, max_views=max_views, spread_views=spread_views,
                   partition=part, min_travel=min_travel, max_gap=max_gap, **sig)
    if heading_drift:
        rh = [(r, dataclasses.replace(h, sigma_heading=drift_sigma_heading(h, h.sigma_heading))
               if h.has_motion else h) for r, h in rh]
    if heading_walk:
        rh = [(r, dataclasses.replace(h, sigma_heading=walk_sigma_heading(
            h, h.sigma_heading, heading_walk)) if h.has_motion and h.n_views > 1 else h)
              for r, h in rh]
    if not distances:
        rh = [(r, dataclasses.replace(h, distances=None)) for r, h in rh]
    elif sigma_distance_ratio:
        rh = [(r, dataclasses.replace(h, sigma_distance_ratio=float(sigma_distance_ratio)))
              for r, h in rh]
    return Prepared(path=str(Path(path)), dataset=ds, swaps=swaps, prior=pr, partition=part,
                    prior_states=q_c, prior_camera_states=q_x, histories=rh, mode=mode,
                    prior_name=prior,
                    solver_options={"bearing_tail": tail, "model_check": float(model_check),
                                    "distance_tail": dtail if distances else None,
                                    "heading_tail": htail,
                                    # only where set: runs without it solve as before
                                    "camera_prior": None if camera_prior == "point"
                                    else camera_prior,
                                    # a factor, turned into the solver's options in solve_piece
                                    "budget": None if budget == 1.0 else budget,
                                    "populations": None if populations == 1
                                    else int(populations)})


def n_pieces(prep: Prepared, piece: int = CHUNK) -> int:
    """How many pieces of ``piece`` histories the run has."""
    return -(-len(prep.histories) // int(piece))


def solve_piece(prep: Prepared, index: int, *, method: str = "full", seed=0, piece: int = CHUNK,
                **solver_options) -> list[LightEstimate]:
    """Solve piece ``index`` (histories ``[index * piece, (index + 1) * piece)``) with the
    random stream ``SeedSequence(seed, spawn_key=(index,))`` (= child ``index`` of
    ``SeedSequence(seed)``): the same numbers whether pieces are solved in one go, one by one,
    or some of them again after an interruption. Only the (m,) vectors are kept (an estimate
    may keep solver state; dataset 5 in one call once exhausted 24 GB)."""
    from qfg.solvers import solve_triplets

    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    hs = [h for _, h in prep.histories[index * piece:(index + 1) * piece]]
    if method == "none":
        return [LightEstimate(prep.prior_states.copy(), np.tile(prep.prior_camera_states, (h.n_views, 1)),
                       "none", False) for h in hs]
    ss = np.random.SeedSequence(int(seed), spawn_key=(int(index),))
    # the run's noise model and check (prepare_run), only where set: the solvers' defaults
    # otherwise (the baseline takes no model check)
    opts = {k: v for k, v in prep.solver_options.items() if v}
    budget = opts.pop("budget", None)
    if budget is not None:
        from qfg.solvers.common.options import scaled_budget

        opts.update(scaled_budget(method, budget))
    if method == "baseline":
        # no model check, and no odometry distances in its model
        opts.pop("model_check", None)
        opts.pop("distance_tail", None)
        opts.pop("heading_tail", None)
        opts.pop("camera_prior", None)
        opts.pop("populations", None)
    pairs = solve_triplets(hs, method=method, partition=prep.partition, seed=ss,
                           hypotheses=True, **dict(opts, **solver_options, prior=prep.prior))
    out = []
    for k, (h, (e, hyp)) in enumerate(zip(hs, pairs, strict=True)):
        pos = None
        if hyp is not None and _ascending(h.landmarks):
            pos = summarize_position(hyp, e.landmark, prep.prior, partition=prep.partition.name,
                                     seed=np.random.SeedSequence(int(seed),
                                                                 spawn_key=(int(index), k, 1)))
        out.append(LightEstimate(e.landmark, e.cameras, e.method, bool(e.degenerate),
                          float(getattr(e, "model_check", float("nan"))), pos))
    return out


def _ascending(landmarks) -> bool:
    """Whether a history's landmarks are in ascending order (its set's first ordering)."""
    a, b, c = (int(x) for x in landmarks)
    return a < b < c


def _exact(p) -> str:
    """A vector as text that reads back to the same floats (``repr``: shortest exact)."""
    return ";".join(repr(float(x)) for x in np.ravel(p))


def _unexact(text: str, shape=None) -> np.ndarray:
    a = np.array([float(x) for x in str(text).split(";")]) if text else np.zeros(0)
    return a.reshape(shape) if shape is not None else a


def piece_rows(prep: Prepared, index: int, ests: list[LightEstimate], piece: int = CHUNK) -> list[dict]:
    """The record of a solved piece: one row per history with its estimates written exactly
    (``landmark``: P(S^{AB:C} | H), m numbers; ``cameras``: the views' camera states, n_views x m,
    kept only when the capture gives them a truth to be scored against)."""
    rows = []
    for k, e in enumerate(ests):
        hk = index * piece + k
        r, h = prep.histories[hk]
        cams = h.truth.camera_states is not None
        rows.append({"history": hk, "robot": int(r), "A": int(h.landmarks[0]),
                     "B": int(h.landmarks[1]), "C": int(h.landmarks[2]),
                     "n_views": int(h.n_views), "method": e.method, "degenerate": e.degenerate,
                     "model_check": repr(float(e.model_check)),
                     "landmark": _exact(e.landmark),
                     "cameras": _exact(e.cameras) if cams else "",
                     "position": (json.dumps(e.position.to_dict()) if e.position is not None
                                  else "")})
    return rows


def estimates_from_rows(prep: Prepared, rows: list[dict]) -> list[LightEstimate]:
    """The solved estimates of every history back from piece records (:func:`piece_rows`);
    ValueError when the records do not cover the run's histories one by one."""
    by = {int(r["history"]): r for r in rows}
    n = len(prep.histories)
    if sorted(by) != list(range(n)):
        raise ValueError(f"records: {len(by)} solved histories recorded, the data give {n}: "
                         "the data changed since the run was recorded; pass --overwrite")
    m = prep.partition.n_states
    out = []
    for k in range(n):
        r = by[k]
        h = prep.histories[k][1]
        if (int(r["A"]), int(r["B"]), int(r["C"])) != tuple(int(x) for x in h.landmarks):
            raise ValueError(f"records: history {k} is of another triplet than the data give: "
                             "the data changed since the run was recorded; pass --overwrite")
        cams = (_unexact(r["cameras"], (h.n_views, m)) if r.get("cameras")
                else np.full((h.n_views, m), 1.0 / m))
        pos = r.get("position") or ""
        out.append(LightEstimate(_unexact(r["landmark"]), cams, str(r["method"]),
                          str(r["degenerate"]) == "True" or r["degenerate"] is True,
                          float(r.get("model_check", "nan")),
                          PositionSummary.from_dict(json.loads(pos)) if pos else None))
    return out


def _solver_of(ests) -> str:
    names = sorted({e.method for e in ests})
    return "none" if names == ["none"] else ",".join(n for n in names if n != "none")


#: Tempering powers the cross-pass check chooses from (``temper="auto"``), largest first.
AUTO_TEMPERS = (1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1)


def history_groups(prep: Prepared) -> dict:
    """{ordered triplet (landmark indices): [history index, ...]}."""
    ds = prep.dataset
    groups: dict[tuple, list[int]] = {}
    for k, (_, h) in enumerate(prep.histories):
        groups.setdefault(tuple(ds.landmark_index(h.landmarks).tolist()), []).append(k)
    return groups


def _history_pairs(groups: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(first, second, cluster index) of every pair of histories of one group; a cluster is an
    unordered landmark set (its orderings' histories share their measurements)."""
    pairs, keys = [], []
    for g, ks in groups.items():
        for i, a in enumerate(ks):
            for b in ks[i + 1:]:
                pairs.append((a, b))
                keys.append(tuple(sorted(g)))
    if not pairs:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty, empty
    a, b = np.array(pairs).T
    return a, b, np.unique(np.array(keys), axis=0, return_inverse=True)[1].ravel()


def _pair_agreements(P, a, b, q, tau: float) -> np.ndarray:
    """Per pair (a, b) of histories: ``log sum_s t_a t_b / q``, t tempered by ``tau``."""
    T = temper(np.asarray(P, dtype=float), q, tau)
    return np.log(np.sum(T[a] * T[b] / q, axis=1))


def cross_pass_agreement(P, groups: dict, q, tau: float) -> tuple[float, int]:
    """How well the histories of one ordered triplet (separate passes, other robots) predict
    each other once tempered by ``tau``: the mean over pairs (i, j) of histories of one group of

        log sum_s t_i(s) t_j(s) / q(s),   t = temper(p, q, tau),

    which is log P(D_j | D_i) / P(D_j) when the two passes are independent given the state and
    the tempered estimates are their posteriors (q the prior's state distribution). No ground
    truth enters. ``P`` (H, m) the histories' estimates; returns (mean, number of pairs); (0, 0)
    without a group of two.

    >>> q = np.full(4, 0.25)
    >>> P = np.array([[0.97, 0.01, 0.01, 0.01], [0.01, 0.97, 0.01, 0.01]])
    >>> a1, n = cross_pass_agreement(P, {(0, 1, 2): [0, 1]}, q, 1.0)
    >>> a0, _ = cross_pass_agreement(P, {(0, 1, 2): [0, 1]}, q, 0.0)
    >>> n, round(a1, 3), round(a0, 3)      # confident and contradicting: worse than the prior
    (1, -2.546, 0.0)
    """
    a, b, _ = _history_pairs(groups)
    if not a.size:
        return 0.0, 0
    return float(np.mean(_pair_agreements(P, a, b, q, tau))), int(a.size)




def choose_temper(prep: Prepared, ests: list[LightEstimate], taus=AUTO_TEMPERS,
                  rule: str = "auto") -> tuple[float, list]:
    """The model check over histories: the tempering power (of ``taus``) under which the
    histories of each ordered triplet agree best (:func:`cross_pass_agreement`). Passes that
    contradict each other under the model (each confident, on different states) choose a power
    below 1, which widens every estimate toward the prior; where they agree it stays 1. With
    ``rule="auto-1se"`` the smallest power within one standard error (:func:`qfg.metrics.clustered_se`, by
    unordered landmark set) of the best. Returns (the power, [(tau, agreement, pairs, se),
    ...]); 1 when no triplet has two histories."""
    P = np.array([e.landmark for e in ests], dtype=float)
    return choose_power(P, history_groups(prep), prep.prior_states, taus, rule)


def choose_power(P, groups: dict, q, taus=AUTO_TEMPERS, rule: str = "auto") -> tuple[float, list]:
    """:func:`choose_temper` on arrays: ``P`` (H, m) the histories' estimates, ``groups``
    {ordered triplet: [history index, ...]}, ``q`` (m,) the prior's state distribution."""
    if rule not in TEMPER_RULES:
        raise ValueError(f"rule: expected one of {TEMPER_RULES}, got {rule!r}")
    a, b, cid = _history_pairs(groups)
    if not a.size:
        return 1.0, [(float(t), 0.0, 0, 0.0) for t in taus]
    table = []
    for t in taus:
        ag = _pair_agreements(P, a, b, q, t)
        table.append((float(t), float(np.mean(ag)), int(ag.size), metrics.clustered_se(ag, cid)))
    if not table:
        return 1.0, table
    best = max(table, key=lambda r: (r[1], r[0]))
    if rule == "auto":
        return best[0], table
    ok = [r[0] for r in table if r[1] >= best[1] - best[3]]
    return min(ok), table


def seen_estimates(prep: Prepared, ests: list[LightEstimate], *, combine: str = "geometric",
                   temper: float = 1.0, seed: int = 0, tensor=None) -> tuple:
    """Temper each history's estimate, combine those of each ordered triplet (module docstring,
    step 5). Returns (:class:`~qfg.harness.studies.mrclam.maps.SeenEstimates`, the tempered
    estimates, ``{triplet: Combined}``)."""
    from qfg.harness.studies.mrclam.maps import SeenEstimates

    if combine not in COMBINE:
        raise ValueError(f"combine: expected one of {COMBINE}, got {combine!r}")
    ds, q_c, q_x = prep.dataset, prep.prior_states, prep.prior_camera_states
    if temper != 1:
        ests = [LightEstimate(_temper(e.landmark, q_c, temper), _temper(e.cameras, q_x, temper),
                       e.method, e.degenerate, e.model_check, e.position) for e in ests]
    groups = history_groups(prep)
    combined = {t: _combine(np.array([ests[k].landmark for k in ks]), q_c, combine)
                for t, ks in groups.items()}
    trip = np.array(sorted(combined), dtype=np.intp).reshape(-1, 3)
    m = prep.partition.n_states
    seen = SeenEstimates(
        dataset=ds, partition=prep.partition, triplets=trip,
        probabilities=np.array([combined[tuple(t)].probabilities for t in trip.tolist()],
                               dtype=float).reshape(-1, m),
        conflict=np.array([bool(combined[tuple(t)].conflict) for t in trip.tolist()], bool),
        estimates=np.array([e.landmark for e in ests], dtype=float).reshape(-1, m),
        groups=groups, prior_states=q_c, seed=int(seed),
        histories=lambda: list(prep.histories), tensor=tensor, prior=prep.prior,
        prior_camera_states=prep.prior_camera_states, solver=_solver_of(ests),
        positions={k: e.position for k, e in enumerate(ests) if e.position is not None},
        temper=float(temper))
    return seen, ests, combined


def say_map_info(name: str, info, say) -> None:
    """Tell the user which map answered and what it flagged: a fallback and why, bearings the
    joint fit found taken from on their landmark, the joint map's flags and, when it widened
    its covariance, by how much."""
    info = dict(info or {})
    by = info.get("answered_by", name)
    if by != name:
        say(f"map {name}: answered by {by}: {info.get('why', '')}")
        return
    close, out = int(info.get("too_close", 0)), int(info.get("too_close_dropped", 0))
    if close:
        say(f"map {name}: {close} bearing{'s' if close > 1 else ''} from poses the fit had put "
            f"on the landmark seen ({out} left out, the others kept once the poses moved off)")
    flags = info.get("flags") or []
    extra = ""
    if "overdispersion" in info:
        scale = float(info.get("covariance_scale", 1.0))
        why = (f"covariance x{scale:.2f}" if scale != 1.0 else "not widened: "
               + ("no more than it allows" if "kinematic_prior" in flags
                  else "every run has odometry"))
        extra = (f"the robots' own maps scatter {info['overdispersion']:.2f}x what its "
                 f"covariance allows ({why})")
    if flags:
        say(f"map {name}: flags {', '.join(flags)}" + (f"; {extra}" if extra else ""))
    elif extra:
        say(f"map {name}: {extra}")


def map_name(propagate: bool = True, propagation: str = "pooled", map_method: str = "") -> str:
    """The map method the older options name: ``propagate=False`` -> ``"seen"``;
    ``propagation`` ``"pooled"`` or ``"best"``; ``map_method`` wins
    (:attr:`MrclamParams.map_method`)."""
    if map_method:
        return map_method
    if not propagate:
        return "seen"
    if propagation == "mean":
        raise ValueError("propagation: 'mean' is now called 'pooled' (CHANGELOG.md)")
    if propagation not in PROPAGATIONS:
        raise ValueError(f"propagation: expected one of {PROPAGATIONS}, got {propagation!r}")
    return propagation


def finish(prep: Prepared, ests: list[LightEstimate], *, combine: str = "geometric",
           temper: float = 1.0, map_method: str = "pooled", tensor=None, seed: int = 0,
           say=None, record_dir=None, tensor_name: str = "") -> tuple[list[dict], dict]:
    """From the solved estimates to scored rows: temper, combine, the map method, scores of the
    map's rows and of the camera views. ``say``: a callable told each phase (progress);
    ``record_dir``: the map is recorded there (``maps/<name>.npz``) and a record made from the
    same inputs is used instead of making it again. Returns (rows, details)."""
    from qfg.harness.studies.mrclam import maps as mrclam_maps

    say = say or (lambda msg: None)
    method = mrclam_maps.get(map_method)
    temper_check = None
    if temper in TEMPER_RULES:
        rule = temper
        temper, temper_check = choose_temper(prep, ests, rule=rule)
        say(f"temper {rule}: the histories of one ordered triplet "
            f"{'agree best' if rule == 'auto' else 'agree within one standard error of the best'}"
            f" at {temper:g} ({temper_check[0][2] if temper_check else 0} pairs; agreement at 1: "
            f"{temper_check[0][1] if temper_check else 0:.3f}, at {temper:g}: "
            f"{dict((r[0], r[1]) for r in temper_check).get(temper, 0.0):.3f})")
    seen, ests, combined = seen_estimates(prep, ests, combine=combine, temper=temper, seed=seed,
                                          tensor=tensor)
    say(f"combined: {len(ests)} histories into {len(seen.triplets)} seen ordered triplets "
        f"({combine}{'' if temper == 1 else f', tempered {temper:g}'})")
    ds = prep.dataset
    swap_txt = ";".join(f"{a}-{b}" for a, b in prep.swaps)
    common = {"dataset": ds.name, "path": prep.path, "mode": prep.mode,
              "prior": prep.prior_name, "combine": combine, "temper": float(temper),
              "map": method.name, "gt_swaps": swap_txt}
    t0 = time.perf_counter()
    result = None
    rec = None
    if record_dir is not None:
        mrclam_maps.save_seen(Path(record_dir) / "seen.npz", seen, combine=combine,
                              temper=float(temper))
        digest = mrclam_maps.inputs_digest(method.name, seen, tensor_name)
        rec = Path(record_dir) / "maps" / f"{method.name}.npz"
        result = mrclam_maps.load_map(rec, digest)
        if result is not None:
            say(f"map {method.name}: {len(result.triplets)} triplets, as recorded in {rec}")
    if result is None:
        say(f"map {method.name}: {method.description} ...")
        if method.name == "joint":
            # solved here to tell its phases; the map finds the answer remembered
            mrclam_maps.joint_of(seen, progress=say)
        result = method.fn(seen)
        if rec is not None:
            mrclam_maps.save_map(rec, result, digest)
        n_prop = int(np.count_nonzero(~np.asarray(result.seen)))
        say(f"map {method.name}: {len(result.triplets)} triplets ({n_prop} not seen, "
            f"{int(np.count_nonzero(result.reached))} reached) in "
            f"{time.perf_counter() - t0:.1f} s")
    t_map = time.perf_counter() - t0
    say_map_info(method.name, result.info, say)
    rows = score_map(prep, seen, result, ests, common)
    if result.cameras is not None:  # the map answered the cameras too (e.g. the joint map)
        answered = str(result.info.get("camera_method", method.name))
        ests = [LightEstimate(e.landmark, np.asarray(c, dtype=float), answered, e.degenerate,
                       e.model_check, e.position)
                for e, c in zip(ests, result.cameras, strict=True)]
    rows += _camera_rows([h for _, h in prep.histories], prep.histories, ests,
                         prep.prior_camera_states, prep.partition, common)
    say(f"scores: {sum(r['kind'] == 'seen' for r in rows)} seen, "
        f"{sum(r['kind'] == 'propagated' for r in rows)} propagated, "
        f"{sum(r['kind'] == 'camera' for r in rows)} camera views")
    if rows:
        rows[0]["time_propagate_s"] = t_map
    return rows, {"dataset": ds, "swaps": prep.swaps, "histories": prep.histories,
                  "estimates": ests, "seen": seen, "map": result, "partition": prep.partition,
                  "prior": prep.prior, "prior_states": prep.prior_states,
                  "prior_camera_states": prep.prior_camera_states, "combined": combined,
                  "temper": float(temper), "temper_check": temper_check}


_temper = temper


def _combine(V, q, how):
    if how == "prior-once":
        return combine_posteriors(V, q)
    if how == "geometric":
        return geometric_pool(V, q)
    return product_of_posteriors(V)


def load_tensor(partition: str, path: str | None):
    """The composition tensor of ``partition``: the ``.npz`` file at ``path``, or the shipped one
    when ``path`` is empty or None (:func:`qfg.composition.load`, :func:`qfg.composition.tensor`)."""
    from qfg.composition import load, tensor

    return load(path, partition) if path else tensor(partition)


def run_dataset(path, params: MrclamParams | None = None, *, seed=0, tensor=None,
                return_details: bool = False, **solver_options):
    """Solve, combine, map, propagate and score one dataset directory, in memory (``qfg
    mrclam`` runs the same phases and records them: :func:`prepare_run`, :func:`solve_piece`
    per piece, :func:`finish`).

    Args:
        path: an MRCLAM dataset directory.
        params: every option of the run (:class:`MrclamParams`; None: its defaults).
        seed: solver seed (piece c of ``params.piece`` histories gets child c of
            ``SeedSequence(seed)``).
        tensor: the composition tensor ((m, m, m) array or CompositionTensor) instead of the
            file ``params.tensor`` names; None: that file, or the shipped tensor when it is ''.
        return_details: also return the details (dataset, histories, estimates, map, ...).
        **solver_options: further options of the single-triplet solvers
            (:data:`qfg.solvers.DEFAULTS`), e.g. ``n_samples``.

    Returns:
        rows (list of dicts; module docstring). With ``return_details``: ``(rows, details)``.
    """
    p = MrclamParams() if params is None else params
    if not isinstance(p, MrclamParams):
        raise TypeError(f"params: expected a MrclamParams, got {type(p).__name__}")
    ours = sorted(set(solver_options) & set(FIELDS))
    if ours:
        raise TypeError(f"run_dataset: {', '.join(ours)}: options of the run, give them in "
                        f"MrclamParams ({ours[0]}=...), CHANGELOG.md")
    name = p.map_method
    from qfg.harness.studies.mrclam import maps as mrclam_maps

    mrclam_maps.get(name)
    if tensor is None and p.tensor and name != "seen":
        tensor = load_tensor(p.partition, p.tensor)
    prep = prepare_run(path, p)
    t0 = time.perf_counter()
    ests = []
    for c in range(n_pieces(prep, p.piece)):
        ests += solve_piece(prep, c, method=p.method, seed=seed, piece=p.piece, **solver_options)
    t_solve = time.perf_counter() - t0
    rows, details = finish(prep, ests, combine=p.combine, temper=p.temper, map_method=name,
                           tensor=tensor, seed=int(seed))
    if rows:
        rows[0]["time_solve_s"] = t_solve
    if not return_details:
        return rows
    details["graph"] = None
    details["propagation"] = details["map"]
    return rows, details
