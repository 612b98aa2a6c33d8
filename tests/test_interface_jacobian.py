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

from rotor_fmu.jeffcott import JeffcottParams, JeffcottRotor

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
    r = JeffcottRotor(JeffcottParams(initial_sag=False, journal_x0=2e-6))
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
    K = np.array([K_NEAR_CONTACT, K_LIN * np.eye(2)])
    C = np.array([C_NEAR_CONTACT, D_LIN * np.eye(2)])

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


def test_film_at_the_shell_fails_the_step_with_a_clear_message():
    """Damping of a journal at the shell (~1e10 N s/m) would need ~1e6 sub-steps per 0.1 ms:
    the step stops (StiffFilmError, a FloatingPointError: the FMU turns it into fmi2Discard)
    instead of crawling, and says what happened."""
    tc = pytest.importorskip("rotor_fmu.turbocharger")
    from rotor_fmu.interface import MAX_INTERFACE_SUBSTEPS, StiffFilmError
    r = tc.TurbochargerRotor()
    r.initialize()
    s0 = r.state_vector()
    K = np.array([K_NEAR_CONTACT, K_LIN * np.eye(2)])
    C = np.array([1e10 * np.eye(2), D_LIN * np.eye(2)])
    with pytest.raises(StiffFilmError, match="bearing shell") as err:
        r.step(1e-4, np.zeros((2, 2)), K, C)
    assert isinstance(err.value, FloatingPointError) and str(MAX_INTERFACE_SUBSTEPS) in str(err.value)
    assert np.array_equal(r.state_vector(), s0)          # nothing was done
