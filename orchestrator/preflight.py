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

from orchestrator.errors import CosimError


def preflight(scenario) -> tuple[list[str], list[str]]:
    """``(problems, warnings)`` that running ``scenario`` would give before its first macro step."""
    problems: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            if scenario.coupling.scheme == "monolithic":
                from orchestrator.reference.monolithic import preflight as monolithic_preflight
                monolithic_preflight(scenario)
            else:
                from orchestrator.coupling.execution import MasterAlgorithm
                # '{out_dir}' in String parameters (a fields_file) points into a scratch folder that
                # is removed afterwards: without one the FMU would get the literal text and write
                # '{out_dir}/...' into the current folder at fmi2Terminate
                with tempfile.TemporaryDirectory(prefix="rotorcosim-validate-") as scratch:
                    master = MasterAlgorithm(scenario, out_dir=scratch)
                    try:
                        master.setup()
                        with _master_log_quiet():        # its failure comes back as the problem line
                            master.initialize()
                        if master.message and master.status.name == "FAILED":
                            problems.append(master.message)
                    finally:
                        master.terminate(preflight=True)
        except CosimError as e:
            problems.extend(getattr(e, "problems", None) or [str(e)])
    return problems, [f"warning: {w.message}" for w in caught]


@contextlib.contextmanager
def _master_log_quiet():
    """The master logs a failed initialization at ERROR; validate prints it as a problem."""
    logger = logging.getLogger("orchestrator.coupling.execution")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(level)
