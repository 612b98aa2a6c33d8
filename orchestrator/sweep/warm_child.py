"""The child side of the warm run processes (:mod:`orchestrator.sweep.warm`): the loop that
runs scenario after scenario in a long-lived process, ``python -m orchestrator.sweep.warm_child FD``.

Kept apart from the parent side so that the sweep code the CLI imports never imports the CLI
back (the child runs ``orchestrator.cli.main``, as ``rotorcosim run`` would).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from multiprocessing.connection import Connection

from orchestrator.sweep.warm import IDLE_EXIT_S

__all__ = ["serve", "preload", "forget_vanished", "PRELOAD"]


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
    # never through a symlink planted in a run folder (task._clear_stale removes it first)
    log_fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0), 0o644)
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
