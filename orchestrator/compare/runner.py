"""Coupling-scheme comparison (``rotorcosim compare FILE``).

A comparison runs one base scenario in several *variants* (coupling scheme x
extrapolation/interpolation order x macro step, cartesian products allowed),
runs a *reference* (the monolithic integrator of :mod:`orchestrator.reference.monolithic`
or a fine scenario variant), measures the error of every variant against the
reference, fits the observed order of convergence of every scheme/order family,
checks per-variant tolerances and a stored baseline, and writes ``report.md``,
``report.json`` and ``error_vs_cost.png``. The file format, the metrics and the
baseline rules are documented in ``docs/compare.md``.

Call order (library use)::

    spec = load_compare("compare/two_mass.yaml")       # CompareSpecError lists every problem
    report = run_comparison(spec, out_dir)             # runs reference + variants
    failures = check_report(report, spec, baseline)    # list of readable messages
    write_report(report, spec, out_dir, failures)

:func:`main_compare` does all of it and returns the exit code for the CLI.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import logging
import math
import os
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from orchestrator.compare.metrics import (
    METRICS, REFERENCE_FLOOR_FACTOR, RunData, cheapest_within_tolerance, check_baseline_target, check_report,
    derived_error, derived_values, fit_order, load_baseline, read_run, signal_errors, write_baseline)
from orchestrator.compare.report import cheapest_text, write_report
from orchestrator.compare.spec import (
    CompareSpec, CompareSpecError, ReferenceSpec, VariantSpec, apply_changes, expand_variants, load_compare,
    parse_compare)
from orchestrator.errors import CosimError, ScenarioError, path_arg
from orchestrator.reference.models import load_model_file
from orchestrator.scenario import Scenario

log = logging.getLogger(__name__)

__all__ = ["CompareSpecError", "CompareSpec", "VariantSpec", "ReferenceSpec", "load_compare",
           "parse_compare", "expand_variants", "apply_changes", "run_comparison", "main_compare",
           "CompareReport", "default_runner"]


# --------------------------------------------------------------------------- running

def default_runner(scenario: Scenario, out_dir: Path) -> None:
    """Run one scenario with the master (or the monolithic reference) writing ``out_dir``."""
    from orchestrator import run
    run(scenario, out_dir=out_dir, progress=False)


def _run_job(runner, scenario: Scenario, out_dir: str, models: tuple = ()) -> dict[str, Any]:
    """Worker: run one scenario, never raise (a crash is a failed variant, with its message).

    ``models``: files registering monolithic-reference adapters (``spec.reference_models``),
    loaded first (a worker process starts without them)."""
    t0 = time.perf_counter()
    try:
        for path in models:
            load_model_file(path)
        runner(scenario, Path(out_dir))
        error = None
    except Exception as exc:   # noqa: BLE001 - reported per variant, compare continues
        error = f"{type(exc).__name__}: {exc}"
    return {"error": error, "wall_time_s": time.perf_counter() - t0}


def _run_isolated(runner, scenario: Scenario, out_dir: str, models: tuple = ()) -> dict[str, Any]:
    """Run one job in a fresh Python process (``python -m orchestrator.compare JOB``).

    Every run gets its own process: FMUs that load Python packages in-process (ours
    do) cannot mix versions with the monolithic reference's imports, and a run that
    crashes the interpreter fails only itself ("worker process died")."""
    import pickle
    import subprocess
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    job = out / "compare_job.pickle"
    job.write_bytes(pickle.dumps((runner, scenario, str(out), tuple(models))))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    t0 = time.perf_counter()
    with _LIVE_LOCK:
        if _STOPPING:                       # the comparison was interrupted: start nothing more
            return {"error": "not run: the comparison was interrupted", "wall_time_s": 0.0}
        # a process group of its own: the terminal's Ctrl-C reaches the comparison, which passes
        # one stop signal on to each run (a run then stops after its macro step, rows kept)
        proc = subprocess.Popen([sys.executable, "-m", "orchestrator.compare", str(job)], env=env,
                                **({"process_group": 0} if os.name == "posix" else {}))
        _LIVE.add(proc)
    try:
        proc.wait()
    finally:
        with _LIVE_LOCK:
            _LIVE.discard(proc)
    result_file = out / "compare_job.json"
    if proc.returncode == 0 and result_file.exists():
        import json
        return json.loads(result_file.read_text())
    how = (f"killed by signal {-proc.returncode}" if proc.returncode < 0
           else f"exit code {proc.returncode}")
    return {"error": f"worker process died ({how}); see the messages above",
            "wall_time_s": time.perf_counter() - t0}


_LIVE: set = set()          # run processes of _run_isolated now running
_LIVE_LOCK = threading.Lock()
_STOPPING = False           # set when the comparison is interrupted: no new run process starts


def _stop_runs(signum: int) -> None:
    """Pass the stop signal (SIGINT or SIGTERM) on to every run process and wait for them: each
    stops after its current macro step and writes its summary (``interrupted by the user`` /
    ``terminated by signal SIGTERM``), as `rotorcosim run` does; none starts after this."""
    global _STOPPING
    import signal as _signal
    with _LIVE_LOCK:
        _STOPPING = True
        procs = list(_LIVE)
    for proc in procs:
        with contextlib.suppress(OSError):
            proc.send_signal(signum)
    for proc in procs:
        try:
            proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.send_signal(_signal.SIGKILL)


def _run_parallel(runner, jobs: list, runs: Path, models: tuple, workers: int, results: dict) -> None:
    """The jobs in fresh processes, ``workers`` at a time, into ``results``.

    Ctrl-C or SIGTERM stops the comparison: the queued runs are not started, the running ones
    get the signal (and stop after their macro step, rows and summary kept), then the
    KeyboardInterrupt goes on (exit 130 / 143). Before, a Ctrl-C that reached only the
    comparison's process let every queued run start and finish first (minutes to hours), a
    SIGTERM killed it without a word (exit -15), and the runs printed tracebacks."""
    global _STOPPING
    import signal as _signal

    from orchestrator.coupling.lifecycle import RunStopped, _raise_stopped
    _STOPPING = False
    main = threading.current_thread() is threading.main_thread()
    previous = _signal.signal(_signal.SIGTERM, _raise_stopped) if main else None
    pool = concurrent.futures.ThreadPoolExecutor(max_workers=workers)
    try:
        futs = {pool.submit(_run_isolated, runner, sc, str(runs / label), models): label for label, sc in jobs}
        for fut in concurrent.futures.as_completed(futs):
            results[futs[fut]] = fut.result()
            log.info("compare: finished %s", futs[fut])
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", _signal.SIGINT)
        pool.shutdown(wait=False, cancel_futures=True)
        _stop_runs(signum)
        raise exc if isinstance(exc, RunStopped) else RunStopped(signum) from None
    finally:
        pool.shutdown(wait=True)
        if main:
            _signal.signal(_signal.SIGTERM, previous)


def worker_main(job_file: str) -> int:
    import json
    import pickle
    runner, scenario, out_dir, models = pickle.loads(Path(job_file).read_bytes())
    result = _run_job(runner, scenario, out_dir, models)
    (Path(out_dir) / "compare_job.json").write_text(json.dumps(result))
    return 0


@dataclass
class CompareReport:
    """Everything measured; written by :func:`orchestrator.compare.report.write_report`."""

    name: str
    reference: dict[str, Any]
    variants: list[dict[str, Any]]
    orders: list[dict[str, Any]]
    wall_time_s: float = 0.0


def run_comparison(spec: CompareSpec, out_dir: str | os.PathLike, *,
                   runner: Callable[[Scenario, Path], None] = default_runner,
                   workers: int | None = None) -> CompareReport:
    """Run the reference (and its convergence check) and every variant; measure errors.

    Length: the comparison as one sequence read top to bottom (FMU snapshot, jobs, parallel
    runs, errors, orders, checks, baseline, report); each step is a helper of this module."""
    t_start = time.perf_counter()
    out_dir = Path(out_dir)
    runs = out_dir / "runs"
    spec = _snapshot_fmus(spec, out_dir / "fmus")
    jobs: list[tuple[str, Scenario]] = [("reference", spec.scenario(spec.reference.changes))]
    if spec.reference.check:
        jobs.append(("reference-check", spec.scenario(spec.reference.halved(spec.base))))
    jobs += [(v.name, spec.scenario(v.changes)) for v in spec.variants]
    workers = workers or spec.workers or min(2, os.cpu_count() or 1)
    results: dict[str, dict] = {}
    if workers <= 1:
        for label, sc in jobs:
            log.info("compare: running %s", label)
            results[label] = _run_job(runner, sc, str(runs / label), spec.reference_models)
    else:   # threads that each wait for one fresh process per run
        _run_parallel(runner, jobs, runs, spec.reference_models, min(workers, 2), results)

    ref = read_run(runs / "reference", results["reference"])
    if not ref.ok:
        raise RuntimeError(f"compare '{spec.name}': the reference run failed ({ref.message}); "
                           f"see {runs / 'reference'}")
    if spec.window is not None:    # metrics (and scales) over the window only
        t_from, t_to = spec.window
        tol = 1e-9 * max(1.0, abs(t_to))
        keep = (ref.t >= t_from - tol) & (ref.t <= t_to + tol)
        ref.t = ref.t[keep]
        ref.outputs = {k: v[keep] for k, v in ref.outputs.items()}
    scales = {}
    for s, scale in spec.signals.items():
        if s not in ref.outputs:
            raise RuntimeError(f"compare '{spec.name}': signal '{s}' is not in the reference "
                               f"results (has {sorted(ref.outputs)})")
        peak = float(np.max(np.abs(ref.outputs[s])))
        scales[s] = scale if scale is not None else (peak if peak > 0 else 1.0)
    reference = {"changes": dict(spec.reference.changes), "wall_time_s": ref.wall_time_s,
                 "window": list(spec.window) if spec.window else None,
                 "macro_steps": ref.macro_steps, "fmu_calls": ref.fmu_calls,
                 "scales": scales, "dir": str(runs / "reference"),
                 "derived": derived_values(spec.derived, ref.summary)}
    if spec.reference.check:
        chk = read_run(runs / "reference-check", results["reference-check"])
        errs = _errors(spec, ref, chk, scales)
        reference["check"] = {"changes": dict(spec.reference.halved(spec.base)), "ok": chk.ok,
                              "message": chk.message, "errors": errs["total"],
                              "smallest_tolerance": spec.smallest_tolerance(),
                              "derived_tolerances": spec.derived_tolerances(),
                              "derived": derived_values(spec.derived, chk.summary)}
    variants = []
    real = _real_connections(spec.base)
    for v in spec.variants:
        data = read_run(runs / v.name, results[v.name])
        errs = _errors(spec, ref, data, scales)
        finite = all(math.isfinite(x) for k, x in errs["total"].items() if k in spec.metrics)
        diverged = any(x >= 1.0 for k, x in errs["total"].items() if k in spec.metrics)
        stable = data.ok and finite and not diverged
        sc = spec.scenario(v.changes)
        variants.append({
            "name": v.name, "family": v.family, "scheme": sc.coupling.scheme,
            "extrapolation_order": sc.coupling.extrapolation_order,
            "interpolation_order": sc.coupling.interpolation_order,
            "substeps": sc.coupling.substeps, "macro_step": sc.coupling.macro_step,
            "errors": errs["total"], "signal_errors": errs["signals"], "stable": stable,
            "status": "finished" if data.ok else "failed", "message": data.message,
            "wall_time_s": data.wall_time_s, "macro_steps": data.macro_steps,
            "fmu_calls": data.fmu_calls, "tolerance": dict(v.tolerance), "goal": dict(v.goal),
            "meets_goal": (stable and all(errs["total"].get(m, math.inf) <= g for m, g in v.goal.items()))
            if v.goal else None,
            "expect_order": v.expect_order, "dir": str(runs / v.name),
            "derived": derived_values(spec.derived, data.summary),
            "forward_only": _forward_only(data.summary),
            "coupling_defect": _relative_defect(data.summary),
            "order_capped_at": _order_cap(sc, real)})
    floor = _reference_floor(reference, spec.order_metric)
    orders = []
    for fam in dict.fromkeys(v["family"] for v in variants):
        members = [v for v in variants if v["family"] == fam]
        if len({v["macro_step"] for v in members}) < 2:
            continue
        usable = [v for v in members if v["stable"]]
        h = [v["macro_step"] for v in usable]
        e = [v["errors"].get(spec.order_metric, math.nan) for v in usable]
        p, p_fine, n = fit_order(h, e)
        orders.append({"family": fam, "metric": spec.order_metric, "order": p, "order_finest": p_fine,
                       "points": n, "expected": members[0]["expect_order"],
                       "near_reference": [x for x, err in zip(h, e) if floor is not None and err < floor]})
    return CompareReport(name=spec.name, reference=reference, variants=variants, orders=orders,
                         wall_time_s=time.perf_counter() - t_start)


def _reference_floor(reference: dict, metric: str) -> float | None:
    """``REFERENCE_FLOOR_FACTOR`` x the reference check's change in ``metric``, or None without a
    check (or one that failed)."""
    chk = reference.get("check")
    if not chk or not chk.get("ok"):
        return None
    change = chk["errors"].get(metric)
    return REFERENCE_FLOOR_FACTOR * change if change is not None and math.isfinite(change) else None


def _real_connections(base: Scenario) -> list[tuple[str, str]]:
    """``(from, to)`` of the base's Real connections (the FMUs' model descriptions; a connection
    whose source cannot be read counts as Real)."""
    from orchestrator.compare.capabilities import model_descriptions
    mds = model_descriptions(base)
    out = []
    for c in base.connections:
        v = getattr(mds.get(c.src_instance), "variables", {}).get(c.src_variable)
        if v is None or v.type == "Real":
            out.append((c.src, c.dst))
    return out


def _order_cap(sc: Scenario, real: list[tuple[str, str]]) -> int | None:
    """q + 1 when Gauss-Seidel's interpolation order q < k caps the order of this variant's
    coupling (scenario/coupling_sections.py ``interpolated_inputs``), else None."""
    from orchestrator.scenario.coupling_sections import interpolated_inputs
    c = sc.coupling
    order = c.sequence or tuple(f.name for f in sc.fmus)
    capped = interpolated_inputs(c.scheme, c.extrapolation_order, c.interpolation_order, order, real)
    return c.interpolation_order + 1 if capped else None


def _forward_only(summary: dict | None) -> bool:
    """The run's error-controlled step could not reject a step (an FMU cannot save its state):
    summary.json ``step_control.can_reject`` false."""
    sc = (summary or {}).get("step_control")
    return isinstance(sc, dict) and sc.get("can_reject") is False


def _relative_defect(summary: dict | None) -> dict | None:
    """``{"max": ..., "median": ...}``: the largest and the median coupling defect of the run, each
    relative to its entry's typical size, the largest over the entries (summary.json
    ``coupling_defect``, orchestrator/coupling/defect.py; constant steps: interface-Jacobian forces
    and ``coupling.defect_signals``), or None: a reference-free indicator beside the errors."""
    from orchestrator.coupling.defect import relative_defects
    rows = [r for r in relative_defects((summary or {}).get("coupling_defect")) if r[3] is not None]
    if not rows:
        return None
    return {"max": max(r[2] for r in rows), "median": max(r[3] for r in rows)}


def _snapshot_fmus(spec: CompareSpec, dest: Path) -> CompareSpec:
    """Copy every FMU of the base into ``dest`` and point the scenario there, so that all
    runs of one comparison use the same FMU files (nothing rebuilds or replaces them
    while the comparison runs: ``run`` rebuilds stale FMUs only inside the repo's fmus/)."""
    import dataclasses
    import shutil
    dest.mkdir(parents=True, exist_ok=True)
    copies: dict[Path, Path] = {}
    fmus = []
    for f in spec.base.fmus:
        src = Path(f.path)
        if not src.is_file():           # the run reports it
            fmus.append(f)
            continue
        if src not in copies:
            taken = {c.name for c in copies.values()}
            target = dest / (src.name if src.name not in taken else f"{len(copies)}-{src.name}")
            shutil.copy2(src, target)
            copies[src] = target
        fmus.append(dataclasses.replace(f, path=copies[src]))
    return dataclasses.replace(spec, base=dataclasses.replace(spec.base, fmus=tuple(fmus)))


def _errors(spec: CompareSpec, ref: RunData, run: RunData, scales) -> dict[str, Any]:
    per_signal = {}
    total = {m: 0.0 for m in spec.metrics}
    for s in spec.signals:
        if run.ok and s in run.outputs:
            e = signal_errors(ref.t, ref.outputs[s], run.t, run.outputs[s], scales[s])
        else:
            e = {m: math.inf for m in METRICS}
        per_signal[s] = {m: e[m] for m in spec.metrics}
        for m in spec.metrics:
            total[m] = max(total[m], e[m]) if not math.isnan(e[m]) else math.inf
    for dname, d in spec.derived.items():
        total[dname] = derived_error(ref.summary, run.summary, d["key"], d.get("scale"))
    return {"total": total, "signals": per_signal}


# --------------------------------------------------------------------------- CLI entry

def main_compare(path: str | os.PathLike, out_dir: str | os.PathLike | None = None,
                 update_baseline: bool = False, *, workers: int | None = None,
                 runner: Callable[[Scenario, Path], None] = default_runner) -> int:
    """``rotorcosim compare FILE [--out DIR] [--update-baseline]``; returns the exit code.

    0: every variant within tolerance and no regression against the baseline;
    1: some check failed (each failure printed, naming the variant and metric);
    2: the comparison file is invalid or the reference failed.
    With ``update_baseline`` the baseline file is rewritten from this run and
    regressions are not checked (tolerances still are).
    """
    path_arg(path, "main_compare(path)", "main_compare('compare.yaml')")
    if out_dir is not None:
        path_arg(out_dir, "main_compare(out_dir=...)", "main_compare('compare.yaml', out_dir='runs/compare')")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        # "2" ended in "'<=' not supported between instances of 'str' and 'int'" after the FMUs were copied
        raise TypeError(f"main_compare(workers=...) takes a whole number of at least 1, or None for the "
                        f"comparison file's 'workers' (got {workers!r}); e.g. workers=2")
    if not callable(runner):
        raise TypeError(f"main_compare(runner=...) takes a function runner(scenario, out_dir) (got "
                        f"{type(runner).__name__}); leave it out to run each scenario with orchestrator.run")
    try:
        spec = load_compare(path)
    except ScenarioError as exc:
        print(f"rotorcosim compare: {exc}", file=sys.stderr)
        return 2
    baseline = None
    try:         # before the runs: a missing or broken baseline must not switch the gate off
        if spec.baseline is not None and not update_baseline:
            baseline = load_baseline(spec.baseline)
        if update_baseline and spec.baseline is None:
            raise CosimError(f"{spec.source}: --update-baseline given but the file has no 'compare.baseline' path; "
                             "add 'baseline: baselines/NAME.json' to its compare: section")
        if update_baseline:     # a pipe, folder or link there would fail (or block) only after every run
            check_baseline_target(spec.baseline, f"{spec.source}: 'compare.baseline'")
    except CosimError as exc:
        print(f"rotorcosim compare: {exc}", file=sys.stderr)
        return 2
    out = Path(out_dir) if out_dir is not None else Path("out") / "compare" / spec.name
    out.mkdir(parents=True, exist_ok=True)
    try:
        report = run_comparison(spec, out, runner=runner, workers=workers)
    except RuntimeError as exc:
        print(f"rotorcosim compare: {exc}", file=sys.stderr)
        return 2
    failures = check_report(report, spec, baseline)
    write_report(report, spec, out, failures)
    if update_baseline:
        write_baseline(report, spec, spec.baseline)
        print(f"baseline written: {spec.baseline}")
    print(f"report: {out / 'report.md'}  ({len(report.variants)} variants, "
          f"{report.wall_time_s:.1f} s)")
    best = cheapest_within_tolerance(report, failures)
    if best is not None:
        print(f"cheapest within tolerance: {cheapest_text(best)}")
    for f in failures:
        print(f"FAIL {f}", file=sys.stderr)
    if not failures:
        print("compare: all checks passed")
    return 1 if failures else 0
