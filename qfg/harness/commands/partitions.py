"""``qfg partitions``: draw a partition and print its states."""

from qfg.harness.commands import FORMATS


def register(sub):
    p = sub.add_parser("partitions", help="draw a partition and print its states")
    p.add_argument("--name", default="edc", help="partition name: edc, fdc, lr, tpcc (default edc)")
    p.add_argument("--output", default=None,
                   help="figure path; folders are created (default out/partitions/<name>.<format>)")
    p.add_argument("--format", default=None, choices=FORMATS,
                   help="figure format (default: the suffix of --output, else png)")
    p.set_defaults(func=_main)


def _main(args):
    from pathlib import Path

    from qfg import partitions
    from qfg.harness.plotting import partition_figure
    from qfg.harness.runner import check_output

    part = partitions.get(args.name)
    suffix = Path(args.output).suffix.lstrip(".").lower() if args.output else ""
    if args.format and suffix in FORMATS and suffix != args.format:
        raise ValueError(f"--format: {args.format} contradicts the suffix of --output "
                         f"{args.output!r}")
    fmt = args.format or (suffix if suffix in FORMATS else "png")
    path = Path(args.output or f"out/partitions/{part.name}.{fmt}")
    if args.output and suffix not in FORMATS:
        path = path.with_name(f"{path.name}.{fmt}")
    check_output(path.parent)
    print(f"{part.name.upper()}: {part.n_states} states, window {part.window}")
    print(part.table())
    partition_figure(part, path, fmt)
    print(f"figure: {path}")
    return 0
