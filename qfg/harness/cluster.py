"""Run a study's scenarios on a Dask cluster (``qfg experiment NAME --scheduler ADDRESS``).

:class:`DaskExecutor` has the runner's executor interface (``map_unordered(fn, arglists)``
yielding results as they complete, ``close()``), so :func:`qfg.harness.runner.run_study` neither
knows nor cares where scenarios run. Results do not depend on the executor: each scenario draws
from its own seeded stream (:func:`qfg.harness.runner.scenario_rng`) and rows are sorted by
scenario before writing.

Dask is an optional extra (``pip install qfg[dask]``); it is imported when an executor is made.

Workers must be able to import ``qfg`` (and the study's module): start them from the same
environment, e.g. ``dask scheduler`` then ``dask worker tcp://HOST:8786`` on each machine.

>>> from qfg.harness.cluster import DaskExecutor         # doctest: +SKIP
>>> ex = DaskExecutor("tcp://127.0.0.1:8786")           # doctest: +SKIP
>>> sorted(ex.map_unordered(pow, [(2, 3), (3, 2)]))     # doctest: +SKIP
[8, 9]
>>> ex.close()                                          # doctest: +SKIP
"""

from __future__ import annotations

from typing import Iterable

__all__ = ["DaskExecutor", "import_distributed"]


def import_distributed():
    """The ``dask.distributed`` module, or an ImportError telling how to install it."""
    try:
        import dask.distributed as distributed
    except ImportError as exc:  # tested by hiding dask (tests/test_cli.py)
        raise ImportError("--scheduler needs Dask's distributed scheduler, which is not installed: "
                          "pip install qfg[dask]  (or: pip install 'dask[distributed]')") from exc
    return distributed


class DaskExecutor:
    """Scenarios as Dask tasks on the cluster whose scheduler is at ``address``.

    Args:
        address: scheduler address (``"tcp://host:8786"``), or an existing ``distributed.Client``
            (not closed by :meth:`close`, since the caller owns it).
        max_in_flight: at most this many calls submitted and not yet collected (None: twice the
            cluster's thread count when the executor starts, at least 2), so a run of thousands of
            scenarios does not queue them all on the scheduler at once.
        timeout: seconds to wait for the scheduler when connecting.
    """

    def __init__(self, address, max_in_flight: int | None = None, timeout: float = 30.0):
        distributed = import_distributed()
        self._distributed = distributed
        if isinstance(address, distributed.Client):
            self.client, self._own = address, False
        else:
            if not isinstance(address, str) or not address.strip():
                raise ValueError(f"address: expected a scheduler address such as "
                                 f"'tcp://127.0.0.1:8786', got {address!r}")
            try:
                self.client = distributed.Client(address, timeout=timeout)
            except OSError as exc:
                raise ValueError(f"address: cannot reach a Dask scheduler at {address!r} "
                                 f"({exc})") from None
            self._own = True
        if max_in_flight is None:
            threads = sum(self.client.nthreads().values())
            max_in_flight = max(2, 2 * threads)
        if int(max_in_flight) < 1:
            raise ValueError(f"max_in_flight: expected >= 1, got {max_in_flight}")
        self.max_in_flight = int(max_in_flight)

    def map_unordered(self, fn, arglists: Iterable[tuple]):
        """Yield ``fn(*args)`` for every args in ``arglists``, in completion order.

        ``pure=False``: two scenarios with equal arguments are still two tasks (Dask would
        otherwise merge calls it takes for identical).
        """
        ac = self._distributed.as_completed()
        it = iter(arglists)
        in_flight = 0
        for args in it:
            ac.add(self.client.submit(fn, *args, pure=False))
            in_flight += 1
            if in_flight >= self.max_in_flight:
                break
        for fut in ac:
            result = fut.result()  # re-raises a worker-side exception here
            fut.release()
            in_flight -= 1
            for args in it:
                ac.add(self.client.submit(fn, *args, pure=False))
                in_flight += 1
                break
            yield result

    def close(self) -> None:
        """Disconnect (the cluster itself keeps running)."""
        if self._own:
            self.client.close()
