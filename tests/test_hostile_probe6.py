"""Sixth probe (after tests/test_hostile_probe5.py): SSP archives written by other tools, sweeps
resumed into the same folder, and the regression gate of `rotorcosim compare`. One test per
finding, each failing on the code before its fix."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest

from tests.test_hostile_probe4 import _with_units

NS = ('xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
      'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
      'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"')


def _ssp(path: Path, system: str, fmus: dict[str, Path], *, head: str = "") -> Path:
    """A hand-written SSP 1.0 archive: ``system`` is the content of the ssd:System element, ``head``
    what goes before it (e.g. ssd:Units is after the System: SSP 1.0 order), ``fmus`` member -> file."""
    ssd = (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription {NS} version="1.0" '
           f'name="probe6"><ssd:System name="top">{system}</ssd:System>{head}'
           '<ssd:DefaultExperiment startTime="0" stopTime="1"/></ssd:SystemStructureDescription>')
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        for member, src in fmus.items():
            zf.write(src, member)
    return path


def _pset(*params: tuple[str, float]) -> str:
    body = "".join(f'<ssv:Parameter name="{n}"><ssv:Real value="{v}"/></ssv:Parameter>' for n, v in params)
    return (f'<ssd:ParameterValues><ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>{body}'
            '</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>')


def test_ssp_parameter_bindings_of_the_system_are_applied_not_dropped(tmp_path, test_fmus):
    """An SSP whose *system* carries the parameter bindings (SSP 1.0: hierarchical names
    ``element.variable``, or the binding's ``prefix="element."`` prepended to bare names; the
    usual way to apply one parameter file to one component) loaded with every such value
    silently dropped: the gain a.k stayed at the FMU's start value 1 instead of 5 and the run
    computed another system. Now they set the component's variables, over the component's own
    bindings (bindings at a higher level take precedence), and a name that reaches no component
    is reported instead of ignored."""
    import orchestrator
    from orchestrator.errors import ScenarioError
    comps = ('<ssd:Elements><ssd:Component name="a" source="resources/Gain.fmu">'
             f'<ssd:ParameterBindings><ssd:ParameterBinding>{_pset(("k", 3.0))}</ssd:ParameterBinding>'
             '</ssd:ParameterBindings></ssd:Component>'
             '<ssd:Component name="b" source="resources/Integrator.fmu"/></ssd:Elements>'
             '<ssd:Connections><ssd:Connection startElement="a" startConnector="y" endElement="b" '
             'endConnector="u"/></ssd:Connections>')
    fmus = {"resources/Gain.fmu": test_fmus["Gain"], "resources/Integrator.fmu": test_fmus["Integrator"]}
    system = ('<ssd:ParameterBindings>'
              f'<ssd:ParameterBinding prefix="a.">{_pset(("k", 5.0))}</ssd:ParameterBinding>'
              f'<ssd:ParameterBinding>{_pset(("b.y0", 0.5))}</ssd:ParameterBinding>'
              '</ssd:ParameterBindings>')
    sc = orchestrator.load_scenario(_ssp(tmp_path / "s.ssp", system + comps, fmus))
    assert dict(sc.fmu("a").parameters) == {"k": 5.0} and dict(sc.fmu("b").parameters) == {"y0": 0.5}
    bad = system.replace('name="b.y0"', 'name="nobody.y0"')
    with pytest.raises(ScenarioError, match="parameter 'nobody.y0' of the system's parameter bindings names no "
                                            "component variable"):
        orchestrator.load_scenario(_ssp(tmp_path / "bad.ssp", bad + comps, fmus))


def test_ssp_mapping_transformations_and_signal_dictionaries_are_refused_by_name(tmp_path, test_fmus):
    """A connection carrying an ssc:BooleanMappingTransformation (or Integer/Enumeration mapping)
    loaded with the mapping silently dropped: the input got the unmapped value. A signal
    dictionary, documented as refused by name, was not checked at all (its connections then
    failed as connections to an unknown instance). Now both are reported by name."""
    import orchestrator
    from orchestrator.errors import ScenarioError
    tp = {"resources/TypedPorts.fmu": test_fmus["TypedPorts"]}
    system = ('<ssd:Elements><ssd:Component name="a" source="resources/TypedPorts.fmu"/>'
              '<ssd:Component name="b" source="resources/TypedPorts.fmu"/></ssd:Elements>'
              '<ssd:Connections><ssd:Connection startElement="a" startConnector="b_out" endElement="b" '
              'endConnector="b_in"><ssc:BooleanMappingTransformation><ssc:MapEntry source="true" target="false"/>'
              '<ssc:MapEntry source="false" target="true"/></ssc:BooleanMappingTransformation></ssd:Connection>'
              '</ssd:Connections>')
    with pytest.raises(ScenarioError, match="connection a.b_out -> b.b_in: a BooleanMappingTransformation is "
                                            "not supported"):
        orchestrator.load_scenario(_ssp(tmp_path / "m.ssp", system, tp))
    system = ('<ssd:Elements><ssd:Component name="a" source="resources/TypedPorts.fmu"/>'
              '<ssd:SignalDictionaryReference name="bus" dictionary="d"/></ssd:Elements>')
    with pytest.raises(ScenarioError, match="signal dictionaries are not supported"):
        orchestrator.load_scenario(_ssp(tmp_path / "d.ssp", system, tp))


def test_ssp_connections_between_different_units_are_converted_as_ssp_says(tmp_path, test_fmus):
    """SSP 1.0: a connection between connectors of different units converts the value (then
    applies its LinearTransformation) unless ``suppressUnitConversion="true"``. The importer
    dropped the conversion: an output in mm into an input in m with a LinearTransformation
    factor 2 gave b.u = 2 * y[mm] (1000x too large), silently, because a gain switches the
    loader's unit warning off. Now the conversion is composed with the transformation (2 * 0.001),
    suppressUnitConversion passes the number as it is, units that cannot be converted are
    reported, and export-ssp writes suppressUnitConversion="true" (our gain/offset is the whole
    conversion), so a scenario's connection comes back unchanged."""
    import orchestrator
    from orchestrator.errors import ScenarioError
    from orchestrator.scenario.ssp import export_ssp
    defs = ('<Unit name="m"><BaseUnit m="1"/></Unit><Unit name="mm"><BaseUnit m="1" factor="0.001"/></Unit>'
            '<Unit name="s"><BaseUnit s="1"/></Unit>')
    _with_units(test_fmus["Integrator"], tmp_path / "A.fmu", "m", "mm", defs)    # a.y in mm
    _with_units(test_fmus["Integrator"], tmp_path / "B.fmu", "m", "m", defs)     # b.u in m
    _with_units(test_fmus["Integrator"], tmp_path / "C.fmu", "s", "m", defs)     # c.u in s
    fmus = {"resources/A.fmu": tmp_path / "A.fmu", "resources/B.fmu": tmp_path / "B.fmu",
            "resources/C.fmu": tmp_path / "C.fmu"}

    def system(attrs: str = "", lt: str = "", to: str = "b") -> str:
        return ('<ssd:Elements><ssd:Component name="a" source="resources/A.fmu"/>'
                '<ssd:Component name="b" source="resources/B.fmu"/><ssd:Component name="c" source="resources/C.fmu"/>'
                '</ssd:Elements><ssd:Connections>'
                f'<ssd:Connection startElement="a" startConnector="y" endElement="{to}" endConnector="u" {attrs}>'
                f'{lt}</ssd:Connection></ssd:Connections>')

    def conn(name: str, text: str):
        c = orchestrator.load_scenario(_ssp(tmp_path / name, text, fmus)).connections[0]
        return pytest.approx(c.gain, rel=1e-15), pytest.approx(c.offset, abs=1e-15)

    lt = '<ssc:LinearTransformation factor="2" offset="0.5"/>'
    assert conn("lt.ssp", system(lt=lt)) == (0.002, 0.5)                  # 2 * (0.001 * y) + 0.5
    assert conn("plain.ssp", system()) == (0.001, 0.0)
    assert conn("off.ssp", system('suppressUnitConversion="true"', lt)) == (2.0, 0.5)
    with pytest.raises(ScenarioError, match=r"connection a.y \[mm\] -> c.u \[s\]: SSP converts between the "
                                            "connectors' units, but they have different dimensions"):
        conn("dim.ssp", system(to="c"))
    # round trip: a scenario's gain is the whole conversion and comes back as it was
    y = tmp_path / "s.yaml"
    y.write_text("name: units\nstop_time: 1.0\nfmus:\n  a: {path: A.fmu}\n  b: {path: B.fmu}\n"
                 "connections:\n  - {from: a.y, to: b.u, gain: 0.001}\n")
    with pytest.warns(UserWarning):
        out = export_ssp(orchestrator.load_scenario(y), tmp_path / "rt.ssp")
    c = orchestrator.load_scenario(out).connections[0]
    assert (c.gain, c.offset) == (0.001, 0.0)


def test_resume_after_the_scenario_changed_runs_again_instead_of_keeping_stale_rows(tmp_path, test_fmus):
    """`rotorcosim sweep --resume` kept every run whose folder held a finished summary of the same
    overrides, whatever the scenario file or FMU were then: a user who fixed the scenario (here
    stop_time 0.1 -> 0.2) and resumed got "2 runs resumed" and the old results in sweep.csv
    (end 0.1), a map of the system before the fix. Now each run records the SHA-256 of its
    scenario file and FMUs in sweep_run.json, and --resume runs again a finished run whose inputs
    changed, with a warning naming what changed; unchanged runs are still skipped."""
    import shutil

    from orchestrator.sweep import load_sweep
    from orchestrator.sweep.plan import plan_sweep
    from orchestrator.sweep.runner import run_sweep
    shutil.copy(test_fmus["Integrator"], tmp_path / "Integrator.fmu")
    sc = tmp_path / "sc.yaml"
    sc.write_text("name: integ\nstop_time: 0.1\nfmus:\n  i: {path: Integrator.fmu}\ncoupling: {macro_step: 0.01}\n")
    sw = tmp_path / "sw.yaml"
    sw.write_text("sweep: 1\nscenario: sc.yaml\nparameters:\n  - name: y0\n    set: fmus.i.parameters.y0\n"
                  "    values: [0.0, 1.0]\ncollect:\n  end: end_time\n")

    def sweep(resume: bool):
        spec = load_sweep(sw)
        return run_sweep(spec, plan_sweep(spec), tmp_path / "out", workers=1, resume=resume, progress=False,
                         warm=False)

    first = sweep(False)
    assert [r["end"] for r in first.rows] == [0.1, 0.1]
    again = sweep(True)                                           # nothing changed: both kept
    assert again.skipped == 2 and not again.warnings
    sc.write_text(sc.read_text().replace("stop_time: 0.1", "stop_time: 0.2"))
    with pytest.warns(UserWarning, match="the scenario file changed since this run finished"):
        fixed = sweep(True)
    assert fixed.skipped == 0 and [r["end"] for r in fixed.rows] == [0.2, 0.2]


def test_compare_variants_the_baseline_does_not_know_are_not_passed_silently(tmp_path, test_fmus, capsys):
    """The regression gate of `rotorcosim compare` skipped every variant missing from the baseline:
    after a change of the comparison file that renames its variants (a new macro step list: the
    names carry the step), no variant was compared with the baseline and the gate printed "all
    checks passed" with exit 0 - switched off without a word. Now a variant not in the baseline, or
    a baseline variant that was not run, fails the check by name, with the fix (--update-baseline
    and review the diff); after that the gate passes again."""
    from orchestrator.compare import main_compare
    from tests.test_compare import compare_files, fake_runner
    write = compare_files.__wrapped__(tmp_path, test_fmus)
    path = write("", baseline=True)
    out = tmp_path / "out"
    assert main_compare(path, out_dir=out, update_baseline=True, runner=fake_runner, workers=1) == 0
    path.write_text(path.read_text().replace("macro_step: [0.2, 0.1, 0.05]", "macro_step: [0.2, 0.1, 0.04]"))
    capsys.readouterr()
    assert main_compare(path, out_dir=out, runner=fake_runner, workers=1) == 1
    err = capsys.readouterr().err
    assert "FAIL variant 'gs-e1i0-h0.04': not in the baseline (12 variants); the regression gate cannot check it" \
        in err, err
    assert "FAIL variant 'gs-e1i0-h0.05': in the baseline but not run" in err
    assert "variant 'gs-e1i0-h0.1'" not in err                    # a variant in both is checked as before
    assert main_compare(path, out_dir=out, update_baseline=True, runner=fake_runner, workers=1) == 0
    assert main_compare(path, out_dir=out, runner=fake_runner, workers=1) == 0


def test_ssp_parameter_values_with_a_unit_are_converted_to_the_variables_unit(tmp_path, test_fmus):
    """An ssv:Real value with a unit (SSP 1.0: converted to the variable's unit) was applied as the
    bare number: y0 = 5 mm set an integrator whose y0 is in m to 5 m. Now it is converted from the
    parameter set's, the SSD's or the FMU's unit definitions (5 mm -> 0.005 m, 20 degC -> 293.15 K),
    and a unit that cannot be converted is reported with the parameter."""
    import orchestrator
    from orchestrator.errors import ScenarioError
    defs = ('<Unit name="m"><BaseUnit m="1"/></Unit><Unit name="K"><BaseUnit K="1"/></Unit>')
    fmu = tmp_path / "I.fmu"
    import shutil
    src = tmp_path / "I0.fmu"
    shutil.copy(test_fmus["Integrator"], src)
    xml_fmu = _with_units(src, tmp_path / "Iu.fmu", "m", "m", defs)
    # y0 declares no unit in the test FMU: give it one through its model description
    with zipfile.ZipFile(xml_fmu) as zin, zipfile.ZipFile(fmu, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = data.decode().replace('causality="parameter" variability="tunable">\n\t\t\t<Real start="0"/>',
                                             'causality="parameter" variability="tunable">\n\t\t\t'
                                             '<Real start="0" unit="m"/>').encode()
                assert b'<Real start="0" unit="m"/>' in data
            zout.writestr(item, data)

    def pset(value: str, unit: str, units: str = "") -> str:
        return (f'<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
                f'<ssv:ParameterSet version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="y0">'
                f'<ssv:Real value="{value}" unit="{unit}"/></ssv:Parameter></ssv:Parameters>{units}'
                '</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>')

    mm = '<ssv:Units><ssc:Unit name="mm"><ssc:BaseUnit m="1" factor="0.001"/></ssc:Unit></ssv:Units>'
    system = (f'<ssd:Elements><ssd:Component name="a" source="resources/I.fmu">{pset("5", "mm", mm)}'
              '</ssd:Component></ssd:Elements>')
    sc = orchestrator.load_scenario(_ssp(tmp_path / "mm.ssp", system, {"resources/I.fmu": fmu}))
    assert sc.fmu("a").parameters["y0"] == pytest.approx(0.005)
    # the unit defined in the SSD instead of the parameter set; the same unit: unchanged
    head = '<ssd:Units><ssc:Unit name="cm"><ssc:BaseUnit m="1" factor="0.01"/></ssc:Unit></ssd:Units>'
    system = f'<ssd:Elements><ssd:Component name="a" source="resources/I.fmu">{pset("5", "cm")}</ssd:Component></ssd:Elements>'
    sc = orchestrator.load_scenario(_ssp(tmp_path / "cm.ssp", system, {"resources/I.fmu": fmu}, head=head))
    assert sc.fmu("a").parameters["y0"] == pytest.approx(0.05)
    system = f'<ssd:Elements><ssd:Component name="a" source="resources/I.fmu">{pset("5", "m")}</ssd:Component></ssd:Elements>'
    assert orchestrator.load_scenario(_ssp(tmp_path / "m.ssp", system, {"resources/I.fmu": fmu})).fmu("a").parameters["y0"] == 5.0
    system = f'<ssd:Elements><ssd:Component name="a" source="resources/I.fmu">{pset("5", "furlong")}</ssd:Component></ssd:Elements>'
    with pytest.raises(ScenarioError, match=r"parameter 'y0' = 5.0 furlong, for a variable in m: 'furlong' is "
                                            r"defined neither"):
        orchestrator.load_scenario(_ssp(tmp_path / "f.ssp", system, {"resources/I.fmu": fmu}))


def test_ssp_connector_unit_contradicting_the_fmu_is_said(tmp_path, test_fmus, caplog):
    """An SSD connector declaring a unit (mm) other than the one its FMU declares for the variable
    (m) was ignored without a word (the FMU's unit is what its numbers are in). Now a warning names
    the connector and both units."""
    import orchestrator
    defs = '<Unit name="m"><BaseUnit m="1"/></Unit>'
    a = _with_units(test_fmus["Integrator"], tmp_path / "A.fmu", "m", "m", defs)
    system = ('<ssd:Elements><ssd:Component name="a" source="resources/A.fmu"><ssd:Connectors>'
              '<ssd:Connector name="y" kind="output"><ssc:Real unit="mm"/></ssd:Connector></ssd:Connectors>'
              '</ssd:Component><ssd:Component name="b" source="resources/B.fmu"/></ssd:Elements>'
              '<ssd:Connections><ssd:Connection startElement="a" startConnector="y" endElement="b" '
              'endConnector="u"/></ssd:Connections>')
    with caplog.at_level("WARNING"):
        orchestrator.load_scenario(_ssp(tmp_path / "c.ssp", system, {"resources/A.fmu": a, "resources/B.fmu": a}))
    said = [r.getMessage() for r in caplog.records if "connector a.y declares unit 'mm'" in r.getMessage()]
    assert len(said) == 1 and "its FMU declares 'm'" in said[0]
