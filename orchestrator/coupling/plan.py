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
        self.links: list[Link] = []
        self.inb: RealBatch | None = None
        self.outb: RealBatch | None = None
        self.derb: RealBatch | None = None
        self.HE = None
        self.HI = None
        self.nE = 0
        self.nI = 0
        self.delivery = None                # an InputDelivery, chosen at setup


@dataclass
class Plan:
    """Everything the macro step needs, in stepping order."""

    order: list[str]
    units: list[Unit]
    history: History
    columns: list[str]
    rec: list                 # (output values, positions, row columns) per unit with recorded signals
    stride: int               # output every ``stride`` macro steps


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


def _connections(scenario, units) -> list:
    """The scenario's connections, checked against the subsystems' variables."""
    problems = []
    seen_dst = {}
    conns = []
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
        if vs.type != "Real" or vd.type != "Real":
            problems.append(f"connection {c.src} -> {c.dst}: types {vs.type} -> {vd.type}; the master couples "
                            "Real variables only")
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
        conns.append(c)
    if problems:
        raise ScenarioError(problems)
    return conns


def output_columns(scenario, units) -> list[str]:
    """The recorded signals (``output.signals``, or every Real output of every subsystem)."""
    sig = scenario.output.signals
    if sig is None:
        cols = []
        for u in units.values():
            md = getattr(u.sub, "md", None)
            if md is not None:
                cols += [f"{u.name}.{v.name}" for v in md.outputs() if v.type == "Real"]
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
            v = units[inst].sub.variable(var)
            if v.type != "Real":
                problems.append(f"output signal '{s}' is of type {v.type}; record Real variables only")
        except ScenarioError as e:
            problems.append(f"output signal '{s}': {e.problems[0]}")
    if problems:
        raise ScenarioError(problems)
    return list(dict.fromkeys(sig))


def _wire(units, conns, scheme, order, columns) -> History:
    """Input blocks, output lists, history views, batches and links of every unit."""
    for c in conns:
        u = units[c.dst_instance]
        if scheme.uses_new_value(c.src_instance, c.dst_instance, order):
            u.int_names.append(c.dst_variable)
        else:
            u.ext_names.append(c.dst_variable)
    for c in conns:
        u = units[c.src_instance]
        if c.src_variable not in u.out_names:
            u.out_names.append(c.src_variable)
    for col in columns:
        inst, var = col.split(".", 1)
        if var not in units[inst].out_names:
            units[inst].out_names.append(var)
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
    for prod in units.values():
        groups: dict[tuple[str, str], list] = {}
        for c in conns:
            if c.src_instance != prod.name:
                continue
            cu = units[c.dst_instance]
            if c.dst_variable in cu.ext_names:
                key, col = (cu.name, "E"), cu.ext_names.index(c.dst_variable)
            else:
                key, col = (cu.name, "I"), cu.int_names.index(c.dst_variable)
            groups.setdefault(key, []).append((prod.out_names.index(c.src_variable), col, c.gain, c.offset,
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
    conns = _connections(scenario, units)
    columns = output_columns(scenario, units)
    history = _wire(units, conns, scheme, order, columns)
    ordered = [units[n] for n in order]
    col_index = {c: i for i, c in enumerate(columns)}
    rec = []
    for u in ordered:
        pos = [u.out_names.index(c.split(".", 1)[1]) for c in columns if c.split(".", 1)[0] == u.name]
        cols = [col_index[c] for c in columns if c.split(".", 1)[0] == u.name]
        if pos:
            rec.append((u.outb.values, np.asarray(pos, dtype=np.intp), np.asarray(cols, dtype=np.intp)))
    H = scenario.coupling.macro_step
    interval = scenario.output.interval or H
    stride = max(1, int(round(interval / H)))
    adaptive = getattr(getattr(scenario.coupling, "step_control", None), "type", "constant") == "error"
    if not adaptive and not math.isclose(stride * H, interval, rel_tol=1e-9):
        warnings.warn(f"output.interval {interval} is not a multiple of coupling.macro_step {H}; "
                      f"writing every {stride} macro steps ({stride * H} s)", stacklevel=3)
    return Plan(order=order, units=ordered, history=history, columns=columns, rec=rec, stride=stride)
