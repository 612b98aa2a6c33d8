"""Result of a run: a frozen :class:`CoSimResult` and the :class:`Status` enum.

``Status`` values are readable messages that say what happened and what to do
(``status.name.lower()`` is the short form written to summary.json).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np


class Status(enum.Enum):
    NOT_STARTED = "not started: call setup() and initialize() first"
    RUNNING = "running: call step() until the status changes"
    FINISHED = "finished: the run reached stop_time"
    STOPPED_BY_FMU = ("stopped by an FMU: an FMU ended the simulation before stop_time (fmi2Terminated); the "
                      "message says which FMU and when, and the rows up to then are kept")
    FAILED = ("failed: the run stopped early; the message says where and why, the rows written so far are in "
              "results.csv; try a smaller macro step or check the FMU named in the message")

    @property
    def short(self) -> str:
        return self.name.lower()


@dataclass(frozen=True, kw_only=True)
class CoSimResult:
    """Outcome of :func:`orchestrator.run`.

    ``t``: output times [s]; ``outputs``: ``"inst.var" -> array`` aligned with
    ``t``; ``stats``: ``macro_steps``, ``wall_time_s``, ``fmu_calls``
    ``{instance: {"doStep": n, "set": n, "get": n, ...}}``; ``end_time``: last
    time reached; ``out_dir``: where results.csv and summary.json are.
    """

    status: Status
    message: str
    t: np.ndarray
    outputs: Mapping[str, np.ndarray]
    stats: Mapping[str, Any] = field(default_factory=dict)
    out_dir: Path | None = None
    end_time: float | None = None
    analysis: Mapping[str, Any] | None = None

    @property
    def success(self) -> bool:
        return self.status in (Status.FINISHED, Status.STOPPED_BY_FMU)

    @classmethod
    def load(cls, out_dir: str | Path) -> "CoSimResult":
        """The result of a finished (or failed) run read back from its folder (results.csv and
        summary.json, through :class:`orchestrator.results.run_directory.RunDirectory`)."""
        from orchestrator.errors import CosimError, path_arg
        from orchestrator.results.run_directory import RunDirectory
        run = RunDirectory(path_arg(out_dir, "CoSimResult.load(out_dir)", "CoSimResult.load('runs/quickstart')"))
        if not run.has_summary() and not run.has_results():
            what = "no such folder" if not run.path.exists() else (
                "not a folder" if not run.path.is_dir() else "no results.csv, results.parquet or summary.json in it")
            raise CosimError(f"{run.path}: no run folder ({what}); give the out_dir of a run (it holds "
                             "results.csv and summary.json)")
        summary = run.summary() if run.has_summary() else {}
        cols = run.columns() if run.has_results() else {"time": np.zeros(0)}
        t = cols.pop("time", np.zeros(0))
        status = Status[str(summary.get("status", "failed")).upper()] if str(
            summary.get("status", "")).upper() in Status.__members__ else Status.FAILED
        stats = {k: summary[k] for k in ("macro_steps", "rejected_steps", "retried_steps", "retry_substeps",
                                         "wall_time_s", "fmu_calls") if k in summary}
        message = str(summary.get("message", "")) if summary else (
            f"{run.summary_json} is missing: the run was killed before its summary was written, or is "
            "still running; the rows of its results file are loaded")
        return cls(status=status, message=message, t=t, outputs=cols, stats=stats,
                   out_dir=run.path, end_time=summary.get("end_time"), analysis=summary.get("analysis"))

    def __repr__(self) -> str:
        return (f"CoSimResult(status={self.status.short}, end_time={self.end_time}, rows={len(self.t)}, "
                f"signals={len(self.outputs)}, message={self.message!r})")
