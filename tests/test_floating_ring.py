"""Floating-ring bearing model (bearing_fmu/floating_ring.py) against independent references.

* Petroff's friction torque of a centred journal, ``T = -2 pi eta R^3 B (omega - Omega) / c``
  (Petroff 1883; Hamrock et al. 2004, *Fundamentals of Fluid Film Lubrication*, sec. 8.4);
* the steady ring speed ratio of two concentric films, ``Omega / omega = a / (a + b)``,
  ``a = eta_i R_i^3 B_i / c_i``, ``b = eta_o R_o^3 B_o / c_o`` (Petroff torque balance), and
  the exponential approach to it with time constant ``J / (2 pi (a + b))``;
* each film's force with a moving and spinning shell against Ocvirk's short bearing
  (``bearing_fmu.reference.short_bearing_force``) with the journal kinematics relative to
  the ring and the wedge driven by the sum of the surface speeds, at B/D = 1/16 (the
  finite-length error there is below 1 %, tests/test_bearing_validation.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bearing_fmu import reference as ref
from bearing_fmu.floating_ring import (FloatingRing, RingParams, petroff_coefficient, petroff_ratio,
                                       shear_torques, static_equilibrium)
from bearing_fmu.model import BearingParams, BearingModel

R_I = 4.9e-3
PSI_I = 2.8e-3
ETA = 0.012
OMEGA = 2 * math.pi * 200.0


def ring_params(*, B_i=7.84e-3, B_o=7.84e-3, n_phi=40, n_z=40, cavitation=0, **kw):
    inner = BearingParams(R=R_I, B=B_i, psi=PSI_I, eta0=ETA, n_phi=n_phi, n_z=n_z,
                          cavitation=cavitation)
    outer = BearingParams(R=1.6 * R_I, B=B_o, psi=2 * PSI_I / 1.6, eta0=0.8 * ETA, n_phi=n_phi,
                          n_z=n_z, cavitation=cavitation)
    kw.setdefault("gravity", 0.0)
    return RingParams(inner=inner, outer=outer, **kw)


def rel(a, b):
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b))


@pytest.mark.parametrize("cavitation", [0, 1])
@pytest.mark.parametrize("omega_ring", [0.0, 0.3 * OMEGA])
def test_petroff_torque_centred(cavitation, omega_ring):
    """Centred journal and ring: the torque on the journal and on the ring's bore are
    Petroff's, with the slip omega - Omega (p = p0 everywhere). The mass-conserving film
    at p = p0 has the fluid fraction theta(p0) = 1 + delta ln(1 - e^-3) of its cavitation
    law (bearing_fmu/cavitation.py; 0.99751 at delta = 0.05), which scales the Couette
    shear exactly."""
    fr = FloatingRing(ring_params(cavitation=cavitation))
    fr.initialize(0.0, 0.0, 0.0, 0.0, OMEGA, omega_ring=omega_ring)
    out = fr.outputs
    th0 = 1.0 if cavitation == 0 else 1 + fr.params.inner.cav_smoothing * math.log(1 - math.exp(-3))
    a = th0 * petroff_coefficient(fr.params.inner)
    b = th0 * petroff_coefficient(fr.params.outer)
    T_ref = -2 * math.pi * a * (OMEGA - omega_ring)
    assert out["T_journal"] == pytest.approx(T_ref, rel=1e-9)
    assert out["T_ring_inner"] == pytest.approx(-T_ref, rel=1e-9)
    assert out["T_ring_outer"] == pytest.approx(-2 * math.pi * b * omega_ring, rel=1e-9, abs=1e-15)
    P_ref = -T_ref * OMEGA + T_ref * omega_ring + 2 * math.pi * b * omega_ring ** 2
    assert out["P_loss"] == pytest.approx(P_ref, rel=1e-9)


def test_shear_torque_matches_film_torque_for_a_fixed_shell():
    """With the shell at rest, :func:`shear_torques` on the journal is the film's own torque
    output (same face quadrature, ``film.integrals``), eccentric and cavitated."""
    p = BearingParams(R=R_I, B=7.84e-3, psi=PSI_I, eta0=ETA, cavitation=0)
    b = BearingModel(p)
    x, y = 0.3 * p.c, -0.5 * p.c
    b.initialize(x, y, 0.0, 0.0, OMEGA)
    Tj, _ = shear_torques(b.fields(), x, y, p.c, p.R, p.B, p.eta0, OMEGA, 0.0, OMEGA)
    assert Tj == pytest.approx(b.outputs["torque"], rel=1e-10)


def test_torque_difference_is_the_pressure_couple():
    """T_journal + T_shell = -R int h dp/dx dA (the Couette parts cancel): for an eccentric
    film this couple is e x F (the pressure force on the journal acts on the journal
    centre, its reaction on the shell centre), up to the grid error."""
    p = BearingParams(R=R_I, B=7.84e-3, psi=PSI_I, eta0=ETA, n_phi=160, n_z=40, cavitation=0)
    b = BearingModel(p)
    x, y = 0.2 * p.c, -0.55 * p.c
    b.initialize(x, y, 0.0, 0.0, OMEGA)
    Tj, Ts = shear_torques(b.fields(), x, y, p.c, p.R, p.B, p.eta0, OMEGA, 0.3 * OMEGA, 1.3 * OMEGA)
    Fx, Fy = b.outputs["Fx"], b.outputs["Fy"]
    couple = x * Fy - y * Fx          # torque about the shell centre of F applied at the journal centre
    assert Tj + Ts == pytest.approx(-couple, rel=0.02)


def test_concentric_ring_speed_ratio_closed_form():
    """Concentric films: the ring spins up from rest to a / (a + b) of the journal speed
    with time constant tau = J / (2 pi (a + b)); compared at t = 0.5 tau, 1 tau and 8 tau."""
    P = ring_params(J_ring=2e-8, h_ring=2e-5)
    fr = FloatingRing(P)
    fr.initialize(0.0, 0.0, 0.0, 0.0, OMEGA, omega_ring=0.0)
    a, b = petroff_coefficient(P.inner), petroff_coefficient(P.outer)
    ratio = a / (a + b)
    assert petroff_ratio(P) == pytest.approx(ratio)
    tau = P.J_ring / (2 * math.pi * (a + b))
    n_tau = 50                      # steps per tau (each 2.5 ring sub-steps)
    dt = tau / n_tau
    for k in range(1, 8 * n_tau + 1):
        fr.step(dt, 0.0, 0.0, 0.0, 0.0, OMEGA)
        if k in (n_tau // 2, n_tau, 8 * n_tau):
            exact = ratio * (1 - math.exp(-k * dt / tau))
            assert fr.outputs["omega_ring"] / OMEGA == pytest.approx(exact, rel=2e-4)
    assert fr.outputs["eps"] == 0.0 and fr.outputs["eps_outer"] == 0.0


def test_semi_floating_ring_does_not_spin():
    fr = FloatingRing(ring_params(floating=0, J_ring=2e-8))
    fr.initialize(0.0, 0.0, 0.0, 0.0, OMEGA)
    for _ in range(5):
        fr.step(1e-4, 0.0, 0.0, 0.0, 0.0, OMEGA)
    assert fr.outputs["omega_ring"] == 0.0
    assert fr.outputs["T_journal"] == pytest.approx(-2 * math.pi * petroff_coefficient(fr.params.inner)
                                                    * OMEGA, rel=1e-9)


# (journal x, y, vx, vy) / c_i, ring (x, y, vx, vy) / c_o, Omega / omega
SHELL_CASES = {
    "ring spinning": ((0.1, -0.5, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), 0.4),
    "ring moving and spinning": ((0.25, -0.45, 0.08, 0.05), (-0.2, 0.1, -0.03, 0.06), 0.35),
    "journal still, ring spinning": ((0.0, -0.6, 0.0, 0.0), (0.1, 0.0, 0.02, 0.0), 1.0),
}


@pytest.mark.parametrize("case", sorted(SHELL_CASES))
def test_films_with_moving_spinning_shell_vs_ocvirk(case):
    """Both films at B/D = 1/16 against Ocvirk's short bearing: the inner film with the
    journal relative to the moving ring and the wedge speed omega + Omega, the outer film
    with the ring's own kinematics and Omega. Velocities are given in units of c omega."""
    jn, rg, k = SHELL_CASES[case]
    spin_j = 0.0 if case.startswith("journal still") else OMEGA
    B_i, B_o = 2 * R_I / 16, 2 * 1.6 * R_I / 16
    P = ring_params(B_i=B_i, B_o=B_o, n_phi=360, n_z=40)
    ci, co = P.inner.c, P.outer.c
    w = OMEGA
    journal = (jn[0] * ci + rg[0] * co, jn[1] * ci + rg[1] * co,
               jn[2] * ci * w + rg[2] * co * w, jn[3] * ci * w + rg[3] * co * w)
    ring = tuple(v * co * (w if i >= 2 else 1.0) for i, v in enumerate(rg))
    Om = k * OMEGA
    fr = FloatingRing(P)
    fr.initialize(*journal, spin_j, ring=ring, omega_ring=Om)
    rel_kin = [journal[i] - ring[i] for i in range(4)]
    f_in = ref.short_bearing_force(*rel_kin, spin_j + Om, R=R_I, B=B_i, c=ci, eta=ETA)
    assert rel([fr.outputs["Fx"], fr.outputs["Fy"]], f_in) < 0.01
    fo = fr.outer.outputs
    if any(rg):
        f_out = ref.short_bearing_force(*ring, Om, R=P.outer.R, B=B_o, c=co, eta=P.outer.eta0)
        assert rel([fo["Fx"], fo["Fy"]], f_out) < 0.01


def test_half_frequency_whirl_of_the_inner_film_carries_no_load():
    """A journal whirling round the ring centre at (omega + Omega) / 2 with the ring at rest
    in translation sees no film force (the wedge and the squeeze cancel exactly in the
    continuous equation; discretely the wedge uses the gap at the faces and the squeeze the
    centre values, an O(dphi^2) mismatch: measured 1.1e-4 of the static force at 120 cells)."""
    P = ring_params(n_phi=120)
    ci = P.inner.c
    Om = 0.35 * OMEGA
    nu = 0.5 * (OMEGA + Om)
    e = 0.4 * ci
    fr = FloatingRing(P)
    fr.initialize(e, 0.0, 0.0, e * nu, OMEGA, omega_ring=Om)
    f_static = FloatingRing(P)
    f_static.initialize(e, 0.0, 0.0, 0.0, OMEGA, omega_ring=Om)
    assert math.hypot(fr.outputs["Fx"], fr.outputs["Fy"]) < 1e-3 * math.hypot(
        f_static.outputs["Fx"], f_static.outputs["Fy"])


def test_state_round_trip_and_failed_step_keeps_state():
    P = ring_params(cavitation=1, m_ring=7e-3, J_ring=3e-7)
    fr = FloatingRing(P)
    fr.initialize(0.0, -0.3 * P.inner.c, 0.0, 0.0, OMEGA, ring="equilibrium")
    fr.step(1e-4, 0.0, -0.3 * P.inner.c, 0.0, 0.0, OMEGA)
    s = fr.get_state()
    out = dict(fr.outputs)
    fr.step(1e-4, 0.0, -0.31 * P.inner.c, 0.0, 0.0, OMEGA)
    fr.set_state(s)
    assert fr.outputs == out
    with pytest.raises(Exception):
        fr.step(1e-4, 0.0, -2.0 * P.inner.c - 3 * P.outer.c, 0.0, 0.0, OMEGA)
    assert fr.outputs == out


def test_bad_parameters_name_the_field():
    inner = BearingParams(R=R_I, B=7.84e-3, psi=PSI_I, eta0=ETA)
    with pytest.raises(ValueError, match="outer radius"):
        RingParams(inner=inner, outer=BearingParams(R=R_I, B=7.84e-3, psi=PSI_I, eta0=ETA))
    with pytest.raises(ValueError, match="floating"):
        ring_params(floating=2)
    with pytest.raises(ValueError, match="m_ring"):
        ring_params(m_ring=-1.0)
    with pytest.raises(ValueError, match="input_hold"):
        ring_params(input_hold=3)
    with pytest.raises(ValueError, match="ring_integrator"):
        ring_params(ring_integrator=2)


def test_step_coefficients_limits():
    """Short step: the inner film alone (the ring's inertia holds it); long step: the two
    films in series, K_i (K_i + K_o)^-1 K_o (the ring settles under the held input)."""
    from bearing_fmu.floating_ring import step_coefficients
    Ki = np.array([[1e6, 4e5], [-2e6, 2e6]])
    Ko = np.array([[3e6, -1e5], [-1e6, 1e6]])
    Ci = np.array([[1e4, -2e3], [-3e3, 2e4]])
    Co = np.array([[3e4, -4e3], [-4e3, 1e4]])
    K0, C0 = step_coefficients(Ki, Ci, Ko, Co, 7e-3, 1e-14)
    assert np.allclose(K0, Ki, rtol=1e-6) and np.allclose(C0, Ci, rtol=1e-6)
    Kl, _ = step_coefficients(Ki, Ci, Ko, Co, 7e-3, 1.0)
    assert np.allclose(Kl, Ki @ np.linalg.solve(Ki + Ko, Ko), rtol=1e-6)


def test_static_equilibrium_balances_both_films():
    """At static_equilibrium the inner film carries the load and the outer film the load plus
    the ring weight (the ring's net force vanishes)."""
    from bearing_fmu.floating_ring import static_equilibrium
    P = ring_params(gravity=9.81, m_ring=7.3e-3)
    journal, ring = static_equilibrium(P, 29.43, OMEGA)
    fr = FloatingRing(P)
    fr.initialize(*journal, 0.0, 0.0, OMEGA, ring=(*ring, 0.0, 0.0))
    assert fr.outputs["Fx"] == pytest.approx(0.0, abs=1e-6)
    assert fr.outputs["Fy"] == pytest.approx(29.43, rel=1e-8)
    fo = fr.outer.outputs
    assert fo["Fy"] == pytest.approx(29.43 + 7.3e-3 * 9.81, rel=1e-8)
    assert fr.equilibrium() == pytest.approx(ring, rel=1e-6)


def test_ring_time_integration_is_second_order():
    """BDF2 (``ring_integrator = 0``). The journal follows a prescribed smooth orbit, given at the end of each step (as a
    Gauss-Seidel master gives it); the ring's position after 1 ms converges at second order
    (linearly implicit BDF2) against a run with 16x smaller steps: the error falls by more
    than 10 from 80 us to 20 us steps (16 for exact second order, 4 for first order; measured
    57, pre-asymptotic). The trapezoidal rule used before stalled at 1.2e-8 m (its stiff ring
    mode, m_r / C ~ 1 us, is not damped: amplification -> -1)."""
    P = ring_params(m_ring=7.3e-3, J_ring=3.1e-7, n_phi=24, n_z=8)
    ci = P.inner.c
    w = 2 * math.pi * 150.0

    def journal(t):
        return (0.25 * ci * math.cos(w * t), -0.3 * ci + 0.25 * ci * math.sin(w * t),
                -0.25 * ci * w * math.sin(w * t), 0.25 * ci * w * math.cos(w * t), OMEGA)

    def run(dt):
        fr = FloatingRing(P.replace(h_ring=dt, ring_integrator=0, input_hold=0))
        fr.initialize(*journal(0.0), ring=(0.0, -0.2 * P.outer.c, 0.0, 0.0))
        for k in range(1, round(1e-3 / dt) + 1):
            fr.step(dt, *journal(k * dt))
        return np.array([fr.outputs["x_ring"], fr.outputs["y_ring"]])

    ref = run(5e-6)
    e_coarse = np.linalg.norm(run(8e-5) - ref)
    e_fine = np.linalg.norm(run(2e-5) - ref)
    assert e_coarse / e_fine > 10
    assert e_fine < 1e-4 * P.outer.c


def test_expm_small_matches_scipy():
    """The compiled scaling-and-squaring Taylor exponential of the ring's augmented ODE against
    scipy's Pade expm, on a matrix as stiff as the ring's (h C / m_r ~ 300)."""
    from scipy.linalg import expm
    from bearing_fmu.floating_ring_expm import expm_small
    rng = np.random.default_rng(1)
    A = np.zeros((8, 8))
    A[:2, 2:4] = np.eye(2)
    A[2:4, :2] = -rng.random((2, 2)) * 4e9
    A[2:4, 2:4] = -rng.random((2, 2)) * 3e6
    A[:4, 4:] = rng.random((4, 4)) * 1e3
    A[5, 4] = A[6, 5] = A[7, 6] = 1.0
    E = expm(1e-4 * A)
    assert np.max(np.abs(expm_small(1e-4 * A) - E)) < 1e-9 * np.max(np.abs(E))
    assert np.allclose(expm_small(np.zeros((3, 3))), np.eye(3))


def test_exponential_ring_integrator_is_exact_for_a_small_whirl():
    """The journal whirls at 540 Hz (the Jeffcott case's inner-film whirl) with 0.002 c_i round
    its static equilibrium; ring and spin start at theirs (spin held: J huge). The ring's
    position after 2 ms against a 2.5 us reference: the exponential integrator with the cubic
    Hermite input (the defaults, ``ring_integrator = 1``, ``input_hold = 2``) is exact for the
    linearised ring, so only the films' nonlinearity and the input's interpolation are left:
    measured error 4.5e-4 of the whirl amplitude at 0.1 ms steps, falling at second order,
    against 4.2e-2 for BDF2 with the zero-order hold (the inner whirl's +35 1/s growth-rate error
    at 850 Hz, docs/floating-ring.md)."""
    P = ring_params(m_ring=7.3e-3, J_ring=1e3, n_phi=24, n_z=8)
    (jx, jy), _ = static_equilibrium(P, 30.0, OMEGA)
    a, w = 2e-3 * P.inner.c, 2 * math.pi * 540.0

    def journal(t):
        return (jx + a * math.cos(w * t), jy + a * math.sin(w * t), -a * w * math.sin(w * t),
                a * w * math.cos(w * t), OMEGA)

    def run(dt, **kw):
        fr = FloatingRing(P.replace(h_ring=dt, **kw))
        fr.initialize(*journal(0.0), ring="equilibrium", omega_ring=0.3 * OMEGA)
        for k in range(1, round(2e-3 / dt) + 1):
            fr.step(dt, *journal(k * dt))
        return np.array([fr.outputs["x_ring"], fr.outputs["y_ring"]])

    ref = run(2.5e-6)
    e_exp = [np.linalg.norm(run(dt) - ref) / a for dt in (1e-4, 5e-5)]
    e_bdf = np.linalg.norm(run(1e-4, ring_integrator=0, input_hold=0) - ref) / a
    assert e_exp[0] < 2e-3
    assert e_exp[0] < e_bdf / 20
    assert e_exp[0] / e_exp[1] > 3            # second order (4 exact)
