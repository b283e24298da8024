"""``qfg partitions``: draw a partition and print its states."""


def register(sub):
    p = sub.add_parser("partitions", help="draw a partition (PNG) and print its states")
    p.add_argument("--name", default="edc", help="partition name: edc, fdc, lr, tpcc (default edc)")
    p.add_argument("--output", default=None, help="PNG path (default <name>.png)")
    p.set_defaults(func=_main)


def _main(args):
    from qfg import partitions
    from qfg.harness.plotting import partition_figure

    part = partitions.get(args.name)
    path = args.output or f"{part.name}.png"
    print(f"{part.name.upper()}: {part.n_states} states, window {part.window}")
    print(part.table())
    partition_figure(part, path)
    print(f"figure: {path}")
    return 0
