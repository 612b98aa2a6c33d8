"""Interface-Jacobian (linearly-implicit) coupling, rotor side (rotor_fmu/interface.py).

Set-up: the paper's Jeffcott rotor (journal mass 0.1 kg) on two "bearings" with a
film-like stiffness and squeeze damping (k = 1e7 N/m, d = 5e4 N s/m, so the explicit
limit is H < 2 m / d = 4 us), co-simulated Gauss-Seidel style with macro steps far
above that limit: the bearing's force is evaluated at the journal kinematics at t0
and held; with interface-Jacobian coupling the rotor also gets K = -dF/dr, C = -dF/dv.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rotor_fmu.jeffcott import JeffcottParams, JeffcottModel

K_LIN = 1.0e7      # N/m
D_LIN = 5.0e4      # N s/m
T_END = 0.01       # s (journals drop onto the "film" and settle; ramp speed up to 4 Hz)


class LinearBearing:
    """F = -K r - C v (anisotropic, cross-coupled like a film)."""

    def __init__(self, k=K_LIN, d=D_LIN):
        self.K = np.array([[k, 0.4 * k], [-0.6 * k, 1.3 * k]])
        self.C = np.array([[d, 0.1 * d], [0.1 * d, 1.2 * d]])

    def force(self, r, v):
        return -self.K @ r - self.C @ v

    def coeffs(self, r, v):
        return self.K, self.C


class CubicBearing(LinearBearing):
    """F = -K r - C v - k3 |r|^2 r: nonlinear, K(r) = K + k3 (|r|^2 I + 2 r r^T)."""

    k3 = 3.0e18   # N/m^3: cubic term ~ 100 % of the linear one at |r| = 2 um

    def force(self, r, v):
        return super().force(r, v) - self.k3 * (r @ r) * r

    def coeffs(self, r, v):
        return self.K + self.k3 * ((r @ r) * np.eye(2) + 2.0 * np.outer(r, r)), self.C


def _rotor():
    # disc released from the undeflected position (no initial sag): it swings at ~130 Hz
    # with ~15 um amplitude and drives the journals on the film
    r = JeffcottModel(JeffcottParams(initial_sag=False, journal_x0=2e-6))
    r.initialize()
    return r


def _kin(rotor):
    o = rotor.outputs
    return [(np.array([o[f"x_{i}"], o[f"y_{i}"]]), np.array([o[f"vx_{i}"], o[f"vy_{i}"]]))
            for i in (1, 2)]


def cosim(bearing, H, t_end=T_END, jacobian=True):
    """Gauss-Seidel co-simulation (rotor first with the held force); returns (t, x_1, y_1)
    at the macro times, or None when it blew up (non-finite/left a 1 mm ball)."""
    rotor = _rotor()
    n = int(round(t_end / H))
    out = np.empty((n + 1, 2))
    out[0] = [rotor.outputs["x_1"], rotor.outputs["y_1"]]
    for k in range(n):
        kin = _kin(rotor)
        F = np.array([bearing.force(r, v) for r, v in kin])
        if jacobian:
            KC = [bearing.coeffs(r, v) for r, v in kin]
            K = np.array([a for a, _ in KC])
            C = np.array([b for _, b in KC])
            rotor.step(H, F, K, C)
        else:
            try:
                rotor.step(H, F)
            except FloatingPointError:
                return None
        out[k + 1] = [rotor.outputs["x_1"], rotor.outputs["y_1"]]
        if not np.all(np.abs(out[k + 1]) < 1e-3):
            return None
    return H * np.arange(n + 1), out


def monolithic(bearing, t_end=T_END):
    """The rotor's first-order form with the bearing force inside (Radau, tight tolerances)."""
    rotor = _rotor()
    n = rotor.n_dof
    bd = rotor.bearing_dofs

    def f(t, s):
        F = np.array([bearing.force(s[bd[i]], s[n + bd[i]]) for i in range(2)])
        return rotor.rhs(t, s, F)

    sol = solve_ivp(f, (0.0, t_end), rotor.state_vector(), method="Radau", rtol=1e-10,
                    atol=1e-16, dense_output=True)
    assert sol.success
    return lambda t: sol.sol(t)[bd[0]].T


def test_zero_coefficients_are_the_plain_step():
    a, b = _rotor(), _rotor()
    F = np.array([[1.0, -20.0], [0.5, -25.0]])
    for _ in range(5):
        a.step(2e-5, F)
        b.step(2e-5, F, np.zeros((2, 2, 2)), np.zeros((2, 2, 2)))
    assert np.array_equal(a.s, b.s)


def test_linear_bearing_exact_at_large_macro_steps_plain_coupling_blows_up():
    """For a linear bearing the corrected force is exactly -K r(t) - C v(t), so the
    co-simulation is the monolithic solution up to the rotor's integrator error at any H;
    plain coupling at the same H (5x-25x the explicit limit 2 m/d = 4 us) blows up."""
    lin = LinearBearing()
    ref = monolithic(lin)
    scale = np.abs(ref(np.linspace(0, T_END, 200))).max()
    assert scale > 1e-6                                    # the journal really moves
    for H in (2e-5, 5e-5, 1e-4):
        t, xy = cosim(lin, H)
        err = np.abs(xy - ref(t)).max()
        assert err < 1e-3 * scale, (H, err, scale)
        assert cosim(lin, H, jacobian=False) is None
    # plain coupling below the limit works (the test's bearing is sane)
    t, xy = cosim(lin, 1e-6, t_end=2e-3, jacobian=False)
    assert np.abs(xy - ref(t)).max() < 1e-2 * scale


def test_nonlinear_bearing_first_order_convergence():
    """Tangent K(r(t0)) of a cubic spring: the held linear model is exact to first
    order in the deviation, so the co-simulation converges (at least first order) to the
    monolithic solution as H -> 0, with H far above the explicit limit."""
    cub = CubicBearing()
    ref = monolithic(cub)
    Hs = (4e-4, 2e-4, 1e-4, 5e-5)   # 100x ... 12x the explicit limit
    # (below ~2e-5 the coupling error reaches the rotor-integrator/reference level ~1e-11 m)
    errs = []
    for H in Hs:
        t, xy = cosim(cub, H)
        errs.append(np.abs(xy - ref(t)).max())
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    print("H", Hs, "err", errs, "orders", orders)
    assert np.all(orders > 0.8), (errs, orders)   # observed ~2 (trapezoidal-like)
    assert cosim(cub, 2e-5, jacobian=False) is None


def test_turbocharger_rotor_accepts_coefficients():
    """Same linearly-implicit step on the flexible rotor (shared LinearRotor.step)."""
    tc = pytest.importorskip("rotor_fmu.turbocharger")
    try:
        r = tc.TurbochargerRotor()
    except Exception as exc:   # pragma: no cover - rotor engineer's model in flux
        pytest.skip(f"turbocharger rotor not constructible: {exc}")
    r.initialize()
    r2 = tc.TurbochargerRotor()
    r2.add_linear_supports(K_LIN, D_LIN)
    r2.initialize()
    # same initial state needed for the comparison: start both from the supported one
    r.set_state(r2.get_state())
    K = np.broadcast_to(K_LIN * np.eye(2), (r.n_bearings, 2, 2))
    C = np.broadcast_to(D_LIN * np.eye(2), (r.n_bearings, 2, 2))
    H = 5e-5
    for _ in range(100):
        kin = np.array([[r.outputs[f"x_{i}"], r.outputs[f"y_{i}"], r.outputs[f"vx_{i}"],
                         r.outputs[f"vy_{i}"]] for i in range(1, r.n_bearings + 1)])
        F = -K_LIN * kin[:, :2] - D_LIN * kin[:, 2:]
        r.step(H, F, K, C)
    for _ in range(1000):
        r2.step(H / 10, np.zeros((r.n_bearings, 2)))
    a = np.array([r.outputs[f"y_{i}"] for i in range(1, r.n_bearings + 1)])
    b = np.array([r2.outputs[f"y_{i}"] for i in range(1, r.n_bearings + 1)])
    assert np.all(np.isfinite(a))
    assert np.abs(a - b).max() < 1e-3 * max(np.abs(b).max(), 1e-9), (a, b)


# Half-Sommerfeld coefficients (bearing_fmu.linearize.hs_linearization) of the turbocharger
# bearing (R 4.9 mm, B 7.84 mm, psi 2.8e-3, 40 x 40) at 66 Hz, eps 0.988, journal moving
# at 0.05 omega c outward and 1.05 omega c eps tangentially: symmetric part of C indefinite
# (eigenvalues -4.33e5, 1.37e7 N s/m), the state where the mass-conserving turbocharger
# run-ups blew up at 0.1 ms macro steps (docs/runups.md section 4).
K_NEAR_CONTACT = np.array([[4.2816e10, -4.9687e10], [-5.6990e10, 6.8650e10]])
C_NEAR_CONTACT = np.array([[6510470.9765, -7184268.6464], [-6967998.1558, 6778941.9122]])


def test_dissipative_damping_projection():
    from rotor_fmu.interface import dissipative_damping
    good = np.array([LinearBearing().C, np.zeros((2, 2))])
    assert dissipative_damping(good) is good               # PSD: untouched (bit-identical runs)
    C = np.array([C_NEAR_CONTACT, LinearBearing().C])
    P = dissipative_damping(C)
    assert np.array_equal(P[1], C[1])
    S, A = 0.5 * (P[0] + P[0].T), 0.5 * (P[0] - P[0].T)
    assert np.allclose(A, 0.5 * (C[0] - C[0].T), rtol=0, atol=1e-9)   # skew part kept
    lam = np.linalg.eigvalsh(S)
    lam0 = np.linalg.eigvalsh(0.5 * (C[0] + C[0].T))
    assert lam0[0] < -4e5 and abs(lam[0]) < 1e-6 * lam0[1]             # negative one -> 0
    assert lam[1] == pytest.approx(lam0[1], rel=1e-12)                 # positive one kept


def test_indefinite_film_damping_does_not_blow_up_the_turbocharger(monkeypatch):
    """Measured near-contact HS coefficients held over 0.1 ms steps on the turbocharger's
    compressor-side journal: with the damping used as given (negative damping 4.3e5 N s/m
    on a ~0.26 kg journal, growth ~1.7e6 1/s) the linear step explodes; with the
    dissipative projection the journal stays put."""
    tc = pytest.importorskip("rotor_fmu.turbocharger")
    import rotor_fmu.interface as interface

    K = np.array([K_NEAR_CONTACT, K_LIN * np.eye(2)])
    C = np.array([C_NEAR_CONTACT, D_LIN * np.eye(2)])

    def run(n=5, H=1e-4):
        r = tc.TurbochargerRotor()
        r.initialize()
        s = r.state_vector()
        s[r.n_dof + r.bearing_dofs[0, 0]] = 1e-4       # 0.1 mm/s velocity seed at journal 1
        r.set_state({"t": r.t, "s": s})
        for _ in range(n):
            r.step(H, np.zeros((2, 2)), K, C)
        return r

    r = run()
    x = np.array([r.outputs["x_1"], r.outputs["y_1"]])
    assert np.all(np.isfinite(r.s)) and np.abs(x).max() < 1e-7, x    # << clearance 13.7 um
    monkeypatch.setattr(interface, "dissipative_damping", lambda C: C)
    try:
        with np.errstate(all="ignore"):
            r = run()
        grown = np.abs(r.s).max()
    except FloatingPointError:
        grown = np.inf
    assert grown > 1.0, grown          # without the projection: blow-up (> 1 m)


def test_many_substeps_iterate_the_map_and_agree_with_the_matrix_form(monkeypatch):
    """Near contact the interface Jacobian asks for thousands of rotor sub-steps. The numpy
    sub-stepping then iterates the affine map instead of building its (2n, nsub n) matrix R
    (memory O(n^2), not O(nsub n^2)); both forms are the same scheme and must agree to
    round-off, unbalance forcing included."""
    tc = pytest.importorskip("rotor_fmu.turbocharger")
    import rotor_fmu.linear_rotor as lr
    if lr._kernel is not None:
        pytest.skip("numba rotor kernel selected (ROTORCOSIM_ROTOR_KERNEL)")
    import rotor_fmu.interface as interface
    K = np.array([K_NEAR_CONTACT, K_LIN * np.eye(2)])
    C = np.array([C_NEAR_CONTACT, D_LIN * np.eye(2)])
    # ~4.7e3 sub-steps needed: above LSTABLE_SWITCH, so force the trapezoidal path here
    monkeypatch.setattr(interface, "LSTABLE_SWITCH", float("inf"))

    def run(limit):
        monkeypatch.setattr(lr, "DIRECT_SUBSTEP_SIZE", limit)
        r = tc.TurbochargerRotor(tc.TurbochargerParams(f_max=105.0))
        r.initialize()
        s = r.state_vector()
        s[r.n_dof + r.bearing_dofs[0, 0]] = 1e-4
        r.set_state({"t": 3.0, "s": s})
        for _ in range(3):
            r.step(1e-4, np.array([[1.0, -50.0], [0.5, -20.0]]), K, C)
        return r.s

    matrix, direct = run(10 ** 12), run(0)
    assert np.all(np.isfinite(direct))
    assert np.abs(direct - matrix).max() <= 1e-9 * np.abs(matrix).max(), np.abs(direct - matrix).max()


# --------------------------------------------------------------------------------------
# L-stable path (LinearRotor._step_lstable, used above interface.LSTABLE_SWITCH sub-steps)

def _swapped_step(rotor, dt, F, K, C, nsub, lstable):
    """One macro step with the augmented matrices swapped in exactly as
    step_with_interface_jacobian does, with a chosen scheme and sub-step count:
    the L-stable SDIRK (``_step_lstable``) or the rotor's trapezoidal ``step``."""
    from rotor_fmu.interface import augmented, dissipative_damping
    MiK, MiC, F_eff = augmented(rotor, F, K, dissipative_damping(C))
    saved = (rotor._MiK, rotor._MiC, rotor._nsub_cache)
    try:
        rotor._MiK, rotor._MiC, rotor._nsub_cache = MiK, MiC, {dt: nsub}
        if lstable:
            rotor._step_lstable(dt, F_eff, nsub)
        else:
            rotor.step(dt, F_eff)
    finally:
        rotor._MiK, rotor._MiC, rotor._nsub_cache = saved


def _frozen_reference(rotor, dt, F, K, C):
    """State after one macro step of the ODE both schemes discretize: first-order form of
    the augmented linear system with the speed-dependent matrices frozen at the mid-step
    speed (as the rotor does) and the exact unbalance forcing; Radau, rtol 1e-12."""
    from rotor_fmu.interface import augmented, dissipative_damping
    from rotor_fmu.linear_rotor import _drive_eval_py
    MiK, MiC, F_eff = augmented(rotor, F, K, dissipative_damping(C))
    n = rotor.n_dof
    w, a, _ = _drive_eval_py(rotor.t + 0.5 * dt, *rotor._drive_tab)
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -(MiK + w * rotor._MiKc + a * rotor._MiKa)
    A[n:, n:] = -(MiC + w * rotor._MiG)
    fF = rotor._Mifg + rotor._MiB @ F_eff.reshape(-1)

    def f(t, x):
        dx = A @ x
        dx[n:] += fF + rotor._unbalance_acc(t)
        return dx

    sol = solve_ivp(f, (rotor.t, rotor.t + dt), rotor.s.copy(), method="Radau", rtol=1e-12,
                    atol=1e-18, jac=A)
    assert sol.success
    return sol.y[:, -1]


def _jeffcott_on_ramp(t0=1.0):
    """Jeffcott rotor at 400 Hz on the paper ramp (alpha = 2 pi 400 rad/s^2), a 100x
    unbalance (1e-4 kg m) and a 1 mm/s velocity seed at journal 1; exact mid-step speed in
    the trapezoidal kernel too (omega_quantum 0), so both schemes freeze the same matrices."""
    r = JeffcottModel(JeffcottParams(unbalance=1e-4, initial_sag=False, journal_x0=2e-6))
    r.omega_quantum = 0.0
    r.initialize()
    s = r.state_vector()
    s[r.n_dof + r.bearing_dofs[0, 0]] = 1e-3
    r.set_state({"t": t0, "s": s})
    return r


F_TEST = np.array([[1.0, -20.0], [0.5, -25.0]])


def _rel_err(x, ref, n):
    return max(np.abs(x[:n] - ref[:n]).max() / np.abs(ref[:n]).max(),
               np.abs(x[n:] - ref[n:]).max() / np.abs(ref[n:]).max())


def test_lstable_step_second_order_with_stiff_film_damping():
    """Stiff station damping 1e7 N s/m on a 0.1 kg journal (rate 1e8 1/s, h rate = 100..800
    here) plus a moderate cross-coupled K, unbalance and speed ramp: the SDIRK sub-steps
    converge at second order in h to the Radau solution of the same frozen linear system
    (measured: orders 1.987, 1.994, 1.997 from nsub 16 -> 128, errors 1.4e-3 -> 2.2e-5)."""
    Kst = np.array([[1e7, 4e6], [-6e6, 1.3e7]])
    K = np.array([Kst, Kst])
    C = np.array([1e7 * np.eye(2), D_LIN * np.eye(2)])
    dt = 1e-3
    ref = _frozen_reference(_jeffcott_on_ramp(), dt, F_TEST, K, C)
    errs = []
    for nsub in (16, 32, 64, 128):
        r = _jeffcott_on_ramp()
        _swapped_step(r, dt, F_TEST, K, C, nsub, lstable=True)
        assert r.t == pytest.approx(1.0 + dt, abs=1e-15)
        errs.append(_rel_err(r.s, ref, r.n_dof))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    print("errs", errs, "orders", orders)
    assert np.all(orders > 1.9) and np.all(orders < 2.2), (errs, orders)
    assert errs[-1] < 1e-4, errs


def test_lstable_and_trapezoidal_agree_to_second_order_at_moderate_stiffness():
    """Moderate film (LinearBearing: 1e7 N/m, 5e4 N s/m): both second-order schemes on
    the same sub-steps agree with each other and with the reference up to their O(h^2)
    errors; the difference falls ~4x per halving of h."""
    lin = LinearBearing()
    K = np.array([lin.K, lin.K])
    C = np.array([lin.C, lin.C])
    dt = 1e-3
    ref = _frozen_reference(_jeffcott_on_ramp(), dt, F_TEST, K, C)
    diffs = []
    for nsub in (16, 32, 64):
        a, b = _jeffcott_on_ramp(), _jeffcott_on_ramp()
        _swapped_step(a, dt, F_TEST, K, C, nsub, lstable=True)
        _swapped_step(b, dt, F_TEST, K, C, nsub, lstable=False)
        ea, eb = _rel_err(a.s, ref, a.n_dof), _rel_err(b.s, ref, b.n_dof)
        d = _rel_err(a.s, b.s, a.n_dof)
        assert d <= ea + eb + 1e-12, (nsub, d, ea, eb)
        assert max(ea, eb) < 1e-2 * (16 / nsub) ** 2, (nsub, ea, eb)   # measured 1.4e-3 / 4.4e-3 at 16
        diffs.append(d)
    ratios = np.array(diffs[:-1]) / np.array(diffs[1:])
    print("diffs", diffs, "ratios", ratios)
    assert np.all((ratios > 3.5) & (ratios < 4.5)), (diffs, ratios)


@pytest.mark.parametrize("c_film", [1e9, 1e10])
def test_film_at_the_shell_takes_the_lstable_path_without_ringing(c_film):
    """Station damping of a journal near/at the shell (1e9 - 1e10 N s/m; formerly
    StiffFilmError: ~3.4e5 / 3.4e6 trapezoidal sub-steps per 0.1 ms) on the turbocharger,
    co-simulated with a linear film F = -K r - C v: the step completes with the rotor's
    ~31 sub-steps, stays finite and the seeded station velocity (0.1 mm/s) falls at once
    to the quasi-static value of the monolithic solution and stays there -- whereas the
    trapezoidal rule with the same sub-steps rings (amplification ~ -1 per sub-step)."""
    tc = pytest.importorskip("rotor_fmu.turbocharger")
    K = np.array([K_LIN * np.eye(2), K_LIN * np.eye(2)])
    C = np.array([c_film * np.eye(2), D_LIN * np.eye(2)])
    v_seed, H, n_steps = 1e-4, 1e-4, 4

    def fresh():
        r = tc.TurbochargerRotor()
        r.initialize()
        s = r.state_vector()
        s[r.n_dof + r.bearing_dofs[0, 0]] = v_seed
        r.set_state({"t": 3.0, "s": s})
        return r

    def film(r):
        kin = r.journal_kinematics(r.t, r.s)
        return np.array([-K[i] @ kin[i, :2] - C[i] @ kin[i, 2:] for i in range(r.n_bearings)])

    # monolithic reference: film inside the rotor's first-order form
    r0 = fresh()
    n, bd = r0.n_dof, r0.bearing_dofs

    def f(t, s):
        kin = r0.journal_kinematics(t, s)
        F = np.array([-K[i] @ kin[i, :2] - C[i] @ kin[i, 2:] for i in range(r0.n_bearings)])
        return r0.rhs(t, s, F)

    def jac(t, s):
        J, JF = r0.jacobian(t)
        for i, (ix, iy) in enumerate(bd):
            J[:, [ix, iy]] -= JF[:, 2 * i:2 * i + 2] @ K[i]
            J[:, [n + ix, n + iy]] -= JF[:, 2 * i:2 * i + 2] @ C[i]
        return J

    t_out = 3.0 + H * np.arange(1, n_steps + 1)
    sol = solve_ivp(f, (3.0, t_out[-1]), r0.s.copy(), method="Radau", rtol=1e-10, atol=1e-16,
                    jac=jac, t_eval=t_out)
    assert sol.success
    v_ref = sol.y[n + bd[0, 0]]

    r = fresh()
    called = []
    orig = r._step_lstable
    r._step_lstable = lambda *a: (called.append(a[2]), orig(*a))
    dev = []
    for k in range(n_steps):
        r.step(H, film(r), K, C)
        assert np.all(np.isfinite(r.s))
        dev.append(r.outputs["vx_1"] - v_ref[k])
    assert called and all(ns == r.n_substeps(H) for ns in called), called   # 31 sub-steps
    print("c", c_film, "v_ref", v_ref, "dev", dev)
    assert np.all(np.abs(v_ref) < 1e-3 * v_seed)           # quasi-static: the seed is gone
    assert np.all(np.abs(dev) < 1e-3 * v_seed), dev
    x_ref = sol.y[:n, -1]
    print("q err", np.abs(r.s[:n] - x_ref).max(), "q scale", np.abs(x_ref).max())
    assert np.abs(r.s[:n] - x_ref).max() < 1e-5 * np.abs(x_ref).max()   # measured 3.3e-7

    # the trapezoidal rule with the same sub-steps rings: the seed comes back with alternating sign
    q = fresh()
    vt = []
    for _ in range(2):
        _swapped_step(q, H, film(q), K, C, q.n_substeps(H), lstable=False)
        vt.append(q.outputs["vx_1"])
    assert abs(vt[0]) > 0.9 * v_seed and abs(vt[1]) > 0.9 * v_seed and vt[0] * vt[1] < 0, vt


def test_below_the_switch_the_trapezoidal_path_is_bit_identical(monkeypatch):
    """Steps that need <= LSTABLE_SWITCH sub-steps use the unchanged trapezoidal code: the
    result equals (bit for bit) the former implementation, i.e. rotor.step with the
    augmented matrices swapped in and max(n_substeps, ceil(need)) sub-steps; above the
    switch the L-stable path is taken. (The numpy form: the compiled step, rotor_fmu/ij_kernel.py,
    agrees with it to round-off, tests/test_ij_kernel.py.)"""
    import rotor_fmu.interface as interface
    from rotor_fmu.interface import LSTABLE_SWITCH, augmented
    monkeypatch.setattr(interface, "FAST", False)
    lin = LinearBearing()
    calls = []

    def spy(self, dt, F, nsub):
        calls.append(nsub)
        return orig(self, dt, F, nsub)

    orig = JeffcottModel._step_lstable
    monkeypatch.setattr(JeffcottModel, "_step_lstable", spy)
    H = 1e-4
    # need = H ||M^-1 C_aug|| / 2 ~ 5e-4 x c [N s/m] on the 0.1 kg journal
    for c in (D_LIN, 3.0e6, 3.9e6):
        K = np.array([lin.K, lin.K])
        C = np.array([c * np.eye(2), lin.C])
        a, b = _jeffcott_on_ramp(), _jeffcott_on_ramp()
        a.omega_quantum = b.omega_quantum = 0.5       # the shipped default
        for _ in range(3):
            a.step(H, F_TEST, K, C)
            # former code path, written out
            MiK, MiC, F_eff = augmented(b, F_TEST, K, C)
            need = H * max(np.linalg.norm(MiC, 2), np.sqrt(np.linalg.norm(MiK, 2))) / 2.0
            assert need <= LSTABLE_SWITCH, need
            nsub = max(b.n_substeps(H), int(np.ceil(need - 1e-12)))
            saved = (b._MiK, b._MiC, b._nsub_cache)
            b._MiK, b._MiC, b._nsub_cache = MiK, MiC, {H: nsub}
            try:
                b.step(H, F_eff)
            finally:
                b._MiK, b._MiC, b._nsub_cache = saved
        assert np.array_equal(a.s, b.s) and a.t == b.t, c
    assert calls == []
    # just above the switch: L-stable, on the structural/film-stiffness sub-steps
    a = _jeffcott_on_ramp()
    a.step(H, F_TEST, np.array([lin.K, lin.K]), np.array([4.1e6 * np.eye(2), lin.C]))
    assert len(calls) == 1 and calls[0] == max(a.n_substeps(H), 1), calls
    assert np.all(np.isfinite(a.s))


def test_non_finite_film_matrices_raise_stiff_film_error():
    """StiffFilmError (a FloatingPointError: fmi2Discard in the FMU) remains for film
    coefficients whose augmented matrices overflow; nothing is done."""
    tc = pytest.importorskip("rotor_fmu.turbocharger")
    from rotor_fmu.interface import StiffFilmError
    r = tc.TurbochargerRotor()
    r.initialize()
    s0 = r.state_vector()
    K = np.array([K_NEAR_CONTACT, K_LIN * np.eye(2)])
    C = np.array([1e308 * np.eye(2), D_LIN * np.eye(2)])
    with np.errstate(all="ignore"), pytest.raises(StiffFilmError, match="non-finite") as err:
        r.step(1e-4, np.zeros((2, 2)), K, C)
    assert isinstance(err.value, FloatingPointError)
    assert np.array_equal(r.state_vector(), s0) and r.t == r.t0
