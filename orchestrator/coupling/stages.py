"""Stages: groups of subsystems that may step at the same time (``coupling.parallel``).

A stage is a run of consecutive subsystems in the stepping order none of which uses the
*new* value (the value at T(n+1)) of an output of another member: a subsystem that does
starts the next stage. Jacobi uses no new values, so all its subsystems form one stage;
Gauss-Seidel ``[rotor, bearing1, bearing2]`` with the rotor feeding both bearings gives
``[rotor], [bearing1, bearing2]``. Stepping the members of a stage concurrently changes
neither what any of them receives nor the order of the FMI calls of any one of them, so
the results are the same bit for bit.

One exception: during the start-up iteration every input is read from the newest
history level (``all_interp``), also the inputs a member gets from another member of its
own stage, which that member overwrites while stepping. Sequentially the first member
reads the previous pass and the later ones the current pass; concurrently that would be
a race. So a stage whose members are connected to each other (``linked``) is stepped one
after the other in start-up steps (:meth:`Stage.concurrent`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable, Sequence


@dataclass(frozen=True)
class Stage:
    names: tuple[str, ...]
    linked: bool            # some member feeds another member (Jacobi)

    def concurrent(self, *, startup: bool) -> bool:
        """May the members step at the same time in this kind of step?"""
        return len(self.names) > 1 and not (startup and self.linked)


def stages(order: Sequence[str], links: Iterable[tuple[str, str]],
           uses_new_value: Callable[[str, str, Sequence[str]], bool]) -> list[Stage]:
    """Split ``order`` into stages; ``links`` are (producer, consumer) instance pairs."""
    pairs = {(a, b) for a, b in links if a != b}
    groups: list[list[str]] = []
    for name in order:
        current = groups[-1] if groups else None
        if current is not None and not any((p, name) in pairs and uses_new_value(p, name, order) for p in current):
            current.append(name)
        else:
            groups.append([name])
    return [Stage(tuple(g), any((a, b) in pairs for a in g for b in g)) for g in groups]
