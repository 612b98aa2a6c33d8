"""rotorcosim orchestrator: load a scenario, run it, get a result.

```python
from orchestrator import load_scenario, run, CoSimResult
sc = load_scenario("scenarios/x.yaml", overrides=["coupling.macro_step=5e-5"])
res = run(sc, out_dir="out/x")          # writes out/x/results.csv and out/x/summary.json
res.status, res.success, res.message, res.t, res.outputs, res.stats
```

For step-by-step control use :class:`orchestrator.master.MasterAlgorithm`.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import sys
import threading
import time as _time
from pathlib import Path

from .results import CoSimResult, Status

__all__ = ["load_scenario", "run", "CoSimResult", "Status"]

log = logging.getLogger(__name__)


def load_scenario(path, overrides=(), **kwargs):
    """Load and validate a scenario YAML file (see docs/scenario-format.md).

    Implemented in :mod:`orchestrator.scenario`; imported lazily so that this
    package imports even while the loader is being developed.
    """
    from . import scenario as _scenario
    loader = getattr(_scenario, "load_scenario", None)
    if loader is None:   # pragma: no cover - only while the frontend part is missing
        raise NotImplementedError("orchestrator.scenario.load_scenario is not available in this installation")
    return loader(path, overrides=overrides, **kwargs)


def _summary(scenario, res: CoSimResult, out_dir: Path) -> dict:
    from dataclasses import asdict, is_dataclass
    from .observers import versions
    coupling = asdict(scenario.coupling) if is_dataclass(scenario.coupling) else dict(scenario.coupling)
    stats = dict(res.stats)
    return {
        "scenario": scenario.name,
        "scenario_file": str(scenario.source) if scenario.source else None,
        "status": res.status.short,
        "message": res.message,
        "start_time": scenario.start_time,
        "stop_time": scenario.stop_time,
        "end_time": res.end_time,
        "macro_steps": stats.get("macro_steps"),
        "rejected_steps": stats.get("rejected_steps", 0),
        "retried_steps": stats.get("retried_steps", 0),
        "retry_substeps": stats.get("retry_substeps", 0),
        "wall_time_s": stats.get("wall_time_s"),
        "fmu_calls": stats.get("fmu_calls", {}),
        **{k: stats[k] for k in ("iterations", "step_control") if k in stats},
        "coupling": coupling,
        "output": {"columns": list(res.outputs), "rows": int(len(res.t))},
        "versions": versions(),
    }


@contextlib.contextmanager
def _interrupt_between_steps(master):
    """Defer Ctrl-C (SIGINT) to the end of the current macro step.

    A KeyboardInterrupt raised while an FMU's Python code runs (PythonFMU slaves run in
    this process) escapes through the FMU as fmi2Fatal, which the master would report as
    a numerical failure of that FMU ("try a smaller macro step"), and PythonFMU 0.7.0 then
    leaves the slave's objects one reference short (docs/dev/requests.md). So the first
    Ctrl-C only sets ``master.interrupt_requested``; ``master.run`` raises KeyboardInterrupt
    before the next macro step, from master code, after which ``run`` writes summary.json
    ("interrupted by the user at t=...") and the FMUs are terminated and freed normally.
    A second Ctrl-C interrupts at once. Only in the main thread (elsewhere Python does
    not deliver signals and nothing changes).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        if master.interrupt_requested:
            raise KeyboardInterrupt
        master.interrupt_requested = True
        print("\ninterrupt: stopping after this macro step (Ctrl-C again to stop at once)",
              file=sys.stderr, flush=True)

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def run(scenario, out_dir: str | Path = "out", progress: bool | None = None, *, observers=()) -> CoSimResult:
    """Run ``scenario`` and write ``out_dir/results.csv`` and ``out_dir/summary.json``.

    Parameters
    ----------
    scenario : a validated :class:`orchestrator.scenario.Scenario`.
    out_dir : run directory (created); ``{out_dir}`` in String parameters refers to it.
    progress : None -> progress bar when stderr is a terminal and the run lasts
        more than a few seconds; True -> always; False -> never.
    observers : extra :class:`orchestrator.observers.Observer` objects.

    Numerical failure during the run is reported in the result's ``status`` /
    ``message`` (and summary.json), not raised. Bad scenarios or FMUs raise
    :class:`orchestrator.errors.CosimError` subclasses.

    ``coupling.scheme == "monolithic"`` is delegated to
    :func:`orchestrator.monolithic.run_monolithic`. When the scenario has an
    ``analysis:`` section, :func:`orchestrator.analysis.analyze_run` is called
    afterwards and its dict stored under ``"analysis"`` in summary.json.
    """
    from .observers import CsvWriter, Progress, write_summary

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    try:
        from . import build as _build
    except ImportError:
        _build = None
    if _build is not None and hasattr(_build, "ensure_fmus"):
        _build.ensure_fmus(scenario)

    if scenario.coupling.scheme == "monolithic":
        from .monolithic import run_monolithic
        res = run_monolithic(scenario, out_dir=out_dir, progress=progress)
    else:
        from .master import MasterAlgorithm
        obs = [CsvWriter(out_dir / "results.csv"), Progress(progress), *observers]
        master = MasterAlgorithm(scenario, out_dir=out_dir, observers=obs)
        try:
            with _interrupt_between_steps(master):
                res = master.run()
        except KeyboardInterrupt:
            # interrupted by the user: record where the run stopped, then re-raise
            if master.status is not Status.NOT_STARTED:
                res = master.result()
                msg = f"interrupted by the user at t={res.end_time:.12g} s; " + (res.message or "")
                from dataclasses import replace
                write_summary(out_dir / "summary.json",
                              _summary(scenario, replace(res, status=Status.FAILED, message=msg), out_dir))
            raise
        write_summary(out_dir / "summary.json", _summary(scenario, res, out_dir))

    if scenario.analysis:
        import json
        t0 = _time.perf_counter()
        try:
            from .analysis import analyze_run
            analysis = analyze_run(out_dir, scenario.analysis)
        except Exception as e:   # never lose a run to a failing analysis
            log.warning("analysis of %s failed: %s", out_dir, e)
            analysis = {"error": f"analysis failed: {type(e).__name__}: {e}"}
        path = out_dir / "summary.json"
        try:
            summary = json.loads(path.read_text())
        except (OSError, ValueError):
            summary = _summary(scenario, res, out_dir)
        summary["analysis"] = analysis
        summary["analysis_wall_time_s"] = _time.perf_counter() - t0
        write_summary(path, summary)
        from dataclasses import replace
        res = replace(res, analysis=analysis)
    return res
