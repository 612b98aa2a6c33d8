"""Run a planned sweep on Dask distributed and build its table.

:func:`run_sweep` submits one task per run (:func:`orchestrator.sweep.task.execute_run`)
to a ``distributed.LocalCluster`` (default: one single-threaded worker process per core)
or to an existing cluster given by its scheduler address, shows a progress bar with ETA,
and writes ``DIR/sweep.csv`` (and ``sweep.parquet`` with pyarrow) when the runs are done
or when the user interrupts (Ctrl-C cancels the pending tasks; finished runs are kept).
A failed or crashed run is a row, never the end of the sweep.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from orchestrator.errors import CosimError
from orchestrator.sweep.plan import RunPlan
from orchestrator.sweep.spec import SweepSpec
from orchestrator.sweep.table import build_rows, write_table
from orchestrator.sweep.progress import progress_bar as _progress
from orchestrator.sweep.task import RUN_RECORD, execute_run
from orchestrator.sweep.units import sweep_labels

__all__ = ["SweepOutcome", "run_sweep", "resumable", "connect"]

log = logging.getLogger(__name__)


@dataclass(kw_only=True)
class SweepOutcome:
    """What :func:`run_sweep` did: the table rows, where they are, and whether it was interrupted."""

    rows: list[dict]
    out_dir: Path
    table: Path
    interrupted: bool = False
    stopped_by: str | None = None                 # the signal that interrupted it: "SIGINT" or "SIGTERM"
    skipped: int = 0                              # runs taken from an earlier sweep (--resume)
    warnings: list[str] = field(default_factory=list)


# Nesting of a run's summary.json or sweep_run.json: ours are 5-6 levels deep; deeper ones
# (a hand-edited or planted file) are refused before anything walks or copies them.
MAX_RECORD_DEPTH = 64


def _nesting_over(value, limit: int) -> bool:
    """Whether ``value`` (parsed JSON) nests more than ``limit`` lists/objects deep (iterative)."""
    stack = [(value, 1)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, (dict, list)):
            if depth > limit:
                return True
            stack.extend((v, depth + 1) for v in (node.values() if isinstance(node, dict) else node))
    return False


def read_run_file(path: Path, what: str) -> tuple[dict | None, str | None]:
    """(the JSON object in a run folder's ``summary.json`` / ``sweep_run.json``, None) or
    (None, why it cannot be used); (None, None) when there is no such file.

    Read with the bounded reader (a regular file of at most ``untrusted.MAX_TEXT_BYTES``, UTF-8,
    nesting the parser can take; a symlink to /dev/zero or a directory is refused without
    reading), then checked to be an object nested at most :data:`MAX_RECORD_DEPTH` levels.
    """
    from orchestrator.untrusted import InputError, load_json

    if not path.exists() and not path.is_symlink():
        return None, None
    try:
        doc = load_json(path, what=what)
    except InputError as exc:
        return None, str(exc)
    if not isinstance(doc, dict):
        return None, f"{path}: expected a JSON object, got {type(doc).__name__}"
    if _nesting_over(doc, MAX_RECORD_DEPTH):
        return None, f"{path}: nested more than {MAX_RECORD_DEPTH} levels deep (ours are a few)"
    return doc, None


def _record_problem(record: dict) -> str | None:
    """Why a parsed sweep_run.json is ill-formed (None: it is well-formed)."""
    overrides = record.get("overrides")
    if overrides is not None and not (isinstance(overrides, list) and all(isinstance(o, str) for o in overrides)):
        return "'overrides' is not a list of texts"
    if not isinstance(record.get("status", ""), str) or not isinstance(record.get("message", ""), str):
        return "'status' or 'message' is not a text"
    wall = record.get("wall_time_s")
    if wall is not None and (isinstance(wall, bool) or not isinstance(wall, (int, float))):
        return "'wall_time_s' is not a number"
    inputs = record.get("inputs", {})
    if not isinstance(inputs, dict):
        return "'inputs' is not an object"
    if not isinstance(inputs.get("scenario", ""), str):
        return "'inputs.scenario' is not a text (a digest)"
    for key in ("fmus", "files"):       # what _changed_inputs compares: {name or path: digest}
        if key in inputs and not (isinstance(inputs[key], dict)
                                  and all(isinstance(v, str) for v in inputs[key].values())):
            return f"'inputs.{key}' is not an object of texts (digests)"
    return None


def _changed_inputs(recorded: dict, now: dict) -> str | None:
    """What changed between the files a run was recorded with and the sweep's now (None: nothing,
    or a record written before inputs were recorded; ``files`` are compared when the record has
    them: a file edited, no longer read or newly read)."""
    if not recorded or not now:
        return None
    what = []
    if recorded.get("scenario") != now.get("scenario"):
        what.append("the scenario file")
    old, new = recorded.get("fmus") or {}, now.get("fmus") or {}
    changed = sorted(i for i in set(old) | set(new) if old.get(i) != new.get(i))
    if changed:
        what.append("the FMU of " + ", ".join(repr(i) for i in changed[:5]) + (", ..." if len(changed) > 5 else ""))
    if isinstance(recorded.get("files"), dict):      # absent in records written before files were recorded
        old, new = recorded["files"], now.get("files") or {}
        edited = sorted(p for p in set(old) & set(new) if old[p] != new[p])
        gone, added = sorted(set(old) - set(new)), sorted(set(new) - set(old))
        for paths, note in ((edited, ""), (gone, " (no longer read)"), (added, " (read now, not by this run)")):
            if paths:
                what.append(("the file " if len(paths) == 1 else "the files ") + ", ".join(paths[:5])
                            + (f", ... ({len(paths)} in all)" if len(paths) > 5 else "") + note)
    return " and ".join(what) or None


def _redo(problem: str) -> None:
    warnings.warn(f"--resume: {problem}; running that run again (its summary.json and sweep_run.json are "
                  "rewritten)", stacklevel=3)


def resumable(run_dir: Path, run: RunPlan) -> dict | None:
    """The record of a finished earlier run with the same overrides in ``run_dir``, or None.

    An unreadable or ill-formed ``summary.json`` or ``sweep_run.json`` (too large, not a regular
    file, not UTF-8 or JSON, not an object, nested too deeply, fields of the wrong type) makes
    the run not finished: it runs again, with a warning naming the file and why.
    """
    summary, problem = read_run_file(run_dir / "summary.json", "summary.json")
    if problem is not None:
        _redo(problem)
        return None
    if summary is None or summary.get("status") != "finished":
        return None
    record, problem = read_run_file(run_dir / RUN_RECORD, RUN_RECORD)
    if problem is None and record is not None:
        problem = _record_problem(record)
        problem = f"{run_dir / RUN_RECORD}: {problem}" if problem else None
    if problem is not None:
        _redo(problem)
        return None
    record = record or {}
    if record.get("overrides") not in (None, list(run.overrides)):
        return None                                # a different run hashed to this folder: run it again
    changed = _changed_inputs(record.get("inputs") or {}, run.inputs)
    if changed:
        _redo(f"{run_dir}: {changed} changed since this run finished (its results are of the earlier one)")
        return None
    return {"status": "finished", "message": record.get("message", ""),
            "wall_time_s": record.get("wall_time_s"), "summary": summary}


def _recorded(run_dir: Path, run: RunPlan) -> dict | None:
    """The record a run wrote into ``run_dir`` (``sweep_run.json`` of the same overrides, with its
    summary), or None: after Ctrl-C, the runs that ended before their result reached the client."""
    record, problem = read_run_file(run_dir / RUN_RECORD, RUN_RECORD)
    if record is None or _record_problem(record) is not None or "status" not in record \
            or record.get("overrides") != list(run.overrides):
        return None
    summary, _ = read_run_file(run_dir / "summary.json", "summary.json")
    return {**record, "summary": summary}


_RUN_FILES = ("summary.json", "run.log", "results.csv", "results.parquet")
_SAID_CHARS = 300                                 # of the run's own message in its row


def _in_progress(run_dir: Path, since: float) -> dict | None:
    """The record of a run that was in progress when the sweep was interrupted (it wrote into
    ``run_dir`` after ``since``, the sweep's start, but no sweep_run.json): status ``cancelled``
    (``--resume`` runs it again unless its summary says finished), the message saying it was
    interrupted while running and what its own summary.json says. None when it never started
    (its folder holds nothing of this sweep: a summary from an earlier sweep is not taken)."""
    def newer(name: str) -> bool:
        try:
            return (run_dir / name).stat().st_mtime >= since
        except OSError:
            return False
    if not any(newer(name) for name in _RUN_FILES):
        return None
    summary = read_run_file(run_dir / "summary.json", "summary.json")[0] if newer("summary.json") else None
    status = summary.get("status") if summary is not None else None
    said = summary.get("message") if summary is not None else None
    said = " ".join(said.split()) if isinstance(said, str) else ""
    said = said if len(said) <= _SAID_CHARS else said[:_SAID_CHARS - 3] + "..."
    if not isinstance(status, str):
        how = "it wrote no summary.json yet"
    elif status == "running":
        how = "its summary.json still says running: it was stopped before it wrote its final one"
    else:
        how = f"its summary.json says {status[:40]}" + (f": {said}" if said else "")
    rows = "; its rows so far are in its results file" if newer("results.csv") or newer("results.parquet") else ""
    again = ("; --resume keeps it" if status == "finished" else "; rerun with --resume")
    return {"status": "cancelled", "message": f"interrupted while running ({how}){rows}{again}",
            "wall_time_s": None, "summary": summary}


# The local cluster's housekeeping at the pace of runs that take seconds to hours, not of
# millisecond tasks: Dask's defaults (a statistical profiler sampling every worker every 10 ms,
# event-loop health ticks every 20 ms, memory checks every 100 ms, system monitor every 0.5 s)
# cost ~0.1 s CPU per second of sweep on the shared 2-core host, measured idle: 1.7 s in the
# client and ~3 s in two workers over 30 s, against 0.25 s and ~0.5 s with these (BENCHMARKS.md).
QUIET_LOCAL_CLUSTER = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.admin.system-monitor.gil.enabled": False,
    "distributed.worker.memory.monitor-interval": "1s",
}


def check_cluster_options(scheduler: str | None, workers: int | None) -> str | None:
    """The address of the external cluster (``scheduler``, else ``$DASK_SCHEDULER_ADDRESS``), or None
    for a local one; :class:`CosimError` when ``workers`` is given with an external cluster (its size
    is set where its workers are started). Checked by :func:`run_sweep` before it writes anything."""
    address = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
    if workers is not None and not address:
        local_size(workers)                       # --workers 0 was refused only after every run was validated
    if address and workers is not None:
        raise CosimError("--workers sets the size of the local cluster; with --scheduler (or "
                         "DASK_SCHEDULER_ADDRESS) the cluster has the workers started for it: drop --workers")
    return address


def connect(scheduler: str | None, workers: int | None):
    """A ``distributed.Client`` and the cluster it owns (None for an external cluster).

    ``scheduler`` (or the environment variable ``DASK_SCHEDULER_ADDRESS``): the address of a
    running scheduler, e.g. ``tcp://10.0.0.5:8786``; otherwise a LocalCluster of ``workers``
    (default: the number of cores) single-threaded workers, threads of this process (each run
    executes in a process of its own, :mod:`orchestrator.sweep.task`).
    """
    try:
        from distributed import Client, LocalCluster
    except ModuleNotFoundError:
        raise CosimError("sweeps run on Dask distributed, which is not installed; install it "
                         "(pip install 'dask[distributed]')") from None
    _quiet_dask()
    address = check_cluster_options(scheduler, workers)
    if address:
        # an unreachable address used to be 20 s of silence; a scheduler without workers, runs
        # that wait for ever without a word
        print(f"sweep: connecting to the Dask scheduler at {address} (up to 20 s)", file=sys.stderr, flush=True)
        try:
            client = Client(address, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise CosimError(f"cannot reach the Dask scheduler at {address} ({exc}); start it (`dask scheduler`) "
                             "and its workers (`dask worker ADDRESS`), or leave out --scheduler for a local "
                             "cluster") from None
        if not client.scheduler_info().get("workers"):
            print(f"warning: the Dask scheduler at {address} has no workers; the runs wait until one connects "
                  f"(start them with `dask worker {address} --nthreads 1`, docs/sweeps.md section 2)",
                  file=sys.stderr, flush=True)
        return client, None
    n = local_size(workers)
    import dask
    with dask.config.set(QUIET_LOCAL_CLUSTER):
        # The workers are threads of this process (processes=False), one single-threaded worker
        # per core: every run executes in a run process of its own (task.execute_run), so a
        # worker only waits for its run process. Worker processes (a nanny and a worker each)
        # cost ~2 s wall and ~2 s CPU to start and 0.5 s to close on this 2-core host, and they
        # doubled the processes of a warm sweep (BENCHMARKS.md, "Sweeps", session 3).
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=False,
                               dashboard_address=None, silence_logs=logging.ERROR,
                               scheduler_kwargs={"dashboard_address": ":0"})   # its HTTP port: any free one
        client = Client(cluster)
    return client, cluster


def local_size(workers: int | None) -> int:
    """The number of workers of the local cluster: ``workers``, default the number of cores."""
    n = (os.cpu_count() or 1) if workers is None else workers
    if n < 1:
        raise CosimError(f"--workers must be at least 1 (got {n})")
    return n


def _quiet_dask() -> None:
    """Dask logs every scheduler and worker event at INFO; keep its errors only (unless debugging)."""
    if not logging.getLogger().isEnabledFor(logging.DEBUG):
        logging.getLogger("distributed").setLevel(logging.ERROR)
        # after Ctrl-C, distributed's sync() cancels its pending call with a loop callback that
        # may find it already done and log a harmless traceback through tornado (the local
        # cluster's loop runs in this process); a run's failure is a row, not a log line
        logging.getLogger("tornado.application").setLevel(logging.CRITICAL)


def _submit(client, spec: SweepSpec, todo: list[RunPlan], runs_dir: Path, warm: bool) -> dict:
    futures = {}
    for run in todo:
        fut = client.submit(execute_run, str(spec.scenario), list(run.overrides), str(runs_dir / run.run_id),
                            warm=warm, inputs=run.inputs or None, key=f"rotorcosim-run-{run.run_id}",
                            pure=False, retries=0)
        futures[fut] = run
    return futures


_POLL_S = 0.2


def _stopped_by_user(rec: dict) -> bool:
    """Whether a run was stopped by Ctrl-C: it reaches the runs' processes too (one process
    group), so a run that stopped that way means the user interrupted the sweep."""
    summary = rec.get("summary") or {}
    return rec.get("status") == "cancelled" and summary.get("stopped_by") == "SIGINT"


def _gather(futures: dict, records: dict, bar, interrupt) -> None:
    """Collect finished tasks into ``records`` (run_id -> record) as they complete; raise
    KeyboardInterrupt when the user interrupted (``interrupt``, or a run stopped by Ctrl-C)."""
    from distributed import as_completed
    pending = as_completed(list(futures))
    while not pending.is_empty():
        if interrupt.requested:
            raise KeyboardInterrupt
        batch = pending.next_batch(block=False)
        if not batch:
            time.sleep(_POLL_S)
            continue
        for fut in batch:
            run = futures[fut]
            try:
                rec = fut.result()
            except Exception as exc:                  # the worker died or the task could not start
                hint = ("; do the workers have rotorcosim installed (docs/sweeps.md, section 2)?"
                        if isinstance(exc, ImportError) else "")
                rec = {"status": "crashed", "message": f"the task failed on its worker: {type(exc).__name__}: "
                                                       f"{exc}{hint}", "wall_time_s": None, "summary": None}
            records[run.run_id] = rec
            if rec["status"] != "finished":       # before the update, which prints a line off a terminal
                bar.set_postfix_str(f"{sum(r['status'] != 'finished' for r in records.values())} not finished")
            bar.update(1)
            if _stopped_by_user(rec):
                interrupt.requested = True


def run_sweep(spec: SweepSpec, runs: list[RunPlan], out_dir: str | Path, *, scheduler: str | None = None,
              workers: int | None = None, resume: bool = False, progress: bool | None = None,
              warm: bool = True) -> SweepOutcome:
    """Run ``runs`` (from :func:`orchestrator.sweep.plan.plan_sweep`) into ``out_dir/runs/<run_id>``.

    ``resume``: runs whose folder holds a finished summary.json of the same overrides are not
    run again (an unreadable or ill-formed one is run again, with a warning: :func:`resumable`). ``warm``: each worker runs its runs in one long-lived run process
    (:mod:`orchestrator.sweep.warm`); False: a fresh process per run. On KeyboardInterrupt the pending tasks are cancelled, the table is written with
    the unfinished runs as status ``cancelled``, and the outcome says ``interrupted``.
    """
    check_cluster_options(scheduler, workers)     # a contradictory command line writes nothing
    out_dir = Path(out_dir).resolve()
    runs_dir = out_dir / "runs"
    runs_dir.mkdir(parents=True, exist_ok=True)
    records: dict[str, dict] = {}
    resume_texts: list[str] = []
    if resume:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for run in runs:
                rec = resumable(runs_dir / run.run_id, run)
                if rec is not None:
                    records[run.run_id] = rec
        resume_texts = [str(w.message) for w in caught]
        for text in resume_texts:                 # now, before the runs: the user sees why they run
            warnings.warn(text, stacklevel=2)
    skipped = len(records)
    todo = [r for r in runs if r.run_id not in records]
    interrupted = False
    stopped_by = None
    t0 = time.perf_counter()
    since = time.time()                           # files of this sweep's runs are newer
    if todo:
        client = cluster = futures = None
        bar = _progress(len(todo), progress)
        stack = contextlib.ExitStack()
        # Ctrl-C (and SIGTERM) as a flag (lifecycle.StopRequests), not a KeyboardInterrupt raised wherever
        # the main thread happens to be: in a sweep that is mostly Dask's client code, and an exception
        # raised inside a finaliser or a callback there is printed and dropped ("Exception ignored in
        # ..."): the sweep then carried on and ended with exit 1, its interrupted run a ``failed`` row.
        # _gather looks at the flag every _POLL_S and raises the KeyboardInterrupt itself, from its own
        # code; a second Ctrl-C raises at once. SIGTERM (a batch system or ``kill``) the same way: it
        # killed the sweep outright before, with no sweep.csv and no message, exit -15.
        from orchestrator.coupling.lifecycle import StopRequests
        interrupt = StopRequests()
        try:
            stack.enter_context(interrupt)
            if warm and not (scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS")):
                # the local workers are threads of this process and their run processes its
                # children: start them now, they import the run's libraries while the cluster starts
                from orchestrator.sweep.warm import prestart
                prestart(str(runs_dir), min(local_size(workers), len(todo)))
            client, cluster = connect(scheduler, workers)
            if warm:                              # each worker reaps its warm run process when it closes
                from orchestrator.sweep.warm import WarmPlugin
                client.register_plugin(WarmPlugin())
            futures = _submit(client, spec, todo, runs_dir, warm)
            _gather(futures, records, bar, interrupt)
        except KeyboardInterrupt:
            interrupted = True
            stopped_by = signal.Signals(interrupt.signum or signal.SIGINT).name
            if futures:
                client.cancel([f for f in futures if not f.done()], force=True)
            if cluster is not None and not warm:  # fresh run processes outlive the closed cluster's threads,
                from orchestrator.sweep.task import stop_fresh      # and closing it waits for those threads:
                stop_fresh()                      # stopped first, or the close waits for the runs to finish
        finally:
            stack.close()                         # Ctrl-C is Python's again
            bar.close()
            if client is not None:
                client.close()
            if cluster is not None:
                cluster.close()
        if interrupted:
            # read the runs' folders only now: closing the local cluster stops the runs in
            # progress, which then write their final summary (failed, stopped_by SIGTERM); read
            # before, the rows said "still says running" of a summary that no longer did
            for run in todo:                      # ended on a worker, result not gathered yet
                if run.run_id not in records:
                    rec = _recorded(runs_dir / run.run_id, run) or _in_progress(runs_dir / run.run_id, since)
                    if rec is not None:
                        records[run.run_id] = rec
    log.info("sweep of %d runs took %.1f s", len(todo), time.perf_counter() - t0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rows = build_rows(spec, runs, records, out_dir)
    param_units, collect_units, value_names = sweep_labels(spec, runs[0].overrides) if runs else ({}, {}, {})
    table = write_table(rows, spec, out_dir, (param_units, collect_units), value_names)
    texts = [str(w.message) for w in caught]
    for text in texts:
        warnings.warn(text, stacklevel=2)
    return SweepOutcome(rows=rows, out_dir=out_dir, table=table, interrupted=interrupted, stopped_by=stopped_by,
                        skipped=skipped,
                        warnings=resume_texts + texts)
