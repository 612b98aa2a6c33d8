"""Algebraic loops in the initial exchange: find the loop a signal belongs to, for messages.

At t0 the master exchanges outputs and inputs until they agree (outputs with direct
feedthrough depend on the inputs just set). Through a chain of feedthrough FMUs that
settles in as many passes as the chain is long; around a loop it is a fixed-point
problem ``u = G(u)`` solved with the iterative scheme's solver
(:mod:`orchestrator.coupling.acceleration`, IQN-ILS). When that fails, the message
names the loop: the cycle of connections through the consumer of the signal that
did not settle (a strongly connected component of the instance graph).
"""

from __future__ import annotations

from typing import Sequence


def loop_through(connections: Sequence, instance: str) -> list[str]:
    """The connections ``"a.y -> b.u"`` of the strongly connected component of the instance
    graph (edge producer -> consumer) that contains ``instance``; [] if it is on no cycle."""
    succ: dict[str, set[str]] = {}
    for c in connections:
        succ.setdefault(c.src_instance, set()).add(c.dst_instance)

    def reach(start: str) -> set[str]:
        seen, todo = set(), [start]
        while todo:
            n = todo.pop()
            for m in succ.get(n, ()):
                if m not in seen:
                    seen.add(m)
                    todo.append(m)
        return seen

    fwd = reach(instance)
    if instance not in fwd:
        return []
    comp = {n for n in fwd if instance in reach(n)} | {instance}
    return [f"{c.src} -> {c.dst}" for c in connections if c.src_instance in comp and c.dst_instance in comp]
