"""FMI 2.0 ``modelDescription.xml``: the parsed :class:`ModelDescription` and its parser.

:func:`parse_model_description` reads the bytes of an FMU's model description as untrusted
input (the archive around it is checked by :mod:`orchestrator.fmi.archive`, which reads the
member and calls it): at most :data:`MAX_XML_BYTES`, parsed by
:func:`orchestrator.untrusted.parse_xml` (DOCTYPE and entities refused after decoding,
whatever the encoding), ``fmiVersion`` exactly ``2.0`` (or ``2.0.x``), a ``CoSimulation``
element, every variable with a valueReference in 0..2^32-1 (fmi2ValueReference is a 32-bit
unsigned int) and an FMI 2.0 causality and variability (FMI 2.0 sec. 2.2), and a consistent
``<ModelStructure>`` (:func:`_model_structure`, FMI 2.0 sec. 2.2.8). Every problem
raises :class:`orchestrator.errors.FmuError` naming the file, what is wrong and the fix.
"""

from __future__ import annotations

import math
import re
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from orchestrator.errors import FmuError
from orchestrator.untrusted import InputError, parse_xml

MAX_XML_BYTES = 32 * 2**20            # modelDescription.xml
MAX_VALUE_REFERENCE = 2**32 - 1       # fmi2ValueReference is unsigned int
MAX_DEPENDENCIES = 2_000_000          # <ModelStructure>: dependencies of all Unknowns together
CAUSALITIES = ("parameter", "calculatedParameter", "input", "output", "local", "independent")
VARIABILITIES = ("constant", "fixed", "tunable", "discrete", "continuous")
_VERSION_RE = re.compile(r"^2\.0(\.[0-9]+)?$")


@dataclass(frozen=True)
class Variable:
    """One ``ScalarVariable`` of a model description."""

    name: str
    value_reference: int
    type: str                      # "Real" | "Integer" | "Boolean" | "String" | "Enumeration"
    causality: str                 # "parameter" | "calculatedParameter" | "input" | "output" | "local" | "independent"
    variability: str               # "constant" | "fixed" | "tunable" | "discrete" | "continuous"
    start: Any = None              # parsed to float/int/bool/str when given
    description: str = ""
    unit: str = ""                 # the variable's unit, else its declared type's
    initial: str = ""              # "exact" | "approx" | "calculated" | "" (FMI 2.0 default applies)
    declared_type: str = ""
    min: Any = None                # the variable's min/max, else its declared type's (int/float)
    max: Any = None
    nominal: float | None = None
    items: tuple = ()              # Enumeration: ((name, value, description), ...) of the declared type
    choices: tuple = ()            # String: the values the FMU accepts, from its rotorcosim annotation
    derivative: int | None = None  # Real: index (1-based) of the variable this one is the derivative of


#: the SI base units of an FMI 2.0 ``<BaseUnit>`` (sec. 2.2.2), in order
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


@dataclass(frozen=True)
class UnitDef:
    """One ``<Unit>`` of ``<UnitDefinitions>`` with its ``<BaseUnit>``: a value v of this unit is
    ``factor * v + offset`` in the SI unit of exponents ``exponents`` (:data:`BASE_UNITS`)."""

    exponents: tuple[int, ...]
    factor: float = 1.0
    offset: float = 0.0

    def to(self, other: "UnitDef") -> tuple[float, float] | None:
        """(gain, offset) that turn a value of this unit into one of ``other``
        (``gain * v + offset``); None when the dimensions differ."""
        if self.exponents != other.exponents:
            return None
        return self.factor / other.factor, (self.offset - other.offset) / other.factor


@dataclass(frozen=True)
class Unknown:
    """One ``<Unknown>`` of ``<ModelStructure>`` (FMI 2.0 sec. 2.2.8): ScalarVariable ``index``
    (1-based, in file order) and the indices of the Knowns it depends on."""

    index: int
    name: str
    dependencies: tuple[int, ...] | None = None      # None: not declared (it may depend on every Known)
    dependencies_kind: tuple[str, ...] | None = None  # None: not declared


@dataclass(frozen=True)
class ModelStructure:
    """``<ModelStructure>``: its Outputs, Derivatives and InitialUnknowns, as declared (empty
    when the file has none)."""

    outputs: tuple[Unknown, ...] = ()
    derivatives: tuple[Unknown, ...] = ()
    initial_unknowns: tuple[Unknown, ...] = ()


@dataclass(frozen=True)
class ModelDescription:
    """The parts of an FMI 2.0 ``modelDescription.xml`` the orchestrator uses."""

    path: Path                     # the FMU file it came from
    fmi_version: str
    model_name: str
    guid: str
    model_identifier: str          # of the CoSimulation element
    can_interpolate_inputs: bool = False
    max_output_derivative_order: int = 0
    can_get_and_set_fmu_state: bool = False
    can_handle_variable_step: bool = True
    needs_execution_tool: bool = False
    can_be_instantiated_only_once_per_process: bool = False
    description: str = ""
    generation_tool: str = ""
    default_experiment: Mapping[str, float] = field(default_factory=dict)
    variables: Mapping[str, Variable] = field(default_factory=dict)   # name -> Variable, in file order
    model_structure: ModelStructure = field(default_factory=ModelStructure)
    units: Mapping[str, UnitDef] = field(default_factory=dict)   # <UnitDefinitions> with a valid <BaseUnit>

    def inputs(self) -> list[Variable]:
        return [v for v in self.variables.values() if v.causality == "input"]

    def outputs(self) -> list[Variable]:
        return [v for v in self.variables.values() if v.causality == "output"]

    def parameters(self) -> list[Variable]:
        return [v for v in self.variables.values() if v.causality == "parameter"]

    def direct_feedthrough(self) -> dict[str, tuple[str, ...] | None]:
        """``{output name: names of the inputs it depends on directly}`` from
        ``<ModelStructure><Outputs>`` (FMI 2.0 sec. 2.2.8: at a communication point an output
        depends on these inputs without a step in between); ``()`` for an output that depends on
        no input, None where the FMU does not declare its dependencies (then it may depend on
        every input). Outputs the FMU does not list in ``<Outputs>`` are None too."""
        by_index = list(self.variables.values())
        declared = {u.name: u.dependencies for u in self.model_structure.outputs}
        out = {}
        for v in self.outputs():
            deps = declared.get(v.name)
            out[v.name] = None if deps is None else tuple(
                by_index[i - 1].name for i in deps if by_index[i - 1].causality == "input")
        return out


def _fail(path, what: str, fix: str) -> FmuError:
    return FmuError(f"{path}: {what}; {fix}")

def _bool(s: str | None, default: bool) -> bool:
    if s is None:
        return default
    return s.strip().lower() in ("true", "1")


def _value_reference(path: Path, name: str, vr: str) -> int:
    """``vr`` as an fmi2ValueReference (unsigned 32-bit): no truncation, no silent wrap-around."""
    text = vr.strip()
    if not re.fullmatch(r"[-+]?[0-9]+", text):
        raise _fail(path, f"variable {name!r} has a non-integer valueReference {vr[:40]!r}", "re-export the FMU")
    value = int(text) if len(text) <= 20 else MAX_VALUE_REFERENCE + 1
    if not 0 <= value <= MAX_VALUE_REFERENCE:
        shown = text if len(text) <= 20 else text[:12] + f"... ({len(text)} digits)"
        raise _fail(path, f"valueReference {shown} of variable {name!r} is outside 0..{MAX_VALUE_REFERENCE} "
                    "(fmi2ValueReference is a 32-bit unsigned integer; a larger one would be truncated and read "
                    "another variable)", "re-export the FMU with valid value references")
    return value


def _number(type_: str, s: str | None):
    """A min/max/nominal attribute as int (Integer, Enumeration) or float (Real); None if absent or unreadable."""
    if s is None or type_ not in ("Real", "Integer", "Enumeration"):
        return None
    try:
        return float(s) if type_ == "Real" else int(s)
    except ValueError:
        return None


def _unit_definitions(root) -> dict[str, UnitDef]:
    """``{unit name: UnitDef}`` of ``<UnitDefinitions>`` (FMI 2.0 sec. 2.2.2); a unit without a
    ``<BaseUnit>``, or with one whose numbers do not read, is left out (its relation to other
    units is unknown)."""
    out = {}
    ud = root.find("UnitDefinitions")
    for unit in (ud if ud is not None else []):
        name = unit.get("name")
        found = base_unit(unit.find("BaseUnit")) if unit.tag == "Unit" and name else None
        if found is not None:
            out[name] = found
    return out


def base_unit(base) -> UnitDef | None:
    """The UnitDef of a ``BaseUnit`` element (FMI 2.0's, or SSP's ``ssc:BaseUnit``, which has the
    same attributes); None without one, or when its numbers do not read or the factor is 0."""
    if base is None:
        return None
    try:
        exps = tuple(int(base.get(k, "0")) for k in BASE_UNITS)
        factor, offset = float(base.get("factor", "1")), float(base.get("offset", "0"))
    except ValueError:
        return None
    if math.isfinite(factor) and math.isfinite(offset) and factor != 0.0:
        return UnitDef(exps, factor, offset)
    return None


def _type_definitions(root) -> dict[str, tuple[dict, tuple]]:
    """``{SimpleType name: (attributes of its type element, enumeration items)}`` (FMI 2.0 sec. 2.2.3)."""
    out = {}
    td = root.find("TypeDefinitions")
    for st in (td if td is not None else []):
        if st.tag != "SimpleType" or not st.get("name"):
            continue
        el = next((c for c in st if c.tag in ("Real", "Integer", "Boolean", "String", "Enumeration")), None)
        if el is None:
            continue
        items = []
        if el.tag == "Enumeration":
            for it in el:
                if it.tag == "Item" and it.get("name") is not None:
                    v = _number("Integer", it.get("value"))
                    if v is not None:
                        items.append((it.get("name"), v, it.get("description", "") or ""))
        out[st.get("name")] = (dict(el.attrib), tuple(items))
    return out


def parse_model_description(xml: bytes, path: Path | str = "<memory>") -> ModelDescription:
    """Parse the bytes of an FMI 2.0 ``modelDescription.xml`` (see module doc for the rules)."""
    path = Path(path)
    if len(xml) > MAX_XML_BYTES:
        raise _fail(path, f"modelDescription.xml is {len(xml)} bytes (limit {MAX_XML_BYTES})",
                    "raise orchestrator.fmi.model_description.MAX_XML_BYTES if you trust this FMU")
    try:                      # defusedxml: DOCTYPE/entities refused after decoding (UTF-16 too)
        root = parse_xml(xml, display=str(path), what="modelDescription.xml")
    except InputError as e:
        raise FmuError(str(e)) from None
    if root.tag != "fmiModelDescription":
        raise _fail(path, f"modelDescription.xml has root element <{root.tag}>, expected <fmiModelDescription>",
                    "re-export the FMU")
    version = root.get("fmiVersion", "")
    if not _VERSION_RE.match(version):
        raise _fail(path, f"has fmiVersion {version[:40]!r}, expected FMI 2.0 ('2.0')",
                    "export the model as an FMI 2.0 co-simulation FMU")
    cs = root.find("CoSimulation")
    if cs is None:
        raise _fail(path, "has no <CoSimulation> element (it is a Model Exchange only FMU)",
                    "export the model as an FMI 2.0 co-simulation FMU")
    ident = cs.get("modelIdentifier", "")
    if not ident or any(c in ident for c in "/\\\x00") or ident in (".", ".."):
        raise _fail(path, f"has an invalid modelIdentifier {ident!r}", "re-export the FMU")

    types = _type_definitions(root)
    variables: dict[str, Variable] = {}
    mv = root.find("ModelVariables")
    for sv in (mv if mv is not None else []):
        if sv.tag != "ScalarVariable":
            continue
        var = _variable(sv, types, path)
        if var.name in variables:
            raise _fail(path, f"variable {var.name!r} is declared twice", "re-export the FMU")
        variables[var.name] = var
    structure = _model_structure(root, path, list(variables.values()))

    de = root.find("DefaultExperiment")
    default_experiment = {}
    if de is not None:
        for k in ("startTime", "stopTime", "tolerance", "stepSize"):
            if de.get(k) is not None:
                try:
                    default_experiment[k] = float(de.get(k))
                except ValueError:           # kept as written: reported where it would be used
                    default_experiment[k] = de.get(k)[:40]
    try:
        mod = int(cs.get("maxOutputDerivativeOrder", "0"))
    except ValueError:
        mod = 0
    return ModelDescription(
        path=path, fmi_version=version, model_name=root.get("modelName", ident), guid=root.get("guid", ""),
        model_identifier=ident,
        can_interpolate_inputs=_bool(cs.get("canInterpolateInputs"), False),
        max_output_derivative_order=mod,
        can_get_and_set_fmu_state=_bool(cs.get("canGetAndSetFMUstate"), False),
        can_handle_variable_step=_bool(cs.get("canHandleVariableCommunicationStepSize"), False),
        needs_execution_tool=_bool(cs.get("needsExecutionTool"), False),
        can_be_instantiated_only_once_per_process=_bool(cs.get("canBeInstantiatedOnlyOncePerProcess"), False),
        description=root.get("description", "") or "", generation_tool=root.get("generationTool", "") or "",
        default_experiment=default_experiment, variables=variables, model_structure=structure,
        units=_unit_definitions(root))


_HIDDEN = ("Cc", "Cf", "Zl", "Zp", "Cs")   # as in untrusted.name_problem


def _variable(sv, types, path: Path) -> Variable:
    """One ``ScalarVariable`` element: name, valueReference, one type element, an FMI 2.0
    causality and variability; unit and range from its declared type where it gives none."""
    name = sv.get("name")
    vr = sv.get("valueReference")
    if name is None or vr is None:
        raise _fail(path, "a ScalarVariable lacks name or valueReference", "re-export the FMU")
    type_el = next((c for c in sv if c.tag in ("Real", "Integer", "Boolean", "String", "Enumeration")), None)
    if type_el is None:
        raise _fail(path, f"variable {name!r} has no type element", "re-export the FMU")
    vr_int = _value_reference(path, name, vr)
    causality = sv.get("causality", "local")
    variability = sv.get("variability", "continuous")
    for what, value, allowed in (("causality", causality, CAUSALITIES),
                                 ("variability", variability, VARIABILITIES)):
        if value not in allowed:
            raise _fail(path, f"{what} {value[:40]!r} of variable {name!r} is not an FMI 2.0 {what} (one of "
                        f"{', '.join(allowed)})", "re-export the FMU with a valid model description")
    if not name.strip():
        raise _fail(path, f"a ScalarVariable (valueReference {vr_int}) has an empty name", "re-export the FMU")
    hidden = next((c for c in name if unicodedata.category(c) in _HIDDEN), None)
    if hidden is not None:       # a line break made results.csv's header two lines, 'info' print a fake line
        raise _fail(path, f"variable name {name[:80]!r} holds the control or invisible character "
                    f"U+{ord(hidden):04X}", "re-export the FMU with printable variable names")
    declared = type_el.get("declaredType", "") or ""
    attrs = {**types.get(declared, ({}, ()))[0], **type_el.attrib}
    start = type_el.get("start")
    values = _check_attributes(path, name, type_el.tag, {**attrs, "start": start})
    if type_el.tag == "Boolean":
        values["start"] = None if start is None else _bool(start, False)
    elif type_el.tag == "String":
        values["start"] = start
    return Variable(
        name=name, value_reference=vr_int, type=type_el.tag, causality=causality,
        variability=variability, start=values.get("start"),
        description=sv.get("description", "") or "", unit=attrs.get("unit", "") or "",
        initial=sv.get("initial", "") or "", declared_type=declared,
        min=values.get("min"), max=values.get("max"),
        nominal=_number("Real", attrs.get("nominal")), items=types.get(declared, ({}, ()))[1],
        choices=_choices(sv) if type_el.tag == "String" else (),
        derivative=_derivative(path, name, type_el.get("derivative")) if type_el.tag == "Real" else None)


def _shown(text: str) -> str:
    return repr(text if len(text) <= 40 else text[:40] + "...")


def _integer(text: str) -> int | None:
    """An xs:unsignedInt (whitespace around it and a leading '+' allowed) as int, else None."""
    t = text.strip()
    t = t[1:] if t.startswith("+") else t
    return int(t) if 0 < len(t) <= 10 and t.isascii() and t.isdigit() else None


def _derivative(path: Path, name: str, text: str | None) -> int | None:
    """The ``derivative`` attribute of a Real: the index of a ScalarVariable (its range is
    checked with the ModelStructure, when the number of variables is known)."""
    if text is None:
        return None
    value = _integer(text)
    if value is None:
        raise _fail(path, f"variable {name!r}: derivative {_shown(text)} is not a ScalarVariable index (a "
                          "positive integer)", "re-export the FMU with a valid model description")
    return value


_INT32 = (-2**31, 2**31 - 1)                # fmi2Integer: a C int (FMI 2.0 sec. 2.1.2)
_BOOLEAN_TEXT = ("true", "false", "1", "0")  # xs:boolean


def _check_attributes(path: Path, name: str, type_: str, attrs: dict) -> dict:
    """The start, min, max and nominal of variable ``name`` are values of its type (an
    unreadable one was dropped, or shown as text, before), and min <= max: a model description
    that breaks this is refused with the variable, the attribute and the value. Returns the
    numbers read (``{attribute: float or int}`` of a Real, Integer or Enumeration)."""
    fix = "re-export the FMU with a valid model description"
    numeric = ("start", "min", "max", "nominal") if type_ == "Real" else ("start", "min", "max")
    values = {}
    for key in numeric if type_ in ("Real", "Integer", "Enumeration") else ("start",):
        text = attrs.get(key)
        if text is None or (key == "start" and type_ == "String"):
            continue
        shown = text if len(text) <= 40 else text[:40] + "..."
        if type_ == "Boolean":
            if text.strip().lower() not in _BOOLEAN_TEXT:
                raise _fail(path, f"variable {name!r}: start {shown!r} is not a Boolean (true, false, 1 or 0)", fix)
            continue
        try:
            value = float(text) if type_ == "Real" or key == "nominal" else int(text.strip())
        except ValueError:
            kind = "a number" if type_ == "Real" else "an integer"
            raise _fail(path, f"variable {name!r} ({type_}): {key} {shown!r} is not {kind}", fix) from None
        if type_ != "Real" and not _INT32[0] <= value <= _INT32[1]:
            raise _fail(path, f"variable {name!r} ({type_}): {key} {shown} is outside the 32-bit integers of "
                              f"FMI 2.0 [{_INT32[0]}, {_INT32[1]}]", fix)
        values[key] = value
    if "min" in values and "max" in values and values["min"] > values["max"]:
        raise _fail(path, f"variable {name!r}: min {values['min']!r} is greater than max {values['max']!r}", fix)
    return values


MAX_CHOICES = 1000


def _choices(sv) -> tuple[str, ...]:
    """The values a String variable accepts, when its FMU declares them in a tool annotation
    (FMI 2.0 sec. 2.2.7 allows ``<Annotations>`` in a ScalarVariable; FMI 2.0 itself cannot
    declare them)::

        <Annotations><Tool name="rotorcosim"><Choices>
          <Choice value="band"/><Choice value="lapack"/></Choices></Tool></Annotations>

    Other importers ignore it. () when there is none (any text is accepted)."""
    ann = sv.find("Annotations")
    tool = next((t for t in (ann if ann is not None else []) if t.tag == "Tool" and t.get("name") == "rotorcosim"),
                None)
    if tool is None:
        return ()
    return tuple(c.get("value") for c in tool.iter("Choice") if c.get("value") is not None)[:MAX_CHOICES]


# --------------------------------------------------------------------------- names of switch values
MAX_VALUE_NAMES = 32               # values of one switch that get names
MAX_VALUE_NAME_CHARS = 40          # one name
MAX_VALUE_LIST_CHARS = 2048        # the list, brackets included (32 of the longest items fit)
_NAMED_VALUE = re.compile(r"\s*(-?[0-9]{1,10})\s*=(.*)", re.DOTALL)
_NOT_IN_NAMES = frozenset("(),=")


def value_names(var: Variable) -> dict[int, str]:
    """``{value: name}`` of the values of an Integer switch as its FMU declares them, or of an
    Enumeration's items; ``{}`` when there is no declaration, or a malformed one.

    An Integer declares them at the end of its ``description`` (docs/fmus.md, "Names of switch
    values"): a parenthesised, comma-separated list of ``VALUE = NAME`` as the last thing in
    it, e.g. ``cavitation model: ... (0 = half-Sommerfeld, 1 = mass-conserving)``. FMI 2.0 has
    no other place for them (a ``<SimpleType>`` with ``<Item>``s belongs to Enumeration
    variables only). Parsed strictly, as the model description is untrusted: at least two and at
    most :data:`MAX_VALUE_NAMES` items, each value a decimal 32-bit integer, each name a
    printable text of at most :data:`MAX_VALUE_NAME_CHARS` characters without ``( ) , =``, no
    value and no name twice; anything else gives no names (never an error: the names label a
    plot axis, nothing depends on them). The list, brackets included, is at most
    :data:`MAX_VALUE_LIST_CHARS` characters; only that much of the end of a description is read,
    whatever its length.

    An Enumeration's names are the ``<Item>`` names of its declared type, by the same rules
    (at least one item)."""
    if var.type == "Enumeration":
        if len(var.items) > MAX_VALUE_NAMES:
            return {}
        return checked_value_names([(value, name) for name, value, _ in var.items], least=1)
    if var.type != "Integer":
        return {}
    text = var.description[-MAX_VALUE_LIST_CHARS:].rstrip()   # a name can hold no '(': the last one opens
    start = text.rfind("(")                                   # the list, and a list is no longer than this
    if start < 0 or not text.endswith(")"):
        return {}
    pairs = []
    for item in text[start + 1:-1].split(","):
        m = _NAMED_VALUE.fullmatch(item)
        if m is None:
            return {}
        pairs.append((int(m.group(1)), m.group(2).strip()))
    return checked_value_names(pairs)


def checked_value_names(pairs, least: int = 2) -> dict[int, str]:
    """``pairs`` ((value, name), ...) as ``{value: name}`` when they follow the rules of
    :func:`value_names` (at least ``least`` of them), else ``{}``. Also for the names a
    sweep.json carries (``orchestrator.sweep.plot``)."""
    out: dict[int, str] = {}
    for value, name in pairs:
        if (isinstance(value, bool) or not isinstance(value, int) or not _INT32[0] <= value <= _INT32[1]
                or value in out or not is_value_name(name)):
            return {}
        out[value] = name
    if not least <= len(out) <= MAX_VALUE_NAMES or len(set(out.values())) != len(out):
        return {}
    return out


def is_value_name(name) -> bool:
    """A name of a switch value may label a plot axis: a printable text (no control, format or
    separator characters other than the space) of 1 to :data:`MAX_VALUE_NAME_CHARS` characters,
    without blanks around it and without ``( ) , =``."""
    return (isinstance(name, str) and 0 < len(name) <= MAX_VALUE_NAME_CHARS and name == name.strip()
            and name.isprintable() and not _NOT_IN_NAMES.intersection(name))


# --------------------------------------------------------------------------- ModelStructure
DEPENDENCY_KINDS = ("dependent", "constant", "fixed", "tunable", "discrete")
_KIND = {k: k for k in DEPENDENCY_KINDS}
_INDEX_LIST = re.compile(r"[0-9 \t\r\n]*")       # digits and XML whitespace only (a character class: linear)
_SPLIT_CHARS = 2**20                             # attributes up to this size are split at once
_LISTS = ("Outputs", "Derivatives", "InitialUnknowns")
_FIX = "re-export the FMU with a valid model description"


def _model_structure(root, path: Path, variables: list[Variable]) -> ModelStructure:
    """``<ModelStructure>`` (FMI 2.0 sec. 2.2.8), checked against the variables (``variables``
    in file order: ScalarVariable index i is ``variables[i - 1]``).

    Refused (the file is inconsistent, or its indices do not mean what they say):
    an Unknown index or a dependency that is no integer or outside 1..number of variables, an
    index listed twice in one list, a dependency listed twice in one Unknown, a
    dependenciesKind whose number of entries differs from the dependencies' or with an entry
    other than dependent/constant/fixed/tunable/discrete, an Outputs entry that is no output,
    an output missing from a non-empty Outputs, a Derivatives entry that is no Real with a
    ``derivative`` attribute, a ``derivative`` outside 1..number of variables, a list given
    twice, more than :data:`MAX_DEPENDENCIES` dependencies in all.

    Accepted as written (common in real FMUs, harmless here; the master does not use the
    structure): no ModelStructure, no or an empty Outputs (every output may then depend on
    every input), InitialUnknowns missing or not listing what FMI 2.0 asks, unsorted
    dependencies, dependencies on variables that are not Knowns, an empty dependenciesKind
    without dependencies, other elements (e.g. the ``<DiscreteStates>`` of old OpenModelica
    exports). The work is linear in the size of the file."""
    n = len(variables)
    for v in variables:
        if v.derivative is not None and not 1 <= v.derivative <= n:
            raise _fail(path, f"variable {v.name!r}: derivative {v.derivative} is outside 1..{n} (it is the index "
                              "of a ScalarVariable, counted from 1 in file order)", _FIX)
    ms = root.find("ModelStructure")
    lists: dict[str, tuple[Unknown, ...]] = {}
    budget = [MAX_DEPENDENCIES]
    ints = list(range(n + 1))         # one int object per index, shared by every dependency
    for el in (ms if ms is not None else []):
        if el.tag not in _LISTS:
            continue
        if el.tag in lists:
            raise _fail(path, f"<ModelStructure> has more than one <{el.tag}> element", _FIX)
        lists[el.tag] = _unknowns(el, path, variables, ints, budget)
    outputs = lists.get("Outputs", ())
    for u in outputs:
        c = variables[u.index - 1].causality
        if c != "output":
            raise _fail(path, f"ModelStructure/Outputs: Unknown index {u.index} is variable {u.name!r} of causality "
                              f"{c!r}; every Outputs entry must be a variable of causality 'output' (FMI 2.0 sec. "
                              "2.2.8)", _FIX)
    if outputs:
        listed = {u.index for u in outputs}
        missing = [(i, v.name) for i, v in enumerate(variables, 1) if v.causality == "output" and i not in listed]
        if missing:
            shown = ", ".join(f"{name!r} (index {i})" for i, name in missing[:5])
            more = f" and {len(missing) - 5} more" if len(missing) > 5 else ""
            raise _fail(path, f"ModelStructure/Outputs does not list the output{'s' if len(missing) > 1 else ''} "
                              f"{shown}{more}; it must have one Unknown per variable of causality 'output' "
                              "(FMI 2.0 sec. 2.2.8)", _FIX)
    for u in lists.get("Derivatives", ()):
        v = variables[u.index - 1]
        if v.derivative is None:
            raise _fail(path, f"ModelStructure/Derivatives: Unknown index {u.index} is variable {u.name!r}, which "
                              "is no state derivative (expected a Real with a derivative attribute)", _FIX)
    return ModelStructure(outputs=outputs, derivatives=lists.get("Derivatives", ()),
                          initial_unknowns=lists.get("InitialUnknowns", ()))


def _unknowns(el, path: Path, variables: list[Variable], ints: list[int], budget: list[int]) -> tuple[Unknown, ...]:
    """The ``<Unknown>`` children of one ModelStructure list, each checked (see
    :func:`_model_structure`); ``budget[0]``: dependencies still allowed."""
    n = len(variables)
    where = f"ModelStructure/{el.tag}"
    seen: set[int] = set()
    out = []
    for u in el:
        if u.tag != "Unknown":
            continue
        text = u.get("index")
        if text is None:
            raise _fail(path, f"{where}: an Unknown has no index attribute", _FIX)
        index = _integer(text)
        if index is None:
            raise _fail(path, f"{where}: Unknown index {_shown(text)} is not a positive integer", _FIX)
        if not 1 <= index <= n:
            raise _fail(path, f"{where}: Unknown index {index} is outside 1..{n} (the ScalarVariables, counted from "
                              "1 in file order)", _FIX)
        name = variables[index - 1].name
        if index in seen:
            raise _fail(path, f"{where}: Unknown index {index} ({name!r}) is listed twice", _FIX)
        seen.add(index)
        what = f"{where}: Unknown index {index} ({name!r})"
        deps = _dependencies(path, what, u.get("dependencies"), n, ints, budget)
        kinds = _kinds(path, what, u.get("dependenciesKind"), deps)
        out.append(Unknown(index=index, name=name, dependencies=deps, dependencies_kind=kinds))
    return tuple(out)


def _dependencies(path: Path, what: str, text: str | None, n: int, ints: list[int],
                  budget: list[int]) -> tuple[int, ...] | None:
    if text is None:
        return None
    if len(text) <= _SPLIT_CHARS and _INDEX_LIST.fullmatch(text):    # the usual case, at C speed
        toks = text.split()
        if not toks:
            return ()
        if len(toks) <= budget[0] and max(map(len, toks)) <= 10:
            values = list(map(int, toks))
            if 1 <= min(values) and max(values) <= n and len(set(values)) == len(values):
                budget[0] -= len(values)
                return tuple(map(ints.__getitem__, values))
    deps = []                                       # else token by token, to say which one is wrong
    seen = set()
    for m in re.finditer(r"\S+", text):           # one token at a time: no list of a 30 MB attribute's words
        budget[0] -= 1
        if budget[0] < 0:
            raise _fail(path, f"<ModelStructure> declares more than {MAX_DEPENDENCIES} dependencies",
                        "raise orchestrator.fmi.model_description.MAX_DEPENDENCIES if you trust this FMU")
        tok = m.group()
        k = _integer(tok)
        if k is None:
            raise _fail(path, f"{what}: dependencies entry {_shown(tok)} is not a ScalarVariable index (a positive "
                              "integer)", _FIX)
        if not 1 <= k <= n:
            raise _fail(path, f"{what}: dependencies entry {k} is outside 1..{n} (the ScalarVariables, counted from "
                              "1 in file order)", _FIX)
        if k in seen:
            raise _fail(path, f"{what}: dependencies lists index {k} twice", _FIX)
        seen.add(k)
        deps.append(ints[k])
    return tuple(deps)


def _kinds(path: Path, what: str, text: str | None, deps: tuple[int, ...] | None) -> tuple[str, ...] | None:
    if text is None:
        return None
    if deps is None:
        if text.strip():
            raise _fail(path, f"{what}: has a dependenciesKind but no dependencies (FMI 2.0: dependenciesKind "
                              "needs dependencies with as many entries)", _FIX)
        return None
    if len(text) <= _SPLIT_CHARS:
        toks = text.split()
        if len(toks) == len(deps) and all(map(_KIND.__contains__, toks)):
            return tuple(map(_KIND.__getitem__, toks))
    kinds = []                                      # else token by token, to say which one is wrong
    count = 0
    for m in re.finditer(r"\S+", text):
        count += 1
        if count > len(deps):                       # only counted from here on (the attribute may be huge)
            continue
        kind = _KIND.get(m.group())                 # the shared constant, not one string per entry
        if kind is None:
            raise _fail(path, f"{what}: dependenciesKind entry {_shown(m.group())} is not one of "
                              f"{', '.join(DEPENDENCY_KINDS)}", _FIX)
        kinds.append(kind)
    if count != len(deps):
        raise _fail(path, f"{what}: dependenciesKind has {count} entries, dependencies {len(deps)}; they must "
                          "have the same number (one kind per dependency)", _FIX)
    return tuple(kinds)
