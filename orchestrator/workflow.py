"""``run``: the whole of a run - build our FMUs, run the master or the reference, write summary.json, analyse.

The run's folder life cycle (lock, summary at start and end, Ctrl-C and SIGTERM after the
current macro step, failed summaries) is :class:`orchestrator.coupling.lifecycle.RunFolder`.
"""

from __future__ import annotations

import logging
import signal
import time as _time
from dataclasses import replace
from pathlib import Path

from orchestrator.coupling.execution import MasterAlgorithm
from orchestrator.coupling.lifecycle import RunFolder, RunStopped
from orchestrator.coupling.observers import CsvWriter, Progress, check_observers
from orchestrator.errors import path_arg
from orchestrator.fmi import build
from orchestrator.results.result import CoSimResult, Status
from orchestrator.results.run_directory import RunDirectory
from orchestrator.results.summary import cosim_stats, make_summary
from orchestrator.scenario.analysis_clearance import check_analysis_clearance

log = logging.getLogger(__name__)


def _summary(scenario, res: CoSimResult) -> dict:
    return make_summary(scenario, res, stats=cosim_stats(res.stats))


def _read_back(res: CoSimResult, master, path: Path) -> CoSimResult:
    """The result with ``t``/``outputs`` read from the streamed results file (the run kept no rows in
    memory, so memory stays flat in the number of rows)."""
    import warnings

    from orchestrator.results.writer import read_back
    if not path.is_file() or not hasattr(master, "columns"):
        return res
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)        # a file with a header only: no rows
        try:
            t, outputs = read_back(path, master.columns, master.kinds)
        except (OSError, ValueError) as e:
            # a results.parquet the disk filled before its footer: the run's own reason must not be
            # replaced by "internal error: ArrowInvalid: Parquet magic bytes not found"
            if res.status is Status.FINISHED:
                raise
            log.warning("the rows of %s cannot be read back (%s); the result holds none", path, e)
            return res
    return replace(res, t=t, outputs=outputs)


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
    :class:`orchestrator.errors.CosimError` subclasses; so does an analysis whose journal
    clearance is not its bearing's ``psi R`` (:class:`~orchestrator.errors.ScenarioError` from
    :func:`orchestrator.scenario.analysis_clearance.check_analysis_clearance`, before ``out_dir``
    is made).

    ``coupling.scheme == "monolithic"`` is delegated to
    :func:`orchestrator.reference.monolithic.run_monolithic`. When the scenario has an
    ``analysis:`` section, :func:`orchestrator.results.whirl.analyze_run` is called
    afterwards and its dict stored under ``"analysis"`` in summary.json.
    """
    _check_scenario(scenario)
    if scenario.analysis:
        check_analysis_clearance(scenario)        # the analysis is planned here: refused before the folder is made
    out_dir = path_arg(out_dir, "run(out_dir=...)", "run(scenario, out_dir='runs/x')")
    if progress is not None and not isinstance(progress, bool):
        raise TypeError(f"run(progress=...) takes True, False or None (got {progress!r}); None: a progress bar "
                        "when stderr is a terminal and the run lasts more than a few seconds")
    observers = check_observers(observers, "run(observers=...)")
    with RunFolder(out_dir, scenario) as folder:       # lock, earlier files aside, summary "running"
        res = _execute(scenario, out_dir, folder, progress, observers)
        if scenario.analysis:
            res = _analyse(scenario, res, out_dir, folder)
    return res


def _execute(scenario, out_dir: Path, folder: RunFolder, progress, observers) -> CoSimResult:
    """Build our FMUs, run the master (or the monolithic reference), write the final summary."""
    build.ensure_fmus(scenario)
    if scenario.coupling.scheme == "monolithic":
        from orchestrator.reference.monolithic import run_monolithic     # imported when needed (scipy)
        res = run_monolithic(scenario, out_dir=out_dir, progress=progress)
        folder.finish(RunDirectory(out_dir).summary())     # its own summary, with the folder's times
        return res
    fmt = getattr(scenario.output, "format", "csv")
    results_file = out_dir / ("results.parquet" if fmt == "parquet" else "results.csv")
    obs = [CsvWriter(results_file, format=fmt), Progress(progress), *observers]
    master = MasterAlgorithm(scenario, out_dir=out_dir, observers=obs, record_in_memory=False)
    kept: dict = {}

    def read_back(r: CoSimResult) -> CoSimResult:        # the rows once, however the run ends
        if "rows" not in kept:
            kept["rows"] = _read_back(r, master, results_file)
        return replace(r, t=kept["rows"].t, outputs=kept["rows"].outputs)

    def summary_before_release() -> None:
        # the final summary before the FMUs are freed: one that crashes or hangs in
        # fmi2FreeInstance after a complete run leaves summary.json complete (it said "running").
        # Not for a master that never started: initialize() raised (an error that is no FMU call's,
        # or a second Ctrl-C / SIGTERM while an FMU initializes) and RunFolder writes the failed
        # summary with the reason; this one said "not_started" with no message, in its place
        if master.status is not Status.NOT_STARTED:
            folder.finish(_summary(scenario, read_back(master.result())))

    master.before_release = summary_before_release
    master.call_record = folder.calls
    try:
        with folder.stop_signals(master):
            res = read_back(master.run())
    except BaseException as exc:
        if master.status is Status.NOT_STARTED:
            raise                               # setup failed: RunFolder writes the failed summary
        # stopped by a signal (or failed unexpectedly) while stepping: keep where it stopped, then re-raise
        res = read_back(master.result())
        note = res.message
        if isinstance(exc, KeyboardInterrupt):
            msg = folder.stop_message(res.end_time)
            stop = RunStopped(folder.stop_signal or getattr(exc, "signum", None) or signal.SIGINT)
            if note and note.startswith("interrupted by the user"):
                note = ""       # the master's note of this same stop: said again, or a SIGTERM called the user
        else:
            msg, stop = f"the run stopped at t={res.end_time:.12g} s: {type(exc).__name__}: {exc}", None
            if note and str(exc) in note:
                note = ""       # the master's "stopped by an error (<the same text>)": said twice
        summary = _summary(scenario, replace(res, status=Status.FAILED,
                                             message=msg + ("; " + note if note else "")))
        if stop is not None:                    # machine-readable: a sweep counts such a run as cancelled
            summary["stopped_by"] = signal.Signals(stop.signum).name
        folder.finish(summary)
        if stop is not None:
            raise stop from None
        raise
    folder.finish(_summary(scenario, res))
    return res


def _analyse(scenario, res: CoSimResult, out_dir: Path, folder: RunFolder) -> CoSimResult:
    """The run-up analysis, stored in summary.json; a failing analysis never loses the run."""
    t0 = _time.perf_counter()
    try:
        from orchestrator.results.whirl import analyze_run
        analysis = analyze_run(out_dir, scenario.analysis)
    except Exception as e:   # never lose a run to a failing analysis
        log.warning("analysis of %s failed: %s", out_dir, e)
        analysis = {"error": f"analysis failed: {type(e).__name__}: {e}"}
    try:
        summary = RunDirectory(out_dir).summary()
    except (OSError, ValueError):
        summary = _summary(scenario, res)
    summary["analysis"] = analysis
    summary["analysis_wall_time_s"] = _time.perf_counter() - t0
    folder.finish(summary)
    return replace(res, analysis=analysis)
