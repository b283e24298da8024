"""Assemble ``docs/results.md`` from the per-study sections ``docs/results/<study>.md``.

Each study owner writes its section (tables, figures, the paper's numbers next to ours, and the
exact command that made them) in ``docs/results/<study>.md``; this module only concatenates them
in a fixed order and, when given the runs ``qfg experiment all`` just made, appends a run record:
per study its command, seed, output directory and the scalar entries of its ``summary.json``.
Sections without a ``qfg`` command line are listed in a warning (every number needs its command).

>>> from pathlib import Path
>>> text = build_text({"propagation": "## Propagation\\n\\n    qfg experiment propagation\\n"})
>>> text.splitlines()[0]
'# Results'
"""

from __future__ import annotations

import json
import re
from pathlib import Path

__all__ = ["ORDER", "sections", "build_text", "write", "missing_commands"]

#: Section order (paper order); any other section follows, alphabetically.
ORDER = ("single_triplet", "composition", "exact_vs_approx", "propagation", "mrclam")

_COMMAND = re.compile(r"(^|\s|`)(\.venv/bin/)?qfg \w", re.MULTILINE)


def sections(results_dir) -> dict[str, str]:
    """``{stem: text}`` of ``<results_dir>/*.md`` in :data:`ORDER`, then the rest by name."""
    d = Path(results_dir)
    found = {p.stem: p.read_text() for p in sorted(d.glob("*.md"))} if d.is_dir() else {}
    order = [k for k in ORDER if k in found] + sorted(k for k in found if k not in ORDER)
    return {k: found[k] for k in order}


def missing_commands(secs: dict[str, str]) -> list[str]:
    """Sections that name no ``qfg ...`` command."""
    return [k for k, text in secs.items() if not _COMMAND.search(text)]


def _run_record(runs: list[dict]) -> list[str]:
    out = ["## Run record of `qfg experiment all`", "",
           "Written by `qfg experiment all`: what each study's run produced (scalar entries of its "
           "`summary.json`). The sections above interpret the runs their commands name; where a "
           "number here differs from a section, the section was made by another run.", ""]
    for r in runs:
        out.append(f"### {r['study']}")
        out.append("")
        out.append(f"    {r['command']}")
        out.append("")
        if r.get("error"):
            out.append(f"Failed: `{r['error']}`")
            out.append("")
            continue
        out.append(f"Output `{r['output']}`, seed {r['seed']}, {r['rows']} rows.")
        sj = Path(r["output"]) / "summary.json"
        if sj.exists():
            try:
                s = json.loads(sj.read_text())
            except json.JSONDecodeError:
                s = {}
            scal = {k: v for k, v in s.items() if isinstance(v, (int, float, str)) and k != "command"}
            if scal:
                out += ["", "| key | value |", "|---|---|"]
                for k, v in scal.items():
                    out.append(f"| {k} | {v:.4g} |" if isinstance(v, float) else f"| {k} | {v} |")
        figs = sorted(p for p in (Path(r["output"]) / "figures").glob("*.*")
                      if p.suffix in (".png", ".pdf", ".svg"))
        if figs:
            out += ["", "Figures: " + ", ".join(f"`{f}`" for f in figs)]
        out.append("")
    return out


def build_text(secs: dict[str, str], runs: list[dict] | None = None) -> str:
    """The text of ``docs/results.md`` from section texts (and a run record)."""
    out = ["# Results", "",
           "Assembled by `qfg experiment all --update-docs` (`qfg/harness/results_doc.py`) from "
           "`docs/results/<study>.md`; do not edit by hand: edit the section files. Each section "
           "names the command that made its numbers and figures.", ""]
    if secs:
        out.append("Contents: " + ", ".join(f"[{k}](results/{k}.md)" for k in secs))
        out.append("")
    for text in secs.values():
        # figures are referenced relative to docs/results/; this file lives in docs/
        text = re.sub(r"\]\((?:\.\./)(figures/)", r"](\1", text)
        out.append(text.rstrip("\n"))
        out.append("")
    if runs:
        out += _run_record(runs)
    return "\n".join(out).rstrip("\n") + "\n"


def write(path, runs: list[dict] | None = None, results_dir=None) -> Path:
    """Write the results document ``path`` (the repository's ``docs/results.md``) from the section
    files in ``results_dir`` (default: ``results/`` next to ``path``); returns the path. Warns
    about sections without a command. Nothing here knows where the repository is: the caller
    (``qfg experiment all --update-docs``) names the file."""
    import sys

    path = Path(path)
    results_dir = Path(results_dir) if results_dir is not None else path.parent / "results"
    secs = sections(results_dir)
    for k in missing_commands(secs):
        print(f"results_doc: {results_dir / k}.md names no qfg command", file=sys.stderr)
    path.write_text(build_text(secs, runs))
    return path
