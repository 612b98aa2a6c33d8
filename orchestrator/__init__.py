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

import logging
import signal
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
        "isolation": stats.get("isolation", {}),
        "failure": stats.get("failure"),
        "coupling": coupling,
        "output": {"columns": list(res.outputs), "rows": int(len(res.t))},
        "versions": versions(),
    }


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
    from .coupling.lifecycle import RunFolder

    out_dir = Path(out_dir)
    with RunFolder(out_dir, scenario) as folder:       # lock, earlier files aside, summary "running"
        res = _execute(scenario, out_dir, folder, progress, observers)
        if scenario.analysis:
            res = _analyse(scenario, res, out_dir, folder)
    return res


def _execute(scenario, out_dir: Path, folder, progress, observers) -> CoSimResult:
    """Build our FMUs, run the master (or the monolithic reference), write the final summary."""
    from dataclasses import replace

    from .coupling.lifecycle import RunStopped
    from .observers import CsvWriter, Progress

    from . import build as _build
    _build.ensure_fmus(scenario)
    if scenario.coupling.scheme == "monolithic":
        from .monolithic import run_monolithic
        res = run_monolithic(scenario, out_dir=out_dir, progress=progress)
        import json
        folder.finish(json.loads((out_dir / "summary.json").read_text()))   # its own summary, times added
        return res
    from .master import MasterAlgorithm
    obs = [CsvWriter(out_dir / "results.csv"), Progress(progress), *observers]
    master = MasterAlgorithm(scenario, out_dir=out_dir, observers=obs)
    try:
        with folder.stop_signals(master):
            res = master.run()
    except BaseException as exc:
        if master.status is Status.NOT_STARTED:
            raise                               # setup failed: RunFolder writes the failed summary
        # stopped by a signal (or failed unexpectedly) while stepping: keep where it stopped, then re-raise
        res = master.result()
        if isinstance(exc, KeyboardInterrupt):
            msg = folder.stop_message(res.end_time)
            exc = RunStopped(folder.stop_signal or getattr(exc, "signum", None) or signal.SIGINT)
        else:
            msg = f"the run stopped at t={res.end_time:.12g} s: {type(exc).__name__}: {exc}"
        folder.finish(_summary(scenario, replace(res, status=Status.FAILED,
                                                 message=msg + ("; " + res.message if res.message else "")),
                               out_dir))
        if isinstance(exc, RunStopped):
            raise exc from None
        raise
    folder.finish(_summary(scenario, res, out_dir))
    return res


def _analyse(scenario, res: CoSimResult, out_dir: Path, folder) -> CoSimResult:
    """The run-up analysis, stored in summary.json; a failing analysis never loses the run."""
    import json
    from dataclasses import replace

    t0 = _time.perf_counter()
    try:
        from .analysis import analyze_run
        analysis = analyze_run(out_dir, scenario.analysis)
    except Exception as e:   # never lose a run to a failing analysis
        log.warning("analysis of %s failed: %s", out_dir, e)
        analysis = {"error": f"analysis failed: {type(e).__name__}: {e}"}
    try:
        summary = json.loads((out_dir / "summary.json").read_text())
    except (OSError, ValueError):
        summary = _summary(scenario, res, out_dir)
    summary["analysis"] = analysis
    summary["analysis_wall_time_s"] = _time.perf_counter() - t0
    folder.finish(summary)
    return replace(res, analysis=analysis)


