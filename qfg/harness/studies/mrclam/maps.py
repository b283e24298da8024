"""Map methods of the MRCLAM study: from the seen triplets' estimates to a qualitative map.

A *map method* is one named step of ``qfg mrclam`` (``--map NAME``) and of
:func:`qfg.harness.studies.mrclam.run_dataset` (``MrclamParams(map=NAME)``). It receives the solved and
combined estimates of the seen ordered triplets (:class:`SeenEstimates`) and returns the rows of
its map (:class:`MapResult`): the seen triplets, and any other triplets it estimates. The study
scores every row of a map with the same code (:func:`qfg.harness.studies.mrclam.score_map`),
against the landmark ground truth, which a map method never sees.

Registered here (:data:`MAP_METHODS`):

* ``"pooled"``: the full map (:func:`qfg.graph.full_map`, every ordered triplet), the combined
  estimates as priors, the rest by pooled composition (``qfg.propagate(g, method="pooled")``:
  every unseen triplet the mean of its compositions from the nearest updated triplets). This is
  ``propagation="pooled"``, the study's default (``--propagation pooled``).
* ``"best"``: the same map propagated by the paper's Algorithm 2
  (:func:`qfg.propagation.propagate`, the proposal with the best information score);
  ``--propagation best``.
* ``"seen"``: the seen triplets alone, as combined (no map; ``propagate=False``).

To add a method: write ``def my_map(seen: SeenEstimates) -> MapResult`` here (or anywhere that
is imported before the run) and call ``register("my-name", my_map, "one line")``. It may use
``seen.probabilities`` (the combined estimate of each seen triplet), ``seen.estimates`` with
``seen.groups`` (each history's own estimate, the histories of each triplet),
``seen.histories()`` (the (robot, history) pairs, rebuilt from the data: bearings, headings,
distances, view times), ``seen.dataset`` (the raw measurements: ``dataset.robot(r)``),
``seen.composition_tensor()`` and ``seen.seed``; not the dataset's landmark positions
(``dataset.landmark_xy``: the ground truth the map is scored against). ``qfg mrclam`` records
each method's map in ``<output>/maps/<name>.npz`` and uses the record again on ``--resume`` while
the seen estimates it was made from are unchanged (:func:`inputs_digest`).
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

__all__ = ["SeenEstimates", "MapResult", "MapMethod", "MAP_METHODS", "register", "get",
           "inputs_digest", "save_map", "load_map", "save_seen", "map_pooled", "map_best",
           "map_seen", "map_configurations", "map_configurations_metric", "state_evidence",
           "metric_evidence", "configuration_geometry",
           "map_seen_configurations", "map_seen_prior", "map_joint", "joint_answer", "joint_of",
           "joint_why",
           "JOINT_FALLBACK", "DEFAULT_MAP"]


@dataclass(frozen=True, eq=False)
class SeenEstimates:
    """What every map method starts from: the seen ordered triplets of one dataset, solved and
    combined (one row per seen triplet, sorted).

    Attributes:
        dataset: the :class:`qfg.datasets.mrclam.MRCLAMDataset` (landmark ground truth swapped
            back when the study found swapped pairs); ``landmark_ids`` names the landmarks.
        partition: the :class:`qfg.partitions.Partition` of the states (m states).
        triplets: (s, 3) int, each seen ordered triplet as landmark *indices* (into
            ``dataset.landmark_ids``), sorted.
        probabilities: (s, m), each seen triplet's combined estimate (rows sum to 1).
        conflict: (s,) bool, whether its histories' estimates conflict (:mod:`qfg.combine`).
        estimates: (H, m), each history's own estimate of C (after tempering), history order.
        groups: ``{triplet (tuple of 3 indices): [history numbers]}``.
        prior_states: (m,) the state distribution the prior alone gives.
        seed: an int for the method's own random numbers.
        histories: ``() -> list[(robot, history)]``, the solved histories in history order.
        tensor: the composition tensor to use (an array or CompositionTensor), or None for the
            shipped tensor of the partition (:meth:`composition_tensor`).
        prior: the world prior the solvers were given (a :class:`qfg.priors.WorldBoxPrior` or a
            name); ``prior_states`` is its state distribution.
        prior_camera_states: (m,) the state distribution of a camera the prior alone gives.
        solver: the single-triplet solver(s) behind the estimates (``"none"``: no solver ran, every
            estimate is the prior alone).
        positions: ``{history number: PositionSummary}``, C's AB-frame position from the solver's
            weighted samples (:func:`qfg.configurations.summarize_position`), for the histories
            whose landmarks are in ascending order (one ordering per set and pass); empty for
            runs recorded before summaries were kept.
        temper: the power the histories' estimates were tempered by (1: none).
    """

    dataset: object
    partition: object
    triplets: np.ndarray
    probabilities: np.ndarray
    conflict: np.ndarray
    estimates: np.ndarray
    groups: Mapping
    prior_states: np.ndarray
    seed: int
    histories: Callable[[], list]
    tensor: object = None
    prior: object = "world"
    prior_camera_states: np.ndarray | None = None
    solver: str = ""
    positions: Mapping = field(default_factory=dict)
    temper: float = 1.0

    def composition_tensor(self):
        """The composition tensor of the run (the shipped one unless ``--tensor`` gave one)."""
        if self.tensor is not None:
            return self.tensor
        from qfg.composition import tensor

        return tensor(self.partition.name)


@dataclass(frozen=True, eq=False)
class MapResult:
    """The rows of one map, every one scored.

    Attributes:
        triplets: (n, 3) int, landmark indices of each row's ordered triplet (no repeats); it
            must hold every seen triplet.
        probabilities: (n, m), each row's state distribution (normalized when scored).
        seen: (n,) bool, the row is a seen triplet (scored as kind ``"seen"``, else
            ``"propagated"``).
        reached: (n,) bool, an unseen row the method could estimate (False: left uniform).
        info: extras, JSON-able (recorded with the map).
        cameras: None, or one (n_views, m) array per history (history order): the camera states
            of the views, when the map answers them (they then replace the solvers' cameras).
    """

    triplets: np.ndarray
    probabilities: np.ndarray
    seen: np.ndarray
    reached: np.ndarray
    info: Mapping = field(default_factory=dict)
    cameras: tuple | None = None


@dataclass(frozen=True)
class MapMethod:
    """A registered map method: ``fn(seen) -> MapResult`` with a name and one line.
    ``needs_estimates``: False for a method that works from the raw measurements alone, so that
    ``qfg mrclam`` need not run the single-triplet solvers for it (``--method none``).
    ``whole_configurations``: True for a method that infers whole landmark configurations
    (:mod:`qfg.configurations`: landmarks i.i.d. in the box, so a pair-scale prior is refused)."""

    name: str
    fn: Callable[[SeenEstimates], MapResult]
    description: str
    needs_estimates: bool = True
    whole_configurations: bool = False


#: The map methods by name (``--map``).
MAP_METHODS: dict[str, MapMethod] = {}

#: ``qfg mrclam``'s map method when ``--map`` is not given. The rule: the map method with the
#: best mean log score over the seen and unseen triplets of MRCLAM datasets 1-6, as recorded in
#: docs/results/mrclam_maps.csv (``tests/test_mrclam_maps.py`` checks the two agree).
DEFAULT_MAP = "joint"



def register(name: str, fn: Callable[[SeenEstimates], MapResult], description: str, *,
             needs_estimates: bool = True, whole_configurations: bool = False) -> MapMethod:
    """Register ``fn`` as map method ``name`` (a new name; ValueError if taken)."""
    if not isinstance(name, str) or not name or name in MAP_METHODS:
        raise ValueError(f"name: expected a new map method name, got {name!r}")
    MAP_METHODS[name] = MapMethod(name, fn, description, bool(needs_estimates),
                                  bool(whole_configurations))
    return MAP_METHODS[name]


def get(name: str) -> MapMethod:
    """The map method called ``name``; ValueError naming ``--map`` and the known ones."""
    if name not in MAP_METHODS:
        raise ValueError(f"--map: expected one of {', '.join(MAP_METHODS)}, got {name!r}")
    return MAP_METHODS[name]


# ------------------------------------------------------------------------------- the methods
def _full_map_propagated(seen: SeenEstimates, rule: str) -> MapResult:
    from qfg.graph import full_map
    from qfg.propagation import propagate

    g = full_map(seen.dataset.landmark_ids.size, partition=seen.partition.name,
                 tensor=seen.composition_tensor(),
                 priors={tuple(t): p for t, p in zip(seen.triplets.tolist(), seen.probabilities,
                                                     strict=True)})
    res = propagate(g, method=rule)
    return MapResult(triplets=np.array(g.triplets, dtype=np.intp),
                     probabilities=np.asarray(res.probabilities, dtype=float),
                     seen=np.asarray(g.seen, dtype=bool),
                     reached=np.asarray(res.info["reached"], dtype=bool),
                     info={"rule": rule, "engine": res.method})


def map_pooled(seen: SeenEstimates) -> MapResult:
    """Every ordered triplet; the unseen ones by pooled composition
    (``qfg.propagate(g, method="pooled")``)."""
    return _full_map_propagated(seen, "pooled")


def map_best(seen: SeenEstimates) -> MapResult:
    """Every ordered triplet; the unseen ones by the paper's Algorithm 2
    (:func:`qfg.propagation.propagate`, best information score)."""
    return _full_map_propagated(seen, "best")


def all_ordered_triplets(n: int) -> np.ndarray:
    """(n (n - 1) (n - 2), 3) every ordered triplet of ``n`` landmarks (indices), in
    :func:`itertools.permutations` order."""
    import itertools

    return np.array(list(itertools.permutations(range(n), 3)), dtype=np.intp).reshape(-1, 3)


#: The configuration map's sampler options (beyond qfg.configurations.DEFAULTS): 4000 particles
#: and 8 sweeps per stage, because fewer left the sampler's populations in different places on a
#: whole MRCLAM map (the measurement: docs/configurations.md, "On MRCLAM").
CONFIG_OPTIONS = {"n_particles": 4000, "n_sweeps": 8}

#: ``widen`` of the configuration map (:meth:`qfg.configurations.ConfigurationPosterior.
#: marginals`) and its answer for triplets across groups of landmarks no seen triplet links
#: (``unlinked``), chosen with the likelihood's temper and floor on development datasets by the
#: mean log score over seen and unseen triplets (docs/configurations.md, "On MRCLAM").
#: ``unlinked="prior"`` because nothing measured ties such groups together: the world prior alone
#: would place them, and can place them confidently wrong.
CONFIG_WIDEN = 0.05
CONFIG_UNLINKED = "prior"

#: The leave-one-out check of the configuration map (:meth:`qfg.configurations.
#: ConfigurationPosterior.loo_check`): every row widened toward the prior when the seen triplets
#: predict each other worse than the prior alone: a safeguard against evidence that contradicts
#: itself.
CONFIG_CHECK = True


def map_configurations(seen: SeenEstimates, likelihood: str = "state") -> MapResult:
    """Every ordered triplet by configuration inference (:func:`qfg.configurations.
    configuration_marginals`): landmark configurations sampled from the solvers' prior, each seen
    landmark set weighting them by one ordering's combined estimate over the prior's state
    distribution (``likelihood="metric"``: by its passes' summaries of C's AB-frame position,
    :func:`metric_evidence`); every triplet, seen or not, is then read off the same samples."""
    if likelihood == "metric":
        return _configuration_map(seen, metric_evidence(seen), "metric")
    return _configuration_map(seen, state_evidence(seen), likelihood)


def state_evidence(seen: SeenEstimates) -> dict:
    """``{triplet: (m,) combined estimate}``, one ordering per seen landmark set
    (:func:`qfg.configurations.one_ordering_per_set`): the state likelihood's evidence."""
    from qfg.configurations import one_ordering_per_set

    return one_ordering_per_set({tuple(t): p for t, p in zip(seen.triplets.tolist(),
                                                              seen.probabilities, strict=True)})


def metric_evidence(seen: SeenEstimates) -> dict:
    """``{triplet: PositionSummary}``, one per seen landmark set (its ascending ordering): the
    summaries of its passes combined as independent evidence (:func:`qfg.configurations.
    combine_positions`, the run's tempering power on each pass's likelihood ratio), with the
    set's combined state estimate as the summary's states. ValueError when the run kept no
    summaries (recorded before they were, or solved with ``--method none``)."""
    from qfg.configurations import combine_positions

    if not seen.positions:
        raise ValueError("--map config-metric: the run's solved pieces keep no summaries of C's "
                         "position (recorded before qfg kept them, or --method none): solve "
                         "again with --overwrite and --method full, fast or baseline")
    row = {tuple(t): i for i, t in enumerate(seen.triplets.tolist())}
    out = {}
    for t in sorted(seen.groups):
        if not t[0] < t[1] < t[2]:
            continue
        summ = [seen.positions[k] for k in seen.groups[t] if k in seen.positions]
        if len(summ) != len(seen.groups[t]):
            raise ValueError(f"--map config-metric: {len(seen.groups[t]) - len(summ)} of the "
                             f"histories of triplet {t} keep no position summary")
        out[t] = combine_positions(summ, seen.prior, temper=seen.temper,
                                   states=seen.probabilities[row[t]],
                                   seed=np.random.SeedSequence(int(seen.seed), spawn_key=t))
    return out


def _configuration_map(seen: SeenEstimates, evidence: dict, likelihood: str) -> MapResult:
    from qfg.configurations import configuration_marginals

    seen_keys = {tuple(t) for t in seen.triplets.tolist()}
    wanted = all_ordered_triplets(seen.dataset.landmark_ids.size)
    res = configuration_marginals(evidence, prior=seen.prior, triplets=[tuple(t) for t in
                                                                        wanted.tolist()],
                                  partition=seen.partition.name, method=f"config-{likelihood}",
                                  seed=seen.seed, widen=CONFIG_WIDEN, unlinked=CONFIG_UNLINKED,
                                  check=CONFIG_CHECK, **CONFIG_OPTIONS)
    is_seen = np.array([tuple(t) in seen_keys for t in wanted.tolist()], bool)
    info = {k: v for k, v in res.info.items() if isinstance(v, (int, float, str, bool))}
    err = res.info.get("mc_error")
    if err is not None:
        info["mc_error_max"] = float(np.max(err))
    w = np.asarray(res.info.get("widened", np.zeros(len(wanted))))
    info["widened_half"] = float(np.mean(w > 0.5))   # share of rows mostly the prior
    info["unsettled"] = float(np.mean(res.info["unsettled"]))
    info["unlinked"] = float(np.mean(res.info.get("unlinked", np.zeros(len(wanted)))))
    chk = res.info.get("check")
    if chk is not None:
        info["check_widen"] = chk.widen
        info["check_mean_log_cpo"] = float(np.mean(chk.log_cpo)) if chk.log_cpo.size else 0.0
    info["map_geometry"] = configuration_geometry(res.info["configurations"],
                                                  seen.dataset.landmark_ids, seed=seen.seed)
    return MapResult(triplets=wanted, probabilities=np.asarray(res.probabilities, dtype=float),
                     seen=is_seen, reached=~is_seen, info={"likelihood": likelihood, **info})


def configuration_geometry(post, landmark_ids, *, samples: int = 300, seed: int = 0) -> dict:
    """What a figure of a configuration map needs, JSON-able (recorded with the map): the
    landmarks' ids (``landmark_ids[i]`` for the posterior's landmark index ``i``), ``samples``
    of its configurations (S, L, 2) in the prior's box (drawn without replacement from the
    particles when they are equally weighted, as after the final resampling, else by weight)
    and each landmark's connected component of the evidence (:meth:`qfg.configurations.
    ConfigurationPosterior.components`: landmarks in different components are placed by the
    prior alone relative to each other)."""
    ids = np.asarray(landmark_ids)
    X = np.asarray(post.positions, dtype=float)
    w = np.asarray(post.weights, dtype=float)
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(7,)))
    if np.allclose(w, w[0]):
        pick = rng.choice(len(X), size=min(int(samples), len(X)), replace=False)
    else:   # weighted particles (not resampled): draws by weight, repeats allowed
        pick = rng.choice(len(X), size=int(samples), replace=True, p=w / w.sum())
    return {"kind": "configurations",
            "landmark_ids": [int(ids[int(i)]) for i in post.landmarks],
            "samples": np.round(X[np.sort(pick)], 4).tolist(),
            "components": [int(c) for c in post.components()]}


def map_configurations_metric(seen: SeenEstimates) -> MapResult:
    """:func:`map_configurations` with the metric likelihood: each seen landmark set weights the
    configurations by its passes' summaries of C's AB-frame position (:func:`metric_evidence`)."""
    return map_configurations(seen, "metric")


def map_seen_configurations(seen: SeenEstimates) -> MapResult:
    """The seen triplets as the solvers' combined estimates, every other ordered triplet by
    configuration inference over them (:func:`map_configurations`)."""
    res = map_configurations(seen)
    rows = {tuple(t): v for v, t in enumerate(res.triplets.tolist())}
    P = np.array(res.probabilities, dtype=float)
    P[[rows[tuple(t)] for t in seen.triplets.tolist()]] = seen.probabilities
    return MapResult(res.triplets, P, res.seen, res.reached,
                     {**dict(res.info), "seen_rows": "solvers"})


def map_seen_prior(seen: SeenEstimates) -> MapResult:
    """The seen triplets as the solvers' combined estimates, every other ordered triplet the
    prior's state distribution (no map: what is known without composing anything)."""
    wanted = all_ordered_triplets(seen.dataset.landmark_ids.size)
    rows = {tuple(t): v for v, t in enumerate(wanted.tolist())}
    P = np.tile(np.asarray(seen.prior_states, dtype=float), (len(wanted), 1))
    idx = [rows[tuple(t)] for t in seen.triplets.tolist()]
    P[idx] = seen.probabilities
    is_seen = np.zeros(len(wanted), bool)
    is_seen[idx] = True
    return MapResult(triplets=wanted, probabilities=P, seen=is_seen, reached=~is_seen,
                     info={"seen_rows": "solvers", "unseen_rows": "prior"})


#: The map method that answers for the joint map when no robot of the run has odometry: the
#: seen triplets from the solvers and the prior alone for the rest. Without odometry nothing ties
#: the passes' estimates into one frame, and configuration inference there put unseen triplets
#: below the prior alone (docs/configurations.md), so the map answers only what was seen.
JOINT_FALLBACK = "seen-prior"


#: The last :func:`joint_answer` (its inputs' digest, the dataset object and the answer).
_JOINT_MEMO: dict = {}


def joint_answer(dataset, histories, *, prior_states, camera_prior_states, partition: str,
                 seed: int, progress=None):
    """:func:`qfg.datasets.mrclam.joint_map.mrclam_marginals` of every ordered triplet of
    ``dataset``'s landmarks and the cameras of ``histories``, remembered for the last inputs:
    ``qfg mrclam`` solves the joint map first on a dataset without odometry (to know whether
    the solvers must run for its fallback), and the map step then uses the same answer instead
    of solving again.
    ``progress``: told each phase of the solve (not part of the inputs remembered)."""
    from qfg.datasets.mrclam.joint_map import mrclam_marginals

    h = hashlib.sha256()
    for x in histories:
        h.update(np.int64(int(x.robot)).tobytes())
        h.update(np.ascontiguousarray(x.views, dtype=np.float64).tobytes())
        h.update(np.ascontiguousarray(x.landmarks, dtype=np.int64).tobytes())
    for a in (prior_states, camera_prior_states):
        h.update(b"-" if a is None else np.ascontiguousarray(a, dtype=np.float64).tobytes())
    h.update(repr((str(partition), int(seed))).encode())
    key = h.hexdigest()
    if _JOINT_MEMO.get("key") == key and _JOINT_MEMO.get("dataset") is dataset:
        return _JOINT_MEMO["answer"]
    ids = np.asarray(dataset.landmark_ids)
    subjects = [tuple(int(x) for x in ids[t]) for t in all_ordered_triplets(ids.size).tolist()]
    j = mrclam_marginals(dataset, triplets=subjects, histories=list(histories),
                         prior_states=prior_states, camera_prior_states=camera_prior_states,
                         partition=partition, seed=seed, progress=progress)
    _JOINT_MEMO.clear()
    _JOINT_MEMO.update(key=key, dataset=dataset, answer=j)
    return j


def joint_of(seen: SeenEstimates, progress=None):
    """:func:`joint_answer` for the histories and prior states of ``seen`` (what
    :func:`map_joint` answers from)."""
    return joint_answer(seen.dataset, [h for _, h in seen.histories()],
                        prior_states=seen.prior_states,
                        camera_prior_states=seen.prior_camera_states,
                        partition=seen.partition.name, seed=seen.seed, progress=progress)


def joint_why(j) -> str:
    """Why a joint answer (:func:`joint_answer`) could not answer: its flags and robots."""
    post = j.posterior
    return (f"{', '.join(post.flags) or 'no map'}; robots: "
            f"{', '.join(f'{r} {f}' for r, f in sorted(post.robot_flags.items()))}")


def map_joint(seen: SeenEstimates) -> MapResult:
    """Every ordered triplet and every history's cameras from one joint posterior over the
    landmark positions and robot poses, fitted on GTSAM to every bearing and the odometry of
    every robot of the dataset (:func:`qfg.datasets.mrclam.joint_map.mrclam_marginals`;
    robots without odometry by the kinematic prior, :mod:`qfg.joint.start`); the seen
    estimates are not used, and the histories chosen (``--robots``) only set which triplets
    count as seen and which cameras are scored. When the joint solve cannot answer (e.g. a
    lone robot without odometry, or robots without odometry whose maps disagree) the map is
    :data:`JOINT_FALLBACK` over the solvers' estimates, and ``info["answered_by"]`` and
    ``info["why"]`` say so."""
    ds = seen.dataset
    ids = np.asarray(ds.landmark_ids)
    wanted = all_ordered_triplets(ids.size)
    subjects = [tuple(int(x) for x in ids[t]) for t in wanted.tolist()]
    j = joint_of(seen)
    if j.method == "none":
        why = f"the joint solve could not answer ({joint_why(j)})"
        if seen.solver == "none":
            raise ValueError(f"--map joint on {ds.name}: {why}, so the map falls back to "
                             f"{JOINT_FALLBACK} over the solvers' estimates: run with --method "
                             "full (or fast, baseline)")
        res = MAP_METHODS[JOINT_FALLBACK].fn(seen)
        return MapResult(res.triplets, res.probabilities, res.seen, res.reached,
                         {**dict(res.info), "answered_by": JOINT_FALLBACK, "why": why})
    is_seen = np.zeros(len(wanted), bool)
    rows = {tuple(t): v for v, t in enumerate(wanted.tolist())}
    is_seen[[rows[tuple(t)] for t in seen.triplets.tolist()]] = True
    post = j.posterior
    info = {"answered_by": "joint", "time_s": float(j.time_s), "camera_method": "joint",
            "flags": list(post.flags), "modes": len(post.modes),
            "robot_flags": {str(r): str(f) for r, f in post.robot_flags.items()},
            "landmark_flags": dict(zip(map(str, post.landmark_ids), post.landmark_flags,
                                          strict=True))}
    for key in ("overdispersion", "covariance_scale", "too_close", "too_close_dropped",
                "outliers_dropped"):
        v = post.info.get(key)
        if v is not None and np.isfinite(v):
            info[key] = float(v)
    info["map_geometry"] = joint_geometry(post, seed=seen.seed)
    P = np.array([j.triplets[t] for t in subjects], dtype=float).reshape(len(wanted), -1)
    return MapResult(triplets=wanted, probabilities=P,
                     seen=is_seen, reached=~is_seen, info=info,
                     cameras=tuple(np.asarray(c, dtype=float) for c in j.cameras))


def joint_geometry(post, *, samples: int = 2000, seed: int = 0, max_path: int = 1500) -> dict:
    """What a figure of a joint map needs, JSON-able (recorded with the map): the landmarks'
    ids, flags, gauge-free means (L, 2) and covariances (L, 2, 2) in the map frame
    (:func:`qfg.joint.landmark_moments`; NaN where unconstrained), each solved robot's
    keyframe positions (at most ``max_path`` of them, evenly thinned) in the same frame, the
    robots' measured scatter about the map (``overdispersion``, :func:`qfg.joint.overdispersion`)
    and the factor the map's covariance was already widened by (``covariance_scale``)."""
    from qfg.joint import landmark_moments

    mu, cov = landmark_moments(post, samples, seed)
    paths = {}
    for r, X in sorted(post.poses.items()):
        X = np.asarray(X, dtype=float)[:, :2]
        X = X[np.isfinite(X).all(axis=1)]
        if len(X):
            paths[str(r)] = np.round(X[::-(-len(X) // max_path)], 4).tolist()
    return {"landmark_ids": [int(x) for x in post.landmark_ids],
            "landmark_flags": [str(f) for f in post.landmark_flags],
            "mean": np.round(mu, 6).tolist(), "covariance": cov.tolist(),
            "robot_flags": {str(r): str(f) for r, f in post.robot_flags.items()},
            "paths": paths,
            "overdispersion": float(post.info.get("overdispersion", float("nan"))),
            "covariance_scale": float(post.info.get("covariance_scale", 1.0))}


def map_seen(seen: SeenEstimates) -> MapResult:
    """The seen triplets alone, as combined."""
    s = len(seen.triplets)
    return MapResult(triplets=np.asarray(seen.triplets, dtype=np.intp).reshape(-1, 3),
                     probabilities=np.asarray(seen.probabilities, dtype=float).reshape(
                         s, seen.partition.n_states),
                     seen=np.ones(s, bool), reached=np.zeros(s, bool))


register("pooled", map_pooled, "full map, unseen triplets by pooled composition (the paper's "
         "pipeline with the pooled rule)")
register("best", map_best, "full map, unseen triplets by the paper's Algorithm 2")
register("seen", map_seen, "the seen triplets alone (no map)")
register("config-state", map_configurations,
         "every triplet by configuration inference over the seen estimates (qfg.configurations; "
         "it shares their systematic errors and can be confidently wrong where they agree on a "
         "wrong configuration, as on MRCLAM datasets 2 and 5: docs/configurations.md)",
         whole_configurations=True)
register("config-metric", map_configurations_metric,
         "every triplet by configuration inference over the seen sets' summaries of C's "
         "AB-frame position (qfg.configurations, metric likelihood)", whole_configurations=True)
register("seen-config", map_seen_configurations,
         "seen triplets as the solvers combined them, the others by configuration inference",
         whole_configurations=True)
register("seen-prior", map_seen_prior,
         "seen triplets as the solvers combined them, the others the prior's state distribution")
register("joint", map_joint, "every triplet and camera from one joint posterior over landmarks "
         "and poses, fitted on GTSAM to all bearings and odometry (qfg.joint)",
         needs_estimates=False)


#: map methods made by configuration inference (their records depend on its options; the joint
#: map's too when its fallback, :data:`JOINT_FALLBACK`, is one of them)
_CONFIG_MAPS = ("config-state", "config-metric", "seen-config")


# ------------------------------------------------------------------------------- records
def inputs_digest(name: str, seen: SeenEstimates, tensor_name: str = "") -> str:
    """A digest of what a map is made from: the method, the seen triplets, their estimates and
    the tensor's name (a recorded map is used again only under the same digest)."""
    h = hashlib.sha256()
    h.update(name.encode())
    if name == "joint":        # the joint map answers by its fallback without odometry
        h.update(JOINT_FALLBACK.encode())
    if name in _CONFIG_MAPS or (name == "joint" and JOINT_FALLBACK in _CONFIG_MAPS):
        # a recorded configuration map is stale once its options change
        h.update(repr((sorted(CONFIG_OPTIONS.items()), CONFIG_WIDEN, CONFIG_UNLINKED,
                       CONFIG_CHECK)).encode())
    h.update(tensor_name.encode())
    h.update(np.ascontiguousarray(seen.triplets, dtype=np.int64).tobytes())
    h.update(np.ascontiguousarray(seen.probabilities, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(seen.estimates, dtype=np.float64).tobytes())
    if name == "config-metric":   # made from the position summaries too
        h.update(repr(float(seen.temper)).encode())
        for k in sorted(seen.positions):
            p = seen.positions[k]
            h.update(np.int64(k).tobytes())
            for a in (p.centres, p.log_weights, p.bandwidth, np.array([p.ess])):
                h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()


def save_map(path, result: MapResult, digest: str) -> Path:
    """Write ``result`` to ``path`` (.npz) atomically (a temporary file in the folder, renamed)."""
    import json

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    cams = {}
    if result.cameras is not None:  # ragged: stacked rows and each history's row count
        cams = {"camera_rows": np.array([len(c) for c in result.cameras], dtype=np.int64),
                "cameras": np.concatenate([np.asarray(c, float) for c in result.cameras])
                if len(result.cameras) else np.zeros((0, result.probabilities.shape[1]))}
    with open(tmp, "wb") as fh:
        np.savez(fh, triplets=result.triplets, probabilities=result.probabilities,
                 seen=result.seen, reached=result.reached, digest=np.array(digest),
                 info=np.array(json.dumps(dict(result.info), default=str)), **cams)
    os.replace(tmp, path)
    return path


def save_seen(path, seen: SeenEstimates, **extra) -> Path:
    """Write the seen estimates to ``path`` (.npz, atomically), for work outside the pipeline:
    ``triplets`` (s, 3) landmark indices and ``triplet_ids`` (s, 3) their subject numbers,
    ``probabilities`` (s, m), ``conflict`` (s,), ``estimates`` (H, m) with ``history_row`` (H,)
    (the row of each history's triplet), ``prior_states`` (m,), ``landmark_ids``, and ``extra``
    (scalars: e.g. ``combine``, ``temper``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    row = {tuple(t): i for i, t in enumerate(seen.triplets.tolist())}
    hist_row = np.full(len(seen.estimates), -1, dtype=np.int64)
    for t, ks in seen.groups.items():
        hist_row[list(ks)] = row[tuple(t)]
    ids = np.asarray(seen.dataset.landmark_ids)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as fh:
        np.savez(fh, triplets=seen.triplets, triplet_ids=ids[seen.triplets].reshape(-1, 3),
                 probabilities=seen.probabilities, conflict=seen.conflict,
                 estimates=seen.estimates, history_row=hist_row,
                 prior_states=seen.prior_states, landmark_ids=ids,
                 **{k: np.array(v) for k, v in extra.items()})
    os.replace(tmp, path)
    return path


def load_map(path, digest: str) -> MapResult | None:
    """The map recorded at ``path`` if it was made from inputs with ``digest``, else None (also
    for a missing or unreadable record: the map is then made again)."""
    import json

    path = Path(path)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["digest"]) != digest:
                return None
            cameras = None
            if "camera_rows" in z.files:
                n = z["camera_rows"]
                cameras = tuple(np.split(z["cameras"], np.cumsum(n)[:-1])) if n.size else ()
            return MapResult(triplets=z["triplets"], probabilities=z["probabilities"],
                             seen=z["seen"], reached=z["reached"], cameras=cameras,
                             info=json.loads(str(z["info"])))
    except (OSError, ValueError, KeyError):
        return None
