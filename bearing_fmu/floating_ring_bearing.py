"""FloatingRingBearing: FMI 2.0 co-simulation slave of a floating-ring bearing.

A thin PythonFMU wrapper around :class:`bearing_fmu.floating_ring.FloatingRing` (physics,
time integration and the interface coefficients are documented there and in
docs/floating-ring.md). It has the rotor-side interface of ``JournalBearing`` (inputs x, y,
vx, vy, omega of the journal; outputs Fx, Fy, eps of the inner film and kxx ... cyy of the
whole ring bearing as the journal sees it), so it replaces a ``JournalBearing`` in any
scenario. Variables, units and defaults: the tables below and docs/fmus.md.

The life cycle and the FMU state follow ``JournalBearing`` (model built on the first output
read in initialization mode or in exit_initialization_mode; full model state in
get/set FMU state; a step the films cannot complete returns fmi2Discard with the state kept).
The FMI plumbing shared with it (units, modelDescription completion, the PythonFMU callback
guard, the numerical-failure test) is imported from ``bearing_fmu.journal_bearing``. That import
happens before ``use_stable_code_copy`` can redirect ``bearing_fmu`` to the content-addressed
copy, so this FMU imports its code from the extracted FMU and numba recompiles the film kernels
once per run (measured below in docs/fmus.md). Loading journal_bearing.py by file path instead
made PythonFMU 0.7.0 crash (segfault) on the second instantiation in a process.
"""

from __future__ import annotations

import math
import re
from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, String
from pythonfmu.enums import Fmi2Initial, Fmi2Status


from bearing_fmu import journal_bearing as _jb  # the bearing's variable tables and code cache
from fmu_common.slave import (
    RealU, check_shipped_layout, check_step_start, exit_initialization_mode, finish_model_description,
    get_slave_state, guard_callbacks, input_setter, output_getter, param_setter, refresh_coefficients,
    set_slave_state, setup_experiment, state_from_bytes, state_to_bytes, value_getter)

_FILM_REAL = {   # per film (suffix _inner / _outer): name -> (inner default, outer default, unit, description)
    "R": (4.9e-3, 7.84e-3, "m", "film radius: journal radius (inner), ring outer radius (outer) [m]"),
    "B": (7.84e-3, 7.84e-3, "m", "axial film width [m]"),
    "psi": (2.8e-3, 3.5e-3, "1", "relative radial clearance psi = c/R, radial clearance over radius [-], typically 1e-3 to 3e-3 (a value in per mille is 1000 times too large; a clearance in m is not psi)"),
    "eta0": (0.012, 0.012, "Pa.s", "oil viscosity [Pa s]"),
    "p_feed": (1.0e5, 1.0e5, "Pa", "feed pressure in the groove [Pa] (inner: fed through the ring)"),
    "groove_width": (0.0, 0.0, "rad", "opening angle of the axial feed groove [rad] (0: no groove)"),
    "groove_angle": (math.pi / 2, math.pi / 2, "rad", "groove centre, from +x counter-clockwise [rad]"),
    "cav_width": (1.0e3, 1.0e3, "Pa", "width of the smooth theta(p) step below p0 (cavitation 1): the cavity "
                                      "pressure is p0 - cav_width [Pa]; keep it small against the film's "
                                      "pressure range"),
}
_FILM_INT = {
    "n_phi": (40, 40, "grid cells in the circumferential direction [-]"),
    "n_z": (40, 40, "grid cells in the axial direction [-]"),
    # a switch's description ends with the names of its values (journal_bearing.INTEGER_PARAMETERS)
    "cavitation": (1, 1, "cavitation model: the quasi-static half-Sommerfeld film or the transient "
                         "mass-conserving two-phase film (0 = half-Sommerfeld, 1 = mass-conserving)"),
    "axial_bc": (0, 0, "axial boundary condition: oil bath is Dirichlet p0, free to air a Neumann penalty "
                       "(0 = oil bath, 1 = free to air)"),
    "theta_transport": (0, 0, "Couette transport of the fluid fraction (cavitation 1): first-order upwind or "
                              "limited second order MUSCL (0 = upwind, 1 = MUSCL)"),
}
REAL_PARAMETERS: dict[str, tuple[float, str, str]] = {
    f"{n}_{side}": (d[k], unit, f"{side} film: {desc}")
    for n, (*d, unit, desc) in _FILM_REAL.items() for k, side in enumerate(("inner", "outer"))}
REAL_PARAMETERS.update({
    "p0": (1.0e5, "Pa", "ambient pressure of both films [Pa]"),
    "m_ring": (7.3e-3, "kg", "ring mass [kg]"),
    "J_ring": (3.1e-7, "kg.m2", "ring polar moment of inertia [kg m^2]"),
    "gravity": (9.81, "m/s2", "gravitational acceleration on the ring, in -y [m/s^2]"),
    "h_ring": (1.0e-4, "s", "largest ring sub-step inside one FMU step [s]"),
    "x_ring0": (0.0, "m", "initial ring centre x [m] (ring_init = 'given')"),
    "y_ring0": (0.0, "m", "initial ring centre y [m] (ring_init = 'given')"),
    "omega_ring0": (-1.0, "rad/s", "initial ring speed [rad/s]; < 0: the concentric Petroff ratio "
                                   "a/(a+b) times the initial journal speed"),
})
# the ring's start: positions as the rotor FMUs' journal_x0 (rotor_fmu.param_ranges); a speed up to
# 1e6 rad/s (the rotors' f_max is at most 1e5 Hz, and a ring turns slower than its journal); any
# value < 0 asks for the Petroff ratio
START_RANGES: dict[str, tuple[float, float]] = {
    "x_ring0": (-1.0, 1.0), "y_ring0": (-1.0, 1.0), "omega_ring0": (-1.0e6, 1.0e6)}
INTEGER_PARAMETERS: dict[str, tuple[int, str]] = {
    f"{n}_{side}": (d[k], f"{side} film: {desc}")
    for n, (*d, desc) in _FILM_INT.items() for k, side in enumerate(("inner", "outer"))}
INTEGER_PARAMETERS.update({
    "floating": (1, "ring spin: locked with the translation free (semi-floating) or free (full floating) "
                    "(0 = semi-floating, 1 = full floating)"),
    "linearize": (0, "N >= 1: output kxx..cyy of the whole ring bearing, refreshed every N-th step; 0: outputs 0"),
    "jacobian_every": (1, "the films' coefficients used by the ring integration are recomputed after "
                          "every N-th step [-]"),
    "input_hold": (2, "journal inputs inside a step: the new input (FMI semantics), first-order hold from the "
                      "previous step's input (second order when stepped after the rotor, Gauss-Seidel) or cubic "
                      "Hermite of the previous and new position and velocity, which ring_integrator 0 uses as "
                      "first-order hold (0 = zero-order hold, 1 = first-order hold, 2 = cubic Hermite)"),
    "ring_integrator": (1, "ring translation inside a step: linearly implicit BDF2, or exponential: the "
                           "linearised ring ODE integrated exactly for the journal input, docs/floating-ring.md "
                           "(0 = BDF2, 1 = exponential)"),
})
STRING_PARAMETERS: dict[str, tuple[str, str]] = {
    "init": ("flooded", "initial film of the mass-conserving films: 'flooded' or 'stationary'"),
    "ring_init": ("equilibrium", "initial ring position: 'equilibrium' (static balance of the quasi-static "
                                 "films and the ring weight) or 'given' (x_ring0, y_ring0)"),
}
INPUTS = _jb.INPUTS
OUTPUTS: dict[str, tuple[str, str]] = {
    "Fx": ("N", "inner-film force on the journal, x [N]"),
    "Fy": ("N", "inner-film force on the journal, y [N]"),
    "eps": ("1", "inner-film eccentricity |r_journal - r_ring| / c_inner [-]"),
    "omega_ring": ("rad/s", "ring angular speed about +z [rad/s]"),
    "x_ring": ("m", "ring centre x relative to the housing [m]"),
    "y_ring": ("m", "ring centre y relative to the housing [m]"),
    "vx_ring": ("m/s", "ring centre velocity x [m/s]"),
    "vy_ring": ("m/s", "ring centre velocity y [m/s]"),
    "eps_outer": ("1", "outer-film eccentricity |r_ring| / c_outer [-]"),
    "T_journal": ("N.m", "friction torque of the inner film on the journal about +z [N m]"),
    "T_ring_inner": ("N.m", "torque of the inner film on the ring about +z [N m]"),
    "T_ring_outer": ("N.m", "torque of the outer film on the ring about +z [N m]"),
    "P_loss": ("W", "friction power of both films [W]"),
    "p_max": ("Pa", "maximum pressure of the inner film [Pa]"),
    "h_min": ("m", "minimum gap of the inner film [m]"),
    "p_max_outer": ("Pa", "maximum pressure of the outer film [Pa]"),
    "h_min_outer": ("m", "minimum gap of the outer film [m]"),
    # for the rotor's ring-interface step (rotor_fmu/ring_interface.py, docs/floating-ring.md)
    "ax_ring": ("m/s2", "ring centre acceleration x from its force balance [m/s^2]"),
    "ay_ring": ("m/s2", "ring centre acceleration y from its force balance [m/s^2]"),
    **{f"{kind}{i}{j}_outer": (unit, f"outer film {what} -dF{i}/d{var}{j} of the ring in the housing [{unit}]")
       for kind, unit, what, var in (("k", "N/m", "stiffness", ""), ("c", "N.s/m", "damping", "v"))
       for i in "xy" for j in "xy"},
}
LINEARIZATION_OUTPUTS: dict[str, tuple[str, str]] = {
    f"{kind}{i}{j}": (unit, f"ring bearing {what} -dF{i}/d{var}{j} as the journal sees it [{unit}] "
                            "(series of the two films, docs/floating-ring.md)")
    for kind, unit, what, var in (("k", "N/m", "stiffness", ""), ("c", "N.s/m", "damping", "v"))
    for i in "xy" for j in "xy"}
_UNITS = dict(_jb.UNITS, **{"kg": dict(kg="1"), "kg.m2": dict(kg="1", m="2"), "m/s2": dict(m="1", s="-2"),
                            "W": dict(kg="1", m="2", s="-3"), "s": dict(s="1")})


def _side_names(msg: str, names, side: str) -> str:
    """A film's message with its parameter names as the FMU spells them: ``n_phi x n_z`` of the
    inner film is ``n_phi_inner x n_z_inner`` (names of one letter are left alone: ``B/D``)."""
    for n in sorted((n for n in names if len(n) > 1), key=len, reverse=True):
        msg = re.sub(rf"(?<![\w.]){re.escape(n)}(?!\w)", f"{n}_{side}", msg)
    return msg


def ring_params(values: dict, instance: str = "?"):
    """The :class:`bearing_fmu.floating_ring.RingParams` of the FMU's parameter values ``values``
    (name -> value, every parameter of the tables above; the FMU's own, and ``rotorcosim stability``
    from a scenario's start values): ``ValueError`` naming every invalid parameter by its FMU name."""
    from bearing_fmu.floating_ring import RingParams
    from bearing_fmu.model import BearingParams
    v = values
    films, problems = {}, []
    for side in ("inner", "outer"):
        kw = {n: v[f"{n}_{side}"] for n in (*_FILM_REAL, *_FILM_INT)}
        try:
            films[side] = BearingParams(p0=v["p0"], **kw)
        except ValueError as exc:     # the model's message in the FMU's parameter names
            for line in str(exc).splitlines()[1:]:
                msg = _jb.fmu_parameter_message(line)
                name = msg.partition("'")[2].partition("'")[0] if msg.startswith("parameter '") else ""
                problems.append(msg.replace(f"'{name}'", f"'{name}_{side}'", 1) if name in kw
                                else f"{side} film: {_side_names(msg, kw, side)}")
    if problems:
        raise ValueError(f"invalid parameters of the FloatingRingBearing FMU instance '{instance}': "
                         + "; ".join(problems) + "; set them in the scenario (fmus.<instance>.parameters)")
    return RingParams(**films, m_ring=v["m_ring"], J_ring=v["J_ring"], floating=v["floating"],
                      gravity=v["gravity"], h_ring=v["h_ring"], jacobian_every=v["jacobian_every"],
                      input_hold=v["input_hold"], ring_integrator=v["ring_integrator"])


@guard_callbacks
class FloatingRingBearing(Fmi2Slave):
    """Floating-ring bearing: ring with mass and inertia between two Reynolds films."""

    author = "rotorcosim"
    description = ("Floating-ring bearing: a ring with mass and polar inertia between an inner and an outer "
                   "Reynolds film (half-Sommerfeld or mass-conserving), advanced together in each step")
    version = "0.1.0"

    def __init__(self, **kwargs: Any):
        super().__init__(**kwargs)
        self.code_dir = _jb.use_stable_code_copy(self.resources)
        self._values: dict[str, Any] = {}
        self._model = None
        self._initialized = False
        self._init_key = None
        self._time = 0.0
        self._start_time = 0.0
        par = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        for name, (default, unit, desc) in REAL_PARAMETERS.items():
            self._real(name, default, unit, desc, self._param_setter(name, float), **par)
        for kind, table in ((int, INTEGER_PARAMETERS), (str, STRING_PARAMETERS)):
            for name, (default, desc) in table.items():
                self._values[name] = default
                cls = Integer if kind is int else String
                self.register_variable(cls(name, description=desc, getter=self._getter(name),
                                           setter=self._param_setter(name, kind), **par))
        for name, (unit, desc) in INPUTS.items():
            self._real(name, 0.0, unit, desc, self._input_setter(name), causality=Fmi2Causality.input,
                       variability=Fmi2Variability.continuous)
        for name, (unit, desc) in {**OUTPUTS, **LINEARIZATION_OUTPUTS}.items():
            self._real(name, 0.0, unit, desc, None, causality=Fmi2Causality.output,
                       variability=Fmi2Variability.continuous, initial=Fmi2Initial.calculated)
        self._real("t_film", 0.0, "s", "model time [s]", None, causality=Fmi2Causality.local,
                   variability=Fmi2Variability.continuous, initial=Fmi2Initial.calculated)
        check_shipped_layout(self)

    # -- registration -----------------------------------------------------------
    def _real(self, name, default, unit, desc, setter, **kw):
        self._values[name] = float(default)
        getter = self._output_getter(name) if kw.get("causality") == Fmi2Causality.output else \
            (lambda: self._time) if name == "t_film" else self._getter(name)
        self.register_variable(RealU(name, unit=unit, description=desc, getter=getter,
                                          setter=setter, **kw))

    _getter = value_getter
    _output_getter = output_getter
    _param_setter = param_setter
    _input_setter = input_setter

    def to_xml(self, model_options: dict[str, str] = dict()):  # noqa: B006 (PythonFMU's signature)
        units = {v[1] for v in REAL_PARAMETERS.values()}
        units |= {v[0] for v in {**INPUTS, **OUTPUTS, **LINEARIZATION_OUTPUTS}.values()} | {"s"}
        ranges = {f"{n}_{side}": _jb.PARAMETER_RANGES[n] for n in (*_FILM_REAL, *_FILM_INT)
                  if n in _jb.PARAMETER_RANGES for side in ("inner", "outer")}
        ranges["p0"] = _jb.PARAMETER_RANGES["p0"]
        from bearing_fmu.floating_ring_statics import RING_RANGES      # (at build time only)
        ranges.update({n: (lo, hi) for n, (lo, hi, _) in RING_RANGES.items()})
        ranges.update(START_RANGES)
        choices = {"init": _jb.STRING_CHOICES["init"], "ring_init": ("equilibrium", "given")}
        return finish_model_description(super().to_xml(model_options), units, _UNITS, ranges, choices)

    # -- model --------------------------------------------------------------------
    def _ring_params(self):
        return ring_params(self._values, getattr(self, "instance_name", "?"))

    def _inputs(self):
        return tuple(self._values[n] for n in INPUTS)

    def _ensure_model(self):
        v = self._values
        names = (*REAL_PARAMETERS, *INTEGER_PARAMETERS, *STRING_PARAMETERS)
        key = (tuple(v[n] for n in names), self._inputs())
        if self._model is not None and key == self._init_key:
            return
        from bearing_fmu.floating_ring import FloatingRing
        if v["ring_init"] not in ("equilibrium", "given"):
            raise ValueError(f"parameter 'ring_init' must be 'equilibrium' or 'given' (got {v['ring_init']!r})")
        if v["init"] not in ("flooded", "stationary"):
            raise ValueError(f"parameter 'init' must be 'flooded' or 'stationary' (got {v['init']!r})")
        model = FloatingRing(self._ring_params())
        ring = "equilibrium" if v["ring_init"] == "equilibrium" else (v["x_ring0"], v["y_ring0"], 0.0, 0.0)
        if ring != "equilibrium" and not any(self._inputs()):
            # inputs not set yet (an output read early in initialization mode): a provisional
            # ring concentric with the journal; the model is rebuilt when the inputs arrive
            ring = (0.0, 0.0, 0.0, 0.0)
        om0 = None if v["omega_ring0"] < 0 else v["omega_ring0"]
        model.initialize(*self._inputs(), ring=ring, omega_ring=om0, init=v["init"])
        self._model = model
        self._init_key = key
        self._copy_outputs()

    def _copy_outputs(self):
        out = self._model.outputs
        for name in OUTPUTS:
            self._values[name] = float(out[name])
        refresh_coefficients(self, self._model.linearization)

    # -- FMI life cycle ---------------------------------------------------------------
    setup_experiment = setup_experiment
    exit_initialization_mode = exit_initialization_mode

    def do_step(self, current_time: float, step_size: float) -> bool:
        check_step_start(self, current_time, step_size)
        if step_size <= 0.0:
            raise ValueError(f"step_size must be > 0 (got {step_size!r})")
        try:
            self._model.step(step_size, *self._inputs())    # restores its own state on failure
        except Exception as exc:
            if not _jb._is_numerical_failure(exc):
                raise
            self.log(f"floating-ring bearing step t={current_time:.9g} dt={step_size:.3g} failed: {exc}",
                     Fmi2Status.discard)
            return False
        self._copy_outputs()
        self._time = current_time + step_size
        return True

    # -- FMU state ----------------------------------------------------------------------
    def _get_fmu_state(self) -> dict[str, Any]:
        return get_slave_state(self, {})

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        set_slave_state(self, state, {})

    _fmu_state_to_bytes = staticmethod(state_to_bytes)
    _fmu_state_from_bytes = staticmethod(state_from_bytes)
