"""The master with real FMUs (built with PythonFMU by the ``test_fmus`` fixture).

PythonFMU FMUs cannot interpolate inputs, so the master sub-steps them with
inputs held at sub-step midpoints; that limits the global order to 2 (see
docs/coupling.md), which these tests check honestly.

Run as a script to print the orders table of docs/coupling.md:
``.venv/bin/python tests/test_master_fmus.py``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.linalg import expm

from orchestrator import CoSimResult, run
from orchestrator.errors import ScenarioError
from orchestrator.results import Status
from orchestrator.scenario import ConnectionSpec, CouplingSpec, FmuSpec, OutputSpec, Scenario

pytestmark = pytest.mark.integration

P = dict(m1=1.0, k1=10.0, m2=1.0, k2=1000.0, d2=1.0, kc=100.0, dc=1.0)


def two_mass(fmus, scheme, H, k, *, T=0.5, substeps=1, q=None):
    return Scenario(
        name="two-mass", stop_time=T,
        fmus=(FmuSpec(name="left", path=fmus["LeftMass"], parameters=dict(m1=P["m1"], k1=P["k1"], x1_0=1.0)),
              FmuSpec(name="right", path=fmus["RightMass"],
                      parameters={k: P[k] for k in ("m2", "k2", "d2", "kc", "dc")})),
        connections=(ConnectionSpec(src="left.x1", dst="right.x1"), ConnectionSpec(src="left.v1", dst="right.v1"),
                     ConnectionSpec(src="right.F", dst="left.F")),
        coupling=CouplingSpec(scheme=scheme, sequence=("left", "right"), macro_step=H, extrapolation_order=k,
                              interpolation_order=k if q is None else q, substeps=substeps),
        output=OutputSpec(signals=("left.x1", "right.x2")))


def exact(t):
    m1, k1, m2, k2, d2, kc, dc = (P[k] for k in ("m1", "k1", "m2", "k2", "d2", "kc", "dc"))
    A = np.array([[0, 1, 0, 0], [-(k1 + kc) / m1, -dc / m1, kc / m1, dc / m1],
                  [0, 0, 0, 1], [kc / m2, dc / m2, -(k2 + kc) / m2, -(d2 + dc) / m2]])
    return np.array([expm(A * ti) @ [1.0, 0, 0, 0] for ti in t])


def error(res: CoSimResult) -> float:
    X = exact(res.t)
    return max(np.abs(res.outputs["left.x1"] - X[:, 0]).max(), np.abs(res.outputs["right.x2"] - X[:, 2]).max())


def order(Hs, errs):
    return float(np.polyfit(np.log(Hs), np.log(errs), 1)[0])


def test_two_mass_oscillator_against_exact_solution(test_fmus, tmp_path):
    res = run(two_mass(test_fmus, "gauss-seidel", 1e-3, 1), out_dir=tmp_path, progress=False)
    assert res.success, res.message
    assert error(res) < 2e-4          # O(H^2) coupling error, amplitude 1 m
    # files
    df = pd.read_csv(tmp_path / "results.csv")
    assert list(df.columns) == ["time", "left.x1", "right.x2"]
    assert len(df) == 501 and df["time"].iloc[-1] == pytest.approx(0.5)
    assert np.allclose(df["left.x1"].to_numpy(), res.outputs["left.x1"], rtol=0, atol=1e-15)
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "finished" and s["end_time"] == pytest.approx(0.5) and s["macro_steps"] == 500
    assert s["fmu_calls"]["left"]["doStep"] == 500 and s["fmu_calls"]["right"]["get"] >= 500
    for key in ("scenario", "scenario_file", "message", "start_time", "stop_time", "wall_time_s", "coupling",
                "versions"):
        assert key in s
    assert s["versions"]["fmpy"] and s["coupling"]["scheme"] == "gauss-seidel"


@pytest.mark.parametrize("scheme", ["jacobi", "gauss-seidel"])
@pytest.mark.parametrize("k, expected", [(0, 1.0), (1, 2.0), (2, 2.0)])
def test_measured_order_with_held_inputs(test_fmus, tmp_path, scheme, k, expected):
    """k=0 -> 1, k=1 -> 2; k=2 is limited to 2 by the piecewise-constant input
    of FMUs that cannot interpolate inputs (one sub-step per macro step)."""
    Hs = np.array([4e-3, 2e-3, 1e-3])
    errs = [error(run(two_mass(test_fmus, scheme, H, k), out_dir=tmp_path / f"{H}", progress=False)) for H in Hs]
    assert abs(order(Hs, errs) - expected) < 0.25, errs
    if k == 2:    # still more accurate than k=1 at the same step
        e1 = error(run(two_mass(test_fmus, scheme, Hs[-1], 1), out_dir=tmp_path / "k1", progress=False))
        assert errs[-1] < e1 / 3


def test_substeps_lift_the_held_input_limit(test_fmus, tmp_path):
    """With 16 sub-steps the hold error (~(H/16)^2) is small against the k=2
    coupling error in this range of H, so the order 3 of the scheme shows."""
    Hs = np.array([8e-3, 4e-3, 2e-3])
    errs = [error(run(two_mass(test_fmus, "gauss-seidel", H, 2, substeps=16), out_dir=tmp_path / f"{H}",
                      progress=False)) for H in Hs]
    assert order(Hs, errs) > 2.7, errs


def chain(fmus, scheme, *, mode=None, t_fail=1e9, H=0.01, T=0.1, k=0, loop=False):
    """Faulty (ramp y=t) -> Gain(2) -> Integrator; optionally a feedback loop
    Integrator.y -> Gain2(-1) -> Integrator2 (third-party-style FMUs)."""
    fm = [FmuSpec(name="src", path=fmus["Faulty"], parameters={"t_fail": t_fail, "mode": mode or 0}),
          FmuSpec(name="gain", path=fmus["Gain"], parameters={"k": 2.0}),
          FmuSpec(name="integ", path=fmus["Integrator"], parameters={"y0": 0.0})]
    cn = [ConnectionSpec(src="src.y", dst="gain.u"), ConnectionSpec(src="gain.y", dst="integ.u")]
    if loop:
        fm += [FmuSpec(name="fb", path=fmus["Gain"], parameters={"k": -1.0}),
               FmuSpec(name="loop", path=fmus["Integrator"], parameters={"y0": 1.0})]
        cn += [ConnectionSpec(src="loop.y", dst="fb.u"), ConnectionSpec(src="fb.y", dst="loop.u")]
    return Scenario(name="chain", stop_time=T, fmus=tuple(fm), connections=tuple(cn),
                    coupling=CouplingSpec(scheme=scheme, macro_step=H, extrapolation_order=k, interpolation_order=1))


@pytest.mark.parametrize("scheme", ["jacobi", "gauss-seidel"])
def test_chain_and_loop_of_third_party_fmus(test_fmus, tmp_path, scheme):
    H = 0.01
    res = run(chain(test_fmus, scheme, loop=True, H=H, T=1.0, k=1), out_dir=tmp_path, progress=False)
    assert res.success, res.message
    t = res.t
    # default signals: every Real output of every FMU
    assert {"src.y", "gain.y", "integ.y", "integ.time", "loop.y", "fb.y"} <= set(res.outputs)
    assert np.allclose(res.outputs["integ.time"], t)
    # integ.y = int 2t dt = t^2 (coupling error O(H^2) for Jacobi, smaller for GS)
    assert np.abs(res.outputs["integ.y"] - t ** 2).max() < 5 * H ** 2
    # loop y' = -y, y(0) = 1 -> exp(-t): explicit coupling error O(H)..O(H^2)
    assert np.abs(res.outputs["loop.y"] - np.exp(-t)).max() < 2 * H
    if scheme == "gauss-seidel":
        assert np.allclose(res.outputs["gain.y"], 2 * t, atol=1e-12)     # no delay through the gain


@pytest.mark.parametrize("mode, words", [
    (0, ["'src'", "fmi2Discard", "t=0.05", "macro_step"]),
    (1, ["'src'", "deliberate failure", "t=0.05", "macro_step"]),
    (2, ["src.y -> gain.u", "nan", "t=0.06", "macro_step"]),
    (3, ["src.y -> gain.u", "inf", "t=0.06", "macro_step"]),
])
def test_mid_run_failure_keeps_rows_and_says_why(test_fmus, tmp_path, mode, words):
    res = run(chain(test_fmus, "gauss-seidel", mode=mode, t_fail=0.05, H=0.01, T=0.1), out_dir=tmp_path,
              progress=False)
    assert res.status is Status.FAILED and not res.success
    for w in words:
        assert w in res.message, (w, res.message)
    assert res.end_time == pytest.approx(0.05)
    df = pd.read_csv(tmp_path / "results.csv")
    assert len(df) == 6 and df["time"].iloc[-1] == pytest.approx(0.05)       # rows 0, 0.01, ..., 0.05
    assert np.isfinite(df.to_numpy()).all()
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "failed" and s["end_time"] == pytest.approx(0.05) and s["message"] == res.message
    assert s["macro_steps"] == 5


def test_parameters_of_every_type_and_out_dir_substitution(test_fmus, tmp_path):
    sc = Scenario(name="params", stop_time=0.02,
                  fmus=(FmuSpec(name="p", path=test_fmus["Params"],
                                parameters={"a": 1.5, "n": 3, "flag": True, "out_file": "{out_dir}/p.txt"}),),
                  coupling=CouplingSpec(macro_step=0.01))
    res = run(sc, out_dir=tmp_path, progress=False)
    assert res.success
    assert res.outputs["p.a_out"][-1] == 1.5 and res.outputs["p.n_out"][-1] == 3.0
    assert res.outputs["p.flag_out"][-1] == 1.0
    assert (tmp_path / "p.txt").read_text().strip() == "a=1.5 n=3 flag=True"


def test_bad_parameter_type_and_unknown_names(test_fmus, tmp_path):
    sc = Scenario(name="params", stop_time=0.02,
                  fmus=(FmuSpec(name="p", path=test_fmus["Params"], parameters={"n": "three"}),),
                  coupling=CouplingSpec(macro_step=0.01))
    with pytest.raises(ScenarioError, match=r"p\.n.*Integer.*'three'"):
        run(sc, out_dir=tmp_path, progress=False)
    sc = Scenario(name="params", stop_time=0.02,
                  fmus=(FmuSpec(name="p", path=test_fmus["Params"], parameters={"nope": 1.0}),),
                  coupling=CouplingSpec(macro_step=0.01))
    with pytest.raises(ScenarioError, match="valid names: a, n, flag"):
        run(sc, out_dir=tmp_path, progress=False)


def test_state_save_restore_round_trip(test_fmus, tmp_path):
    from orchestrator.fmi.subsystem import Subsystem
    s = Subsystem("i", test_fmus["Integrator"], work_dir=tmp_path)
    try:
        s.setup_experiment(0.0, 1.0)
        s.enter_initialization_mode()
        s.exit_initialization_mode()
        u, y = s.real_batch(["u"]), s.real_batch(["y"])
        u.values[:] = 2.0
        s.set_real(u)
        s.do_step(0.0, 0.5)
        st = s.get_state()
        s.do_step(0.5, 0.5)
        assert s.get_real(y)[0] == pytest.approx(2.0)
        s.set_state(st)
        assert s.get_real(y)[0] == pytest.approx(1.0)
        s.free_state(st)
        s.terminate()
        assert s.calls["doStep"] == 2 and s.calls["getFMUstate"] == 1
    finally:
        s.free()


def test_fmu_exception_surfaces_as_fmu_call_error(test_fmus, tmp_path):
    from orchestrator.errors import FmuCallError
    from orchestrator.fmi.subsystem import Subsystem
    s = Subsystem("bad", test_fmus["Faulty"], work_dir=tmp_path)
    try:
        s.set_parameters({"mode": 1, "t_fail": 0.0})
        s.setup_experiment(0.0, 1.0)
        s.enter_initialization_mode()
        s.exit_initialization_mode()
        with pytest.raises(FmuCallError) as ei:
            s.do_step(0.0, 0.1)
        assert ei.value.instance == "bad" and ei.value.function == "fmi2DoStep"
        assert "deliberate failure" in str(ei.value)
    finally:
        s.free()


def test_monolithic_dispatch_and_analysis_hook(test_fmus, tmp_path, monkeypatch):
    import dataclasses
    import types
    calls = {}

    def fake_monolithic(scenario, *, out_dir, progress):
        calls["mono"] = (scenario.name, Path(out_dir), progress)
        (Path(out_dir) / "summary.json").write_text(json.dumps({"status": "finished"}))
        return CoSimResult(status=Status.FINISHED, message="ok", t=np.zeros(1), outputs={}, out_dir=Path(out_dir))

    def broken_analysis(out_dir, spec):
        raise RuntimeError("boom")

    monkeypatch.setitem(sys.modules, "orchestrator.reference.monolithic", types.SimpleNamespace(run_monolithic=fake_monolithic))
    monkeypatch.setitem(sys.modules, "orchestrator.results.whirl", types.SimpleNamespace(analyze_run=broken_analysis))
    sc = two_mass(test_fmus, "jacobi", 0.01, 0, T=0.05)
    sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, scheme="monolithic"),
                             analysis={"speed": "left.x1"})
    res = run(sc, out_dir=tmp_path, progress=False)
    assert calls["mono"] == ("two-mass", tmp_path, False)
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["analysis"]["error"].startswith("analysis failed: RuntimeError: boom")
    assert res.analysis == s["analysis"]


def orders_table(fmus_dir: Path | None = None) -> str:
    """The table of docs/coupling.md (held inputs, 1 sub-step; and 16 sub-steps for k=2)."""
    import tempfile
    sys.path.insert(0, str(Path(__file__).parent))
    from conftest import build_test_fmus
    tmp = Path(tempfile.mkdtemp(prefix="orders-"))
    fmus = build_test_fmus(tmp / "fmus")
    Hs = np.array([4e-3, 2e-3, 1e-3, 5e-4])
    lines = ["| scheme | k | substeps | " + " | ".join(f"H={H:g}" for H in Hs) + " | fitted order |",
             "|---|---|---|" + "---|" * len(Hs) + "---|"]
    for scheme in ("jacobi", "gauss-seidel"):
        for k, m in ((0, 1), (1, 1), (2, 1), (2, 16)):
            errs = [error(run(two_mass(fmus, scheme, H, k, substeps=m), out_dir=tmp / "run", progress=False))
                    for H in Hs]
            lines.append(f"| {scheme} | {k} | {m} | " + " | ".join(f"{e:.3e}" for e in errs)
                         + f" | {order(Hs, errs):.2f} |")
    return "\n".join(lines)


if __name__ == "__main__":
    print(orders_table())


def test_keyboard_interrupt_still_writes_summary(test_fmus, tmp_path):
    from orchestrator.coupling.observers import Observer

    class Interrupt(Observer):
        def on_step_complete(self, view):
            if view.n == 3:
                raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run(two_mass(test_fmus, "jacobi", 0.01, 0, T=0.1), out_dir=tmp_path, progress=False,
            observers=[Interrupt()])
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "failed" and "interrupted" in s["message"] and s["end_time"] == pytest.approx(0.03)
    assert len(pd.read_csv(tmp_path / "results.csv")) == 4


def test_ctrl_c_inside_fmu_code_stops_cleanly_after_the_macro_step(test_fmus, tmp_path):
    """A SIGINT delivered while a Python FMU's do_step runs must not surface as fmi2Fatal of
    that FMU ("try a smaller macro step"): orchestrator.run defers it to the end of the macro
    step, writes summary.json as interrupted by the user and restores the SIGINT handler."""
    import signal
    before = signal.getsignal(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        run(chain(test_fmus, "gauss-seidel", mode=4, t_fail=0.025, H=0.01, T=0.1), out_dir=tmp_path,
            progress=False)
    assert signal.getsignal(signal.SIGINT) is before
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "failed"
    assert s["message"].startswith("interrupted by the user at t=0.03 s"), s["message"]
    assert "fatal" not in s["message"].lower()
    assert s["end_time"] == pytest.approx(0.03)
    assert len(pd.read_csv(tmp_path / "results.csv")) == 4      # t = 0, 0.01, 0.02, 0.03


def test_no_call_after_fatal_not_even_free_instance(test_fmus, tmp_path):
    """FMI 2.0 (section 2.1.3): after fmi2Fatal no function may be called, fmi2FreeInstance
    included. PythonFMU reports an escaped Python exception as Fatal and has already
    released the slave's objects then; freeing again corrupted the interpreter (a segfault
    in the cyclic GC much later). The faulty instance must not be freed, the others must."""
    res = run(chain(test_fmus, "gauss-seidel", mode=1, t_fail=0.05, H=0.01, T=0.1), out_dir=tmp_path,
              progress=False)
    assert res.status is Status.FAILED
    calls = res.stats["fmu_calls"]
    assert calls["src"].get("freeInstance", 0) == 0, calls["src"]
    assert calls["gain"].get("freeInstance", 0) == 1 and calls["integ"].get("freeInstance", 0) == 1, calls
