"""Algebraic loops in the initial exchange: find the loop a signal belongs to, for messages.

At t0 the master exchanges outputs and inputs until they agree (outputs with direct
feedthrough depend on the inputs just set). Through a chain of feedthrough FMUs that
settles in as many passes as the chain is long; around a loop it is a fixed-point
problem ``u = G(u)`` solved with the iterative scheme's solver
(:mod:`orchestrator.coupling.acceleration`, IQN-ILS). When that fails, the message
names the loop: the cycle of connections through the consumer of the signal that
did not settle (a strongly connected component of the instance graph), or, when every FMU
on it declares its direct dependencies (``<ModelStructure><Outputs>``), the cycle through
that signal at the level of the variables: :func:`signal_loop`.
"""

from __future__ import annotations

from typing import Mapping, Sequence


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


def signal_loop(connections: Sequence, signal: str, feedthrough: Mapping[str, Mapping | None]) -> list[str] | None:
    """The loop through the input ``signal`` (``"inst.var"``) at the level of variables, or None
    when an FMU on the instance-level loop does not declare its dependencies.

    Edges: each connection (output -> input) and, inside each FMU, input -> output where
    ``feedthrough[inst][output]`` (the inputs it depends on directly,
    :meth:`orchestrator.fmi.model_description.ModelDescription.direct_feedthrough`) names the
    input. Returns the connections of the strongly connected component of ``signal`` with, after
    each consumer, the outputs it passes on (``"a.y -> b.u (b: u -> y)"``); [] when the
    declared dependencies leave ``signal`` on no cycle."""
    inst = signal.split(".", 1)[0]
    members = {c.split(" -> ", 1)[0].split(".", 1)[0] for c in loop_through(connections, inst)}
    if not members:
        return []
    declared = {}
    for m in members:
        feed = feedthrough.get(m)
        if feed is None or any(d is None for d in feed.values()):
            return None
        declared[m] = feed
    succ: dict[str, list[str]] = {}
    pred: dict[str, list[str]] = {}

    def edge(a: str, b: str) -> None:
        succ.setdefault(a, []).append(b)
        pred.setdefault(b, []).append(a)

    inside = [c for c in connections if c.src_instance in members and c.dst_instance in members]
    for c in inside:
        edge(c.src, c.dst)
    for m, feed in declared.items():
        for out, deps in feed.items():
            for u in deps:
                edge(f"{m}.{u}", f"{m}.{out}")

    def reach(start: str, nxt: dict) -> set[str]:
        seen, todo = {start}, [start]
        while todo:
            for b in nxt.get(todo.pop(), ()):
                if b not in seen:
                    seen.add(b)
                    todo.append(b)
        return seen

    comp = reach(signal, succ) & reach(signal, pred)
    if len(comp) < 2:
        return []
    out = []
    for c in inside:
        if c.src in comp and c.dst in comp:
            passed = [y.split(".", 1)[1] for y in succ.get(c.dst, ()) if y in comp]
            via = f" ({c.dst_instance}: {c.dst_variable} -> {', '.join(passed)})" if passed else ""
            out.append(f"{c.src} -> {c.dst}{via}")
    return out
