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
import time
from multiprocessing.connection import Connection

__all__ = ["WarmProcess", "WarmPlugin", "warm_run", "prestart", "close_warm", "warm_pids", "MAX_RUNS",
           "IDLE_EXIT_S"]

MAX_RUNS = int(os.environ.get("ROTORCOSIM_SWEEP_RUNS_PER_PROCESS", "50") or 50)
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
        from orchestrator.sweep.task import run_env
        self.proc = subprocess.Popen([sys.executable, "-m", "orchestrator.sweep.warm", str(fd), label],
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


# ---------------------------------------------------------------- the child side
def _watch_parent(parent: int) -> None:
    """End this process when its parent (the Dask worker) is gone."""
    while True:
        time.sleep(0.5)
        if os.getppid() != parent:
            os.kill(os.getpid(), signal.SIGTERM)    # a running scenario stops cleanly (exit 143)
            time.sleep(20)
            os._exit(143)


def _clear_warning_registries() -> None:
    """Python shows a warning once per place and process; a run in a warm process should show
    the warnings a fresh process would."""
    for mod in list(sys.modules.values()):
        reg = getattr(mod, "__warningregistry__", None)
        if isinstance(reg, dict):
            reg.clear()


def forget_vanished(modules_before: set[str], path_before: list[str]) -> list[str]:
    """Drop what a run imported from folders that are gone (an FMU's extracted ``resources/``,
    deleted at the run's end): such a module, left in ``sys.modules``, would be reused by the
    next run and fail on its first lazy import; the next run imports it again from its own
    extraction, as a fresh process would. Returns the names dropped."""
    import importlib
    dropped = []
    for name in [n for n in list(sys.modules) if n not in modules_before]:
        f = getattr(sys.modules.get(name), "__file__", None)
        if isinstance(f, str) and os.path.isabs(f) and not os.path.exists(f):
            del sys.modules[name]
            dropped.append(name)
    keep = set(path_before)
    sys.path[:] = [p for p in sys.path if p in keep or not os.path.isabs(p) or os.path.isdir(p)]
    for p in [p for p in sys.path_importer_cache if isinstance(p, str) and os.path.isabs(p)
              and not os.path.exists(p)]:
        del sys.path_importer_cache[p]
    importlib.invalidate_caches()
    return dropped


def _run_one(main, argv: list[str], log_path: str) -> int:
    """``main(argv)`` with file descriptors 1 and 2 on ``log_path``; its exit code."""
    sys.stdout.flush()
    sys.stderr.flush()
    modules_before, path_before = set(sys.modules), list(sys.path)
    saved = os.dup(1), os.dup(2)
    log_fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    try:
        os.dup2(log_fd, 1)
        os.dup2(log_fd, 2)
        _clear_warning_registries()
        try:
            rc = main(argv)
        except SystemExit as exc:             # argparse errors, sys.exit in a run
            rc = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException:                 # noqa: BLE001 - reported in the run's log, exit code 1
            import traceback
            traceback.print_exc()
            rc = 1
        return int(rc or 0)
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, log_fd):
            os.close(fd)
        forget_vanished(modules_before, path_before)


# What a fresh ``rotorcosim run`` of the shipped scenarios imports anyway, in the order it
# does: the orchestrator's run path, fmpy and pythonfmu (before any FMU is loaded), and the
# third-party libraries the shipped FMUs' code imports from the environment (numpy,
# scipy.linalg, numba). Nothing of an FMU's own code (its resources/ folder) is imported here:
# each run imports that from its own extraction, as a fresh process does.
PRELOAD = ("orchestrator.cli", "orchestrator.scenario", "orchestrator.scenario.ssp", "orchestrator.workflow",
           "orchestrator.results.run_directory", "orchestrator.results.whirl", "orchestrator.fmi.build",
           "orchestrator.shipped", "fmpy", "pythonfmu", "numpy", "scipy.linalg", "numba")


def preload() -> float:
    """Import :data:`PRELOAD` and set up numba's CPU target (its first use in a process loads
    ~250 lowering registries, ~0.4 s): the fixed cost of a run process's first run, paid while
    the process waits for it (BENCHMARKS.md, "Sweeps", session 3). A module that fails to
    import is skipped (the run that needs it reports it). Returns the seconds it took."""
    import importlib
    t0 = time.perf_counter()
    for name in PRELOAD:
        try:
            importlib.import_module(name)
        except Exception:                     # noqa: BLE001 - a run that needs it reports it
            continue
    try:
        from numba.core.registry import cpu_target
        cpu_target.target_context.refresh()
    except Exception:                         # noqa: BLE001 - numba missing or changed: no preload
        pass
    return time.perf_counter() - t0


def serve(fd: int) -> None:
    """The child's loop: run requests until the parent closes the connection or sends None."""
    conn = Connection(fd)
    # Ctrl-C belongs to the sweep's client (it cancels and closes the cluster); a run installs
    # its own SIGINT/SIGTERM handling while it runs (orchestrator.coupling.lifecycle)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_parent, args=(os.getppid(),), daemon=True).start()
    if os.environ.get("ROTORCOSIM_SWEEP_PRELOAD", "1") != "0":
        preload()
    from orchestrator.cli import main
    while conn.poll(IDLE_EXIT_S):
        try:
            req = conn.recv()
        except EOFError:
            break
        if req is None:
            break
        conn.send({"rc": _run_one(main, req["argv"], req["log"])})


if __name__ == "__main__":
    serve(int(sys.argv[1]))
    # no interpreter teardown: PythonFMU-built FMUs abort there intermittently
    # (orchestrator.cli.console_main); every run's files are closed by now
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)
