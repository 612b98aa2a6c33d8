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

Watching pays only while each thread has a core to itself. Another busy process on the same
cores (a second run, a build, a browser) makes the watching threads take turns with the ones
that work: measured with one busy-looping process beside the oil-bath run-up on 2 cores, a
macro step took 6.1-7.5 ms with watching against 2.4-2.5 ms with sleeping hand-offs
(``benchmarks/bench_stage_split.py``, BENCHMARKS.md session 18). So the pool measures which
pays (:class:`HandoffChooser`): it times windows of stage steps with and without watching,
keeps the faster mode and measures again later (``ROTORCOSIM_STAGE_HANDOFF``: ``auto``, the
default; ``watch`` or ``sleep`` to fix the mode). The mode changes when a hand-off happens,
never what the FMUs receive, so results do not depend on it.
"""

from __future__ import annotations

import os
import threading
import time
from typing import Callable, Sequence

from orchestrator.coupling.handoff import SPIN_TURNS, new_flags, post_and_watch, watch

IDLE, JOB, DONE = 0, 1, 2           # the states of a worker's flag slot (handoff.new_flags)
HANDOFF_MODES = ("auto", "watch", "sleep")


class HandoffChooser:
    """Which hand-off pays now, watching or sleeping (module doc), by timing the pool's use.

    :meth:`tick` is called at the start of every stage step with the clock and returns
    whether that step watches. The time from one window's first step to the next window's
    first step (``window`` steps, with the master's serial work between them) is the cost
    of the window's mode. A probe times one window in each mode, in turn watching first and
    sleeping first (neighbouring windows cost about the same whatever the run does), and the
    faster mode then runs for ``hold`` windows. The hold doubles, up to ``max_hold``, while
    probes keep choosing the same mode, and falls back to ``min_hold`` when the choice changes.
    Which mode pays also changes within a run and from one run to the next, not only with
    the machine's load (``benchmarks/bench_handoff_modes.py``: the oil-bath run-up to 1.2 s
    recorded in both modes, three times on this 2-vCPU host with nothing else running; mean
    period of a stage step in the quiet phase and at the end of the window, watching against
    sleeping: 1.01 / 3.84 against 1.62 / 2.98 ms, then 1.15 / 3.28 against 1.40 / 3.92 ms, then
    1.32 / 3.08 against 1.39 / 2.73 ms). The cost of the whirl grows over many windows, without a
    jump, so the hold is kept short (at most 16 windows of 64 steps). Replayed on those
    recordings, this chooser gave 21.5 / 23.1 / 21.1 s where the better fixed mode gave
    23.3 / 22.8 / 21.4 s and the better mode of every window 20.3 / 22.3 / 20.3 s. Whole
    runs (BENCHMARKS.md session 18): on the quiet host 0.99x the wall time of always
    watching; beside one busy process 0.48x."""

    def __init__(self, window: int = 64, min_hold: int = 4, max_hold: int = 16, jump: float = 1.3):
        self.window, self.min_hold, self.max_hold, self.jump = window, min_hold, max_hold, jump
        self.hold = min_hold
        self.plan: list[bool] = [True, False]      # the modes of the probe windows still to come
        self.timed: bool | None = None              # mode of the window being timed (None: holding)
        self.cost: dict[bool, float] = {}
        self.watching = True
        self.left = 0                               # steps left in the current window
        self.holding = 0                            # windows left before the next probe
        self.start: float | None = None             # clock at the current window's first step
        self.ref = 0.0                              # cost of the last window in the held mode
        self.flip = False                           # order of the next probe
        self.choices: list[bool] = []               # every probe's choice (diagnostics, tests)

    def tick(self, now: float) -> bool:
        self.left -= 1
        if self.left > 0:
            return self.watching
        # a window ends here (or the first one starts)
        cost = None if self.start is None else now - self.start
        self.start, self.left = now, self.window
        if self.timed is not None:
            self.cost[self.timed] = cost
        if not self.plan and self.timed is not None:    # the probe is complete: choose
            choice = self.cost[True] <= self.cost[False]
            same = bool(self.choices) and self.choices[-1] == choice
            self.hold = min(2 * self.hold, self.max_hold) if same else self.min_hold
            self.choices.append(choice)
            self.watching, self.timed, self.holding = choice, None, self.hold
            self.ref = self.cost[choice]
        elif not self.plan and cost is not None:    # holding
            self.holding -= 1
            # a window that cost much more or less than the last one in this mode: the
            # machine's load may have changed (or the run's work: a probe costs two windows)
            moved = not self.ref / self.jump <= cost <= self.ref * self.jump
            self.ref = cost
            if self.holding <= 0 or moved:          # probe again, in the other order
                self.flip = not self.flip
                self.plan = [False, True] if self.flip else [True, False]
        if self.plan:                               # the probe's next window
            self.watching = self.timed = self.plan.pop(0)
        return self.watching


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
        flags, i = self.flags, self.i
        got = watch(flags, i, JOB, self.turns)
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
            got = post_and_watch(flags, i, DONE, JOB, self.turns)   # turns: the pool's mode now


class StageThreads:
    """``n`` threads that run the extra members' jobs of a stage."""

    def __init__(self, n: int, handoff: str | None = None):
        self._flags = new_flags(n)
        mode = (handoff or os.environ.get("ROTORCOSIM_STAGE_HANDOFF", "") or "auto").strip().lower()
        if mode not in HANDOFF_MODES:
            from orchestrator.untrusted import SettingError
            raise SettingError(f"ROTORCOSIM_STAGE_HANDOFF must be one of {list(HANDOFF_MODES)} (got {mode!r}); "
                               "unset it for the default 'auto'")
        # watch only while every thread of a stage has a core of its own: a thread that
        # watches on a shared core would take it from one that works
        if max(1, n) + 1 > usable_cores():
            mode = "sleep"
        self._chooser = HandoffChooser() if mode == "auto" else None
        self.turns = 0 if mode == "sleep" else SPIN_TURNS
        self._workers = [_Worker(self._flags, k, self.turns) for k in range(max(1, n))]
        self._closed = False
        self.runs = 0           # stage steps run (summary.json "threaded_stage_steps")
        self.watched = 0        # of them with watching hand-offs ("threaded_stage_steps_watched")

    def _set_watching(self, on: bool) -> None:
        self.turns = SPIN_TURNS if on else 0
        for w in self._workers:
            w.turns = self.turns

    def run(self, jobs: Sequence[Callable[[], None]]) -> list[BaseException | None]:
        """Run ``jobs`` at the same time (the first in this thread) and wait for all of them;
        returns each job's exception or None, in order. An interrupt in this thread is held
        until every job has finished (an FMU must not be freed while it steps), then raised."""
        if self._closed:
            raise RuntimeError("StageThreads.run after close()")
        extra = jobs[1:]
        if len(extra) > len(self._workers):
            raise ValueError(f"StageThreads({len(self._workers)}) cannot run {len(jobs)} jobs at once")
        if self._chooser is not None:
            on = self._chooser.tick(time.perf_counter())
            if on != (self.turns > 0):
                self._set_watching(on)
        self.runs += 1
        self.watched += self.turns > 0
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
