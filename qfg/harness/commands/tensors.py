"""``qfg tensors``: build, inspect and compare composition tensors (tensors/<partition>.npz)."""

from __future__ import annotations

from qfg.harness.commands import positive_int, seed_int


def register(sub):
    p = sub.add_parser("tensors", help="build, inspect and compare composition tensors",
                       description="Composition tensors T[i, j, k] of (AB:C, BC:D, AB:D); see "
                                   "docs/composition.md.")
    tsub = p.add_subparsers(dest="tensors_command", metavar="ACTION")

    b = tsub.add_parser("build", help="compute tensors and write <dir>/<partition>.npz")
    b.add_argument("--partition", default="all",
                   help="partition name (edc, fdc, lr, tpcc) or 'all' (default all)")
    b.add_argument("--samples", type=int, default=None,
                   help="weight samples of C per state (default: the shipped count, see "
                        "qfg.composition.build.SHIPPED_SAMPLES)")
    b.add_argument("--support-samples", type=int, default=None,
                   help="corner samples of C per state (default samples / 4)")
    b.add_argument("--seed", type=seed_int, default=0, help="random seed (default 0)")
    b.add_argument("--workers", type=positive_int, default=1, help="worker processes (default 1)")
    b.add_argument("--output", default="out/tensors",
                   help="directory (default out/tensors; the shipped tensors are in "
                        "qfg.composition.tensors_dir())")
    b.add_argument("--force", action="store_true",
                   help="overwrite existing tensor files (needed to replace the shipped ones)")
    b.add_argument("--no-progress", action="store_true", help="no progress bar")
    b.set_defaults(func=_build)

    i = tsub.add_parser("info", help="load, check and describe tensor files")
    i.add_argument("files", nargs="*", help=".npz files (default: every shipped tensor)")
    i.set_defaults(func=_info)

    c = tsub.add_parser("compare", help="how far two tensor files are apart (L1, max relative "
                                        "change, support differences)")
    c.add_argument("a", help="reference .npz file")
    c.add_argument("b", help="other .npz file (same partition)")
    c.add_argument("--threshold", type=float, default=None,
                   help="entries of a at least this large count in max_rel (default 1e-4)")
    c.set_defaults(func=_compare)

    k = tsub.add_parser("check", help="draw random configurations (C, D uniform in the window, D "
                                      "in the BC window) and list any state triple the tensor "
                                      "calls infeasible")
    k.add_argument("--partition", default="all", help="partition name or 'all' (default all)")
    k.add_argument("--configurations", type=float, default=1e7,
                   help="configurations drawn (default 1e7; 1e9 takes minutes)")
    k.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    k.add_argument("--file", default=None, help="tensor file to check (default: the shipped one)")
    k.set_defaults(func=_check)

    p.set_defaults(func=lambda args: (p.print_help(), 0)[1])


def _names(arg):
    from qfg import partitions
    if arg == "all":
        return ["edc", "fdc", "lr", "tpcc"]
    return [partitions.get(arg).name]


def _build(args):
    from pathlib import Path

    from qfg.composition import build as B
    from qfg.composition import save, tensors_dir
    from qfg.harness.runner import check_output

    names = _names(args.partition)
    out = Path(args.output)
    # refuse before computing (a build takes up to half an hour), not after
    existing = [out / f"{n}.npz" for n in names if (out / f"{n}.npz").exists()]
    if existing and not args.force:
        shipped = out.resolve() == tensors_dir().resolve()
        raise ValueError(f"--output: {', '.join(map(str, existing))} exist"
                         + (" (the shipped tensors)" if shipped else "")
                         + "; pass --force to overwrite, or choose another --output")
    check_output(out)
    for name in names:
        samples = args.samples if args.samples is not None else B.SHIPPED_SAMPLES.get(name, 4096)
        t = B.build(name, samples, seed=args.seed, support_samples=args.support_samples,
                    workers=args.workers, progress=not args.no_progress)
        path = out / f"{name}.npz"
        save(path, t)
        print(f"{path}: {t!r}")
        print(f"  build {t.meta['build_seconds']:.1f} s with {t.meta['workers']} worker(s); "
              f"non-zero {t.nnz} of {t.T.size} ({t.meta['nnz_weight_samples']} from the weight "
              f"samples, {t.meta['nnz_support_only']} only from the corner samples; "
              f"{t.meta['dropped_unwitnessed']} polygon slivers dropped)")
    return 0


def _info(args):
    from pathlib import Path

    from qfg.composition import load, tensor

    items = ([load(Path(f)) for f in args.files] if args.files
             else [tensor(n) for n in _names("all")])
    for t in items:
        print(f"{t.path}: {t!r}")
        print(f"  quad_segs {t.quad_segs}, version {t.version}, sha256 {t.sha256[:16]}..., "
              f"min non-zero {t.T[t.support].min():.3g}, max {t.T.max():.3g}")
        for k, v in sorted(t.meta.items()):
            if getattr(v, "ndim", 0):
                print(f"  {k}: array of shape {v.shape}")
            else:
                print(f"  {k}: {v}")
    return 0


def _check(args):
    import time
    from pathlib import Path

    import numpy as np

    from qfg.composition import load, tensor
    from qfg.composition.build import random_configurations

    names = [load(Path(args.file)).partition] if args.file else _names(args.partition)
    n = int(args.configurations)
    bad_total = 0
    for name in names:
        t = load(Path(args.file)) if args.file else tensor(name)
        t0 = time.perf_counter()
        counts = random_configurations(name, n, args.seed)
        dt = time.perf_counter() - t0
        seen = counts > 0
        outside = seen & ~t.support
        bad_total += int(outside.sum())
        print(f"{name}: {n:.3g} configurations drawn, {counts.sum()} kept, {dt:.0f} s; "
              f"{int(seen.sum())} distinct triples seen; tensor support {t.nnz}; "
              f"seen but infeasible in the tensor: {int(outside.sum())}; "
              f"in the tensor but never seen: {int((t.support & ~seen).sum())}")
        for i, j, k in np.argwhere(outside):
            print(f"  infeasible in tensor but seen: (i, j, k) = ({i + 1}, {j + 1}, {k + 1}) "
                  f"x {counts[i, j, k]}")
        unseen = np.argwhere(t.support & ~seen)
        if len(unseen):
            print("  never seen (1-based i, j, k; T): " + ", ".join(
                f"({i + 1},{j + 1},{k + 1}; {t.T[i, j, k]:.1e})" for i, j, k in unseen[:40])
                + (" ..." if len(unseen) > 40 else ""))
    return 1 if bad_total else 0


def _compare(args):
    from pathlib import Path

    from qfg.composition import load
    from qfg.composition.build import COMPARE_THRESHOLD, compare

    a, b = load(Path(args.a)), load(Path(args.b))
    if a.partition != b.partition:
        raise ValueError(f"b: partition {b.partition!r} differs from a's {a.partition!r}")
    thr = COMPARE_THRESHOLD if args.threshold is None else args.threshold
    r = compare(a, b, thr)
    print(f"{a.partition}: a = {a.path} ({a.samples_per_state}/state, seed {a.seed}), "
          f"b = {b.path} ({b.samples_per_state}/state, seed {b.seed})")
    print(f"  L1 = sum |Ta - Tb| = {r['l1']:.3e}")
    print(f"  max relative change over the {r['n_above']} entries with Ta >= {thr:g} "
          f"({100 * r['mass_above']:.2f}% of the mass) = {100 * r['max_rel']:.3f}%")
    print(f"  support: {a.nnz} vs {b.nnz} non-zero; only in a: {r['support_only_a']}, "
          f"only in b: {r['support_only_b']}")
    return 0
