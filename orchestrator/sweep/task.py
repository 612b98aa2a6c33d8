"""One run of a sweep, as a Dask task: the scenario in a run process of the worker, then its summary.

:func:`execute_run` is what a Dask worker executes. It runs the equivalent of
``python -m orchestrator run SCENARIO --set ... --out RUN_DIR --no-progress`` with the
worker's own Python (so the workers need rotorcosim installed) and reads the
``summary.json`` the run wrote. By default the run goes to the worker's warm run process
(:mod:`orchestrator.sweep.warm`: one long-lived child of the worker that runs run after run,
so the interpreter start, the imports and numba's kernel loading are paid once per worker);
``warm=False`` starts a fresh process for the run. Either way the run is not in the worker
itself: a PythonFMU that crashes, aborts or leaks memory takes down that process only, and
the run becomes a row with status ``crashed`` instead of a dead worker.

The task never raises for a failing run; it returns a plain dict (picklable, no rotorcosim
types) with ``status`` (``finished`` / ``failed`` / ``crashed``, or ``cancelled`` for a run that a signal
stopped: its summary has ``stopped_by``), ``message``,
``wall_time_s``, ``returncode`` and ``summary`` (the parsed summary.json or None), and
writes the same dict without the summary to ``RUN_DIR/sweep_run.json``.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from orchestrator.sweep.warm import run_env

__all__ = ["execute_run", "RUN_RECORD"]

RUN_RECORD = "sweep_run.json"
_STDERR_TAIL = 600


def _die_with_parent() -> None:          # pragma: no cover - runs in the child before exec
    """Linux: the run gets SIGTERM when the worker that started it dies (a killed worker must
    not leave an orphaned simulation behind), and starts with Ctrl-C (SIGINT) ignored: Ctrl-C
    belongs to the sweep's client, which cancels and closes the cluster (a run installs its own
    SIGINT handling while it steps); elsewhere a no-op."""
    try:
        import ctypes
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGTERM)     # PR_SET_PDEATHSIG
        libc.signal.argtypes = (ctypes.c_int, ctypes.c_void_p)
        libc.signal(int(signal.SIGINT), ctypes.c_void_p(1))   # SIG_IGN
    except (OSError, AttributeError):
        pass


def _read_summary(path: Path) -> dict | None:
    """The run's summary.json with the bounded reader (None when missing or unusable)."""
    from orchestrator.untrusted import InputError, load_json
    try:
        data = load_json(path, what="summary.json")
    except InputError:
        return None
    return data if isinstance(data, dict) else None


def _clear_stale(out: Path) -> None:
    """Remove an earlier run's summary.json, sweep_run.json and run.log from ``out`` (the run
    writes them anew): files and symlinks are unlinked (a planted symlink is never written
    through), a directory in their place (which the run could not write over) is removed with
    its content; the folder is this sweep's own ``runs/<run_id>``."""
    import shutil
    for name in ("summary.json", RUN_RECORD, "run.log"):
        path = out / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)


def _tail(text: str) -> str:
    text = " ".join(text.strip().split())
    return text if len(text) <= _STDERR_TAIL else "..." + text[-_STDERR_TAIL:]


def _outcome(rc: int, summary: dict | None, stderr: str, run_dir: Path | None = None) -> tuple[str, str]:
    """(status, message) from the exit code and the summary.json the run left."""
    if summary is not None and summary.get("status") == "finished":
        if rc != 0:                        # a teardown crash after the results were written
            return "finished", (f"the run finished and wrote its results, then its process exited with code "
                                f"{rc} (a known PythonFMU teardown problem, docs/dev/requests.md)")
        return "finished", ""
    if summary is not None and summary.get("stopped_by") and summary.get("status") not in (None, "", "running"):
        # stopped by a signal (Ctrl-C reaches the whole process group; a closing worker sends
        # SIGTERM): the run did not fail, it was not let finish; --resume runs it again
        return "cancelled", f"{summary.get('message') or 'stopped by ' + str(summary['stopped_by'])}; rerun with --resume"
    if summary is not None and summary.get("status") not in (None, "", "running"):
        return "failed", str(summary.get("message") or summary.get("status"))
    # no summary, or the one a run writes at its start ("running"): the process died mid-run
    why = f"killed by signal {-rc}{_signal_name(-rc)}" if rc < 0 else f"exit code {rc}"
    calls = []
    if run_dir is not None:        # where it died: the FMI call that never returned (fmi/call_record.py)
        from orchestrator.coupling.lifecycle import open_calls
        calls = open_calls(run_dir)
    hint = ""
    if calls:
        from orchestrator.fmi.call_record import describe_calls
        why += f", in {describe_calls(calls)}"
        # the FMU was in the run's own process (an isolated one's crash is a failed run with a summary)
        names = sorted({n for n, _, _ in calls})
        hint = ("; the FMU ran in the run's own process, so its crash took the run's summary and rows with it: "
                + " or ".join(f"fmus.{n}.isolation: process" for n in names)
                + " (or coupling.isolation: process) reports such a crash as a failed run and keeps the rows "
                "before it (docs/coupling.md)")
    err = _tail(stderr)
    return "crashed", f"the run's process ended without a summary ({why})" + (f": {err}" if err else "") + hint


def _signal_name(number: int) -> str:
    """`` (SIGSEGV)`` for a known signal number, else nothing."""
    import signal
    try:
        return f" ({signal.Signals(number).name})"
    except ValueError:
        return ""


def execute_run(scenario: str, overrides: list[str], run_dir: str, *, timeout_s: float | None = None,
                warm: bool = True, inputs: dict | None = None) -> dict:
    """Run one scenario with ``overrides`` into ``run_dir`` in a separate Python process.

    ``warm`` (default): in this worker's warm run process (:mod:`orchestrator.sweep.warm`),
    started on the first run and reused; otherwise a fresh process for this run only.
    ``inputs``: the digests of the files the run computes from (``plan.run_inputs``), kept in
    the record for ``--resume``.
    Returns the run's record (see the module docstring); never raises for a failed run.
    """
    out = Path(run_dir)
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        # runs/<run_id> is the sweep's own; a file there ended the run as "crashed: the task failed
        # on its worker: FileExistsError: [Errno 17] File exists", and a symbolic link (to ~, say)
        # made the run write its results, summary and log wherever it pointed
        out.unlink()
    out.mkdir(parents=True, exist_ok=True)
    _clear_stale(out)
    args = ["run", str(scenario), "--out", str(out), "--no-progress"]
    for text in overrides:
        args += ["--set", text]
    t0 = time.perf_counter()
    if warm:
        rc, stderr = _warm(args, out, timeout_s)
    else:
        rc, stderr = _fresh(args, out, timeout_s)
    wall = time.perf_counter() - t0
    summary = _read_summary(out / "summary.json")
    status, message = _outcome(rc, summary, stderr, out)
    record = {"status": status, "message": message, "wall_time_s": wall, "returncode": rc,
              "overrides": list(overrides)}
    if inputs:
        record["inputs"] = inputs
    (out / RUN_RECORD).write_text(json.dumps(record, indent=1), encoding="utf-8")
    record["summary"] = summary
    return record


_FRESH: set[subprocess.Popen] = set()  # this process's fresh run processes running now (see stop_fresh)
_FRESH_LOCK = threading.Lock()


def _fresh(args: list[str], out: Path, timeout_s: float | None) -> tuple[int, str]:
    """``python -m orchestrator ARGS`` in a new process: (exit code, its stderr)."""
    env = run_env()
    proc = subprocess.Popen([sys.executable, "-m", "orchestrator", *args], stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, errors="replace", env=env,
                            preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)
    with _FRESH_LOCK:
        _FRESH.add(proc)
    try:
        stdout, stderr = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired as exc:
        proc.kill()
        proc.wait()                    # as subprocess.run: not communicate, a grandchild may hold the pipes
        return -signal.SIGKILL, f"timed out after {exc.timeout:g} s"
    finally:
        with _FRESH_LOCK:
            _FRESH.discard(proc)
    (out / "run.log").write_text(stdout + ("\n--- stderr ---\n" + stderr if stderr else ""), encoding="utf-8")
    return proc.returncode, stderr


def stop_fresh(timeout_s: float = 30.0) -> None:
    """SIGTERM to the fresh run processes of this process's tasks still running, and wait until
    they ended (the run stops as on SIGTERM and writes its final summary). For an interrupted
    sweep on its local cluster, whose workers are threads of the sweep's process: closing the
    cluster does not end a thread waiting for its run, so with ``--fresh-processes`` the runs
    went on after the sweep said they were interrupted (the warm run processes are ended by
    :func:`orchestrator.sweep.warm.close_warm` when their worker closes)."""
    with _FRESH_LOCK:
        procs = list(_FRESH)
    for p in procs:
        p.terminate()
    for p in procs:
        try:
            p.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            p.kill()


def _warm(args: list[str], out: Path, timeout_s: float | None) -> tuple[int, str]:
    """The same in the worker's warm process: (exit code, the end of run.log, where it printed)."""
    from orchestrator.sweep.warm import warm_run
    log = out / "run.log"
    rc, timed_out = warm_run(args, str(log), label=str(out.parent), timeout_s=timeout_s)
    if timed_out:
        return rc, f"timed out after {timeout_s:g} s"
    return rc, _log_tail(log) if rc else ""


def _log_tail(log: Path) -> str:
    """The last ``4 * _STDERR_TAIL`` characters of ``log``, reading only its end (a run may
    print a lot); '' when it is missing or not a regular file."""
    from orchestrator.untrusted import InputError, open_regular
    try:
        with open_regular(log, what="run log") as fh:
            size = fh.seek(0, 2)
            fh.seek(max(0, size - 16 * _STDERR_TAIL))
            return fh.read().decode("utf-8", errors="replace")[-4 * _STDERR_TAIL:]
    except (InputError, OSError):
        return ""


def trivial_run(seconds: float = 0.0) -> dict:
    """A task that does nothing (sleeps ``seconds``): the scheduling-overhead benchmark's run."""
    if seconds:
        time.sleep(seconds)
    return {"status": "finished", "message": "", "wall_time_s": seconds, "returncode": 0, "summary": {}}
