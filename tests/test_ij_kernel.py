"""The compiled interface-Jacobian step (rotor_fmu/ij_kernel.py) against the numpy form.

The kernel is the same scheme as rotor_fmu/interface.py's numpy code in another
floating-point order: the same sub-step counts and projection decisions, states equal to
round-off. Where a decision could go either way by round-off it must hand the step back
(FALLBACK), and the numpy form then gives the former result bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import rotor_fmu.interface as interface
from rotor_fmu import ij_kernel
from rotor_fmu.jeffcott import JeffcottModel, JeffcottParams

pytestmark = pytest.mark.skipif(ij_kernel.kernel is None, reason="numba not installed")

# the shipped MC run-up's rotor (scenarios/jeffcott_runup_oil_bath.yaml), on the ramp at 160 Hz
RUNUP = dict(f_max=800.0, t_ramp=2.0, d_external=500.0, m_disc=5.0, m_journal=0.5,
             journal_x0=4.988e-6, journal_y0=-2.019e-6, t0=0.4)
H = 1e-4


def _jeffcott(**kw):
    r = JeffcottModel(JeffcottParams(**{**RUNUP, **kw}))
    r.initialize()
    return r


def _turbocharger():
    tc = pytest.importorskip("rotor_fmu.turbocharger")
    r = tc.TurbochargerRotor(tc.TurbochargerParams(f_max=105.0))
    r.initialize()
    r.set_state({"t": 3.0, "s": r.state_vector()})
    return r


def _film(rng, nb, k=(1e6, 1e8), c=(1e3, 1e5), indefinite=False):
    """Random film-like coefficients: cross-coupled stiffness, damping with a positive
    definite (or, with ``indefinite``, an indefinite) symmetric part and a skew part."""
    K = np.empty((nb, 2, 2))
    C = np.empty((nb, 2, 2))
    for i in range(nb):
        ks = 10 ** rng.uniform(*np.log10(k))
        K[i] = ks * (np.eye(2) + rng.uniform(-0.8, 0.8, (2, 2)))
        cs = 10 ** rng.uniform(*np.log10(c))
        Q, _ = np.linalg.qr(rng.normal(size=(2, 2)))
        lam = cs * (rng.uniform(0.05, 1.0, 2) if not indefinite else np.array([-rng.uniform(0.01, 0.3), 1.0]))
        skew = cs * rng.uniform(-0.3, 0.3) * np.array([[0.0, 1.0], [-1.0, 0.0]])
        C[i] = (Q * lam) @ Q.T + skew
    return K, C


def _perturbed(rotor, rng):
    s = rotor.state_vector()
    n = rotor.n_dof
    s[:n] += 1e-6 * rng.normal(size=n)
    s[n:] += 1e-3 * rng.normal(size=n)
    rotor.set_state({"t": rotor.t, "s": s})


def _both(make, rng, K, C, F, steps=1):
    """(compiled, numpy) states after ``steps`` macro steps from the same state."""
    a, b = make(), make()
    _perturbed(a, np.random.default_rng(7))
    _perturbed(b, np.random.default_rng(7))
    for _ in range(steps):
        assert interface._fast_step(a, H, F, K, C), "the compiled step handed the step back"
        b_fast, interface.FAST = interface.FAST, False
        try:
            b.step(H, F, K, C)
        finally:
            interface.FAST = b_fast
    return a, b


def _rel(a, b):
    """Largest difference of the states relative to the size of each half (positions, velocities)."""
    n = a.n_dof
    return max(np.abs(a.s[:n] - b.s[:n]).max() / np.abs(b.s[:n]).max(),
               np.abs(a.s[n:] - b.s[n:]).max() / np.abs(b.s[n:]).max())


@pytest.mark.parametrize("rotor", ["jeffcott", "turbocharger"])
@pytest.mark.parametrize("indefinite", [False, True])
def test_compiled_step_agrees_with_the_numpy_form_on_random_coefficients(rotor, indefinite):
    make = _jeffcott if rotor == "jeffcott" else _turbocharger
    rng = np.random.default_rng(11 if indefinite else 3)
    worst = 0.0
    for _ in range(12):
        K, C = _film(rng, 2, indefinite=indefinite)
        F = rng.normal(scale=30.0, size=(2, 2))
        a, b = _both(make, rng, K, C, F, steps=3)
        worst = max(worst, _rel(a, b))
        assert a.t == b.t
    assert worst < 1e-12, worst


def test_sub_step_counts_and_projection_are_the_numpy_forms():
    """The kernel's sub-step count is max(n_substeps, ceil(H rho / 2 - 1e-12)) with rho from
    numpy's 2-norms, and its projected damping is dissipative_damping's (to round-off)."""
    rng = np.random.default_rng(5)
    r = _jeffcott()
    counts = set()
    for i in range(40):
        K, C = _film(rng, 2, c=(1e2, 3e6), indefinite=bool(i % 2))
        F = rng.normal(scale=30.0, size=(2, 2))
        Cp = interface.dissipative_damping(C)
        MiK, MiC, _ = interface.augmented(r, F, K, Cp)
        need = H * max(np.linalg.norm(MiC, 2), math.sqrt(np.linalg.norm(MiK, 2))) / 2.0
        if need > interface.LSTABLE_SWITCH:
            continue
        nsub = max(r.n_substeps(H), int(math.ceil(need - 1e-12)))
        out = np.empty_like(r.s)
        code, got = ij_kernel.kernel(r.s, r.t, H, r.n_substeps(H), F, K, C, r.bearing_dofs, r._MiK, r._MiC,
                                     r._MiG, r._MiKc, r._MiKa, r._MiB, r._Mifg, r._MiU, r._me, r._ph,
                                     *r._drive_tab, r.omega_quantum, r._speed_dependent,
                                     float(interface.LSTABLE_SWITCH), out)
        assert code == ij_kernel.DONE and got == nsub, (code, got, nsub)
        counts.add(nsub)
        proj = np.empty_like(C)
        assert ij_kernel._project(C, proj)
        assert np.abs(proj - Cp).max() <= 1e-12 * np.abs(C).max()
    assert len(counts) > 5, counts          # the cases span many sub-step counts


def test_projection_keeps_positive_semi_definite_damping_exactly():
    rng = np.random.default_rng(2)
    _, C = _film(rng, 3)
    C[2] = 0.0                              # an unconnected station
    out = np.empty_like(C)
    assert ij_kernel._project(C, out) and np.array_equal(out, C)


def test_undecidable_steps_are_left_to_the_numpy_form(monkeypatch):
    """A sub-step count H rho / 2 at an integer (to round-off), a damping eigenvalue at 0 and a
    need above LSTABLE_SWITCH: the kernel returns FALLBACK and rotor.step gives exactly the
    numpy form's result."""
    rng = np.random.default_rng(9)
    K, C = _film(rng, 2)
    F = rng.normal(scale=30.0, size=(2, 2))
    r = _jeffcott()
    MiK, MiC, _ = interface.augmented(r, F, K, C)
    rho = max(np.linalg.norm(MiC, 2), math.sqrt(np.linalg.norm(MiK, 2)))
    C_edge = C.copy()
    C_edge[1] = [[2.0e4, 1.0e4], [1.0e4, 0.5e4]]          # symmetric part singular: eigenvalue 0
    cases = [(2.0 * (7.0 + 1e-12) / rho, K, C),            # need = 7 + 1e-12: ceil could be 7 or 8
             (H, K, C_edge),
             (H, K, C * (2.0 * interface.LSTABLE_SWITCH * 3.0 / (H * rho)))]
    for dt, Ki, Ci in cases:
        a, b = _jeffcott(), _jeffcott()
        assert not interface._fast_step(a, dt, F, Ki, Ci)
        a.step(dt, F, Ki, Ci)
        monkeypatch.setattr(interface, "FAST", False)
        b.step(dt, F, Ki, Ci)
        monkeypatch.setattr(interface, "FAST", True)
        assert np.array_equal(a.s, b.s) and a.t == b.t


def test_bad_coefficients_raise_as_before():
    r = _jeffcott()
    K, C = _film(np.random.default_rng(1), 2)
    Kn = K.copy()
    Kn[0, 0, 1] = np.nan
    with pytest.raises(ValueError, match="interface Jacobian K must be finite"):
        r.step(H, np.zeros((2, 2)), Kn, C)
    with pytest.raises(ValueError, match="F must be finite"):
        r.step(H, np.array([[np.inf, 0.0], [0.0, 0.0]]), K, C)
    with pytest.raises(ValueError, match="expected shape"):
        r.step(H, np.zeros((2, 2)), K[:1], C)
    z = np.zeros((2, 2, 2))
    a, b = _jeffcott(), _jeffcott()
    a.step(H, np.ones((2, 2)), z, z)                      # K = C = 0: the plain step
    b.step(H, np.ones((2, 2)))
    assert np.array_equal(a.s, b.s)


def test_speed_table_breakpoint_inside_a_step():
    """The unbalance forcing at the sub-step ends when the speed table bends within the step
    (the table evaluated at each time, not the one-segment polynomial)."""
    table = {"t": [0.0, 0.40005, 1.0], "f": [150.0, 160.0, 400.0]}
    rng = np.random.default_rng(4)
    K, C = _film(rng, 2, c=(3e4, 1e5))
    F = rng.normal(scale=30.0, size=(2, 2))
    a, b = _both(lambda: _jeffcott(speed_table=table), rng, K, C, F, steps=2)
    assert _rel(a, b) < 1e-12


def test_closed_loop_on_a_linear_film_agrees_to_round_off():
    """Gauss-Seidel-like loop (the film force and coefficients at the start of each step) over
    300 macro steps: the compiled and numpy forms stay together to round-off."""
    Kf = np.array([[2e7, 8e6], [-1.2e7, 2.6e7]])
    Cf = np.array([[6e4, 6e3], [6e3, 7e4]])
    K, C = np.array([Kf, Kf]), np.array([Cf, Cf])
    runs = []
    for fast in (True, False):
        interface_fast, interface.FAST = interface.FAST, fast
        try:
            r = _jeffcott()
            for _ in range(300):
                o = r.outputs
                F = np.array([-Kf @ [o[f"x_{i}"], o[f"y_{i}"]] - Cf @ [o[f"vx_{i}"], o[f"vy_{i}"]] for i in (1, 2)])
                r.step(H, F, K, C)
        finally:
            interface.FAST = interface_fast
        runs.append(r)
    assert _rel(*runs) < 1e-12


def test_fast_real_access_of_the_rotor_slave():
    """fast_get_real / fast_set_real (fmu_common/slave.py), the rotor FMU's get_real and
    set_real, against PythonFMU's own methods: same values, TypeError for non-Real references."""
    from pythonfmu import Fmi2Slave
    from rotor_fmu.jeffcott_rotor import JeffcottRotor
    s = JeffcottRotor(instance_name="r")
    vr = {v.name: k for k, v in s.vars.items()}
    ins = [vr[n] for n in ("Fx_1", "kxy_2", "cyy_1", "m_disc")]
    s.set_real(ins, [1.5, -2.0, 3.0, 5.0])
    assert [s._values[n] for n in ("Fx_1", "kxy_2", "cyy_1", "m_disc")] == [1.5, -2.0, 3.0, 5.0]
    outs = [vr[n] for n in ("x_1", "omega", "Fx_1", "m_disc")]
    assert s.get_real(outs) == Fmi2Slave.get_real(s, outs)
    for bad in ([vr["initial_sag"]], [10 ** 6]):
        with pytest.raises(TypeError, match="is not of type Real"):
            s.get_real(bad)
        with pytest.raises(TypeError, match="is not of type Real"):
            s.set_real(bad, [1.0])
