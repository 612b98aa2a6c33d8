"""SSP: export a scenario, run the archive in libcosim and in our master, read it back.

The scenario couples two AllTypes C FMUs (tests/fmus_c) by Real (with gain and offset),
Integer and Boolean connections and sets Real, Integer, Enumeration and String values.
`rotorcosim export-ssp` writes it as SSP 1.0; libcosim (`CosimExecution.from_ssp_file`,
in a subprocess) runs the archive with its fixed-step algorithm (Jacobi, zero-order hold);
our master runs the original scenario with `scheme: jacobi`, `extrapolation_order: 0`:
the recorded values must be equal (Integer, Boolean exactly; Real to round-off). Our master
also runs the archive itself (`rotorcosim run system.ssp`) to the same values, and a YAML
scenario may name `ssp: FILE` and change what it records and how it couples.
"""

from __future__ import annotations

import importlib.util
import json
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve()
H, N = 0.1, 15
RECORD = ["a.count", "b.count", "a.b_out", "b.b_out", "b.x", "b.y"]

pytestmark = [pytest.mark.integration,
              pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")]


@pytest.fixture(scope="module")
def scenario_file(tmp_path_factory) -> Path:
    spec = importlib.util.spec_from_file_location("b", HERE.parent / "fmus_c" / "build_c_fmu.py")
    b = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(b)
    d = tmp_path_factory.mktemp("ssp")
    b.build_c_fmu(d, "AllTypes")
    p = d / "system.yaml"
    p.write_text(_SYSTEM)
    # libcosim's SSP loader sets parameters and inputs only (a start value of the state b.x is ignored
    # there, with a warning of export-ssp): the libcosim comparison starts b.x at its default
    (d / "system_lc.yaml").write_text(_SYSTEM.replace("x: 0.25, ", ""))
    return p


_SYSTEM = f"""name: ssp_round_trip
stop_time: {H * N}
fmus:
  a: {{path: AllTypes.fmu, parameters: {{u: 1.5, gain: 3.0, mode: Fast, label: alpha}}}}
  b: {{path: AllTypes.fmu, parameters: {{x: 0.25, stop_after: 0}}}}
connections:
  - {{from: a.y, to: b.u, gain: 0.5, offset: 0.125}}
  - {{from: a.count, to: b.n_in}}
  - {{from: a.b_out, to: b.b_in}}
  - {{from: b.b_out, to: a.b_in}}
coupling: {{scheme: jacobi, macro_step: {H}, extrapolation_order: 0}}
output: {{signals: [{', '.join(RECORD)}]}}
"""


def _run(path: Path, out: Path, overrides=()):
    import orchestrator
    res = orchestrator.run(orchestrator.load_scenario(path, overrides), out_dir=out, progress=False)
    assert res.success, res.message
    return res


def _libcosim_main(ssp: str, out: str) -> None:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    ex = CosimExecution.from_ssp_file(ssp, step_size=round(H * 1e9))
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    idx = {n: ex.slave_index_from_instance_name(n) for n in ("a", "b")}
    refs = {n: {v.name.decode(): (v.reference, v.type) for v in ex.slave_variables(i)} for n, i in idx.items()}
    rows = {k: [] for k in RECORD}
    for _ in range(N):
        assert ex.step(1)
        for sig in RECORD:
            inst, var = sig.split(".")
            ref, kind = refs[inst][var]
            get = {0: obs.last_real_values, 1: obs.last_integer_values, 3: obs.last_boolean_values}[int(kind)]  # CosimVariableType
            rows[sig].append(float(get(idx[inst], [ref])[0]))
    np.savez(out, **{k: np.asarray(v) for k, v in rows.items()})


if __name__ == "__main__" and len(sys.argv) == 4 and sys.argv[1] == "--libcosim":
    _libcosim_main(sys.argv[2], sys.argv[3])
    sys.exit(0)


def test_exported_ssp_runs_in_libcosim_to_our_jacobi_values(scenario_file, tmp_path):
    pytest.importorskip("libcosimpy")
    from orchestrator.cli import main
    ssp = tmp_path / "system.ssp"
    scenario_file = scenario_file.with_name("system_lc.yaml")
    assert main(["export-ssp", str(scenario_file), str(ssp)]) == 0
    proc = subprocess.run([sys.executable, str(HERE), "--libcosim", str(ssp), str(tmp_path / "lc.npz")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    lc = np.load(tmp_path / "lc.npz")
    ours = _run(scenario_file, tmp_path / "ours")
    for sig in RECORD:
        np.testing.assert_allclose(np.asarray(ours.outputs[sig], float)[1:], lc[sig], rtol=1e-13, atol=1e-13,
                                   err_msg=sig)
    # the values travelled: b.u = 0.5 * (3 * 1.5) + 0.125 = 2.375, b.y = (default gain 2) * b.u
    assert lc["b.y"][-1] == pytest.approx(2.0 * 2.375)
    assert lc["b.x"][-1] == pytest.approx(2.375 * H * N)
    assert len(set(lc["b.b_out"])) == 2


def test_our_master_runs_the_ssp_and_a_scenario_can_name_it(scenario_file, tmp_path):
    from orchestrator.scenario.ssp import export_ssp
    import orchestrator
    sc = orchestrator.load_scenario(scenario_file)
    with pytest.warns(UserWarning, match="b.x are start values of outputs"):
        ssp = export_ssp(sc, tmp_path / "system.ssp")
    back = orchestrator.load_scenario(ssp)
    assert [(c.src, c.dst, c.gain, c.offset) for c in back.connections] == \
        [(c.src, c.dst, c.gain, c.offset) for c in sc.connections]
    assert dict(back.fmu("a").parameters) == dict(sc.fmu("a").parameters)
    assert (back.start_time, back.stop_time, back.coupling.macro_step, back.coupling.scheme) == \
        (sc.start_time, sc.stop_time, sc.coupling.macro_step, "jacobi")
    direct = _run(scenario_file, tmp_path / "direct")
    from_ssp = _run(ssp, tmp_path / "from_ssp", ["output.signals=[a.count,b.count,a.b_out,b.b_out,b.x,b.y]"])
    for sig in RECORD:
        np.testing.assert_array_equal(from_ssp.outputs[sig], direct.outputs[sig], err_msg=sig)
    # a YAML scenario naming the SSP: adds a parameter, changes the recorded signals and the scheme
    over = tmp_path / "over.yaml"
    over.write_text("ssp: system.ssp\nfmus:\n  b: {parameters: {stop_after: 5}}\n"
                    "coupling: {scheme: gauss-seidel, sequence: [a, b]}\noutput: {signals: [b.count]}\n")
    res = orchestrator.run(orchestrator.load_scenario(over), out_dir=tmp_path / "over", progress=False)
    assert res.status is orchestrator.Status.STOPPED_BY_FMU and list(res.outputs) == ["b.count"]


def test_unsupported_ssp_content_is_reported(tmp_path):
    import zipfile
    import orchestrator
    from orchestrator.errors import ScenarioError
    ssd = """<?xml version="1.0"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" version="1.0" name="x">
 <ssd:System name="x"><ssd:Elements>
  <ssd:Component name="a" source="resources/missing.fmu"/>
  <ssd:System name="inner"/>
 </ssd:Elements></ssd:System>
</ssd:SystemStructureDescription>"""
    p = tmp_path / "bad.ssp"
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("SystemStructure.ssd", ssd)
    with pytest.raises(ScenarioError) as info:
        orchestrator.load_scenario(p)
    text = str(info.value)
    assert "FMU of component 'a' 'resources/missing.fmu' not found" in text


_PLAIN_COUPLING = f"coupling: {{scheme: jacobi, macro_step: {H}, extrapolation_order: 0}}\n"
_RICH = _SYSTEM.replace(
    _PLAIN_COUPLING + f"output: {{signals: [{', '.join(RECORD)}]}}\n",
    f"""coupling:
  scheme: gauss-seidel
  sequence: [b, a]
  macro_step: {H}
  extrapolation_order: 1
  interpolation_order: 1
  parallel: false
  step_control: {{type: error, rtol: 1.0e-3, atol: {{"b.u": 1.0e-6}}, max_step: 0.2}}
output: {{signals: [b.y, a.count], interval: 0.05}}
""").replace("stop_after: 0}}", "stop_after: 0}, substeps: 2, isolation: process}")


def test_export_then_run_the_ssp_keeps_signals_output_coupling_and_instance_settings(scenario_file, tmp_path):
    """`export-ssp s.yaml x.ssp` then `run x.ssp` dropped output.signals (every output was
    recorded), the output interval, the coupling beyond the macro step (the run was Jacobi, zero
    order) and substeps/isolation of an instance, silently. Now they travel in an
    org.rotorcosim.scenario annotation (ignored by libcosim) and come back."""
    import zipfile

    import orchestrator
    from orchestrator.scenario.ssp import export_ssp
    rich = scenario_file.with_name("rich.yaml")
    rich.write_text(_RICH)
    sc = orchestrator.load_scenario(rich)
    with pytest.warns(UserWarning, match="reads the whole coupling section back"):
        ssp = export_ssp(sc, tmp_path / "rich.ssp")
    with zipfile.ZipFile(ssp) as zf:
        assert b'<ssc:Annotation type="org.rotorcosim.scenario">' in zf.read("SystemStructure.ssd")
    back = orchestrator.load_scenario(ssp)
    assert back.coupling == sc.coupling and back.coupling.scheme == "gauss-seidel"
    assert back.output == sc.output and back.output.signals == ("b.y", "a.count")
    assert [(f.name, f.substeps, f.isolation) for f in back.fmus] == [("a", None, None), ("b", 2, "process")]
    res = orchestrator.run(back, out_dir=tmp_path / "run", progress=False)
    assert res.success, res.message
    assert list(res.outputs) == ["b.y", "a.count"]
    # a YAML scenario naming the SSP still changes what the annotation set
    over = tmp_path / "over.yaml"
    over.write_text("ssp: rich.ssp\ncoupling: {scheme: jacobi}\noutput: {signals: [b.count]}\n")
    again = orchestrator.load_scenario(over)
    assert again.coupling.scheme == "jacobi" and again.coupling.extrapolation_order == 1
    assert again.output.signals == ("b.count",)


def test_a_shipped_scenario_with_analysis_survives_the_ssp_round_trip(tmp_path):
    import orchestrator
    from orchestrator.scenario.ssp import export_ssp
    from orchestrator.shipped import resolve
    sc = orchestrator.load_scenario(resolve("jeffcott_runup_half_sommerfeld"))
    assert sc.analysis and sc.output.signals
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")              # what libcosim would not run as we do
        back = orchestrator.load_scenario(export_ssp(sc, tmp_path / "j.ssp"))
    assert (back.analysis, back.output, back.coupling) == (sc.analysis, sc.output, sc.coupling)
    assert [dict(f.parameters) for f in back.fmus] == [dict(f.parameters) for f in sc.fmus]


def _ssd_with(annotation: str) -> str:
    return f"""<?xml version="1.0"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
  xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
  xmlns:rc="https://rotorcosim.org/SSP/ScenarioAnnotation" version="1.0" name="x">
 <ssd:System name="x"><ssd:Elements>
  <ssd:Component name="a" source="resources/AllTypes.fmu"/>
 </ssd:Elements></ssd:System>
 <ssd:Annotations><ssc:Annotation type="org.rotorcosim.scenario">{annotation}</ssc:Annotation></ssd:Annotations>
</ssd:SystemStructureDescription>"""


@pytest.mark.parametrize("annotation, needle", [
    ('<rc:Scenario format="1">output: {signals: [a.nope]}</rc:Scenario>', "a.nope"),
    ('<rc:Scenario format="1">stop_time: 5\nfmus: {a: {path: /etc/passwd}, z: {substeps: 2}}</rc:Scenario>',
     "unknown key 'stop_time'"),
    ('<rc:Scenario format="1">fmus: {a: {path: /etc/passwd}, z: {substeps: 2}}</rc:Scenario>',
     "'fmus.a' may set only substeps, isolation"),
    ('<rc:Scenario format="1">fmus: {z: {substeps: 2}}</rc:Scenario>', "'fmus' names 'z', which is no component"),
    ('<rc:Scenario format="2">output: {}</rc:Scenario>', "format '2'; this rotorcosim reads format 1"),
    ('<rc:Scenario format="1">a: &amp;a [*a]</rc:Scenario>', "(a recursive alias)"),
    ('<rc:Scenario format="1">' + "x" * ((1 << 20) + 1) + '</rc:Scenario>', "not a plausible scenario annotation"),
    ('<rc:Scenario format="1">' + "[" * 200 + '</rc:Scenario>', "nested more than 64 levels deep"),
])
def test_the_scenario_annotation_is_read_as_untrusted(scenario_file, tmp_path, annotation, needle):
    import zipfile

    import orchestrator
    from orchestrator.errors import ScenarioError
    p = tmp_path / "x.ssp"
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("SystemStructure.ssd", _ssd_with(annotation))
        zf.write(scenario_file.with_name("AllTypes.fmu"), "resources/AllTypes.fmu")
    with pytest.raises(ScenarioError) as info:
        orchestrator.load_scenario(p)
    assert needle in str(info.value), str(info.value)
