"""The checks ``run`` makes before its first step, for ``validate`` to make too (same messages).

:func:`preflight` sets the run up as :func:`orchestrator.run` would, without
stepping: for a co-simulation it creates a :class:`MasterAlgorithm` and calls
``setup()`` (the FMU archives are checked and extracted, the binary for this
platform loaded, every FMU instantiated and its values set, the coupling plan
built: types, fixed-step FMUs, discard retries that need state saving, the
output interval) and ``initialize()`` (FMI initialization and the initial exchange:
an FMU that refuses its parameter values there, or an algebraic loop that does not
converge, is reported as ``run`` reports it), then terminates and frees everything; for ``scheme: monolithic`` it calls
:func:`orchestrator.monolithic.preflight`. Whatever ``run`` would raise comes
back as problem lines; warnings ``run`` would give come back as lines starting
with ``warning:``.
"""

from __future__ import annotations

import contextlib
import logging
import tempfile
import warnings

from orchestrator.errors import CosimError, FmuCrashError


def preflight(scenario) -> tuple[list[str], list[str]]:
    """``(problems, warnings)`` that running ``scenario`` would give before its first macro step.

    Every FMU is loaded in a worker process of its own here (``isolation: process``,
    docs/coupling.md), whatever the scenario says: an FMU whose binary crashes while it is
    loaded, instantiated, initialized or freed then ends its worker, not ``validate``, and
    comes back as a problem (a warning when it crashes in fmi2FreeInstance) naming the instance,
    the FMI function and the signal, with what ``run`` would do with it."""
    problems: list[str] = []
    freeing: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            if scenario.coupling.scheme == "monolithic":
                from orchestrator.reference.monolithic import preflight as monolithic_preflight
                monolithic_preflight(scenario)
            else:
                from orchestrator.coupling.execution import MasterAlgorithm
                from orchestrator.scenario.limits import max_worker_processes
                limit = max_worker_processes()
                if len(scenario.fmus) > limit:      # a worker process each (~35 MB): load them as run does
                    warnings.warn(f"validate loads the {len(scenario.fmus)} FMU instances as `run` does, not each in "
                                  f"a worker process of its own (more than ROTORCOSIM_MAX_WORKERS = {limit}); an FMU "
                                  "that crashes while loading then ends validate without a message")
                    checked = scenario
                else:
                    checked = _isolated(scenario)
                # '{out_dir}' in String parameters (a fields_file) points into a scratch folder that
                # is removed afterwards: without one the FMU would get the literal text and write
                # '{out_dir}/...' into the current folder at fmi2Terminate
                with tempfile.TemporaryDirectory(prefix="rotorcosim-validate-") as scratch:
                    master = MasterAlgorithm(checked, out_dir=scratch)
                    try:
                        master.setup()
                        with _master_log_quiet():        # its failure comes back as the problem line
                            master.initialize()
                        if master.message and master.status.name == "FAILED":
                            problems.append(master.message + _crash_hint(scenario, master.failure))
                    finally:
                        with _collect_warnings(freeing):  # a crash while freeing: a warning line
                            master.terminate(preflight=True)
        except FmuCrashError as e:
            problems.append(str(e) + _crash_hint(scenario, e.report()))
        except CosimError as e:
            problems.extend(getattr(e, "problems", None) or [str(e)])
    return problems, [f"warning: {w.message}" for w in caught] + [
        f"warning: {text}; `run` writes results.csv and summary.json before it frees the FMUs, so a "
        "run keeps its record, but its exit code shows the crash" for text in freeing]


#: [s] the longest ``validate`` waits for one FMI call of an FMU when the scenario sets no
#: ``coupling.call_timeout``: an FMU that hangs while it is instantiated, initialized or freed
#: is then reported instead of holding ``validate`` forever (our mass-conserving bearings
#: initialize in about a second; a 2^18-cell film in a few minutes)
VALIDATE_CALL_TIMEOUT = 600.0


def _isolated(scenario):
    """``scenario`` with every FMU in a worker process of its own (``isolation: process``) and,
    unless the scenario bounds it, :data:`VALIDATE_CALL_TIMEOUT` for each call."""
    from dataclasses import replace
    timeout = scenario.coupling.call_timeout
    return replace(scenario, fmus=tuple(replace(f, isolation="process") for f in scenario.fmus),
                   coupling=replace(scenario.coupling, isolation="process",
                                    call_timeout=VALIDATE_CALL_TIMEOUT if timeout is None else timeout))


def _crash_hint(scenario, failure: dict | None) -> str:
    """What ``run`` does with an FMU that crashed in ``validate``'s worker: in the master's own
    process (``isolation: none``) the crash ends the run without a report."""
    if not failure or not failure.get("instance"):
        return ""
    if failure.get("timeout_s") is not None:
        if scenario.coupling.call_timeout is not None:
            return ""
        name = failure["instance"]
        isolated = _isolation(scenario, name) == "process"
        return (f"; validate waits at most {VALIDATE_CALL_TIMEOUT:g} s for each FMI call when the scenario "
                "sets no coupling.call_timeout; `run` waits without a limit (a second Ctrl-C or SIGTERM ends "
                "it): set coupling.call_timeout"
                + ("" if isolated else f" and fmus.{name}.isolation: process (the limit applies to FMUs in "
                                       "worker processes)"))
    name = failure["instance"]
    if _isolation(scenario, name) != "none":
        return ""
    return (f"; `run` loads '{name}' into its own process (isolation: none), where this crash would end "
            f"the run without a message or final summary: set fmus.{name}.isolation: process to have it "
            "reported, or fix or replace the FMU")


def _isolation(scenario, name: str) -> str | None:
    """The isolation ``run`` gives instance ``name`` ("none", "process"; None: not in the scenario)."""
    try:
        spec = scenario.fmu(name)
    except KeyError:
        return None
    return spec.isolation or scenario.coupling.isolation


@contextlib.contextmanager
def _collect_warnings(into: list[str]):
    """Warnings the master and the worker adapters log meanwhile, collected as text, not shown."""
    class _Collect(logging.Handler):
        def emit(self, record):
            if record.levelno >= logging.WARNING:
                into.append(record.getMessage())

    loggers = [logging.getLogger(n) for n in ("orchestrator.fmi.worker", "orchestrator.coupling.execution")]
    handler = _Collect()
    saved = [(lg.propagate, lg.handlers[:]) for lg in loggers]
    for lg in loggers:
        lg.addHandler(handler)
        lg.propagate = False
    try:
        yield
    finally:
        for lg, (prop, _) in zip(loggers, saved):
            lg.removeHandler(handler)
            lg.propagate = prop


def _master_log_quiet():
    """The master logs a failed initialization at ERROR; validate prints it as a problem."""
    return quiet_logger("orchestrator.coupling.execution", logging.CRITICAL)


@contextlib.contextmanager
def quiet_logger(name: str, level: int):
    """Only records of ``level`` and above from the logger ``name`` (and its children that set no
    level of their own) while the block runs; its own level again afterwards."""
    logger = logging.getLogger(name)
    before = logger.level
    logger.setLevel(level)
    try:
        yield
    finally:
        logger.setLevel(before)
