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

Hand-offs (issue 16): a stage thread waits for its next job, and the master for the end of
a stage thread's job, by watching a flag in a compiled loop without the GIL
(:mod:`.handoff`, about 2 ms) before it sleeps, instead of sleeping on a queue and a future:
waking a sleeping thread cost 20-25 us here, two or three times per macro step (a stage of
two jobs of 17 us each: 67 us with the pool's queue and future, 21 us now). Measured
(farm-bench, interleaved pairs, against the pool): the shipped free-to-air run-up to 1.0 s
wall A/B 0.915 (0.895-0.963, 3 pairs), the oil bath to 1.0 s 0.914 (2 pairs), the free-to-air
run-up from rest to 1.2 s 0.89 (2 pairs); results byte-identical. The price: during a run
each stage thread keeps its core busy (CPU time +6 %), so run no more threaded runs at once
than there are cores for their threads. A hand-off that outlasts the watch (a long job, a
long pause between stages) sleeps on an event as before; with more stage threads than the
process has cores, nobody watches (every hand-off sleeps).
"""

from __future__ import annotations

import os
import threading
from typing import Callable, Sequence

from orchestrator.coupling.handoff import SPIN_TURNS, new_flags, post_and_watch, watch

IDLE, JOB, DONE = 0, 1, 2           # the states of a worker's flag slot (handoff.new_flags)


class _Worker:
    """One stage thread: watches its flag slot for a job (:mod:`.handoff`: a compiled loop
    without the GIL, then asleep on ``wake``), runs it, posts DONE and watches again."""

    def __init__(self, flags, k: int, turns: int):
        self.flags, self.i = flags, 8 * k          # slot k: its own cache line
        self.turns = turns
        self.job: Callable[[], None] | None = None
        self.error: BaseException | None = None
        self.closing = False
        # the sleeping side of a hand-off that outlasted the watch (both flags and events are
        # touched under the GIL: the poster tests ``*_asleep`` after posting, the sleeper sets
        # it before looking at the slot a last time, so no post is missed)
        self.wake = threading.Event()
        self.asleep = False
        self.finished = threading.Event()
        self.master_asleep = False
        self.thread = threading.Thread(target=self._loop, name=f"rotorcosim-stage_{k}", daemon=True)
        self.thread.start()

    def _loop(self) -> None:
        flags, i, turns = self.flags, self.i, self.turns
        got = watch(flags, i, JOB, turns)
        while True:
            while not got:              # asleep until the master posts a job (and sets wake)
                self.asleep = True
                if not watch(flags, i, JOB, 1):
                    self.wake.wait()
                self.wake.clear()
                self.asleep = False
                got = watch(flags, i, JOB, 1)
            if self.closing:
                return
            try:
                self.job()
            except BaseException as e:              # noqa: BLE001 - reported in order by run
                self.error = e
            self.job = None
            if self.master_asleep:
                self.finished.set()
            # DONE is posted from inside the compiled loop, with the GIL already released, so
            # the master finds it free when it sees DONE
            got = post_and_watch(flags, i, DONE, JOB, turns)


class StageThreads:
    """``n`` threads that run the extra members' jobs of a stage."""

    def __init__(self, n: int):
        self._flags = new_flags(n)
        # watch only while every thread of a stage has a core of its own: a thread that
        # watches on a shared core would take it from one that works
        self.turns = SPIN_TURNS if max(1, n) + 1 <= usable_cores() else 0
        self._workers = [_Worker(self._flags, k, self.turns) for k in range(max(1, n))]
        self._closed = False
        self.runs = 0           # stage steps run (summary.json "threaded_stage_steps")

    def run(self, jobs: Sequence[Callable[[], None]]) -> list[BaseException | None]:
        """Run ``jobs`` at the same time (the first in this thread) and wait for all of them;
        returns each job's exception or None, in order. An interrupt in this thread is held
        until every job has finished (an FMU must not be freed while it steps), then raised."""
        if self._closed:
            raise RuntimeError("StageThreads.run after close()")
        extra = jobs[1:]
        if len(extra) > len(self._workers):
            raise ValueError(f"StageThreads({len(self._workers)}) cannot run {len(jobs)} jobs at once")
        self.runs += 1
        flags = self._flags
        busy = self._workers[:len(extra)]
        for w, job in zip(busy, extra):
            w.job, w.error = job, None
            flags[w.i] = JOB
            if w.asleep:
                w.wake.set()
        errors: list[BaseException | None] = [None] * len(jobs)
        interrupt = None
        try:
            jobs[0]()
        except BaseException as e:            # noqa: BLE001 - reported in order by the caller
            errors[0] = e
        for k, w in enumerate(busy, 1):
            while True:
                try:
                    while not watch(flags, w.i, DONE, self.turns):
                        w.master_asleep = True          # a long job: asleep until its end
                        if flags[w.i] != DONE:
                            w.finished.wait(0.002)
                        w.finished.clear()
                        w.master_asleep = False
                    break
                except KeyboardInterrupt as e:    # wait for the job, then stop
                    interrupt = e
            flags[w.i] = IDLE
            errors[k] = w.error
        if interrupt is not None:
            raise interrupt
        return errors

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            for w in self._workers:
                w.closing = True
                self._flags[w.i] = JOB
                w.wake.set()
            for w in self._workers:
                w.thread.join(timeout=10.0)


def usable_cores() -> int:
    """The processors this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):          # not on every platform
        return os.cpu_count() or 1


def in_worker_thread() -> bool:
    """True in one of the pool's threads (for diagnostics and tests)."""
    return threading.current_thread().name.startswith("rotorcosim-stage")
