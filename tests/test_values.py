"""Typed values before initialization: which variables are settable, conversion and range checks."""

from __future__ import annotations

import math

import pytest

from orchestrator.fmi.values import (INT32_MAX, TypedBatch, check_value, declared_range, default_initial,
                                     settable_problem)
from orchestrator.fmi.archive import Variable, parse_model_description


def V(name="v", type="Real", causality="parameter", variability="fixed", **kw):
    return Variable(name, 1, type, causality, variability, **kw)


@pytest.mark.parametrize("var, settable", [
    (V(), True),
    (V(causality="input", variability="continuous"), True),
    (V(causality="output", variability="continuous"), False),                  # initial calculated
    (V(causality="output", variability="continuous", initial="exact"), True),  # a state with a start value
    (V(causality="local", variability="continuous", initial="approx"), True),
    (V(causality="calculatedParameter"), False),
    (V(causality="local", variability="constant"), False),
    (V(causality="independent", variability="continuous"), False),
])
def test_settable_follows_fmi2_initial_rules(var, settable):
    assert (settable_problem(var) is None) is settable


def test_default_initial_table():
    assert default_initial(V()) == "exact"
    assert default_initial(V(causality="output", variability="constant")) == "exact"
    assert default_initial(V(causality="output", variability="discrete")) == "calculated"
    assert default_initial(V(causality="input", variability="continuous")) == ""


def test_real_range_and_finite():
    v = V(min=0.0, max=10.0)
    assert check_value(v, 3, "a.v") == (3.0, None)
    val, msg = check_value(v, 11.0, "a.v")
    assert val is None and "'a.v'" in msg and "[0.0, 10.0]" in msg and "11.0" in msg
    for bad in (math.inf, math.nan):
        assert "finite" in check_value(V(), bad, "a.v")[1]
    assert "Real" in check_value(V(), "abc", "a.v")[1]
    assert "Real" in check_value(V(), True, "a.v")[1]


def test_integer_32_bit_and_bounds():
    v = V(type="Integer", max=5)
    assert check_value(v, 4.0, "a.n") == (4, None)
    assert "[-2147483648, 5]" in check_value(v, 6, "a.n")[1]
    _, msg = check_value(V(type="Integer"), INT32_MAX + 1, "a.n")
    assert "32-bit" in msg and str(INT32_MAX + 1) in msg
    assert "Integer" in check_value(V(type="Integer"), 2.5, "a.n")[1]


def test_enumeration_items_by_value_or_name():
    v = V(type="Enumeration", declared_type="Mode", items=(("Off", 1, ""), ("On", 2, "")))
    assert check_value(v, 2, "a.m") == (2, None)
    assert check_value(v, "On", "a.m") == (2, None)
    _, msg = check_value(v, 3, "a.m")
    assert "{Off=1, On=2}" in msg and "3" in msg
    assert "not an item name" in check_value(v, "Auto", "a.m")[1]


def test_boolean_and_string():
    assert check_value(V(type="Boolean"), True, "a.b") == (True, None)
    assert "Boolean" in check_value(V(type="Boolean"), 1, "a.b")[1]
    assert check_value(V(type="String"), "x", "a.s") == ("x", None)
    assert declared_range(V(type="Boolean")) == "true/false"


MD = b"""<?xml version="1.0"?>
<fmiModelDescription fmiVersion="2.0" modelName="m" guid="{x}">
  <CoSimulation modelIdentifier="m"/>
  <UnitDefinitions><Unit name="m/s"/></UnitDefinitions>
  <TypeDefinitions>
    <SimpleType name="Speed"><Real unit="m/s" min="0" max="100" nominal="10"/></SimpleType>
    <SimpleType name="Mode"><Enumeration><Item name="Off" value="1"/><Item name="On" value="2"/></Enumeration>
    </SimpleType>
  </TypeDefinitions>
  <ModelVariables>
    <ScalarVariable name="v" valueReference="0" causality="output" variability="continuous" initial="exact">
      <Real declaredType="Speed" start="1" max="50"/></ScalarVariable>
    <ScalarVariable name="mode" valueReference="1" causality="parameter" variability="fixed">
      <Enumeration declaredType="Mode" start="1"/></ScalarVariable>
  </ModelVariables>
</fmiModelDescription>"""


def test_model_description_reads_declared_types():
    md = parse_model_description(MD)
    v = md.variables["v"]
    assert (v.unit, v.min, v.max, v.nominal, v.initial) == ("m/s", 0.0, 50.0, 10.0, "exact")
    assert settable_problem(v) is None
    assert "outside its declared range [0.0, 50.0]" in check_value(v, 60.0, "x.v")[1]
    m = md.variables["mode"]
    assert m.items == (("Off", 1, ""), ("On", 2, "")) and m.declared_type == "Mode"


def test_typed_batches():
    b = TypedBatch("Integer", ["a", "b"], [3, 4])
    b.values[:] = [7, -1]
    assert list(b.c_values[:2]) == [7, -1]
    s = TypedBatch("String", ["s"], [0])
    assert s.strings() == [""]
    s.set_strings(["hé"])
    assert s.strings() == ["hé"]
    with pytest.raises(ValueError):
        TypedBatch("Float", ["x"], [0])
