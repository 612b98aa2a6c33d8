"""Jeffcott rotor model against closed forms.

References: Jeffcott (1919), Phil. Mag. 37; Genta (2005) "Dynamics of Rotating Systems",
ch. 4 (unbalance response, synchronous whirl is unaffected by rotating damping) and
ch. 6 (rotating damping); Friswell et al. (2010) "Dynamics of Rotating Machines" ch. 3.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rotor_fmu.drive import RampProfile, TableProfile
from rotor_fmu.jeffcott import JeffcottParams, JeffcottModel

KB = 2.0e7      # linear support stiffness per journal [N/m] (test value)


def closed_form_response(p, kb, cb, Om):
    """Complex steady-state amplitudes (Z_disc, Z_journal) of the forward synchronous
    whirl z = Z exp(i Om t), z = x + i y, for a constant speed Om, journals on isotropic
    supports kb, cb.  Rotating damping drops out (z' = i Om z).  Written independently
    of the model: disc  (k - m_d Om^2 + i Om d_e) Zd - k Zj = m e Om^2,
    journals (both)      (k + 2 kb - 2 m_j Om^2 + 2 i Om cb) Zj - k Zd = 0."""
    k = p.k_shaft
    a11 = k - p.m_disc * Om**2 + 1j * Om * p.d_external
    a22 = k + 2 * kb - 2 * p.m_journal * Om**2 + 2j * Om * cb
    det = a11 * a22 - k * k
    f = p.unbalance * Om**2
    return f * a22 / det, f * k / det


def test_natural_frequencies_on_supports_closed_form():
    p = JeffcottParams(d_external=0.0, d_internal=0.0)
    r = JeffcottModel(p)
    r.add_linear_supports(KB)
    M, C, K = r.system_matrices(0.0)
    w_model = np.sort(np.sqrt(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    md, mj, k = p.m_disc, p.m_journal, p.k_shaft
    # symmetric (disc + both journals) 2-dof: md*2mj w^4 - (md(k+2kb) + 2mj k) w^2 + 2 k kb = 0
    a, b, c = md * 2 * mj, -(md * (k + 2 * KB) + 2 * mj * k), 2 * k * KB
    w2 = np.roots([a, b, c])
    # antisymmetric journal mode (disc at rest): mj w^2 = k/2 + kb
    w_anti = np.sqrt((0.5 * k + KB) / mj)
    w_ref = np.sort(np.sqrt(np.concatenate([w2, w2, [w_anti**2, w_anti**2]])))
    np.testing.assert_allclose(w_model, w_ref, rtol=1e-10)
    # rigid supports limit: classical Jeffcott sqrt(k/m) within the journal-mass effect
    r2 = JeffcottModel(p)
    r2.add_linear_supports(1e13)
    M, C, K = r2.system_matrices(0.0)
    w1 = np.sort(np.sqrt(np.linalg.eigvals(np.linalg.solve(M, K)).real))[0]
    assert w1 == pytest.approx(np.sqrt(k / md), rel=1e-6)


def test_unbalance_response_frequency_domain_over_speed():
    """Harmonic balance of the assembled matrices (incl. rotating damping) vs closed form."""
    p = JeffcottParams()
    cb = 300.0
    r = JeffcottModel(p)
    r.add_linear_supports(KB, cb)
    for f in np.linspace(20.0, 400.0, 39):
        Om = 2 * np.pi * f
        M, C, K = r.system_matrices(Om)
        # forward whirl: q = Re(Q e^{i Om t}) with Q_y = -i Q_x; force me Om^2 (1, -i) on the disc
        Fv = np.zeros(6, complex)
        Fv[0], Fv[1] = p.unbalance * Om**2, -1j * p.unbalance * Om**2
        Q = np.linalg.solve(K - Om**2 * M + 1j * Om * C, Fv)
        Zd, Zj = closed_form_response(p, KB, cb, Om)
        assert Q[0] == pytest.approx(Zd, rel=1e-9)
        assert Q[2] == pytest.approx(Zj, rel=1e-9)
        assert Q[1] == pytest.approx(-1j * Zd, rel=1e-9)


@pytest.mark.parametrize("f_hz", [60.0, 85.0, 140.0])
def test_unbalance_response_time_domain_amplitude_phase(f_hz):
    """Constant speed below / near / above the critical (~90 Hz on these supports):
    integrated steady state vs closed-form amplitude and phase, plus the static sag."""
    cb = 200.0    # some support damping so that the start transient of the journal modes decays
    yj_static = -(6.0 + 2 * 0.1) * 9.81 / (2 * KB)
    p = JeffcottParams(f_max=f_hz, t_ramp=0.0, journal_y0=yj_static)
    r = JeffcottModel(p)
    r.add_linear_supports(KB, cb)
    r.initialize()
    dt = 5e-5
    n_settle = int(0.25 / dt)
    F0 = np.zeros((2, 2))
    for _ in range(n_settle):
        r.step(dt, F0)
    n_per = int(round(1.0 / f_hz / dt * 4))  # record ~4 revolutions
    ts, xd, yd, yj = [], [], [], []
    for _ in range(n_per):
        r.step(dt, F0)
        ts.append(r.t)
        xd.append(r.outputs["x_disc"])
        yd.append(r.outputs["y_disc"])
        yj.append(r.outputs["y_1"])
    ts, xd, yd, yj = map(np.asarray, (ts, xd, yd, yj))
    Om = 2 * np.pi * f_hz
    Zd, Zj = closed_form_response(p, KB, cb, Om)
    yd_static = yj_static - p.m_disc * p.g / p.k_shaft
    angle = np.array([r.drive.angle(t) for t in ts])
    xd_ref = np.real(Zd * np.exp(1j * angle))
    yd_ref = yd_static + np.imag(Zd * np.exp(1j * angle))
    amp = abs(Zd)
    assert np.max(np.abs(xd - xd_ref)) < 0.01 * amp
    assert np.max(np.abs(yd - yd_ref)) < 0.01 * amp
    # amplitude and phase by least squares on cos/sin of the angle
    A = np.stack([np.cos(angle), np.sin(angle)], 1)
    cx = np.linalg.lstsq(A, xd, rcond=None)[0]
    amp_fit, lag_fit = np.hypot(*cx), np.arctan2(cx[1], cx[0])
    assert amp_fit == pytest.approx(amp, rel=5e-3)
    assert lag_fit == pytest.approx(-np.angle(Zd), abs=5e-3)   # phase lag of the response
    assert np.mean(yj) == pytest.approx(yj_static, rel=1e-2)


def test_unbalance_force_includes_tangential_term():
    """f_unb = -m e d^2/dt^2 (cos phi, sin phi): check against a finite difference."""
    p = JeffcottParams(f_max=800.0, t_ramp=2.0)
    r = JeffcottModel(p)
    t, h = 0.37, 1e-5
    pos = lambda t: np.array([np.cos(r.drive.angle(t)), np.sin(r.drive.angle(t))])
    acc = (pos(t + h) - 2 * pos(t) + pos(t - h)) / h**2
    np.testing.assert_allclose(r.unbalance_forces(t)[0], -p.unbalance * acc, rtol=1e-5)
    alpha = 2 * np.pi * 800.0 / 2.0
    phi = r.drive.angle(t)
    tang = np.array([-np.sin(phi), np.cos(phi)])
    assert r.unbalance_forces(t)[0] @ tang == pytest.approx(-p.unbalance * alpha, rel=1e-9)


def test_energy_conserved_undamped_unforced():
    """Undamped, unforced, constant speed: the trapezoidal rule conserves v'Mv/2 + q'Kq/2."""
    p = JeffcottParams(d_external=0.0, d_internal=0.0, g=0.0, unbalance=0.0,
                       f_max=300.0, t_ramp=0.0, initial_sag=False)
    r = JeffcottModel(p)
    r.add_linear_supports(KB)
    r.initialize()
    s = r.get_state()
    s["s"][0], s["s"][3], s["s"][8] = 2e-5, -1e-5, 0.3   # disc x, journal 1 y, journal 2 vx
    r.set_state(s)
    e0 = r.energy()
    for _ in range(3000):
        r.step(2e-5, np.zeros((2, 2)))
    assert r.energy() == pytest.approx(e0, rel=1e-11)


def test_step_matches_first_order_rhs_second_order():
    """step() (trapezoidal sub-steps) vs a tight solve_ivp of rhs() during the ramp with
    film forces held: the error is second order in the sub-step (ratio ~4 per halving)."""
    p = JeffcottParams(max_phase_per_substep=10.0)      # one sub-step per macro step
    F = np.array([[1.0, 20.0], [-2.0, 25.0]])
    t_a, t_end = 0.3, 0.305
    errs = []
    for dt in (1e-5, 5e-6):
        r = JeffcottModel(p)
        r.add_linear_supports(2e6, 200.0)     # journal mode 6.3e3 rad/s: asymptotic regime
        r.initialize()
        st = r.get_state(); st["t"] = t_a; r.set_state(st)   # start inside the ramp
        s0 = r.state_vector()
        for _ in range(int(round((t_end - t_a) / dt))):
            r.step(dt, F)
        assert r.t == pytest.approx(t_end, abs=1e-12)
        ref = solve_ivp(lambda t, s: r.rhs(t, s, F), (t_a, t_end), s0, method="DOP853",
                        rtol=1e-12, atol=1e-18)
        kin_ref = r.journal_kinematics(t_end, ref.y[:, -1])
        kin = r.journal_kinematics(r.t, r.state_vector())
        errs.append(np.max(np.abs(kin - kin_ref) / np.abs(kin_ref).max(axis=0)))
    assert errs[1] < 1e-3
    assert 3.5 < errs[0] / errs[1] < 4.5


def test_run_up_passes_critical_with_expected_peak():
    """Slow linear run-up 50 -> 130 Hz in 1 s through the critical (~90 Hz) on linear
    supports: the peak disc amplitude approaches the steady-state peak (slow sweep,
    alpha / omega_n^2 ~ 1.6e-3; Lewis 1932, Markert & Seidler 2001) and occurs slightly
    above the critical speed; the response is also checked against an independent
    integration of the closed-form complex 2-dof equations."""
    f0, f1, t1 = 50.0, 130.0, 1.0
    kb, mj = 5e6, 0.5
    p = JeffcottParams(speed_table={"t": [0.0, t1], "f": [f0, f1]}, g=0.0, m_journal=mj)
    r = JeffcottModel(p)
    r.add_linear_supports(kb, 0.0)
    r.initialize()
    dt = 1e-4
    n = int(round(t1 / dt))
    amp = np.empty(n); fs = np.empty(n)
    for i in range(n):
        r.step(dt, np.zeros((2, 2)))
        amp[i] = np.hypot(r.outputs["x_disc"], r.outputs["y_disc"])
        fs[i] = r.outputs["omega"] / (2 * np.pi)
    Oms = 2 * np.pi * np.linspace(f0, f1, 8001)
    ss = np.abs(closed_form_response(p, kb, 0.0, Oms)[0])
    i_ss = int(np.argmax(ss))
    i_pk = int(np.argmax(amp))
    assert amp[i_pk] == pytest.approx(ss[i_ss], rel=0.05)
    assert 0.0 < fs[i_pk] - Oms[i_ss] / (2 * np.pi) < 5.0
    # independent reference: complex equations (z = x + i y) with solve_ivp
    md, k, de, me = p.m_disc, p.k_shaft, p.d_external, p.unbalance
    a = 2 * np.pi * (f1 - f0) / t1
    w0 = 2 * np.pi * f0

    def f(t, u):
        zd, zj, vd, vj = u[0] + 1j * u[1], u[2] + 1j * u[3], u[4] + 1j * u[5], u[6] + 1j * u[7]
        Om, phi = w0 + a * t, w0 * t + 0.5 * a * t * t
        fu = me * (Om**2 - 1j * a) * np.exp(1j * phi)
        ad = (fu - de * vd - k * (zd - zj)) / md
        aj = (-k * (zj - zd) - 2 * kb * zj) / (2 * mj)
        return [vd.real, vd.imag, vj.real, vj.imag, ad.real, ad.imag, aj.real, aj.imag]

    ref = solve_ivp(f, (0, t1), np.zeros(8), method="DOP853", rtol=1e-7, atol=1e-13,
                    dense_output=True)
    tt = np.arange(1, n + 1) * dt
    zr = ref.sol(tt)
    amp_ref = np.hypot(zr[0], zr[1])
    assert np.max(np.abs(amp - amp_ref)) < 0.01 * amp_ref.max()
    assert amp_ref.max() == pytest.approx(amp[i_pk], rel=0.005)


def test_state_round_trip_exact():
    r = JeffcottModel()
    r.initialize()
    F = np.array([[3.0, 30.0], [2.0, 31.0]])
    for _ in range(50):
        r.step(2e-5, F)
    s = r.get_state()
    outs = []
    for _ in range(3):
        r.step(2e-5, F)
        outs.append(dict(r.outputs))
    r.set_state(s)
    for o in outs:
        r.step(2e-5, F)
        assert r.outputs == o
    assert np.array_equal(r.state_vector(), r.get_state()["s"])


def test_api_shapes_and_errors():
    r = JeffcottModel()
    assert r.n_bearings == 2
    with pytest.raises(RuntimeError, match="initialize"):
        r.step(1e-5, np.zeros((2, 2)))
    r.initialize()
    for key in ("x_1", "y_1", "vx_1", "vy_1", "x_2", "y_2", "vx_2", "vy_2", "omega", "angle",
                "x_disc", "y_disc"):
        assert key in r.outputs
    assert r.outputs["y_disc"] == pytest.approx(-6.0 * 9.81 / 4e6)
    with pytest.raises(ValueError, match=r"shape \(2, 2\)"):
        r.step(1e-5, np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        r.step(1e-5, np.array([[np.nan, 0], [0, 0]]))
    with pytest.raises(ValueError, match="m_disc"):
        JeffcottModel(JeffcottParams(m_disc=-1.0))
    kin = r.journal_kinematics(0.0, r.state_vector())
    assert kin.shape == (2, 4)
    assert r.rhs(0.0, r.state_vector(), np.zeros((2, 2))).shape == (12,)


def test_speed_table_profile_angle_exact():
    tp = TableProfile(t=[0.0, 1.0, 3.0], f=[0.0, 100.0, 100.0])
    rp = RampProfile(f_max=100.0, t_ramp=1.0)
    for t in (0.2, 0.9, 1.0, 2.5, 4.0):
        assert tp.angle(t) == pytest.approx(rp.angle(t), rel=1e-13)
        assert tp.omega(t) == pytest.approx(rp.omega(t), rel=1e-13)
    assert rp.angle(2.0) == pytest.approx(np.pi * 100.0 * 1.0 + 2 * np.pi * 100.0 * 1.0)
    r = JeffcottModel(JeffcottParams(speed_table={"t": [0.0, 1.0], "f": [0.0, 100.0]}))
    assert r.drive.omega(0.5) == pytest.approx(2 * np.pi * 50.0)
