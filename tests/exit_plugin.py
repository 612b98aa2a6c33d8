"""pytest hooks: the test process leaves as the ``rotorcosim`` command does (``orchestrator.cli.exit_process``).

Many tests load our PythonFMU-built FMUs in this process. PythonFMU 0.7.0 can abort in the
interpreter's teardown when it frees them ("corrupted double-linked list", SIGABRT, exit 134;
the reason is in ``orchestrator.cli.console_main``). Seen once at the end of CI's test run
(2026-12-03, clean clone of 2225364): 934 passed, the summary printed, then the abort, and
``.ci/run`` failed on exit code 134. So when an FMU library was loaded, the session ends
after every other plugin's ``pytest_unconfigure`` (trylast) through ``exit_process`` with
pytest's own exit status: the atexit handlers run and the output is flushed, the teardown
is skipped. Without an in-process FMU the process ends normally.
"""

from __future__ import annotations

import pytest

_status: list[int] = []


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session, exitstatus):
    _status[:] = [int(exitstatus)]


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    import sys
    subsystem = sys.modules.get("orchestrator.fmi.subsystem")
    if _status and subsystem is not None and subsystem.native_fmu_loaded:
        from orchestrator.cli import exit_process
        exit_process(_status[0])
