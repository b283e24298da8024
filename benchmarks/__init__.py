"""Benchmarks: ``python -m benchmarks [topic ...]`` (or ``make bench``).

Each ``benchmarks/bench_<topic>.py`` defines ``run() -> list[dict]`` with keys ``name``, ``value``,
``unit``, ``note`` (and optionally ``target``). Results of a topic are saved to
``benchmarks/results/<topic>.json`` with the machine they were measured on, and
``docs/benchmarks.md`` is rebuilt from every saved topic, so re-running one topic keeps the others.
Speed is measured here, never asserted in tests. A benchmark whose data are absent raises
:class:`Skip` from ``run()``: it is reported and its recorded results are left as they are.
"""


class Skip(Exception):
    """Raised by a benchmark's ``run()`` when what it needs is absent (e.g. a data directory); the
    message says what to provide."""


def median_time(fn, repeats: int = 7) -> float:
    """Median wall time (s) of ``fn()`` over ``repeats`` calls, after one warm-up call."""
    import time

    fn()
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    ts.sort()
    return ts[len(ts) // 2]
