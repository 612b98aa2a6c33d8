"""JeffcottRotor: FMI 2.0 co-simulation slave of the Jeffcott rotor (paper section 3.2).

A thin PythonFMU wrapper around :class:`rotor_fmu.jeffcott.JeffcottModel`. The
rotor-slave machinery (variable registration, life cycle, full FMU state) is
written here as plain functions that ``turbocharger_rotor.py`` reuses: the FMU's
C loader finds the slave class with the regular expression
``^class (\\w+)\\(\\s*Fmi2Slave\\s*\\)\\s*:``, so each slave must derive
*directly* from ``Fmi2Slave`` and cannot inherit from a common base class.

Variables (see ``docs/fmus.md``)
--------------------------------
* parameters: every scalar field of the model's parameter dataclass
  (:class:`rotor_fmu.jeffcott.JeffcottParams`: ``m_disc``, ``f_max``, ``t_ramp``,
  ``d_external``, ...), settable before and during initialization;
* inputs ``Fx_i``, ``Fy_i`` [N]: film force on journal i (i = 1, 2);
* outputs ``x_i``, ``y_i`` [m], ``vx_i``, ``vy_i`` [m/s], ``omega`` [rad/s],
  ``angle`` [rad], ``alpha`` [rad/s^2] and the model's extra outputs (disc centre
  ``x_disc``, ``y_disc``, ``vx_disc``, ``vy_disc``).

The model is built in initialization mode (when an output is first read, at the
latest in ``exit_initialization_mode``); ``do_step`` holds the input forces
constant over the step. FMU state save/restore copies the model state (time,
all coordinates and velocities) together with the FMI scalars; states
serialize with ``pickle``.
"""

from __future__ import annotations

import dataclasses
from typing import Any
from xml.etree.ElementTree import Element

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, String
from pythonfmu.enums import Fmi2Initial, Fmi2Status
from pythonfmu.variables import Boolean

from fmu_common.slave import (
    RealU, check_shipped_layout, fast_get_real, fast_set_real, check_step_start, exit_initialization_mode,
    finish_model_description,
    get_slave_state, guard_callbacks, input_setter, journal_kinematics, output_getter, param_setter, set_slave_state,
    scalar_default, setup_experiment, shipped_parameters, state_from_bytes, state_to_bytes, value_getter)

from rotor_fmu.param_ranges import RANGES

N_BEARINGS = 2

UNITS = {
    "m": dict(m="1"), "m/s": dict(m="1", s="-1"), "rad": dict(rad="1"),
    "rad/s": dict(rad="1", s="-1"), "rad/s2": dict(rad="1", s="-2"), "N": dict(kg="1", m="1", s="-2"),
    "kg": dict(kg="1"), "kg.m": dict(kg="1", m="1"), "kg.m2": dict(kg="1", m="2"),
    "N/m": dict(kg="1", s="-2"), "N.s/m": dict(kg="1", s="-1"), "m/s2": dict(m="1", s="-2"),
    "Hz": dict(s="-1"), "s": dict(s="1"), "1": {},
}

# Known parameter names -> (unit, description); others get a generic description.
PARAMETER_DOCS: dict[str, tuple[str | None, str]] = {
    "m_disc": ("kg", "disc mass [kg]"),
    "m_journal": ("kg", "mass of each journal [kg]"),
    "unbalance": ("kg.m", "unbalance m e [kg m]"),
    "unbalance_phase": ("rad", "phase of the unbalance relative to the drive angle [rad]"),
    "k_shaft": ("N/m", "shaft stiffness, disc relative to the journals [N/m]"),
    "d_internal": ("N.s/m", "internal (rotating) shaft damping [N s/m]"),
    "d_external": ("N.s/m", "external viscous damping on the disc [N s/m]"),
    "g": ("m/s2", "gravity, acting in -y [m/s^2]"),
    "f_max": ("Hz", "speed at the end of the linear ramp [Hz]"),
    "t_ramp": ("s", "duration of the linear speed ramp 0 -> f_max [s]"),
    "f_start": ("Hz", "speed at the start of the ramp [Hz]"),
    "t0": ("s", "model start time [s] (the FMU uses the experiment start time)"),
    "journal_x0": ("m", "initial x of the journals [m]"),
    "journal_y0": ("m", "initial y of the journals [m]"),
    "initial_sag": (None, "start the disc at its static sag below the journals"),
    "max_phase_per_substep": ("rad", "bound of omega_max * h of the internal trapezoidal sub-steps [rad]"),
    "rotor_file": (None, "rotor description file (empty: the bundled default rotor)"),
    "reduce": (None, "Craig-Bampton reduction of the shaft model (false: full finite-element model)"),
    "n_modes": (None, "fixed-interface modes per bending plane of the reduction (0: the rotor file's value)"),
    "shear": (None, "Timoshenko (true) or Euler-Bernoulli (false) beam elements"),
}
OUTPUT_DOCS: dict[str, tuple[str, str]] = {
    **journal_kinematics(" {i}"),
    "angle": ("rad", "rotation angle (integral of omega) [rad]"),
    "alpha": ("rad/s2", "angular acceleration [rad/s^2]"),
}


def scalar_fields(params_cls) -> list[tuple[str, Any, type]]:
    """(name, default, type) of the dataclass fields with a bool/int/float/str default."""
    out = []
    for f in dataclasses.fields(params_cls):
        if f.name.startswith("_"):
            continue
        found = scalar_default(f)
        if found is not None:
            out.append((f.name, found[1], found[0]))
    return out


# ----------------------------------------------------------------------------
# Rotor-slave machinery, shared by JeffcottRotor and TurbochargerRotor.
# A slave class sets: _params_cls (callable returning the parameter dataclass),
# _make_model (callable(self, params_dict) -> model), and assigns these functions.
# ----------------------------------------------------------------------------
def rotor_init(self, **kwargs: Any) -> None:
    Fmi2Slave.__init__(self, **kwargs)
    self._values: dict[str, Any] = {}
    self._param_names: list[str] = []
    self._model = None
    self._initialized = False
    self._init_key = None
    self._time = 0.0
    self._start_time = 0.0
    units: set[str] = set()
    par = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
    fields = shipped_parameters(self.resources)
    if fields is None:                # building: from the model's parameter dataclass
        fields = self._parameter_fields()
    for name, default, kind in fields:
        if name == "t0" or name in RING_PARAMETERS:   # t0: the experiment start time; rings: below
            continue
        unit, desc = PARAMETER_DOCS.get(name, (None, f"rotor model parameter '{name}' (SI units)"))
        self._values[name] = default
        self._param_names.append(name)
        getter, setter = _getter(self, name), _param_setter(self, name, kind)
        if kind is float:
            self.register_variable(RealU(name, unit=unit, description=desc, getter=getter,
                                          setter=setter, **par))
            if unit:
                units.add(unit)
        elif kind is bool:
            self.register_variable(Boolean(name, description=desc, getter=getter, setter=setter, **par))
        elif kind is int:
            self.register_variable(Integer(name, description=desc, getter=getter, setter=setter, **par))
        else:
            self.register_variable(String(name, description=desc, getter=getter, setter=setter, **par))
    for i in range(1, N_BEARINGS + 1):
        for comp in ("x", "y"):
            name = f"F{comp}_{i}"
            self._values[name] = 0.0
            self.register_variable(RealU(
                name, unit="N", description=f"film force on journal {i}, {comp} [N]",
                causality=Fmi2Causality.input, variability=Fmi2Variability.continuous,
                getter=_getter(self, name), setter=_input_setter(self, name)))
    units.add("N")
    for i in range(1, N_BEARINGS + 1):   # interface-Jacobian coupling (docs/stiff-coupling.md)
        for kind, unit, what in (("k", "N/m", "stiffness -dF/dr"), ("c", "N.s/m", "damping -dF/dv")):
            for comp in ("xx", "xy", "yx", "yy"):
                name = f"{kind}{comp}_{i}"
                self._values[name] = 0.0
                self.register_variable(RealU(
                    name, unit=unit, description=(
                        f"film {what} {comp} of bearing {i} [{unit}] for interface-Jacobian "
                        "coupling (default 0: plain force coupling)"),
                    causality=Fmi2Causality.input, variability=Fmi2Variability.continuous,
                    getter=_getter(self, name), setter=_input_setter(self, name)))
            units.add(unit)
    _register_ring_variables(self, par)
    units |= {"kg", "m", "m/s", "m/s2", "N/m", "N.s/m"}
    for name in self._output_names():
        base = name.rsplit("_", 1)[0] if name.rsplit("_", 1)[-1].isdigit() else name   # x_1: journal 1
        unit, desc = OUTPUT_DOCS.get(base, (None, None))
        disc = name.rsplit("_", 1)[-1]
        if desc is None and disc.startswith("disc") and disc[4:].isdigit():
            what = "displacement" if name.startswith(("x_", "y_")) else "velocity"
            unit = "m" if what == "displacement" else "m/s"
            desc = (f"{name}: {what} of the centre of disc {disc[4:]} (its place in the rotor file's "
                    f"'discs' list), {name.split('_')[0][-1]} component [{unit}]; NaN when the file has fewer discs")
        elif desc is None:
            if name.startswith(("x_", "y_")):
                unit, desc = "m", f"{name}: displacement [m]"
            elif name.startswith(("vx_", "vy_")):
                unit, desc = "m/s", f"{name}: velocity [m/s]"
            else:
                desc = f"{name} (SI units)"
        else:
            desc = desc.format(i=name.rsplit("_", 1)[-1])
        self._values[name] = 0.0
        self.register_variable(RealU(
            name, unit=unit, description=desc, causality=Fmi2Causality.output,
            variability=Fmi2Variability.continuous, initial=Fmi2Initial.calculated,
            getter=_output_getter(self, name)))
        if unit:
            units.add(unit)
    self._units = units
    check_shipped_layout(self)


_getter, _output_getter, _param_setter, _input_setter = value_getter, output_getter, param_setter, input_setter

# floating rings at the bearing stations (rotor_fmu/ring_interface.py, docs/floating-ring.md)
RING_PARAMETERS = tuple(f"m_ring_{i}" for i in range(1, N_BEARINGS + 1))
RING_INPUTS: dict[str, tuple[str, str]] = {
    **{f"{q}_ring": (u, f"floating-ring centre {w} [{u}] at bearing {{i}}")
       for q, u, w in (("x", "m", "x"), ("y", "m", "y"), ("vx", "m/s", "velocity x"),
                       ("vy", "m/s", "velocity y"), ("ax", "m/s2", "acceleration x"),
                       ("ay", "m/s2", "acceleration y"))},
    **{f"{kind}{a}{b}_outer": (unit, f"outer film {what} {a}{b} of the ring at bearing {{i}} [{unit}]")
       for kind, unit, what in (("k", "N/m", "stiffness -dF/dr"), ("c", "N.s/m", "damping -dF/dv"))
       for a in "xy" for b in "xy"},
}


def _register_ring_variables(self, par: dict) -> None:
    """Parameters ``m_ring_i`` and inputs ``x_ring_i .. cyy_outer_i`` of the ring-interface step:
    with ``m_ring_i > 0`` the rotor's implicit step integrates the ring of bearing i with the
    journals (its kxx_i..cyy_i are then the inner film's, in journal-minus-ring coordinates)."""
    for i, name in enumerate(RING_PARAMETERS, start=1):
        self._values[name] = 0.0
        self.register_variable(RealU(
            name, unit="kg", description=(
                f"mass of the floating ring at bearing {i} [kg] for the ring-interface step (connect "
                f"x_ring_{i} .. cyy_outer_{i} from a FloatingRingBearing; 0: no ring, the plain step)"),
            getter=_getter(self, name), setter=_param_setter(self, name, float), **par))
    for i in range(1, N_BEARINGS + 1):
        for base, (unit, desc) in RING_INPUTS.items():
            name = f"{base}_{i}"
            self._values[name] = 0.0
            self.register_variable(RealU(
                name, unit=unit, description=desc.format(i=i), causality=Fmi2Causality.input,
                variability=Fmi2Variability.continuous, getter=_getter(self, name),
                setter=_input_setter(self, name)))


def rotor_ring_inputs(self):
    """The ``ring`` argument of :func:`rotor_fmu.ring_interface.step_with_ring_interface` from
    the ring parameters and inputs, or None when no station has a ring (m_ring_i = 0)."""
    if not any(self._values[n] for n in RING_PARAMETERS):
        return None
    import numpy as np
    m = np.array([self._values[n] for n in RING_PARAMETERS])
    st = range(1, N_BEARINGS + 1)
    v = self._values
    return dict(
        m=m, s=np.array([[v[f"{q}_ring_{i}"] for q in ("x", "y", "vx", "vy")] for i in st]),
        a=np.array([[v[f"ax_ring_{i}"], v[f"ay_ring_{i}"]] for i in st]),
        Ko=np.array([[[v[f"k{a}{b}_outer_{i}"] for b in "xy"] for a in "xy"] for i in st]),
        Co=np.array([[[v[f"c{a}{b}_outer_{i}"] for b in "xy"] for a in "xy"] for i in st]))


# Declared ranges of the parameters of both rotor FMUs (modelDescription.xml min/max, inclusive):
# an importer refuses a bad value when it loads a scenario; JeffcottParams / TurbochargerParams
# .validate check the same when the model is made. Names a rotor lacks are skipped.
PARAMETER_RANGES: dict[str, tuple[Any, Any]] = {n: (lo, hi) for n, (lo, hi, _) in RANGES.items()}


def rotor_to_xml(self, model_options: dict[str, str] = dict()) -> Element:  # noqa: B006
    return finish_model_description(Fmi2Slave.to_xml(self, model_options), self._units, UNITS, PARAMETER_RANGES)


def rotor_output_names(self) -> list[str]:
    """Outputs: the journal kinematics of each station, speed, angle, then the model's extras."""
    names = [f"{c}_{i}" for i in range(1, N_BEARINGS + 1) for c in ("x", "y", "vx", "vy")]
    names += ["omega", "angle", "alpha"]
    names += [n for n in self._extra_output_names() if n not in names]
    return names


def rotor_ensure_model(self) -> None:
    params = {n: self._values[n] for n in self._param_names}
    key = (tuple(sorted(params.items())), self._start_time)
    if self._model is not None and key == self._init_key:
        return
    model = self._make_model(params, self._start_time)
    if model.n_bearings != N_BEARINGS:
        raise ValueError(f"rotor model has {model.n_bearings} bearing stations; this FMU has "
                         f"{N_BEARINGS} (inputs Fx_1..Fy_{N_BEARINGS}); use a rotor with {N_BEARINGS}")
    model.initialize()
    self._model = model
    self._init_key = key
    self._copy_outputs()


def rotor_copy_outputs(self) -> None:
    out = self._model.outputs
    values = self._values
    names = self.__dict__.get("_output_list")
    if names is None:                  # the names are fixed once the slave is made
        names = self._output_list = tuple(self._output_names())
    for name in names:
        values[name] = float(out[name])


FORCE_NAMES = tuple(f"F{c}_{i}" for i in range(1, N_BEARINGS + 1) for c in "xy")
COEFF_NAMES = tuple(f"{kind}{a}{b}_{i}" for kind in "kc" for i in range(1, N_BEARINGS + 1)
                    for a in "xy" for b in "xy")    # (kind, station, row, column) order


def rotor_forces(self):
    import numpy as np
    values = self._values
    return np.array([values[n] for n in FORCE_NAMES]).reshape(N_BEARINGS, 2)


def rotor_coefficients(self):
    """Film coefficients (K, C), each (N_BEARINGS, 2, 2), from the inputs kxx_i..cyy_i;
    (None, None) when all are 0 (plain coupling, bit-identical to the old step)."""
    values = self._values
    v = [values[n] for n in COEFF_NAMES]
    if not any(v):
        return None, None
    import numpy as np
    v = np.array(v).reshape(2, N_BEARINGS, 2, 2)
    return v[0], v[1]


rotor_setup_experiment, rotor_exit_initialization_mode = setup_experiment, exit_initialization_mode


def rotor_do_step(self, current_time: float, step_size: float) -> bool:
    check_step_start(self, current_time, step_size)
    saved = self._model.get_state()        # a copy (LinearRotor.get_state copies the state vector)
    try:
        ring = rotor_ring_inputs(self)
        if ring is None:
            self._model.step(step_size, self._forces(), *rotor_coefficients(self))
        else:
            from rotor_fmu.ring_interface import step_with_ring_interface
            step_with_ring_interface(self._model, step_size, self._forces(), *rotor_coefficients(self), ring)
    except FloatingPointError as exc:   # state became non-finite: cannot complete this step
        self._model.set_state(saved)
        self.log(f"rotor step t={current_time:.9g} dt={step_size:.3g} failed: {exc}", Fmi2Status.discard)
        return False
    self._copy_outputs()
    self._time = current_time + step_size
    return True


_STATE_ATTRS = {"start_time": "_start_time"}     # saved with the FMU state besides the common part


def rotor_get_fmu_state(self) -> dict[str, Any]:
    return get_slave_state(self, _STATE_ATTRS)


def rotor_set_fmu_state(self, state: dict[str, Any]) -> None:
    set_slave_state(self, state, _STATE_ATTRS)
    if state["model"] is not None:
        self._copy_outputs()


# ----------------------------------------------------------------------------
def _jeffcott_fields():
    from rotor_fmu.jeffcott import JeffcottParams
    return scalar_fields(JeffcottParams)


def _jeffcott_model(params: dict[str, Any], t0: float):
    from rotor_fmu.jeffcott import JeffcottModel as Model, JeffcottParams
    return Model(JeffcottParams(**params, t0=t0))


@guard_callbacks
class JeffcottRotor(Fmi2Slave):
    """Jeffcott rotor (disc on a flexible massless shaft, two journals), kinematic speed ramp."""

    author = "rotorcosim"
    description = ("Jeffcott rotor with two journals, gravity, unbalance, internal and external damping, "
                   "kinematically driven speed ramp (paper section 3.2)")
    version = "0.1.0"

    __init__ = rotor_init
    to_xml = rotor_to_xml
    setup_experiment = rotor_setup_experiment
    exit_initialization_mode = rotor_exit_initialization_mode
    do_step = rotor_do_step
    get_real = fast_get_real
    set_real = fast_set_real
    _get_fmu_state = rotor_get_fmu_state
    _set_fmu_state = rotor_set_fmu_state
    _fmu_state_to_bytes = staticmethod(state_to_bytes)
    _fmu_state_from_bytes = staticmethod(state_from_bytes)
    _output_names = rotor_output_names
    _ensure_model = rotor_ensure_model
    _copy_outputs = rotor_copy_outputs
    _forces = rotor_forces

    @staticmethod
    def _parameter_fields():
        return _jeffcott_fields()

    @staticmethod
    def _extra_output_names() -> list[str]:
        return ["x_disc", "y_disc", "vx_disc", "vy_disc"]

    @staticmethod
    def _make_model(params: dict[str, Any], t0: float):
        return _jeffcott_model(params, t0)


