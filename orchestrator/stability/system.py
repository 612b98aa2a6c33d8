"""What ``rotorcosim stability`` linearises: the scenario's rotor and the bearing at each of its
stations (:func:`build_system`), and the static load on each bearing (:func:`_static_loads`).

Supported scenarios: one of our ``JeffcottRotor`` or ``TurbochargerRotor`` FMUs (its parameters,
incl. ``rotor_file``, from the scenario) and one of our ``JournalBearing`` FMUs at every bearing
station, connected by the station convention of docs/fmus.md (``rotor.x_i -> bearing.x``, ``y``,
``vx``, ``vy``, ``rotor.omega -> bearing.omega``, ``bearing.Fx -> rotor.Fx_i``, ``Fy``; gain 1,
offset 0), or one of our ``FloatingRingBearing`` FMUs at every station, connected the same way.
Anything else (another FMU, plain and floating-ring bearings on one rotor, ``m_ring_i > 0`` at a
plain bearing's station, a semi-floating ring, a bearing connected otherwise) is refused with a
message naming what is supported.

The static load on each bearing is the rotor's gravity load on that station
(:func:`rotor_fmu.stability.static_bearing_loads`, stations held at 0), plus any static force
given per bearing (``loads``, the command's ``--load BEARING=FX,FY``: a gear or belt force, a
magnetic pull, the load of a horizontal rotor with g = 0).
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from orchestrator.errors import CosimError
from orchestrator.scenario.analysis_clearance import BEARING_MODEL
from orchestrator.scenario.analysis_sampling import ROTOR_MODELS

RING_MODEL = "FloatingRingBearing"
SUPPORTED = (f"supported: one of our {' or '.join(ROTOR_MODELS)} FMUs and one of our {BEARING_MODEL} FMUs (or "
             f"one of our {RING_MODEL} FMUs) at every bearing station i, connected by the station convention of "
             "docs/fmus.md (rotor.x_i, y_i, vx_i, vy_i -> bearing.x, y, vx, vy; rotor.omega -> bearing.omega; "
             "bearing.Fx, Fy -> rotor.Fx_i, Fy_i; gain 1, offset 0), and no other FMU")
_STATION_IN = ("x", "y", "vx", "vy")


class StabilityError(CosimError):
    """A scenario the stability command does not support, or a computation that failed."""


class EigenvaluesFailed(StabilityError):
    """A speed with its static equilibrium (or orbit) whose eigenvalues could not be computed (the
    argument-principle count and the Arnoldi runs disagreed with no dense solve in reach, the rotor's
    matrices not finite): left out of the search as a speed without an equilibrium is, but named
    apart from those (``speeds_without_eigenvalues_hz``)."""


@dataclass
class Bearing:
    instance: str
    station: int                      # 1-based station of the rotor
    params: Any                       # bearing_fmu.model.BearingParams, or RingParams (kind "floating_ring")
    kind: str = "journal"             # "journal" (JournalBearing) or "floating_ring" (FloatingRingBearing)


@dataclass
class System:
    rotor_instance: str
    rotor_model: str
    rotor: Any                        # rotor_fmu.linear_rotor.LinearRotor
    f_max: float                      # the scenario's ramp end speed [Hz]
    bearings: list[Bearing]

    @property
    def rings(self) -> bool:
        """True when the stations carry floating-ring bearings (all of them: build_system)."""
        return bool(self.bearings) and self.bearings[0].kind == "floating_ring"


def _where(scenario, spec) -> str:
    src = scenario.source or "scenario"
    return f"{src}:{spec.line}" if spec.line else str(src)


def _md(spec):
    from orchestrator.fmi.archive import cached_model_description
    return cached_model_description(str(spec.path))


def _params(md, spec) -> dict:
    """The FMU's parameter values as the run has them: its start values, then the scenario's."""
    out = {n: v.start for n, v in md.variables.items() if v.causality == "parameter" and v.start is not None}
    out.update(spec.parameters)
    return out


def _fields(cls, params: dict) -> dict:
    names = {f.name for f in dataclasses.fields(cls)}
    return {k: v for k, v in params.items() if k in names}


def _make_rotor(model: str, params: dict):
    if model == "JeffcottRotor":
        from rotor_fmu.jeffcott import JeffcottModel, JeffcottParams
        kw = _fields(JeffcottParams, params)
        return JeffcottModel(JeffcottParams(**kw)), float(kw.get("f_max", JeffcottParams.f_max))
    from rotor_fmu.turbocharger import TurbochargerParams, TurbochargerRotor
    kw = _fields(TurbochargerParams, params)
    kw["rotor_file"] = params.get("rotor_file") or None       # as rotor_fmu/turbocharger_rotor.py
    kw["n_modes"] = params.get("n_modes") or None
    return TurbochargerRotor(TurbochargerParams(**kw)), float(kw.get("f_max", TurbochargerParams.f_max))


def build_system(scenario) -> System:
    """The rotor model and the bearing of each station, or :class:`StabilityError` naming why not."""
    from bearing_fmu import journal_bearing as slave
    from bearing_fmu.model import BearingParams

    kinds = {spec.name: _md(spec).model_name for spec in scenario.fmus}
    rotors = [s for s in scenario.fmus if kinds[s.name] in ROTOR_MODELS]
    if len(rotors) != 1:
        found = ", ".join(f"'{n}' ({k})" for n, k in kinds.items())
        raise StabilityError(f"{scenario.source}: `stability` needs exactly one rotor FMU of ours "
                             f"({' or '.join(ROTOR_MODELS)}); the scenario has {len(rotors)} among {found}; "
                             f"{SUPPORTED}")
    rspec = rotors[0]
    rname, rmodel = rspec.name, kinds[rspec.name]
    rparams = _params(_md(rspec), rspec)
    try:
        rotor, f_max = _make_rotor(rmodel, rparams)
    except (ValueError, OSError) as exc:
        raise StabilityError(f"{_where(scenario, rspec)}: the rotor '{rname}' ({rmodel}) cannot be built from its "
                             f"parameters: {exc}") from None
    n_st = len(rotor.bearing_dofs)
    ports = sum(1 for v in _md(rspec).variables if re.fullmatch(r"x_[0-9]+", v))
    if n_st != ports:     # the FMU refuses such a rotor when the run starts; `stability` analysed it
        raise StabilityError(f"{_where(scenario, rspec)}: the rotor '{rname}' ({rmodel}) has {n_st} bearing "
                             f"station(s) (its rotor_file {rparams.get('rotor_file') or '(the bundled one)'}), but "
                             f"the FMU has {ports} (x_1 .. x_{ports}) and refuses it when a run starts; use a rotor "
                             f"file with {ports} bearing stations")
    conns = list(scenario.connections)
    bearings: list[Bearing] = []
    for i in range(1, n_st + 1):
        hits = [c for c in conns if c.src == f"{rname}.x_{i}" and c.dst_variable == "x"]
        if len(hits) != 1:
            raise StabilityError(f"{scenario.source}: station {i} of the rotor '{rname}' needs exactly one "
                                 f"connection {rname}.x_{i} -> <bearing>.x (found {len(hits)}); {SUPPORTED}")
        b = hits[0].dst_instance
        if kinds.get(b) not in (BEARING_MODEL, RING_MODEL):
            raise StabilityError(f"{scenario.source}:{hits[0].line}: station {i} of '{rname}' is connected to "
                                 f"'{b}' ({kinds.get(b)}), not to our {BEARING_MODEL} or {RING_MODEL}; {SUPPORTED}")
        want = [(f"{rname}.{v}_{i}", f"{b}.{v}") for v in _STATION_IN] + [(f"{rname}.omega", f"{b}.omega")]
        want += [(f"{b}.F{a}", f"{rname}.F{a}_{i}") for a in ("x", "y")]
        for src, dst in want:
            ok = [c for c in conns if c.src == src and c.dst == dst and c.gain == 1.0 and c.offset == 0.0]
            if not ok:
                raise StabilityError(f"{scenario.source}: the bearing '{b}' at station {i} of '{rname}' lacks the "
                                     f"connection {src} -> {dst} (gain 1, offset 0) of the station convention; "
                                     f"write it in 'connections:'; {SUPPORTED}")
        bspec = scenario.fmu(b)
        m_ring = rparams.get(f"m_ring_{i}", 0.0)
        if kinds[b] == RING_MODEL:
            from bearing_fmu.floating_ring_bearing import ring_params
            try:
                params = ring_params(_params(_md(bspec), bspec), b)
            except (KeyError, TypeError, ValueError) as exc:
                raise StabilityError(f"{_where(scenario, bspec)}: the bearing '{b}': {exc}") from None
            bearings.append(Bearing(b, i, params, "floating_ring"))
            continue
        if isinstance(m_ring, (int, float)) and m_ring > 0:
            raise StabilityError(f"{_where(scenario, rspec)}: fmus.{rname}.parameters.m_ring_{i} is {m_ring:g} kg "
                                 f"(a ring at station {i} in the rotor's step), but station {i} carries the plain "
                                 f"{BEARING_MODEL} '{b}': set m_ring_{i}: 0, or put a {RING_MODEL} there; {SUPPORTED}")
        renamed = getattr(slave, "RENAMED", {})
        bp = {renamed.get(k, k): v for k, v in _params(_md(bspec), bspec).items()}
        try:
            params = BearingParams(**_fields(BearingParams, bp))
        except (TypeError, ValueError) as exc:
            raise StabilityError(f"{_where(scenario, bspec)}: the bearing '{b}': {exc}") from None
        bearings.append(Bearing(b, i, params))
    if len({x.kind for x in bearings}) > 1:
        rings = [f"'{x.instance}'" for x in bearings if x.kind == "floating_ring"]
        plain = [f"'{x.instance}'" for x in bearings if x.kind != "floating_ring"]
        raise StabilityError(f"{scenario.source}: the rotor '{rname}' has floating-ring bearings ({', '.join(rings)}) "
                             f"and plain journal bearings ({', '.join(plain)}); `stability` takes one kind at every "
                             f"station; {SUPPORTED}")
    used = {rname, *(b.instance for b in bearings)}
    extra = [n for n in kinds if n not in used]
    if extra:
        spec = scenario.fmu(extra[0])
        raise StabilityError(f"{_where(scenario, spec)}: the FMU '{extra[0]}' ({kinds[extra[0]]}) is not a bearing "
                             f"at a station of '{rname}'; `stability` does not know what it adds to the linear "
                             f"system and does not guess; {SUPPORTED}")
    if len({b.instance for b in bearings}) != len(bearings):
        raise StabilityError(f"{scenario.source}: one bearing instance is connected at two stations; {SUPPORTED}")
    return System(rname, rmodel, rotor, f_max, bearings)


def _static_loads(system: System, loads: dict | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(weight share, ``loads`` given, their sum) per station, (n_stations, 2) [N] each, the force
    the rotor puts on each bearing (down is -y); :class:`StabilityError` for a load on a bearing
    the scenario does not have, one not finite, a station left without load, and a net load on a
    floating ring that is not straight down."""
    from rotor_fmu.stability import static_bearing_loads
    weight = static_bearing_loads(system.rotor)
    extra = np.zeros_like(weight)
    names = [b.instance for b in system.bearings]
    for name, f in (loads or {}).items():
        if name not in names:
            raise StabilityError(f"--load {name}=...: the scenario has no bearing '{name}' at a station of the rotor "
                                 f"'{system.rotor_instance}'; its bearings: {', '.join(names)}")
        fx, fy = (float(v) for v in f)
        if not (math.isfinite(fx) and math.isfinite(fy)):
            raise StabilityError(f"--load {name}: the force must be finite (got {fx:g}, {fy:g} N)")
        extra[names.index(name)] += (fx, fy)
    total = weight + extra
    for k, (b, ld) in enumerate(zip(system.bearings, total)):
        scale = float(np.hypot(*weight[k]) + np.hypot(*extra[k]))
        if extra[k].any() and np.hypot(*ld) <= 1e-9 * scale:     # the weight cancelled up to rounding
            raise StabilityError(f"--load {b.instance}={extra[k][0]:g},{extra[k][1]:g} cancels the bearing's share of "
                                 f"the rotor's weight ({weight[k][0] + 0.0:.6g}, {weight[k][1] + 0.0:.6g}) N: it "
                                 "carries no static load, so there is no equilibrium to linearize at; --load is added "
                                 "to the weight share (the force the rotor puts on the bearing, down is -y), not its "
                                 "reaction")
        if not np.hypot(*ld) > 0.0:
            raise StabilityError(f"the bearing '{b.instance}' (station {b.station}) carries no static load (the "
                                 f"rotor's g is {getattr(system.rotor.params, 'g', '?')} and no --load for it): "
                                 "`stability` linearizes each film at its equilibrium under its static load and "
                                 f"has none to find it; give the rotor g > 0, or --load {b.instance}=FX,FY [N]")
    if system.rings:
        sideways = [(b.instance, ld) for b, ld in zip(system.bearings, total) if ld[0] != 0.0 or not ld[1] < 0.0]
        if sideways:
            name, ld = sideways[0]
            raise StabilityError(f"the floating-ring bearing '{name}' carries a static load of "
                                 f"({ld[0]:g}, {ld[1]:g}) N: "
                                 "`stability` finds a ring's operating point only under a downward load (0, -W); "
                                 "give --load with an x component of 0 and a net downward force")
    return weight, extra, total
