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

from qfg.harness.commands import add_format, one_line_error, seed_int


def _int_list(text: str, option: str = "--robots") -> list[int]:
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"{option}: expected comma-separated integers, got {text!r}") from None


def register(sub):

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
    p.error = one_line_error(p)
    p.add_argument("path", help="an MRCLAM_DatasetN directory")
    _add_options(p)
    p.add_argument("--curve", default="",
                   help="comma-separated view caps (0 = all), e.g. 3,5,8,0: also score the seen "
                        "triplets with each pass cut to that many views (curve.csv, curve figure)")
    p.add_argument("--seed", type=seed_int, default=0, help="solver seed (default 0)")
    p.add_argument("--output", default=None, help="output directory (default out/mrclam-<name>)")
    p.add_argument("--resume", action="store_true", help="continue (or re-summarize) a run in "
                                                         "--output")
    p.add_argument("--overwrite", action="store_true", help="start again in a used --output")
    p.add_argument("--no-figures", action="store_true", help="skip the figures")
    p.add_argument("--no-progress", action="store_true",
                   help="no phase lines and no bar on stderr")
    add_format(p)
    p.set_defaults(func=_main)


def _add_options(p) -> None:
    """One option per :class:`~qfg.harness.studies.mrclam.MrclamParams` field that has one:
    flag, type, choices, default and help from the field and its documentation."""
    from qfg.harness.studies.mrclam.maps import DEFAULT_MAP, MAP_METHODS
    from qfg.harness.studies.mrclam.params import cli_fields

    for f, flag, choices, default in cli_fields():
        doc = f.metadata["doc"]
        kw = {"default": default, "dest": f.name}
        if f.name == "map":
            doc = (f"map method (default {DEFAULT_MAP}: the best mean log score over the seen "
                   "and unseen triplets of datasets 1-6, docs/results/mrclam.md): "
                   + "; ".join(f"{m.name}: {m.description}" for m in MAP_METHODS.values()))
        elif f.name == "propagation":
            kw["type"] = _renamed(f)
            doc = "former name of --map: pooled = --map pooled, best = --map best"
        elif f.name == "robots":
            kw["default"] = ""   # comma-separated, parsed by check_options
        elif f.name == "temper":
            kw["type"] = _temper_arg
        elif f.name == "heading_walk":
            kw["default"] = "0"
        elif f.type in ("bool", bool):
            kw["action"] = argparse.BooleanOptionalAction
        elif f.type in ("int", int):
            kw["type"] = int
        elif f.type in ("float", float):
            kw["type"] = float
        if choices is not None:
            kw["choices"] = tuple(choices)
        if choices is None and "action" not in kw:
            kw["metavar"] = flag.lstrip("-").upper().replace("-", "_")
        if default not in (None, "", ()) and f.name not in ("map", "method"):
            doc += f" (default {_shown(default)})"
        kw["help"] = doc.replace("%", "%%")
        p.add_argument(flag, **kw)


def _shown(v) -> str:
    if isinstance(v, bool):
        return "on" if v else "off"
    return f"{v:g}" if isinstance(v, float) else str(v)


def _renamed(f):
    """An option's type that refuses a renamed value with one line naming the new name."""

    def parse(text):
        if text in f.metadata["renamed"]:
            raise argparse.ArgumentTypeError(f"{text!r} is now called "
                                             f"{f.metadata['renamed'][text]!r} (CHANGELOG.md)")
        return text

    return parse


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


def check_options(args):
    """Every option value checked, no file read: (the run's
    :class:`~qfg.harness.studies.mrclam.MrclamParams`, the command's own: ``curve``,
    ``method_given``), or ValueError naming the option as typed on the command line."""
    from qfg.harness.studies.mrclam import maps as mrclam_maps
    from qfg.harness.studies.mrclam.params import MrclamParams, ParamError, flag_of

    robots = _int_list(args.robots)
    map_name = args.map
    if args.propagation is not None:
        if map_name is not None and map_name != args.propagation:
            raise ValueError(f"--propagation {args.propagation} and --map {map_name} disagree; "
                             "give --map alone")
        map_name = args.propagation
    caps = _int_list(args.curve, "--curve")
    if any(c < 0 or c == 1 for c in caps):
        raise ValueError(f"--curve: expected view caps 0 (every view) or >= 2, got {args.curve!r}")
    if args.resume and args.overwrite:
        raise ValueError("--resume and --overwrite: give one of them")
    tensor = ""
    if args.tensor:
        t = Path(args.tensor)
        if not t.is_file():
            raise ValueError(f"--tensor: {t} is not a file")
        tensor = str(t.resolve())
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
    from qfg.harness.studies.mrclam.params import cli_fields

    given = {f.name: getattr(args, f.name) for f, *_ in cli_fields()}
    given.update(robots=robots, method=method, map=map_name, tensor=tensor,
                 **_walk(args))
    given.pop("propagation")
    try:
        params = MrclamParams(**given)
    except ParamError as exc:
        raise ValueError(f"{flag_of(exc.field)}: {exc.problem}") from None
    if params.populations != 1 and method not in ("full", "fast"):
        raise ValueError(f"--populations: only the full and fast solvers run populations; "
                         f"the method here is {method!r}")
    if params.budget != 1.0 and method not in ("full", "fast"):
        raise ValueError(f"--budget: only the full and fast solvers take a budget factor; "
                         f"the method here is {method!r}")
    return params, {"curve": caps, "method_given": args.method is not None}


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
    run, own = check_options(args)
    path = Path(args.path)
    _check_dataset_folder(path)
    params = study.run_record(path.resolve(), run, args.seed)
    # the phases after solving: not part of the run's identity
    after = {"combine": run.combine, "temper": run.temper, "map": run.map,
             "tensor": run.tensor, "curve": own["curve"], "method_given": own["method_given"]}
    out = Path(args.output or f"out/mrclam-{path.resolve().name}")
    if args.resume:
        _keep_recorded_defaults(out, params)
        if not after["method_given"]:
            # a run without a given solver resumes with the one it was recorded with (on a
            # dataset without odometry the default is decided once its data is read)
            params["method"] = _recorded(out).get("method", params["method"])
            run = run.replace(method=params["method"])
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
    robots = list(run.robots)
    missing = [r for r in robots if r not in ds.robots]
    if missing:
        raise ValueError(f"--robots: {', '.join(map(str, missing))} not in {ds.name} (robots "
                         f"{', '.join(map(str, sorted(ds.robots)))})")
    if run.mode == "paper" and not any(ds.robot(r).groundtruth is not None
                                       for r in (robots or ds.robots)):
        raise ValueError(f"--mode paper: needs motion capture (RobotN_Groundtruth); "
                         f"{_no_camera_reason(ds, robots)}")
    no_odometry = run.method == "none" and not any(rd.has_odometry
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
    prep = study.prepare_run(path, run, dataset=ds)
    if not prep.histories:
        raise ValueError(f"--robots: no triplet history to solve in {ds.name}"
                         + (f" for robots {args.robots}" if robots else ""))
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
                                     partition=prep.partition.name, seed=params["seed"],
                                     progress=say)
        if j.method == "none":
            params["method"] = "full"
            run = run.replace(method="full")
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
    k = study.n_pieces(prep, run.piece)
    rs = sorted({r for r, _ in prep.histories})
    say(f"histories: {len(prep.histories)} of robot{'s' if len(rs) > 1 else ''} "
        f"{', '.join(map(str, rs))}; solving them in {k} "
        f"piece{'s' if k > 1 else ''} of up to {run.piece}, each recorded as it finishes")

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
                                      seed=params["seed"], say=say, record_dir=outdir,
                                      tensor_name=after["tensor"])
        shown["rows"] = trows
        shown["summary"] = study.write_outputs(
            outdir, trows, figures=not args.no_figures, details=details,
            figure_robot=robots[0] if robots else None,
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
    s = summ.get(run.mode, {})
    n_cam = s.get("camera", {}).get("n", 0)
    why = f" ({_no_camera_reason(ds, robots)})" if not n_cam else ""
    print(f"{s.get('seen', {}).get('n', 0)} seen, {s.get('propagated', {}).get('n', 0)} "
          f"propagated ({s.get('n_reached', 0)} reached), {n_cam} camera views scored{why} "
          f"-> {out}")
    if after["curve"]:
        say(f"curve: the seen triplets again with each pass cut to "
            f"{', '.join(str(c or 'all') for c in after['curve'])} views")
        # as the curve always ran: the default sigmas of the solvers and pieces of 128
        # histories, whatever --sigma-bearing-deg, --sigma-heading-deg and --piece-size say
        curve = run.replace(sigma_bearing_deg=0.0, sigma_heading_deg=0.0, tensor="",
                            piece=study.CHUNK)
        recs = study.views_curve(path, after["curve"], curve, seed=args.seed)
        study.write_curve(out, recs, figures=not args.no_figures)
        for line in study.curve_lines(recs):
            print(line)
    return 0
