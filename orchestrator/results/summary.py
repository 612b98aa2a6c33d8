"""summary.json: the one writer for co-simulation and monolithic runs alike.

Keys, in order: ``scenario``, ``scenario_file``, ``status``, ``message``, ``start_time``,
``stop_time``, ``end_time``, the run's statistics (``macro_steps``, ...; see
docs/scenario-format.md), ``coupling``, ``output`` (columns, rows, units, the last row's time and
values ``final_time``/``final``), ``versions``; a run
with an ``analysis:`` section adds ``analysis`` and ``analysis_wall_time_s``.
"""

from __future__ import annotations

import json
from dataclasses import asdict, is_dataclass
from pathlib import Path
from typing import Any, Mapping

from orchestrator.results.jsonsafe import plain

SUMMARY = "summary.json"


def make_summary(scenario, res, *, stats: Mapping[str, Any], coupling: Mapping[str, Any] | None = None) -> dict:
    """The summary of the run ``res`` (a :class:`~orchestrator.results.result.CoSimResult`) of
    ``scenario``; ``coupling`` defaults to the scenario's coupling section."""
    if coupling is None:
        coupling = asdict(scenario.coupling) if is_dataclass(scenario.coupling) else dict(scenario.coupling)
    return {
        "scenario": scenario.name,
        "scenario_file": str(scenario.source) if scenario.source else None,
        "status": res.status.short,
        "message": res.message,
        "start_time": scenario.start_time,
        "stop_time": scenario.stop_time,
        "end_time": res.end_time,
        **stats,
        "coupling": coupling,
        "output": {"columns": list(res.outputs), "rows": int(len(res.t)),
                   "units": column_units(scenario, list(res.outputs)),
                   **final_values(res)},
        "versions": versions(),
    }


def final_values(res) -> dict:
    """``{"final_time": t, "final": {column: value}}`` of the last row written (none without rows):
    what a sweep collects as ``output.final.<instance>.<variable>`` (docs/sweeps.md), e.g. the end
    state of a third-party FMU over a coupling parameter, which no analysis section computes."""
    t = getattr(res, "t", None)
    if t is None or len(t) == 0:
        return {}
    out = {}
    for c, v in res.outputs.items():
        x = v[-1]
        out[c] = x.item() if hasattr(x, "item") else x
    return {"final_time": float(t[-1]), "final": out}


def column_units(scenario, columns) -> dict[str, str]:
    """``{column: unit}`` of the recorded columns whose variable declares a unit (its own or its
    declared type's) in its FMU's model description; ``rotorcosim plot`` labels the signals with it.
    A model description that cannot be read leaves its columns out (the summary never fails on it)."""
    by_instance: dict[str, list[str]] = {}
    for c in columns:
        inst, _, var = c.partition(".")
        by_instance.setdefault(inst, []).append(var)
    units: dict[str, str] = {}
    for spec in getattr(scenario, "fmus", ()):
        names = by_instance.get(getattr(spec, "name", None))
        if not names:
            continue
        try:
            from orchestrator.fmi.archive import cached_model_description     # read at load already
            variables = cached_model_description(spec.path).variables
        except Exception:                        # noqa: BLE001 - a label is not worth a failed summary
            continue
        for var in names:
            v = variables.get(var)
            if v is not None and getattr(v, "unit", ""):
                units[f"{spec.name}.{var}"] = v.unit
    return {c: units[c] for c in columns if c in units}


def cosim_stats(stats: Mapping[str, Any]) -> dict:
    """The statistics block of a co-simulation run's summary (missing counters are 0)."""
    return {"macro_steps": stats.get("macro_steps"),
            "rejected_steps": stats.get("rejected_steps", 0),
            "retried_steps": stats.get("retried_steps", 0),
            "retry_substeps": stats.get("retry_substeps", 0),
            "wall_time_s": stats.get("wall_time_s"),
            "fmu_calls": stats.get("fmu_calls", {}),
            "isolation": stats.get("isolation", {}),
            "failure": stats.get("failure"),
            **{k: stats[k] for k in ("iterations", "step_control", "coupling_defect", "threaded_stage_steps",
                                     "threaded_stage_steps_watched") if k in stats}}


def write_summary(path: Path | str, summary: Mapping[str, Any]) -> None:
    """Write ``summary.json`` atomically (temp file + rename), never through a symbolic link."""
    from orchestrator.results.safe_write import write_text_no_follow
    write_text_no_follow(path, json.dumps(plain(summary, "string"), indent=2) + "\n")


def versions() -> dict[str, str]:
    """Versions of the software a run depends on (for summary.json)."""
    import platform
    out = {"python": platform.python_version()}
    from importlib.metadata import PackageNotFoundError, version
    # installed distributions, not sys.modules: an FMU bundling its own pythonfmu may have put its copy there
    for key in ("numpy", "scipy", "fmpy", "pythonfmu"):
        try:
            out[key] = version(key)
        except PackageNotFoundError:
            out[key] = "unavailable"
    try:
        from importlib.metadata import version
        out["rotorcosim"] = version("rotorcosim")
    except Exception:
        out["rotorcosim"] = "unknown"
    return out
