"""Interoperability: our FMUs in libcosim (libcosimpy) against our own master.

libcosim's fixed-step algorithm steps all slaves over the same step with the
inputs their peers produced at the start of the step (Jacobi, zero-order
hold). Our master with ``scheme: jacobi``, extrapolation order 0 and the same
step must give the same journal motion to round-off.

libcosim runs in a subprocess (this file executed as a script): a process that
loaded Python FMUs through both FMPy and libcosim once aborted at exit.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve()
REPO = HERE.parents[1]


# ------------------------------------------------------------------ libcosim side
def run_libcosim(config: dict, out: Path) -> dict[str, np.ndarray]:
    """Run ``config`` with libcosim in a subprocess; return ``{"time": ..., "inst.var": ...}``.

    config: ``{"fmus": {inst: path}, "parameters": {inst: {var: value}},
    "connections": [["a.y", "b.u"], ...], "step": h, "n_steps": n, "record": ["inst.var", ...]}``.
    """
    cfg = out.with_suffix(".json")
    cfg.write_text(json.dumps(config))
    proc = subprocess.run([sys.executable, str(HERE), "--libcosim", str(cfg), str(out)],
                          capture_output=True, text=True, timeout=900)
    if proc.returncode != 0:
        raise RuntimeError(f"libcosim run failed (exit {proc.returncode}):\n{proc.stdout[-3000:]}\n"
                           f"{proc.stderr[-3000:]}")
    data = np.load(out)
    return {k: data[k] for k in data.files}


def _libcosim_main(cfg_path: str, out_path: str) -> None:
    from fmpy import read_model_description
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    cfg = json.loads(Path(cfg_path).read_text())
    h, n = float(cfg["step"]), int(cfg["n_steps"])
    step_ns = round(h * 1e9)
    assert abs(step_ns * 1e-9 - h) < 1e-15, "the step must be a whole number of nanoseconds"
    ex = CosimExecution.from_step_size(step_ns)
    index, mds = {}, {}
    for inst, path in cfg["fmus"].items():
        index[inst] = ex.add_local_slave(CosimLocalSlave(fmu_path=str(path), instance_name=inst))
        mds[inst] = {v.name: v for v in read_model_description(path).modelVariables}
    for inst, values in cfg.get("parameters", {}).items():
        for var, value in values.items():
            v = mds[inst][var]
            if v.type == "Real":
                ok = ex.real_initial_value(index[inst], v.valueReference, float(value))
            elif v.type == "Integer":
                ok = ex.integer_initial_value(index[inst], v.valueReference, int(value))
            elif v.type == "Boolean":
                ok = ex.boolean_initial_value(index[inst], v.valueReference, bool(value))
            else:
                ok = ex.string_initial_value(index[inst], v.valueReference, str(value))
            assert ok, f"libcosim refused the initial value {inst}.{var} = {value!r}"
    for src, dst in cfg["connections"]:
        si, sv = src.split(".", 1)
        di, dv = dst.split(".", 1)
        rc = ex.connect_real_variables(index[si], mds[si][sv].valueReference,
                                       index[di], mds[di][dv].valueReference)
        if rc != 0:                        # libcosim status code, 0 = success
            from libcosimpy._internal import get_last_error_message
            raise AssertionError(f"libcosim refused the connection {src} -> {dst}: {get_last_error_message()}")
    obs = CosimObserver.create_time_series()
    ex.add_observer(obs)
    for sig in cfg["record"]:
        inst, var = sig.split(".", 1)
        obs.start_time_series(index[inst], mds[inst][var].valueReference, CosimVariableType.REAL)
    # libcosimpy trims the sample arrays by the number of zero step numbers, which drops one
    # real sample (step 0 has number 0): take one step more and read steps 0..n
    if not ex.step(n + 1):
        from libcosimpy._internal import get_last_error_message
        raise AssertionError(f"libcosim step failed: {get_last_error_message()}")
    result = {}
    for sig in cfg["record"]:
        inst, var = sig.split(".", 1)
        times, steps, values = obs.time_series_real_samples(
            index[inst], mds[inst][var].valueReference, from_step=0, sample_count=n + 2)
        assert list(steps[: n + 1]) == list(range(n + 1)), "unexpected libcosim sample layout"
        result[sig] = np.asarray(values[: n + 1], float)
        result["time"] = np.asarray(times[: n + 1], float) * 1e-9
        result["step_number"] = np.asarray(steps[: n + 1])
    np.savez(out_path, **result)
    del obs
    del ex


def _libcosim_ssp_main(ssp: str, cfg_path: str, out_path: str) -> None:
    """libcosim runs the SSP archive ``ssp`` (``CosimExecution.from_ssp_file``) for ``n_steps``
    steps of ``step`` s and records the last values of ``record`` after each step."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    cfg = json.loads(Path(cfg_path).read_text())
    ex = CosimExecution.from_ssp_file(ssp, step_size=round(float(cfg["step"]) * 1e9))
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    insts = {sig.split(".", 1)[0] for sig in cfg["record"]}
    index = {n: ex.slave_index_from_instance_name(n) for n in insts}
    refs = {n: {v.name.decode(): v.reference for v in ex.slave_variables(i)} for n, i in index.items()}
    rows: dict[str, list] = {sig: [] for sig in cfg["record"]}
    for _ in range(int(cfg["n_steps"])):
        if not ex.step(1):
            from libcosimpy._internal import get_last_error_message
            raise AssertionError(f"libcosim step failed: {get_last_error_message()}")
        for sig in cfg["record"]:
            inst, var = sig.split(".", 1)
            rows[sig].append(obs.last_real_values(index[inst], [refs[inst][var]])[0])
    np.savez(out_path, **{k: np.asarray(v, float) for k, v in rows.items()})


if __name__ == "__main__" and len(sys.argv) == 5 and sys.argv[1] == "--libcosim-ssp":
    _libcosim_ssp_main(sys.argv[2], sys.argv[3], sys.argv[4])
    sys.stdout.flush()
    sys.stderr.flush()
    import os
    os._exit(0)

if __name__ == "__main__" and len(sys.argv) == 4 and sys.argv[1] == "--libcosim":
    _libcosim_main(sys.argv[2], sys.argv[3])
    # leave without the interpreter's teardown, where PythonFMU 0.7.0 FMUs abort intermittently
    # ("corrupted double-linked list", SIGABRT; seen here in CI after the results were saved):
    # the same exit as orchestrator.cli.console_main; a crash during the run still fails
    sys.stdout.flush()
    sys.stderr.flush()
    import os
    os._exit(0)


# ------------------------------------------------------------------ the tests
def _connections() -> list[list[str]]:
    conns = []
    for i in (1, 2):
        for v in ("x", "y", "vx", "vy"):
            conns.append([f"rotor.{v}_{i}", f"bearing{i}.{v}"])
        conns.append(["rotor.omega", f"bearing{i}.omega"])
        conns.append([f"bearing{i}.Fx", f"rotor.Fx_{i}"])
        conns.append([f"bearing{i}.Fy", f"rotor.Fy_{i}"])
    return conns


# A short Jeffcott start-up on two half-Sommerfeld bearings (quasi-static film: the
# bearings' outputs depend on their inputs only, so initialization order matters
# only through the initial exchange).
H = 5e-6
N_STEPS = 400
ROTOR = {"f_max": 300.0, "t_ramp": 0.01, "journal_y0": -2.0e-6}
BEARING = {"R": 0.005, "B": 0.008, "cavitation": 0, "n_phi": 24, "n_z": 12}
RECORD = ["rotor.x_1", "rotor.y_1", "rotor.vx_1", "rotor.vy_1", "rotor.y_2", "bearing1.Fx", "bearing1.Fy",
          "bearing2.Fy", "rotor.omega"]


def _scenario_yaml(paths: dict[str, Path]) -> str:
    import yaml
    doc = {
        "name": "interop_jeffcott_hs", "version": 1, "start_time": 0.0, "stop_time": H * N_STEPS,
        "fmus": {"rotor": {"path": str(paths["JeffcottRotor"]), "parameters": ROTOR},
                 "bearing1": {"path": str(paths["JournalBearing"]), "parameters": BEARING},
                 "bearing2": {"path": str(paths["JournalBearing"]), "parameters": BEARING}},
        "connections": [{"from": a, "to": b} for a, b in _connections()],
        "coupling": {"scheme": "jacobi", "macro_step": H, "extrapolation_order": 0},
        "output": {"interval": H, "signals": RECORD},
    }
    return yaml.safe_dump(doc, sort_keys=False)


@pytest.fixture(scope="module")
def interop_fmus(tmp_path_factory) -> dict[str, Path]:
    import importlib.util
    if importlib.util.find_spec("bearing_fmu.model") is None:
        pytest.skip("bearing_fmu.model not available yet")
    from orchestrator.fmi.build import build_fmus
    out = tmp_path_factory.mktemp("interop_fmus")
    return {p.stem: p for p in build_fmus(out, force=True, names=["JournalBearing", "JeffcottRotor"])}


@pytest.mark.integration
def test_libcosim_and_our_jacobi_master_agree(interop_fmus, tmp_path):
    import orchestrator
    if not hasattr(orchestrator, "run"):
        pytest.skip("orchestrator.run not available yet")
    config = {"fmus": {"rotor": str(interop_fmus["JeffcottRotor"]),
                       "bearing1": str(interop_fmus["JournalBearing"]),
                       "bearing2": str(interop_fmus["JournalBearing"])},
              "parameters": {"rotor": ROTOR, "bearing1": BEARING, "bearing2": BEARING},
              "connections": _connections(), "step": H, "n_steps": N_STEPS, "record": RECORD}
    lc = run_libcosim(config, tmp_path / "libcosim.npz")
    assert lc["time"].size == N_STEPS + 1
    np.testing.assert_allclose(lc["time"], H * np.arange(N_STEPS + 1), rtol=0, atol=1e-12)

    yml = tmp_path / "interop.yaml"
    yml.write_text(_scenario_yaml(interop_fmus))
    sc = orchestrator.load_scenario(yml)
    res = orchestrator.run(sc, out_dir=tmp_path / "ours", progress=False)
    assert res.success, res.message
    t = np.asarray(res.t)
    # compare on the common time grid (both record every macro step)
    idx_ours = np.searchsorted(t, lc["time"] - 1e-12)
    assert np.allclose(t[idx_ours], lc["time"], atol=1e-12)
    moved = 0.0
    for sig in RECORD:
        a, b = lc[sig], np.asarray(res.outputs[sig])[idx_ours]
        scale = max(np.max(np.abs(a)), 1e-300)
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-9 * scale, err_msg=sig)
        if sig == "rotor.y_1":
            moved = np.ptp(a)
    assert moved > 1e-7          # the journal really moved: the comparison is not trivial


# ------------------------------------------------------- a third-party bearing FMU
THIRD_PARTY_BEARING = '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class SpringDamperBearing(Fmi2Slave):
    """A linear 'bearing' by another author: F = -k r - d v, plain attributes, no state hooks."""

    author = "someone else"
    description = "isotropic spring-damper support with the JournalBearing interface"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.k = 2.0e7
        self.d = 2.0e4
        self.x = self.y = self.vx = self.vy = self.omega = 0.0
        self.Fx = self.Fy = 0.0
        for name in ("k", "d"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter))
        for name in ("x", "y", "vx", "vy", "omega"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("Fx", "Fy"):
            self.register_variable(Real(name, causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.Fx = -self.k * self.x - self.d * self.vx
        self.Fy = -self.k * self.y - self.d * self.vy
        return True
'''


@pytest.mark.integration
def test_third_party_bearing_replaces_ours_by_editing_the_yaml(tmp_path):
    """scenarios/quickstart.yaml with both bearings swapped for another author's FMU:
    only the YAML changes (path, its parameters, the recorded signals, and the
    interface-Jacobian connections the other FMU does not offer)."""
    import yaml
    from pythonfmu.builder import FmuBuilder

    import orchestrator
    if not hasattr(orchestrator, "run"):
        pytest.skip("orchestrator.run not available yet")
    src = tmp_path / "spring_damper_bearing.py"
    src.write_text(THIRD_PARTY_BEARING)
    fmu = Path(FmuBuilder.build_FMU(src, dest=tmp_path))
    doc = yaml.safe_load((REPO / "scenarios" / "quickstart.yaml").read_text())
    assert doc["fmus"]["rotor"]["fmu"] == "JeffcottRotor"     # ours by name: no path to fix up
    for b in ("bearing1", "bearing2"):
        doc["fmus"][b] = {"path": str(fmu), "parameters": {"k": 2.0e7, "d": 2.0e4}}
    doc["output"]["signals"] = [s for s in doc["output"]["signals"] if not s.startswith("bearing")] + [
        "bearing1.Fy", "bearing2.Fy"]
    doc["analysis"]["journals"] = {b: {"x": f"rotor.x_{i}", "y": f"rotor.y_{i}", "clearance": 1.372e-5}
                                   for i, b in ((1, "bearing1"), (2, "bearing2"))}
    # it has no film coefficients: plain coupling, with a step its damping allows (H < 2 m / d)
    doc["connections"] = [c for c in doc["connections"] if c["from"].split(".")[1] in ("Fx", "Fy")
                          or c["from"].startswith("rotor.")]
    doc["coupling"]["macro_step"] = 2.0e-5
    doc["start_time"], doc["stop_time"] = 0.5, 0.53
    yml = tmp_path / "quickstart_third_party.yaml"
    yml.write_text(yaml.safe_dump(doc, sort_keys=False))
    sc = orchestrator.load_scenario(yml)
    res = orchestrator.run(sc, out_dir=tmp_path / "run", progress=False)
    assert res.success, res.message
    # the journals settle where the springs carry the weight: 2 k |y| = (m_disc + 2 m_journal) g
    y1 = np.asarray(res.outputs["rotor.y_1"])
    fy = np.asarray(res.outputs["bearing1.Fy"]) + np.asarray(res.outputs["bearing2.Fy"])
    assert fy[-1] == pytest.approx(6.0 * 9.81, rel=0.05)
    assert y1[-1] == pytest.approx(-fy[-1] / 2 / 2.0e7, rel=0.05)


# ------------------------------------------- an exported SSP that carries the file a parameter names
@pytest.mark.integration
def test_libcosim_runs_an_exported_ssp_that_carries_a_rotor_file(tmp_path, monkeypatch):
    """export-ssp puts the file a String parameter names into the archive (resources/files/...) and
    writes that member's name as the value. libcosim loads such an archive (the extra member and the
    org.rotorcosim.scenario annotation are ignored) and passes the value on as it is, which the FMU
    opens relative to libcosim's working directory: run from the folder where the archive is unzipped,
    libcosim gives our Jacobi master's numbers (which runs the archive anywhere); from elsewhere the
    FMU cannot open the file and says which (docs/limits.md, "Files rotorcosim writes")."""
    pytest.importorskip("libcosimpy")
    import warnings
    import zipfile

    import orchestrator
    from orchestrator.scenario.ssp import export_ssp
    from orchestrator.shipped import resolve
    src = tmp_path / "src"
    src.mkdir()
    text = (REPO / "rotor_fmu" / "data" / "turbocharger.yaml").read_text()
    (src / "my_rotor.yaml").write_text(text.replace("unbalance: 1.5e-6", "unbalance: 3.0e-6", 1))
    monkeypatch.chdir(src)
    n, h = 50, 1e-4
    sc = orchestrator.load_scenario(resolve("turbocharger_runup_half_sommerfeld"), [
        "fmus.rotor.parameters.rotor_file=my_rotor.yaml", "coupling.scheme=jacobi", f"stop_time={2.0 + n * h}",
        f"output.interval={h}"], build_fmus=True)
    assert sc.coupling.extrapolation_order == 0 and sc.coupling.macro_step == h
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                     # start values libcosim ignores: none here
        ssp = export_ssp(sc, tmp_path / "tc.ssp")
    member = "resources/files/rotor/my_rotor.yaml"
    unzipped = tmp_path / "unzipped"
    with zipfile.ZipFile(ssp) as zf:
        assert member in zf.namelist()
        zf.extractall(unzipped)
    record = ["rotor.x_1", "rotor.y_1", "rotor.x_comp", "rotor.y_turb", "bearing1.Fy", "bearing2.Fx"]
    cfg = tmp_path / "lc.json"
    cfg.write_text(json.dumps({"step": h, "n_steps": n, "record": record}))
    proc = subprocess.run([sys.executable, str(HERE), "--libcosim-ssp", str(ssp), str(cfg), str(tmp_path / "lc.npz")],
                          cwd=unzipped, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    lc = np.load(tmp_path / "lc.npz")
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.chdir(empty)                  # our master runs the archive from any folder
    res = orchestrator.run(orchestrator.load_scenario(ssp), out_dir=tmp_path / "ours", progress=False)
    assert res.success, res.message
    assert len(res.t) == n + 1
    for sig in record:
        ours = np.asarray(res.outputs[sig])[1:]
        scale = np.max(np.abs(lc[sig]))
        np.testing.assert_allclose(ours, lc[sig], rtol=0, atol=1e-9 * scale, err_msg=sig)
    assert np.ptp(lc["rotor.x_comp"]) > 1e-8            # the rotor moved: the comparison is not trivial
    # from a folder without the unzipped archive the FMU cannot open the member libcosim passes it
    proc = subprocess.run([sys.executable, str(HERE), "--libcosim-ssp", str(ssp), str(cfg), str(tmp_path / "x.npz")],
                          cwd=empty, capture_output=True, text=True, timeout=900)
    assert proc.returncode != 0
    assert f"invalid rotor file {member}" in proc.stdout + proc.stderr, proc.stdout[-3000:] + proc.stderr[-3000:]
