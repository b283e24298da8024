"""The documentation speaks of the project alone, and every guide page reads in one sitting.

Checked over README.md and every text file under docs/ (markdown, csv, json, toml, the Sphinx
configuration; binary files such as figures are skipped; file names are checked too):

- no issue or pull-request numbers: "issue 20", "issues 13 and 21", "issue #20", "issue21",
  "#53" (a ``#`` followed by digits; markdown anchors such as ``joint.md#flags`` are letters);
- no rounds of work: "session(s)", "this / last / previous / earlier / next round",
  "earlier run(s)", "earlier version";
- no paths outside the repository: ``/work/...``, ``/home/...``, ``/tmp/...``, ``/Users/...``,
  ``/root/...``, a Windows drive (``C:\\...``), ``../shared``, and no relative link that climbs
  out of the checkout;
- commit hashes (7-40 hex digits with at least one digit and one letter) and dates
  (``YYYY-MM-DD``) only in results pages (``docs/results/**``), and there only on a
  provenance line: a line that starts (after markdown list, quote or emphasis marks) with
  ``Provenance:`` or ``Measured at``, e.g.
  ``Provenance: qfg 0.5.0, commit 8be95f8, 2026-12-07; the command above, seed 0.``;
- every guide page (each markdown file in docs/ outside docs/results/ and docs/benchmarks.md)
  is under 400 lines.

Each rule reports every offending line at once (file:line: the rule, the text).
"""

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
MAX_LINES = 400

ISSUE = re.compile(r"(?<![a-z])issues?[ _-]?#?\d+|\bissues?\s+\d+(?:\s*(?:,|and|&)\s*\d+)*"
                   r"|(?<![\w&#/])#\d+\b|\bpull request\s*#?\d+|\bPR\s*#\d+", re.I)
ROUND = re.compile(r"\bsessions?\b|\b(?:this|last|previous|earlier|next)\s+round\b"
                   r"|\bearlier\s+runs?\b|\bearlier\s+version\b", re.I)
ABSOLUTE = re.compile(r"(?<![\w.~-])/(?:work|home|tmp|Users|root|mnt)/|\b[A-Za-z]:\\\\?\w"
                      r"|\.\./shared\b")
RELATIVE = re.compile(r"(?:\.\./)+[\w.-]+")
HASH = re.compile(r"(?<!sha256 `)(?<![.\w])(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b(?![-+.]?\d)")
DATE = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b")
PROVENANCE = re.compile(r"^[\s>*_\-+]*(?:Provenance:|Measured at\b)")
TEXT_SUFFIXES = {".md", ".txt", ".csv", ".json", ".toml", ".py", ".rst", ".cfg", ".yaml",
                 ".yml", ".tex", ".html", ".css", ""}


def _files():
    out = [REPO / "README.md"]
    out += sorted(p for p in DOCS.rglob("*") if p.is_file() and p.suffix in TEXT_SUFFIXES)
    return out


def _lines(path):
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        return []
    if "\x00" in text:
        return []
    return text.splitlines()


def _rel(path):
    return path.relative_to(REPO).as_posix()


def _is_results(path):
    """Results pages: docs/results/**, their index docs/results.md and docs/benchmarks.md."""
    return path.is_relative_to(DOCS / "results") or path in (DOCS / "results.md",
                                                             DOCS / "benchmarks.md")


def _offences(check):
    bad = []
    for f in _files():
        for msg in check(f, _lines(f)):
            bad.append(f"{_rel(f)}:{msg}")
    return bad


def _report(bad):
    assert not bad, f"{len(bad)} offending lines:\n" + "\n".join(bad)


def _pattern(rx, what):
    def check(f, lines):
        hit = rx.search(_rel(f))
        if hit:
            yield f" (file name): {what}: {hit.group(0)!r}"
        for i, line in enumerate(lines, 1):
            for m in rx.finditer(line):
                yield f"{i}: {what}: {m.group(0)!r} in {line.strip()[:120]!r}"
    return check


def test_no_issue_numbers():
    _report(_offences(_pattern(ISSUE, "an issue number")))


def test_no_rounds_of_work():
    _report(_offences(_pattern(ROUND, "a round of work")))


def test_no_paths_outside_the_repository():
    def check(f, lines):
        yield from _pattern(ABSOLUTE, "a path outside the repository")(f, lines)
        for i, line in enumerate(lines, 1):
            for m in RELATIVE.finditer(line):
                target = (f.parent / m.group(0)).resolve()
                if not target.is_relative_to(REPO):
                    yield f"{i}: a relative path out of the checkout: {m.group(0)!r}"
    _report(_offences(check))


@pytest.mark.parametrize("rx, what", [(HASH, "a commit hash"), (DATE, "a date")],
                         ids=["hashes", "dates"])
def test_hashes_and_dates_only_on_provenance_lines_of_results_pages(rx, what):
    def check(f, lines):
        for i, line in enumerate(lines, 1):
            for m in rx.finditer(line):
                if not (_is_results(f) and PROVENANCE.match(line)):
                    yield f"{i}: {what} off a results page's provenance line: {m.group(0)!r}"
    _report(_offences(check))


def test_guide_pages_read_in_one_sitting():
    bad = []
    for f in sorted(DOCS.rglob("*.md")):
        if _is_results(f):
            continue
        n = len(_lines(f))
        if n >= MAX_LINES:
            bad.append(f"{_rel(f)}: {n} lines (at most {MAX_LINES - 1})")
    _report(bad)


@pytest.mark.parametrize("text, rx", [
    ("fixed in issue 20", ISSUE), ("issues 13 and 21", ISSUE), ("see #53", ISSUE),
    ("scores_issue21_fast.csv", ISSUE), ("in the last session", ROUND),
    ("this round of work", ROUND), ("an earlier run gave", ROUND),
    ("under /work/main", ABSOLUTE), ("`/tmp/x`", ABSOLUTE), ("C:\\Users", ABSOLUTE),
    ("../shared/data", ABSOLUTE), ("commit `8be95f8`", HASH), ("on 2026-12-07", DATE)])
def test_the_patterns_catch_what_they_should(text, rx):
    assert rx.search(text)


@pytest.mark.parametrize("text, rx", [
    ("[flags](joint.md#flags)", ISSUE), ("the MAP and PR tasks", ISSUE),
    ("rounds of composition", ROUND), ("a 120-s pass", ROUND),
    ("https://example.org/home/page", ABSOLUTE), ("out/tmp/x", ABSOLUTE),
    ("[cite](../CITATION.cff)", ABSOLUTE), ("1e-3 and 20000000", HASH),
    ("0.0217395611975026e-05", HASH), ("4824062008826203e+01", HASH),
    ("deadline", HASH), ("sha256 `aa2d4305…`", HASH), ("2730 triplets", DATE)])
def test_the_patterns_pass_what_they_should(text, rx):
    assert not rx.search(text)


def test_provenance_lines():
    assert PROVENANCE.match("Provenance: qfg 0.5.0, commit 8be95f8, 2026-12-07")
    assert PROVENANCE.match("> Measured at commit 8be95f8 on 2026-12-07")
    assert not PROVENANCE.match("The rows were measured at commit 8be95f8")
