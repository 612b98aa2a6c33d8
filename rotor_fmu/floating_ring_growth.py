"""Growth rate of a rotor's whirl in floating-ring bearings at CONSTANT speed, three ways
(docs/floating-ring.md, "Why the run-ups did not whirl"); CLI: docs/scripts/floating_ring_growth.py.

* linear: the eigenvalue of :mod:`rotor_fmu.floating_ring_stability` (HS films, ring spin held);
* :meth:`Case.mono`: the nonlinear monolithic model, rotor + rings (2 translation DOFs each) as
  ONE ODE with the films' quasi-static half-Sommerfeld forces
  (:func:`bearing_fmu.linearize.hs_force`), ring spin held at the torque-balance value,
  scipy's Radau (rtol 1e-8, the linear system matrix as its Jacobian) -- no co-simulation;
* :meth:`Case.cosim`: the co-simulation as the master runs it (Gauss-Seidel rotor -> bearings,
  the rotor's interface-Jacobian step with the bearing's coefficients, the
  :class:`~bearing_fmu.floating_ring.FloatingRing` model the FMU wraps bit-identically),
  macro step H.

Both time-domain runs start at the static equilibrium plus the least-damped eigenvector's real
part (journal amplitude ``amp`` x c_i), no unbalance. Growth rates and frequencies are read
from the journal and ring displacements by the matrix-pencil method (Hua & Sarkar 1990, IEEE
Trans. ASSP 38(5) 814-824), poles ordered by energy, which separates the outer-film whirl
(~100 Hz) from the inner one (~540 Hz) and from the harmonics of the nonlinear film.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from bearing_fmu.floating_ring import FloatingRing, RingParams
from bearing_fmu.linearize import hs_force
from bearing_fmu.model import BearingParams

from .floating_ring_stability import _augmented, ring_system_eigen
from .jeffcott import JeffcottModel, JeffcottParams
from .ring_interface import step_with_ring_interface

__all__ = ["Case", "pencil", "jeffcott_floating_ring", "turbocharger_floating_ring", "slaved_coefficients",
           "sliding_growth", "zero_crossing", "runup_cosim"]


def jeffcott_floating_ring(cavitation=0, n=40, **rotor_kw):
    """The Jeffcott rotor of scenarios/jeffcott_runup_floating_ring_half_sommerfeld.yaml and its
    two (identical) rings: (JeffcottModel, [RingParams, RingParams])."""
    kw = dict(m_disc=5.0, m_journal=0.5, d_external=500.0)
    kw.update(rotor_kw)
    rotor = JeffcottModel(JeffcottParams(**kw))
    inner = BearingParams(R=4.9e-3, B=7.84e-3, psi=2.8e-3, eta0=0.012, n_phi=n, n_z=n, cavitation=cavitation)
    outer = BearingParams(R=7.84e-3, B=7.84e-3, psi=3.5e-3, eta0=0.012, n_phi=n, n_z=n, cavitation=cavitation)
    ring = RingParams(inner=inner, outer=outer, m_ring=7.3e-3, J_ring=3.1e-7)
    return rotor, [ring, ring]


def pencil(y, dt, M=12):
    """Matrix pencil: poles s_k [1/s] of the multichannel signal y (channels x samples) and
    their energies (sum over channels of |amplitude|^2 times sum_t |z^t|^2), largest first."""
    y = np.atleast_2d(y)
    L = y.shape[1] // 3
    Y = np.vstack([np.array([yc[i:i + L + 1] for i in range(y.shape[1] - L)]) for yc in y])
    V = np.linalg.svd(Y, full_matrices=False)[2][:M].conj().T
    z = np.linalg.eigvals(np.linalg.pinv(V[:-1]) @ V[1:]).astype(complex)
    Zv = z[None, :] ** np.arange(y.shape[1])[:, None]            # Vandermonde (samples x M)
    amp = np.linalg.lstsq(Zv, y.T.astype(complex), rcond=None)[0]  # (M x channels)
    energy = np.sum(np.abs(amp) ** 2, axis=1) * np.sum(np.abs(Zv) ** 2, axis=0)
    k = np.argsort(-energy)
    return np.log(z[k]) / dt, energy[k] / energy[k[0]]


def turbocharger_floating_ring(cavitation=0, n=40, **rotor_kw):
    """The turbocharger rotor (rotor_fmu/data/turbocharger.yaml) in two floating rings, the
    inner film the plain bearing of scenarios/turbocharger_runup_half_sommerfeld.yaml, the ring
    that of the Jeffcott case: (TurbochargerRotor, [RingParams, RingParams])."""
    from .turbocharger import TurbochargerParams, TurbochargerRotor
    rotor = TurbochargerRotor(TurbochargerParams(**rotor_kw))
    return rotor, jeffcott_floating_ring(cavitation, n)[1]


def slaved_coefficients(fr):
    """Inner-film (K, C) with the ring velocity slaved to the journal's, ``K_i (I - S)``,
    ``C_i (I - S)``, ``S = (C_i + C_o)^-1 C_i`` (the first-order response when the ring follows
    within ~m_r / C; measured in docs/floating-ring.md, not used by the FMU)."""
    c = fr.film_coefficients()
    S = np.linalg.solve(c["Ci"] + c["Co"], c["Ci"])
    return c["Ki"] @ (np.eye(2) - S), c["Ci"] @ (np.eye(2) - S)


def ring_inputs(frs) -> dict:
    """What :func:`rotor_fmu.ring_interface.step_with_ring_interface` needs of each ring, read
    from the :class:`FloatingRing` models as the FMU outputs them."""
    out = {"m": [], "s": [], "a": [], "Ko": [], "Co": []}
    for fr in frs:
        o = fr.outputs
        out["m"].append(fr.params.m_ring)
        out["s"].append([o["x_ring"], o["y_ring"], o["vx_ring"], o["vy_ring"]])
        out["a"].append([o["ax_ring"], o["ay_ring"]])
        out["Ko"].append([[o[f"k{a}{b}_outer"] for b in "xy"] for a in "xy"])
        out["Co"].append([[o[f"c{a}{b}_outer"] for b in "xy"] for a in "xy"])
    return {k: np.array(v) for k, v in out.items()}


class Case:
    """The Jeffcott rotor in two floating rings at CONSTANT journal speed f [Hz], no unbalance:
    linear system, static equilibrium and the seeded initial state (module doc)."""

    def __init__(self, f, amp=1e-3, rotor=None, rings=None):
        """``rotor``, ``rings``: any LinearRotor at constant speed f and its RingParams (one per
        bearing station; its unbalances are removed here); default the Jeffcott case."""
        self.w = w = 2 * math.pi * f
        if rotor is None:
            rotor, rings = jeffcott_floating_ring(unbalance=0.0, f_max=f, t_ramp=0.0)
        else:
            rotor.unbalances = []
            rotor._precompute()
        self.rotor, self.rings = rotor, rings
        _, self.pts = ring_system_eigen(self.rotor, self.rings, w)
        M, C, K = _augmented(self.rotor, w, self.pts)
        self.N, self.n = N, n = M.shape[0], self.rotor.n_dof
        Mi = np.linalg.inv(M)
        self.A = A = np.block([[np.zeros((N, N)), np.eye(N)], [-Mi @ K, -Mi @ C]])
        self.Om = [p._Om for p in self.pts]
        self.bd = self.rotor.bearing_dofs
        z = np.zeros(2 * N)
        for k, p in enumerate(self.pts):
            z[self.bd[k]] = p._journal[:2]
            z[[n + 2 * k, n + 2 * k + 1]] = p._ring[:2]
        for _ in range(30):                         # Newton on the positions, rotor included
            dq = np.linalg.solve(A[N:, :N], -self.rhs(0.0, z)[N:])
            z[:N] += dq
            if np.linalg.norm(dq) < 1e-15:
                break
        self.z_eq = z
        lam, V = np.linalg.eig(A)
        k = int(np.argmax(lam.real))
        self.lam = lam[k]
        v = V[:, k].real
        self.z0 = z + v / np.max(np.abs(v[self.bd.ravel()])) * amp * self.rings[0].inner.c

    def rhs(self, t, z):
        N, n, bd = self.N, self.n, self.bd
        q, v = z[:N], z[N:]
        nb = len(self.pts)
        Fj, acc = np.zeros((nb, 2)), np.zeros(2 * nb)
        for k, p in enumerate(self.pts):
            j, r = bd[k], [n + 2 * k, n + 2 * k + 1]
            Fi = hs_force(p.inner, *(q[j] - q[r]), *(v[j] - v[r]), self.w + self.Om[k])
            Fo = hs_force(p.outer, *q[r], *v[r], self.Om[k])
            Fj[k] = Fi
            acc[2 * k:2 * k + 2] = (-Fi + Fo - [0.0, p.params.m_ring * p.params.gravity]) / p.params.m_ring
        ds = self.rotor.rhs(t, np.concatenate([q[:n], v[:n]]), Fj)
        return np.concatenate([v, ds[n:], acc])

    def mono(self, T, dt_out=2e-4):
        """Monolithic nonlinear run over [0, T] [s]: (t, Z) with Z the state (2N x samples)."""
        sol = solve_ivp(self.rhs, (0.0, T), self.z0, method="Radau", jac=lambda t, z: self.A,
                        rtol=1e-8, atol=1e-13, dense_output=True, max_step=2e-4)
        if sol.status != 0:
            raise RuntimeError(sol.message)
        t = np.arange(0.0, T, dt_out)
        return t, sol.sol(t)

    def cosim(self, T, H, J_ring=1e3, coeffs=0.0, dt_out=2e-4, n_sub=1, input_hold=None, ring_coupling=False,
              ring_integrator=None):
        """Co-simulation as the master runs it (module doc), macro step H [s]: (t, Z).
        ``coeffs`` >= 0: ``FloatingRing.linearization(coeffs)`` (0: the FMU's K_i, C_i);
        < 0: :func:`slaved_coefficients`. ``n_sub`` ring sub-steps per macro step; ``input_hold``,
        ``ring_integrator`` as RingParams (None: the rings' own, i.e. the defaults)."""
        N, n, bd, z0 = self.N, self.n, self.bd, self.z0
        rotor = self.rotor
        rotor.initialize()
        rotor.s = np.concatenate([z0[:n], z0[N:N + n]])
        frs = []
        for k, p in enumerate(self.pts):
            kw = {k_: v_ for k_, v_ in (("input_hold", input_hold), ("ring_integrator", ring_integrator))
                  if v_ is not None}
            fr = FloatingRing(self.rings[k].replace(h_ring=H / n_sub, J_ring=J_ring, **kw))
            r = [n + 2 * k, n + 2 * k + 1]
            fr.initialize(*z0[bd[k]], *z0[N + bd[k]], self.w, ring=(*z0[r], *z0[N + np.array(r)]),
                          omega_ring=self.Om[k])
            frs.append(fr)
        every = max(1, int(round(dt_out / H)))
        out = []
        for i in range(int(round(T / H))):
            F = np.array([[fr.outputs["Fx"], fr.outputs["Fy"]] for fr in frs])
            KC = [fr.linearization(coeffs) if coeffs >= 0 else slaved_coefficients(fr) for fr in frs]
            if ring_coupling:       # the rings' translation in the rotor's implicit step
                step_with_ring_interface(rotor, H, F, np.array([a for a, _ in KC]),
                                         np.array([b for _, b in KC]), ring_inputs(frs))
            else:
                rotor.step(H, F, np.array([a for a, _ in KC]), np.array([b for _, b in KC]))
            kin = rotor.journal_kinematics(rotor.t, rotor.s)
            for k, fr in enumerate(frs):
                fr.step(H, *kin[k], self.w)
            if (i + 1) % every == 0:
                out.append(np.concatenate([rotor.s[:n], *[fr._ring[:2] for fr in frs],
                                           rotor.s[n:], *[fr._ring[2:] for fr in frs]]))
                if not np.all(np.isfinite(out[-1])):
                    raise FloatingPointError(f"cosim: state not finite at step {i + 1}")
        return H * every * np.arange(1, len(out) + 1), np.array(out).T

    def rates(self, t, Z):
        """Poles (growth rate [1/s], frequency [Hz], relative energy) with positive frequency,
        most energetic first, from the journal and ring displacements."""
        ch = list(self.bd.ravel()) + list(range(self.n, self.N))
        s, e = pencil((Z - self.z_eq[:, None])[ch], t[1] - t[0])
        keep = s.imag > 1.0
        return [(float(x.real), float(x.imag / (2 * math.pi)), float(en)) for x, en in zip(s[keep], e[keep])]


def sliding_growth(t, Y, band_hz, window=0.025, hop=0.005, M=10):
    """Growth rate of the most energetic pole with frequency in ``band_hz`` in sliding windows of
    the signals Y (channels x samples, sampled at t [s], equidistant): (window mid-times [s],
    growth rates [1/s], frequencies [Hz]). Each window is detrended (linear fit per channel):
    the run-up's slowly moving equilibrium. ``M`` poles per window: enough for the 1x, both
    whirls and a residual pair; more let the pencil split a mode whose rate changes within the
    window into several poles (tests/test_floating_ring_growth.py: 4.5 1/s off at M = 16,
    0.01 1/s at M = 10 for a rate rising 0.5 1/s over the window)."""
    dt = float(t[1] - t[0])
    nw, nh = int(round(window / dt)), max(1, int(round(hop / dt)))
    mids, sig, frq = [], [], []
    x = np.arange(nw)
    for i0 in range(0, Y.shape[1] - nw + 1, nh):
        seg = Y[:, i0:i0 + nw]
        coef = np.polyfit(x, seg.T, 1)
        s, _ = pencil(seg - (np.outer(coef[0], x) + coef[1][:, None]), dt, M=M)
        f = s.imag / (2 * math.pi)
        k = np.flatnonzero((f >= band_hz[0]) & (f <= band_hz[1]))
        if k.size:
            mids.append(float(t[i0 + nw // 2]))
            sig.append(float(s[k[0]].real))
            frq.append(float(f[k[0]]))
    return np.array(mids), np.array(sig), np.array(frq)


def zero_crossing(speed_hz, sigma, lo, hi):
    """Speed [Hz] where a straight line fitted (least squares) to sigma(speed) over [lo, hi]
    crosses zero, and the line's slope [1/s per Hz]."""
    m = (speed_hz >= lo) & (speed_hz <= hi)
    a, b = np.polyfit(speed_hz[m], sigma[m], 1)
    return float(-b / a), float(a)


def runup_cosim(H, t0, t1, *, journal0, omega_ring0, f_max=900.0, t_ramp=2.25, dt_out=1e-4):
    """The seeded run-up of scenarios/jeffcott_runup_floating_ring_half_sommerfeld_seeded.yaml
    as the master runs it (Gauss-Seidel rotor -> bearings, the rotor's interface-Jacobian step
    with the FMU's coefficients K_i, C_i, the FloatingRing model the FMU wraps bit-identically,
    the same initialisation), without the FMI layer: t [s] and the rows (omega, x_1, y_1,
    x_ring1, y_ring1) every ``dt_out``. ``journal0`` (x, y) [m] both journals, ``omega_ring0``
    [rad/s] both rings (ring positions at their equilibrium)."""
    rotor, rings = jeffcott_floating_ring(f_max=f_max, t_ramp=t_ramp, t0=t0, journal_x0=journal0[0],
                                          journal_y0=journal0[1])
    rotor.initialize()
    kin = rotor.journal_kinematics(rotor.t, rotor.s)
    w = float(rotor.drive.omega(rotor.t))
    frs = []
    for k, p in enumerate(rings):
        fr = FloatingRing(p.replace(h_ring=max(H, 1e-4)))
        fr.initialize(*kin[k], w, ring="equilibrium", omega_ring=omega_ring0)
        frs.append(fr)
    every = max(1, int(round(dt_out / H)))
    rows = []
    for i in range(int(round((t1 - t0) / H))):
        F = np.array([[fr.outputs["Fx"], fr.outputs["Fy"]] for fr in frs])
        KC = [fr.linearization() for fr in frs]
        rotor.step(H, F, np.array([a for a, _ in KC]), np.array([b for _, b in KC]))
        kin = rotor.journal_kinematics(rotor.t, rotor.s)
        w = float(rotor.drive.omega(rotor.t))
        for k, fr in enumerate(frs):
            fr.step(H, *kin[k], w)
        if (i + 1) % every == 0:
            rows.append((w, kin[0][0], kin[0][1], frs[0]._ring[0], frs[0]._ring[1]))
    return t0 + H * every * np.arange(1, len(rows) + 1), np.array(rows).T
