"""The experiment runner every study goes through.

A :class:`Study` is three plain functions: ``tasks(params)`` lists the scenarios, ``run_task(task,
rng)`` runs one and returns rows, ``summarize(outdir, rows, params)`` writes tables and figures;
optionally a parameter spec (:class:`Param`, :func:`param_spec`) so that bad parameters are
rejected, naming the parameter, before anything runs. :func:`run_study` runs the scenarios and
guarantees (``docs/runner.md``):

* one seeded random stream per scenario, ``SeedSequence(seed, spawn_key=(index,))``, so the numbers
  do not depend on the worker count or the order scenarios finish in;
* a record per scenario appended to ``records.jsonl`` as it finishes; ``resume=True`` skips finished
  scenarios, a partial last line left by a kill is detected and dropped, and records are
  de-duplicated by scenario index when read (the first complete record of a scenario counts);
* one run per output directory at a time: a lock file (``run.lock``: the holder's PID and host) is
  held while running; a lock whose holder is dead is taken over, a live one refuses the run. The
  lock is taken before the directory is inspected, so of two runs started together on a fresh
  directory exactly one proceeds;
* a scenario that raises is recorded with its index, seed and traceback, and the run goes on; a
  run in which every scenario failed raises :class:`ScenariosFailed`;
* nothing lost: a pool worker killed by a signal has its scenarios rerun one at a time (a
  scenario whose worker dies ``retries + 1`` times alone raises :class:`RunAborted`); a full disk
  or an unwritable records file cuts the file back to its last complete record and raises
  :class:`RunAborted` (one line; ``resume`` continues); records carry their seed and are checked
  (index, rows, seed) with the file and line when read;
* outputs are written to a temporary file in the folder and renamed (:func:`write_text`): a
  link planted at an output's name is replaced, never written through;
* worker processes exit when the main process dies (even by SIGKILL), and ignore Ctrl-C, which
  the main process turns into :class:`RunInterrupted` (finished scenarios are kept for
  ``resume``);
* a progress bar with rate and time left;
* execution behind an :class:`Executor` (in-process, a local process pool, or a cluster), so that
  studies never see how they are run.

Outputs in the output directory: ``run.json`` (study, params, seed, command, version),
``records.jsonl`` (raw, completion order), ``rows.csv`` (sorted by scenario, no timing columns:
identical for identical inputs), ``timings.csv`` (columns whose name starts with ``time``),
``errors.json`` when any scenario failed, then whatever ``summarize`` writes: tables
(:func:`write_table`), the headline table on stdout (:func:`print_table`) and figures in
``figures/`` (:func:`save_figure`, in the run's figure format).

Modules, by job: :mod:`~qfg.harness.runner.params` (:class:`Study`, :class:`Param`,
:func:`param_spec`, :func:`validate_params`), :mod:`~qfg.harness.runner.executors` (serial,
process pool, cluster), :mod:`~qfg.harness.runner.lock` (the output directory and its lock),
:mod:`~qfg.harness.runner.records` (``records.jsonl``, :func:`write_text`, the table writer),
:mod:`~qfg.harness.runner.figures` (:func:`save_figure`), :mod:`~qfg.harness.runner.presets`
(:func:`load_presets`), :mod:`~qfg.harness.runner.run` (:func:`run_study`) and
:mod:`~qfg.harness.runner.errors`. Every public name is importable from here.

>>> spec = param_spec({"n": 10, "sigma": [1.0, 2.0], "mode": "fast"}, n={"min": 1},
...                   sigma={"min": 0.0}, mode={"choices": ("fast", "full")})
>>> validate_params(spec, {"n": 3})
{'n': 3, 'sigma': [1.0, 2.0], 'mode': 'fast'}
>>> validate_params(spec, {"n": -1})
Traceback (most recent call last):
...
qfg.harness.runner.errors.RunnerError: n: expected an integer >= 1, got -1
"""

from __future__ import annotations

from qfg._version import __version__  # noqa: F401 - importable here, as before
from qfg.harness.runner.errors import (
    OutputInUse,
    RunAborted,
    RunInterrupted,
    RunnerError,
    ScenariosFailed,
)
from qfg.harness.runner.executors import (
    Executor,
    ProcessExecutor,
    SerialExecutor,
    WorkerLost,
    make_executor,
)
from qfg.harness.runner.figures import (  # noqa: F401 - use_figure_format importable here, as before
    FIGURE_FORMATS,
    figure_format,
    save_figure,
    use_figure_format,
)
from qfg.harness.runner.lock import LOCK_NAME, OutputLock, check_output, this_host
from qfg.harness.runner.params import Param, Study, param_spec, validate_params
from qfg.harness.runner.presets import (  # noqa: F401 - experiments_dir, tomllib importable here, as before
    experiments_dir,
    load_presets,
    preset_path,
    presets_dir,
    tomllib,
)
from qfg.harness.runner.records import (
    dedupe_records,
    format_table,
    print_table,
    read_records,
    write_table,
    write_text,
)
from qfg.harness.runner.run import TIMING_PREFIX, run_study, scenario_rng

__all__ = [
    "Study",
    "Param",
    "param_spec",
    "validate_params",
    "Executor",
    "SerialExecutor",
    "ProcessExecutor",
    "make_executor",
    "scenario_rng",
    "run_study",
    "read_records",
    "dedupe_records",
    "OutputLock",
    "check_output",
    "load_presets",
    "preset_path",
    "presets_dir",
    "RunnerError",
    "OutputInUse",
    "ScenariosFailed",
    "RunInterrupted",
    "RunAborted",
    "WorkerLost",
    "write_text",
    "write_table",
    "format_table",
    "print_table",
    "save_figure",
    "figure_format",
    "FIGURE_FORMATS",
    "TIMING_PREFIX",
    "LOCK_NAME",
    "this_host",
]
