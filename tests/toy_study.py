"""A tiny study used by the runner tests (importable by worker and killed subprocesses)."""

import time

from qfg.harness.runner import Study


def tasks(params):
    return [{"i": i, "fail": i in params.get("fail", [])} for i in range(params["n"])]


def run_task(task, rng):
    if task["fail"]:
        raise RuntimeError(f"scenario {task['i']} fails on purpose")
    time.sleep(task.get("sleep", 0.0))
    x = rng.normal(size=3)
    return [{"i": task["i"], "k": k, "x": float(x[k]), "time_s": time.perf_counter()} for k in range(3)]


def slow_tasks(params):
    return [{"i": i, "fail": False, "sleep": params["sleep"]} for i in range(params["n"])]


STUDY = Study("toy", tasks, run_task, None, "toy study for tests")
SLOW = Study("toy-slow", slow_tasks, run_task, None, "slow toy study for tests")


def all_fail_tasks(params):
    return [{"i": i, "fail": True} for i in range(params["n"])]


FAILING = Study("toy-failing", all_fail_tasks, run_task, None, "every scenario fails")


#: Small propagation-study parameters (seconds per run; a seeded random tensor, not the file).
PROPAGATION_SMALL = {"n_graphs": 4, "n_landmarks": 6, "n_fc_min": 3, "n_fc_max": 8,
                     "n_candidates": 3, "random_tensor": True}
