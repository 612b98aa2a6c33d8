"""Short-bearing coefficients and stability thresholds against independent checks.

References: Ocvirk (1952) NACA TN 2808 (short bearing); Childs (1993) "Turbomachinery
Rotordynamics" ch. 3 (pi-film forces, Lund's threshold); Lund (1974) J. Eng. Ind.
96:509; half-frequency whirl of light-loaded plain bearings (e.g. Newkirk & Taylor
1925; Vance 1988 "Rotordynamics of Turbomachinery" ch. 5).
"""

import math

import numpy as np
import pytest

from rotor_fmu.jeffcott import JeffcottParams, JeffcottModel
from rotor_fmu.stability import (
    lund_threshold_speed,
    max_real_eigenvalue,
    short_bearing_coefficient_fn,
    short_bearing_coefficients,
    short_bearing_equilibrium,
    short_bearing_force,
    threshold_speed,
)

R = 0.02
L, C, ETA = 1.6 * R, 2.8e-3 * R, 0.012
BRG = dict(R=R, L=L, C=C, eta=ETA)


def force_by_quadrature(x, y, vx, vy, omega, fixed_half=False):
    """Independent check: integrate the short-bearing pressure (Reynolds with
    h'' only in z) numerically over the region where it is positive, or (fixed_half)
    over the converging half of the gap relative to the line of centres - the
    classical pi-film convention of the closed forms with squeeze/whirl velocities."""
    th = np.linspace(0.0, 2 * np.pi, 200001)[:-1]
    dth = th[1] - th[0]
    h = C - x * np.cos(th) - y * np.sin(th)
    dh_dth = x * np.sin(th) - y * np.cos(th)
    dh_dt = -vx * np.cos(th) - vy * np.sin(th)
    # h^3/(12 eta) p_zz = omega/2 dh/dth + dh/dt  ->  int p dz = -eta L^3 Q / h^3
    Q = 0.5 * omega * dh_dth + dh_dt
    pz = -ETA * L**3 * Q / h**3
    if fixed_half:
        rel = (th - math.atan2(y, x)) % (2 * np.pi)
        pz = np.where(rel > np.pi, pz, 0.0)
    else:
        pz = np.where(pz > 0.0, pz, 0.0)
    return -R * np.sum(pz * np.cos(th)) * dth, -R * np.sum(pz * np.sin(th)) * dth


@pytest.mark.parametrize("state", [(10e-6, -30e-6, 0.0, 0.0), (-5e-6, -40e-6, 1e-3, -2e-3),
                                   (20e-6, 5e-6, -3e-3, 1e-3)])
def test_closed_form_force_matches_pressure_quadrature(state):
    w = 2 * np.pi * 200.0
    fc = np.array(short_bearing_force(*state, w, **BRG))
    fq = np.array(force_by_quadrature(*state, w, fixed_half=True))
    assert np.allclose(fc, fq, rtol=2e-4, atol=1e-6 * np.abs(fq).max())
    if state[2] == state[3] == 0.0:      # static: the positive region is exactly that half
        fp = np.array(force_by_quadrature(*state, w))
        assert np.allclose(fc, fp, rtol=2e-4, atol=1e-6 * np.abs(fq).max())


@pytest.mark.parametrize("W,f", [(30.0, 150.0), (300.0, 100.0), (1000.0, 50.0)])
def test_coefficients_match_finite_differences(W, f):
    w = 2 * np.pi * f
    K, Cm = short_bearing_coefficients((0.0, -W), w, **BRG)
    eps, psi = short_bearing_equilibrium((0.0, -W), w, **BRG)
    s0 = np.array([eps * C * math.cos(psi), eps * C * math.sin(psi), 0.0, 0.0])
    F0 = np.array(short_bearing_force(*s0, w, **BRG))
    np.testing.assert_allclose(F0, [0.0, W], atol=1e-9 * W)        # equilibrium
    assert math.cos(psi) > 0                                         # displaced towards +x (CCW spin)
    Kn, Cn = np.zeros((2, 2)), np.zeros((2, 2))
    for j, hstep in enumerate([1e-6 * C, 1e-6 * C, 1e-4 * C * w, 1e-4 * C * w]):
        d = np.zeros(4); d[j] = hstep
        dF = (np.array(short_bearing_force(*(s0 + d), w, **BRG))
              - np.array(short_bearing_force(*(s0 - d), w, **BRG))) / (2 * hstep)
        (Kn if j < 2 else Cn)[:, j % 2] = -dF
    np.testing.assert_allclose(K, Kn, rtol=1e-5, atol=1e-7 * np.abs(K).max())
    np.testing.assert_allclose(Cm, Cn, rtol=1e-5, atol=1e-7 * np.abs(Cm).max())


def test_eigenvalue_threshold_rigid_rotor_equals_lund():
    """Near-rigid rotor (very stiff shaft, tiny journals): eigenvalue threshold = Lund."""
    p = JeffcottParams(d_external=0.0, d_internal=0.0, k_shaft=1e11, m_journal=1e-3)
    r = JeffcottModel(p)
    wt, nu = threshold_speed(r, short_bearing_coefficient_fn(r, **BRG))
    m = (p.m_disc + 2 * p.m_journal) / 2
    wl = lund_threshold_speed(m, **BRG)
    assert wt == pytest.approx(wl, rel=1e-4)
    assert nu / wt == pytest.approx(0.5, abs=0.01)       # half-frequency whirl (light load)
    assert max_real_eigenvalue(r, 0.9 * wt, short_bearing_coefficient_fn(r, **BRG))[0] < 0
    assert max_real_eigenvalue(r, 1.1 * wt, short_bearing_coefficient_fn(r, **BRG))[0] > 0


def test_eigenvalue_threshold_flexible_jeffcott_equals_lund_flexible():
    """Paper's Jeffcott shaft (4000 N/mm), no external damping, light journals:
    threshold from the eigenvalues = Lund's flexible-rotor condition
    m nu^2 = K_eq k_s / (K_eq + k_s) with k_s = k_shaft / 2 per bearing; and it is
    lower than the rigid-rotor threshold."""
    p = JeffcottParams(d_external=0.0, d_internal=0.0, m_journal=1e-3)
    r = JeffcottModel(p)
    wt, nu = threshold_speed(r, short_bearing_coefficient_fn(r, **BRG))
    m = (p.m_disc + 2 * p.m_journal) / 2
    wl = lund_threshold_speed(m, k_shaft=p.k_shaft / 2, **BRG)
    assert wt == pytest.approx(wl, rel=5e-4)
    assert wt < lund_threshold_speed(m, **BRG)
    # classical bound: the onset stays below twice the rigid-support critical speed
    assert wt < 2 * math.sqrt(p.k_shaft / p.m_disc)


def test_external_damping_raises_threshold():
    fn = lambda r: short_bearing_coefficient_fn(r, **BRG)
    r0 = JeffcottModel(JeffcottParams(d_external=0.0))
    r1 = JeffcottModel(JeffcottParams(d_external=500.0))
    assert threshold_speed(r1, fn(r1))[0] > threshold_speed(r0, fn(r0))[0]


# ------------------------------------------------------------ shipped turbocharger rotor
def test_turbocharger_threshold_inside_the_runup():
    """The shipped turbocharger (rotor_fmu/data/turbocharger.yaml) on the paper's bearings
    (R = 4.9 mm, B = 1.6 R, psi = 2.8e-3, eta0 = 12 mPa s) loses stability on HS films
    inside the 0 -> 105 Hz ramp, as documented (docs/rotor-models.md): 56.59 Hz with the
    40 x 40 film of the bearing model (docs/turbocharger_threshold.py), half-frequency
    whirl of the lightly loaded compressor-side journal; the short-bearing theory
    (independent closed form) agrees to ~6 % (60.0 Hz)."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs"))
    import turbocharger_threshold as tt
    from rotor_fmu.turbocharger import TurbochargerRotor

    rotor = TurbochargerRotor()
    bearings = [tt.hs_bearing(4.9e-3, 40) for _ in range(2)]
    f, st = tt.threshold_hz(rotor, bearings, f_lo=30.0, f_hi=105.0, df=5.0)
    assert f == pytest.approx(56.59, rel=5e-3)
    assert st["whirl_hz"] / f == pytest.approx(0.5, abs=0.01)
    v = st["vec"]
    (i1, _), (i2, _) = rotor.bearing_dofs
    assert abs(v[i2]) < 0.1 * abs(v[i1])                 # the compressor-side journal whirls
    assert tt.max_real(rotor, bearings, 2 * math.pi * 45.0, {}) < 0    # stable before
    assert tt.max_real(rotor, bearings, 2 * math.pi * 80.0, {}) > 5.0  # growing after
    fn = short_bearing_coefficient_fn(rotor, R=4.9e-3, L=7.84e-3, C=2.8e-3 * 4.9e-3, eta=0.012)
    w_sb, _ = threshold_speed(rotor, fn, omega_max=2 * math.pi * 300.0)
    assert w_sb / (2 * math.pi) == pytest.approx(f, rel=0.1)
