"""Warm run processes: one long-lived Python process per Dask worker that runs many scenarios.

Why: a fresh ``python -m orchestrator run`` per run pays the interpreter start, the imports
(numpy, scipy, fmpy, the orchestrator) and numba loading every cached kernel, about 2 s CPU
on the shipped Jeffcott run-ups (BENCHMARKS.md, "Sweeps"), which on short runs is as much as
the run itself. A warm process pays that once and then runs scenario after scenario, with the
kernels already in memory, exactly as ``rotorcosim run`` would (the same ``orchestrator.cli``
entry point, the same arguments).

Isolation is kept: the warm process is a *child* of the Dask worker, not the worker itself,
so an FMU that segfaults or aborts ends the child only; the run is a ``crashed`` row and the
next run starts a new child. A run that does not end with exit code 0 (failed or crashed)
also retires its child, so a half-torn-down FMU never meets the next run, and so does every
:data:`MAX_RUNS`-th run (a bound on whatever a long process accumulates). A child serves one
sweep folder (``DIR/runs``); a run for another folder gets a new child, so a long-lived
cluster picks up a changed rotorcosim with the next sweep. An idle child exits after
:data:`IDLE_EXIT_S`, and a child whose parent died ends itself (a watchdog thread sends it
SIGTERM, which a running scenario turns into a clean stop, then exits).

Protocol: a ``socket.socketpair``; the parent sends ``{"argv": [...], "log": path}`` with
``multiprocessing.connection`` pickles, the child replies ``{"rc": exit code}``. For the
duration of a run the child's file descriptors 1 and 2 point to the run's ``run.log``, so
whatever the run or a native library prints lands there.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
from multiprocessing.connection import Connection

from orchestrator.untrusted import env_number

__all__ = ["WarmProcess", "WarmPlugin", "warm_run", "prestart", "close_warm", "warm_pids", "MAX_RUNS",
           "IDLE_EXIT_S"]

# A run keeps one core busy (one single-threaded worker per core): BLAS threads on top of it
# oversubscribe the cores (a 4 x 4 expm 20 ms instead of 0.1 ms on the loaded 2-core host).
# The user's own settings win.
SINGLE_THREADED = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def run_env() -> dict[str, str]:
    """The environment of a run process (warm or fresh): this one, with single-threaded BLAS
    unless set."""
    return {**SINGLE_THREADED, **os.environ, "PYTHONUNBUFFERED": "1"}


MAX_RUNS = int(env_number("ROTORCOSIM_SWEEP_RUNS_PER_PROCESS", 50, minimum=1, maximum=10**6, integer=True,
                          meaning="runs of a sweep one warm process serves"))
IDLE_EXIT_S = 600.0


# ---------------------------------------------------------------- the parent side (in the worker)
class WarmProcess:
    """One warm child process and the connection to it."""

    def __init__(self, label: str):
        parent_sock, child_sock = socket.socketpair()
        fd = child_sock.fileno()
        self.label = label
        self.runs = 0
        # the label (the sweep's runs folder) is on the command line so that one can see whose it is
        self.proc = subprocess.Popen([sys.executable, "-m", "orchestrator.sweep.warm_child", str(fd), label],
                                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL, pass_fds=(fd,), close_fds=True, env=run_env())
        child_sock.close()
        self.conn = Connection(os.dup(parent_sock.fileno()))
        parent_sock.close()

    def alive(self) -> bool:
        return self.proc.poll() is None

    def run(self, argv: list[str], log_path: str, timeout_s: float | None) -> tuple[int, bool, bool]:
        """(exit code, whether the child survived, whether it timed out); a dead child gives
        its signal as -N."""
        self.runs += 1
        try:
            self.conn.send({"argv": list(argv), "log": log_path})
            if not self.conn.poll(timeout_s):
                self.kill()
                return -signal.SIGKILL, False, True
            reply = self.conn.recv()
            return int(reply["rc"]), True, False
        except (EOFError, OSError):           # the child died during the run
            try:
                rc = self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.kill()
                rc = -signal.SIGKILL
            return (rc if rc != 0 else -signal.SIGKILL), False, False

    def kill(self) -> None:
        try:
            self.conn.close()
        except OSError:
            pass
        if self.proc.poll() is None:
            self.proc.kill()
        try:
            self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:      # pragma: no cover
            pass

    def close(self) -> None:
        """Ask the child to exit (it closes its FMUs' process normally); kill it if it does not."""
        try:
            self.conn.send(None)
            self.proc.wait(timeout=10)
        except (OSError, EOFError, subprocess.TimeoutExpired):
            pass
        self.kill()


# The pool of this process's warm children: idle ones wait in _IDLE, each run takes one (or
# starts one) and gives it back when the run ended with exit code 0. A Dask worker thread runs
# one task at a time, so a process with N worker threads (the local cluster's workers are
# threads of the sweep's process, runner.connect) has at most N children busy at once.
_LOCK = threading.Lock()
_IDLE: list[WarmProcess] = []
_BUSY: set[WarmProcess] = set()
_ATEXIT: list[bool] = []


def _register_atexit() -> None:
    if not _ATEXIT:
        import atexit
        atexit.register(close_warm)
        _ATEXIT.append(True)


def prestart(label: str, n: int) -> None:
    """Start ``n`` warm children for the sweep folder ``label`` now, without waiting for them:
    they import the run's libraries while the cluster starts (the sweep's first runs then find
    them ready). Children already idle for ``label`` count."""
    with _LOCK:
        have = sum(1 for w in _IDLE if w.label == label and w.alive())
        for _ in range(max(0, n - have)):
            _IDLE.append(WarmProcess(label))
        _register_atexit()


def _take(label: str) -> WarmProcess:
    """An idle child for ``label`` (started when there is none); retires unusable idle ones."""
    stale = []
    with _LOCK:
        chosen = None
        for w in list(_IDLE):
            if not w.alive() or w.runs >= MAX_RUNS or w.label != label:
                _IDLE.remove(w)
                stale.append(w)
            elif chosen is None:
                _IDLE.remove(w)
                chosen = w
        if chosen is None:
            chosen = WarmProcess(label)
            _register_atexit()
        _BUSY.add(chosen)
    for w in stale:
        w.close()
    return chosen


def warm_run(argv: list[str], log_path: str, label: str, timeout_s: float | None = None) -> tuple[int, bool]:
    """Run ``python -m orchestrator ARGV`` in one of this process's warm children (started when
    none is idle): (exit code, timed out); a negative code is the signal that ended the child.
    Thread-safe: concurrent runs get different children."""
    wp = _take(label)
    try:
        rc, survived, timed_out = wp.run(argv, log_path, timeout_s)
    except BaseException:
        wp.kill()
        raise
    finally:
        with _LOCK:
            _BUSY.discard(wp)
    if rc == 0 and survived:
        with _LOCK:
            _IDLE.append(wp)
    elif survived:                        # failed: the next run gets a fresh child
        wp.close()
    else:
        wp.kill()
    return rc, timed_out


def warm_pids() -> dict[str, list[int]]:
    """The process ids of this process's warm children, idle and busy (for tests and diagnostics)."""
    with _LOCK:
        return {"idle": [w.proc.pid for w in _IDLE], "busy": [w.proc.pid for w in _BUSY]}


def close_warm() -> None:
    """End this process's warm children and reap them (so that their CPU time is accounted to
    this process). Idle ones are asked to exit; busy ones get SIGTERM (the run stops as on
    SIGTERM and its task reports it), so a closing worker never waits for a long run."""
    with _LOCK:
        idle, busy = list(_IDLE), list(_BUSY)
        _IDLE.clear()
    for w in idle:
        w.close()
    for w in busy:
        w.proc.terminate()
    for w in busy:
        try:
            w.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            w.proc.kill()


try:
    from distributed.diagnostics.plugin import WorkerPlugin as _WorkerPlugin
except ImportError:                        # pragma: no cover - dask is a dependency
    _WorkerPlugin = object


class WarmPlugin(_WorkerPlugin):
    """Dask worker plugin: the worker closes its warm child when it shuts down."""

    name = "rotorcosim-warm-run-process"

    def teardown(self, worker):
        close_warm()
