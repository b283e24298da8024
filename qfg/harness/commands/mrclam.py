"""``qfg mrclam PATH``: the MRCLAM study on one dataset directory (paper section 6d).

What it guarantees (docs/mrclam.md, "The command"):

* **Checked up front.** Every option value, the dataset folder and every data file of the
  dataset are checked before anything is solved or written: a bad value, the folder above the
  datasets, a folder that is not a dataset or a damaged file ends the command with one line
  naming the option (in its command-line spelling) or the file and line, exit status 2, and
  nothing written.
* **Visible.** Each phase says what it did on stderr: loading, histories, solving (a bar),
  combining, the map, scores.
* **Recorded in pieces.** The histories are solved in pieces of ``--piece-size`` (128), each
  recorded in ``records.jsonl`` as it finishes (the run is a runner run, one scenario per piece:
  :func:`qfg.harness.runner.run_study`); Ctrl-C keeps finished pieces and ``--resume`` solves only
  the rest. Piece c is solved with ``SeedSequence(seed, spawn_key=(c,))``, so an interrupted and
  resumed run writes the same ``triplets.csv`` as one that ran through. The map is recorded too
  (``maps/<name>.npz``); ``--resume`` with another ``--map``, ``--combine`` or ``--temper`` reuses
  the solved pieces (the run's identity, ``run.json``, is what fixes the solved estimates).
* **The output folder** follows the rules of ``qfg experiment``: a used folder needs ``--resume``
  or ``--overwrite``; it is locked while running.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from qfg.harness.commands import add_format, seed_int

#: The map methods ``--map`` accepts (the registry of :mod:`qfg.harness.studies.mrclam.maps`).
_PROPAGATION_MAP = {"mean": "pooled", "best": "best"}


def _int_list(text: str, option: str = "--robots") -> list[int]:
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"{option}: expected comma-separated integers, got {text!r}") from None


def _one_line_error(parser):
    """argparse's error as one line (``qfg mrclam: error: ...``, exit 2), not usage + message."""

    def error(message):
        parser.exit(2, f"qfg mrclam: error: {message} (qfg mrclam --help)\n")

    return error


def register(sub):
    from qfg.harness.studies.mrclam.maps import MAP_METHODS

    p = sub.add_parser("mrclam", help="solve, map, propagate and score one MRCLAM dataset",
                       description="The qualitative map of one dataset (every ordered "
                                   "landmark triplet and every camera view), made by a map "
                                   "method (--map; by default one joint posterior from all "
                                   "bearings and odometry), scored against the landmark ground "
                                   "truth beside uniform and the prior alone "
                                   "(docs/results/mrclam.md). Maps made from single-triplet "
                                   "solves solve each history and combine those of one ordered "
                                   "triplet first. Options and data are checked before anything "
                                   "runs; the solving is recorded in pieces (Ctrl-C, then "
                                   "--resume, continues).")
    p.error = _one_line_error(p)
    p.add_argument("path", help="an MRCLAM_DatasetN directory")
    p.add_argument("--robots", default="", help="comma-separated robot numbers whose histories "
                   "are solved and scored (default: all; the joint map fits every robot's "
                   "measurements)")
    p.add_argument("--method", default=None, choices=("fast", "full", "baseline", "none"),
                   help="single-triplet solver (robots without odometry: baseline); none: no "
                        "solver (for a map from the raw measurements). Default: none for such a "
                        "map (--map joint; on a dataset without odometry, full when the joint "
                        "solve, done first, cannot answer), else full")
    from qfg.harness.studies.mrclam.maps import DEFAULT_MAP

    p.add_argument("--map", default=None, choices=tuple(MAP_METHODS),
                   help=f"map method (default {DEFAULT_MAP}: the best mean log score over the "
                        "seen and unseen triplets of datasets 1-6, docs/results/mrclam.md): "
                        + "; ".join(f"{m.name}: {m.description}" for m in MAP_METHODS.values()))
    p.add_argument("--propagation", default=None, choices=tuple(_PROPAGATION_MAP),
                   help="former name of --map: mean = --map pooled, best = --map best")
    p.add_argument("--mode", default="honest", choices=("honest", "paper"),
                   help="honest: measured bearings and odometry (default); paper: bearings and "
                        "headings from motion capture (paper emulation; dataset 6)")
    p.add_argument("--prior", default="arena", choices=("arena", "world", "arena-logscale"),
                   help="world-box prior on the arena's extent (default), the same with every "
                        "scale of each landmark pair equally likely (arena-logscale: for "
                        "landmarks that stand in clusters), or the simulator's box")
    p.add_argument("--combine", default="geometric",
                   choices=("prior-once", "geometric", "product"),
                   help="how several histories of one ordered triplet combine, at the state level "
                        "with the prior counted once: by the geometric mean of their likelihoods "
                        "(default) or as independent passes (prior-once); or the plain product")
    p.add_argument("--min-travel", type=float, default=0.02,
                   help="metres between kept views of a pass (default 0.02: every view with motion)")
    p.add_argument("--max-gap", type=float, default=120.0,
                   help="seconds a triplet may go unseen within one pass (default 120)")
    p.add_argument("--max-views", type=int, default=0,
                   help="keep the first N views of each pass (default 0: all)")
    p.add_argument("--spread-views", type=int, default=3,
                   help="keep N views spread evenly over each pass (default 3; 0: all)")
    p.add_argument("--distances", action=argparse.BooleanOptionalAction, default=True,
                   help="use the odometry's travelled distances (a factor on ratios of "
                        "consecutive step lengths; default on: seen triplets of dataset 6 -1.16 vs -1.21)")
    p.add_argument("--sigma-bearing-deg", type=float, default=0.0,
                   help="bearing sigma the solvers assume, degrees (default 0: the loader's "
                        "0.66, measured on dataset 6; with a bearing tail, its core)")
    p.add_argument("--sigma-heading-deg", type=float, default=0.0,
                   help="odometry heading sigma the solvers assume, degrees (default 0: the "
                        "loader's 1.57, measured on dataset 6; docs/mrclam.md)")
    p.add_argument("--sigma-distance-ratio", type=float, default=0.0,
                   help="noise of their log ratio (default 0: the loader's 0.074)")
    p.add_argument("--bearing-tail", default="normal", choices=("normal", "measured",
                                                                 "within-view"),
                   help="bearing-noise model of the solvers: normal (the loader's sigma, "
                        "default), measured (a normal core with a wider normal and a uniform "
                        "outlier share, fitted to dataset 6 against motion capture) or "
                        "within-view (the same fitted within one image; the per-image offset "
                        "moved to the motion headings); docs/mrclam.md")
    p.add_argument("--distance-tail", default="normal", choices=("normal", "measured"),
                   help="noise model of the log ratio of consecutive odometry step lengths: "
                        "normal (sigma --sigma-distance-ratio, default the loader's 0.074) or "
                        "measured (a normal core of 0.092 with 8.8%% of the ratios from a normal "
                        "7.2x wider, fitted to dataset 6 against motion capture); docs/mrclam.md")
    p.add_argument("--camera-prior", default="point", choices=("point", "joint"),
                   help="the cameras' prior in the solvers' intermediate weights: point (a "
                        "product of per-point priors, default) or joint (the prior of the "
                        "cameras so far together: closer to the exact posterior when a pass's "
                        "cameras stay close together far from the landmarks); docs/solvers.md")
    p.add_argument("--bearing-calibration", default="none", choices=("none", "measured"),
                   help="each robot's bearings corrected first by its bias and scale measured "
                        "against motion capture on dataset 6 (measured; robot 4: -0.8 deg and "
                        "+3.9%%, docs/mrclam.md) or as recorded (none, default)")
    p.add_argument("--populations", type=int, default=1,
                   help="the full/fast solvers' independent SIS populations, each with its "
                        "share of the budget, answers averaged (default 1; docs/solvers.md, "
                        "'Independent populations')")
    p.add_argument("--budget", type=float, default=1.0,
                   help="the full/fast solvers' sampling budget (n_samples, max_hypotheses, "
                        "posterior_samples) times this factor, for about as many times the "
                        "time: where a pass's cameras stay far from close landmarks the default "
                        "budget was measured not to resolve 5 views (docs/solvers.md, \"The "
                        "budget\"); default 1")
    p.add_argument("--heading-walk", default="0",
                   help="each step's heading sigma B sqrt(step seconds) degrees (the odometry's "
                        "heading as a random walk): B a number, 'measured' (1.21, fitted to "
                        "dataset 6 against motion capture) or 'measured-tail' (0.85 with 4.6%% "
                        "of the steps from a normal 4.84x wider, fitted the same way); default "
                        "0: one sigma per history")
    p.add_argument("--model-check", type=float, default=0.0,
                   help="level of the solvers' model check (full, fast): an answer whose "
                        "bearings and headings get a posterior predictive p below it is widened "
                        "toward the prior and flagged (default 0: reported only)")
    p.add_argument("--heading-drift", action=argparse.BooleanOptionalAction, default=False,
                   help="heading sigma of each history from its longest step (the odometry's "
                        "direction error by step duration, measured against motion capture: "
                        "1.6 deg at 6.5 s, 5.0 at 20 s, 9.8 at 65 s); default off")
    p.add_argument("--temper", type=_temper_arg, default=1.0,
                   help="temper each estimate's likelihood part by this power in [0, 1] before "
                        "combining (default 1: none; docs/results/mrclam.md), or auto: the "
                        "power under which the histories of each ordered triplet (passes, "
                        "robots) agree best, a model check without ground truth; auto-1se: "
                        "the smallest power that agrees within one standard error of the best")
    p.add_argument("--curve", default="",
                   help="comma-separated view caps (0 = all), e.g. 3,5,8,0: also score the seen "
                        "triplets with each pass cut to that many views (curve.csv, curve figure)")
    p.add_argument("--tensor", default=None,
                   help="composition tensor .npz (default: the shipped tensor of the partition)")
    p.add_argument("--no-fix-landmarks", action="store_true",
                   help="score against the landmark ground truth as shipped (no swap check)")
    p.add_argument("--seed", type=seed_int, default=0, help="solver seed (default 0)")
    p.add_argument("--piece-size", type=int, default=128,
                   help="histories solved and recorded together (default 128; piece c is solved "
                        "with child c of the seed, so this is part of the run's identity)")
    p.add_argument("--output", default=None, help="output directory (default out/mrclam-<name>)")
    p.add_argument("--resume", action="store_true", help="continue (or re-summarize) a run in "
                                                         "--output")
    p.add_argument("--overwrite", action="store_true", help="start again in a used --output")
    p.add_argument("--no-figures", action="store_true", help="skip the figures")
    p.add_argument("--no-progress", action="store_true",
                   help="no phase lines and no bar on stderr")
    add_format(p)
    p.set_defaults(func=_main)


# ------------------------------------------------------------------------------ checks
def _temper_arg(text: str):
    """``--temper``: a number, ``auto`` or ``auto-1se`` (checked in range by
    :func:`check_options`)."""
    from qfg.harness.studies.mrclam import TEMPER_RULES

    if str(text).strip().lower() in TEMPER_RULES:
        return str(text).strip().lower()
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a number in [0, 1], auto or auto-1se, got {text!r}") from None


def _number(args, name: str, *, lo=None, hi=None, lo_open=False) -> float:
    import math

    v = getattr(args, name.lstrip("-").replace("-", "_"))
    bad = not math.isfinite(v) or (lo is not None and (v <= lo if lo_open else v < lo)) or (
        hi is not None and v > hi)
    if bad:
        if lo is not None and hi is not None:
            want = f"a number in [{lo:g}, {hi:g}]"
        elif lo is not None:
            want = f"a number {'>' if lo_open else '>='} {lo:g}"
        else:
            want = "a finite number"
        raise ValueError(f"{name}: expected {want}, got {v:g}")
    return float(v)


def _walk(args) -> dict:
    """``--heading-walk``: 'measured' (:data:`study.HEADING_WALK`), 'measured-tail'
    (:data:`study.HEADING_WALK_TAIL`: the walk's b and the solvers' heading tail) or a number
    >= 0; returns the run's ``heading_walk`` and ``heading_tail``."""
    import math

    from qfg.harness.studies import mrclam as study

    text = str(args.heading_walk).strip()
    if text == "measured":
        return {"heading_walk": float(study.HEADING_WALK), "heading_tail": "normal"}
    if text == "measured-tail":
        return {"heading_walk": float(study.HEADING_WALK_TAIL[0]), "heading_tail": "measured"}
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not math.isfinite(v) or v < 0:
        raise ValueError(f"--heading-walk: expected 'measured', 'measured-tail' or a number >= 0 "
                         f"(degrees per sqrt(second)), got {text!r}")
    return {"heading_walk": v, "heading_tail": "normal"}


def _views(args, name: str) -> int:
    v = getattr(args, name.lstrip("-").replace("-", "_"))
    if v < 0 or v == 1:
        raise ValueError(f"{name}: expected 0 (every view) or an integer >= 2, got {v}")
    return int(v)


def check_options(args) -> dict:
    """Every option value checked, no file read: the run's parameters, or ValueError naming the
    option as typed on the command line."""
    robots = _int_list(args.robots)
    if any(r < 1 for r in robots):
        raise ValueError(f"--robots: expected robot numbers >= 1, got {args.robots!r}")
    if len(set(robots)) != len(robots):
        raise ValueError(f"--robots: a robot named twice in {args.robots!r}")
    map_name = args.map
    if args.propagation is not None:
        if map_name is not None and map_name != _PROPAGATION_MAP[args.propagation]:
            raise ValueError(f"--propagation {args.propagation} and --map {map_name} disagree; "
                             "give --map alone")
        map_name = _PROPAGATION_MAP[args.propagation]
    caps = _int_list(args.curve, "--curve")
    if any(c < 0 or c == 1 for c in caps):
        raise ValueError(f"--curve: expected view caps 0 (every view) or >= 2, got {args.curve!r}")
    if args.piece_size < 1:
        raise ValueError(f"--piece-size: expected an integer >= 1, got {args.piece_size}")
    if args.resume and args.overwrite:
        raise ValueError("--resume and --overwrite: give one of them")
    tensor = ""
    if args.tensor:
        t = Path(args.tensor)
        if not t.is_file():
            raise ValueError(f"--tensor: {t} is not a file")
        tensor = str(t.resolve())
    from qfg.harness.studies import mrclam as study
    from qfg.harness.studies.mrclam import maps as mrclam_maps

    map_name = map_name or mrclam_maps.DEFAULT_MAP
    if args.prior == "arena-logscale" and mrclam_maps.get(map_name).whole_configurations:
        raise ValueError(f"--prior arena-logscale: the {map_name} map infers whole landmark "
                         "configurations, drawn i.i.d. in the arena; a pair-scale prior "
                         "describes one triplet's frame (use --prior arena)")
    method = args.method
    if method is None:
        method = "full" if mrclam_maps.get(map_name).needs_estimates else "none"
    elif method == "none" and mrclam_maps.get(map_name).needs_estimates:
        raise ValueError(f"--method none: the map {map_name!r} is made from the solvers' "
                         "estimates; give a solver (full, fast, baseline) or a map from the raw "
                         "measurements (--map joint)")
    later = {"bearing_tail": args.bearing_tail, "heading_drift": bool(args.heading_drift),
             "distance_tail": args.distance_tail,
             "camera_prior": args.camera_prior,
             "bearing_calibration": args.bearing_calibration,
             "budget": _number(args, "--budget", lo=0.0, lo_open=True),
             "populations": args.populations,
             **_walk(args),
             "model_check": _number(args, "--model-check", lo=0.0, hi=0.5)}
    if later["populations"] < 1:
        raise ValueError(f"--populations: expected a whole number >= 1, got "
                         f"{later['populations']}")
    if later["populations"] != 1 and method not in ("full", "fast"):
        raise ValueError(f"--populations: only the full and fast solvers run populations; "
                         f"the method here is {method!r}")
    if later["budget"] != 1.0 and method not in ("full", "fast"):
        raise ValueError(f"--budget: only the full and fast solvers take a budget factor; "
                         f"the method here is {method!r}")
    # at their defaults these stay out of the run's identity: runs recorded before they existed
    # resume as before
    later = {k: v for k, v in later.items() if v != study.DEFAULTS[k]}
    return {**later,
        "robots": robots, "method": method, "mode": args.mode, "prior": args.prior,
        "partition": "edc", "fix_landmarks": not args.no_fix_landmarks,
        "min_travel": _number(args, "--min-travel", lo=0.0),
        "max_gap": _number(args, "--max-gap", lo=0.0, lo_open=True),
        "max_views": _views(args, "--max-views"),
        "spread_views": _views(args, "--spread-views"),
        "sigma_bearing_deg": _number(args, "--sigma-bearing-deg", lo=0.0),
        "sigma_heading_deg": _number(args, "--sigma-heading-deg", lo=0.0),
        "distances": bool(args.distances),
        "sigma_distance_ratio": _number(args, "--sigma-distance-ratio", lo=0.0),
        "piece": int(args.piece_size), "seed": int(args.seed),
        # the phases after solving: not part of the run's identity
        "_after": {"combine": args.combine, "temper": args.temper if isinstance(args.temper, str)
                   else _number(args, "--temper", lo=0.0, hi=1.0),
                   "map": map_name, "tensor": tensor, "curve": caps,
                   "method_given": args.method is not None},
    }


def _check_dataset_folder(path: Path) -> None:
    from qfg.datasets.mrclam import DataFormatError

    if not path.exists():
        raise ValueError(f"path: {path} does not exist")
    if not path.is_dir():
        raise ValueError(f"path: {path} is not a directory (give an MRCLAM_DatasetN folder)")
    try:
        next(iter(path.iterdir()), None)
    except OSError as exc:
        raise DataFormatError(path, None, f"cannot list the folder: {exc.strerror or exc}") from None


def check_output(out: Path, params: dict, seed: int, resume: bool, overwrite: bool) -> None:
    """The runner's checks of an output folder, made before anything is read or written (the
    runner makes them again, under its lock): a file in the way, a used folder without
    ``--resume``/``--overwrite``, a run with other parameters to resume."""
    from qfg.harness.runner import RunnerError

    for p in (out, *out.parents):
        if p.exists() and not p.is_dir():
            what = "is a file" if p == out else f"is inside {p}, which is a file"
            raise RunnerError(f"output: {out} {what}; give a directory")
    if (out / "records.jsonl").exists() and not (resume or overwrite):
        raise RunnerError(f"output: {out} already holds a run; pass --resume to continue it or "
                          "--overwrite to start again")
    run_json = out / "run.json"
    if resume and run_json.is_file():
        try:
            old = json.loads(run_json.read_text())
        except (OSError, ValueError):
            return  # the runner names what is wrong with it
        if not isinstance(old, dict):
            return
        mine = {"study": "mrclam", "params": params, "seed": seed}
        theirs = {k: old.get(k) for k in mine}
        if json.loads(json.dumps(mine)) != theirs:
            diff = sorted(k for k in set(params) | set(theirs.get("params") or {})
                          if params.get(k) != (theirs.get("params") or {}).get(k))
            raise RunnerError(f"output: {out} holds a run with other options "
                              f"({', '.join(diff) or 'seed'} differ); --resume needs the same "
                              "ones, or pass --overwrite")


def _recorded(out: Path) -> dict:
    """The recorded run's params, or {} (check_output names what is wrong with a bad record)."""
    try:
        return json.loads((out / "run.json").read_text()).get("params") or {}
    except (OSError, ValueError, AttributeError):
        return {}


def _keep_recorded_defaults(out: Path, params: dict) -> None:
    """Runs recorded while the later options were always written (at their defaults too) keep
    them in their identity: a later option the recorded run holds at its default, and this run
    leaves out because it is at its default, is put back, so that such a run resumes."""
    from qfg.harness.studies import mrclam as study

    old = _recorded(out)
    for k in study.LATER_KEYS:
        if k in old and k not in params and old[k] == study.DEFAULTS[k]:
            params[k] = old[k]


def _no_camera_reason(ds, robots) -> str:
    rs = robots or sorted(ds.robots)
    if not any(ds.robot(r).groundtruth is not None for r in rs):
        which = "" if not robots else f" for robot{'s' if len(rs) > 1 else ''} " \
                                      f"{', '.join(map(str, rs))}"
        return f"no motion capture (RobotN_Groundtruth) in {ds.name}{which}"
    return "no view of a solved history is covered by the motion capture"


# ------------------------------------------------------------------------------ the command
def _main(args):
    import shlex
    import shutil

    from qfg.harness import runner
    from qfg.harness.studies import mrclam as study
    from qfg.harness.studies.mrclam import maps as mrclam_maps

    # 1. options and the output folder: no file read, nothing written
    opts = check_options(args)
    after = opts.pop("_after")
    mrclam_maps.get(after["map"])
    path = Path(args.path)
    _check_dataset_folder(path)
    params = {"path": str(path.resolve()), **opts}
    out = Path(args.output or f"out/mrclam-{path.resolve().name}")
    if args.resume:
        _keep_recorded_defaults(out, params)
        if not after["method_given"]:
            # a run without a given solver resumes with the one it was recorded with (on a
            # dataset without odometry the default is decided once its data is read)
            opts["method"] = params["method"] = _recorded(out).get("method", params["method"])
            after["method_recorded"] = "method" in _recorded(out)
    check_output(out, params, args.seed, args.resume, args.overwrite)
    quiet = args.no_progress

    def say(msg):
        if not quiet:
            print(msg, file=sys.stderr, flush=True)

    # 2. the data: every file read and checked (DataFormatError names file and line)
    from qfg.datasets import mrclam as data

    t0 = time.perf_counter()
    ds = data.load(path)
    missing = [r for r in opts["robots"] if r not in ds.robots]
    if missing:
        raise ValueError(f"--robots: {', '.join(map(str, missing))} not in {ds.name} (robots "
                         f"{', '.join(map(str, sorted(ds.robots)))})")
    if opts["mode"] == "paper" and not any(ds.robot(r).groundtruth is not None
                                           for r in (opts["robots"] or ds.robots)):
        raise ValueError(f"--mode paper: needs motion capture (RobotN_Groundtruth); "
                         f"{_no_camera_reason(ds, opts['robots'])}")
    no_odometry = opts["method"] == "none" and not any(rd.has_odometry
                                                        for rd in ds.robots.values())
    if no_odometry and after["method_given"]:
        # the joint map (every robot of the dataset) solves robots without odometry with the
        # kinematic prior but trusts them only when two or more agree: given --method none,
        # it needs at least two robots to have a chance
        seeing = [r for r, rd in sorted(ds.robots.items()) if rd.visible.any()]
        if len(seeing) < 2:
            raise ValueError(f"--method none: {ds.name} has no odometry and only "
                             f"{len(seeing)} robot with landmark views, so the map "
                             f"{after['map']!r} falls back to the solvers' estimates; give "
                             "--method full (or fast, baseline)")
    T = None
    if after["tensor"]:
        try:
            T = study.load_tensor("edc", after["tensor"])
        except (OSError, ValueError, KeyError) as exc:
            raise ValueError(f"--tensor: {after['tensor']}: {exc}") from None
    prep = study.prepare_run(path, dataset=ds, **{k: opts[k] for k in (
        "mode", "prior", "partition", "fix_landmarks", "min_travel", "max_gap", "max_views",
        "spread_views", "sigma_bearing_deg", "sigma_heading_deg", "distances",
        "sigma_distance_ratio")}, **{k: opts.get(k, study.DEFAULTS[k]) for k in study.LATER_KEYS},
        robots=opts["robots"] or None)
    if not prep.histories:
        raise ValueError(f"--robots: no triplet history to solve in {ds.name}"
                         + (f" for robots {args.robots}" if opts["robots"] else ""))
    n_views = sum(rd.n_views for rd in ds.robots.values())
    say(f"loaded {ds.name}: {len(ds.robots)} robots, {n_views} views, every file checked "
        f"({time.perf_counter() - t0:.1f} s)")
    if no_odometry and not after["method_given"] and not after.get("method_recorded"):
        # without odometry the joint map may fall back to the solvers' estimates (robots
        # without odometry are trusted only when two or more agree): solve it first, and run
        # the solvers (full) only when it cannot answer; the map step then uses this answer
        say(f"no robot of {ds.name} has odometry: the {after['map']} map first (robots by a "
            "kinematic motion prior, kept when two or more agree) ...")
        t1 = time.perf_counter()
        j = mrclam_maps.joint_answer(prep.dataset, [h for _, h in prep.histories],
                                     prior_states=prep.prior_states,
                                     camera_prior_states=prep.prior_camera_states,
                                     partition=prep.partition.name, seed=opts["seed"],
                                     progress=say)
        if j.method == "none":
            opts["method"] = params["method"] = "full"
            check_output(out, params, args.seed, args.resume, args.overwrite)
            say(f"the {after['map']} map cannot answer ({mrclam_maps.joint_why(j)}; "
                f"{time.perf_counter() - t1:.0f} s): solving with full, the map falls back to "
                f"{mrclam_maps.JOINT_FALLBACK}")
        else:
            say(f"the {after['map']} map answers ({time.perf_counter() - t1:.0f} s): no "
                "single-triplet solver needed")
    study.remember(params, prep)
    if prep.swaps:
        say(f"landmark ground truth corrected: swapped "
            f"{';'.join(f'{a}-{b}' for a, b in prep.swaps)} (check_landmarks)")
    k = study.n_pieces(prep, opts["piece"])
    rs = sorted({r for r, _ in prep.histories})
    say(f"histories: {len(prep.histories)} of robot{'s' if len(rs) > 1 else ''} "
        f"{', '.join(map(str, rs))}; solving them in {k} "
        f"piece{'s' if k > 1 else ''} of up to {opts['piece']}, each recorded as it finishes")

    # 3. solving, piece by piece, recorded; 4. combine, map, scores (the runner's summary step)
    shown = {}

    def summarize(outdir, rows, _params):
        if args.overwrite:
            # starting again means the maps too (a recorded map is reused whenever its inputs
            # match, whatever code made it); here, under the run's lock
            shutil.rmtree(Path(outdir) / "maps", ignore_errors=True)
        ests = study.estimates_from_rows(prep, rows)
        trows, details = study.finish(prep, ests, combine=after["combine"],
                                      temper=after["temper"], map_method=after["map"], tensor=T,
                                      seed=opts["seed"], say=say, record_dir=outdir,
                                      tensor_name=after["tensor"])
        shown["rows"] = trows
        shown["summary"] = study.write_outputs(
            outdir, trows, figures=not args.no_figures, details=details,
            figure_robot=opts["robots"][0] if opts["robots"] else None,
            options={**params, **{k: v for k, v in after.items() if k != "curve"},
                     "temper_chosen": details.get("temper"),
                     "temper_check": details.get("temper_check")})

    pieces = runner.Study("mrclam", study.piece_tasks, study.run_piece, summarize,
                          "one MRCLAM dataset, solved in pieces")
    runner.run_study(pieces, params, out, seed=args.seed, resume=args.resume,
                     overwrite=args.overwrite, progress=not quiet,
                     command="qfg " + " ".join(shlex.quote(a) for a in sys.argv[1:]),
                     figure_format=args.format)
    summ = shown["summary"]
    print("\n".join(study.table_lines(summ)))
    print(study.TABLE_KEY)
    s = summ.get(opts["mode"], {})
    n_cam = s.get("camera", {}).get("n", 0)
    why = f" ({_no_camera_reason(ds, opts['robots'])})" if not n_cam else ""
    print(f"{s.get('seen', {}).get('n', 0)} seen, {s.get('propagated', {}).get('n', 0)} "
          f"propagated ({s.get('n_reached', 0)} reached), {n_cam} camera views scored{why} "
          f"-> {out}")
    if after["curve"]:
        say(f"curve: the seen triplets again with each pass cut to "
            f"{', '.join(str(c or 'all') for c in after['curve'])} views")
        recs = study.views_curve(path, after["curve"], robots=opts["robots"] or None,
                                 method=opts["method"], mode=opts["mode"], prior=opts["prior"],
                                 combine=after["combine"], min_travel=opts["min_travel"],
                                 max_gap=opts["max_gap"], temper=after["temper"],
                                 spread_views=opts["spread_views"],
                                 fix_landmarks=opts["fix_landmarks"], seed=args.seed,
                                 distances=opts["distances"],
                                 sigma_distance_ratio=opts["sigma_distance_ratio"],
                                 **{k: opts.get(k, study.DEFAULTS[k])
                                    for k in study.LATER_KEYS})
        study.write_curve(out, recs, figures=not args.no_figures)
        for line in study.curve_lines(recs):
            print(line)
    return 0
