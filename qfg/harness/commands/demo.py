"""``qfg demo``."""

from qfg.harness.commands import add_format, seed_int


def register(sub):
    p = sub.add_parser("demo", help="simulate a small scenario and show its qualitative map")
    p.add_argument("--seed", type=seed_int, default=0, help="random seed (default 0)")
    p.add_argument("--output", default="out/demo",
                   help="directory; the figure goes to <output>/figures/ (default out/demo)")
    add_format(p)
    p.set_defaults(func=_main)


def _main(args):
    from qfg.harness.demo import run
    from qfg.harness.runner import check_output

    run(seed=args.seed, output=check_output(args.output), fmt=args.format)
    return 0
