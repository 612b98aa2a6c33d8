"""The stepping plan, precomputed at setup: units (one per subsystem), links, the sequence.

:func:`make_plan` checks the wiring against the subsystems (which may be plain-Python
fakes the scenario loader never saw), splits each consumer's inputs into extrapolated
and interpolated blocks, allocates the coupling history and chooses each unit's input
delivery once (:mod:`orchestrator.coupling.delivery`).
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass

import numpy as np

from orchestrator.coupling.delivery import choose_delivery
from orchestrator.coupling.discrete import DiscreteSignals
from orchestrator.coupling.signals import History
from orchestrator.errors import ScenarioError
from orchestrator.fmi.subsystem import RealBatch, SubsystemBase
from orchestrator.scenario.model import MAX_ORDER

log = logging.getLogger(__name__)


class Link:
    """Outputs of one producer going into one consumer block (vectorised)."""

    __slots__ = ("pos", "block", "cols", "gain", "offset", "names", "identity", "tmp", "small", "row0")

    def __init__(self, pos, block, cols, gain, offset, names):
        self.pos = np.asarray(pos, dtype=np.intp)
        self.block = block
        self.cols = np.asarray(cols, dtype=np.intp)
        self.gain = np.asarray(gain, dtype=float)
        self.offset = np.asarray(offset, dtype=float)
        self.names = names          # "src -> dst" per entry, for messages
        self.identity = bool(np.all(self.gain == 1.0) and np.all(self.offset == 0.0))
        self.tmp = np.zeros(len(self.pos))
        self.row0 = block[0]
        self.small = None
        if len(self.pos) <= 4:
            self.small = [(int(p), int(c), float(g), float(o))
                          for p, c, g, o in zip(self.pos, self.cols, self.gain, self.offset)]
        c = self.cols
        if len(c) and np.array_equal(c, np.arange(c[0], c[0] + len(c))):
            self.cols = slice(int(c[0]), int(c[0]) + len(c))     # contiguous: cheaper assignment


class Unit:
    """Per-subsystem plan: inputs (extrapolated ``E`` / interpolated ``I``), outputs, links, delivery."""

    def __init__(self, sub: SubsystemBase, substeps: int):
        self.sub = sub
        self.name = sub.name
        self.substeps = substeps
        self.ext_names: list[str] = []      # inputs extrapolated (producer not yet stepped)
        self.int_names: list[str] = []      # inputs interpolated (producer stepped before)
        self.out_names: list[str] = []
        self.out_pos: dict[str, int] = {}   # name -> index in out_names (setup linear in the variables)
        self.links: list[Link] = []
        self.inb: RealBatch | None = None
        self.outb: RealBatch | None = None
        self.derb: RealBatch | None = None
        self.HE = None
        self.HI = None
        self.nE = 0
        self.nI = 0
        self.delivery = None                # an InputDelivery, chosen at setup
        self.disc = False                   # has non-Real inputs or outputs (orchestrator.coupling.discrete)

    def add_output(self, name: str) -> None:
        if name not in self.out_pos:
            self.out_pos[name] = len(self.out_names)
            self.out_names.append(name)


@dataclass
class Plan:
    """Everything the macro step needs, in stepping order."""

    order: list[str]
    units: list[Unit]
    history: History
    columns: list[str]
    rec: list                 # (output values, positions, row columns) per unit with recorded signals
    stride: int               # output every ``stride`` macro steps
    kinds: list[str]          # FMI type of each column
    discrete: DiscreteSignals  # the non-Real connections and recorded signals
    rec_typed: list           # (row column, reader) per non-Real recorded signal


def _where(scenario) -> str:
    src = getattr(scenario, "source", None)
    return f"{src}: " if src else ""


def _units(scenario, subsystems) -> dict[str, Unit]:
    units = {}
    for f in scenario.fmus:
        sub = subsystems[f.name]
        m = f.substeps if f.substeps is not None else scenario.coupling.substeps
        if not (isinstance(m, int) and m >= 1):
            raise ScenarioError(f"substeps of '{f.name}' must be an integer >= 1 (got {m!r})")
        units[f.name] = Unit(sub, m)
    return units


def _connections(scenario, units) -> tuple[list, list]:
    """The scenario's connections, checked against the subsystems' variables: ``(Real connections,
    non-Real connections as (src_instance, src_variable, dst_instance, dst_variable))``."""
    problems = []
    seen_dst = {}
    conns = []
    discrete = []
    for c in scenario.connections:
        si, di = c.src_instance, c.dst_instance
        for inst, what in ((si, c.src), (di, c.dst)):
            if inst not in units:
                problems.append(f"connection {c.src} -> {c.dst}: no FMU instance '{inst}' "
                                f"(instances: {', '.join(units)})")
        if si not in units or di not in units:
            continue
        try:
            vs = units[si].sub.variable(c.src_variable)
            vd = units[di].sub.variable(c.dst_variable)
        except ScenarioError as e:
            problems.append(f"connection {c.src} -> {c.dst}: {e.problems[0]}")
            continue
        if vs.type != vd.type:
            problems.append(f"connection {c.src} -> {c.dst}: type mismatch, '{c.src}' is {vs.type} but "
                            f"'{c.dst}' is {vd.type}; connect variables of the same type")
            continue
        if vd.causality != "input":
            problems.append(f"connection {c.src} -> {c.dst}: '{c.dst}' has causality '{vd.causality}', "
                            "expected an input")
            continue
        if c.dst in seen_dst:
            problems.append(f"input '{c.dst}' is connected twice (from {seen_dst[c.dst]} and {c.src}); "
                            "connect each input once")
            continue
        seen_dst[c.dst] = c.src
        if vs.type != "Real":
            if c.gain != 1.0 or c.offset != 0.0:
                problems.append(f"connection {c.src} -> {c.dst}: gain/offset apply to Real connections only "
                                f"(this one is {vs.type}); remove them")
            discrete.append((si, c.src_variable, di, c.dst_variable))
            continue
        conns.append(c)
    if problems:
        raise ScenarioError(problems)
    return conns, discrete


def output_columns(scenario, units) -> list[str]:
    """The recorded signals (``output.signals``, or every output of every subsystem, of any type)."""
    sig = scenario.output.signals
    if sig is None:
        cols = []
        for u in units.values():
            md = getattr(u.sub, "md", None)
            if md is not None:
                cols += [f"{u.name}.{v.name}" for v in md.outputs()]
            else:
                cols += [f"{u.name}.{n}" for n in getattr(u.sub, "output_names", ())]
        return cols
    problems = []
    for s in sig:
        if "." not in s or s.split(".", 1)[0] not in units:
            problems.append(f"output signal '{s}': expected '<instance>.<variable>' with an instance in "
                            f"{list(units)}")
            continue
        inst, var = s.split(".", 1)
        try:
            units[inst].sub.variable(var)
        except ScenarioError as e:
            problems.append(f"output signal '{s}': {e.problems[0]}")
    if problems:
        raise ScenarioError(problems)
    return list(dict.fromkeys(sig))


def _wire(units, conns, scheme, order, columns, kinds) -> History:
    """Input blocks, output lists, history views, batches and links of every unit."""
    for c in conns:
        u = units[c.dst_instance]
        if scheme.uses_new_value(c.src_instance, c.dst_instance, order):
            u.int_names.append(c.dst_variable)
        else:
            u.ext_names.append(c.dst_variable)
    for c in conns:
        units[c.src_instance].add_output(c.src_variable)
    for col, kind in zip(columns, kinds):
        inst, var = col.split(".", 1)
        if kind == "Real":
            units[inst].add_output(var)
    history = History(MAX_ORDER + 1)
    sizes = []
    for u in units.values():
        u.nE, u.nI = len(u.ext_names), len(u.int_names)
        sizes += [u.nE, u.nI]
    views = iter(history.allocate(sizes))
    for u in units.values():
        u.inb = u.sub.real_batch(u.ext_names + u.int_names)
        u.outb = u.sub.real_batch(u.out_names)
        u.HE = next(views)
        u.HI = next(views)
        if u.sub.can_interpolate_inputs and (u.nE + u.nI):
            u.derb = u.sub.derivative_batch(u.ext_names + u.int_names, MAX_ORDER)
        u.delivery = choose_delivery(u)
    block_pos = {(u.name, grp): {n: i for i, n in enumerate(names)}
                 for u in units.values() for grp, names in (("E", u.ext_names), ("I", u.int_names))}
    for prod in units.values():
        groups: dict[tuple[str, str], list] = {}
        for c in conns:
            if c.src_instance != prod.name:
                continue
            grp = "E" if c.dst_variable in block_pos[(c.dst_instance, "E")] else "I"
            key, col = (c.dst_instance, grp), block_pos[(c.dst_instance, grp)][c.dst_variable]
            groups.setdefault(key, []).append((prod.out_pos[c.src_variable], col, c.gain, c.offset,
                                               f"{c.src} -> {c.dst}"))
        for (cname, grp), entries in groups.items():
            block = units[cname].HE if grp == "E" else units[cname].HI
            pos, cols, gains, offs, nm = zip(*entries)
            prod.links.append(Link(pos, block, cols, gains, offs, list(nm)))
    return history


def make_plan(scenario, subsystems, scheme) -> Plan:
    """The plan of ``scenario`` over ``subsystems`` (``{name: SubsystemBase}``) for ``scheme``."""
    order = scheme.stepping_order(list(subsystems))
    units = _units(scenario, subsystems)
    conns, discrete_conns = _connections(scenario, units)
    columns = output_columns(scenario, units)
    kinds = [units[c.split(".", 1)[0]].sub.variable(c.split(".", 1)[1]).type for c in columns]
    history = _wire(units, conns, scheme, order, columns, kinds)
    discrete = DiscreteSignals({n: u.sub for n, u in units.items()}, discrete_conns,
                               [c for c, k in zip(columns, kinds) if k != "Real"],
                               lambda a, b: scheme.uses_new_value(a, b, order))
    for u in units.values():
        port = discrete.ports[u.name]
        u.disc = bool(port.inb or port.outb)
    ordered = [units[n] for n in order]
    col_index = {c: i for i, c in enumerate(columns)}
    real_cols = [c for c, k in zip(columns, kinds) if k == "Real"]
    rec_typed = [(col_index[c], discrete.value_reader(*c.split(".", 1))) for c, k in zip(columns, kinds) if k != "Real"]
    rec = []
    for u in ordered:
        pos = [u.out_pos[c.split(".", 1)[1]] for c in real_cols if c.split(".", 1)[0] == u.name]
        cols = [col_index[c] for c in real_cols if c.split(".", 1)[0] == u.name]
        if pos:
            rec.append((u.outb.values, np.asarray(pos, dtype=np.intp), np.asarray(cols, dtype=np.intp)))
    H = scenario.coupling.macro_step
    interval = scenario.output.interval or H
    stride = max(1, int(round(interval / H)))
    spec = getattr(scenario.coupling, "step_control", None)
    # error-controlled to the end (no step_control.until, after which the constant steps write every stride)
    adaptive = getattr(spec, "type", "constant") == "error" and getattr(spec, "until", None) is None
    if not adaptive and not math.isclose(stride * H, interval, rel_tol=1e-9):
        warnings.warn(f"output.interval {interval} is not a multiple of coupling.macro_step {H}; "
                      f"writing every {stride} macro steps ({stride * H} s)", stacklevel=3)
    return Plan(order=order, units=ordered, history=history, columns=columns, rec=rec, stride=stride,
                kinds=kinds, discrete=discrete, rec_typed=rec_typed)
