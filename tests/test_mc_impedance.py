"""Film impedance of the mass-conserving film with its theta dynamics
(bearing_fmu.linearize.mc_impedance / MCFilmLinear; docs/analysis.md, "Linear threshold of
the mass-conserving film (film impedance)"): small grid, oil bath with a cavity
(cav_width 0.9 p0, second-order theta transport, the Jeffcott bearing of the shipped scenario)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bearing_fmu.linearize import MCFilmLinear, _force, mc_impedance
from bearing_fmu.model import BearingModel, BearingParams, solve_stationary

OMEGA = 2 * math.pi * 200.0


def params(**kw):
    p = dict(R=4.9e-3, B=7.84e-3, psi=2.8e-3, eta0=0.012, p0=1e5, p_feed=1e5, n_phi=16, n_z=8,
             cavitation=1, axial_bc=0, cav_width=9.0e4, theta_transport=1)
    p.update(kw)
    return BearingParams(**p)


@pytest.fixture(scope="module")
def state():
    p = params()
    c = p.c
    q0 = np.array([0.2 * c, -0.2 * c])
    b = solve_stationary(p, q0[0], q0[1], OMEGA)
    return p, q0, b, MCFilmLinear(b)


def test_static_impedance_is_quasi_steady_stiffness(state):
    """(a) Z(0) = -dF/dq of steady solves (central differences, O(step^2)); the slope dZ/ds(0)
    = its central difference in s, and differs from the quasi-steady damping by the cavity's
    storage term (the theta dynamics)."""
    p, q0, b, L = state
    Z0 = mc_impedance(b, 0.0)
    assert np.abs(Z0.imag).max() == 0.0
    c = p.c

    def force(x, y, vx=0.0, vy=0.0):
        kin = b._kinematics(x, y, vx, vy, OMEGA)
        u, _ = b._steady_newton(kin, L.u, np.zeros_like(L.u), 40)
        pp, th = b.law.p_theta(u)
        return np.asarray(_force(b, pp, th, kin))

    h = 1e-4 * c
    K = np.column_stack([-(force(q0[0] + h, q0[1]) - force(q0[0] - h, q0[1])) / (2 * h),
                         -(force(q0[0], q0[1] + h) - force(q0[0], q0[1] - h)) / (2 * h)])
    assert np.abs(K - Z0.real).max() < 1e-4 * np.abs(Z0).max()
    hv = 1e-4 * c * OMEGA
    C = np.column_stack([-(force(*q0, hv, 0) - force(*q0, -hv, 0)) / (2 * hv),
                         -(force(*q0, 0, hv) - force(*q0, 0, -hv)) / (2 * hv)])
    K_qs, C_qs = L.quasi_steady()
    assert np.abs(C - C_qs).max() < 1e-4 * np.abs(C_qs).max()
    ds = 1e-3 * OMEGA
    fd = (L.impedance(ds) - L.impedance(-ds)) / (2 * ds)
    dZ = L.slope0()
    assert np.abs(fd - dZ).max() < 1e-4 * np.abs(dZ).max()
    assert np.abs(dZ - C_qs).max() > 0.1 * np.abs(C_qs).max()     # the cavity's storage matters
    assert L.poles().real.max() < 0                                # the film alone is stable


def _td_column(p, q0, u0, nu, delta, n_per=200, settle=0.02):
    """Column x of Z(i nu) from the transient film under x = q0 +- delta sin(nu t)."""
    T = 2 * math.pi / nu
    dt = T / n_per
    n_settle = int(math.ceil(settle / T))
    n_tot = (n_settle + 1) * n_per
    F = []
    for sg in (1.0, -1.0):
        b = BearingModel(p)
        b.initialize(q0[0], q0[1], 0.0, 0.0, OMEGA)
        b.film.init_state(u0.copy())
        Fs = np.empty((n_tot, 2))
        for k in range(n_tot):
            tm = (k + 0.5) * dt
            b.step(dt, q0[0] + sg * delta * math.sin(nu * tm), q0[1],
                   sg * delta * nu * math.cos(nu * tm), 0.0, OMEGA)
            Fs[k] = b.outputs["Fx"], b.outputs["Fy"]
        F.append(Fs)
    tm = (np.arange(n_tot) + 0.5) * dt
    m = slice(n_settle * n_per, n_tot)
    dF = (F[0] - F[1]) / 2
    cf = 2.0 / n_per * (dF[m] * np.exp(-1j * nu * tm[m])[:, None]).sum(axis=0)
    return cf / (1j * delta)


def test_impedance_matches_transient_film(state):
    """(c) The transient film (its own BDF solver, tight tolerances) under a small prescribed
    harmonic journal motion: the force's Fourier component at nu is -Z(i nu) x."""
    p, q0, b, L = state
    pt = p.replace(theta_atol=1e-5, newton_atol=1e-7, newton_rtol=1e-8)
    bt = solve_stationary(pt, q0[0], q0[1], OMEGA)
    Lt = MCFilmLinear(bt)
    nu = 0.45 * OMEGA
    col = _td_column(pt, q0, Lt.u, nu, 1e-4 * p.c)
    Z = Lt.impedance(1j * nu)[:, 0]
    err = np.abs(col - Z).max() / np.abs(Z).max()
    print("rel diff", err)
    assert err < 2e-3


def test_update_is_a_new_linearisation_bit_for_bit():
    """MCFilmLinear.update (mc_static_equilibrium's Newton steps keep one object, issue 16
    review): after the journal moved and the film was solved again, every array and the
    impedance are those of a new MCFilmLinear at that state, to the bit; with polish = 0 too,
    and the impedance's kept matrix is that of the new state (not the old J_s)."""
    p = params()
    c = p.c
    b = solve_stationary(p, 0.2 * c, -0.2 * c, OMEGA)
    kept = MCFilmLinear(b, polish=0)
    z_old = kept.impedance(-3.0 + 900j)
    b.initialize(0.35 * c, -0.1 * c, 0.0, 0.0, OMEGA, init="stationary")     # as a Newton step moves it
    for polish in (0, 2):
        new = MCFilmLinear(b, polish=polish)
        assert kept.update(polish=polish) is kept
        for name in ("u", "r0", "Mdiag", "Rq", "Rv", "Fq", "Fv", "Fu", "F0"):
            assert np.array_equal(getattr(kept, name), getattr(new, name)), name
        assert kept.polish_step == new.polish_step
        assert (kept.Js != new.Js).nnz == 0 and np.array_equal(kept.Js.indptr, new.Js.indptr)
        for s in (0.0, -3.0 + 900j):
            assert np.array_equal(kept.impedance(s), new.impedance(s))
        assert not np.array_equal(kept.impedance(-3.0 + 900j), z_old)
