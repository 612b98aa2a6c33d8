"""``run``: the whole of a run - build our FMUs, run the master or the reference, write summary.json, analyse.

Ctrl-C is deferred to the end of the current macro step (:func:`interrupt_between_steps`).
"""

from __future__ import annotations

import contextlib
import logging
import signal
import sys
import threading
import time as _time
from dataclasses import replace
from pathlib import Path

from orchestrator.coupling.execution import MasterAlgorithm
from orchestrator.coupling.observers import CsvWriter, Progress
from orchestrator.fmi import build
from orchestrator.results.result import CoSimResult, Status
from orchestrator.results.run_directory import RunDirectory
from orchestrator.results.summary import cosim_stats, make_summary, write_summary

log = logging.getLogger(__name__)


def _summary(scenario, res: CoSimResult) -> dict:
    return make_summary(scenario, res, stats=cosim_stats(res.stats))


@contextlib.contextmanager
def interrupt_between_steps(master):
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


def _check_scenario(scenario) -> None:
    """``run()`` takes a loaded Scenario; a file name or anything else is refused before the
    output folder is created."""
    from orchestrator.scenario.model import Scenario
    if isinstance(scenario, Scenario):
        return
    if isinstance(scenario, (str, Path)):
        raise TypeError(f"run() takes a loaded scenario, not the file name {str(scenario)!r}; write "
                        f"run(load_scenario({str(scenario)!r}), out_dir=...)")
    raise TypeError(f"run() takes a Scenario from load_scenario() (got {type(scenario).__name__}); write "
                    "run(load_scenario('file.yaml'), out_dir=...)")


def _read_back(res: CoSimResult, master, path: Path) -> CoSimResult:
    """The result with ``t``/``outputs`` read from the streamed results file (the run kept no rows in
    memory, so memory stays flat in the number of rows)."""
    import warnings

    from orchestrator.results.writer import read_back
    if not path.is_file() or not hasattr(master, "columns"):
        return res
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)        # a file with a header only: no rows
        t, outputs = read_back(path, master.columns, master.kinds)
    return replace(res, t=t, outputs=outputs)


def run(scenario, out_dir: str | Path = "out", progress: bool | None = None, *, observers=()) -> CoSimResult:
    """Run ``scenario`` and write ``out_dir/results.csv`` and ``out_dir/summary.json``.

    Parameters
    ----------
    scenario : a validated :class:`orchestrator.scenario.Scenario`.
    out_dir : run directory (created); ``{out_dir}`` in String parameters refers to it.
    progress : None -> progress bar when stderr is a terminal and the run lasts
        more than a few seconds; True -> always; False -> never.
    observers : extra :class:`orchestrator.coupling.observers.Observer` objects.

    Numerical failure during the run is reported in the result's ``status`` /
    ``message`` (and summary.json), not raised. Bad scenarios or FMUs raise
    :class:`orchestrator.errors.CosimError` subclasses.

    ``coupling.scheme == "monolithic"`` is delegated to
    :func:`orchestrator.reference.monolithic.run_monolithic`. When the scenario has an
    ``analysis:`` section, :func:`orchestrator.results.whirl.analyze_run` is called
    afterwards and its dict stored under ``"analysis"`` in summary.json.
    """
    _check_scenario(scenario)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    build.ensure_fmus(scenario)

    if scenario.coupling.scheme == "monolithic":
        from orchestrator.reference.monolithic import run_monolithic     # imported when needed (scipy)
        res = run_monolithic(scenario, out_dir=out_dir, progress=progress)
    else:
        fmt = getattr(scenario.output, "format", "csv")
        results_file = out_dir / ("results.parquet" if fmt == "parquet" else "results.csv")
        obs = [CsvWriter(results_file, format=fmt), Progress(progress), *observers]
        master = MasterAlgorithm(scenario, out_dir=out_dir, observers=obs, record_in_memory=False)
        try:
            with interrupt_between_steps(master):
                res = _read_back(master.run(), master, results_file)
        except KeyboardInterrupt:
            # interrupted by the user: record where the run stopped, then re-raise
            if master.status is not Status.NOT_STARTED:
                res = _read_back(master.result(), master, results_file)
                msg = res.message if (res.message or "").startswith("interrupted by the user") else (
                    f"interrupted by the user at t={res.end_time:.12g} s; " + (res.message or ""))
                write_summary(out_dir / "summary.json",
                              _summary(scenario, replace(res, status=Status.FAILED, message=msg)))
            raise
        write_summary(out_dir / "summary.json", _summary(scenario, res))

    if scenario.analysis:
        t0 = _time.perf_counter()
        try:
            from orchestrator.results.whirl import analyze_run
            analysis = analyze_run(out_dir, scenario.analysis)
        except Exception as e:   # never lose a run to a failing analysis
            log.warning("analysis of %s failed: %s", out_dir, e)
            analysis = {"error": f"analysis failed: {type(e).__name__}: {e}"}
        path = out_dir / "summary.json"
        try:
            summary = RunDirectory(out_dir).summary()
        except (OSError, ValueError):
            summary = _summary(scenario, res)
        summary["analysis"] = analysis
        summary["analysis_wall_time_s"] = _time.perf_counter() - t0
        write_summary(path, summary)
        res = replace(res, analysis=analysis)
    return res
