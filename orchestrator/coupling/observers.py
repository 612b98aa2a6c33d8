"""Observers: read-only watchers of a run (recording, CSV, progress).

Call order (by :class:`orchestrator.coupling.execution.MasterAlgorithm`)::

    on_initialized(view)            after initialization, outputs at start_time valid
    on_step_complete(view)          after every accepted macro step
    on_step_rejected(view)          after a step attempt was rejected and rolled back (the step-size
                                    controller retries it); view.rejected = (t_a, t_b, reason)
    on_terminated(view)             once, after finish or failure (also after a failed step)

``view`` is a :class:`RunView` (time, step index, the recorded row, status,
message). Observers must not change it. Rows are offered at output times
only: ``view.is_output`` tells whether the current point is one.
"""

from __future__ import annotations

import sys
import time as _time
from pathlib import Path
from typing import Sequence

import numpy as np


class RunView:
    """Read-only state of the run as observers see it (filled in by the master)."""

    __slots__ = ("t", "n", "row", "columns", "is_output", "status", "message", "t_start", "t_stop",
                 "n_steps", "end_time", "rejected")

    def __init__(self, columns: Sequence[str], t_start: float, t_stop: float, n_steps: int):
        self.columns = tuple(columns)
        self.t = t_start
        self.n = 0
        self.row = np.zeros(len(columns))
        self.is_output = False
        self.status = None
        self.message = ""
        self.t_start = t_start
        self.t_stop = t_stop
        self.n_steps = n_steps
        self.end_time = t_start
        self.rejected = None        # (t_a, t_b, reason) during on_step_rejected


class Observer:
    """Base class with no-op hooks."""

    def on_initialized(self, view: RunView) -> None:
        pass

    def on_step_complete(self, view: RunView) -> None:
        pass

    def on_step_rejected(self, view: RunView) -> None:
        pass

    def on_terminated(self, view: RunView) -> None:
        pass


class Recorder(Observer):
    """Keeps the output rows in memory for :class:`CoSimResult` (``t``, ``outputs``)."""

    def __init__(self, expected_rows: int = 0):
        self._rows: list[np.ndarray] = []
        self._t: list[float] = []
        self.columns: tuple[str, ...] = ()

    def _take(self, view: RunView) -> None:
        if view.is_output:
            self._t.append(view.t)
            self._rows.append(view.row.copy())

    def on_initialized(self, view):
        self.columns = view.columns
        self._take(view)

    def on_step_complete(self, view):
        self._take(view)

    def arrays(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        t = np.asarray(self._t, dtype=float)
        data = np.vstack(self._rows) if self._rows else np.zeros((0, len(self.columns)))
        return t, {c: data[:, i].copy() for i, c in enumerate(self.columns)}


class CsvWriter(Observer):
    """Streams ``results.csv``: header ``time,<inst>.<var>,...``, one row per output time.

    Rows are written as they come and the file is flushed at least every
    ``flush_interval`` seconds of wall time and at termination, so a run that
    stops early (or is watched with ``tail -f``) keeps every row written.
    """

    def __init__(self, path: Path | str, *, flush_interval: float = 0.5):
        self.path = Path(path)
        self.flush_interval = flush_interval
        self._f = None
        self._last_flush = 0.0

    def on_initialized(self, view):
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._f = open(self.path, "w", newline="")
        self._f.write("time," + ",".join(view.columns) + "\n")
        self._write(view)
        self._f.flush()
        self._last_flush = _time.monotonic()

    def _write(self, view):
        if view.is_output and self._f is not None:
            self._f.write(repr(float(view.t)) + "," + ",".join(map(repr, view.row.tolist())) + "\n")
            now = _time.monotonic()
            if now - self._last_flush > self.flush_interval:
                self._f.flush()
                self._last_flush = now

    def on_step_complete(self, view):
        self._write(view)

    def on_terminated(self, view):
        if self._f is not None:
            self._f.flush()
            self._f.close()
            self._f = None


class Progress(Observer):
    """Progress bar with time left (tqdm, on stderr).

    ``enabled``: None -> shown when stderr is a terminal and the run has lasted
    longer than ``delay`` seconds of wall time; True -> always (after
    ``delay``); False -> never.
    """

    def __init__(self, enabled: bool | None = None, *, delay: float = 2.0, stream=None):
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        self.enabled = enabled
        self.delay = delay
        self._bar = None
        self._t0 = 0.0
        self._check_every = 1
        self._last_n = 0

    def on_initialized(self, view):
        self._t0 = _time.monotonic()

    def on_step_complete(self, view):
        if not self.enabled:
            return
        if self._bar is None:
            if view.n % 64 and view.n < view.n_steps:
                return
            if _time.monotonic() - self._t0 < self.delay:
                return
            from tqdm import tqdm
            self._bar = tqdm(total=view.n_steps, initial=view.n, file=self.stream, unit="step",
                             desc="co-simulation", dynamic_ncols=True, mininterval=0.5)
            self._last_n = view.n
            return
        if view.n - self._last_n >= 16 or view.n >= view.n_steps:
            self._bar.update(view.n - self._last_n)
            self._bar.set_postfix_str(f"t={view.t:.6g}/{view.t_stop:.6g} s", refresh=False)
            self._last_n = view.n

    def on_terminated(self, view):
        if self._bar is not None:
            self._bar.update(view.n - self._last_n)
            self._bar.close()
            self._bar = None
