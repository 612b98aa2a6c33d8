"""Iterative coupling with interface-Jacobian coefficients held during a step's passes
(``coupling.iteration.hold_jacobian``, orchestrator/coupling/iterative.py item 7): the same converged
answer as iterating them on a linear film, what the step commits, the key, and the real FMUs' contact
phase from rest, which the iteration over the coefficients never got past."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from orchestrator.coupling.execution import MasterAlgorithm
from orchestrator.errors import ScenarioError
from orchestrator.scenario import OutputSpec, load_scenario
from orchestrator.scenario.model import IterationSpec
from test_master_adaptive_scales import CF, K0, KF, M, IJJournal, film, ij_scenario

ROOT = Path(__file__).resolve().parents[1]
FROM_REST = ROOT / "scenarios" / "jeffcott_runup_free_to_air_from_rest.yaml"


def _closed_form(t):
    """The journal on the linear film (F = -KF q - CF v) and the spring K0, released from x = 1 mm at rest."""
    w = math.sqrt((K0 + KF) / M - (CF / (2 * M)) ** 2)
    return 1e-3 * np.exp(-CF / (2 * M) * t) * (np.cos(w * t) + CF / (2 * M * w) * np.sin(w * t))


def _linear(hold, c_reported=CF, H=2e-4):
    sc = ij_scenario(None)
    sc = dataclasses.replace(
        sc, stop_time=0.02,
        coupling=dataclasses.replace(sc.coupling, scheme="iterative", macro_step=H, extrapolation_order=0,
                                     interpolation_order=1, iteration=IterationSpec(hold_jacobian=hold)),
        output=OutputSpec(interval=H, signals=("rotor.x_1", "bearing.Fx", "bearing.cxx")))
    res = MasterAlgorithm(sc, subsystems={"rotor": IJJournal(), "bearing": film(c_reported=c_reported)}).run()
    assert res.success, res.message
    return res


@pytest.mark.parametrize("c_reported", [CF, CF / 2])
def test_held_and_iterated_coefficients_converge_to_the_same_motion(c_reported):
    """On a linear film the coefficients are constants, so holding them changes nothing the iteration
    converges to: the journal's motion agrees with iterating them to the iteration tolerance, and both
    follow the closed form to the coupling's own error (also when the film reports half its damping:
    the coefficients only linearise the force within the step)."""
    held, iterated = _linear(True, c_reported), _linear(False, c_reported)
    x_h, x_i = held.outputs["rotor.x_1"], iterated.outputs["rotor.x_1"]
    np.testing.assert_allclose(x_h, x_i, rtol=0, atol=1e-9)          # 1e-6 of the 1 mm amplitude
    # against the closed form: the error falls with the step (measured 1.09e-4 / 5.85e-5 m at 0.2 / 0.1 ms,
    # the same held or iterated)
    err = np.abs(x_h - _closed_form(held.t)).max()
    finer = _linear(True, c_reported, H=1e-4)
    assert np.abs(finer.outputs["rotor.x_1"] - _closed_form(finer.t)).max() < 0.6 * err < 1e-4
    # the committed coefficient is the film's own output, not the held first iterate
    np.testing.assert_array_equal(held.outputs["bearing.cxx"][1:], c_reported)
    assert held.stats["iterations"]["total"] <= iterated.stats["iterations"]["total"]


def test_hold_jacobian_key(tmp_path):
    base = ROOT / "scenarios" / "quickstart.yaml"
    assert load_scenario(base).coupling.iteration.hold_jacobian is True
    assert load_scenario(base, ["coupling.iteration.hold_jacobian=false"]).coupling.iteration.hold_jacobian is False
    for bad, got in (("1", "1"), ("yes please", "'yes please'"), ("[true]", "a list")):
        with pytest.raises(ScenarioError, match=r"'coupling.iteration.hold_jacobian' must be true or false "
                                                rf"\(got {got}"):
            load_scenario(base, [f"coupling.iteration.hold_jacobian={bad}"])
    text = base.read_text().replace("coupling:\n", "coupling:\n  iteration: {hold_jacobian: maybe}\n", 1)
    (tmp_path / "s.yaml").write_text(text)
    with pytest.raises(ScenarioError, match=r"s\.yaml:\d+.*hold_jacobian"):
        load_scenario(tmp_path / "s.yaml")


def _from_rest(tmp_path, hold, stop):
    from orchestrator import run as run_scenario
    sc = load_scenario(FROM_REST, [f"stop_time={stop}", "coupling.scheme=iterative", "coupling.defect_retries=0",
                                   "coupling.step_control={type: constant}",    # shipped: error-controlled phase
                                   "coupling.iteration.max_iterations=50",
                                   f"coupling.iteration.hold_jacobian={'true' if hold else 'false'}"])
    return run_scenario(sc, out_dir=tmp_path / str(hold), progress=False)


def test_contact_phase_from_rest_iterative(tmp_path):
    """docs/coupling.md 'Iterative coupling': the mass-conserving run-up from rest (journals on the shell,
    the stiff asperity contact). Iterating the coefficients with the forces, the first step does not
    converge; held, the first 10 ms run at 5-8 passes per step and the bearing forces stay at the load's
    scale (29.4 N per bearing; measured 46 N at most over the 60 ms to lift-off, where the constant step
    of the explicit scheme records 2637 N and the error-controlled step, which resolves the phase, stays
    below 60 N)."""
    res = _from_rest(tmp_path, False, 0.002)
    assert not res.success and "iterative coupling did not converge in the macro step t=0.." in res.message
    res = _from_rest(tmp_path, True, 0.01)
    assert res.success, res.message
    np.testing.assert_allclose(res.t, np.linspace(0.0, 0.01, 101), atol=1e-15)
    peak = max(np.hypot(res.outputs[f"bearing{i}.Fx"], res.outputs[f"bearing{i}.Fy"]).max() for i in (1, 2))
    assert 20.0 < peak < 60.0
    assert res.stats["iterations"]["mean_per_step"] < 10


def test_a_residual_close_to_tol_suggests_a_larger_tol():
    """A step that ends a few orders above tol (the films' own Newton stalls a pass's outputs at ~1e-6)
    names the tolerance as the setting to change; one far from converging does not."""
    from types import SimpleNamespace
    from orchestrator.coupling.iterative import IterativeMacroStep
    step = SimpleNamespace(names=["rotor.Fx_2"], spec=IterationSpec(max_iterations=50))
    close = IterativeMacroStep._message(step, SimpleNamespace(worst=0, residual=2.4e-6, iterations=50), 0.0, 1e-4)
    assert "still changed by 2.4e-06 of its scale (tol 1e-08)" in close
    assert "coupling.iteration.tol above it, e.g. 1e-05" in close
    far = IterativeMacroStep._message(step, SimpleNamespace(worst=0, residual=0.8, iterations=50), 0.0, 1e-4)
    assert "coupling.iteration.tol" not in far and "raise coupling.iteration.max_iterations" in far


def test_iterative_with_held_end_values_warns(tmp_path, caplog):
    """`scheme: iterative` with interpolation_order 0 holds every input at its end-of-step iterate (first
    order, damping: the whole from-rest run-up's onset at 440 Hz against 359-373 Hz); the loader says so and
    names interpolation_order 1. With 1, or with an explicit scheme, no such warning."""
    import logging
    import shutil
    from orchestrator.scenario.checks import ITERATIVE_HELD_WARNING
    path = tmp_path / "from_rest.yaml"          # a path of its own: the loader warns once per text and process
    shutil.copy(FROM_REST, path)
    for sets, warned in ((["coupling.scheme=iterative"], True),
                         (["coupling.scheme=iterative", "coupling.interpolation_order=1"], False),
                         ([], False)):
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="orchestrator.scenario.checks"):
            load_scenario(path, sets + ["coupling.defect_retries=0", "coupling.step_control={type: constant}"])
        got = [r.getMessage() for r in caplog.records if ITERATIVE_HELD_WARNING in r.getMessage()]
        assert bool(got) == warned, (sets, [r.getMessage() for r in caplog.records])
    assert "interpolation_order: 1" in ITERATIVE_HELD_WARNING
