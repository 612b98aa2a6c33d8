"""The names of a switch's values on a sweep plot come from the FMU's own declaration (the end of
the variable's description, docs/fmus.md "Names of switch values"), not from a table of our
bearing's switches.

Before: orchestrator/sweep/plot.py had SWITCH_NAMES, our bearing's switch values matched by the
parameter's *name*: a third-party FMU's Integer ``contact`` got "no contact (0)" and "asperity
contact (1)" on its axis, and a new switch of our FMUs needed an edit of the plotting module.
Now the sweep asks the FMU of the swept instance (``sweep_labels``) and records the names in
sweep.json; the plot draws them. The test FMUs ``Switches`` (Integer ``contact`` without names,
``cavitation``/``axial_bc``/``theta_transport`` with malformed ones) and ``NamedSwitches``
(``contact``: 0 = open, 1 = slipping, 2 = locked) are in tests/fmus_src.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from orchestrator.fmi.model_description import Variable, parse_model_description

REPO = Path(__file__).resolve().parents[1]
MAX_VALUE_NAMES = 32              # orchestrator.fmi.model_description.MAX_VALUE_NAMES


def value_names(var: Variable) -> dict:
    from orchestrator.fmi.model_description import value_names
    return value_names(var)


def test_the_limits_are_those_documented():
    from orchestrator.fmi import model_description as md
    assert (md.MAX_VALUE_NAMES, md.MAX_VALUE_NAME_CHARS, md.MAX_VALUE_LIST_CHARS) == (MAX_VALUE_NAMES, 40, 2048)


def _integer(description: str, type_: str = "Integer", items: tuple = ()) -> Variable:
    return Variable("s", 1, type_, "parameter", "fixed", description=description, items=items)


# ------------------------------------------------------------------ the declaration, parsed strictly
@pytest.mark.parametrize("description, names", [
    ("cavitation model: ... (0 = half-Sommerfeld, 1 = mass-conserving)", {0: "half-Sommerfeld", 1: "mass-conserving"}),
    ("gear (a text in brackets) of the box (-1 = reverse, 0 = neutral, 1 = first)  \n",
     {-1: "reverse", 0: "neutral", 1: "first"}),                      # negative values; blanks after it
    ("(0=off,1=on)", {0: "off", 1: "on"}),                           # the blanks are optional
    ("(7 = b, 2 = a)", {7: "b", 2: "a"}),                            # any order, any values
    ("x (" + ", ".join(f"{i} = v{i}" for i in range(MAX_VALUE_NAMES)) + ")",
     {i: f"v{i}" for i in range(MAX_VALUE_NAMES)}),
    ("(0 = " + "n" * 40 + ", 1 = b)", {0: "n" * 40, 1: "b"}),
    ("(-2147483648 = low, 2147483647 = high)", {-2**31: "low", 2**31 - 1: "high"}),
])
def test_a_declared_list_of_names_is_read(description, names):
    assert value_names(_integer(description)) == names


@pytest.mark.parametrize("description", [
    "", "cavitation model: 0 half-Sommerfeld (quasi-static), 1 mass-conserving two-phase (transient)",  # the old prose
    "(0 = half-Sommerfeld)",                    # one value is no switch
    "(0 = a, 1 = b) and then more text",        # not at the end
    "(0 = a, 0 = b)", "(0 = a, 1 = a)",         # a value or a name twice
    "(0 = a, one = b)", "(0.5 = a, 1 = b)", "(+1 = a, 2 = b)", "(0x1 = a, 2 = b)", "(١ = a, 2 = b)",
    "(0 = a, 1 = )", "(0 = a,  = b)", "(0 = a, 1)", "(0 = a,, 1 = b)", "(0 = a, 1 = b,)",
    "(0 = a, 1 = b = c)", "(0 = a, 1 = b (c))", "(0 = a, 1 = b", "0 = a, 1 = b)", "()", "(,)",
    "(0 = a, 2147483648 = b)", "(0 = a, 12345678901 = b)", "(0 = a, -2147483649 = b)",
    "(0 = a, 1 = " + "x" * 41 + ")",            # a name too long
    "(0 = a, 1 = b\tc)", "(0 = a, 1 = b\nc)", "(0 = a, 1 = b\u202ec)", "(0 = a, 1 = b\u00a0c)", "(0 = a, 1 = \x00)",
    "(" + ", ".join(f"{i} = v{i}" for i in range(MAX_VALUE_NAMES + 1)) + ")",    # too many
    "(0 = a, 1 = " + " " * 3000 + "b)",         # longer than a list can be
    "(e.g. 0.012 for 12 mPa s = 12 cP)", "(asperity contact, contact = 1)", "(contact = 1)",
])
def test_a_malformed_list_gives_no_names(description):
    assert value_names(_integer(description)) == {}


def test_only_the_end_of_a_long_description_is_read():
    """A 32 MB description (the largest a model description may be) costs no more than a short one."""
    import time
    long = "x" * 32_000_000
    t0 = time.perf_counter()
    assert value_names(_integer(long + " (0 = a, 1 = b)")) == {0: "a", 1: "b"}
    assert value_names(_integer("(" * 16_000_000 + ")" * 16_000_000)) == {}
    assert value_names(_integer(long + ")")) == {}
    assert time.perf_counter() - t0 < 1.0


def test_only_integers_and_enumerations_have_names():
    for type_ in ("Real", "Boolean", "String"):
        assert value_names(_integer("(0 = a, 1 = b)", type_)) == {}
    items = (("open", 0, ""), ("closed", 1, "the valve is shut"))
    assert value_names(_integer("", "Enumeration", items)) == {0: "open", 1: "closed"}
    assert value_names(_integer("(0 = a, 1 = b)", "Enumeration", items)) == {0: "open", 1: "closed"}
    assert value_names(_integer("", "Enumeration", (("a\nb", 0, ""), ("c", 1, "")))) == {}
    assert value_names(_integer("", "Enumeration", (("a", 0, ""), ("b", 0, "")))) == {}
    many = tuple((f"i{k}", k, "") for k in range(MAX_VALUE_NAMES + 1))
    assert value_names(_integer("", "Enumeration", many)) == {}


def test_the_names_are_read_from_the_model_description_xml():
    """Through the parser of untrusted model descriptions: escapes are decoded before the rules
    apply (a line break written as &#10; is a line break in a name: no names)."""
    def md(description: str) -> bytes:
        return ('<?xml version="1.0" encoding="UTF-8"?><fmiModelDescription fmiVersion="2.0" modelName="M" '
                'guid="{1}"><CoSimulation modelIdentifier="M"/><TypeDefinitions><SimpleType name="Valve">'
                '<Enumeration><Item name="open" value="1"/><Item name="shut" value="2"/></Enumeration></SimpleType>'
                '</TypeDefinitions><ModelVariables>'
                f'<ScalarVariable name="contact" valueReference="0" causality="parameter" variability="fixed" '
                f'description="{description}"><Integer start="0"/></ScalarVariable>'
                '<ScalarVariable name="valve" valueReference="1" causality="parameter" variability="fixed">'
                '<Enumeration declaredType="Valve" start="1"/></ScalarVariable>'
                '</ModelVariables></fmiModelDescription>').encode()
    variables = parse_model_description(md("clutch (0 = open, 1 = locked)")).variables
    assert value_names(variables["contact"]) == {0: "open", 1: "locked"}
    assert value_names(variables["valve"]) == {1: "open", 2: "shut"}
    assert value_names(parse_model_description(md("clutch (0 = open&#10;x, 1 = locked)")).variables["contact"]) == {}
    assert value_names(parse_model_description(md("clutch (0 = open &amp; shut, 1 = locked)"))
                       .variables["contact"]) == {0: "open & shut", 1: "locked"}


# ------------------------------------------------------------------ our FMUs declare them
OUR_SWITCHES = {
    "JournalBearing": {
        "cavitation": {0: "half-Sommerfeld", 1: "mass-conserving"},
        "axial_bc": {0: "oil bath", 1: "free to air"},
        "theta_transport": {0: "upwind", 1: "MUSCL"},
        "contact": {0: "no contact", 1: "asperity contact"},
    },
    "FloatingRingBearing": {
        **{f"{name}_{side}": names for side in ("inner", "outer") for name, names in (
            ("cavitation", {0: "half-Sommerfeld", 1: "mass-conserving"}),
            ("axial_bc", {0: "oil bath", 1: "free to air"}),
            ("theta_transport", {0: "upwind", 1: "MUSCL"}))},
        "floating": {0: "semi-floating", 1: "full floating"},
        "input_hold": {0: "zero-order hold", 1: "first-order hold", 2: "cubic Hermite"},
        "ring_integrator": {0: "BDF2", 1: "exponential"},
    },
    "JeffcottRotor": {},
    "TurbochargerRotor": {},
}


@pytest.mark.parametrize("fmu", sorted(OUR_SWITCHES))
def test_our_fmus_name_the_values_of_their_switches(fmu):
    """Every Integer switch of our FMUs names its values in its modelDescription (the names the
    plot table had, and the floating-ring bearing's switches, which it lacked); the counts
    (n_phi, linearize, n_modes, ...) name none. Interface unchanged: Integer parameters."""
    from orchestrator.fmi.archive import read_model_description
    from orchestrator.fmi.build import FMU_DIR
    md = read_model_description(FMU_DIR / f"{fmu}.fmu")
    named = {v.name: value_names(v) for v in md.variables.values() if value_names(v)}
    assert named == OUR_SWITCHES[fmu]
    for name in named:
        var = md.variables[name]
        assert (var.type, var.causality, var.variability) == ("Integer", "parameter", "fixed")
        assert var.start in named[name]


# ------------------------------------------------------------------ the sweep asks the swept FMU
SCENARIO = ("name: switches\nstop_time: 0.02\nfmus:\n  plain: {path: fmus/Switches.fmu}\n"
            "  named: {path: fmus/NamedSwitches.fmu}\ncoupling: {macro_step: 0.01}\n")


@pytest.fixture
def swdir(tmp_path, test_fmus) -> Path:
    (tmp_path / "fmus").mkdir()
    for name in ("Switches", "NamedSwitches"):
        shutil.copy(test_fmus[name], tmp_path / "fmus" / f"{name}.fmu")
    (tmp_path / "sw.yaml").write_text(SCENARIO)
    return tmp_path


def _spec(folder: Path, parameters: str, scenario: str = "sw.yaml"):
    from orchestrator.sweep import load_sweep
    from orchestrator.sweep.plan import expand
    (folder / "sweep.yaml").write_text(f"sweep: 1\nscenario: {scenario}\nparameters:\n{parameters}"
                                       "collect: {steps: macro_steps}\n")
    spec = load_sweep(folder / "sweep.yaml")
    return spec, expand(spec)


def test_the_sweep_records_the_names_the_swept_fmu_declares(swdir):
    from orchestrator.sweep.units import sweep_labels
    spec, runs = _spec(swdir, (
        "  - {name: clutch, set: [fmus.named.parameters.contact], values: [0, 1, 2]}\n"
        "  - {name: contact, set: [fmus.plain.parameters.contact], values: [0, 1]}\n"
        "  - {name: cavitation, set: [fmus.plain.parameters.cavitation], values: [0, 1]}\n"
        "  - {name: axial_bc, set: [fmus.plain.parameters.axial_bc], values: [0, 1]}\n"
        "  - {name: theta_transport, set: [fmus.plain.parameters.theta_transport], values: [0, 1]}\n"
        "  - {name: t_end, set: [stop_time], values: [0.02]}\n"))
    _, _, names = sweep_labels(spec, runs[0].overrides)
    # NamedSwitches' own names; none for Switches' contact (no names), its malformed lists, stop_time
    assert names == {"clutch": {0: "open", 1: "slipping", 2: "locked"}}
    # a parameter set in two FMUs whose names differ (here: one names none) has none
    spec, runs = _spec(swdir, "  - {name: both, set: [fmus.named.parameters.contact, fmus.plain.parameters.contact], "
                              "values: [0, 1]}\n")
    assert sweep_labels(spec, runs[0].overrides)[2] == {}


def test_the_sweep_records_our_bearings_names(tmp_path):
    from orchestrator.sweep.units import sweep_labels
    spec, runs = _spec(tmp_path, (
        "  - {name: cavitation, set: [fmus.bearing1.parameters.cavitation, fmus.bearing2.parameters.cavitation], "
        "values: [0, 1]}\n"
        "  - {name: n_phi, set: [fmus.bearing1.parameters.n_phi], values: [24, 40]}\n"),
        scenario=str(REPO / "scenarios" / "quickstart.yaml"))
    _, _, names = sweep_labels(spec, runs[0].overrides)
    assert names == {"cavitation": {0: "half-Sommerfeld", 1: "mass-conserving"}}


def _ticks(fig):
    ax = next(a for a in fig.axes if a.get_xlabel())
    return [t.get_text() for t in ax.get_xticklabels()], [t.get_text() for t in ax.get_yticklabels()]


@pytest.mark.filterwarnings("ignore:collect")
def test_a_sweep_over_third_party_switches_shows_their_own_names_or_numbers(swdir, figures):
    """A real sweep: the heat map over NamedSwitches' contact (its own names, not our bearing's)
    and Switches' contact (no names: numbers, not "no contact (0)")."""
    from orchestrator.sweep import sweep
    from orchestrator.sweep.plot import plot_sweep
    (swdir / "sweep.yaml").write_text(
        "sweep: 1\nscenario: sw.yaml\nparameters:\n"
        "  - {name: clutch, set: [fmus.named.parameters.contact], values: [0, 2]}\n"
        "  - {name: contact, set: [fmus.plain.parameters.contact], values: [0, 1]}\n"
        "collect: {steps: macro_steps}\n")
    df = sweep(swdir / "sweep.yaml", out_dir=swdir / "o", workers=1)
    assert list(df["status"]) == ["finished"] * 4
    meta = json.loads((swdir / "o" / "sweep.json").read_text())
    assert meta["parameters"][0]["value_names"] == {"0": "open", "1": "slipping", "2": "locked"}
    assert "value_names" not in meta["parameters"][1]
    plot_sweep(swdir / "o")
    assert _ticks(figures[0]) == (["open (0)", "locked (2)"], ["0", "1"])


def _folder(tmp_path: Path, spec, runs, rows) -> Path:
    """The sweep folder the sweep writes (write_table with sweep_labels), for ``rows`` of values."""
    from orchestrator.sweep.table import build_rows, write_table
    from orchestrator.sweep.units import sweep_labels
    out = tmp_path / "o"
    out.mkdir()
    params, collect, names = sweep_labels(spec, runs[0].overrides)
    records = {r.run_id: {"status": "finished", "summary": {"macro_steps": v}, "wall_time_s": 1.0}
               for r, v in zip(runs, rows, strict=True)}
    write_table(build_rows(spec, runs, records, out), spec, out, (params, collect), names)
    return out


def test_malformed_names_leave_the_numbers_on_the_axes(swdir, figures):
    """Switches' cavitation, axial_bc and theta_transport (named as our bearing's switches, with
    malformed lists) and contact (no list)."""
    from orchestrator.sweep.plot import plot_sweep
    spec, runs = _spec(swdir, (
        "  - {name: cavitation, set: [fmus.plain.parameters.cavitation], values: [0, 1]}\n"
        "  - {name: axial_bc, set: [fmus.plain.parameters.axial_bc], values: [0, 1]}\n"))
    plot_sweep(_folder(swdir, spec, runs, [1, 2, 3, 4]))
    assert _ticks(figures[0]) == (["0", "1"], ["0", "1"])
    spec, runs = _spec(swdir, (
        "  - {name: theta_transport, set: [fmus.plain.parameters.theta_transport], values: [0, 1]}\n"
        "  - {name: contact, set: [fmus.plain.parameters.contact], values: [0, 1]}\n"))
    shutil.rmtree(swdir / "o")
    plot_sweep(_folder(swdir, spec, runs, [1, 2, 3, 4]))
    assert _ticks(figures[1]) == (["0", "1"], ["0", "1"])


# ------------------------------------------------------------------ sweep.json is untrusted
def _hand_folder(tmp_path: Path, value_names, values=(0, 1)) -> Path:
    """A sweep folder over contact (with ``value_names`` in its sweep.json entry) x eta0."""
    out = tmp_path / "h"
    out.mkdir()
    entry = {"name": "contact", "set": ["fmus.b.parameters.contact"]}
    if value_names is not None:
        entry["value_names"] = value_names
    (out / "sweep.json").write_text(json.dumps({
        "sweep": 1, "scenario": "s.yaml", "mode": "grid",
        "parameters": [entry, {"name": "eta0", "set": ["fmus.b.parameters.eta0"]}], "collect": {"v": "macro_steps"}}))
    (out / "sweep.csv").write_text("run_id,contact,eta0,v,status,message,wall_time_s,run_dir\n" + "".join(
        f"r{v}{e},{v},{e},{k},finished,,1.0,runs/r{v}{e}\n" for k, (v, e) in
        enumerate((v, e) for v in values for e in (0.008, 0.012))))
    return out


@pytest.mark.parametrize("value_names, values, ticks", [
    ({"0": "open", "1": "shut"}, (0, 1), ["open (0)", "shut (1)"]),
    ({"0": "open", "1": "shut", "2": "stuck"}, (0, 1), ["open (0)", "shut (1)"]),
    (None, (0, 1), ["0", "1"]),                                # no names (a sweep of before, or none declared)
    ({"0": "open"}, (0, 1), ["0", "1"]),                       # a value without a name: none named
    ({"00": "open", "1": "shut"}, (0, 1), ["0", "1"]),         # not as a sweep writes a value
    ({"0": "open", "1.0": "shut"}, (0, 1), ["0", "1"]),
    ({"0": "open", "x": "shut"}, (0, 1), ["0", "1"]),
    ({"0": "open", "99999999999": "shut"}, (0, 1), ["0", "1"]),
    ({"0": "open", "1": "open"}, (0, 1), ["0", "1"]),          # a name twice
    ({"0": "open", "1": 5}, (0, 1), ["0", "1"]),
    ({"0": "open", "1": None}, (0, 1), ["0", "1"]),
    ({"0": "open", "1": "x" * 41}, (0, 1), ["0", "1"]),
    ({"0": "open", "1": "a\nb"}, (0, 1), ["0", "1"]),
    ({"0": "open", "1": "a\u202eb"}, (0, 1), ["0", "1"]),
    ({"0": "open", "1": "$\\foo$"}, (0, 1), ["open (0)", "$\\foo$ (1)"]),     # drawn as written
    ({str(k): f"v{k}" for k in range(MAX_VALUE_NAMES + 1)}, (0, 1), ["0", "1"]),
    (["open", "shut"], (0, 1), ["0", "1"]),
    ("open", (0, 1), ["0", "1"]),
])
def test_names_in_sweep_json_are_drawn_only_when_they_follow_the_rules(tmp_path, figures, value_names, values,
                                                                       ticks):
    """sweep.json may come from anyone: names that break the rules of the FMU's declaration give
    numbers (never an error), as do names that leave a value of the runs unnamed."""
    from orchestrator.sweep.plot import plot_sweep
    plot_sweep(_hand_folder(tmp_path, value_names, values))
    figures[0].canvas.draw()
    assert _ticks(figures[0])[0] == ticks
