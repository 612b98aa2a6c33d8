"""coupling.discard_retries: a macro step an FMU discards (fmi2Discard) is redone
from the saved FMU states and coupling history in halves, down to H / 2^N.

The discarding FMU is tests/fmus_src/step_limited_mass.py (LeftMass that
discards steps longer than h_max in a time window and leaves NaN states behind,
so a missing restore shows), built here with canGetAndSetFMUstate; its partner
is RightMass. Both integrate their step exactly, so with hold extrapolation
(k = 0) a run whose every macro step H is split into H/4 must equal a run with
macro step H/4 to round-off.
"""

from __future__ import annotations

import json
import logging
import shutil
import textwrap
from pathlib import Path

import numpy as np
import pytest

from orchestrator import run
from orchestrator.errors import ScenarioError
from orchestrator.coupling.execution import MasterAlgorithm
from orchestrator.results import Status
from orchestrator.scenario import (ConnectionSpec, CouplingSpec, FmuSpec, OutputSpec, Scenario, load_scenario)

pytestmark = pytest.mark.integration

P = dict(m1=1.0, k1=10.0, m2=1.0, k2=1000.0, d2=1.0, kc=100.0, dc=1.0)


@pytest.fixture(scope="module")
def limited_fmu(tmp_path_factory):
    """StepLimitedMass.fmu with canGetAndSetFMUstate (tests/conftest.py builds it without)."""
    from pythonfmu.builder import FmuBuilder
    src = Path(__file__).parent / "fmus_src" / "step_limited_mass.py"
    return Path(FmuBuilder.build_FMU(src, dest=tmp_path_factory.mktemp("retry_fmu"), canGetAndSetFMUstate=True,
                                     project_files={src.parent / "left_mass.py"}))


def two_mass(limited, fmus, *, H, retries=0, scheme="gauss-seidel", first="left", k=0, q=1, T=0.2,
             h_max=1e9, window=(0.0, 1e9), interval=None):
    left = FmuSpec(name="left", path=limited,
                   parameters=dict(m1=P["m1"], k1=P["k1"], x1_0=1.0, h_max=h_max, t_lo=window[0], t_hi=window[1]))
    right = FmuSpec(name="right", path=fmus["RightMass"],
                    parameters={k_: P[k_] for k_ in ("m2", "k2", "d2", "kc", "dc")})
    order = (left, right) if first == "left" else (right, left)
    return Scenario(
        name="two-mass-retry", stop_time=T, fmus=order,
        connections=(ConnectionSpec(src="left.x1", dst="right.x1"), ConnectionSpec(src="left.v1", dst="right.v1"),
                     ConnectionSpec(src="right.F", dst="left.F")),
        coupling=CouplingSpec(scheme=scheme, sequence=tuple(f.name for f in order), macro_step=H,
                              extrapolation_order=k, interpolation_order=q, discard_retries=retries),
        output=OutputSpec(interval=interval, signals=("left.x1", "left.v1", "right.x2", "right.F")))


def assert_same(a, b, atol):
    assert np.array_equal(a.t, b.t) or np.allclose(a.t, b.t, rtol=0, atol=1e-15)
    for key in a.outputs:
        np.testing.assert_allclose(a.outputs[key], b.outputs[key], rtol=0, atol=atol, err_msg=key)


# ---------------------------------------------------------------- default 0 unchanged
def test_default_zero_stops_on_discard_as_before(test_fmus, tmp_path):
    """Faulty (mode 0) discards from t=0.05 on: with the default the run stops with the old message."""
    sc = Scenario(name="chain", stop_time=0.1,
                  fmus=(FmuSpec(name="src", path=test_fmus["Faulty"], parameters={"t_fail": 0.05, "mode": 0}),
                        FmuSpec(name="gain", path=test_fmus["Gain"], parameters={"k": 2.0})),
                  connections=(ConnectionSpec(src="src.y", dst="gain.u"),),
                  coupling=CouplingSpec(macro_step=0.01))
    assert sc.coupling.discard_retries == 0
    res = run(sc, out_dir=tmp_path, progress=False)
    assert res.status is Status.FAILED
    assert res.message.startswith("FMU instance 'src' could not complete the step (fmi2Discard) in fmi2DoStep "
                                  "during the macro step from t=0.05 s to t=0.06 s (")
    assert "Rows up to t=0.05 s are kept" in res.message and "halving" not in res.message
    assert res.end_time == pytest.approx(0.05) and res.t[-1] == pytest.approx(0.05)
    st = res.stats
    assert (st["rejected_steps"], st["retried_steps"], st["retry_substeps"]) == (0, 0, 0)
    assert "getFMUstate" not in st["fmu_calls"]["src"] and st["fmu_calls"]["src"]["doStep"] == 6
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "failed" and s["message"] == res.message and s["coupling"]["discard_retries"] == 0


def test_retries_enabled_but_never_needed_give_identical_results(limited_fmu, test_fmus, tmp_path):
    """Saving states each macro step (and noSetFMUStatePriorToCurrentPoint=false) changes nothing."""
    a = run(two_mass(limited_fmu, test_fmus, H=2e-3, k=2, q=2), out_dir=tmp_path / "a", progress=False)
    b = run(two_mass(limited_fmu, test_fmus, H=2e-3, k=2, q=2, retries=3), out_dir=tmp_path / "b", progress=False)
    assert a.success and b.success, (a.message, b.message)
    assert_same(a, b, atol=0.0)
    assert b.stats["retried_steps"] == 0 and b.stats["fmu_calls"]["left"]["getFMUstate"] >= 100


# ---------------------------------------------------------------- retries succeed
@pytest.mark.parametrize("scheme", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("first", ["left", "right"])
def test_every_step_split_equals_the_small_step_run(limited_fmu, test_fmus, tmp_path, caplog, scheme, first):
    """h_max = H/4 everywhere: every macro step needs 2 halvings. With first='right' the
    discarding FMU is stepped second, so the other FMU (already stepped) must be restored too."""
    H, h = 4e-3, 1e-3
    caplog.set_level(logging.INFO, logger="orchestrator.coupling")
    res = run(two_mass(limited_fmu, test_fmus, H=H, retries=3, h_max=h, scheme=scheme, first=first),
              out_dir=tmp_path / "r", progress=False)
    assert res.success, res.message
    ref = run(two_mass(limited_fmu, test_fmus, H=h, h_max=h, scheme=scheme, first=first, interval=H),
              out_dir=tmp_path / "ref", progress=False)
    assert ref.success and ref.stats["retried_steps"] == 0
    assert len(res.t) == 51 and res.t[-1] == pytest.approx(0.2)     # nominal output grid
    assert_same(res, ref, atol=1e-12)
    # the comparison can fail: the plain H run differs by far more than round-off
    plain = run(two_mass(limited_fmu, test_fmus, H=H, scheme=scheme, first=first), out_dir=tmp_path / "p",
                progress=False)
    assert np.abs(plain.outputs["left.x1"] - res.outputs["left.x1"]).max() > 1e-5
    st = res.stats
    # per macro step: H discarded -> 2 x H/2 (both discarded) -> 4 x H/4
    assert st["retried_steps"] == 50 and st["retry_substeps"] == 50 * 6 and st["rejected_steps"] == 50 * 3
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["status"] == "finished" and s["rejected_steps"] == 150 and s["coupling"]["discard_retries"] == 3
    assert (s["retried_steps"], s["retry_substeps"]) == (50, 300)
    lines = [r.getMessage() for r in caplog.records if "discarded the macro step" in r.getMessage()]
    assert len(lines) == 20 and "2 halving(s)" in lines[0] and "only counted" in lines[-1]
    assert any("50 macro step(s) were redone" in r.getMessage() and "only the first 20" in r.getMessage()
               for r in caplog.records)


def test_retry_window_with_extrapolation_keeps_the_nominal_history(limited_fmu, test_fmus):
    """k = 2 (start-up iteration on), discards only in [0.101, 0.115): 4 macro steps are split.
    After every step the history levels are the nominal grid points, rows before the window
    equal the run without discards exactly, and after it the results stay close to it."""
    H = 4e-3
    sc = two_mass(limited_fmu, test_fmus, H=H, retries=2, k=2, q=2, h_max=H / 4, window=(0.101, 0.115))
    m = MasterAlgorithm(sc)
    m.setup()
    m.initialize()
    try:
        while m.status is Status.RUNNING:
            m.step()
            hist = m.history
            expect = [m.grid.time(m.n - i) for i in range(hist.count)]
            assert hist.times[1:1 + hist.count].tolist() == expect, (m.n, hist.times)
            # level 1 holds the outputs just read at the new grid point (x1 -> right.x1)
            right = next(u for u in m.units if u.name == "right")
            assert right.HI[1][0] == m.view.row[0]
    finally:
        m.terminate()
    res = m.result()
    assert res.success, res.message
    assert (res.stats["retried_steps"], res.stats["retry_substeps"]) == (4, 4 * 6)
    plain = MasterAlgorithm(two_mass(limited_fmu, test_fmus, H=H, k=2, q=2)).run()
    before = res.t <= 0.1 + 1e-12
    assert np.array_equal(res.outputs["left.x1"][before], plain.outputs["left.x1"][before])
    diff = np.abs(res.outputs["left.x1"] - plain.outputs["left.x1"]).max()
    assert 0 < diff < 1e-4, diff


# ---------------------------------------------------------------- retries exhausted / refused
def test_too_few_retries_stop_with_the_halvings_in_the_message(limited_fmu, test_fmus, tmp_path):
    H = 4e-3
    res = run(two_mass(limited_fmu, test_fmus, H=H, retries=1, h_max=H / 4, window=(0.101, 0.115)),
              out_dir=tmp_path, progress=False)
    assert res.status is Status.FAILED
    msg = res.message
    assert msg.startswith("FMU instance 'left' could not complete the step (fmi2Discard) in fmi2DoStep during the "
                          "macro step from t=0.1 s to t=0.104 s (")
    assert "Rows up to t=0.1 s are kept" in msg
    assert "retried this macro step with 1 halving of the step (coupling.discard_retries = 1, smallest step " \
           "0.002 s); the sub-step from t=0.1 s to t=0.102 s was still discarded" in msg
    assert res.end_time == pytest.approx(0.1) and res.t[-1] == pytest.approx(0.1) and len(res.t) == 26
    assert res.stats["retried_steps"] == 1 and res.stats["retry_substeps"] == 1


def test_fmu_without_state_support_is_refused_at_setup(test_fmus):
    sc = Scenario(name="chain", stop_time=0.1,
                  fmus=(FmuSpec(name="src", path=test_fmus["Faulty"]),
                        FmuSpec(name="integ", path=test_fmus["Integrator"])),
                  connections=(ConnectionSpec(src="src.y", dst="integ.u"),),
                  coupling=CouplingSpec(macro_step=0.01, discard_retries=2))
    m = MasterAlgorithm(sc)
    with pytest.raises(ScenarioError) as ei:
        m.setup()
    text = str(ei.value)
    assert "discard_retries = 2" in text and "'src'" in text and "canGetAndSetFMUstate" in text
    assert "'integ'" not in text      # Integrator is built with state support


def test_invalid_discard_retries_given_in_python(test_fmus):
    sc = Scenario(name="x", stop_time=0.1, fmus=(FmuSpec(name="g", path=test_fmus["Gain"]),),
                  coupling=CouplingSpec(macro_step=0.01, discard_retries=-1))
    with pytest.raises(ScenarioError, match="coupling.discard_retries must be an integer between 0 and 30 "
                                            r"\(got -1\)"):
        MasterAlgorithm(sc)


# ---------------------------------------------------------------- loader
@pytest.fixture
def sdir(tmp_path, test_fmus):
    (tmp_path / "fmus").mkdir()
    for name in ("LeftMass", "RightMass"):
        shutil.copy(test_fmus[name], tmp_path / "fmus" / f"{name}.fmu")
    return tmp_path


def write(sdir, coupling: str):
    p = sdir / "s.yaml"
    p.write_text(textwrap.dedent("""\
        name: x
        stop_time: 0.01
        fmus:
          left: {path: fmus/LeftMass.fmu}
          right: {path: fmus/RightMass.fmu}
        connections:
          - {from: left.x1, to: right.x1}
          - {from: right.F, to: left.F}
        coupling:
        """) + textwrap.indent(textwrap.dedent(coupling), "  "))
    return p


@pytest.mark.parametrize("value, got", [("-1", "must be between 0 and 30 (got -1)"),
                                        ("31", "must be between 0 and 30 (got 31)"),
                                        ("two", "must be an integer (got 'two', a string)"),
                                        ("1.5", "must be an integer (got 1.5, a number)"),
                                        ("true", "must be an integer (got True, a boolean)")])
def test_loader_rejects_bad_values(sdir, value, got):
    p = write(sdir, f"macro_step: 1e-3\ndiscard_retries: {value}\n")
    with pytest.raises(ScenarioError) as ei:
        load_scenario(p, build_fmus=False)
    (problem,) = ei.value.problems
    assert problem.startswith(f"{p}:11: 'coupling.discard_retries' {got}; use 0 (stop the run when an FMU returns "
                              "fmi2Discard) or the number of times"), problem


def test_loader_default_value_and_override(sdir, caplog):
    p = write(sdir, "macro_step: 1e-3\n")
    assert load_scenario(p, build_fmus=False).coupling.discard_retries == 0
    assert load_scenario(p, ["coupling.discard_retries=4"], build_fmus=False).coupling.discard_retries == 4
    p = write(sdir, "macro_step: 1e-3\ndiscard_retries: 3\n")
    assert load_scenario(p, build_fmus=False).coupling.discard_retries == 3
    with caplog.at_level(logging.WARNING, logger="orchestrator.scenario"):
        sc = load_scenario(p, ["coupling.scheme=monolithic"], build_fmus=False)
    assert sc.coupling.discard_retries == 3
    assert any("discard_retries = 3 is ignored by the monolithic scheme" in r.getMessage() for r in caplog.records)


# ---------------------------------------------------------------- step-size controller seam
def test_rejected_attempts_reach_the_observers(limited_fmu, test_fmus, tmp_path):
    """Every rolled-back attempt is told to the observers (on_step_rejected), with its interval."""
    from orchestrator.coupling.observers import Observer

    class Rejections(Observer):
        def __init__(self):
            self.seen = []

        def on_step_rejected(self, view):
            self.seen.append(view.rejected)

    H, h = 4e-3, 1e-3
    obs = Rejections()
    res = run(two_mass(limited_fmu, test_fmus, H=H, retries=3, h_max=h, T=0.02), out_dir=tmp_path,
              progress=False, observers=[obs])
    assert res.success, res.message
    assert len(obs.seen) == res.stats["rejected_steps"] == 5 * 3
    t_a, t_b, reason = obs.seen[0]
    assert (t_a, t_b) == (pytest.approx(0.0), pytest.approx(H)) and "discard" in reason
    assert obs.seen[1][:2] == (pytest.approx(0.0), pytest.approx(H / 2))     # then the first half


def test_a_custom_controller_drives_the_steps(test_fmus, tmp_path):
    """The master asks the controller for the grid and lets it take every step (the protocol of
    orchestrator.coupling.step_control): a controller counting its calls sees every macro step."""
    from orchestrator.coupling.execution import MasterAlgorithm
    from orchestrator.coupling.step_control import ConstantStep

    class Counting(ConstantStep):
        calls = 0

        def take_step(self, stepper, t, t_next):
            Counting.calls += 1
            stepper.step(t, t_next)

    sc = Scenario(name="chain", stop_time=0.1,
                  fmus=(FmuSpec(name="src", path=test_fmus["Faulty"], parameters={"t_fail": 1.0, "mode": 0}),
                        FmuSpec(name="gain", path=test_fmus["Gain"], parameters={"k": 2.0})),
                  connections=(ConnectionSpec(src="src.y", dst="gain.u"),),
                  coupling=CouplingSpec(macro_step=0.01))
    m = MasterAlgorithm(sc, out_dir=tmp_path, step_size=Counting(0.0, 0.1, 0.01))
    res = m.run()
    assert res.success and Counting.calls == 10 == res.stats["macro_steps"]
    assert res.stats["rejected_steps"] == 0
