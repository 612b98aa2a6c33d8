"""Non-Real coupling signals (Integer, Enumeration, Boolean, String): held, never extrapolated.

A non-Real input is set once before a unit's ``fmi2DoStep`` and held over the
whole macro step (and all its sub-steps). Its value is the producer's output
read after the producer's latest step:

* a consumer stepped *after* its producer in the same macro step (the
  Gauss-Seidel case, ``uses_new_value``) gets the value at T(n+1) at once;
* every other consumer (Jacobi, and Gauss-Seidel against the stepping order)
  gets it at the end of the macro step (:meth:`DiscreteSignals.commit`), so
  during the step from T(n) it sees the value at T(n), as libcosim's Jacobi
  with zero-order hold does.

Gain and offset do not apply (they are Real-only; the scenario loader refuses
them on other types). The master calls, per macro step and unit in stepping
order: :meth:`set_inputs` (before the unit's first doStep), :meth:`read` (after
its last doStep, which also forwards the new values to immediate consumers),
and :meth:`commit` once after all units; :meth:`snapshot` / :meth:`restore`
around steps it may redo.
"""

from __future__ import annotations

from typing import Callable, Mapping, Sequence

from orchestrator.fmi.values import FAMILY, TypedBatch


FAMILIES = ("Integer", "Boolean", "String")


class _Port:
    """The typed batches of one unit: inputs and outputs per type family."""

    def __init__(self, sub, in_names: dict[str, list[str]], out_names: dict[str, list[str]]):
        self.sub = sub
        self.inb = {f: sub.typed_batch(n, f) for f, n in in_names.items() if n}
        self.outb = {f: sub.typed_batch(n, f) for f, n in out_names.items() if n}


def _copy(src: TypedBatch, i: int, dst: TypedBatch, j: int) -> None:
    if src.family == "String":
        dst.c_values[j] = src.c_values[i]      # ctypes copies the bytes and keeps them alive
    else:
        dst.values[j] = src.values[i]


def _get(sub, b: TypedBatch) -> None:
    sub.get_values(b)
    if b.family == "String":
        # the FMU's char* is valid only until its next call: take copies now
        for k, x in enumerate(b.c_values[: b.n]):
            if x is None:
                _null_string(sub, b.names[k])
            b.c_values[k] = x or b""


def _null_string(sub, name: str) -> None:
    """A NULL from fmi2GetString (FMI 2.0 wants a string, "" when empty): recorded and passed on
    as "", said once per variable of the run (a warning, not a failure: the value is unusable,
    the run is not)."""
    sub.warn_once(("NULL string", name), "FMU instance '%s' gave a NULL pointer for the String '%s' in "
                  "fmi2GetString (FMI 2.0 asks for a string, \"\" when empty); it is recorded and passed on as "
                  "\"\"; only its first NULL is reported", sub.name, name)


class DiscreteSignals:
    """The non-Real connections of a run and the non-Real recorded signals.

    ``connections``: ``(src_instance, src_variable, dst_instance, dst_variable)``
    of non-Real connections (types already checked equal); ``recorded``:
    ``instance.variable`` of non-Real recorded signals; ``immediate(src, dst)``
    tells whether ``dst`` is stepped after ``src`` in the same macro step and
    so takes its new value at once.
    """

    def __init__(self, subsystems: Mapping, connections: Sequence[tuple[str, str, str, str]],
                 recorded: Sequence[str], immediate: Callable[[str, str], bool]):
        ins: dict[str, dict[str, list[str]]] = {n: {f: [] for f in FAMILIES} for n in subsystems}
        outs: dict[str, dict[str, list[str]]] = {n: {f: [] for f in FAMILIES} for n in subsystems}

        def fam(inst, var):
            return FAMILY[subsystems[inst].variable(var).type]

        def need(table, inst, var):
            lst = table[inst][fam(inst, var)]
            if var not in lst:
                lst.append(var)

        for si, sv, di, dv in connections:
            need(outs, si, sv)
            need(ins, di, dv)
        for sig in recorded:
            inst, var = sig.split(".", 1)
            need(outs, inst, var)
        self.ports = {n: _Port(subsystems[n], ins[n], outs[n]) for n in subsystems}
        self.active = any(p.inb or p.outb for p in self.ports.values())
        # (src batch, index, dst batch, index) per connection
        self._now: dict[str, list] = {n: [] for n in subsystems}
        self._later: list = []
        self._all: list = []
        for si, sv, di, dv in connections:
            f = fam(si, sv)
            link = (self.ports[si].outb[f], outs[si][f].index(sv), self.ports[di].inb[f], ins[di][f].index(dv))
            self._all.append(link)
            (self._now[si] if immediate(si, di) else self._later).append(link)

    # -- the macro step ------------------------------------------------------------------
    def set_inputs(self, name: str) -> None:
        port = self.ports[name]
        for b in port.inb.values():
            port.sub.set_values(b)

    def read(self, name: str) -> None:
        port = self.ports[name]
        for b in port.outb.values():
            _get(port.sub, b)
        for link in self._now[name]:
            _copy(*link)

    def commit(self) -> None:
        for link in self._later:
            _copy(*link)

    def exchange_all(self) -> None:
        """Initialization: read every unit's outputs, forward along every connection, set every input."""
        for name in self.ports:
            port = self.ports[name]
            for b in port.outb.values():
                _get(port.sub, b)
        for link in self._all:
            _copy(*link)
        for name in self.ports:
            self.set_inputs(name)

    # -- values for recording ------------------------------------------------------------------
    def value_reader(self, inst: str, var: str) -> Callable[[], object]:
        """A function returning the current value of recorded non-Real output ``inst.var``."""
        sub = self.ports[inst].sub
        f = FAMILY[sub.variable(var).type]
        b = self.ports[inst].outb[f]
        i = b.names.index(var)
        if f == "String":
            return lambda: (b.c_values[i] or b"").decode("utf-8", "replace")
        if f == "Boolean":
            return lambda: bool(b.values[i])
        return lambda: int(b.values[i])

    # -- redoing steps -------------------------------------------------------------------------
    def snapshot(self):
        out = []
        for p in self.ports.values():
            for b in (*p.inb.values(), *p.outb.values()):
                out.append(list(b.c_values[: b.n]) if b.family == "String" else b.values.copy())
        return out

    def restore(self, snap) -> None:
        it = iter(snap)
        for p in self.ports.values():
            for b in (*p.inb.values(), *p.outb.values()):
                v = next(it)
                if b.family == "String":
                    for i, x in enumerate(v):
                        b.c_values[i] = x
                else:
                    b.values[:] = v
