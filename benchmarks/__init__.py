"""Benchmarks: ``python -m benchmarks [topic ...]`` (or ``make bench``).

Each ``benchmarks/bench_<topic>.py`` defines ``run() -> list[dict]`` with keys ``name``, ``value``,
``unit``, ``note`` (and optionally ``target``). Results of a topic are saved to
``benchmarks/results/<topic>.json`` with the machine they were measured on, and
``docs/benchmarks.md`` is rebuilt from every saved topic, so re-running one topic keeps the others.
Speed is measured here, never asserted in tests.
"""
