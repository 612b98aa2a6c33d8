"""Fourth hostile and any-FMU probe (after tests/test_hostile_probe3.py and the other catalogues):
third-party FMUs coupled the way a co-simulation engineer couples them, and text that no UTF-8
can hold. One test per finding, each failing on the code before its fix."""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")


def _c_fmu(dest: Path, name: str, **kw) -> Path:
    spec = importlib.util.spec_from_file_location("build_c_fmu", HERE / "fmus_c" / "build_c_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.build_c_fmu(dest, name, **kw)


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
    _c_fmu(tmp_path, "AllTypes", fixed_step=True)
    p = tmp_path / "fixed.yaml"
    p.write_text("name: fixed\nstart_time: 1000000.1\nstop_time: 1000001.1\nfmus:\n"
                 "  a: {path: AllTypesFixed.fmu, parameters: {u: 1.0}}\ncoupling: {macro_step: 0.1}\n"
                 "output: {signals: [a.x, a.count]}\n")
    res = _run(p, tmp_path / "out")
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
