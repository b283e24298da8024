"""``qfg demo``."""


def register(sub):
    p = sub.add_parser("demo", help="simulate a small scenario and show its qualitative map")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--output", default="out/demo", help="directory for figures (default out/demo)")
    p.set_defaults(func=_main)


def _main(args):
    from qfg.harness.demo import run

    run(seed=args.seed, output=args.output)
    return 0
