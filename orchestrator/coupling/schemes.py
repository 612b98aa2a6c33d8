"""Coupling schemes: policies the master asks once, at setup.

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

from abc import ABC, abstractmethod
from typing import Sequence

from orchestrator.errors import ScenarioError


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
    if scheme in ("gauss-seidel", "iterative"):     # iterative: Gauss-Seidel passes repeated (iterative.py)
        return GaussSeidel(sequence)
    raise ScenarioError(f"coupling.scheme must be one of ['gauss-seidel', 'iterative', 'jacobi'] for the master "
                        f"(got {scheme!r}); 'monolithic' is run by orchestrator.reference")
