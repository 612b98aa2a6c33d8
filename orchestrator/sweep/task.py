"""One run of a sweep, as a Dask task: the scenario in a fresh subprocess, then its summary.

:func:`execute_run` is what a Dask worker executes. It runs
``python -m orchestrator run SCENARIO --set ... --out RUN_DIR --no-progress`` with the
worker's own Python (so the workers need rotorcosim installed) and reads the
``summary.json`` the run wrote. A fresh process per run costs about one interpreter and
import start-up (measured in BENCHMARKS.md) and buys isolation: a PythonFMU that crashes,
aborts at interpreter exit (docs/dev/requests.md) or leaks memory takes down that process
only, and the run becomes a row with status ``crashed`` instead of a dead worker.

The task never raises for a failing run; it returns a plain dict (picklable, no rotorcosim
types) with ``status`` (``finished`` / ``failed`` / ``crashed``), ``message``,
``wall_time_s``, ``returncode`` and ``summary`` (the parsed summary.json or None), and
writes the same dict without the summary to ``RUN_DIR/sweep_run.json``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

__all__ = ["execute_run", "RUN_RECORD"]

RUN_RECORD = "sweep_run.json"
_STDERR_TAIL = 600


def _die_with_parent() -> None:          # pragma: no cover - runs in the child before exec
    """Linux: the run gets SIGTERM when the worker that started it dies (a killed worker must
    not leave an orphaned simulation behind); elsewhere a no-op."""
    try:
        import ctypes
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGTERM)     # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def _read_summary(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _tail(text: str) -> str:
    text = " ".join(text.strip().split())
    return text if len(text) <= _STDERR_TAIL else "..." + text[-_STDERR_TAIL:]


def _outcome(rc: int, summary: dict | None, stderr: str) -> tuple[str, str]:
    """(status, message) from the exit code and the summary.json the run left."""
    if summary is not None and summary.get("status") == "finished":
        if rc != 0:                        # a teardown crash after the results were written
            return "finished", (f"the run finished and wrote its results, then its process exited with code "
                                f"{rc} (a known PythonFMU teardown problem, docs/dev/requests.md)")
        return "finished", ""
    if summary is not None and summary.get("status"):
        return "failed", str(summary.get("message") or summary.get("status"))
    why = f"killed by signal {-rc}" if rc < 0 else f"exit code {rc}"
    err = _tail(stderr)
    return "crashed", f"the run's process ended without a summary ({why})" + (f": {err}" if err else "")


def execute_run(scenario: str, overrides: list[str], run_dir: str, *, timeout_s: float | None = None) -> dict:
    """Run one scenario with ``overrides`` into ``run_dir`` in a fresh Python process.

    Returns the run's record (see the module docstring); never raises for a failed run.
    """
    out = Path(run_dir)
    out.mkdir(parents=True, exist_ok=True)
    for stale in ("summary.json", RUN_RECORD):
        (out / stale).unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "orchestrator", "run", str(scenario), "--out", str(out), "--no-progress"]
    for text in overrides:
        cmd += ["--set", text]
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, errors="replace", env=env, timeout=timeout_s,
                              preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)
        rc, stderr = proc.returncode, proc.stderr
        (out / "run.log").write_text(proc.stdout + ("\n--- stderr ---\n" + proc.stderr if proc.stderr else ""),
                                     encoding="utf-8")
    except subprocess.TimeoutExpired as exc:
        rc, stderr = -signal.SIGKILL, f"timed out after {exc.timeout:g} s"
    wall = time.perf_counter() - t0
    summary = _read_summary(out / "summary.json")
    status, message = _outcome(rc, summary, stderr)
    record = {"status": status, "message": message, "wall_time_s": wall, "returncode": rc,
              "overrides": list(overrides)}
    (out / RUN_RECORD).write_text(json.dumps(record, indent=1), encoding="utf-8")
    record["summary"] = summary
    return record


def trivial_run(seconds: float = 0.0) -> dict:
    """A task that does nothing (sleeps ``seconds``): the scheduling-overhead benchmark's run."""
    if seconds:
        time.sleep(seconds)
    return {"status": "finished", "message": "", "wall_time_s": seconds, "returncode": 0, "summary": {}}
