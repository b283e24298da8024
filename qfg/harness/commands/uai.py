"""``qfg uai``: solve a UAI competition task (PR, MAR, MAP) on a ``.uai`` model, exactly."""

from qfg.inference.tasks import TASKS


def register(sub):
    p = sub.add_parser(
        "uai", help="exact PR, MAR or MAP on a UAI model file, result in the competition's format",
        description="Solve one task of the UAI inference competitions exactly (junction tree, "
                    "evidence clamped first) and write the competition's result file: the task "
                    "on the first line, the solution on the second.")
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
                        "current directory, as the competition's solvers write it)")
    p.add_argument("--memory", default=None,
                   help="memory budget: bytes, a size (512M, 2G, 2GiB), a percentage of the "
                        "machine's memory (50%%) or inf (default $QFG_MEMORY_BUDGET, else half "
                        "of the machine's memory); refused before any work when over")
    p.set_defaults(func=_main)


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
    model = read_uai(model_path)
    task = "MAP" if args.task == "MPE" else args.task
    res = solve_task(model, task, evidence=evid, memory=memory)
    out = Path(args.output) if args.output else Path(f"{model_path.name}.{task}")
    write_result(res, out)
    print(f"{model_path.name}: {model.n} variables, {len(model.scopes)} factors, "
          f"{len(res.evidence)} observed; {task} in {res.seconds:.3g} s; log10 Z(e) = "
          f"{res.log10_z:.6f}")
    print(f"result: {out}")
    return 0
