"""Threads of the master for the members of a stage (``coupling.parallel: threads``).

With ``parallel: threads`` the FMUs of a stage (:mod:`.stages`) that are loaded into the
master's process step at the same time: the first member in this thread, each further
one in a thread of its own, kept for the whole run. An FMI call through ctypes releases
the GIL, so two FMUs run on two cores as far as their own code does not hold it: a C FMU
entirely, our bearing FMU for its film step (:func:`bearing_fmu.fused.advance_fused`, a
numba call without the GIL), a Python FMU whose work is Python code not at all (that code
holds the GIL).

FMI 2.0 does not promise that two instances of an FMU may be called from two threads at
the same time, so this is a choice for FMUs known to allow it (each instance keeps its own
state; ours do), not the default. What each FMU receives and the order of its calls do
not change, so neither do the results.

The interpreter's switch interval is left at CPython's 5 ms: on the free-to-air run-up
(to 0.7 s, two interleaved runs each) 1 ms and 0.1 ms were no faster (10.6-11.5 s against
10.1-10.4 s) and spent more system time on GIL hand-overs.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Sequence


class StageThreads:
    """A pool of ``n`` threads that runs the extra members' jobs of a stage."""

    def __init__(self, n: int):
        self._pool = ThreadPoolExecutor(max_workers=max(1, n), thread_name_prefix="rotorcosim-stage")
        self._closed = False
        self.runs = 0           # stage steps run (summary.json "threaded_stage_steps")

    def run(self, jobs: Sequence[Callable[[], None]]) -> list[BaseException | None]:
        """Run ``jobs`` at the same time (the first in this thread) and wait for all of them;
        returns each job's exception or None, in order. An interrupt in this thread is held
        until every job has finished (an FMU must not be freed while it steps), then raised."""
        self.runs += 1
        futures = [self._pool.submit(job) for job in jobs[1:]]
        errors: list[BaseException | None] = [None] * len(jobs)
        interrupt = None
        try:
            jobs[0]()
        except BaseException as e:            # noqa: BLE001 - reported in order by the caller
            errors[0] = e
        for k, fut in enumerate(futures, 1):
            while True:
                try:
                    errors[k] = fut.exception()
                    break
                except KeyboardInterrupt as e:    # wait for the job, then stop
                    interrupt = e
        if interrupt is not None:
            raise interrupt
        return errors

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._pool.shutdown(wait=True)


def in_worker_thread() -> bool:
    """True in one of the pool's threads (for diagnostics and tests)."""
    return threading.current_thread().name.startswith("rotorcosim-stage")
