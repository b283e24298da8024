"""``qfg partitions``: draw a partition and print its states."""

from qfg.harness.commands import FORMATS, add_format


def register(sub):
    p = sub.add_parser("partitions", help="draw a partition and print its states")
    p.add_argument("--name", default="edc", help="partition name: edc, fdc, lr, tpcc (default edc)")
    p.add_argument("--output", default="out/partitions",
                   help="directory, created if missing; the figure goes to "
                        "<output>/figures/<name>.<format> (default out/partitions)")
    add_format(p)
    p.set_defaults(func=_main)


def _main(args):
    from pathlib import Path

    import matplotlib.pyplot as plt

    from qfg import partitions
    from qfg.harness.plotting import draw_partition
    from qfg.harness.runner import check_output, save_figure

    part = partitions.get(args.name)
    suffix = Path(args.output).suffix.lstrip(".").lower()
    if suffix in FORMATS:  # --output used to be the figure file: say what changed
        raise ValueError(f"--output: a folder, like every other command (the figure goes to "
                         f"<output>/figures/{part.name}.<format>), got the file name "
                         f"{args.output!r}; use --format for the format")
    out = check_output(args.output)
    print(f"{part.name.upper()}: {part.n_states} states, window {part.window}")
    print(part.table())
    fig, ax = plt.subplots(figsize=(5, 6))
    draw_partition(part, ax)
    fig.tight_layout()
    path = save_figure(fig, out, part.name, fmt=args.format)
    print(f"figure: {path}")
    return 0
