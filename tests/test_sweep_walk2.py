"""Frictions of the second sweeps walkthrough (docs/sweeps.md): too-thin oil diagnosed as a
blow-up, stability refusing a psi --set for an analysis clearance it does not use, sweep
maps that show 0/1 for the cavitation model and a made-up colour range for a constant map."""

import math

import pytest

from bearing_fmu.model import BearingModel, BearingParams
from bearing_fmu.solver import StepFailed

R, B, PSI = 4.9e-3, 7.84e-3, 2.8e-3
C = PSI * R
W = 2 * math.pi * 220.0


def _bearing(eta0, linearized=False):
    b = BearingModel(BearingParams(R=R, B=B, psi=PSI, eta0=eta0, n_phi=24, n_z=8, cavitation=0))
    b.linearized = linearized
    b.initialize(0.0, -0.5 * C, 0.0, 0.0, W)
    b.step(1e-4, 0.0, -0.95 * C, 0.0, -0.03, W)
    return b


def test_too_thin_oil_is_named_as_the_oil_not_a_blow_up():
    """eta0 = 1e-7 Pa s: the journal falls into the shell. The message used to say 'the coupled
    simulation went unstable ... use linearize: 1'; it must name eta0 and the film's load capacity."""
    b = _bearing(1e-7, linearized=True)
    cap = b.load_capacity(W)
    assert 0.0 < cap < 0.1                          # 12 mPa s carries ~1e5 times more
    with pytest.raises(StepFailed) as info:
        b.step(1e-4, 0.0, -1.16 * C, 0.0, -0.03, W)
    msg = str(info.value)
    assert "cannot carry the load" in msg and "eta0 = 1e-07 Pa s is far below any oil" in msg
    assert f"load capacity at this viscosity and speed is about {cap:.3g} N" in msg
    assert "not a coupling instability" in msg and "0.012 for 12 mPa s" in msg
    assert "unstable before" not in msg and "linearize" not in msg
    with pytest.raises(StepFailed, match="cannot carry the load"):   # just past the shell, too
        b.step(1e-4, 0.0, -1.01 * C, 0.0, -0.03, W)


def test_a_blow_up_with_real_oil_stays_a_blow_up_and_gives_the_capacity():
    b = _bearing(0.012, linearized=True)
    with pytest.raises(StepFailed) as info:
        b.step(1e-4, 0.0, -1.16 * C, 0.0, -0.03, W)
    msg = str(info.value)
    assert "went unstable before this step" in msg
    assert "interface-Jacobian coupling is already on" in msg and "(linearize: 1)" not in msg
    assert f"about {b.load_capacity(W):.3g} N at eps = 0.95" in msg
    assert "not a coupling instability" not in msg
    b = _bearing(0.012, linearized=False)
    with pytest.raises(StepFailed, match=r"use interface-Jacobian coupling \(linearize: 1\)"):
        b.step(1e-4, 0.0, -1.16 * C, 0.0, -0.03, W)


def test_load_capacity_scales_with_viscosity_and_speed():
    thin, thick = _bearing(1e-6), _bearing(1e-2)
    assert thick.load_capacity(W) == pytest.approx(1e4 * thin.load_capacity(W), rel=1e-9)
    assert thick.load_capacity(2 * W) == pytest.approx(2 * thick.load_capacity(W), rel=1e-9)
