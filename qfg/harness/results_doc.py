"""Assemble ``docs/results.md``, the index of the results pages ``docs/results/<study>.md``.

Each study owner writes its page (tables, figures, the paper's numbers next to ours, and the
exact command that made them) in ``docs/results/<study>.md``. A page opens with its title
heading and a lead: the commands that regenerate it, the data it came from, one paragraph and
its key table or headline number; its details follow under subheadings. This module takes each
page's lead (:func:`lead`: the text up to the first subheading), in a fixed order, links the
full page, and, when given the runs ``qfg experiment all`` just made, appends a run record: per
study its command, seed, output directory and the scalar entries of its ``summary.json``. The
output depends on the page files (and the runs) alone. Pages without a ``qfg`` command line are
listed in a warning (every number needs its command).

>>> from pathlib import Path
>>> text = build_text({"propagation": "## Propagation\\n\\n    qfg experiment propagation\\n"})
>>> text.splitlines()[0]
'# Results'
"""

from __future__ import annotations

import json
import re
from pathlib import Path

__all__ = ["ORDER", "sections", "lead", "build_text", "write", "missing_commands"]

#: Section order (paper order); any other section follows, alphabetically.
ORDER = ("single_triplet", "composition", "exact_vs_approx", "propagation", "mrclam")

_COMMAND = re.compile(r"(^|\s|`)(\.venv/bin/)?qfg \w", re.MULTILINE)
_HEADING = re.compile(r"^#{1,6} ", re.MULTILINE)
_FENCE = re.compile(r"^(```|~~~)", re.MULTILINE)
# a relative markdown link target (not a URL, not an anchor, not an absolute path)
_LINK = re.compile(r"\]\((?![a-z][a-z0-9+.-]*:|#|/)([^)\s]+)\)")


def sections(results_dir) -> dict[str, str]:
    """``{stem: text}`` of ``<results_dir>/*.md`` in :data:`ORDER`, then the rest by name."""
    d = Path(results_dir)
    found = {p.stem: p.read_text() for p in sorted(d.glob("*.md"))} if d.is_dir() else {}
    order = [k for k in ORDER if k in found] + sorted(k for k in found if k not in ORDER)
    return {k: found[k] for k in order}


def lead(text: str) -> str:
    """The lead of a results page: its title heading and the text up to the next heading (of
    any level) outside code fences; the whole text when there is none.

    >>> lead("## T\\n\\nrun `qfg x`\\n\\n### Details\\n\\nmore\\n")
    '## T\\n\\nrun `qfg x`'
    """
    lines = text.splitlines()
    out, fenced, titled = [], False, False
    for line in lines:
        if _FENCE.match(line):
            fenced = not fenced
        elif not fenced and _HEADING.match(line):
            if titled:
                break
            titled = True
        out.append(line)
    return "\n".join(out).strip("\n")


def _rebase(text: str) -> str:
    """Links of ``docs/results/<stem>.md`` made relative to ``docs/`` (where the index lives)."""
    def fix(m):
        target = m.group(1)
        if target.startswith("../"):
            return f"]({target[3:]})"
        return f"](results/{target})"
    return _LINK.sub(fix, text)


def missing_commands(secs: dict[str, str]) -> list[str]:
    """Sections that name no ``qfg ...`` command."""
    return [k for k, text in secs.items() if not _COMMAND.search(text)]


def _run_record(runs: list[dict]) -> list[str]:
    out = ["## Run record of `qfg experiment all`", "",
           "Written by `qfg experiment all`: what each study's run produced (scalar entries of its "
           "`summary.json`). The pages above report the runs their own commands name.", ""]
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
    """The text of ``docs/results.md``: each page's lead (:func:`lead`) with a link to the full
    page, in the order of ``secs``, then the run record of ``runs`` (if any)."""
    out = ["# Results", "",
           "The index of the results pages in `docs/results/`: each entry is the opening of its "
           "page (the commands that regenerate it, the data, the key table or number); the full "
           "page has the details. Rebuilt by `qfg experiment all --doc-only` (or after the runs, "
           "`--update-docs`) from the pages (`qfg/harness/results_doc.py`); edit the pages, not "
           "this file.", ""]
    if secs:
        out.append("Pages: " + ", ".join(f"[{k}](results/{k}.md)" for k in secs))
        out.append("")
    for stem, text in secs.items():
        head, _, rest = lead(text).partition("\n")
        out.append(head)
        out.append("")
        out.append(f"Full page: [results/{stem}.md](results/{stem}.md).")
        body = _rebase(rest).strip("\n")
        if body:
            out += ["", body]
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
