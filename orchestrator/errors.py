"""Exception hierarchy of rotorcosim.

Bad input and misuse raise one of these; numerical failure during a run is a
status of the result (see :mod:`orchestrator.coupling.execution`), not an exception.

Every message names the thing, what was expected, what came, and the fix,
in the form ``file:line: what is wrong (got X); how to fix``.
"""

from __future__ import annotations


class CosimError(Exception):
    """Base of every error rotorcosim raises on purpose."""


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
