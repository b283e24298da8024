"""The MRCLAM study's parameters: :class:`MrclamParams`, one frozen object holding every option
of a run on one dataset with its default, each documented once (in its field), checked when
made (:class:`ParamError` names the field). :func:`~qfg.harness.studies.mrclam.run_dataset`
takes it, ``qfg mrclam`` builds its options from its fields (:func:`cli_fields`) and ``qfg
experiment mrclam`` its parameters (:data:`DEFAULTS`).

>>> p = MrclamParams(robots=[4], method="fast", max_views=5)
>>> p.robots, p.map_method
((4,), 'pooled')
>>> for bad in ({"max_gap": 0}, {"propagation": "mean"}):
...     try:
...         MrclamParams(**bad)
...     except ParamError as exc:
...         print(exc)
max_gap: expected a number > 0, got 0
propagation: 'mean' is now called 'pooled' (CHANGELOG.md)
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Mapping

from qfg.harness.studies.mrclam.history import (
    BEARING_TAILS,
    DISTANCE_TAILS,
    HEADING_WALK,
    HEADING_WALK_TAIL,
    MODES,
    PRIORS,
)

COMBINE = ("prior-once", "geometric", "product")
#: single-triplet solvers; ``"none"``: no solver, every history's estimate the prior alone (for
#: map methods that work from the raw measurements, e.g. ``--map joint``)
METHODS = ("fast", "full", "baseline", "none")
KINDS = ("seen", "propagated", "camera")
#: Scores of every row, each also with the ``uniform_`` and ``prior_`` baselines.
SCORES = ("p_truth", "log_score", "brier", "gt_rating", "truth_under_1pct")
#: Samples behind each prior's state distribution (standard error <= 1.2e-3 per state).
PRIOR_SAMPLES = 200_000
#: Bearing calibrations: none, or each robot's bias and scale measured against motion capture
#: on dataset 6 (:mod:`qfg.datasets.mrclam._calibration`).
BEARING_CALIBRATIONS = ("none", "measured")
#: ``propagation``: pooled composition, or the paper's Algorithm 2.
PROPAGATIONS = ("pooled", "best")
#: ``temper`` rules of the check over histories: ``auto`` the power with the best agreement;
#: ``auto-1se`` the smallest power whose agreement is within one (cluster-robust) standard error
#: of the best, the one-standard-error rule: among powers the passes cannot tell apart, the most
#: cautious (chosen on the development sets, docs/results/mrclam.md).
TEMPER_RULES = ("auto", "auto-1se")
#: Histories solved per call (and per recorded piece of ``qfg mrclam``): only the (m,) vectors
#: are kept, piece by piece (an estimate may keep solver state; dataset 5 in one call once
#: exhausted 24 GB).
CHUNK = 128


def _camera_priors() -> tuple:
    from qfg.solvers.common.options import CAMERA_PRIORS

    return tuple(CAMERA_PRIORS)


def _map_methods() -> tuple:
    from qfg.harness.studies.mrclam.maps import MAP_METHODS

    return tuple(MAP_METHODS)


class ParamError(ValueError):
    """A bad value of one :class:`MrclamParams` field: ``field`` names it, ``problem`` says what
    is wrong (the message is ``"<field>: <problem>"``, one line)."""

    def __init__(self, name: str, problem: str):
        super().__init__(f"{name}: {problem}")
        self.field = name
        self.problem = problem


# ----------------------------------------------------------------------------- value checks
# Each takes a value and returns it normalized (tuples, floats, ints) or raises ValueError with
# the problem alone; MrclamParams puts the field's name in front.
def _number(lo=None, hi=None, *, above=False, what="a number"):
    def check(v):
        if isinstance(v, bool) or not isinstance(v, (int, float)) and not hasattr(v, "__float__"):
            raise ValueError(f"expected {what}, got {v!r}")
        x = float(v)
        if not math.isfinite(x) or (lo is not None and (x <= lo if above else x < lo)) or (
                hi is not None and x > hi):
            if lo is not None and hi is not None:
                want = f"{what} in [{lo:g}, {hi:g}]"
            elif lo is not None:
                want = f"{what} {'>' if above else '>='} {lo:g}"
            else:
                want = f"a finite {what.removeprefix('a ')}"
            raise ValueError(f"expected {want}, got {v:g}")
        return x
    return check


def _whole(lo: int):
    def check(v):
        if isinstance(v, bool) or int(v) != v or v < lo:
            raise ValueError(f"expected a whole number >= {lo}, got {v!r}")
        return int(v)
    return check


def _views(v):
    if isinstance(v, bool) or int(v) != v or v < 0 or v == 1:
        raise ValueError(f"expected 0 (every view) or an integer >= 2, got {v}")
    return int(v)


def _flag(v):
    if not isinstance(v, bool) and type(v).__name__ != "bool_":
        raise ValueError(f"expected true or false, got {v!r}")
    return bool(v)


def _text(v):
    if not isinstance(v, str):
        raise ValueError(f"expected a string, got {v!r}")
    return v


def _robots(v):
    if isinstance(v, (str, bytes)) or not hasattr(v, "__iter__"):
        raise ValueError(f"expected a list of robot numbers, got {v!r}")
    rs = tuple(v)
    if any(isinstance(r, bool) or int(r) != r for r in rs):
        raise ValueError(f"expected robot numbers, got {list(rs)!r}")
    rs = tuple(int(r) for r in rs)
    if any(r < 1 for r in rs):
        raise ValueError(f"expected robot numbers >= 1, got {list(rs)!r}")
    if len(set(rs)) != len(rs):
        raise ValueError(f"a robot named twice in {list(rs)!r}")
    return rs


def _temper(v):
    if isinstance(v, str):
        if v not in TEMPER_RULES:
            raise ValueError(f"expected a number in [0, 1], auto or auto-1se, got {v!r}")
        return v
    return _number(0.0, 1.0)(v)


def _map(v):
    if v != "" and v not in _map_methods():
        raise ValueError(f"expected '' or one of {_map_methods()}, got {v!r}")
    return v


def _option(default, doc: str, *, choices=None, check=None, renamed=None, phase="solve",
            later=False, flag=None, cli=True, cli_default=dataclasses.MISSING):
    """A field of :class:`MrclamParams` and its documentation.

    ``doc``: meaning, unit and allowed values (the field's docstring and its ``--help`` line);
    ``choices``: the allowed strings (a tuple, or a function giving them when asked);
    ``renamed``: {former value: new name}, refused with a line naming the new one; ``check``:
    value -> normalized value (ValueError with the problem); ``phase``: ``"solve"`` for the
    options that fix the solved estimates (a recorded piece depends on them), ``"map"`` for
    those after solving; ``later``: an option added after runs were recorded without it
    (left out of a run's record at its default); ``flag``: the ``qfg mrclam`` option
    (default ``--name-with-dashes``), ``cli=False`` for none; ``cli_default``: the command's
    default where it differs from the study's."""
    meta = {"doc": doc, "choices": choices, "check": check, "renamed": renamed or {},
            "phase": phase, "later": later, "flag": flag, "cli": cli,
            "cli_default": cli_default}
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class MrclamParams:
    """Every option of one MRCLAM run (one dataset directory), GTSAM-params style: make it with
    the options that differ from the defaults, pass it to :func:`run_dataset`; fields with
    lists are kept as tuples. Each field is checked when the object is made
    (:class:`ParamError` names the first bad one). The fields, with their defaults:
    """

    # ---- the histories and how they are solved (what fixes the solved estimates)
    robots: tuple = _option(
        (), "robot numbers whose histories are solved and scored (empty: every robot; the "
            "joint map fits every robot's measurements)", check=_robots)
    method: str = _option(
        "full", "single-triplet solver (robots without odometry get the baseline: the row's "
                "method); none: no solver, every estimate the prior alone (for a map from the "
                "raw measurements). qfg mrclam: none for such a map (--map joint; on a dataset "
                "without odometry, full when the joint solve, done first, cannot answer), "
                "else full", choices=METHODS, cli_default=None)
    mode: str = _option(
        "honest", "honest: the measured bearings and odometry; paper: bearings and headings "
                  "computed from motion capture (paper emulation; dataset 6)", choices=MODES)
    prior: str = _option(
        "arena", "arena: world-box prior on the arena's extent (the landmarks' and the robots' "
                 "area); arena-logscale: the same with every scale of each landmark pair "
                 "equally likely (for landmarks that stand in clusters); world: the "
                 "simulator's 6 x 7 m box", choices=PRIORS)
    partition: str = _option("edc", "the qualitative partition of the states", cli=False,
                             check=_text)
    fix_landmarks: bool = _option(
        True, "landmark pairs seen at each other's ground-truth position "
              "(qfg.datasets.mrclam.check_landmarks) swapped back before scoring (off: the "
              "ground truth as shipped)", check=_flag)
    min_travel: float = _option(
        0.02, "metres the robot moves between kept views of a pass (0.02: every view with "
              "motion)", check=_number(0.0))
    max_gap: float = _option(
        120.0, "seconds a triplet may go unseen within one pass (longer ends the pass)",
        check=_number(0.0, above=True))
    max_views: int = _option(
        0, "keep the first N views of each pass (0: all)", check=_views)
    spread_views: int = _option(
        3, "keep N views spread evenly over each pass, with the odometry's headings between "
           "them (0: all)", check=_views)
    sigma_bearing_deg: float = _option(
        0.0, "bearing sigma the solvers assume, degrees (0: the loader's 0.66, measured on "
             "dataset 6; with a bearing tail, its core)", check=_number(0.0))
    sigma_heading_deg: float = _option(
        0.0, "odometry heading sigma the solvers assume, degrees (0: the loader's 1.57, "
             "measured on dataset 6; docs/mrclam.md)", check=_number(0.0))
    distances: bool = _option(
        True, "the odometry's travelled distances go to the solvers (full, fast: a factor on "
              "ratios of consecutive step lengths; seen triplets of dataset 6 -1.16 with them, "
              "-1.21 without, docs/results/mrclam.md)", check=_flag)
    sigma_distance_ratio: float = _option(
        0.0, "noise of their log ratio the solvers assume (0: the loader's 0.074)",
        check=_number(0.0))
    bearing_tail: str = _option(
        "normal", "bearing-noise model of the solvers: normal (the loader's sigma), measured "
                  "(a normal core with a wider normal and a uniform outlier share, fitted to "
                  "dataset 6 against motion capture) or within-view (the same fitted within one "
                  "image; the per-image offset moved to the motion headings); docs/mrclam.md",
        choices=tuple(BEARING_TAILS), later=True)
    heading_drift: bool = _option(
        False, "heading sigma of each history from its longest step (the odometry's direction "
               "error by step duration, measured against motion capture: 1.6 deg at 6.5 s, "
               "5.0 at 20 s, 9.8 at 65 s)", check=_flag, later=True)
    distance_tail: str = _option(
        "normal", "noise model of the log ratio of consecutive odometry step lengths: normal "
                  "(sigma sigma_distance_ratio) or measured (a normal core of 0.092 with 8.8% "
                  "of the ratios from a normal 7.2x wider, fitted to dataset 6 against motion "
                  "capture; also the core sigma unless sigma_distance_ratio is given); "
                  "docs/mrclam.md", choices=tuple(DISTANCE_TAILS), later=True)
    camera_prior: str = _option(
        "point", "the cameras' prior in the solvers' intermediate weights: point (a product "
                 "of per-point priors) or joint (the prior of the cameras so far together: "
                 "closer to the exact posterior when a pass's cameras stay close together far "
                 "from the landmarks); docs/solvers.md", choices=_camera_priors, later=True)
    bearing_calibration: str = _option(
        "none", "measured: each robot's bearings corrected first by its bias and scale "
                "measured against motion capture on dataset 6 (robot 4: -0.8 deg and +3.9%, "
                "docs/mrclam.md); none: as recorded", choices=BEARING_CALIBRATIONS, later=True)
    budget: float = _option(
        1.0, "the full/fast solvers' sampling budget (n_samples, max_hypotheses, "
             "posterior_samples) times this factor, for about as many times the time: where a "
             "pass's cameras stay far from close landmarks the default budget was measured not "
             "to resolve 5 views (docs/solvers.md, \"The budget\")",
        check=_number(0.0, above=True, what="a factor"), later=True)
    populations: int = _option(
        1, "the full/fast solvers' independent SIS populations, each with its share of the "
           "budget, answers averaged (docs/solvers.md, 'Independent populations')",
        check=_whole(1), later=True)
    heading_walk: float = _option(
        0.0, "each step's heading sigma B sqrt(step seconds) degrees, B in deg / sqrt(s) (the "
             "odometry's heading as a random walk; 0: one sigma per history). qfg mrclam also "
             f"takes 'measured' ({HEADING_WALK}, fitted to dataset 6 against motion capture) "
             f"or 'measured-tail' ({HEADING_WALK_TAIL[0]} with {HEADING_WALK_TAIL[1][0]:.1%} of "
             f"the steps from a normal {HEADING_WALK_TAIL[1][1]}x wider, fitted the same way: "
             "heading_tail measured)", check=_number(0.0), later=True)
    heading_tail: str = _option(
        "normal", "measured: the solvers' headings get the two-normal tail of HEADING_WALK_TAIL "
                  "(qfg mrclam: --heading-walk measured-tail)", choices=("normal", "measured"),
        later=True, flag="--heading-walk", cli=False)
    model_check: float = _option(
        0.0, "level of the solvers' model check (full, fast): an answer whose bearings and "
             "headings get a posterior predictive p below it is widened toward the prior and "
             "flagged (0: reported only)", check=_number(0.0, 0.5), later=True)
    piece: int = _option(
        CHUNK, "histories solved and recorded together (piece c is solved with child c of the "
               "seed, so this is part of the run's identity)", check=_whole(1),
        flag="--piece-size")
    # ---- after solving: combine, map, propagate
    combine: str = _option(
        "geometric", "how several histories of one ordered triplet combine, at the state level "
                     "with the prior counted once: by the geometric mean of their likelihoods "
                     "(geometric) or as independent passes (prior-once); or the plain product "
                     "(product, the prior counted k times)", choices=COMBINE, phase="map")
    temper: float = _option(
        1.0, "temper each estimate's likelihood part by this power in [0, 1] before combining "
             "(1: none; docs/results/mrclam.md), or auto: the power under which the histories "
             "of each ordered triplet (passes, robots) agree best, a model check without ground "
             "truth; auto-1se: the smallest power that agrees within one standard error of the "
             "best", check=_temper, phase="map")
    map: str = _option(
        "", "map method by name (maps.MAP_METHODS); '': named by propagate and propagation. "
            "qfg mrclam: default DEFAULT_MAP (joint)", check=_map, phase="map", cli_default=None)
    propagate: bool = _option(
        True, "build the map and propagate (False: the seen triplets alone, map seen)",
        check=_flag, phase="map", cli=False)
    propagation: str = _option(
        "pooled", "the map method when map is '': pooled (pooled composition, every unseen "
                  "triplet the mean of its compositions from the nearest updated triplets) or "
                  "best (the paper's Algorithm 2, the sharpest proposal). qfg mrclam: the "
                  "former name of --map", choices=PROPAGATIONS, renamed={"mean": "pooled"},
        phase="map", cli_default=None)
    tensor: str = _option(
        "", "composition tensor .npz file ('': the shipped tensor of the partition)",
        check=_text, phase="map", cli_default=None)

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            try:
                new = _check(f, v)
            except ParamError:
                raise
            except (TypeError, ValueError) as exc:
                raise ParamError(f.name, str(exc)) from None
            if new is not v:
                object.__setattr__(self, f.name, new)
        if self.heading_drift and self.heading_walk:
            raise ParamError("heading_walk", "one heading model at a time (heading_drift is on)")

    # ------------------------------------------------------------------ derived and conversions
    @property
    def map_method(self) -> str:
        """The map method these options name: ``map`` when given; else ``"seen"`` without
        ``propagate``, else ``propagation`` (``"pooled"`` or ``"best"``)."""
        if self.map:
            return self.map
        return "seen" if not self.propagate else self.propagation

    def to_dict(self) -> dict:
        """Every field, JSON-ready (tuples as lists), in field order."""
        return {f.name: list(v) if isinstance(v, tuple) else v
                for f in dataclasses.fields(self) for v in (getattr(self, f.name),)}

    @classmethod
    def from_dict(cls, d: Mapping) -> "MrclamParams":
        """From a mapping of field values (a preset, a run's record); ParamError naming an
        unknown key."""
        unknown = sorted(set(d) - set(FIELDS))
        if unknown:
            raise ParamError(unknown[0], f"unknown option; known: {', '.join(FIELDS)}")
        return cls(**d)

    def replace(self, **changes) -> "MrclamParams":
        """A copy with ``changes`` (checked again)."""
        return dataclasses.replace(self, **changes)


def _check(f, v):
    m = f.metadata
    if m["renamed"] and v in m["renamed"]:
        raise ParamError(f.name, f"{v!r} is now called {m['renamed'][v]!r} (CHANGELOG.md)")
    choices = m["choices"]
    if choices is not None:
        allowed = choices() if callable(choices) else choices
        if v not in allowed:
            raise ParamError(f.name, f"expected one of {tuple(allowed)}, got {v!r}")
        return v
    return m["check"](v) if m["check"] is not None else v


FIELDS = tuple(f.name for f in dataclasses.fields(MrclamParams))
#: The options that fix the solved estimates (what a piece record depends on), with ``path``.
SOLVE_KEYS = ("path", *(f.name for f in dataclasses.fields(MrclamParams)
                        if f.metadata["phase"] == "solve"))
#: Options added after runs were recorded without them: a run's record leaves them out at their
#: defaults, so that those runs resume (``qfg mrclam --resume``) as before.
LATER_KEYS = tuple(f.name for f in dataclasses.fields(MrclamParams) if f.metadata["later"])
#: The parameters of ``qfg experiment mrclam`` with their defaults: ``data`` (the directory
#: holding MRCLAM_Dataset*; "": $QFG_MRCLAM_DIR), ``datasets`` (dataset numbers; empty: every
#: one found) and every :class:`MrclamParams` field.
DEFAULTS = {"data": "", "datasets": [], **MrclamParams().to_dict()}


def cli_fields() -> list:
    """The fields ``qfg mrclam`` has an option for, in field order: (field, flag, choices,
    default) with the choices asked now (map methods registered so far)."""
    out = []
    for f in dataclasses.fields(MrclamParams):
        m = f.metadata
        if not m["cli"]:
            continue
        flag = m["flag"] or "--" + f.name.replace("_", "-")
        ch = m["choices"]
        ch = ch() if callable(ch) else ch
        if f.name == "map":
            ch = _map_methods()
        default = f.default if m["cli_default"] is dataclasses.MISSING else m["cli_default"]
        out.append((f, flag, ch, default))
    return out


def flag_of(name: str) -> str:
    """The ``qfg mrclam`` option of field ``name`` (its own spelling, e.g. ``--piece-size``)."""
    f = {f.name: f for f in dataclasses.fields(MrclamParams)}.get(name)
    if f is None:
        return name
    return f.metadata["flag"] or "--" + name.replace("_", "-")


def _document():
    """The class docstring's field list, from the fields' documentation (written once)."""
    lines = []
    for f in dataclasses.fields(MrclamParams):
        ch = f.metadata["choices"]
        allowed = "" if ch is None or callable(ch) else f" One of {', '.join(ch)}."
        lines.append(f"    {f.name} = {f.default!r}: {f.metadata['doc']}.{allowed}")
    MrclamParams.__doc__ = (MrclamParams.__doc__ or "") + "\n" + "\n".join(lines) + "\n"


_document()
