"""Linear stability threshold of a scenario's rotor-bearing system (``rotorcosim stability``).

What it computes (docs/analysis.md, "Linear stability threshold"): the lowest speed at which an
eigenvalue of the rotor's linear model with speed-dependent linear film coefficients at its
bearing stations crosses into the right half plane (a geometric scan of the whole range, then
Brent on every sign change of the largest real part, the first upwards with the bracket and
tolerances of :func:`rotor_fmu.stability.threshold_speed`; Lund 1974, J. Eng. Ind. 96:509; Childs
1993, "Turbomachinery Rotordynamics", sec. 3.6), the whirl frequency ratio of the crossing mode,
and each bearing's static eccentricity there. The coefficients are taken at the static
equilibrium of each journal under the rotor's gravity load on that station
(:func:`rotor_fmu.stability.static_bearing_loads`, stations held at 0), plus any static force
given per bearing (``loads``, the command's ``--load BEARING=FX,FY``: a gear or belt force, a
magnetic pull, the load of a horizontal rotor with g = 0):

* ``film="short"``: the closed-form short-bearing (Ocvirk 1952, NACA TN 2808) pi-film
  coefficients (:func:`rotor_fmu.stability.short_bearing_coefficients`) of each bearing's
  R, B (length), c = psi R and eta0 - a bound for B/D not small; grooves and feed pressure
  are not in the closed form;
* ``film="hs"``: the scenario's own finite-length half-Sommerfeld film (its R, B, psi, eta0,
  p0, p_feed, groove, grid): the equilibrium by Newton on the journal centre
  (:func:`bearing_fmu.linearize.hs_static_equilibrium`), the coefficients
  by :func:`bearing_fmu.linearize.hs_linearization` (what the FMU outputs as ``kxx .. cyy``;
  with ``contact = 1`` plus the asperity contact's force and coefficients, as the FMU adds them),
  as docs/paper_cases_radius.py does. For a mass-conserving bearing (``cavitation = 1``) these
  are the half-Sommerfeld film's coefficients (the HS linearisation), said so in the result.

Supported scenarios: one of our ``JeffcottRotor`` or ``TurbochargerRotor`` FMUs (its parameters,
incl. ``rotor_file``, from the scenario) and one of our ``JournalBearing`` FMUs at every bearing
station, connected by the station convention of docs/fmus.md (``rotor.x_i -> bearing.x``, ``y``,
``vx``, ``vy``, ``rotor.omega -> bearing.omega``, ``bearing.Fx -> rotor.Fx_i``, ``Fy``; gain 1,
offset 0), or one of our ``FloatingRingBearing`` FMUs at every station, connected the same way.
Anything else (another FMU, plain and floating-ring bearings on one rotor, ``m_ring_i > 0`` at a
plain bearing's station, a semi-floating ring, a bearing connected otherwise) is refused with a
message naming what is supported.

Floating-ring bearings (:func:`rotor_fmu.floating_ring_stability.ring_system_eigen`,
docs/floating-ring.md): at each speed, each ring's steady operating point under the station's
static load (its weight share plus any ``loads``, downward only; ring speed from the torque
balance of its two films, journal and ring at their static equilibria), the half-Sommerfeld
coefficients of its inner film (at the wedge speed omega + Omega) and outer film, and the ring's
translation as two more degrees of freedom per station (mass ``m_ring``). The ring spin is held
at its steady value, as the classical linear analyses do (Tatara 1970; Tanaka & Hori 1972);
``ring_spin=True`` adds each ring's spin perturbation as a first-order degree of freedom. Only
the half-Sommerfeld films (``film="hs"``): the short-bearing closed form has no ring.
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

FILMS = ("short", "hs", "mc")
MC_SCAN = 12            # speeds of the default scan with --film mc (about 20 s each at 40 x 40)
RING_MODEL = "FloatingRingBearing"
SUPPORTED = (f"supported: one of our {' or '.join(ROTOR_MODELS)} FMUs and one of our {BEARING_MODEL} FMUs (or "
             f"one of our {RING_MODEL} FMUs) at every bearing station i, connected by the station convention of "
             "docs/fmus.md (rotor.x_i, y_i, vx_i, vy_i -> bearing.x, y, vx, vy; rotor.omega -> bearing.omega; "
             "bearing.Fx, Fy -> rotor.Fx_i, Fy_i; gain 1, offset 0), and no other FMU")
_STATION_IN = ("x", "y", "vx", "vy")


class StabilityError(CosimError):
    """A scenario the stability command does not support, or a computation that failed."""


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


# --------------------------------------------------------------------------- coefficients
def _short(p) -> dict:
    """The short-bearing closed form's geometry and viscosity of a bearing's BearingParams."""
    return dict(R=p.R, L=p.B, C=p.psi * p.R, eta=p.eta0)


_NUMERIC = (ValueError, ArithmeticError, np.linalg.LinAlgError)   # what an absurd parameter makes the numerics raise


def _failed(b: Bearing, omega: float | None, exc: BaseException) -> StabilityError:
    """The message of a film computation of bearing b that failed (an absurd parameter, a speed far off)."""
    p = b.params
    at = f" at {omega / (2 * math.pi):.4g} Hz" if omega is not None else ""
    return StabilityError(f"bearing '{b.instance}' (station {b.station}; R = {p.R:g} m, B = {p.B:g} m, "
                          f"c = psi R = {p.psi * p.R:g} m, eta0 = {p.eta0:g} Pa s): its film has no usable static "
                          f"equilibrium{at}: {exc or type(exc).__name__}; check these parameters (--set "
                          f"fmus.{b.instance}.parameters.NAME=VALUE) against the load, or give a --speeds LO:HI "
                          "nearer the rotor's running speeds")


class _ShortFilm:
    """Ocvirk coefficients of each station under its static load (closed form)."""

    method = ("short-bearing (Ocvirk) pi-film closed form (rotor_fmu/stability.py), at the static equilibrium "
              "under its static load (the rotor's weight share, plus --load)")

    def __init__(self, system: System, loads: np.ndarray):
        self.loads = loads
        self.system = system

    def __call__(self, omega):
        from rotor_fmu.stability import short_bearing_coefficients
        K, C = [], []
        for b, ld in zip(self.system.bearings, self.loads):
            try:
                k, c = short_bearing_coefficients(ld, omega, **_short(b.params))
            except _NUMERIC as exc:
                raise _failed(b, omega, exc) from None
            K.append(k)
            C.append(c)
        return np.array(K), np.array(C)

    def eccentricities(self, omega):
        from rotor_fmu.stability import short_bearing_equilibrium
        out = []
        for b, ld in zip(self.system.bearings, self.loads):
            try:
                out.append(short_bearing_equilibrium(ld, omega, **_short(b.params))[0])
            except _NUMERIC as exc:
                raise _failed(b, omega, exc) from None
        return out


class _HSFilm:
    """Half-Sommerfeld film coefficients of each station's own bearing at its static equilibrium."""

    method = ("finite-length half-Sommerfeld film of each bearing (its parameters and grid), linearized by central "
              "differences (bearing_fmu/linearize.py hs_linearization) at the static equilibrium under the rotor's "
              "static load: the rotor's weight share, plus --load (Newton on the journal centre)")

    def __init__(self, system: System, loads: np.ndarray):
        from bearing_fmu.model import BearingModel
        self.system = system
        self.loads = loads
        self.models = []
        for b in system.bearings:
            p = dataclasses.replace(b.params, cavitation=0)
            try:
                m = BearingModel(p)
                m.initialize(0.0, -0.5 * m.c, 0.0, 0.0, 1.0)
            except _NUMERIC as exc:
                raise _failed(b, None, exc) from None
            self.models.append(m)
        self.q: list = [None] * len(self.models)

    def coefficients(self, j: int, q, omega: float):
        """(K, C) of bearing j's HS film at rest at q, plus those of the asperity contact when the
        bearing has ``contact = 1`` (bearing_fmu/contact.py; exactly 0 above 6 roughness heights),
        as ``bearing_fmu.linearize.linearization`` adds them."""
        from bearing_fmu.contact import contact_coefficients
        from bearing_fmu.linearize import hs_linearization
        m = self.models[j]
        K, C = hs_linearization(m, q[0], q[1], 0.0, 0.0, omega)
        if m.params.contact:
            Kc, Cc = contact_coefficients(q[0], q[1], 0.0, 0.0, omega, **m.contact_kw)
            K, C = K + Kc, C + Cc
        return K, C

    def equilibrium(self, j: int, omega: float) -> np.ndarray:
        """Journal centre (x, y) [m] where the bearing force equals -load
        (:func:`bearing_fmu.linearize.hs_static_equilibrium`: Newton with K = -dF/dq, the contact
        force included when the bearing has ``contact = 1``); started from the last speed's
        equilibrium, or from the short-bearing one (kept inside 0.8 c), or, without that, from
        hs_static_equilibrium's default start."""
        from bearing_fmu.linearize import HSEquilibriumError, hs_static_equilibrium
        from rotor_fmu.stability import short_bearing_equilibrium
        b, m, ld = self.system.bearings[j], self.models[j], self.loads[j]
        c = m.c
        target = -np.asarray(ld, float)
        q = self.q[j]
        if q is None:       # start from the short-bearing equilibrium (kept inside 0.8 c)
            try:
                eps, psi = short_bearing_equilibrium(ld, omega, **_short(b.params))
                q = min(eps, 0.8) * c * np.array([math.cos(psi), math.sin(psi)])
            except ValueError:          # no closed-form equilibrium (a load far off its capacity): the
                pass                    # default start, mid-gap on the load's side (also for a sideways --load)
        try:
            q = hs_static_equilibrium(m, target, omega, guess=q, max_iter=60, max_ecc=0.995)
        except HSEquilibriumError as exc:
            # a non-finite film force is a film far stiffer than the load (speed, viscosity), not a speed too low
            fix = ("give a --speeds LO:HI nearer the rotor's running speeds, or check the bearing's parameters (R, B, "
                   "psi, eta0) against the load" if "non-finite" in str(exc) else "raise the lower end of --speeds")
            raise StabilityError(f"bearing '{b.instance}': no half-Sommerfeld static equilibrium found at "
                                 f"{omega / (2 * math.pi):.4g} Hz under the load {np.hypot(*target):.4g} N "
                                 f"({exc}); {fix}") from None
        except _NUMERIC as exc:
            raise _failed(b, omega, exc) from None
        self.q[j] = q
        return q

    def __call__(self, omega):
        K, C = [], []
        for j in range(len(self.models)):
            q = self.equilibrium(j, omega)
            try:
                k, d = self.coefficients(j, q, omega)
            except _NUMERIC as exc:
                raise _failed(self.system.bearings[j], omega, exc) from None
            K.append(k)
            C.append(d)
        return np.array(K), np.array(C)

    def contact_share(self, omega):
        """Share of each bearing's static load carried by asperity contact at omega (0 without contact)."""
        from bearing_fmu.contact import contact_force
        out = []
        for j, m in enumerate(self.models):
            if not m.params.contact:
                out.append(0.0)
                continue
            q = self.equilibrium(j, omega)
            Fn = contact_force(q[0], q[1], 0.0, 0.0, omega, **m.contact_kw)[2]
            out.append(float(abs(Fn) / np.hypot(*self.loads[j])))
        return out

    def eccentricities(self, omega):
        return [float(np.hypot(*self.equilibrium(j, omega)) / m.c) for j, m in enumerate(self.models)]


class _RingFilms:
    """Floating-ring bearings: the rotor with each ring's translation as two more degrees of
    freedom, coupled by the half-Sommerfeld coefficients of its two films at the steady operating
    point (:func:`rotor_fmu.floating_ring_stability.ring_system_eigen`; module doc)."""

    def __init__(self, system: System, loads: np.ndarray, spin: bool = False):
        self.system, self.spin = system, spin
        self.loads = loads
        self.rings = [b.params for b in system.bearings]
        self._at: tuple[float, list] | None = None
        held = ("each ring's spin as a first-order degree of freedom (--ring-spin)" if spin else
                "the ring spin held at its steady value (classical; --ring-spin adds its perturbation)")
        self.method = ("finite-length half-Sommerfeld inner and outer films of each floating-ring bearing (their "
                       "parameters and grids), linearized by central differences (bearing_fmu/linearize.py "
                       "linearization) at the ring's steady operating point under its static load (the rotor's "
                       "weight share, plus --load; ring speed from the torque balance of its two films, journal "
                       "and ring at their static equilibria), the ring's translation as two more degrees of "
                       f"freedom per station (mass m_ring), {held} (rotor_fmu/floating_ring_stability.py)")

    def max_re(self, omega: float) -> tuple[float, float]:
        """(largest real part [1/s], |Im| of that eigenvalue [rad/s]) at journal speed omega."""
        from bearing_fmu.model import StepFailed
        from rotor_fmu.floating_ring_stability import ring_system_eigen
        try:
            with np.errstate(all="raise"):
                lam, points = ring_system_eigen(self.system.rotor, self.rings, omega, spin=self.spin,
                                                loads=self.loads)
        except (StepFailed, ArithmeticError, ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
            raise StabilityError(f"no steady operating point of the floating-ring bearings at "
                                 f"{omega / (2 * math.pi):.4g} Hz ({exc}); at low speed a ring's outer film may "
                                 "not carry its load; raise the lower end of --speeds") from None
        if not np.all(np.isfinite(lam)):
            raise StabilityError(f"the floating-ring system's eigenvalues at {omega / (2 * math.pi):.4g} Hz are "
                                 "not finite (a film at the edge of its clearance); raise the lower end of --speeds")
        self._at = (omega, points)
        from rotor_fmu.stability import rightmost
        return rightmost(lam)     # a real part within rounding of zero is no crossing

    def points(self, omega: float) -> list:
        """Each station's FloatingRing model at its steady operating point at omega."""
        if self._at is None or self._at[0] != omega:
            self.max_re(omega)
        return self._at[1]

    def eccentricities(self, omega):
        return [float(p.outputs["eps"]) for p in self.points(omega)]


class _MCFilm:
    """Each station's own mass-conserving film, linearised about its steady state with its cavity
    (theta) dynamics: the rotor and the films as one descriptor system
    (:func:`rotor_fmu.stability.film_system_eigenvalues`, :class:`bearing_fmu.linearize.MCFilmLinear`;
    docs/analysis.md, "Linear threshold of the mass-conserving film")."""

    method = ("each bearing's own mass-conserving film (its parameters and grid) linearised about its steady "
              "state with its cavity (theta) dynamics, i.e. its film impedance Z(s) (bearing_fmu/linearize.py "
              "MCFilmLinear), at the static equilibrium of the steady film under its static load; the finite "
              "eigenvalues of the rotor and films as one descriptor system (rotor_fmu/stability.py "
              "film_system_eigenvalues)")

    def __init__(self, system: System, loads: np.ndarray):
        from bearing_fmu.model import BearingModel
        plain = [b.instance for b in system.bearings if b.params.cavitation != 1]
        if plain:
            raise StabilityError(f"--film mc linearises a mass-conserving film (cavitation = 1), but the bearing "
                                 f"'{plain[0]}' is half-Sommerfeld (cavitation = 0): use --film hs")
        self.system, self.loads = system, loads
        self.models = [BearingModel(b.params) for b in system.bearings]
        self.q: list = [None] * len(self.models)
        self._at: tuple[float, list] | None = None

    def _films(self, omega: float) -> list:
        """Each station's MCFilmLinear at its equilibrium at omega (the last speed's kept)."""
        from bearing_fmu.linearize import HSEquilibriumError, mc_static_equilibrium
        from bearing_fmu.model import StepFailed
        from rotor_fmu.stability import short_bearing_equilibrium
        if self._at is not None and self._at[0] == omega:
            return self._at[1]
        films = []
        for j, (b, m, ld) in enumerate(zip(self.system.bearings, self.models, self.loads)):
            guess = self.q[j]
            if guess is None:           # the short-bearing equilibrium, kept inside 0.8 c
                try:
                    eps, psi = short_bearing_equilibrium(ld, omega, **_short(b.params))
                except (ArithmeticError, ValueError):
                    eps, psi = 0.5, math.atan2(-ld[1], -ld[0]) + math.pi / 4
                guess = min(eps, 0.8) * m.c * np.array([math.cos(psi), math.sin(psi)])
            try:
                with np.errstate(all="ignore"):
                    q, lin = mc_static_equilibrium(m, -np.asarray(ld, float), omega, guess=guess)
            except (HSEquilibriumError, StepFailed, ArithmeticError, ValueError, RuntimeError,
                    np.linalg.LinAlgError) as exc:
                raise _failed(b, omega, exc) from None
            self.q[j] = q
            films.append(lin)
        self._at = (omega, films)
        return films

    def max_re(self, omega: float) -> tuple[float, float]:
        from rotor_fmu.stability import film_system_eigenvalues
        lam = film_system_eigenvalues(self.system.rotor, omega, self._films(omega))
        k = int(np.argmax(lam.real))
        return float(lam.real[k]), float(abs(lam.imag[k]))

    def eccentricities(self, omega):
        self._films(omega)
        return [float(np.hypot(*q) / m.c) for q, m in zip(self.q, self.models)]


# --------------------------------------------------------------------------- the command's library call
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
        sideways = [b.instance for b, ld in zip(system.bearings, total) if ld[0] != 0.0 or not ld[1] < 0.0]
        if sideways:
            raise StabilityError(f"the floating-ring bearing '{sideways[0]}' carries a static load of "
                                 f"({total[names.index(sideways[0])][0]:g}, {total[names.index(sideways[0])][1]:g}) N: "
                                 "`stability` finds a ring's operating point only under a downward load (0, -W); "
                                 "give --load with an x component of 0 and a net downward force")
    return weight, extra, total


def _notes(system: System, film: str, ring_spin: bool, weight: np.ndarray, extra: np.ndarray) -> list[str]:
    """The result's notes on its inputs: each --load with the sum it makes, what the linear model
    leaves out of each bearing (its own mass-conserving film, the ring spin, grooves and feed
    pressure in the short-bearing closed form) and the short bearing's B/D."""
    names = [b.instance for b in system.bearings]
    total = weight + extra
    fmt = lambda v: f"({v[0] + 0.0:.4g}, {v[1] + 0.0:.4g}) N"        # noqa: E731 (+ 0.0: no "-0")
    notes = [f"bearing '{n}': static load {fmt(total[k])} = the rotor's weight share {fmt(weight[k])} plus --load "
             f"{fmt(extra[k])}" for k, n in enumerate(names) if extra[k].any()]
    for b in (x for x in system.bearings if x.kind == "floating_ring"):
        mc = [side for side in ("inner", "outer") if getattr(b.params, side).cavitation == 1]
        if mc:
            notes.append(f"bearing '{b.instance}': its {' and '.join(mc)} film is mass-conserving (cavitation = 1); "
                         "its coefficients here are those of the half-Sommerfeld film")
        if not ring_spin:                       # every ring floats (a semi-floating one is refused)
            notes.append(f"bearing '{b.instance}': full floating ring, spin held at its steady value in the "
                         "linear model (--ring-spin adds its perturbation)")
    for b in (x for x in system.bearings if x.kind == "journal"):
        if b.params.cavitation == 1 and film != "mc":
            notes.append(f"bearing '{b.instance}' is mass-conserving (cavitation = 1): its coefficients here are "
                         "those of the half-Sommerfeld film (the HS linearisation), not of its own film; "
                         "--film mc linearises its own film with its cavity dynamics")
        if film == "short" and (b.params.groove_width > 0 or b.params.p_feed != b.params.p0):
            notes.append(f"bearing '{b.instance}': the short-bearing closed form has no groove and no feed "
                         "pressure (use --film hs for the film with them)")
    if film == "short":
        notes.append("short-bearing theory is a bound for B/D not small (B/D of "
                     + ", ".join(f"'{b.instance}' {b.params.B / (2 * b.params.R):.2f}" for b in system.bearings)
                     + ")")
    return notes


def _search(max_re, ws: np.ndarray, result: dict, xtol: float = 1e-9) -> float | None:
    """Fill ``result`` (its ``crossings``, ``status``, the threshold's entries, ``notes``) from
    ``max_re(omega) -> (largest real part, |Im| there)`` at the speeds ``ws`` [rad/s] and between
    them; return the threshold speed [rad/s], or None without one."""
    from rotor_fmu.stability import refine_crossing
    # the whole range on a geometric grid, then Brent on every sign change of the largest real part
    # between neighbouring speeds (rotor_fmu.stability.refine_crossing, as threshold_speed refines
    # its bracket: the same number): the first one upwards is the threshold, a later one downwards is
    # where the system is stable again (a run-up's whirl "vanish" has its linear counterpart there).
    # A speed without a static equilibrium (a load a film cannot carry there inside its clearance,
    # e.g. a floating ring's outer film at low speed) is left out, and no crossing is sought across it:
    # a sign change across such speeds is named (status "threshold_not_located" when it is the first).
    vals: list[float | None] = []
    failed: list[tuple[float, StabilityError]] = []
    for w in ws:
        try:
            vals.append(max_re(w)[0])
        except StabilityError as exc:
            vals.append(None)
            failed.append((w, exc))
    ok = [k for k, v in enumerate(vals) if v is not None]
    if not ok:
        raise failed[0][1]
    if failed:
        where = ", ".join(f"{w / (2 * math.pi):.4g}" for w, _ in failed[:6]) + (" ..." if len(failed) > 6 else "")
        result["notes"].append(f"no static equilibrium at {len(failed)} of the {len(ws)} speeds searched ({where} Hz), "
                               f"left out: {failed[0][1]}".replace("; raise the lower end of --speeds", ""))
        result["speeds_without_equilibrium_hz"] = [w / (2 * math.pi) for w, _ in failed]
    unlocated = None          # the first sign change, when it lies across speeds without equilibrium
    for k0, k1 in zip(ok, ok[1:]):
        if (vals[k0] < 0.0) == (vals[k1] < 0.0):
            continue
        if k1 == k0 + 1:
            wc, nu = refine_crossing(max_re, ws[k0], ws[k1], xtol)
            result["crossings"].append({"speed_hz": wc / (2 * math.pi), "whirl_hz": nu / (2 * math.pi),
                                        "becomes": "unstable" if vals[k0] < 0.0 else "stable"})
            continue
        between = [ws[k0] / (2 * math.pi), ws[k1] / (2 * math.pi)]
        becomes = "unstable" if vals[k0] < 0.0 else "stable"
        result["notes"].append(f"the largest real part changes sign between {between[0]:.4g} and "
                               f"{between[1]:.4g} Hz (it becomes {becomes}), across speeds without a static "
                               "equilibrium: that crossing is not located")
        if unlocated is None and not result["crossings"]:
            unlocated = between
    vals = [vals[k] for k in ok]
    at = None
    if vals[0] >= 0.0:
        status = "unstable_at_lower_bound"
    elif unlocated is not None:        # stable below, unstable above, speeds without equilibrium between
        status = "threshold_not_located"
        result["threshold_between_hz"] = unlocated
    elif not result["crossings"]:
        status = "stable"
    else:
        first = result["crossings"][0]
        status, at = "threshold", 2 * math.pi * first["speed_hz"]
        result.update(threshold_hz=first["speed_hz"], whirl_hz=first["whirl_hz"],
                      whirl_ratio=first["whirl_hz"] / first["speed_hz"])
    result["status"] = status
    return at


def later_crossings(result: dict) -> list[dict]:
    """The crossings of a :func:`stability` result other than the threshold: after the first one
    when that is the threshold (status ``"threshold"``), else all of them (already unstable at the
    lower end: the first crossing is where it becomes stable)."""
    crossings = result.get("crossings") or []
    return crossings[1:] if result.get("status") == "threshold" else list(crossings)


def stability(scenario, *, film: str = "hs", speeds: tuple[float, float] | None = None, n_scan: int | None = None,
              ring_spin: bool = False, loads: dict[str, tuple[float, float]] | None = None) -> dict:
    """The threshold result (a JSON-ready dict) of a loaded scenario; see the module doc.

    ``loads``: bearing instance -> static force (Fx, Fy) [N] the rotor puts on that bearing in
    addition to its share of the rotor's weight (``--load``: a gear or belt force, a magnetic pull,
    a horizontal rotor's load with g = 0), in the convention of
    :func:`rotor_fmu.stability.static_bearing_loads` (down is -y). ``n_scan``: speeds of the scan
    (default 80; :data:`MC_SCAN` with ``film="mc"``, whose speeds cost about 20 s each at 40 x 40,
    and its crossings are refined to 0.01 Hz instead of 1e-9 rad/s)."""
    from rotor_fmu.stability import max_real_eigenvalue

    if film not in FILMS:
        raise StabilityError(f"--film must be one of {', '.join(FILMS)} (got {film!r})")
    system = build_system(scenario)
    lo, hi = speeds if speeds is not None else (0.1 * system.f_max, system.f_max)
    if speeds is None and not (0.0 < lo < hi and math.isfinite(hi)):
        raise StabilityError(f"the default speed range 0.1 f_max : f_max is {lo:g}:{hi:g} Hz, but the rotor "
                             f"'{system.rotor_instance}' has f_max = {system.f_max:g} Hz (no ramp to take the range "
                             "from); give the range: --speeds LO:HI in Hz, e.g. --speeds 50:800")
    if not (0.0 < lo < hi and math.isfinite(hi)):
        raise StabilityError(f"--speeds: need 0 < LO < HI in Hz (got {lo:g}:{hi:g})")
    if system.rings and film == "mc":
        raise StabilityError("--film mc: floating-ring bearings are linearized with their half-Sommerfeld films "
                             "(--film hs); the mass-conserving film impedance is for plain JournalBearings")
    if system.rings and film == "short":
        raise StabilityError("--film short: the short-bearing closed form has no floating ring; the floating-ring "
                             "bearings of this scenario are linearized with their half-Sommerfeld films (--film hs)")
    if ring_spin and not system.rings:
        raise StabilityError("--ring-spin: the scenario has no floating-ring bearings (its stations carry "
                             f"{BEARING_MODEL}s); leave --ring-spin out")
    fixed = [b.instance for b in system.bearings if b.kind == "floating_ring" and not b.params.floating]
    if fixed:           # its outer film at rest: bearing_fmu.floating_ring_statics finds no equilibrium at any speed
        raise StabilityError(f"the ring of '{fixed[0]}' is semi-floating (floating = 0): its outer film does not "
                             "spin and carries no static load in the quasi-static (half-Sommerfeld) film, so "
                             "`stability` has no operating point to linearize at, at any speed; it takes floating "
                             "rings (floating = 1) only")
    weight, extra, total = _static_loads(system, loads)
    if system.rings:
        fn = _RingFilms(system, total, spin=ring_spin)
        max_re = fn.max_re
    elif film == "mc":
        fn = _MCFilm(system, total)
        max_re = fn.max_re
    else:
        fn = _ShortFilm(system, total) if film == "short" else _HSFilm(system, total)

        def coefficients(omega):
            """The film's (K, C) at omega, refused when not finite (NaN would read as "stable")."""
            K, C = fn(omega)
            for b, k, c in zip(system.bearings, K, C):
                if not (np.all(np.isfinite(k)) and np.all(np.isfinite(c))):
                    raise _failed(b, omega, ValueError(f"its linear coefficients are not finite (K = {k.tolist()}, "
                                                       f"C = {c.tolist()})"))
            return K, C
        max_re = lambda w: max_real_eigenvalue(system.rotor, w, coefficients)     # noqa: E731
    notes = _notes(system, film, ring_spin, weight, extra)
    seen: dict[float, tuple[float, float]] = {}
    search = max_re

    def max_re(w):                       # every speed evaluated, for result["scan"] and --plot
        try:
            v = search(w)
        except _NUMERIC as exc:          # the rotor's own matrices (an absurd mass, a speed far off)
            raise StabilityError(f"the eigenvalues of the rotor '{system.rotor_instance}' in its bearings cannot "
                                 f"be computed at {w / (2 * math.pi):.4g} Hz: {exc or type(exc).__name__}; check the "
                                 "rotor's and the bearings' parameters, or give a --speeds LO:HI nearer the rotor's "
                                 "running speeds") from exc
        seen[float(w)] = v
        return v

    w_lo, w_hi = 2 * math.pi * lo, 2 * math.pi * hi
    result: dict[str, Any] = {
        "scenario": scenario.name, "file": str(scenario.source) if scenario.source else None,
        "rotor": {"instance": system.rotor_instance, "model": system.rotor_model},
        "film": film, "method": fn.method, "speed_range_hz": [lo, hi],
        "threshold_hz": None, "whirl_hz": None, "whirl_ratio": None, "crossings": [], "bearings": {},
        "notes": notes,
    }
    if n_scan is None:
        n_scan = MC_SCAN if film == "mc" else 80
    at = _search(max_re, np.geomspace(w_lo, w_hi, n_scan), result,
                 xtol=2 * math.pi * 0.01 if film == "mc" else 1e-9)
    from orchestrator.results.plots.stability import log_decrement
    result["scan"] = [{"speed_hz": w / (2 * math.pi), "max_re_per_s": re, "whirl_hz": im / (2 * math.pi),
                       "log_decrement": log_decrement(re, im)} for w, (re, im) in sorted(seen.items())]
    eps = fn.eccentricities(at) if at is not None else [None] * len(system.bearings)
    if at is not None and film == "hs" and not system.rings:
        for b, share in zip(system.bearings, fn.contact_share(at)):
            if share > 1e-3:
                notes.append(f"bearing '{b.instance}': asperity contact carries {share:.1%} of its static load at "
                             "the threshold (its coefficients are included, bearing_fmu/contact.py)")
    points = fn.points(at) if at is not None and system.rings else [None] * len(system.bearings)
    for b, e, ld, pt in zip(system.bearings, eps, total, points):
        result["bearings"][b.instance] = _bearing_entry(b, film, ld, e, pt, at)
    return result


def _bearing_entry(b: Bearing, film: str, load, eps, point, at: float | None) -> dict:
    """A bearing's part of the result: its static ``load`` (2,) [N], eccentricity ratio ``eps``
    at the threshold speed ``at`` [rad/s] (None without one), and for a floating ring its steady
    operating ``point`` there (a FloatingRing model, or None)."""
    entry = {"station": b.station, "kind": b.kind, "load_n": float(np.hypot(*load)),
             "load_vector_n": [float(load[0]), float(load[1])], "eps_at_threshold": eps}
    if b.kind == "floating_ring":       # eps, clearance, cavitation, grid: of the inner film
        inner, outer = b.params.inner, b.params.outer
        entry.update(clearance_m=inner.psi * inner.R, cavitation=int(inner.cavitation),
                     grid=[int(inner.n_phi), int(inner.n_z)],
                     eps_outer_at_threshold=None if point is None else float(point.outputs["eps_outer"]),
                     ring_speed_ratio_at_threshold=None if point is None else float(point.outputs["omega_ring"] / at),
                     clearance_outer_m=outer.psi * outer.R, cavitation_outer=int(outer.cavitation),
                     grid_outer=[int(outer.n_phi), int(outer.n_z)], m_ring_kg=float(b.params.m_ring),
                     floating=int(b.params.floating))
    else:
        entry.update(clearance_m=b.params.psi * b.params.R, cavitation=int(b.params.cavitation),
                     grid=[int(b.params.n_phi), int(b.params.n_z)] if film in ("hs", "mc") else None)
    return entry
