"""Python log records of FMUs: attributed to the instance whose FMI call runs, and capped.

A PythonFMU FMU runs its Python code in our process (or in its worker process) and may log
through Python's ``logging``. Its records reached our handlers like ours:
``WARNING component_model.variable: set(): values [99.0] outside range.`` named no FMU instance
(the crane-fmu FMUs log so), and an FMU that logs on every step flooded the terminal.

Now :class:`~orchestrator.fmi.subsystem.Subsystem` says in this thread which instance's FMI
call runs (one attribute store of ``RUNNING.name`` on entry and one on exit, inline in its
per-call paths as its call record is; :func:`enter` and :func:`leave` do the same; the hot path
allocates nothing; :func:`running_instance` reads it, :func:`unattributed` clears it for a
block), and the log record factory installed by :func:`install` rewrites every record made
meanwhile by a logger that is not ours (not ``orchestrator`` or below): its message becomes
``<instance>: <message>``, shown on one line with control characters escaped as the FMU's FMI
log messages are (``subsystem.log_message_text``), and the record gets ``fmu_instance``. So the
line above reads ``ERROR component_model.variable: crane: set(): values [99.0] outside range.``:
the logger name stays (it says which Python module of the FMU logged), the instance is named.
Records of our own loggers, and records made outside an FMU call, are unchanged.

The volume: a filter on the root logger's handlers (added by :func:`install`; the CLI's and a
worker process's handlers are there) lets :data:`LOG_SHOWN` such records through per instance
and run, marks the last one shown, and counts the rest; :func:`forget` (when the instance is
freed) says how many were not shown and the last of them. The FMU's full log is not kept (an
FMU that logs a million lines must not fill the disk either). A handler the FMU adds to its own
logger (``propagate = False``) gets the attributed records, uncapped: that is the FMU's choice.

Python ``warnings`` an FMU raises during its call (``warnings.warn`` in a PythonFMU slave) went
to the terminal as ``warning: <text>``, the form of rotorcosim's own warnings; :func:`install`
wraps ``warnings.showwarning`` so that one shown while an FMI call runs in this thread reads
``warning: <instance>: <text>`` and counts toward the same cap (the ``warnings`` module's own
filters still decide first whether it is shown at all).
"""

from __future__ import annotations

import contextlib
import logging
import threading

log = logging.getLogger(__name__)

#: Python log records of an FMU instance shown per run (as the FMI logger's messages:
#: ``subsystem.LOG_SHOWN``); the rest are counted and summed up when the instance is freed
LOG_SHOWN = 20

#: this thread's FMI call: ``RUNNING.name`` is the name of the instance whose FMI call runs in
#: this thread, None or unset when none does. Written by :func:`enter` and :func:`leave`, or
#: directly (one attribute store each, no call) by a caller's per-call hot path as
#: :class:`~orchestrator.fmi.subsystem.Subsystem`'s; read it with :func:`running_instance`
RUNNING = threading.local()
_counts: dict[str, list] = {}          # instance -> [shown, not shown, last text not shown]
_lock = threading.Lock()
_previous_factory = None


def enter(instance: str) -> None:
    """The FMI call of ``instance`` runs in this thread from now on."""
    RUNNING.name = instance


def leave() -> None:
    """No FMI call runs in this thread any more."""
    RUNNING.name = None


def running_instance() -> str | None:
    """The name of the instance whose FMI call runs in this thread, or None."""
    return getattr(RUNNING, "name", None)


@contextlib.contextmanager
def unattributed():
    """A block in which no FMI call runs in this thread as far as logging goes (records and
    warnings made in it are not attributed to an instance nor counted toward its cap); the
    instance that ran before is restored after it, also when the block raises."""
    before = running_instance()
    RUNNING.name = None
    try:
        yield
    finally:
        RUNNING.name = before


def _ours(name: str) -> bool:
    return name == "orchestrator" or name.startswith("orchestrator.")


def _factory(*args, **kwargs) -> logging.LogRecord:
    record = _previous_factory(*args, **kwargs)
    inst = getattr(RUNNING, "name", None)      # running_instance() inline: every record comes here
    if inst is not None and not _ours(record.name):
        from orchestrator.fmi.subsystem import log_message_text
        try:
            text = record.getMessage()
        except Exception as e:            # the FMU's format and arguments do not fit
            text = f"{record.msg!r} % {record.args!r} (cannot be formatted: {type(e).__name__})"
        record.fmu_text = log_message_text(text)
        record.msg = f"{log_message_text(inst)[:80]}: {record.fmu_text}"
        record.args = ()
        record.fmu_instance = inst
    return record


class _Cap(logging.Filter):
    """Lets :data:`LOG_SHOWN` attributed records per instance through (decided once per record,
    whichever handler sees it first)."""

    def filter(self, record: logging.LogRecord) -> bool:
        inst = getattr(record, "fmu_instance", None)
        if inst is None:
            return True
        shown = getattr(record, "fmu_shown", None)
        if shown is None:
            with _lock:
                c = _counts.setdefault(inst, [0, 0, ""])
                shown = c[0] < LOG_SHOWN
                if shown:
                    c[0] += 1
                    if c[0] == LOG_SHOWN:
                        record.msg = (f"{record.msg} (the FMU's further Python log lines are not shown: "
                                      f"{LOG_SHOWN} shown; their number is given when the instance is freed)")
                else:
                    c[1] += 1
                    c[2] = getattr(record, "fmu_text", record.msg)
            record.fmu_shown = shown
        return shown


_CAP = _Cap()
_previous_showwarning = None


def _showwarning(message, category, filename, lineno, file=None, line=None):
    inst = running_instance()
    if inst is not None:
        from orchestrator.fmi.subsystem import log_message_text
        text = log_message_text(str(message))
        with _lock:
            c = _counts.setdefault(inst, [0, 0, ""])
            if c[0] >= LOG_SHOWN:
                c[1] += 1
                c[2] = text
                return
            c[0] += 1
        message = f"{log_message_text(inst)[:80]}: {text}"
    _previous_showwarning(message, category, filename, lineno, file, line)


def install() -> None:
    """Install the record factory and the cap on the root logger's handlers (idempotent; new
    root handlers get the cap when the next FMU is loaded)."""
    global _previous_factory, _previous_showwarning
    with _lock:
        current = logging.getLogRecordFactory()
        if current is not _factory:
            _previous_factory = current
            logging.setLogRecordFactory(_factory)
    import warnings
    if warnings.showwarning is not _showwarning:
        _previous_showwarning = warnings.showwarning
        warnings.showwarning = _showwarning
    for handler in logging.getLogger().handlers:
        if _CAP not in handler.filters:
            handler.addFilter(_CAP)


def forget(instance: str) -> None:
    """The instance is freed: say how many of its Python log lines were not shown (and the last),
    and count afresh for the next instance of that name."""
    with _lock:
        c = _counts.pop(instance, None)
    if c and c[1]:
        log.warning("%s: %d more Python log lines of the FMU were not shown (%d shown; the full log is not "
                    "kept); the last: %s", instance, c[1], c[0], c[2][:300])
