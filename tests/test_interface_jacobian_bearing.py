"""Film coefficients K = -dF/dr, C = -dF/dv for interface-Jacobian coupling
(bearing_fmu/linearize.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bearing_fmu import reference as ref
from bearing_fmu.linearize import hs_force, linearization
from bearing_fmu.model import BearingParams, BearingModel

R, PSI, ETA, P0 = 0.02, 2.8e-3, 0.012, 1e5
C_CL = PSI * R
OMEGA = 2 * math.pi * 100


def params(B=0.032, n_phi=40, n_z=10, cavitation=0):
    return BearingParams(R=R, B=B, psi=PSI, eta0=ETA, p0=P0, p_feed=P0, n_phi=n_phi,
                         n_z=n_z, cavitation=cavitation)


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.mark.parametrize("xy", [(0.0, -0.6), (0.25, -0.45)])
def test_hs_coefficients_tend_to_short_bearing(xy):
    """vs the closed-form short-bearing coefficients (reference.short_bearing_coefficients,
    Lund 1987 / Childs 1993 sec. 3.6) as B/D -> 0: the finite-length error is
    O((B/D)^2), so the stiffness error must fall by ~4 per halving of B/D (accepted 3 to
    5.5) and both be below 2 % at B/D = 1/16 (360 x 40 grid; the damping reaches the
    grid-error floor of ~0.8 % there, so only its decrease is checked)."""
    x, y = xy[0] * C_CL, xy[1] * C_CL
    eK, eC = [], []
    for bd in (0.25, 0.125, 0.0625):
        B = bd * 2 * R
        b = BearingModel(params(B=B, n_phi=360, n_z=40))
        b.initialize(x, y, 0.0, 0.0, OMEGA)
        K, C = linearization(b)
        Kr, Cr = ref.short_bearing_coefficients(x, y, OMEGA, R=R, B=B, c=C_CL, eta=ETA)
        eK.append(rel(K, Kr))
        eC.append(rel(C, Cr))
    for e1, e2 in zip(eK, eK[1:]):
        assert 3.0 < e1 / e2 < 5.5, eK
    assert eK[-1] < 0.02 and eC[-1] < 0.02, (eK, eC)
    assert eC[0] > 3 * eC[-1], eC


def test_hs_coefficients_predict_a_finite_perturbation_and_leave_state_alone():
    """F(z0 + dz) - F(z0) ~ -[K C] dz to second order in dz (dz = 1e-3 c, 1e-3 c omega),
    checked per direction; linearization() does not change state/outputs."""
    b = BearingModel(params())
    z0 = np.array([0.3 * C_CL, -0.5 * C_CL, 0.02 * C_CL * OMEGA, -0.01 * C_CL * OMEGA])
    b.initialize(*z0, OMEGA)
    out0, s0 = dict(b.outputs), b.get_state()
    K, C = linearization(b)
    D = np.hstack([K, C])
    assert b.outputs == out0
    for k, v in s0.items():
        assert np.array_equal(np.asarray(v), np.asarray(b.get_state()[k]))
    f0 = hs_force(b, *z0, OMEGA)
    assert np.allclose(f0, [out0["Fx"], out0["Fy"]], rtol=1e-12)
    steps = [1e-3 * C_CL] * 2 + [1e-3 * C_CL * OMEGA] * 2
    for j in range(4):
        dz = np.zeros(4)
        dz[j] = steps[j]
        df = hs_force(b, *(z0 + dz), OMEGA) - f0
        pred = -D @ dz
        assert np.linalg.norm(df - pred) < 0.02 * np.linalg.norm(df), (j, df, pred)
    # and the damping is the large squeeze term the coupling must see (>> m/H scale)
    assert np.all(np.diag(C) > 1e4)


def test_mc_coefficients_equal_the_finite_difference_of_one_film_step():
    """Mass-conserving film: after a step that is exactly one internal BDF step, the
    coefficients (Newton-Jacobian sensitivity, film history held) equal central finite
    differences of that step's end force w.r.t. the held kinematics."""
    w = 2 * math.pi * 200
    b = BearingModel(params(cavitation=1))
    z = np.array([0.2 * C_CL, -0.5 * C_CL, 0.01 * C_CL * w, 0.02 * C_CL * w])
    b.initialize(*z, w)
    for _ in range(10):
        b.step(2e-5, *z, w)
    S = b.get_state()
    dt = min(b.film.h_next, b.params.h_max)
    n0 = b.film.stats["steps"]
    b.step(dt, *z, w)
    assert b.film.stats["steps"] == n0 + 1          # one internal step: same sensitivity
    K, C = linearization(b, method="film")

    def force(zz):
        b.set_state(S)
        b.step(dt, *zz, w)
        return np.array([b.outputs["Fx"], b.outputs["Fy"]])

    D = np.empty((2, 4))
    st = [1e-5 * C_CL] * 2 + [1e-5 * C_CL * w] * 2
    for j in range(4):
        zp, zm = z.copy(), z.copy()
        zp[j] += st[j]
        zm[j] -= st[j]
        D[:, j] = -(force(zp) - force(zm)) / (2 * st[j])
    assert rel(K, D[:, :2]) < 1e-3, (K, D[:, :2])
    assert rel(C, D[:, 2:]) < 1e-3, (C, D[:, 2:])
    # differs from the half-Sommerfeld coefficients (it is not the fallback)
    from bearing_fmu.linearize import hs_linearization
    Kh, Ch = hs_linearization(b, *z, w)
    assert rel(K, Kh) > 0.05


def test_mc_default_coefficients_are_the_quasi_static_ones_at_the_kinematics():
    """The FMU's default for the mass-conserving film: half-Sommerfeld coefficients at the
    film's current kinematics (bearing_fmu.linearize.linearization docstring)."""
    from bearing_fmu.linearize import hs_linearization
    w = 2 * math.pi * 200
    b = BearingModel(params(cavitation=1))
    z = np.array([0.2 * C_CL, -0.5 * C_CL, 0.01 * C_CL * w, 0.02 * C_CL * w])
    b.initialize(*z, w)
    b.step(2e-5, *z, w)
    K, C = linearization(b)
    Kh, Ch = hs_linearization(b, *z, w)
    assert np.array_equal(K, Kh) and np.array_equal(C, Ch)
    with pytest.raises(ValueError):
        linearization(b, method="exact")
