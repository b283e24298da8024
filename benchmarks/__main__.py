"""Run benchmarks; results go to out/benchmarks (or --output). Only ``--update`` (``make
bench-update``) rewrites the recorded results benchmarks/results/*.json and docs/benchmarks.md;
``--docs-only`` rewrites their descriptions alone (each result's ``doc`` from its benchmark's
docstring, then docs/benchmarks.md), running nothing."""

from __future__ import annotations

import argparse
import ast
import datetime as _dt
import importlib
import json
import os
import pkgutil
import platform
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
DOC = HERE.parent / "docs" / "benchmarks.md"


def machine() -> dict:
    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numpy

    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(),
            "numpy": numpy.__version__, "platform": platform.platform(),
            "date": _dt.datetime.now().strftime("%Y-%m-%d %H:%M")}


def topics() -> list[str]:
    return sorted(m.name[len("bench_"):] for m in pkgutil.iter_modules([str(HERE)])
                  if m.name.startswith("bench_"))


def run_topic(topic: str, results: Path = RESULTS) -> dict | None:
    """Run one topic and save its results; None (nothing saved) when it raises :class:`Skip`."""
    from benchmarks import Skip

    mod = importlib.import_module(f"benchmarks.bench_{topic}")
    print(f"== {topic}", flush=True)
    try:
        rows = mod.run()
    except Skip as e:
        print(f"   skipped: {e}", flush=True)
        return None
    for r in rows:
        print(f"   {r['name']}: {r['value']:.4g} {r['unit']}  {r.get('note', '')}", flush=True)
    res = {"topic": topic, "machine": machine(), "rows": rows,
           "command": f"python -m benchmarks {topic}", "doc": (mod.__doc__ or "").strip()}
    results.mkdir(parents=True, exist_ok=True)
    (results / f"{topic}.json").write_text(json.dumps(res, indent=2) + "\n")
    return res


def docstring(topic: str) -> str:
    """The docstring of ``benchmarks/bench_<topic>.py``, read without importing it (stripped, as
    :func:`run_topic` records ``mod.__doc__``)."""
    tree = ast.parse((HERE / f"bench_{topic}.py").read_text())
    return (ast.get_docstring(tree, clean=False) or "").strip()


def refresh_docs(results: Path = RESULTS, doc: Path = DOC) -> list[Path]:
    """Rewrite each recorded result's ``doc`` from its benchmark's docstring and rebuild ``doc``
    from the results; rows, machine and command are kept as recorded. Returns the files written."""
    written = []
    for f in sorted(results.glob("*.json")):
        res = json.loads(f.read_text())
        new = docstring(res["topic"])
        if new != res.get("doc"):
            res["doc"] = new
            f.write_text(json.dumps(res, indent=2) + "\n")
            written.append(f)
    doc.write_text(render(results))
    return written + [doc]


def render(results: Path = RESULTS) -> str:
    out = ["# Benchmarks", "",
           "Measured by `python -m benchmarks [topic ...]` (`make bench` runs all). Each section names "
           "the machine and date it was measured on and the command that made it. The machine is "
           "shared and noisy (2 cores): compare ratios within one section rather than absolute "
           "times across sections.", ""]
    for f in sorted(results.glob("*.json")):
        res = json.loads(f.read_text())
        m = res["machine"]
        out += [f"## {res['topic']}", ""]
        if res.get("doc"):
            out += [res["doc"], ""]
        out += [f"Measured at {m['date']} on {m['cpu']} ({m['cores']} cores), Python "
                f"{m['python']}, numpy {m['numpy']}, by `{res['command']}`.", "",
                "| benchmark | value | unit | target | note |", "|---|---|---|---|---|"]
        for r in res["rows"]:
            out.append(f"| {r['name']} | {r['value']:.4g} | {r['unit']} | {r.get('target', '')} | "
                       f"{r.get('note', '')} |")
        out.append("")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
    ap.add_argument("topics", nargs="*", help=f"topics (default all): {', '.join(topics())}")
    ap.add_argument("--output", default="out/benchmarks",
                    help="directory for the results and their page (default out/benchmarks)")
    ap.add_argument("--update", action="store_true",
                    help="record the results in benchmarks/results/ and rebuild docs/benchmarks.md "
                         "(make bench-update)")
    ap.add_argument("--docs-only", action="store_true",
                    help="run nothing: refresh the recorded results' descriptions from the "
                         "benchmarks' docstrings and rebuild docs/benchmarks.md from them")
    args = ap.parse_args(argv)
    if args.docs_only:
        if args.topics or args.update:
            ap.error("--docs-only: takes no topics and no --update (it runs nothing)")
        for f in refresh_docs():
            print(f"wrote {f}")
        return 0
    chosen = args.topics or topics()
    unknown = set(chosen) - set(topics())
    if unknown:
        ap.error(f"unknown topic(s) {sorted(unknown)}; known: {topics()}")
    sys.path.insert(0, str(HERE.parent))
    results = RESULTS if args.update else Path(args.output)
    results.mkdir(parents=True, exist_ok=True)
    for t in chosen:
        run_topic(t, results)
    doc = DOC if args.update else results / "benchmarks.md"
    doc.write_text(render(results))
    print(f"wrote {doc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
