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
                 "n_steps", "end_time", "rejected", "kinds", "typed", "grid")

    def __init__(self, columns: Sequence[str], t_start: float, t_stop: float, n_steps: int, *,
                 kinds: Sequence[str] | None = None, grid=None):
        self.columns = tuple(columns)
        # FMI type per column; ``row`` holds every column as float (String: NaN), ``typed`` the
        # values of the non-Real columns as int/bool/str (None for Real columns)
        self.kinds = tuple(kinds) if kinds is not None else ("Real",) * len(self.columns)
        self.typed: list = [None] * len(self.columns)
        self.grid = grid                  # a results.writer.TimeGrid: time of row n from the index, or None
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


HOOKS = ("on_initialized", "on_step_complete", "on_step_rejected", "on_terminated")


def check_observers(observers, call: str) -> tuple:
    """``observers`` as a tuple of objects with every observer hook, or a TypeError naming ``call``
    and the first that is not one (an int among them used to fail mid-run, "'int' object has no
    attribute 'on_initialized'", after the output folder was set up)."""
    if isinstance(observers, (str, bytes)) or not hasattr(observers, "__iter__"):
        raise TypeError(f"{call} takes a list of Observer objects (got {type(observers).__name__}); "
                        "e.g. observers=[MyObserver()], with MyObserver a subclass of "
                        "orchestrator.coupling.observers.Observer")
    observers = tuple(observers)
    for i, o in enumerate(observers):
        missing = [h for h in HOOKS if not callable(getattr(o, h, None))]
        if missing:
            raise TypeError(f"{call}: item {i} ({type(o).__name__} {o!r:.60}) is no observer: it has no "
                            f"{missing[0]}() method; subclass orchestrator.coupling.observers.Observer (its hooks "
                            "do nothing until you override them)")
    return observers


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
    """Keeps the output rows in memory for :class:`CoSimResult` (``t``, ``outputs``).

    Rows go into float64 blocks of ``CHUNK`` rows (8 bytes per value, no object
    per row). ``keep=False`` keeps nothing (a run that streams results.csv reads
    its result back from the file, so memory stays flat in the number of rows).
    String columns are kept as lists of str when kept.
    """

    CHUNK = 4096

    def __init__(self, expected_rows: int = 0, *, keep: bool = True):
        self.keep = keep
        self._blocks: list[np.ndarray] = []
        self._n = 0
        self._t: list[np.ndarray] = []
        self._text: dict[int, list[str]] = {}
        self.columns: tuple[str, ...] = ()

    def _take(self, view: RunView) -> None:
        if not (view.is_output and self.keep):
            return
        i = self._n % self.CHUNK
        if i == 0:
            self._blocks.append(np.empty((self.CHUNK, len(self.columns))))
            self._t.append(np.empty(self.CHUNK))
        self._blocks[-1][i] = view.row
        self._t[-1][i] = view.grid.time(view.n) if view.grid is not None else view.t
        for j in self._text:
            self._text[j].append(view.typed[j])
        self._n += 1

    def on_initialized(self, view):
        self.columns = view.columns
        self._text = {j: [] for j, k in enumerate(view.kinds) if k == "String"}
        self._take(view)

    def on_step_complete(self, view):
        self._take(view)

    def arrays(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        n = self._n
        t = np.concatenate(self._t)[:n] if self._t else np.zeros(0)
        data = np.concatenate(self._blocks)[:n] if self._blocks else np.zeros((0, len(self.columns)))
        out = {c: data[:, i].copy() for i, c in enumerate(self.columns)}
        for j, vals in self._text.items():
            out[self.columns[j]] = np.asarray(vals, dtype=object)
        return t, out


class CsvWriter(Observer):
    """Streams ``results.csv`` (or ``results.parquet``) through :class:`orchestrator.results.writer.ResultsWriter`.

    Header ``time,<inst>.<var>,...`` written by the csv module; one row per
    output time, the time from the step index (``view.grid``) when the master
    gives one. The file is flushed at least every ``flush_interval`` seconds of
    wall time and at termination, so a run that stops early (or is watched
    with ``tail -f``) keeps every row written.
    """

    def __init__(self, path: Path | str, *, flush_interval: float = 1.0, format: str = "csv"):
        self.path = Path(path)
        self.flush_interval = flush_interval
        self.format = format
        self._w = None
        self._typed: list[int] = []

    def on_initialized(self, view):
        from orchestrator.results.writer import ResultsWriter
        self._w = ResultsWriter(self.path, view.columns, view.kinds, format=self.format,
                                flush_interval=self.flush_interval)
        self._w.open()
        self._typed = [j for j, k in enumerate(view.kinds) if k != "Real"]
        self._write(view)
        self._w.flush()

    def _write(self, view):
        if view.is_output and self._w is not None:
            t = view.grid.time(view.n) if view.grid is not None else view.t
            if self._typed:
                values = view.row.tolist()
                for j in self._typed:
                    values[j] = view.typed[j]
                self._w.write(t, values)
            else:
                self._w.write(t, view.row)

    def on_step_complete(self, view):
        self._write(view)

    def flush(self) -> None:
        """Write the buffered rows out now (the stop watchdog, coupling/lifecycle.py, calls it from
        its thread while the main thread is stuck inside an FMU call)."""
        if self._w is not None:
            self._w.flush()

    def on_terminated(self, view):
        if self._w is not None:
            self._w.close()
            self._w = None


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
            if self._bar.total != view.n_steps:     # an estimate made exact (step_control.until reached)
                self._bar.total = view.n_steps
            self._bar.update(view.n - self._last_n)
            self._bar.set_postfix_str(f"t={view.t:.6g}/{view.t_stop:.6g} s", refresh=False)
            self._last_n = view.n

    def on_terminated(self, view):
        if self._bar is not None:
            self._bar.update(view.n - self._last_n)
            self._bar.close()
            self._bar = None
