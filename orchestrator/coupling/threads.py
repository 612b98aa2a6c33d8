"""Threads of the master for the members of a stage (``coupling.parallel: threads``).

With ``parallel: threads`` the FMUs of a stage (:mod:`.stages`) that are loaded into the
master's process step at the same time: the first member in this thread, each further
one in a thread of its own, kept for the whole run. An FMI call through ctypes releases
the GIL, so two FMUs run on two cores as far as their own code does not hold it: a C FMU
entirely, our bearing FMU for its film step (:func:`bearing_fmu.fused.advance_fused`, a
numba call without the GIL), a Python FMU not at all (its Python code holds the GIL; the
run is then as fast as sequential, a little slower).

FMI 2.0 does not promise that two instances of an FMU may be called from two threads at
the same time, so this is a choice for FMUs known to allow it (each instance keeps its own
state; ours do), not the default. What each FMU receives and the order of its calls do
not change, so neither do the results.
"""

from __future__ import annotations

import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Sequence

#: the interpreter's switch interval while stages step in threads [s]: a thread whose FMU
#: call returns needs the GIL back, and with CPython's default (5 ms) it may wait that long
#: for the other thread to reach its next GIL-free call; 0.1 ms is well below a film step
SWITCH_INTERVAL = 1.0e-4


class StageThreads:
    """A pool of ``n`` threads that runs the extra members' jobs of a stage."""

    def __init__(self, n: int):
        self._pool = ThreadPoolExecutor(max_workers=max(1, n), thread_name_prefix="rotorcosim-stage")
        self._switch = sys.getswitchinterval()
        sys.setswitchinterval(min(self._switch, SWITCH_INTERVAL))
        self._closed = False

    def run(self, jobs: Sequence[Callable[[], None]]) -> list[BaseException | None]:
        """Run ``jobs`` at the same time (the first in this thread) and wait for all of them;
        returns each job's exception or None, in order. An interrupt in this thread is held
        until every job has finished (an FMU must not be freed while it steps), then raised."""
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
            sys.setswitchinterval(self._switch)


def in_worker_thread() -> bool:
    """True in one of the pool's threads (for diagnostics and tests)."""
    return threading.current_thread().name.startswith("rotorcosim-stage")
