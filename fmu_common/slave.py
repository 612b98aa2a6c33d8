"""FMU slave plumbing shared by our PythonFMU slaves (bearing, Jeffcott and turbocharger rotors).

The build bundles this package into every FMU next to the model package
(``orchestrator.fmi.build.RECIPES``), so a slave imports it at run time from the
FMU's ``resources/`` folder. The slave classes still derive from ``Fmi2Slave``
directly (PythonFMU's loader finds them by that base); what they share is here:
``RealU`` (a Real with a unit), :func:`finish_model_description`, the shipped
variable layout (:func:`shipped_parameters`, :func:`check_shipped_layout`) and the
guard against PythonFMU 0.7.0's reference-count bug (:func:`guard_callbacks`).
"""

from __future__ import annotations

import pickle
import copy
import dataclasses
from pathlib import Path
from typing import Any, Callable
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import Real


def journal_kinematics(journal: str = "") -> dict[str, tuple[str, str]]:
    """The rotor-bearing interface: name -> (unit, description) of the journal kinematics a
    rotor outputs for each bearing (``x_1``, ...) and a bearing takes as its inputs, in one
    table so that the two sides cannot drift apart (docs/fmus.md). ``journal``: text after
    "journal" in the descriptions (the rotor passes " {i}", formatted per bearing)."""
    return {
        "x": ("m", f"journal{journal} centre x relative to the bearing centre [m] (x horizontal)"),
        "y": ("m", f"journal{journal} centre y relative to the bearing centre [m] (y vertical up)"),
        "vx": ("m/s", f"journal{journal} centre velocity x [m/s]"),
        "vy": ("m/s", f"journal{journal} centre velocity y [m/s]"),
        "omega": ("rad/s", "journal (rotor) angular speed about +z (counter-clockwise positive) [rad/s]"),
    }


#: FMI ``nominal`` (sec. 2.2.7, the typical size of a variable, for scaling) of the interface
#: signals whose typical size is not the size they start from: the rotor speed starts at 0 in a
#: run-up from rest, so a tolerance relative to the size it has had so far asks for a step that
#: resolves the first rad/s (rotorcosim's error-controlled step forced its first 4 steps to
#: min_step on it: orchestrator/coupling/signal_scales.py); 1000 rad/s is the order of the speeds
#: of our machines (the Jeffcott run-up to 5027 rad/s, the turbocharger to 660 rad/s). Declared on
#: the rotors' output and the bearings' input alike (:func:`finish_model_description`).
NOMINALS: dict[str, float] = {"omega": 1000.0}


def declare_nominals(root: Element, nominals: dict[str, float]) -> Element:
    """Write ``nominal`` on the Real element of the variables named in ``nominals``; names the
    FMU lacks are ignored."""
    for sv in root.iter("ScalarVariable"):
        value = nominals.get(sv.get("name"))
        el = sv.find("Real")
        if value is not None and el is not None:
            el.set("nominal", repr(float(value)))
    return root


class RealU(Real):
    """PythonFMU ``Real`` with an FMI ``unit`` attribute."""

    def __init__(self, name: str, unit: str | None = None, **kwargs: Any):
        super().__init__(name, **kwargs)
        self.unit = unit

    def to_xml(self) -> Element:
        node = super().to_xml()
        if self.unit:
            node.find("Real").set("unit", self.unit)
        return node


# FMI 2.0 min/max are inclusive: "greater than 0" is declared as min = the smallest positive double
POSITIVE = 5e-324


def declare_ranges(root: Element, ranges: dict[str, tuple[Any, Any]]) -> Element:
    """Write ``min``/``max`` (FMI 2.0 sec. 2.2.7) on the Real and Integer type elements of the
    variables named in ``ranges`` (name -> (min or None, max or None)), so that an importer can
    refuse a value before it instantiates the FMU (rotorcosim does when it loads a scenario:
    ``orchestrator.fmi.values.check_value``). Names the FMU lacks are ignored."""
    for sv in root.iter("ScalarVariable"):
        bounds = ranges.get(sv.get("name"))
        el = next((c for c in sv if c.tag in ("Real", "Integer")), None)
        if bounds is None or el is None:
            continue
        for attr, value in zip(("min", "max"), bounds):
            if value is not None:
                el.set(attr, repr(float(value)) if el.tag == "Real" else str(int(value)))
    return root


def declare_choices(root: Element, choices: dict[str, tuple[str, ...]]) -> Element:
    """Declare the values the String variables named in ``choices`` accept, in a ``rotorcosim``
    tool annotation of the ScalarVariable (FMI 2.0 cannot declare them; other importers ignore
    it; rotorcosim checks a scenario's value against them when it loads the scenario)."""
    for sv in root.iter("ScalarVariable"):
        values = choices.get(sv.get("name"))
        if values is None or sv.find("String") is None:
            continue
        ann = sv.find("Annotations")
        if ann is None:
            ann = SubElement(sv, "Annotations")
        lst = SubElement(SubElement(ann, "Tool", attrib={"name": "rotorcosim"}), "Choices")
        for v in values:
            SubElement(lst, "Choice", attrib={"value": v})
    return root


def finish_model_description(root: Element, units: set[str], table: dict[str, dict[str, str]],
                             ranges: dict[str, tuple[Any, Any]] | None = None,
                             choices: dict[str, tuple[str, ...]] | None = None) -> Element:
    """Complete PythonFMU's ``modelDescription.xml`` tree.

    * ``<UnitDefinitions>`` right after ``<CoSimulation>`` (schema order), so the
      ``unit`` attributes of the variables refer to defined units;
    * ``<Outputs>``: ``dependencies=""``: outputs change only in ``fmi2DoStep``
      (setting an input does not change an output: no direct feedthrough);
    * ``<InitialUnknowns>``: every output (initial="calculated"), with the default
      (unknown) dependencies: in initialization mode outputs are computed from
      the parameters and inputs.

    * ``min``/``max`` of the parameters in ``ranges`` (:func:`declare_ranges`), the values of
      the String parameters in ``choices`` (:func:`declare_choices`), the ``nominal`` of the
      interface signals in :data:`NOMINALS` (:func:`declare_nominals`).

    ``table``: unit name -> base-unit exponents (the slave's ``UNITS``).
    """
    declare_nominals(root, NOMINALS)
    if ranges:
        declare_ranges(root, ranges)
    if choices:
        declare_choices(root, choices)
    if units:
        defs = Element("UnitDefinitions")
        for name in sorted(units):
            u = SubElement(defs, "Unit", attrib={"name": name})
            SubElement(u, "BaseUnit", attrib=table[name])
        children = list(root)
        idx = next(i for i, c in enumerate(children) if c.tag == "CoSimulation") + 1
        root.insert(idx, defs)
    structure = root.find("ModelStructure")
    outputs = structure.find("Outputs")
    if outputs is not None:
        indices = []
        for unknown in outputs.findall("Unknown"):
            unknown.set("dependencies", "")
            indices.append(unknown.get("index"))
        initial = SubElement(structure, "InitialUnknowns")
        for index in indices:
            SubElement(initial, "Unknown", attrib={"index": index})
    return root


def shipped_parameters(resources: str | None) -> list[tuple[str, Any, type]] | None:
    """Parameters declared in the FMU's own ``modelDescription.xml`` (name, start, type), in order.

    At run time the variable list must be the one the importer read, even if the
    Python model found at run time has other parameter fields (e.g. a process that
    imported a newer ``bearing_fmu`` before loading an older FMU): value references
    are positions in this list. ``None`` when there is no shipped description
    (the builder is writing it).
    """
    if not resources:
        return None
    path = Path(resources).parent / "modelDescription.xml"
    if not path.is_file():
        return None
    from xml.etree import ElementTree
    kinds = {"Real": float, "Integer": int, "Boolean": bool, "String": str}
    out = []
    for sv in ElementTree.parse(path).getroot().iter("ScalarVariable"):
        if sv.get("causality") != "parameter":
            continue
        for tag, kind in kinds.items():
            node = sv.find(tag)
            if node is not None:
                start = node.get("start", "")
                value = (start.lower() == "true") if kind is bool else kind(start) if start != "" or kind is str \
                    else kind()
                out.append((sv.get("name"), value, kind))
                break
    return out


def check_shipped_layout(slave) -> None:
    """Raise if the registered variables differ from the shipped modelDescription.xml."""
    if not slave.resources:
        return
    path = Path(slave.resources).parent / "modelDescription.xml"
    if not path.is_file():
        return
    from xml.etree import ElementTree
    shipped = [(int(sv.get("valueReference")), sv.get("name"))
               for sv in ElementTree.parse(path).getroot().iter("ScalarVariable")]
    have = [(vr, v.name) for vr, v in slave.vars.items()]
    if shipped != have:
        diff = sorted(set(shipped) ^ set(have))[:6]
        raise RuntimeError(f"{type(slave).__name__}: the variables of this slave differ from its "
                           f"modelDescription.xml (first differences {diff}); rebuild the FMU "
                           "(`rotorcosim build-fmus --force`)")


# ----------------------------------------------------------------------------
# PythonFMU 0.7.0 reference-count bug: when a Python exception escapes an FMI
# callback, its C++ handle_py_exception() calls cleanPyObject(), which
# Py_XDECREFs the slave class, the slave instance and its log queue WITHOUT
# clearing the pointers; fmi2FreeInstance later decrefs them again. The objects
# end up with one reference too few and Python's cyclic GC later crashes on them
# (seen as segfaults in unrelated tests). Until PythonFMU fixes it (pinned to
# 0.7.0 in pyproject.toml), every callback that lets an exception escape first
# adds the one reference that the extra decref will take away, so the FMU still
# reports the error (fmi2Fatal) and nothing is corrupted.
# ----------------------------------------------------------------------------
def compensate_pythonfmu_decref(slave) -> None:
    import ctypes
    for obj in (type(slave), slave, getattr(slave, "log_queue", None)):
        if obj is not None:
            ctypes.pythonapi.Py_IncRef(ctypes.py_object(obj))


def fmi_callback(fn):
    """Wrap a method PythonFMU calls from C++ (see compensate_pythonfmu_decref)."""
    import functools

    @functools.wraps(fn)
    def wrapper(self, *args, **kwargs):
        try:
            return fn(self, *args, **kwargs)
        except BaseException:
            compensate_pythonfmu_decref(self)
            raise
    return wrapper


CALLBACKS = ("setup_experiment", "enter_initialization_mode", "exit_initialization_mode", "do_step",
             "terminate", "get_integer", "get_real", "get_boolean", "get_string", "set_integer",
             "set_real", "set_boolean", "set_string", "_get_fmu_state", "_set_fmu_state")


def guard_callbacks(cls):
    """Class decorator: wrap every PythonFMU callback of ``cls`` with :func:`fmi_callback`."""
    for name in CALLBACKS:
        setattr(cls, name, fmi_callback(getattr(cls, name)))
    return cls


def _real_accessors(self) -> tuple[dict, dict]:
    """(getters, setters) of the slave's Real variables by value reference, made on first use
    (every variable is registered in ``__init__``, before the first get or set)."""
    acc = self.__dict__.get("_real_access")
    if acc is None:
        vars_ = [(vr, v) for vr, v in self.vars.items() if isinstance(v, Real)]
        acc = self._real_access = ({vr: v.getter for vr, v in vars_ if v.getter is not None},
                                   {vr: v.setter for vr, v in vars_ if v.setter is not None})
    return acc


def fast_get_real(self, vrs):
    """``Fmi2Slave.get_real`` without its per-variable ``isinstance`` test of an abstract class
    (~1.5 us per variable, a third of the call): same values, same TypeError for a reference
    that is not a Real; a Real without getter raises as PythonFMU's does (TypeError: None is
    not callable). Assign as the slave's ``get_real``."""
    getters = _real_accessors(self)[0]
    try:
        return [float(getters[vr]()) for vr in vrs]
    except KeyError as e:
        vr = e.args[0]
        if vr in self.vars and isinstance(self.vars[vr], Real):    # a Real without a getter
            raise TypeError("'NoneType' object is not callable") from None
        raise TypeError(f"Variable with valueReference={vr} is not of type Real!") from None


def fast_set_real(self, vrs, values):
    """``Fmi2Slave.set_real`` the same way as :func:`fast_get_real`; the values before a bad
    reference are set, as PythonFMU does."""
    setters = _real_accessors(self)[1]
    for vr, value in zip(vrs, values):
        f = setters.get(vr)
        if f is None:
            if vr in self.vars and isinstance(self.vars[vr], Real):
                raise TypeError("'NoneType' object is not callable")
            raise TypeError(f"Variable with valueReference={vr} is not of type Real!")
        f(value)


class InitializationStateError(RuntimeError):
    """An FMI call came in the wrong life-cycle phase."""


# variable accessors of a slave that keeps its FMI-visible values in ``self._values``
def value_getter(self, name: str) -> Callable[[], Any]:
    """Getter of the slave's ``_values[name]``."""
    return lambda: self._values[name]


def output_getter(self, name: str) -> Callable[[], Any]:
    """Getter of an output: asked in initialization mode, the model is made first (``_ensure_model``)."""
    def get():
        if not self._initialized:
            self._ensure_model()
        return self._values[name]
    return get


def param_setter(self, name: str, kind: type):
    """Setter of a parameter: fixed after initialization (a changed value raises)."""
    def set_(value):
        value = kind(value)
        if self._initialized and value != self._values[name]:
            raise InitializationStateError(
                f"parameter '{name}' is fixed after initialization (tried {value!r}, "
                f"has {self._values[name]!r}); set it before fmi2ExitInitializationMode")
        self._values[name] = value
    return set_


def input_setter(self, name: str):
    """Setter of a Real input."""
    def set_(value):
        self._values[name] = float(value)
    return set_


def refresh_coefficients(self, linearization: Callable[[], tuple],
                         hold: Callable[[], bool] | None = None) -> None:
    """Film coefficient outputs ``kxx..cyy`` for interface-Jacobian coupling: recomputed by
    ``linearization() -> (K, C)`` every ``linearize``-th step (and while not initialized),
    held in between; ``_values["_lin_age"]`` counts the steps (it is in the FMU state).
    ``hold() -> bool`` (optional): True skips a refresh that is due (e.g. the kinematics
    have not moved since the last one; the journal bearing's ``linearize_tol``)."""
    n_lin = int(self._values.get("linearize", 0))
    if n_lin <= 0:
        return
    age = int(self._values.get("_lin_age", n_lin))
    if age >= n_lin and self._initialized and hold is not None and hold():
        self._values["_lin_age"] = age + 1
        return
    if age >= n_lin or not self._initialized:
        K, C = linearization()
        for m, kind in ((K, "k"), (C, "c")):
            for a, i in enumerate("xy"):
                for b, j in enumerate("xy"):
                    self._values[f"{kind}{i}{j}"] = float(m[a, b])
        age = 0
    self._values["_lin_age"] = age + 1


# life cycle shared by the slaves (``self._time``, ``self._start_time``, ``self._initialized``)
def setup_experiment(self, start_time: float, stop_time=None, tolerance=None):
    self._start_time = float(start_time)
    self._time = float(start_time)


def exit_initialization_mode(self):
    self._ensure_model()
    self._time = self._start_time
    self._initialized = True


def check_step_start(self, current_time: float, step_size: float) -> None:
    """Raise unless the slave is initialized and at ``current_time`` (the step's start)."""
    if not self._initialized:
        raise InitializationStateError("do_step before exit_initialization_mode")
    if abs(current_time - self._time) > 1e-9 * max(1.0, abs(current_time)) + 1e-6 * step_size:
        raise InitializationStateError(
            f"do_step at t={current_time!r} but the FMU is at t={self._time!r}; "
            "restore a saved FMU state to step from an earlier time")


def state_to_bytes(state: dict[str, Any]) -> bytes:
    return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)


def state_from_bytes(state: bytes) -> dict[str, Any]:
    return pickle.loads(state)


def get_slave_state(self, extra: dict[str, str]) -> dict[str, Any]:
    """The slave's FMU state: FMI-visible values, time, phase, the model's own state (deep
    copy, unless the model's class says with ``STATE_IS_COPY = True`` that its ``get_state``
    returns arrays and values it does not keep) and the ``extra`` attributes (state key ->
    attribute name)."""
    state = {"values": dict(self._values), "time": self._time, "initialized": self._initialized,
             "init_key": self._init_key}
    state.update({key: getattr(self, attr) for key, attr in extra.items()})
    model = self._model
    if model is None:
        state["model"] = None
    elif getattr(model, "STATE_IS_COPY", False):
        state["model"] = model.get_state()
    else:
        state["model"] = copy.deepcopy(model.get_state())
    return state


def set_slave_state(self, state: dict[str, Any], extra: dict[str, str]) -> None:
    """Restore a state of :func:`get_slave_state` (from this or another instance of the FMU)."""
    if state["model"] is not None and self._model is None:
        # state taken from another instance of the same FMU: rebuild the model first
        self._values.update(state["values"])
        for key, attr in extra.items():
            setattr(self, attr, state[key])
        self._ensure_model()
    self._values = dict(state["values"])
    self._time = state["time"]
    for key, attr in extra.items():
        setattr(self, attr, state[key])
    self._initialized = state["initialized"]
    self._init_key = state["init_key"]
    if state["model"] is None:
        self._model = None
    else:
        self._model.set_state(copy.deepcopy(state["model"]))


def scalar_default(f: dataclasses.Field) -> tuple[type, Any] | None:
    """``(kind, default)`` of a dataclass field whose default is a bool/int/float/str, else None."""
    if f.default is not dataclasses.MISSING:
        default = f.default
    elif f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
        default = f.default_factory()  # type: ignore[misc]
    else:
        return None
    for kind in (bool, int, float, str):
        if isinstance(default, kind):
            return kind, kind(default)
    return None
