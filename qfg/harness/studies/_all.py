"""``qfg experiment all``: every study with one preset; the results document rebuilt on request.

Studies are the modules of :mod:`qfg.harness.studies` with a ``STUDY`` (this module has none, so
it is not one). Each runs through :func:`qfg.harness.runner.run_study` into
``<root>/<name>-<preset>`` with the same seed, executor, figure format and resume/overwrite
choice; a study that fails (e.g. a missing tensor file) is reported and the others still run.
Ctrl-C stops everything. Exit status 1 if any study failed.
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from qfg.harness import results_doc, runner
from qfg.harness.studies import studies

__all__ = ["run_all"]


def _order(names):
    key = {n.replace("_", "-"): i for i, n in enumerate(results_doc.ORDER)}
    return sorted(names, key=lambda n: (key.get(n, len(key)), n))


def run_all(preset: str = "quick", *, root="out", seed: int = 0, workers: int = 1,
            executor=None, resume: bool = False, overwrite: bool = False, progress: bool = True,
            only=None, doc: tuple[Path, Path] | None = None, extra_args: str = "",
            figure_format: str = "png") -> list[dict]:
    """Run every study's ``preset``; return one record per study (study, command, output, seed,
    rows, error). ``doc = (results_md, sections_dir)``: also rebuild that results document with
    a run record (:func:`qfg.harness.results_doc.write`); None (default): write no document."""
    found = studies()
    names = _order(found) if only is None else list(only)
    runs = []
    for name in names:
        study = found[name]
        output = str(Path(root) / f"{name}-{preset}")
        command = (f"qfg experiment {name} --preset {preset} --seed {seed} "
                   f"--output {shlex.quote(output)}{extra_args}")
        rec = {"study": name, "command": command, "output": output, "seed": seed, "rows": 0}
        try:
            presets = runner.load_presets(name)
            if preset not in presets:
                raise runner.RunnerError(f"no [{preset}] preset in "
                                         f"{runner.preset_path(name)}")
            rows = runner.run_study(study, presets[preset], output, seed=seed, workers=workers,
                                    resume=resume, overwrite=overwrite, executor=executor,
                                    progress=progress, command=command,
                                    figure_format=figure_format)
            rec["rows"] = len(rows)
            print(f"{name}: {len(rows)} rows in {output}")
        except Exception as exc:  # noqa: BLE001 - one failed study must not stop the others
            rec["error"] = f"{type(exc).__name__}: {exc}"
            print(f"{name}: FAILED: {rec['error']}", file=sys.stderr)
        runs.append(rec)
    if doc is not None:
        path, secs = doc
        print(f"rebuilt {results_doc.write(path, runs, results_dir=secs)}")
    return runs
