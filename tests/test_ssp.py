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
