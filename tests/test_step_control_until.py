"""``coupling.step_control: {type: error, ..., until: T}``: the macro step is error-controlled from
start_time to T, then constant ``macro_step`` steps to stop_time (orchestrator/coupling/adaptive.py,
ErrorThenConstant), with discard_retries / defect_retries acting after T only. The key's checks
(scenario/coupling_sections.py ``until_problem``), the run with plain-Python fakes, and compare's
checks of a variant that sets it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from orchestrator.coupling.execution import MasterAlgorithm
from orchestrator.coupling.observers import Observer, Progress
from orchestrator.errors import ScenarioError
from orchestrator.scenario import load_scenario
from orchestrator.scenario.model import StepControlSpec
from test_master_adaptive import run, switched
from test_master_iterative import scenario as two_mass_scenario

UNTIL = 0.15            # the switch of the fakes' coupling spring is at 0.1 s; rows every 0.01 s


class Calls(Observer):
    """Every accepted step's end (the master's view) and every rolled-back attempt."""

    def __init__(self):
        self.ends, self.rejected = [], []

    def on_step_complete(self, view):
        self.ends.append(view.t)

    def on_step_rejected(self, view):
        self.rejected.append(view.rejected)


def _record_do_steps(subs):
    """Wrap the fakes' do_step to record (t, h) of every doStep the master sent (attempts included)."""
    calls = []
    right = subs["right"]
    inner = right.do_step

    def do_step(t, h):
        calls.append((t, h))
        return inner(t, h)
    right.do_step = do_step
    return calls


# --- the run -------------------------------------------------------------------------------------
def test_error_control_until_then_constant_steps_on_the_index_grid():
    """Before ``until`` the step follows the error (steps of many sizes, rejections), the last one
    ends exactly at ``until``; after it every doStep is macro_step long and starts at until + n * H
    (from the index, bit for bit); rows stay on the output grid; the statistics count both parts."""
    H = 1e-3
    subs = switched()
    calls = _record_do_steps(subs)
    obs = Calls()
    s = two_mass_scenario("gauss-seidel", H, T=0.3, k=1, q=1)
    s = dataclasses.replace(s, coupling=dataclasses.replace(s.coupling, step_control=StepControlSpec(
        type="error", rtol=1e-3, atol=1e-6, until=UNTIL)), output=dataclasses.replace(s.output, interval=1e-2))
    res = MasterAlgorithm(s, subsystems=subs, observers=[obs]).run()
    assert res.success, res.message
    np.testing.assert_allclose(res.t, np.arange(31) * 1e-2, rtol=0, atol=1e-12)
    assert UNTIL in obs.ends                                         # a step ends exactly at until
    before = [(t, h) for t, h in calls if t < UNTIL]
    after = [(t, h) for t, h in calls if t >= UNTIL]
    assert all(t + h <= UNTIL * (1 + 1e-12) for t, h in before)
    assert len({round(h, 12) for _, h in before}) > 10               # error-controlled: many step sizes
    assert len(after) == 150
    assert [t for t, _ in after] == [UNTIL + n * H for n in range(150)]   # from n, not accumulated
    assert all(h == H for _, h in after)
    st = res.stats
    sc = st["step_control"]
    assert sc["until"] == UNTIL and sc["constant_steps"] == 150 and sc["constant_macro_step"] == H
    assert sc["accepted_steps"] == len(before) - sc["rejected_steps"] > 150        # small steps before until
    assert sc["accepted_steps"] + sc["constant_steps"] == st["macro_steps"]
    assert sc["rejected_steps"] == len(obs.rejected) > 0
    assert all(b <= UNTIL for _, b, _ in obs.rejected)
    # the jump of the spring at 0.1 s is taken above the tolerance: said of the error-controlled part
    assert (f"{sc['over_tolerance_steps']} of the {sc['accepted_steps']} error-controlled macro steps (up to "
            "step_control.until, 0.15 s) had a scaled error above 1") in res.message
    # the whole run error-controlled takes more steps after until than the 150 constant ones
    whole = run(H, control=StepControlSpec(type="error", rtol=1e-3, atol=1e-6))
    assert whole.stats["macro_steps"] > st["macro_steps"]


def test_until_with_a_progress_bar_and_extrapolation_carried_over(capsys):
    """The progress display's step count is an estimate before until and exact after it (the bar
    does not break); the first constant steps extrapolate through the error-controlled history
    (order 1 here): the result is as accurate as the error-controlled run before the switch."""
    import io
    stream = io.StringIO()
    res = run(1e-3, control=StepControlSpec(type="error", rtol=1e-3, atol=1e-6, until=UNTIL),
              observers=[Progress(True, delay=0.0, stream=stream)])
    assert res.success, res.message
    assert "co-simulation" in stream.getvalue()
    from test_master_adaptive import rel_error
    assert rel_error(res) < 1e-3


def test_the_extrapolation_history_carries_over_the_switch():
    """No restart at until: the first constant step extrapolates (order 1) through the newest
    error-controlled levels, whose times are uneven (a restart would hold the value, order 0)."""
    H = 1e-3
    s = two_mass_scenario("gauss-seidel", H, T=0.3, k=1, q=1)
    s = dataclasses.replace(s, coupling=dataclasses.replace(s.coupling, step_control=StepControlSpec(
        type="error", rtol=1e-3, atol=1e-6, until=UNTIL)), output=dataclasses.replace(s.output, interval=1e-2))
    m = MasterAlgorithm(s, subsystems=switched())
    m.setup()
    m.initialize()
    while m.grid.variable:
        m.step()
    hist = m.stepper.history
    assert m.t == UNTIL and hist.times[1] == UNTIL and hist.count >= 2
    h_last = UNTIL - hist.times[2]                  # the last error-controlled step
    assert h_last != H
    w = m.predictor.weights(hist, UNTIL, H, 1)
    assert w.p == 1 and w.extrap_end == pytest.approx([1 + H / h_last, -H / h_last])
    m.step()                                        # the first constant step
    assert m.t == UNTIL + H and hist.times[2] == UNTIL and hist.times[3] == UNTIL - h_last
    m.terminate()


def test_until_with_defect_retries_redoes_steps_only_after_until():
    """defect_retries with the error-controlled step is refused without until; with it the retries
    judge and redo the constant steps after until only (the error-controlled steps before it keep
    their own rejection), the monitor watches the constant steps and says from when."""
    from test_coupling_defect import CF, IJJournal, film, scenario as ij
    sc = ij()
    spec = StepControlSpec(type="error", rtol=1e-2, until=0.01)
    sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, defect_limit=0.002, defect_retries=2,
                                                              step_control=spec))
    obs = Calls()
    res = MasterAlgorithm(sc, subsystems={"rotor": IJJournal(), "bearing": film(c_reported=CF / 2)},
                          observers=[obs]).run()
    assert res.success, res.message
    np.testing.assert_allclose(res.t, np.arange(201) * 1e-4, rtol=0, atol=1e-12)
    defect = [(a, b) for a, b, why in obs.rejected if "coupling.defect_retries" in why]
    error = [(a, b) for a, b, why in obs.rejected if "scaled error" in why]
    assert defect and all(a >= 0.01 for a, _ in defect)
    assert all(b <= 0.01 for _, b in error)
    st = res.stats
    assert st["defect_retried_steps"] == st["retried_steps"] > 0
    cd = st["coupling_defect"]
    assert cd["monitored_from"] == 0.01 and cd["steps"] == st["step_control"]["constant_steps"] == 100
    assert cd["steps_not_monitored"] == st["step_control"]["accepted_steps"]
    assert cd["retries"]["retried_steps"] == st["retried_steps"]
    # without until the combination is refused when the master is made
    bad = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, step_control=dataclasses.replace(
        spec, until=None)))
    with pytest.raises(ScenarioError, match="defect_retries cannot be combined.*step_control.until"):
        MasterAlgorithm(bad, subsystems={"rotor": IJJournal(), "bearing": film()})


def test_a_discard_after_until_is_redone_and_not_monitored():
    """discard_retries after until: a constant step the film discards once is redone in halves from
    the saved states; the defect monitor leaves that macro step out (its pieces had fresh
    coefficients), as on a constant-step run."""
    from orchestrator.errors import FmuCallError
    from test_coupling_defect import CF, H, IJJournal, film, scenario as ij

    class OnceDiscarding(type(film())):
        def do_step(self, t, h):
            if not getattr(self, "discarded", False) and abs(t - 0.015) < 1e-12 and h == H:
                self.discarded = True
                raise FmuCallError("bearing", "fmi2DoStep", "discard", "step too long once")
            super().do_step(t, h)

    bearing = film(c_reported=CF / 2)
    bearing.__class__ = OnceDiscarding
    sc = ij()
    spec = StepControlSpec(type="error", rtol=1e-2, until=0.01)
    sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, discard_retries=1, step_control=spec))
    res = MasterAlgorithm(sc, subsystems={"rotor": IJJournal(), "bearing": bearing}).run()
    assert res.success, res.message
    st = res.stats
    assert bearing.discarded and st["retried_steps"] == 1 and st["rejected_steps"] == 1
    cd = st["coupling_defect"]
    assert cd["steps"] == st["step_control"]["constant_steps"] - 1 == 99
    assert cd["steps_not_monitored"] == st["step_control"]["accepted_steps"] + 1


def test_until_built_in_code_is_checked_by_the_master():
    s = two_mass_scenario("gauss-seidel", 1e-3, T=0.3)
    s = dataclasses.replace(s, output=dataclasses.replace(s.output, interval=1e-2))
    for until, kind, says in ((0.0, "error", "must lie after start_time"), (0.155, "error", "use 0.15 or 0.16"),
                              (0.15, "constant", "is for type error")):
        bad = dataclasses.replace(s, coupling=dataclasses.replace(s.coupling, step_control=StepControlSpec(
            type=kind, until=until)))
        with pytest.raises(ScenarioError, match=says):
            MasterAlgorithm(bad, subsystems=switched())


# --- the key in a scenario file ------------------------------------------------------------------
def _two_mass_file(tmp_path, test_fmus, coupling: str, left="LeftMass"):
    """test_compare_capabilities' two-mass scenario (rows every 0.2 s, stop 1 s) with macro_step 0.01 and
    the ``coupling`` lines given (its line 14 is the first of them)."""
    from test_compare_capabilities import _two_mass
    return _two_mass(tmp_path, test_fmus[left], test_fmus["RightMass"],
                     "\n  scheme: gauss-seidel\n  macro_step: 0.01\n" + coupling, file="until.yaml")


@pytest.mark.integration
def test_until_key_parses_and_round_trips(test_fmus, tmp_path):
    import warnings

    from orchestrator.scenario.ssp import export_ssp
    from orchestrator.scenario.ssp_annotation import scenario_annotation
    p = _two_mass_file(tmp_path, test_fmus, "  step_control: {type: error, rtol: 1.0e-3, until: 0.4}\n"
                                            "  discard_retries: 2\n  defect_retries: 1")
    sc = load_scenario(p)
    assert sc.coupling.step_control.until == 0.4 and sc.coupling.discard_retries == 2
    assert scenario_annotation(sc)["coupling"]["step_control"]["until"] == 0.4
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        back = load_scenario(export_ssp(sc, tmp_path / "until.ssp"))
    assert back.coupling == sc.coupling
    assert load_scenario(p, ["coupling.step_control.until=0.6"]).coupling.step_control.until == 0.6
    res = __import__("orchestrator").run(sc, out_dir=tmp_path / "run", progress=False)
    assert res.success, res.message
    np.testing.assert_allclose(res.t, np.arange(6) * 0.2, rtol=0, atol=1e-12)
    assert res.stats["step_control"]["constant_steps"] == 60


@pytest.mark.integration
@pytest.mark.parametrize("coupling, line, says", [
    ("  step_control:\n    type: constant\n    until: 0.4", 16,
     "'coupling.step_control.until' (0.4) is for type error"),
    ("  step_control:\n    type: error\n    until: -0.5", 16,
     "'coupling.step_control.until' must lie after start_time (0.0) (got -0.5); give the time up to which the "
     "step is error-controlled, an output time in 0.2..0.8, e.g. 0.2 (at or after stop_time (1.0) the whole run "
     "is error-controlled)"),
    ("  step_control:\n    type: error\n    until: 0.0", 16, "e.g. 0.2"),
    ("  step_control:\n    type: error\n    until: 0.5", 16,
     "'coupling.step_control.until' (0.5) is not on the output grid start_time + k * output.interval (0.0 + k * "
     "0.2): the constant steps after it write a row every output interval from 'until', which would miss the "
     "grid; use 0.4 or 0.6"),
    ("  step_control:\n    type: error\n    until: soon", 16, "'coupling.step_control.until' must be a"),
    ("  step_control: {type: error}\n  defect_retries: 2", 15,
     "coupling.step_control type error and coupling.defect_retries cannot be combined"),
])
def test_until_refusals_name_the_line(test_fmus, tmp_path, coupling, line, says):
    p = _two_mass_file(tmp_path, test_fmus, coupling)
    with pytest.raises(ScenarioError) as info:
        load_scenario(p)
    text = str(info.value)
    assert f"until.yaml:{line}: " in text and says in text, text


@pytest.mark.integration
def test_until_with_retries_over_fmus_that_cannot_save_state_is_refused(test_fmus, tmp_path):
    """The retries after until need state saving as they do on a constant step."""
    p = _two_mass_file(tmp_path, test_fmus, "  step_control: {type: error, until: 0.4}\n  discard_retries: 2",
                       left="StepLimitedMass")
    with pytest.raises(ScenarioError, match=r"until.yaml:15: coupling.discard_retries = 2 needs every FMU to "
                                            r"save and restore its state"):
        load_scenario(p)


# --- compare ---------------------------------------------------------------------------------------
@pytest.mark.integration
def test_a_compare_variant_with_until_is_checked_at_load(test_fmus, tmp_path, capsys):
    from orchestrator.compare import load_compare, main_compare
    from test_compare_capabilities import _compare, _never_runs, _two_mass
    _two_mass(tmp_path, test_fmus["LeftMass"], test_fmus["RightMass"])      # rows every 0.2 s, stop 1 s
    good = _compare(tmp_path, "{scheme: gauss-seidel, macro_step: 0.01}",
                    "    - {name: until-retry, scheme: gauss-seidel, macro_step: 0.1,\n"
                    "       set: {coupling.step_control.type: error, coupling.step_control.until: 0.4,\n"
                    "             coupling.discard_retries: 1, coupling.defect_retries: 2}}\n")
    spec = load_compare(good)
    assert [v.name for v in spec.variants] == ["until-retry"]
    path = _compare(tmp_path, "{scheme: gauss-seidel, macro_step: 0.01}",
                    "    - {scheme: gauss-seidel, macro_step: [0.2, 0.1]}\n"
                    "    - {name: off-grid, scheme: gauss-seidel, macro_step: 0.1,\n"
                    "       set: {coupling.step_control.type: error, coupling.step_control.until: 0.5}}\n"
                    "    - {name: early, scheme: gauss-seidel, macro_step: 0.1,\n"
                    "       set: {coupling.step_control.type: error, coupling.step_control.until: 0.8,\n"
                    "             start_time: 0.8}}\n"
                    "    - {name: constant-until, scheme: gauss-seidel, macro_step: 0.1,\n"
                    "       set: {coupling.step_control.until: 0.4}}\n")
    assert main_compare(path, out_dir=tmp_path / "out", runner=_never_runs, workers=1) == 2
    err = capsys.readouterr().err
    assert ("cmp.yaml:7: 'compare.variants[1]' variant 'off-grid' cannot run with these FMUs: "
            "'coupling.step_control.until' (0.5) is not on the output grid") in err and "use 0.4 or 0.6" in err
    assert ("cmp.yaml:9: 'compare.variants[2]' variant 'early' cannot run with these FMUs: "
            "'coupling.step_control.until' must lie after start_time (0.8) (got 0.8)") in err
    assert "variant 'constant-until'" in err and "is for type error" in err
    assert "gs-e0i0" not in err
    assert not (tmp_path / "out" / "runs").exists()


def test_capability_problems_apply_the_loaders_until_rule():
    """compare/capabilities.py: the shared rules, on a scenario built in code."""
    from types import SimpleNamespace

    from orchestrator.compare.capabilities import capability_problems
    state = SimpleNamespace(can_get_and_set_fmu_state=True, can_handle_variable_step=True)
    s = two_mass_scenario("gauss-seidel", 1e-2, T=1.0)
    s = dataclasses.replace(s, output=dataclasses.replace(s.output, interval=0.2))
    spec = StepControlSpec(type="error", until=0.4)
    ok = dataclasses.replace(s, coupling=dataclasses.replace(s.coupling, step_control=spec, discard_retries=1,
                                                             defect_retries=1))
    assert capability_problems(ok, {"left": state, "right": state}) == ([], [])
    no_until = dataclasses.replace(ok, coupling=dataclasses.replace(ok.coupling, step_control=dataclasses.replace(
        spec, until=None)))
    errors, _ = capability_problems(no_until, {"left": state, "right": state})
    assert len(errors) == 2 and all("cannot be combined" in e for e in errors)
    short = dataclasses.replace(ok, stop_time=0.4)      # until at stop_time: error-controlled to the end
    assert capability_problems(short, {"left": state, "right": state}) == ([], [])
    late = dataclasses.replace(ok, start_time=0.4)
    errors, _ = capability_problems(late, {"left": state, "right": state})
    assert errors and "must lie after start_time (0.4) (got 0.4)" in errors[0]


def test_until_at_or_after_stop_time_controls_the_whole_run():
    """A run shortened below until (``--set stop_time=0.01`` on a scenario with until 0.06) is
    error-controlled to its end: the same rows as the scenario without until, the retries keys inert."""
    s = two_mass_scenario("gauss-seidel", 1e-3, T=0.3)
    s = dataclasses.replace(s, output=dataclasses.replace(s.output, interval=1e-2))
    runs = []
    for until, retries in ((None, 0), (0.3, 2), (5.0, 2)):
        sc = dataclasses.replace(s, coupling=dataclasses.replace(
            s.coupling, discard_retries=retries, step_control=StepControlSpec(type="error", rtol=1e-3, until=until)))
        res = MasterAlgorithm(sc, subsystems=switched()).run()
        assert res.success, res.message
        assert "until" not in res.stats["step_control"]
        runs.append(res)
    for res in runs[1:]:
        np.testing.assert_array_equal(res.t, runs[0].t)
        for k in runs[0].outputs:
            np.testing.assert_array_equal(res.outputs[k], runs[0].outputs[k])


def test_the_error_controlled_step_redoes_a_discarded_attempt_at_half_the_step():
    """An attempt an FMU discards (fmi2Discard) is a rejected attempt of the error-controlled step: the
    states are restored and it is redone at half the length; counted in step_control.discarded_steps.
    At min_step the discard ends the run with the FMU's message."""
    from orchestrator.errors import FmuCallError
    from test_coupling_defect import IJJournal, _closed_form, film, scenario as ij

    class LongStepsDiscarded(type(film())):
        """Discards every step longer than 3e-5 s after t = 5 ms (the states must be restored: the
        base class's state is only updated by a step it takes)."""
        limit = 3e-5

        def do_step(self, t, h):
            if t >= 0.005 and h > self.limit:
                self.refused = getattr(self, "refused", 0) + 1
                raise FmuCallError("bearing", "fmi2DoStep", "discard", f"step {h:g} s too long")
            super().do_step(t, h)

    def run(limit, min_step=None):
        bearing = film()
        bearing.__class__ = LongStepsDiscarded
        bearing.limit = limit
        sc = ij()
        sc = dataclasses.replace(sc, coupling=dataclasses.replace(sc.coupling, step_control=StepControlSpec(
            type="error", rtol=1e-2, min_step=min_step)))
        return bearing, MasterAlgorithm(sc, subsystems={"rotor": IJJournal(), "bearing": bearing}).run()

    bearing, res = run(3e-5)
    assert res.success, res.message
    sc = res.stats["step_control"]
    assert sc["discarded_steps"] == bearing.refused > 0
    assert sc["max_step_taken"] > 3e-5 and res.t[-1] == pytest.approx(0.02)
    # interface-Jacobian coupling with the film's own coefficients is exact on this linear film for any
    # step, so the redone attempts must leave the closed-form motion (measured 2e-18 m; a rotor state not
    # restored after a discarded attempt would have stepped twice)
    np.testing.assert_allclose(res.outputs["rotor.x_1"], _closed_form(res.t), rtol=0, atol=1e-12)
    # a limit below min_step: the discard at min_step ends the run with the FMU's message
    bearing, res = run(1e-7, min_step=1e-6)
    assert not res.success and "step 1e-06 s too long" in res.message


@pytest.mark.integration
def test_a_compare_variant_may_replace_a_whole_section(test_fmus, tmp_path, capsys):
    """`set: {coupling.step_control: {type: constant}}` replaces the scenario's error control with until
    (the from-rest contact-phase comparison, compare/jeffcott_contact_phase_mc.yaml); before 2026-12-07 a
    mapping there was kept as a plain dict and compare ended with an internal error. A mapping with an
    unknown key, or not a mapping, is refused at its line."""
    from orchestrator.compare import load_compare, main_compare
    from orchestrator.compare.spec import apply_changes
    from test_compare_capabilities import _compare, _never_runs, _two_mass
    _two_mass(tmp_path, test_fmus["LeftMass"], test_fmus["RightMass"])
    base = (tmp_path / "two_mass.yaml").read_text().replace(
        "coupling: {scheme: gauss-seidel, macro_step: 0.1}",
        "coupling: {scheme: gauss-seidel, macro_step: 0.1, step_control: {type: error, until: 0.4}}")
    (tmp_path / "two_mass.yaml").write_text(base)
    good = _compare(tmp_path, "{scheme: gauss-seidel, macro_step: 0.01}",
                    "    - {name: constant, scheme: gauss-seidel, macro_step: 0.1,\n"
                    "       set: {coupling.step_control: {type: constant}, coupling.iteration: {max_iterations: 5}}}\n")
    spec = load_compare(good)
    sc = apply_changes(load_scenario(tmp_path / "two_mass.yaml"), spec.variants[0].changes)
    assert sc.coupling.step_control == StepControlSpec(type="constant")
    assert sc.coupling.iteration.max_iterations == 5
    for bad, says in (("{typo: constant}", "(got ['typo'])"), ("5", "(got 5)")):
        path = _compare(tmp_path, "{scheme: gauss-seidel, macro_step: 0.01}",
                        "    - {name: constant, scheme: gauss-seidel, macro_step: 0.1,\n"
                        f"       set: {{coupling.step_control: {bad}}}}}\n")
        assert main_compare(path, out_dir=tmp_path / "out", runner=_never_runs, workers=1) == 2
        err = capsys.readouterr().err
        assert "cmp.yaml:5:" in err and "'coupling.step_control': expected a mapping of" in err and says in err
        assert "internal error" not in err


def test_until_null_is_not_set():
    """`until: null` (e.g. --set coupling.step_control.until=null on a scenario that ships one) means no
    until: the error control to the end, with its usual refusal of the retries keys."""
    from pathlib import Path
    base = Path(__file__).resolve().parents[1] / "scenarios" / "jeffcott_runup_free_to_air_from_rest.yaml"
    sc = load_scenario(base, ["coupling.step_control.until=null", "coupling.defect_retries=0",
                              "coupling.discard_retries=0"])
    assert sc.coupling.step_control.type == "error" and sc.coupling.step_control.until is None
    with pytest.raises(ScenarioError, match="discard_retries cannot be combined"):
        load_scenario(base, ["coupling.step_control.until=null"])
