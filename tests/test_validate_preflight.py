"""`validate` makes every check `run` makes before its first step, with the same message."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import pytest

from orchestrator.cli import main

pytestmark = pytest.mark.integration


def _write(d: Path, name: str, text: str) -> Path:
    p = d / name
    p.write_text(text)
    return p


def _run_message(path: Path, tmp_path: Path) -> str:
    import orchestrator
    from orchestrator.errors import CosimError
    with pytest.raises(CosimError) as info:
        orchestrator.run(orchestrator.load_scenario(path), out_dir=tmp_path / "run", progress=False)
    return str(info.value)


def test_retries_need_state_saving(test_fmus, tmp_path, capsys):
    p = _write(tmp_path, "s.yaml", f"""name: retries
stop_time: 0.1
fmus:
  t: {{path: {test_fmus['TypedPorts']}}}
coupling: {{macro_step: 0.01, discard_retries: 2}}
""")
    assert main(["validate", str(p)]) == 1
    out = capsys.readouterr().out
    assert "coupling.discard_retries = 2 needs every FMU to save and restore its state" in out
    assert "coupling.discard_retries = 2 needs every FMU to save and restore its state" in _run_message(p, tmp_path)


def test_output_interval_off_the_grid_is_the_same_warning(test_fmus, tmp_path, capsys):
    p = _write(tmp_path, "s.yaml", f"""name: interval
stop_time: 0.1
fmus:
  t: {{path: {test_fmus['TypedPorts']}}}
coupling: {{macro_step: 0.01}}
output: {{interval: 0.025}}
""")
    assert main(["validate", str(p)]) == 0
    out = capsys.readouterr().out
    assert "warning: output.interval 0.025 is not a multiple of coupling.macro_step 0.01" in out


def test_missing_binary_for_this_platform(test_fmus, tmp_path, capsys):
    src = test_fmus["TypedPorts"]
    stripped = tmp_path / "NoBinary.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(stripped, "w") as zout:
        for item in zin.infolist():
            if not item.filename.startswith("binaries/"):
                zout.writestr(item, zin.read(item))
    p = _write(tmp_path, "s.yaml", f"name: nobin\nstop_time: 0.1\nfmus:\n  t: {{path: {stripped}}}\n")
    assert main(["validate", str(p)]) == 1
    out = capsys.readouterr().out
    assert "has no binary for this platform" in out
    assert "has no binary for this platform" in _run_message(p, tmp_path)


def test_monolithic_with_a_third_party_fmu(test_fmus, tmp_path, capsys):
    p = _write(tmp_path, "s.yaml", f"""name: mono
stop_time: 0.1
fmus:
  t: {{path: {test_fmus['TypedPorts']}}}
coupling: {{scheme: monolithic, macro_step: 0.01}}
""")
    assert main(["validate", str(p)]) == 1
    out = capsys.readouterr().out.strip().splitlines()[0]
    assert out and out in _run_message(p, tmp_path)


def test_valid_scenario_says_which_defaults_were_taken(test_fmus, tmp_path, capsys):
    if shutil.which("gcc") is None:
        pytest.skip("gcc not installed (native test FMU)")
    import importlib.util
    spec = importlib.util.spec_from_file_location("b", Path(__file__).parent / "fmus_c" / "build_c_fmu.py")
    b = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(b)
    fmu = b.build_c_fmu(tmp_path, "AllTypes")
    p = _write(tmp_path, "s.yaml", f"name: d\nfmus:\n  a: {{path: {fmu}}}\n")
    assert main(["validate", str(p)]) == 0
    out = capsys.readouterr().out
    assert "stop_time = 1.0 (DefaultExperiment stopTime of 'a')" in out
    assert "coupling.macro_step = 0.1 (DefaultExperiment stepSize of 'a')" in out


def test_a_parameter_the_fmu_refuses_at_initialization(tmp_path, capsys):
    """FMI initialization is part of what `run` does before its first step: an FMU that refuses
    its values there (our bearing: p_feed below p0, a rule across two parameters that no
    declared range can express) makes `validate` fail with run's message."""
    import orchestrator
    from orchestrator.shipped import resolve
    path = resolve("quickstart")
    override = "fmus.bearing1.parameters.p_feed=5.0e4"
    assert main(["validate", str(path), "--set", override]) == 1
    out = capsys.readouterr().out
    expected = "parameter 'p_feed' must be >= p0 (a groove feeds oil)"      # in the FMU's parameter names
    assert "initialization failed: FMU instance 'bearing1'" in out and expected in out
    res = orchestrator.run(orchestrator.load_scenario(path, overrides=[override], build_fmus=True),
                           out_dir=tmp_path / "run", progress=False)
    assert res.status.name == "FAILED" and expected in res.message
    assert main(["validate", str(path)]) == 0       # the shipped values initialize


def test_validate_writes_no_fields_file(tmp_path, monkeypatch, capsys):
    """`validate` checks without running: a String parameter '{out_dir}/...' (the shipped stationary
    scenarios' fields_file, written by the bearing at fmi2Terminate) must not leave a folder named
    '{out_dir}' in the current folder (it did: preflight set the text unsubstituted)."""
    path = Path(__file__).resolve().parents[1] / "scenarios" / "stationary_oil_bath.yaml"
    assert '"{out_dir}/' in path.read_text()
    monkeypatch.chdir(tmp_path)
    assert main(["validate", str(path)]) == 0
    assert "valid" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == []
