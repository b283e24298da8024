"""Toy studies whose scenarios kill their own worker process (runner tests, issue 18 item 5)."""

import os
import signal
from pathlib import Path

from toy_study import run_task

from qfg.harness.runner import Study


def tasks(params):
    return [{"i": i, "fail": False, "kill": i in params["kill"], "mode": params["mode"],
             "flags": params["flags"]} for i in range(params["n"])]


def run_task_killing(task, rng):
    """Scenario ``i`` in ``kill`` kills its process with SIGKILL: the first time only (mode
    "once"), or until the file ``<flags>/healed`` exists (mode "until-healed"). Only in a pool
    worker: the flag folder records which scenarios did it."""
    if task["kill"]:
        flags = Path(task["flags"])
        mark = flags / f"killed-{task['i']}"
        if task["mode"] == "once" and not mark.exists():
            mark.touch()
            os.kill(os.getpid(), signal.SIGKILL)
        if task["mode"] == "until-healed" and not (flags / "healed").exists():
            with open(mark, "a") as fh:
                fh.write("x")
            os.kill(os.getpid(), signal.SIGKILL)
    out = run_task(task, rng)
    return [{k: v for k, v in r.items() if k != "time_s"} for r in out]


KILLING = Study("toy-killing", tasks, run_task_killing, None, "scenarios that kill their worker")


def summarize_big(outdir, rows, params):
    """Writes ``params["bytes"]`` bytes next to the outputs (fills a small disk)."""
    from qfg.harness.runner import write_text

    write_text(Path(outdir) / "big.txt", "x" * params["bytes"])


def big_tasks(params):
    return [{"i": i, "fail": False} for i in range(params["n"])]


BIG_SUMMARY = Study("toy-big-summary", big_tasks, run_task, summarize_big,
                    "a summary larger than a small disk")
