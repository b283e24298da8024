"""``qfg uai``: solve a UAI competition task (PR, MAR, MAP) on a ``.uai`` model, exactly.

Bad input ends the command with one line on stderr naming the option or the file (and line),
exit status 2: an unknown ``--task``, a bad ``--memory``, a malformed model or evidence file,
evidence the model does not have or that has probability zero, an output that cannot be
written. The result file is replaced whole (:mod:`qfg.files`): a failed write leaves an existing
result as it was.
"""

import os

from qfg.harness.commands import one_line_error
from qfg.inference.tasks import TASKS


def register(sub):
    p = sub.add_parser(
        "uai", help="exact PR, MAR or MAP on a UAI model file, result in the competition's format",
        description="Solve one task of the UAI inference competitions exactly (junction tree, "
                    "evidence clamped first) and write the competition's result file: the task "
                    "on the first line, the solution on the second.")
    p.error = one_line_error(p)
    p.add_argument("model", help="the model, a .uai file (MARKOV or BAYES)")
    p.add_argument("--evid", default=None,
                   help="evidence file (.evid: 'n v x ...' or the older '1 n v x ...' layout); "
                        "default: MODEL.evid if it exists, else none")
    p.add_argument("--no-evid", action="store_true",
                   help="ignore MODEL.evid even if it exists")
    p.add_argument("--task", required=True, type=str.upper, choices=TASKS + ("MPE",),
                   help="PR (log10 Z(e)), MAR (marginals given the evidence) or MAP (MPE)")
    p.add_argument("--output", default=None,
                   help="result file (default: the model's file name plus .TASK in the "
                        "current directory, as the competition's solvers write it); replaced "
                        "whole, or left as it was when the write fails")
    p.add_argument("--memory", default=None,
                   help="memory budget: bytes, a size (512M, 2G, 2GiB), a percentage of the "
                        "machine's memory (50%%) or inf (default $QFG_MEMORY_BUDGET, else half "
                        "of the machine's memory); refused before any work when over")
    p.set_defaults(func=_main)


def _cannot_write(out, exc: OSError) -> ValueError:
    """One line naming the result file and why it cannot be written."""
    reason = exc.strerror or str(exc)
    if not out.is_absolute():
        try:
            os.getcwd()
        except FileNotFoundError:
            reason = "the current directory no longer exists"
    return ValueError(f"--output: cannot write the result {out}: {reason}")


def _check_output(out) -> None:
    """What can be known before solving: the result is not a folder, its folder not a file, a
    relative path has a working directory."""
    if not out.is_absolute():
        try:
            os.getcwd()
        except FileNotFoundError:
            raise ValueError(f"--output: cannot write the result {out}: the current directory "
                             f"no longer exists") from None
    if out.is_dir():
        raise ValueError(f"--output: cannot write the result {out}: it is a folder")
    for parent in out.parents:
        if parent.exists():
            if not parent.is_dir():
                raise ValueError(f"--output: cannot write the result {out}: {parent} is a file, "
                                 f"not a folder")
            break


def _main(args):
    from pathlib import Path

    from qfg.budget import memory_budget
    from qfg.inference.tasks import solve_task, write_result
    from qfg.inference.uai import read_uai

    model_path = Path(args.model)
    evid = args.evid
    if evid is not None and args.no_evid:
        raise ValueError("--evid: contradicts --no-evid")
    if evid is None and not args.no_evid:
        default = model_path.with_name(model_path.name + ".evid")
        evid = default if default.exists() else None
    memory = memory_budget(args.memory, name="--memory") if args.memory is not None else None
    task = "MAP" if args.task == "MPE" else args.task
    out = Path(args.output) if args.output else Path(f"{model_path.name}.{task}")
    _check_output(out)
    model = read_uai(model_path)
    res = solve_task(model, task, evidence=evid, memory=memory)
    try:
        write_result(res, out)
    except OSError as exc:
        raise _cannot_write(out, exc) from None
    line = (f"{model_path.name}: {model.n} variables, {len(model.scopes)} factors, "
            f"{len(res.evidence)} observed; {task} in {res.seconds:.3g} s; log10 Z(e) = "
            f"{res.log10_z:.6f}")
    if task == "MAP":
        line += f"; log10 p(MAP | e) = {res.log10_p:.6f}"
    print(line)
    print(f"result: {out}")
    return 0
