"""``rotorcosim compare``: a variant (or a co-simulation reference) that the FMUs cannot run is
refused when the file is loaded (exit 2, the variant group's line), before any run.

Found with third-party FMUs (crane-fmu's HarmonicOscillator6D, PythonFMU without
canGetAndSetFMUstate): an ``iterative`` variant ran after the reference and was reported as
*unstable* with infinite error, a verdict on the coupling scheme where the FMUs simply cannot
save their state. The master's own checks (coupling/execution.py) are the same; the scenario
loader's (scenario/coupling_sections.py) never saw the variants' couplings.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from orchestrator.compare import load_compare, main_compare

pytestmark = pytest.mark.integration


def _never_runs(scenario, out_dir: Path) -> None:       # the comparison must stop before any run
    raise AssertionError(f"a run was started ({scenario.coupling.scheme}) although the file is invalid")


def _two_mass(tmp_path: Path, left: Path, right: Path, coupling: str = "{scheme: gauss-seidel, macro_step: 0.1}",
              file: str = "two_mass.yaml") -> Path:
    """The two-mass scenario (rows every 0.2 s, stop 1 s) in ``tmp_path / file``; ``coupling`` is the text
    after ``coupling:`` (a flow mapping, or a block starting with a newline). Its line 11 is ``coupling:``."""
    p = tmp_path / file
    p.write_text(f"""
name: two-mass
stop_time: 1.0
fmus:
  left: {{path: {left}}}
  right: {{path: {right}}}
connections:
  - {{from: left.x1, to: right.x1}}
  - {{from: left.v1, to: right.v1}}
  - {{from: right.F, to: left.F}}
coupling: {coupling}
output: {{interval: 0.2}}
""")
    return p


def _compare(tmp_path: Path, reference: str, groups: str) -> Path:
    p = tmp_path / "cmp.yaml"
    p.write_text(f"""compare:
  scenario: two_mass.yaml
  signals: [left.x1]
  reference: {reference}
  variants:
{groups}""")
    return p


def test_variants_the_fmus_cannot_save_state_for_are_refused_at_load(test_fmus, tmp_path, capsys):
    # StepLimitedMass is LeftMass built without canGetAndSetFMUstate (tests/conftest.py)
    _two_mass(tmp_path, test_fmus["StepLimitedMass"], test_fmus["RightMass"])
    path = _compare(tmp_path, "{scheme: iterative, macro_step: 0.01}",
                    "    - {scheme: gauss-seidel, extrapolation_order: 1, macro_step: [0.2, 0.1]}\n"
                    "    - {scheme: iterative, macro_step: 0.1}\n"
                    "    - {name: gs-retry, scheme: gauss-seidel, macro_step: 0.1,\n"
                    "       set: {coupling.discard_retries: 2}}\n"
                    # defect_retries redoes steps from saved states as discard_retries does: the same refusal
                    "    - {name: gs-defect, scheme: gauss-seidel, macro_step: 0.1,\n"
                    "       set: {coupling.defect_retries: 3}}\n")
    assert main_compare(path, out_dir=tmp_path / "out", runner=_never_runs, workers=1) == 2
    err = capsys.readouterr().err
    assert "cmp.yaml:4: 'compare.reference' cannot run with these FMUs: 'coupling.scheme: iterative'" in err
    assert ("cmp.yaml:7: 'compare.variants[1]' variant 'it-e0i0-h0.1' cannot run with these FMUs: "
            "'coupling.scheme: iterative' repeats every macro step from saved FMU states, but 'left' cannot "
            "save them (canGetAndSetFMUstate is false); use gauss-seidel or jacobi") in err
    assert ("cmp.yaml:8: 'compare.variants[2]' variant 'gs-retry' cannot run with these FMUs: "
            "coupling.discard_retries = 2 needs every FMU to save and restore its state") in err
    assert "set coupling.discard_retries: 0" in err
    assert ("cmp.yaml:10: 'compare.variants[3]' variant 'gs-defect' cannot run with these FMUs: "
            "coupling.defect_retries = 3 needs every FMU to save and restore its state") in err
    assert "set coupling.defect_retries: 0" in err
    assert "gs-e1i0" not in err                          # the explicit variants are fine
    assert not (tmp_path / "out" / "runs").exists()


def test_the_same_variants_load_when_every_fmu_can_save_state(test_fmus, tmp_path):
    _two_mass(tmp_path, test_fmus["LeftMass"], test_fmus["RightMass"])      # both canGetAndSetFMUstate
    spec = load_compare(_compare(tmp_path, "{scheme: iterative, macro_step: 0.01}",
                                 "    - {scheme: iterative, macro_step: 0.1}\n"
                                 "    - {name: gs-retry, scheme: gauss-seidel, macro_step: 0.1,\n"
                                 "       set: {coupling.discard_retries: 2}}\n"))
    assert [v.name for v in spec.variants] == ["it-e0i0-h0.1", "gs-retry"]


def test_an_error_controlled_variant_with_discard_retries_is_refused_at_load(test_fmus, tmp_path, capsys):
    """``step_control: {type: error}`` with ``discard_retries > 0`` is refused whatever the FMUs
    (the error-controlled step has its own rejection): the scenario loader refused it, compare's
    own copy of the rules did not, so over FMUs that save their state such a variant loaded and
    failed only when its run started. Now compare applies the loader's rules."""
    _two_mass(tmp_path, test_fmus["LeftMass"], test_fmus["RightMass"])      # both canGetAndSetFMUstate
    path = _compare(tmp_path, "{scheme: gauss-seidel, macro_step: 0.01}",
                    "    - {scheme: gauss-seidel, macro_step: [0.2, 0.1]}\n"
                    "    - {name: err-retry, scheme: gauss-seidel, macro_step: 0.1,\n"
                    "       set: {coupling.step_control.type: error, coupling.discard_retries: 1}}\n")
    assert main_compare(path, out_dir=tmp_path / "out", runner=_never_runs, workers=1) == 2
    err = capsys.readouterr().err
    assert ("cmp.yaml:7: 'compare.variants[1]' variant 'err-retry' cannot run with these FMUs: "
            "coupling.step_control type error and coupling.discard_retries cannot be combined (the "
            "error-controlled step has its own rejection); set discard_retries: 0") in err
    assert "gs-e0i0" not in err and "compare.reference" not in err
    assert not (tmp_path / "out" / "runs").exists()


def test_an_error_controlled_variant_over_stateless_fmus_loads_with_the_loaders_warning(test_fmus, tmp_path,
                                                                                      caplog):
    """Without state saving the error-controlled step adapts forward only: not refused (as by the
    loader), and the loader's warning is logged with the variant's line."""
    import logging
    _two_mass(tmp_path, test_fmus["StepLimitedMass"], test_fmus["RightMass"])
    path = _compare(tmp_path, "{scheme: gauss-seidel, macro_step: 0.01}",
                    "    - {name: gs-err, scheme: gauss-seidel, macro_step: 0.1,\n"
                    "       set: {coupling.step_control.type: error}}\n")
    with caplog.at_level(logging.WARNING, logger="orchestrator.compare"):
        spec = load_compare(path)
    assert [v.name for v in spec.variants] == ["gs-err"]
    said = [r.getMessage() for r in caplog.records if "adapts forward" in r.getMessage()]
    assert said and "cmp.yaml:6: 'compare.variants[0]' variant 'gs-err' runs with a warning: " \
                    "'coupling.step_control: {type: error}': 'left' cannot save and restore its state" in said[0], said


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")
def test_variants_a_fixed_step_fmu_cannot_take_are_refused_at_load(tmp_path, capsys):
    from tests.fmus_c.build_c_fmu import build_c_fmu
    fixed = build_c_fmu(tmp_path, "AllTypes", fixed_step=True)     # canHandleVariableCommunicationStepSize false
    (tmp_path / "fixed.yaml").write_text(f"""
name: fixed
stop_time: 1.0
fmus:
  a: {{path: {fixed}}}
coupling: {{macro_step: 0.1}}
output: {{signals: [a.x]}}
""")
    path = tmp_path / "cmp.yaml"
    path.write_text("""compare:
  scenario: fixed.yaml
  signals: [a.x]
  reference: {macro_step: 0.05}
  variants:
    - {scheme: jacobi, macro_step: [0.2, 0.1]}
    - {name: err, scheme: jacobi, macro_step: 0.1, set: {coupling.step_control.type: error}}
    - {name: off-grid, scheme: jacobi, macro_step: 0.1, set: {stop_time: 1.05}}
""")
    assert main_compare(path, out_dir=tmp_path / "out", runner=_never_runs, workers=1) == 2
    err = capsys.readouterr().err
    assert ("cmp.yaml:7: 'compare.variants[1]' variant 'err' cannot run with these FMUs: 'coupling.step_control: "
            "{type: error}' varies the macro step, but 'a' cannot take varying steps") in err
    assert ("cmp.yaml:8: 'compare.variants[2]' variant 'off-grid' cannot run with these FMUs: stop_time 1.05 is "
            "not on the macro-step grid") in err
    assert "'jac-e0i0-h0.2'" not in err and "compare.reference" not in err


def test_a_monolithic_reference_of_models_it_does_not_know_is_refused_at_load(test_fmus, tmp_path, capsys):
    """``reference`` left out means the monolithic reference, which knows our rotor and bearing
    models (and the two-mass test FMUs, registered by tests/conftest.py) only. Over the Gain FMU
    (or crane-fmu's oscillators) every variant ran, and then the comparison ended with "the
    reference run failed"."""
    (tmp_path / "gains.yaml").write_text(f"""
name: gains
stop_time: 1.0
fmus:
  g1: {{path: {test_fmus['Gain']}}}
  g2: {{path: {test_fmus['Gain']}}}
connections:
  - {{from: g1.y, to: g2.u}}
coupling: {{macro_step: 0.1}}
""")
    path = tmp_path / "cmp.yaml"
    path.write_text("compare:\n  scenario: gains.yaml\n  signals: [g2.y]\n"
                    "  variants:\n    - {scheme: jacobi, macro_step: [0.2, 0.1]}\n")
    assert main_compare(path, out_dir=tmp_path / "out", runner=_never_runs, workers=1) == 2
    err = capsys.readouterr().err
    assert ("'compare.reference' is the monolithic reference (the default when 'reference' is left out), which "
            "has no model of 'g1' (modelName 'Gain'), 'g2' (modelName 'Gain')") in err
    assert "'reference: {scheme: gauss-seidel, extrapolation_order: 1, interpolation_order: 1, macro_step: 0.01}'" in err
    # the fix it gives loads
    path.write_text(path.read_text() + "  reference: {scheme: gauss-seidel, extrapolation_order: 1, "
                    "interpolation_order: 1, macro_step: 0.01}\n")
    assert load_compare(path).reference.changes["coupling.macro_step"] == 0.01


@pytest.mark.parametrize("listed", [False, True])
def test_a_string_signal_is_refused_at_load(test_fmus, tmp_path, capsys, listed):
    """'signals: [ft.String_output]' (the Reference FMU Feedthrough) made every error 'inf': the
    reference 'failed its convergence check' and every variant was 'unstable'. A text has no
    numeric error; Integer and Boolean signals are compared as numbers."""
    signals = "\noutput: {signals: [t.s_out, t.count, t.b_out]}" if listed else ""
    (tmp_path / "typed.yaml").write_text(f"name: typed\nstop_time: 1.0\nfmus:\n  t: {{path: {test_fmus['TypedPorts']}}}\n"
                                         f"coupling: {{macro_step: 0.1}}{signals}\n")
    path = tmp_path / "cmp.yaml"
    path.write_text("compare:\n  scenario: typed.yaml\n  signals: [t.count, t.s_out, t.b_out]\n"
                    "  reference: {scheme: jacobi, macro_step: 0.05}\n"
                    "  variants:\n    - {scheme: jacobi, macro_step: [0.2, 0.1]}\n")
    assert main_compare(path, out_dir=tmp_path / "out", runner=_never_runs, workers=1) == 2
    err = capsys.readouterr().err
    assert ("cmp.yaml:3: 'compare.signals' entry 't.s_out' is a String variable, which has no numeric error to "
            "measure") in err
    assert "'t.count'" not in err and "'t.b_out'" not in err
