"""Exception hierarchy of rotorcosim.

Bad input and misuse raise one of these; numerical failure during a run is a
status of the result (see :mod:`orchestrator.coupling.execution`), not an exception.

Every message names the thing, what was expected, what came, and the fix,
in the form ``file:line: what is wrong (got X); how to fix``.
"""

from __future__ import annotations


class CosimError(Exception):
    """Base of every error rotorcosim raises on purpose."""


def path_arg(value, call: str, example: str):
    """``value`` as a :class:`pathlib.Path` for the Python API: a str or os.PathLike, else a
    TypeError that names the call and argument (``call``, e.g. ``"run(out_dir=...)"``) and shows
    ``example`` (``None``, a number or bytes used to end in pathlib's "expected str, bytes or
    os.PathLike object, not NoneType")."""
    import os
    from pathlib import Path
    if isinstance(value, (str, os.PathLike)) and not isinstance(value, bytes):
        try:
            return Path(value)
        except TypeError:        # an os.PathLike whose __fspath__ gives bytes
            pass
    got = f"{type(value).__name__} {value!r}"[:120]
    fix = ("; decode it first (os.fsdecode(...))" if isinstance(value, bytes) else "")
    raise TypeError(f"{call} takes a file or folder name as str or pathlib.Path (got {got}){fix}; "
                    f"e.g. {example}")


class ScenarioError(CosimError):
    """A scenario file (or its FMUs) is invalid.

    ``problems`` holds every problem found, one readable line each; the
    message joins them so that a user fixes them all in one go.
    """

    def __init__(self, problems: list[str] | str):
        if isinstance(problems, str):
            problems = [problems]
        self.problems = list(problems)
        head = "invalid scenario" if len(self.problems) == 1 else (
            f"invalid scenario ({len(self.problems)} problems)")
        super().__init__(head + ":\n  " + "\n  ".join(self.problems))


class FmuError(CosimError):
    """An FMU archive cannot be used (missing, unsafe, unreadable, unsupported)."""


class FmuCallError(CosimError):
    """An FMI function returned fmi2Warning-worse status or the FMU raised.

    Attributes: ``instance`` (scenario instance name), ``function`` (FMI
    function name), ``status`` (``'error'``, ``'discard'``, ``'fatal'``, ...).
    """

    def __init__(self, instance: str, function: str, status: str, detail: str = ""):
        self.instance = instance
        self.function = function
        self.status = status
        msg = f"FMU instance '{instance}': {function} returned {status}"
        if detail:
            msg += f": {detail}"
        super().__init__(msg)


class CouplingError(CosimError):
    """A coupling signal became invalid (NaN/inf) or the scheme cannot proceed."""


class LifecycleError(CosimError):
    """A master or subsystem method was called out of order."""


class OutputWriteError(LifecycleError):
    """A run's own file (results.csv / results.parquet, summary.json) could not be written: the disk
    is full, a quota is exceeded, the device failed. The message names the file, the operating
    system's reason and, for results, the time the run stopped at and the rows kept."""


class FmuCrashError(FmuCallError):
    """An FMU's worker process died or did not answer in time (``coupling.call_timeout``).

    Raised by :class:`orchestrator.fmi.worker.WorkerSubsystem` in place of the reply to an
    FMI call. Attributes besides ``instance`` / ``function``: ``status`` (``'crashed'`` or
    ``'timeout'``), ``fmu`` (the .fmu file), ``time`` (simulation time of the call [s]),
    ``cause`` (short: ``'SIGSEGV'``, ``'exit code 3'``, ``'timeout after 2 s'``),
    ``signal`` (signal name or None), ``exit_code`` (int or None), ``timeout`` (s or None).
    :meth:`report` is the dict written to summary.json.
    """

    def __init__(self, instance: str, function: str, *, fmu: str, time: float | None, cause: str,
                 signal: str | None = None, exit_code: int | None = None, timeout: float | None = None,
                 detail: str = ""):
        self.instance, self.function = instance, function
        self.status = "timeout" if timeout is not None else "crashed"
        self.fmu, self.time, self.cause = fmu, time, cause
        self.signal, self.exit_code, self.timeout = signal, exit_code, timeout
        at = f" at t={time:.12g} s" if time is not None else ""
        what = "did not answer" if timeout is not None else "crashed"
        CosimError.__init__(self, f"FMU instance '{instance}' ({fmu}) {what} in {function}{at}: {detail or cause}")

    def report(self) -> dict:
        return {"instance": self.instance, "fmu": self.fmu, "function": self.function, "time": self.time,
                "cause": self.cause, "signal": self.signal, "exit_code": self.exit_code,
                "timeout_s": self.timeout}
