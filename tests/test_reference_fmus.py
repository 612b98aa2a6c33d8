"""FMI call sequences against the Modelica Reference FMUs (issue 13, point 4).

The Reference FMUs (https://github.com/modelica/Reference-FMUs, BSD-2) check every call
against the FMI 2.0 state machine and log ``fmi2<Function>: Illegal call sequence.`` with
fmi2Error otherwise. Their sources are not ours to commit and are not on PyPI, so this module
runs only where they have been built (FMI 2.0, with cmake) and their folder is named by the
environment variable ``ROTORCOSIM_REFERENCE_FMUS``::

    git clone https://github.com/modelica/Reference-FMUs && cd Reference-FMUs
    cmake -B b2 -DFMI_VERSION=2 -DCMAKE_BUILD_TYPE=Release && cmake --build b2
    ROTORCOSIM_REFERENCE_FMUS=$PWD/b2/fmus python -m pytest -q tests/test_reference_fmus.py

Every case runs our master over them (both schemes, in process and in worker processes,
iterative coupling and the error-controlled step with state save/restore, discard retries,
an FMU-requested stop, a run that fails at its 5th step in another FMU) and fails on any
logged illegal call. The first test checks that such a log line is seen at all.
The C test FMU AllTypes (tests/test_all_types.py) enforces the same state machine in the
default suite.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import pytest

from orchestrator import load_scenario, run
from orchestrator.fmi.subsystem import Subsystem

REF = os.environ.get("ROTORCOSIM_REFERENCE_FMUS")
pytestmark = pytest.mark.skipif(
    not REF, reason="set ROTORCOSIM_REFERENCE_FMUS to a folder of the FMI 2.0 Reference FMUs (see module doc)")
MODELS = ("BouncingBall", "Dahlquist", "Feedthrough", "Resource", "Stair", "VanDerPol")


def ref(name: str) -> Path:
    path = Path(REF or ".") / f"{name}.fmu"
    if not path.is_file():
        pytest.skip(f"{path} not built")
    return path


def illegal(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if "illegal call sequence" in r.getMessage().lower()]


def test_an_illegal_call_is_seen(tmp_path, caplog):
    """Positive control: a doStep before initialization is logged and caught by illegal()."""
    caplog.set_level(logging.DEBUG)
    sub = Subsystem("a", ref("Dahlquist"), work_dir=tmp_path)
    try:
        with pytest.raises(Exception, match="Illegal call sequence"):
            sub.do_step(0.0, 0.1)
    finally:
        sub.free()
    assert illegal(caplog)


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("isolation", ["none", "process"])
def test_each_reference_fmu_alone(model, isolation, tmp_path, caplog):
    caplog.set_level(logging.DEBUG)
    (tmp_path / "s.yaml").write_text(f"name: ref-{model.lower()}\nfmus:\n  a: {{path: {ref(model)}}}\n")
    res = run(load_scenario(tmp_path / "s.yaml", [f"fmus.a.isolation={isolation}"]),
              out_dir=tmp_path / "out", progress=False)
    assert res.status.short in ("finished", "stopped_by_fmu"), res.message
    assert illegal(caplog) == []


COUPLED = """name: ref-coupled
stop_time: 1.0
fmus:
  a: {{path: {Dahlquist}}}
  b: {{path: {VanDerPol}}}
  f: {{path: {Feedthrough}}}
  s: {{path: {Stair}}}
connections:
  - {{from: b.x0, to: f.Float64_continuous_input}}
  - {{from: s.counter, to: f.Int32_input}}
coupling: {{scheme: gauss-seidel, macro_step: 0.01}}
"""


@pytest.mark.parametrize("overrides", [
    [], ["coupling.scheme=jacobi"], ["coupling.isolation=process"], ["coupling.discard_retries=3"],
    ["coupling.scheme=iterative"],
    ["coupling.step_control={type: error, rtol: 1.0e-4, atol: 1.0e-6, min_step: 1.0e-5, max_step: 0.05}"],
    ["stop_time=12"],     # past Stair's own end at 9 s: the FMU stops the run
], ids=lambda o: ",".join(o) or "default")
def test_coupled_reference_fmus(overrides, tmp_path, caplog):
    caplog.set_level(logging.DEBUG)
    text = COUPLED.format(**{m: ref(m) for m in ("Dahlquist", "VanDerPol", "Feedthrough", "Stair")})
    (tmp_path / "s.yaml").write_text(text)
    res = run(load_scenario(tmp_path / "s.yaml", overrides), out_dir=tmp_path / "out", progress=False)
    assert res.status.short in ("finished", "stopped_by_fmu"), res.message
    assert illegal(caplog) == []


@pytest.mark.parametrize("isolation", ["none", "process"])
@pytest.mark.parametrize("fault", [5, 6])     # NaN output (the master stops), fmi2Error
def test_a_failing_run_ends_every_fmu_legally(isolation, fault, tmp_path, caplog):
    """Another FMU fails at its 5th step: the Reference FMUs are terminated and freed in states
    that allow it (no terminate of an FMU in error, no call after a failed step)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("build_c_fmu", Path(__file__).parent / "fmus_c" / "build_c_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    caplog.set_level(logging.DEBUG)
    bad = mod.build_c_fmu(tmp_path, "MisbehavingBearing")
    (tmp_path / "s.yaml").write_text(
        f"name: ref-fail\nstop_time: 1.0\nfmus:\n  a: {{path: {ref('Dahlquist')}}}\n"
        f"  b: {{path: {ref('VanDerPol')}}}\n  f: {{path: {ref('Feedthrough')}}}\n"
        f"  m: {{path: {bad}, parameters: {{fault: {fault}, fault_step: 5}}}}\n"
        "connections:\n  - {from: b.x0, to: m.x}\n  - {from: m.Fx, to: f.Float64_continuous_input}\n"
        "coupling: {macro_step: 0.01}\n")
    res = run(load_scenario(tmp_path / "s.yaml", [f"coupling.isolation={isolation}"]),
              out_dir=tmp_path / "out", progress=False)
    assert res.status.short == "failed", res.message
    assert illegal(caplog) == []


def test_error_controlled_step_over_a_fixed_internal_step_says_it_missed_the_tolerance(tmp_path):
    """Dahlquist integrates in fixed internal steps of 0.1 s, so its output changes in stairs; an
    error-controlled macro step cannot resolve them: it forced steps at min_step and accepted jumps
    (with rtol 1e-3: 82 and 23 of 706), and the run said only "finished". Now the message (and a
    warning) gives the count, the signal and the fix (a constant step that is a multiple of the
    FMU's own, or the signal left out of the estimate)."""
    (tmp_path / "s.yaml").write_text(
        f"name: dq\nfmus:\n  dq: {{path: {ref('Dahlquist')}}}\n  ft: {{path: {ref('Feedthrough')}}}\n"
        "connections:\n  - {from: dq.x, to: ft.Float64_continuous_input}\n"
        "coupling: {scheme: jacobi, macro_step: 0.1, extrapolation_order: 1,\n"
        "           step_control: {type: error, rtol: 1.0e-3, atol: 1.0e-4}}\noutput: {interval: 0.5}\n")
    res = run(load_scenario(tmp_path / "s.yaml"), out_dir=tmp_path / "out", progress=False)
    assert res.success, res.message
    st = res.stats["step_control"]
    assert st["over_tolerance_steps"] == st["forced_steps"] + st["jumps"] > 0
    assert f"{st['over_tolerance_steps']} of {st['accepted_steps']} accepted macro steps had a scaled error" in res.message
    assert "signals: ft.Float64_continuous_input" in res.message and "fixed internal step" in res.message
    # a constant step on the FMU's own grid: nothing to say
    res = run(load_scenario(tmp_path / "s.yaml", ["coupling.step_control={type: constant}"]),
              out_dir=tmp_path / "out2", progress=False)
    assert res.success and res.message == "finished at t=10 s after 100 macro steps"
