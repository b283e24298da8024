"""The runner's errors: what a command turns into its exit status and one line."""

from __future__ import annotations

from pathlib import Path


class RunnerError(ValueError):
    """A study, its parameters or an output directory that cannot be run as asked (exit 2)."""


class OutputInUse(RunnerError):
    """The output directory is locked by another run that is still alive."""


class ScenariosFailed(RuntimeError):
    """Every scenario of a run failed (exit 1); the details are in ``errors.json``."""


class RunAborted(RuntimeError):
    """The run stopped for a reason outside the study (exit 1): a full disk or an unwritable
    output file, a worker process that dies every time it runs a scenario. Every scenario
    recorded before stays in ``records.jsonl`` (which ends at its last complete record) and
    ``resume`` continues from there."""


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C during a run: ``done`` of ``total`` scenarios are recorded and ``resume`` continues.

    A KeyboardInterrupt, so code that does not know the runner still stops.
    """

    def __init__(self, done: int, total: int, output: Path):
        super().__init__(f"interrupted after {done} of {total} scenarios; continue with --resume")
        self.done, self.total, self.output = done, total, Path(output)

    def __str__(self):
        return self.args[0]
