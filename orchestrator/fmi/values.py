"""Typed FMI 2.0 values: which variables a master may set, conversion and range checks, typed batches.

Rules (FMI 2.0.4 standard, sec. 2.2.7 "Definition of Model Variables" and the
co-simulation state machine of sec. 4.2.4):

* Before ``fmi2EnterInitializationMode`` (state *instantiated*) a master may
  call ``fmi2SetXXX`` on every variable with ``variability != "constant"`` that
  has ``initial = "exact"`` or ``"approx"``, and on inputs (which have no
  ``initial``; their ``start`` is required). Parameters default to
  ``initial="exact"``; outputs and locals default to ``"calculated"`` (not
  settable) unless the FMU declares ``exact``/``approx`` for them (states with
  start values, e.g. ``initial="exact"`` outputs). ``independent`` variables
  (time) and ``calculatedParameter`` with the default ``calculated`` are not
  settable. :func:`settable_problem` says why a variable is not settable.
* :func:`check_value` converts a scenario value to the variable's Python type
  and checks it against the declared type: ``min``/``max`` (of the variable,
  else of its ``declaredType``), the items of an Enumeration type, the 32-bit
  range of ``fmi2Integer`` (C ``int``), a finite Real, and the values a String accepts
  when the FMU declares them (a ``rotorcosim`` tool annotation, see
  :func:`orchestrator.fmi.model_description._choices`). A problem is returned as text
  naming the variable, the declared range and the value.

:class:`TypedBatch` holds value references and a ctypes value buffer for one
FMI type (Real, Integer/Enumeration, Boolean, String), made once at setup so
the step loop allocates nothing; ``Subsystem.set_values``/``get_values`` call
``fmi2SetXXX``/``fmi2GetXXX`` with it.
"""

from __future__ import annotations

import ctypes
import math
from typing import Any, Sequence

import numpy as np

from orchestrator.untrusted import surrogate_problem, terminal_text

INT32_MIN, INT32_MAX = -2**31, 2**31 - 1      # fmi2Integer is a C int (FMI 2.0 sec. 2.1.2, fmi2TypesPlatform.h)

FMI_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")

# the FMI function family of each variable type (Enumeration travels as fmi2Integer)
FAMILY = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean", "String": "String"}

_EXAMPLE = {"Real": "1.5", "Integer": "3", "Enumeration": "1 (or an item name)", "Boolean": "true",
            "String": '"text"'}


def default_initial(var) -> str:
    """The ``initial`` of ``var`` as declared, else the FMI 2.0 default for its causality/variability.

    FMI 2.0 sec. 2.2.7, table of allowed ``initial`` values: parameter -> exact;
    calculatedParameter -> calculated; input, independent -> none ("");
    output/local: constant -> exact, otherwise calculated.
    """
    if var.initial:
        return var.initial
    if var.causality == "parameter":
        return "exact"
    if var.causality in ("input", "independent"):
        return ""
    if var.variability == "constant":
        return "exact"
    return "calculated"


def settable_problem(var) -> str | None:
    """Why ``var`` cannot be given a value before initialization, or None if it can."""
    if var.variability == "constant":
        return "a constant (FMI 2.0 forbids setting constants)"
    if var.causality == "independent":
        return "the independent variable (time), which the master sets through fmi2DoStep"
    if var.causality == "input":
        return None
    init = default_initial(var)
    if init in ("exact", "approx"):
        return None
    what = f"{var.variability} {var.causality}"
    return (f"a {what} with initial=\"{init}\" (computed by the FMU); FMI 2.0 lets a master set only parameters, "
            "inputs and variables with initial=\"exact\" or \"approx\"")


#: below this a declared Real min is read as "greater than 0" (our FMUs declare 5e-324)
POSITIVE_MIN = 1e-300


def declared_range(var) -> str:
    """The declared value set of ``var`` as text, e.g. ``[0, 10]``, ``{Off=0, On=1}``, ``32-bit integers``."""
    if var.type == "Enumeration" and var.items:
        return "{" + ", ".join(f"{n}={v}" for n, v, _ in var.items) + "}"
    lo = var.min if var.min is not None else ("-inf" if var.type == "Real" else INT32_MIN)
    hi = var.max if var.max is not None else ("inf" if var.type == "Real" else INT32_MAX)
    if var.type == "Real" and var.min is not None and 0.0 < var.min <= POSITIVE_MIN:
        # min = the smallest positive double: how an FMU says "> 0" (FMI's min is inclusive)
        return f"(0, {hi}]" if var.max is not None else "(0, inf)"
    if var.type in ("Real", "Integer", "Enumeration"):
        return f"[{lo}, {hi}]"
    return {"Boolean": "true/false", "String": "a string"}.get(var.type, "?")


def _as_type(value, fmi_type: str):
    """``value`` as the Python type of ``fmi_type``, or None if it does not fit (no range check)."""
    if fmi_type == "Real":
        if isinstance(value, bool):
            return None
        if isinstance(value, (int, float, np.integer, np.floating)):
            return float(value)
        return None
    if fmi_type in ("Integer", "Enumeration"):
        if isinstance(value, bool):
            return None
        if isinstance(value, (float, np.floating)) and float(value).is_integer():
            return int(value)
        return int(value) if isinstance(value, (int, np.integer)) else None
    if fmi_type == "Boolean":
        return bool(value) if isinstance(value, (bool, np.bool_)) else None
    if fmi_type == "String":
        return value if isinstance(value, str) else None
    return None


def check_value(var, value: Any, qualified: str) -> tuple[Any, str | None]:
    """Convert ``value`` for ``var`` (``qualified`` is e.g. ``"osc.x0"``); return ``(value, None)`` or
    ``(None, problem)``. Enumeration values may be given as an item name."""
    t = var.type
    if t == "Enumeration" and isinstance(value, str) and var.items:
        for name, v, _ in var.items:
            if name == value:
                return v, None
        return None, (f"'{qualified}' is an Enumeration of type {var.declared_type or '?'} with items "
                      f"{declared_range(var)}; got {value!r}, which is not an item name: give one of them")
    conv = _as_type(value, t)
    if conv is None:
        return None, (f"'{qualified}' is {t} (got {value!r}, {type(value).__name__}); give a {t} value "
                      f"such as {_EXAMPLE.get(t, 'a value')}")
    if t == "String" and "\0" in conv:
        i = conv.index("\0")
        return None, (f"'{qualified}' is String and holds a NUL character (\\0, character {i + 1}), which ends "
                      f"the text for the FMU (fmi2SetString takes a C string: it would get "
                      f"{_short(conv[:i])}); remove it")
    if t == "String" and (why := surrogate_problem(conv, yaml_fix=False)) is not None:
        return None, f"'{qualified}' is String and the text {why}; write the character itself"
    if t == "String" and getattr(var, "choices", ()) and conv not in var.choices:
        shown = ", ".join(repr(c) for c in var.choices[:20]) + (", ..." if len(var.choices) > 20 else "")
        return None, (f"'{qualified}' must be one of {shown} (the values the FMU declares); got {conv[:80]!r}: "
                      "give one of them")
    if t == "Real" and not math.isfinite(conv):
        return None, f"'{qualified}' is Real and must be finite (got {conv!r}); give a finite number"
    if t in ("Integer", "Enumeration") and not INT32_MIN <= conv <= INT32_MAX:
        return None, (f"'{qualified}' is {t}, a 32-bit integer in [{INT32_MIN}, {INT32_MAX}] (FMI 2.0 fmi2Integer); "
                      f"got {conv}: give a value in that range")
    if t == "Enumeration" and var.items and conv not in {v for _, v, _ in var.items}:
        return None, (f"'{qualified}' is an Enumeration of type {var.declared_type or '?'} with items "
                      f"{declared_range(var)}; got {conv}, which is not an item value: give one of them")
    if t in ("Real", "Integer", "Enumeration"):
        lo, hi = var.min, var.max
        if (lo is not None and conv < lo) or (hi is not None and conv > hi):
            return None, (f"'{qualified}' = {conv!r} is outside its declared range {declared_range(var)} "
                          f"(min/max{' of type ' + var.declared_type if var.declared_type else ''}); "
                          f"give a value inside the range{_what_it_is(var)}")
    return conv, None


def _what_it_is(var, n: int = 300) -> str:
    """``"; it is <description> [unit]"`` of ``var`` for a range error, so that the user sees what
    the number means and in which unit (psi is C/R, not per mille; R is in m, not mm); the FMU's
    text shown escaped and cut at ``n`` characters. Empty when the FMU declares neither."""
    desc = terminal_text(" ".join((getattr(var, "description", "") or "").split()))
    unit = terminal_text(getattr(var, "unit", "") or "")
    if len(desc) > n:
        desc = desc[:n] + "..."
    if unit and unit != "1" and "[" not in desc and desc:       # a description such as "radius R [m]" has it
        desc += f" (unit {unit})"
    elif unit and not desc:
        desc = f"in {unit}"
    return f"; '{var.name}' is: {desc}" if desc else ""


def _short(text: str, n: int = 40) -> str:
    return repr(text) if len(text) <= n else repr(text[:n]) + "..."


class TypedBatch:
    """Value references and a ctypes buffer for batched ``fmi2Set/GetXXX`` of one type family.

    ``family`` is "Real", "Integer" (Integer and Enumeration), "Boolean" or
    "String". ``values`` is a numpy view of the buffer for Real (float64) and
    Integer/Boolean (int32); String batches keep ``c_values`` (``char*``) and
    :meth:`strings`/:meth:`set_strings` convert.
    """

    __slots__ = ("family", "names", "n", "c_vrs", "c_values", "values", "_keep")

    _CTYPE = {"Real": ctypes.c_double, "Integer": ctypes.c_int, "Boolean": ctypes.c_int,
              "String": ctypes.c_char_p}

    def __init__(self, family: str, names: Sequence[str], vrs: Sequence[int]):
        if family not in self._CTYPE:
            raise ValueError(f"unknown FMI type family {family!r}; expected one of {list(self._CTYPE)}")
        self.family = family
        self.names = tuple(names)
        self.n = len(vrs)
        self.c_vrs = (ctypes.c_uint * max(self.n, 1))(*[int(v) for v in vrs])
        self.c_values = (self._CTYPE[family] * max(self.n, 1))()
        self._keep: list[bytes] = []
        if family == "String":
            self.values = None
            for i in range(self.n):
                self.c_values[i] = b""
        else:
            self.values = np.ctypeslib.as_array(self.c_values)[: self.n]

    def own_strings(self) -> list[tuple[str, str]]:
        """After fmi2GetString: replace every char* the FMU handed over by a copy of our own, read
        without trusting the pointer (:func:`orchestrator.fmi.safe_log.copy_string`), so that no
        later read dereferences it (an unreadable pointer crashed the process that read it). NULL
        stays NULL. Returns ``[(variable, what was wrong)]`` for the values that could not be read
        whole; without the safe library nothing is done (the pointers are read as before)."""
        from orchestrator.fmi.safe_log import copy_string
        raw = ctypes.cast(self.c_values, ctypes.POINTER(ctypes.c_void_p))
        wrong = []
        for k in range(self.n):
            address = raw[k]
            if not address:
                continue
            data, why = copy_string(address)
            if data is None:
                return wrong
            self.c_values[k] = data          # ctypes keeps the bytes alive with the array
            if why:
                wrong.append((self.names[k], why))
        return wrong

    def strings(self, keep_null: bool = False) -> list[str | None]:
        """The String values (after a get), decoded as UTF-8; a NULL pointer reads as "" (None
        with ``keep_null``: the worker passes it on, so that the master can report it)."""
        return [None if b is None and keep_null else (b or b"").decode("utf-8", "replace")
                for b in self.c_values[: self.n]]

    def set_strings(self, values: Sequence[str | None]) -> None:
        """Put String values into the buffer (kept alive until the next call); None puts a NULL
        pointer (what an FMU gave, see :meth:`strings`)."""
        self._keep = [None if v is None else str(v).encode("utf-8") for v in values]
        for i, b in enumerate(self._keep):
            self.c_values[i] = b


def batch_for(variables: Sequence, family: str) -> TypedBatch:
    """A :class:`TypedBatch` of ``family`` for model variables (all of that family)."""
    bad = [v.name for v in variables if FAMILY.get(v.type) != family]
    if bad:
        raise ValueError(f"variables {bad} are not of the {family} family")
    return TypedBatch(family, [v.name for v in variables], [v.value_reference for v in variables])
