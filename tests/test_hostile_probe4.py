"""Fourth hostile and any-FMU probe (after tests/test_hostile_probe3.py and the other catalogues):
third-party FMUs coupled the way a co-simulation engineer couples them, and text that no UTF-8
can hold. One test per finding, each failing on the code before its fix."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.fmus_c.build_c_fmu import build_c_fmu

needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")


def _run_fixed_step(tmp_path: Path, start: str, stop: str):
    """AllTypesFixed (built in tmp_path; it cannot vary its step) from ``start`` to ``stop`` in
    macro steps of 0.1 s, a.x and a.count recorded."""
    p = tmp_path / "fixed.yaml"
    p.write_text(f"name: fixed\nstart_time: {start}\nstop_time: {stop}\nfmus:\n"
                 "  a: {path: AllTypesFixed.fmu, parameters: {u: 1.0}}\ncoupling: {macro_step: 0.1}\n"
                 "output: {signals: [a.x, a.count]}\n")
    return _run(p, tmp_path / f"fixed-{start}")


def _run(path: Path, out: Path, overrides=()):
    import orchestrator
    return orchestrator.run(orchestrator.load_scenario(path, overrides=list(overrides)), out_dir=out, progress=False)


@needs_gcc
def test_every_macro_step_is_passed_as_the_macro_step_itself(tmp_path, test_fmus, monkeypatch):
    """fmi2DoStep got communicationStepSize = T(n+1) - T(n) of the grid times, which is not the macro
    step in floating point (0.3 - 0.2 = 0.09999999999999998; at start_time 1e6 + 0.1 the steps
    alternate 0.0999999999767 / 0.1000000000931). An FMU that cannot vary its step
    (canHandleVariableCommunicationStepSize="false", AllTypesFixed) refused the third step with
    fmi2Error and the run failed. Now every whole macro step is passed as coupling.macro_step
    exactly (sub-steps as macro_step / substeps), from the grid time T(n) = t0 + n*H."""
    build_c_fmu(tmp_path, "AllTypes", fixed_step=True)
    res = _run_fixed_step(tmp_path, "1000000.1", "1000001.1")
    assert res.success, res.message
    assert list(res.outputs["a.count"]) == list(range(11))

    from orchestrator.fmi.subsystem import Subsystem
    calls = []
    real = Subsystem.do_step

    def recording(self, t, h):
        calls.append((t, h))
        return real(self, t, h)
    monkeypatch.setattr(Subsystem, "do_step", recording)
    shutil.copy(test_fmus["Integrator"], tmp_path / "Integrator.fmu")
    q = tmp_path / "integ.yaml"
    q.write_text("name: integ\nstop_time: 3.0\nfmus:\n  i: {path: Integrator.fmu, parameters: {u: 1.0}}\n"
                 "coupling: {macro_step: 0.1, substeps: 2}\n")
    assert _run(q, tmp_path / "integ").success
    assert len(calls) == 60
    assert {h for _, h in calls} == {0.05}
    assert [t for t, _ in calls[::2]] == [n * 0.1 for n in range(30)]


def test_a_surrogate_escape_in_any_yaml_text_is_named_with_its_line(tmp_path, capsys):
    """A "\\ud83d\\ude00" escape in a double-quoted YAML string (how JSON writes an emoji) gives two
    lone UTF-16 surrogates: PyYAML does not join them, and no UTF-8 text can hold one. In an FMU
    path or a recorded signal `rotorcosim validate` / `run` ended in "internal error:
    UnicodeEncodeError", in a String parameter `run` did; in the description the run passed. Now
    the bounded YAML reader (untrusted.check_yaml_tree, under every scenario, --set value, sweep
    and comparison file) refuses such text with its line and the escape to write instead."""
    from hostile_builders import cli, md_scenario
    from orchestrator.errors import ScenarioError
    from orchestrator.scenario import load_scenario

    p = md_scenario(tmp_path, top='description: "rotor \\ud83d\\ude00 test"\n')
    with pytest.raises(ScenarioError) as exc:
        load_scenario(p)
    msg = str(exc.value)
    assert f"{p}:3: the text holds \\ud83d (character 7), half of a UTF-16 surrogate pair" in msg, msg
    assert "one escape of its code point: \\U0001F600" in msg, msg

    p = md_scenario(tmp_path)
    for setting, part in [('fmus.a.path="m\\ud800.fmu"', "holds \\ud800 (character 2)"),
                          ('output.signals=["a.y\\udc00"]', "holds \\udc00 (character 4)"),
                          ('fmus.a.parameters.k="\\ud800"', "holds \\ud800 (character 1)")]:
        rc, text = cli(capsys, "validate", p, "--no-build", "--set", setting)
        assert rc == 1 and f"--set {setting}:1: the text {part}" in text, text
        assert "\\U and 8 hex digits" in text and "Traceback" not in text, text

    from orchestrator.sweep import SweepError, load_sweep
    (tmp_path / "w.yaml").write_text('sweep: 1\nscenario: s.yaml\nparameters:\n'
                                     '  - {name: "k\\ud800", set: stop_time, values: [1, 2]}\n')
    with pytest.raises(SweepError, match=r"w.yaml:4: the text holds \\ud800"):
        load_sweep(tmp_path / "w.yaml")


def test_a_string_parameter_holding_nul_is_refused_not_cut(tmp_path, capsys):
    """A String parameter written with a "\\0" escape (prefix: "ab\\0cd") was accepted and the FMU got
    "ab" (fmi2SetString takes a C string): a run finished with the wrong value and no word. Now
    check_value refuses it at load, naming the parameter, the character and what the FMU would get;
    a lone surrogate from a Python scenario is refused there too (was UnicodeEncodeError at run)."""
    from hostile_builders import cli, md_scenario, md_xml, write_fmu
    from orchestrator.fmi.values import check_value

    write_fmu(tmp_path / "m.fmu", md_xml(variables=(
        '<ScalarVariable name="label" valueReference="0" causality="parameter" variability="fixed">'
        '<String start="x"/></ScalarVariable>')))
    p = tmp_path / "s.yaml"
    p.write_text('name: strings\nstop_time: 1\nfmus:\n  a: {path: m.fmu, parameters: {label: "ab\\0cd"}}\n')
    rc, text = cli(capsys, "validate", p, "--no-build")
    assert rc == 1, text
    assert (f"{p}:4: parameter 'a.label' is String and holds a NUL character (\\0, character 3), which ends "
            "the text for the FMU (fmi2SetString takes a C string: it would get 'ab'); remove it") in text, text

    class Var:
        type, choices, min, max = "String", (), None, None
    assert check_value(Var, "fine", "a.label") == ("fine", None)
    value, why = check_value(Var, "a\ud800", "a.label")
    assert value is None and "'a.label' is String and the text holds \\ud800 (character 2)" in why


def test_a_summary_json_with_a_lone_surrogate_is_skipped_not_an_internal_error(tmp_path, capsys):
    """summary.json is untrusted (a run folder from someone else): a JSON string with a lone "\\ud800"
    escape is valid JSON, and `rotorcosim plot` ended in "internal error: TypeError: set_text()"
    drawing the scenario name as a title. Now untrusted.load_json (under plot, CoSimResult.load,
    sweep --resume and compare baselines) refuses it as it refuses bad JSON, naming the file, and
    plot draws from results.csv alone with a warning."""
    import json

    from hostile_builders import cli
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.csv").write_text("time,osc.x\n" + "".join(f"{i * 0.1!r},{i * 0.5!r}\n" for i in range(10)))
    (run / "summary.json").write_text(json.dumps({"scenario": "s\ud800", "status": "finished"}))
    with pytest.warns(UserWarning) as seen:
        rc, text = cli(capsys, "plot", run)
    assert rc == 0, text
    warned = " ".join(str(w.message) for w in seen)
    assert (f"{run / 'summary.json'}: the summary.json cannot be used: a text in it holds \\ud800 (character 2), "
            "half of a UTF-16 surrogate pair") in warned, warned
    assert (run / "plots").is_dir() and list((run / "plots").glob("*.png"))


def _enum_fmu(path: Path, type_name: str, items, causality: str) -> Path:
    from hostile_builders import md_xml, write_fmu
    types = (f'<TypeDefinitions><SimpleType name="{type_name}"><Enumeration>'
             + "".join(f'<Item name="{n}" value="{v}"/>' for n, v in items) + "</Enumeration></SimpleType></TypeDefinitions>")
    start = f' start="{items[0][1]}"' if causality == "input" else ""
    xml = md_xml(variables=f'<ScalarVariable name="e" valueReference="0" causality="{causality}" variability="discrete">'
                           f'<Enumeration declaredType="{type_name}"{start}/></ScalarVariable>')
    return write_fmu(path, xml.replace("<ModelVariables>", types + "<ModelVariables>"))


def test_an_enumeration_output_connected_to_an_input_of_another_enumeration_type(tmp_path, capsys):
    """Both ends of a connection must have the same type, but two Enumeration ends of different
    enumeration types passed: Mode {Off=1, Slow=2, Fast=3} -> Level {Low=0, High=1} loaded and ran,
    handing the input FMU the values 2 and 3 its model description does not declare (FMUs index
    tables with them). Now such a connection is a load error naming both types and the values the
    input lacks; an input type that has every value of the output's type is still accepted."""
    from hostile_builders import cli
    _enum_fmu(tmp_path / "src.fmu", "Mode", [("Off", 1), ("Slow", 2), ("Fast", 3)], "output")
    _enum_fmu(tmp_path / "level.fmu", "Level", [("Low", 0), ("High", 1)], "input")
    _enum_fmu(tmp_path / "wide.fmu", "Gear", [("N", 0), ("G1", 1), ("G2", 2), ("G3", 3)], "input")
    p = tmp_path / "s.yaml"
    p.write_text("name: enums\nstop_time: 1\nfmus:\n  a: {path: src.fmu}\n  b: {path: level.fmu}\n"
                 "  c: {path: wide.fmu}\nconnections:\n  - a.e -> b.e\n  - a.e -> c.e\n")
    rc, text = cli(capsys, "validate", p, "--no-build")
    assert rc == 1, text
    assert (f"{p}:8: enumeration mismatch: 'a.e' is of type Mode {{Off=1, Slow=2, Fast=3}} but 'b.e' is of type "
            "Level {Low=0, High=1}: the values 2 (Slow), 3 (Fast) that 'a.e' may give are no items of 'b.e'") in text
    assert ":9:" not in text and "1 problem found" in text, text


@needs_gcc
def test_a_run_starting_at_a_large_time_steps_to_its_stop_time(tmp_path, test_fmus):
    """At start_time 31536000 s (one year in seconds, where building and grid FMUs start) and a
    macro step of 0.1 s, rounding makes (t0 + 3h - t0) / h = 3.0000000447, above the 1e-9 steps
    the grid absorbed: the run planned a fourth step of length 0 and ended in "internal error:
    ZeroDivisionError" after its last row (run() raised it); with step_control: error the output
    grid gave a zero step at t0 + 0.2 the same way; and a fixed-step FMU was refused with "stop_time
    31536000.4 is not on the macro-step grid ... use stop_time 31536000.3 or 31536000.4". Now the
    remainder rounding alone can make is absorbed everywhere (scenario.limits.step_slack: 16 units
    in the last place of the time, over the step), and each macro step reaches the FMUs as 0.1."""
    for name in ("Integrator",):
        shutil.copy(test_fmus[name], tmp_path / f"{name}.fmu")
    build_c_fmu(tmp_path, "AllTypes", fixed_step=True)
    p = tmp_path / "year.yaml"
    p.write_text("name: year\nstart_time: 31536000\nstop_time: 31536000.3\nfmus:\n"
                 "  i1: {path: Integrator.fmu, parameters: {u: 1.0}}\n  i2: {path: Integrator.fmu}\n"
                 "connections: [i1.y -> i2.u]\ncoupling: {macro_step: 0.1}\n")
    res = _run(p, tmp_path / "constant")
    assert res.success, res.message
    assert list(res.t) == [31536000.0, 31536000.1, 31536000.2, 31536000.3]
    assert list(res.outputs["i1.y"]) == [0.0, 0.1, 0.2, 0.1 + 0.1 + 0.1]

    res = _run(p, tmp_path / "error", ["stop_time=31536000.5", "output.interval=0.1",
                                       "coupling.step_control={type: error, rtol: 1.0e-3}"])
    assert res.success, res.message
    assert len(res.t) == 6 and res.t[-1] == 31536000.5

    res = _run_fixed_step(tmp_path, "31536000", "31536000.4")
    assert res.success, res.message
    assert list(res.outputs["a.count"]) == [0, 1, 2, 3, 4]


def test_a_macro_step_below_a_femtosecond_is_refused_with_its_line(tmp_path, test_fmus):
    """stop_time 1e-300, macro_step 1e-301: the master's input weights take 1/h up to the third
    power, and run ended in "internal error: OverflowError". Now the loader refuses a macro step,
    and a step_control min_step or max_step, below 1 fs (scenario.limits.MIN_MACRO_STEP), naming
    the line."""
    import orchestrator
    from orchestrator.errors import ScenarioError
    shutil.copy(test_fmus["Integrator"], tmp_path / "Integrator.fmu")
    p = tmp_path / "tiny.yaml"
    p.write_text("name: tiny\nstop_time: 1.0e-300\nfmus:\n  i: {path: Integrator.fmu}\n"
                 "coupling: {macro_step: 1.0e-301}\n")
    with pytest.raises(ScenarioError, match=r"tiny\.yaml:5: 'coupling\.macro_step' 1e-301 s is below the "
                                            r"smallest macro step, 1e-15 s"):
        orchestrator.load_scenario(p)
    p.write_text("name: tiny\nstop_time: 1.0e-12\nfmus:\n  i: {path: Integrator.fmu}\n"
                 "coupling: {macro_step: 1.0e-13, step_control: {type: error, min_step: 1.0e-300}}\n")
    with pytest.raises(ScenarioError, match=r"'coupling\.step_control\.min_step' 1e-300 s is below"):
        orchestrator.load_scenario(p)
    p.write_text("name: tiny\nstop_time: 1.0e-12\nfmus:\n  i: {path: Integrator.fmu}\ncoupling: {macro_step: 1.0e-13}\n")
    assert _run(p, tmp_path / "ok").success            # 0.1 ps steps still run


def _with_units(src: Path, dst: Path, u_unit: str, y_unit: str, defs: str) -> Path:
    """A copy of the Integrator test FMU whose input u and output y declare units (its model
    description only: the loader reads nothing else)."""
    import zipfile
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                xml = data.decode()
                xml = xml.replace('causality="input">\n\t\t\t<Real start="0"/>',
                                  f'causality="input">\n\t\t\t<Real start="0" unit="{u_unit}"/>')
                xml = xml.replace('description="integral [-]" causality="output">\n\t\t\t<Real/>',
                                  f'description="integral [-]" causality="output">\n\t\t\t<Real unit="{y_unit}"/>')
                xml = xml.replace("\t<ModelVariables>", f"\t<UnitDefinitions>{defs}</UnitDefinitions>\n\t<ModelVariables>")
                assert f'unit="{u_unit}"' in xml and f'unit="{y_unit}"' in xml
                data = xml.encode()
            zout.writestr(item, data)
    return dst


def test_a_connection_between_different_units_is_named_with_the_gain_to_write(tmp_path, test_fmus, caplog):
    """An output in mm connected to an input in m (no gain) loaded silently, and the input got
    the number in mm. Now the loader warns, and from the FMUs' unit definitions gives the gain
    (or says the dimensions differ); the same unit under two names, or a connection with a gain,
    is left alone."""
    import orchestrator
    defs = ('<Unit name="m"><BaseUnit m="1"/></Unit><Unit name="mm"><BaseUnit m="1" factor="0.001"/></Unit>'
            '<Unit name="metre"><BaseUnit m="1"/></Unit><Unit name="s"><BaseUnit s="1"/></Unit>'
            '<Unit name="degC"><BaseUnit K="1" offset="273.15"/></Unit><Unit name="K"><BaseUnit K="1"/></Unit>')
    cases = {("mm", "m"): "write {gain: 0.001} in the connection",
             ("degC", "K"): "write {gain: 1, offset: 273.15} in the connection",
             ("m", "s"): "the units have different dimensions",
             ("m", "furlong"): "the units differ and the FMUs do not define both",
             ("m", "metre"): None}
    for k, ((y_unit, u_unit), expected) in enumerate(cases.items()):
        _with_units(test_fmus["Integrator"], tmp_path / f"a{k}.fmu", "m", y_unit, defs)
        _with_units(test_fmus["Integrator"], tmp_path / f"b{k}.fmu", u_unit, "m", defs)
        p = tmp_path / f"s{k}.yaml"
        p.write_text(f"name: units\nstop_time: 1.0\nfmus:\n  a: {{path: a{k}.fmu}}\n  b: {{path: b{k}.fmu}}\n"
                     f"connections:\n  - {{from: a.y, to: b.u}}\n")
        caplog.clear()
        with caplog.at_level("WARNING"):
            orchestrator.load_scenario(p)
        said = [r.getMessage() for r in caplog.records if "connection 'a.y'" in r.getMessage()]
        if expected is None:
            assert said == []
        else:
            assert len(said) == 1 and f"s{k}.yaml:7: connection 'a.y' [{y_unit}] -> 'b.u' [{u_unit}]" in said[0]
            assert expected in said[0], said[0]
    p.write_text("name: units\nstop_time: 1.0\nfmus:\n  a: {path: a0.fmu}\n  b: {path: b0.fmu}\n"
                 "connections:\n  - {from: a.y, to: b.u, gain: 0.001}\n")
    caplog.clear()
    with caplog.at_level("WARNING"):
        orchestrator.load_scenario(p)
    assert not [r for r in caplog.records if "connection 'a.y'" in r.getMessage()]
