"""Result of a run: a frozen :class:`CoSimResult` and the :class:`Status` enum.

``Status`` values are readable messages that say what happened and what to do
(``status.name.lower()`` is the short form written to summary.json).
"""

from __future__ import annotations

import enum
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

log = logging.getLogger(__name__)


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
        checked = _checked_summary(summary, run.summary_json)
        stats = {k: checked[k] for k in _STATS if k in checked}
        message = checked.get("message", "") if summary else (
            f"{run.summary_json} is missing: the run was killed before its summary was written, or is "
            "still running; the rows of its results file are loaded")
        return cls(status=checked["status"], message=message, t=t, outputs=cols, stats=stats,
                   out_dir=run.path, end_time=checked.get("end_time"), analysis=checked.get("analysis"))

    def __repr__(self) -> str:
        return (f"CoSimResult(status={self.status.short}, end_time={self.end_time}, rows={len(self.t)}, "
                f"signals={len(self.outputs)}, message={self.message!r})")


_COUNTERS = ("macro_steps", "rejected_steps", "retried_steps", "retry_substeps")
_STATS = (*_COUNTERS, "wall_time_s", "fmu_calls")
_NONFINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}   # summary.json's "string" JSON policy


def _number(x) -> float | int | None:
    """``x`` as a number if it is one (a JSON number, or the "nan"/"inf"/"-inf" the summary
    writer puts for a non-finite float), else None."""
    if isinstance(x, bool):
        return None
    if isinstance(x, (int, float)):
        return x
    if isinstance(x, str) and x in _NONFINITE:
        return _NONFINITE[x]
    return None


def _checked_summary(summary: Mapping[str, Any], path: Path) -> dict[str, Any]:
    """The fields :meth:`CoSimResult.load` reads from summary.json, each of the type the run
    writes; a field of another type is dropped with a warning naming the file, the field, what
    was expected and what came (a run folder may come from anyone; ``plot`` drops a malformed
    analysis the same way, with a note). An unknown ``status`` reads as failed, said likewise."""
    out: dict[str, Any] = {"status": Status.FAILED}

    def drop(key: str, expected: str, got) -> None:
        shown = repr(got)
        shown = shown if len(shown) <= 80 else shown[:77] + "..."
        log.warning("%s: field '%s' must be %s (got %s %s); ignored", path, key, expected,
                    type(got).__name__, shown)

    if "status" in summary:
        st = summary["status"]
        if isinstance(st, str) and st.upper() in Status.__members__:
            out["status"] = Status[st.upper()]
        else:
            drop("status", f"one of {[s.short for s in Status]}", st)
            log.warning("%s: the run is taken as failed", path)
    if "message" in summary:
        if isinstance(summary["message"], str):
            out["message"] = summary["message"]
        else:
            drop("message", "a string", summary["message"])
    for key in _COUNTERS:
        if key in summary:
            v = summary[key]
            if v is None or (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
                out[key] = v
            else:
                drop(key, "a count (an integer >= 0) or null", v)
    if "wall_time_s" in summary:
        v = summary["wall_time_s"]
        n = _number(v)
        if v is None or (n is not None and n >= 0):
            out["wall_time_s"] = n
        else:
            drop("wall_time_s", "a number of seconds >= 0 or null", v)
    if "end_time" in summary:
        v = summary["end_time"]
        n = _number(v)
        if v is None or n is not None:
            out["end_time"] = n
        else:
            drop("end_time", "a number of seconds or null", v)
    if "fmu_calls" in summary:
        v = summary["fmu_calls"]
        if isinstance(v, Mapping) and all(
                isinstance(calls, Mapping) and all(isinstance(n, int) and not isinstance(n, bool) and n >= 0
                                                   for n in calls.values()) for calls in v.values()):
            out["fmu_calls"] = v
        else:
            drop("fmu_calls", "a mapping {instance: {call: count}}", v)
    if "analysis" in summary:
        v = summary["analysis"]
        if v is None or isinstance(v, Mapping):
            out["analysis"] = v
        else:
            drop("analysis", "a mapping or null", v)
    return out
