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

__all__ = ["WarmProcess", "WarmPlugin", "warm_run", "close_warm", "MAX_RUNS", "IDLE_EXIT_S"]

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


_LOCK = threading.Lock()
_CURRENT: WarmProcess | None = None
_ATEXIT: list[bool] = []


def _register_atexit() -> None:
    if not _ATEXIT:
        import atexit
        atexit.register(close_warm)
        _ATEXIT.append(True)


def warm_run(argv: list[str], log_path: str, label: str, timeout_s: float | None = None) -> tuple[int, bool]:
    """Run ``python -m orchestrator ARGV`` in this process's warm child (started when needed):
    (exit code, timed out); a negative code is the signal that ended the child. One run at a
    time per process."""
    global _CURRENT
    with _LOCK:
        if _CURRENT is not None and (not _CURRENT.alive() or _CURRENT.label != label
                                     or _CURRENT.runs >= MAX_RUNS):
            _CURRENT.close()
            _CURRENT = None
        if _CURRENT is None:
            _CURRENT = WarmProcess(label)
            _register_atexit()
        rc, survived, timed_out = _CURRENT.run(argv, log_path, timeout_s)
        if rc != 0 or not survived:           # failed or crashed: the next run gets a fresh child
            if survived:
                _CURRENT.close()
            else:
                _CURRENT.kill()
            _CURRENT = None
        return rc, timed_out


def close_warm() -> None:
    """End this process's warm child, if any, and reap it (so that its CPU time is accounted to
    the worker). Between runs it is asked to exit; during a run it gets SIGTERM (the run stops
    as on SIGTERM and that task reports it), so a closing worker never waits for a long run."""
    global _CURRENT
    cur = _CURRENT
    if cur is None:
        return
    if _LOCK.acquire(blocking=False):
        try:
            cur.close()
            _CURRENT = None
        finally:
            _LOCK.release()
        return
    cur.proc.terminate()
    try:
        cur.proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        cur.proc.kill()


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


def serve(fd: int) -> None:
    """The child's loop: run requests until the parent closes the connection or sends None."""
    conn = Connection(fd)
    threading.Thread(target=_watch_parent, args=(os.getppid(),), daemon=True).start()
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
