"""A PythonFMU FMU's hot FMI calls (fmi2SetReal, fmi2GetReal, fmi2DoStep) are made without
releasing the GIL (orchestrator.fmi.subsystem._holding_the_gil, issue 16): the same values as
through ctypes.CDLL, the same errors, and in a thread beside another member's thread."""

from __future__ import annotations

import ctypes
import threading

import numpy as np
import pytest

from orchestrator.errors import FmuCallError
from orchestrator.fmi import subsystem as subsystem_mod
from orchestrator.fmi.subsystem import Subsystem


def _drive(sub, n=25, params=None):
    """Parameters, initialization, n set/doStep/get cycles of a Faulty ramp; its outputs."""
    sub.set_parameters({"t_fail": 1.0, "mode": 0, **(params or {})})
    sub.setup_experiment(0.0, 1.0)
    sub.enter_initialization_mode()
    inb, outb = sub.real_batch(["u"]), sub.real_batch(["y"])
    sub.exit_initialization_mode()
    out = []
    for i in range(n):
        inb.values[:] = [0.1 * i]
        sub.set_real(inb)
        sub.do_step(i * 0.01, 0.01)
        out.append(sub.get_real(outb).copy())
    return np.array(out)


def _pythonapi(f) -> bool:
    return bool(f._flags_ & ctypes._FUNCFLAG_PYTHONAPI)


def test_a_python_fmu_is_called_holding_the_gil_with_the_same_values(test_fmus, tmp_path, monkeypatch):
    held = Subsystem("held", test_fmus["Faulty"], work_dir=tmp_path / "a")
    try:
        assert all(_pythonapi(f) for f in (held._c_set_real, held._c_get_real, held._c_do_step))
        got = _drive(held)
    finally:
        held.free()
    monkeypatch.setattr(subsystem_mod, "is_python_fmu", lambda d: False)
    plain = Subsystem("plain", test_fmus["Faulty"], work_dir=tmp_path / "b")
    try:
        assert not _pythonapi(plain._c_do_step)
        expected = _drive(plain)
    finally:
        plain.free()
    assert got.tobytes() == expected.tobytes() and got[-1, 0] == pytest.approx(0.25)


@pytest.mark.parametrize("in_thread", [False, True])
def test_an_exception_in_the_slave_is_an_fmu_call_error(test_fmus, tmp_path, in_thread):
    """Faulty mode 1: do_step raises from t_fail on; PythonFMU returns fmi2Error and clears the
    Python error, so the call held the GIL without leaving an exception set behind it."""
    sub = Subsystem("faulty", test_fmus["Faulty"], work_dir=tmp_path)
    errors = []

    def run():
        try:
            _drive(sub, params={"t_fail": 0.05, "mode": 1})
        except FmuCallError as e:
            errors.append(e)

    try:
        if in_thread:
            t = threading.Thread(target=run)
            t.start()
            t.join(60)
        else:
            run()
    finally:
        sub.free()
    assert len(errors) == 1 and errors[0].function == "fmi2DoStep" and errors[0].instance == "faulty"
