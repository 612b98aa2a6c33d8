"""Coupling schemes and step-size controllers: policies the master asks once, at setup.

A :class:`CouplingScheme` decides (1) the order in which subsystems are
stepped within a macro step and (2) for each connection, whether the consumer
sees the producer's *new* value y(T(n+1)) (then its input is interpolated
through that value) or only the history up to T(n) (then it is extrapolated).
The master precomputes both at setup; the hot path never calls the scheme.

Rules for implementers: :meth:`stepping_order` returns every subsystem name
exactly once; :meth:`uses_new_value` must be consistent with that order
(a consumer can only use the new value of a producer stepped before it).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Sequence

from .errors import ScenarioError


class CouplingScheme(ABC):
    name: str = ""

    @abstractmethod
    def stepping_order(self, names: Sequence[str]) -> list[str]:
        """Order in which the subsystems are stepped within a macro step."""

    @abstractmethod
    def uses_new_value(self, producer: str, consumer: str, order: Sequence[str]) -> bool:
        """True if ``consumer`` gets ``producer``'s value at T(n+1) during the step."""


class Jacobi(CouplingScheme):
    """Parallel scheme: every subsystem steps from T(n) with extrapolated inputs.

    Each connection therefore carries one macro step of delay (with
    extrapolation order 0 an output change at T(n) reaches the consumer's
    output at T(n+2) earliest); extrapolation of order k cuts the error to
    O(H^(k+1)). The subsystems are independent within the step (they are
    stepped one after another in this process; the result does not depend on
    the order).
    """

    name = "jacobi"

    def stepping_order(self, names):
        return list(names)

    def uses_new_value(self, producer, consumer, order):
        return False


class GaussSeidel(CouplingScheme):
    """Sequential scheme (figure 4 of the paper): subsystems step in ``sequence``;
    a subsystem later in the sequence interpolates the inputs coming from
    subsystems already stepped (their new values at T(n+1) are known) and
    extrapolates the others.

    ``sequence`` may list a subset of the subsystems; the rest follow in
    scenario order.
    """

    name = "gauss-seidel"

    def __init__(self, sequence: Sequence[str] = ()):
        self.sequence = tuple(sequence)

    def stepping_order(self, names):
        names = list(names)
        unknown = [s for s in self.sequence if s not in names]
        if unknown:
            raise ScenarioError(f"coupling.sequence names {unknown} which are not FMU instances; "
                                f"valid names: {names}")
        if len(set(self.sequence)) != len(self.sequence):
            raise ScenarioError(f"coupling.sequence lists an instance twice: {list(self.sequence)}; list each once")
        return list(self.sequence) + [n for n in names if n not in self.sequence]

    def uses_new_value(self, producer, consumer, order):
        return order.index(producer) < order.index(consumer)


def scheme_from_spec(scheme: str, sequence: Sequence[str] = ()) -> CouplingScheme:
    """The scheme object for ``coupling.scheme`` (strings become classes once, here)."""
    if scheme == "jacobi":
        return Jacobi()
    if scheme == "gauss-seidel":
        return GaussSeidel(sequence)
    raise ScenarioError(f"coupling.scheme must be one of ['gauss-seidel', 'jacobi'] for the master "
                        f"(got {scheme!r}); 'monolithic' is run by orchestrator.monolithic")


class StepSizeController(ABC):
    """Gives the macro-step grid. ``time(n)`` is T(n) computed from the index
    (never accumulated); ``n_steps`` is the number of steps to reach stop_time."""

    @abstractmethod
    def time(self, n: int) -> float: ...

    n_steps: int


class ConstantStep(StepSizeController):
    """T(n) = t0 + n*H; the last step is shortened to end exactly at stop_time
    (a remainder below 1e-9*H is absorbed, not stepped)."""

    def __init__(self, t0: float, t_stop: float, h: float):
        if not (h > 0 and math.isfinite(h)):
            raise ScenarioError(f"coupling.macro_step must be a positive number (got {h!r})")
        if not t_stop > t0:
            raise ScenarioError(f"stop_time ({t_stop}) must be greater than start_time ({t0})")
        self.t0, self.t_stop, self.h = float(t0), float(t_stop), float(h)
        self.n_steps = max(1, math.ceil((self.t_stop - self.t0) / self.h - 1e-9))

    def time(self, n: int) -> float:
        if n >= self.n_steps:
            return self.t_stop
        return self.t0 + n * self.h


def fixed_step_problem(t0: float, t_stop: float, h: float, fixed: Sequence[str], discard_retries: int = 0) -> str | None:
    """Why a run cannot honour FMUs that cannot vary their communication step size, or None.

    ``fixed`` names the instances whose model description says
    ``canHandleVariableCommunicationStepSize="false"``. Such an FMU must get the
    same step every time (FMI 2.0 sec. 4.3.1), so the run needs ``stop_time`` on
    the grid ``start_time + n*macro_step`` (no shortened last step) and no discard
    retries (which halve the step).
    """
    if not fixed:
        return None
    who = ", ".join(repr(f) for f in fixed)
    why = (f"FMU instance{'s' if len(fixed) > 1 else ''} {who} cannot vary the communication step size "
           "(canHandleVariableCommunicationStepSize=\"false\")")
    steps = (t_stop - t0) / h
    if abs(steps - round(steps)) > 1e-9 * max(1.0, steps):
        lo, hi = t0 + math.floor(steps) * h, t0 + math.ceil(steps) * h
        return (f"stop_time {t_stop!r} is not on the macro-step grid start_time + n*{h!r}, so the last step would "
                f"be shortened, but {why}; use stop_time {lo:.12g} or {hi:.12g}, or a macro_step that divides "
                "stop_time - start_time")
    if discard_retries:
        return (f"coupling.discard_retries = {discard_retries} redoes discarded steps with halved step sizes, but "
                f"{why}; set coupling.discard_retries: 0")
    return None
