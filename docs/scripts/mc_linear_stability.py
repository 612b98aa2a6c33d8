"""Linear threshold of the mass-conserving film with its theta dynamics (film impedance),
docs/analysis.md "Linear threshold of the mass-conserving film (film impedance)".

    S=scenarios/jeffcott_runup_oil_bath.yaml A=scenarios/jeffcott_runup_free_to_air.yaml
    PY=".venv/bin/python docs/scripts/mc_linear_stability.py"
    T1="fmus.bearing1.parameters.theta_transport=1 fmus.bearing2.parameters.theta_transport=1"
    G80="fmus.bearing1.parameters.n_phi=80 fmus.bearing1.parameters.n_z=80 \
         fmus.bearing2.parameters.n_phi=80 fmus.bearing2.parameters.n_z=80"
    $PY checks $S 200; $PY checks $A 300         # checks (a), (b), the film's own poles
    $PY timedomain $S 200 1e-3 200               # check (c): delta = 1e-3 c, 200 steps per period
    $PY timedomain $S 200 1e-4 400               # (and $A 300 with both)
    $PY threshold $S 100:300:25                  # 182.45 Hz (scan, then Brent)
    $PY threshold $A 150:500:25                  # 234.12 Hz
    $PY threshold $A 150:500:25 $T1              # 232.91 Hz
    $PY track $S 160 200 -10 520 $G80            # 80 x 80, sparse: 178.17 Hz
    $PY track $S 165 190 -5 520 $G160            # 160 x 160 (G160 as G80 with 160): 176.27 Hz
    $PY track $A 210 260 -15 680 $G80            # 233.60 Hz
    T0="fmus.bearing1.parameters.theta_transport=0 fmus.bearing2.parameters.theta_transport=0"
    $PY track $S 160 200 -10 520 $T0             # oil bath, first-order transport: 185.68 Hz
    $PY track $S 160 200 -10 520 $T0 $G80        # 181.08 Hz

Each bearing station: the static equilibrium q0 of its journal under the rotor's gravity load
with the steady mass-conserving film (Newton on q with K = Z(0)), the linearised film there
(bearing_fmu.linearize.MCFilmLinear) and its impedance Z(s). The rotor's characteristic
equation det(s^2 M + s C + K + sum_j P_j^T Z_j(s) P_j) = 0 is solved as the finite
eigenvalues of the descriptor system of rotor and linearised films (rotor q, q'; each film u;
E x' = A x), dense: all roots at once, so the least damped one cannot be missed (a secant
from the half-Sommerfeld roots, tried first, converged to a well damped root at 200 Hz while
an unstable one existed). The root at the threshold is then refined as a root of the
determinant equation with Z(s) itself (secant on lambda(s) - s, lambda(s) the eigenvalue
nearest s of the quadratic problem with Z frozen at s) and its smallest singular value
reported: the two formulations are the same equation.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np
import scipy.linalg as sl
from scipy.optimize import brentq

from bearing_fmu.linearize import MCFilmLinear, _force, mc_static_equilibrium
from bearing_fmu.model import BearingModel
from orchestrator.scenario import load_scenario
from orchestrator.stability import _HSFilm, build_system
from rotor_fmu.stability import film_system_eigenvalues, short_bearing_equilibrium, static_bearing_loads


class Station:
    """A mass-conserving bearing at the static equilibrium of its journal under ``load``."""

    def __init__(self, params, load):
        self.b = BearingModel(params)
        self.load = np.asarray(load, float)
        self.q = None

    def equilibrium(self, omega):
        """The journal's static equilibrium with the steady film and the film's linearisation
        there (bearing_fmu.linearize.mc_static_equilibrium, from the last speed's position)."""
        b, c = self.b, self.b.c
        q = self.q
        if q is None:
            p = b.params
            eps, psi = short_bearing_equilibrium(self.load, omega, R=p.R, L=p.B, C=c, eta=p.eta0)
            q = min(eps, 0.8) * c * np.array([math.cos(psi), math.sin(psi)])
        self.q, self.lin = mc_static_equilibrium(b, -self.load, omega, guess=q)
        return self.q


class System:
    def __init__(self, scenario, sets=()):
        self.system = build_system(load_scenario(scenario, list(sets), build_fmus=True))
        self.rotor = self.system.rotor
        self.loads = static_bearing_loads(self.rotor)
        self.st = [Station(b.params, ld) for b, ld in zip(self.system.bearings, self.loads)]
        self.hs = _HSFilm(self.system, self.loads)

    def setup(self, omega):
        for s in self.st:
            s.equilibrium(omega)
        self.M, self.C, self.K = self.rotor.system_matrices(omega)
        self.omega = omega

    def _P(self, ix, iy):
        P = np.zeros((2, self.M.shape[0]))
        P[0, ix] = P[1, iy] = 1.0
        return P

    def quad_eigs(self, K, C):
        n = self.M.shape[0]
        Mi = np.linalg.inv(self.M)
        return np.linalg.eigvals(np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ K, -Mi @ C]]))

    def coefficient_eigs(self, KC):
        """Eigenvalues with 2x2 (K, C) per station (HS or quasi-steady)."""
        K, C = self.K.copy(), self.C.copy()
        for (k, c), (ix, iy) in zip(KC, self.rotor.bearing_dofs):
            P = self._P(ix, iy)
            K += P.T @ k @ P
            C += P.T @ c @ P
        return self.quad_eigs(K, C)

    def DZ(self, s):
        K = self.K.astype(complex)
        for st, (ix, iy) in zip(self.st, self.rotor.bearing_dofs):
            P = self._P(ix, iy)
            K = K + P.T @ st.lin.impedance(s) @ P
        return K

    def det_root(self, s0, tol=1e-10, maxit=60):
        def g(s):
            lam = self.quad_eigs(self.DZ(s), self.C.astype(complex))
            return lam[np.argmin(np.abs(lam - s))] - s
        s_a = complex(s0)
        g_a = g(s_a)
        s_b = s_a + g_a
        for it in range(maxit):
            g_b = g(s_b)
            if abs(g_b) <= tol * abs(s_b) or g_b == g_a:
                return s_b, it
            s_a, g_a, s_b = s_b, g_b, s_b - g_b * (s_b - s_a) / (g_b - g_a)
        return s_b, -1

    def sv_ratio(self, s):
        sv = np.linalg.svd(s * s * self.M + s * self.C + self.DZ(s), compute_uv=False)
        return sv[-1] / sv[0]

    def descriptor(self):
        """Finite eigenvalues of E x' = A x, x = (q, q', u_1, u_2, ...) (largest Re first):
        rotor_fmu.stability.film_system_eigenvalues."""
        return film_system_eigenvalues(self.rotor, self.omega, [st.lin for st in self.st])

    def descriptor_near(self, sigma, k=8):
        """The k eigenvalues of the same descriptor system nearest ``sigma`` (sparse
        shift-invert Arnoldi; for grids where the dense problem is too large)."""
        import scipy.sparse as sp
        import scipy.sparse.linalg as spla
        M, C, K = self.M, self.C, self.K
        n = M.shape[0]
        I = sp.identity(n)
        rows_A = [[None, I], [sp.csr_matrix(-K), sp.csr_matrix(-C)]]
        rows_E = [[I, None], [None, sp.csr_matrix(M)]]
        nf = len(self.st)
        top_A = [[rows_A[0][0], rows_A[0][1]] + [None] * nf, [rows_A[1][0], rows_A[1][1]] + [None] * nf]
        top_E = [[rows_E[0][0], None] + [None] * nf, [None, rows_E[1][1]] + [None] * nf]
        film_A, film_E = [], []
        for j, (st, (ix, iy)) in enumerate(zip(self.st, self.rotor.bearing_dofs)):
            L, P = st.lin, self._P(ix, iy)
            top_A[1][2 + j] = sp.csr_matrix(P.T @ L.Fu)
            top_A[1][0] = top_A[1][0] + sp.csr_matrix(P.T @ L.Fq @ P)
            top_A[1][1] = top_A[1][1] + sp.csr_matrix(P.T @ L.Fv @ P)
            ra = [sp.csr_matrix(-L.Rq @ P), sp.csr_matrix(-L.Rv @ P)] + [None] * nf
            ra[2 + j] = -L.Js
            re = [None, None] + [None] * nf
            re[2 + j] = sp.diags(L.Mdiag)
            film_A.append(ra)
            film_E.append(re)
        A = sp.bmat(top_A + film_A, format="csc")
        E = sp.bmat(top_E + film_E, format="csc")
        lu = spla.splu((A - sigma * E).astype(complex).tocsc())
        op = spla.LinearOperator(A.shape, matvec=lambda x: lu.solve((E @ x).astype(complex)), dtype=complex)
        mu = spla.eigs(op, k=k, which="LM", return_eigenvectors=False)
        lam = sigma + 1.0 / mu
        return lam[np.argsort(-lam.real)]


def threshold(scenario, rng, sets):
    lo, hi, step = (float(a) for a in rng.split(":"))
    S = System(scenario, sets)
    t0 = time.time()
    memo = {}

    def top(f):
        w = 2 * math.pi * f
        S.setup(w)
        lam = S.descriptor()
        lam = lam[lam.imag >= 0]
        hs = S.coefficient_eigs(list(zip(*S.hs(w))))
        qs = S.coefficient_eigs([st.lin.quasi_steady() for st in S.st])
        eps = float(np.hypot(*S.st[0].q) / S.st[0].b.c)
        memo[f] = (lam[0], eps)
        print(f"  {f:8.3f} Hz  eps {eps:.4f}  film impedance: max Re {lam[0].real:+9.3f} 1/s, whirl "
              f"{lam[0].imag / w:.4f} | HS coefficients {hs.real.max():+9.3f} | quasi-steady MC "
              f"coefficients {qs.real.max():+9.3f}  ({time.time() - t0:.0f} s)", flush=True)
        return lam[0].real

    prev = None
    for f in np.arange(lo, hi + 1e-9, step):
        if top(f) >= 0:
            if prev is None:
                print(f"already unstable at {lo} Hz")
                return
            ft = brentq(top, prev, f, xtol=0.01)
            s, eps = memo[ft]
            S.setup(2 * math.pi * ft)
            r, it = S.det_root(s)
            print(f"THRESHOLD {ft:.2f} Hz, whirl {s.imag / (2 * math.pi):.2f} Hz (ratio "
                  f"{s.imag / (2 * math.pi * ft):.4f}), eps {eps:.4f}; root of det with Z(s) from "
                  f"the descriptor root: {r:.4f} (|change| {abs(r - s):.1e}, smallest/largest singular "
                  f"value {S.sv_ratio(r):.1e})")
            return
        prev = f
    print(f"stable up to {hi} Hz")


def track(scenario, f_lo, f_hi, sigma, sets):
    """Threshold in [f_lo, f_hi] (stable at f_lo, unstable at f_hi) with the sparse eigenvalues
    nearest the last root (start: ``sigma`` at f_lo, e.g. the 40 x 40 root); for fine grids."""
    S = System(scenario, sets)
    last = {"s": sigma, "f": f_lo}

    def top(f):
        w = 2 * math.pi * f
        S.setup(w)
        sg = complex(last["s"].real, last["s"].imag * f / last["f"])
        lam = S.descriptor_near(sg)
        lam = lam[lam.imag > 0]
        s = lam[0]
        last["s"], last["f"] = s, f
        eps = float(np.hypot(*S.st[0].q) / S.st[0].b.c)
        print(f"  {f:8.3f} Hz  eps {eps:.4f}  max Re near {sg:.1f}: {s.real:+9.3f} 1/s, whirl {s.imag / w:.4f}; "
              f"next {lam[1]:.1f}", flush=True)
        return s.real

    if top(f_lo) >= 0 or top(f_hi) < 0:
        print("no bracket")
        return
    ft = brentq(top, f_lo, f_hi, xtol=0.01)
    s = last["s"]
    print(f"THRESHOLD {ft:.2f} Hz, whirl ratio {s.imag / (2 * math.pi * ft):.4f}")


def checks(scenario, f):
    S = System(scenario)
    w = 2 * math.pi * f
    st = S.st[0]
    q = st.equilibrium(w)
    L = st.lin
    b = st.b
    print(f"{scenario} {f} Hz: q0/c = {q / b.c}, eps {np.hypot(*q) / b.c:.4f}, force {L.F0} N, "
          f"load {st.load} N; polishing step {L.polish_step:.1e}, steady residual {np.abs(L.r0).max():.1e}")
    K0, C0 = L.quasi_steady()
    Z0 = L.impedance(0.0)

    def fz(z):
        kin = b._kinematics(z[0], z[1], z[2], z[3], w)
        u, _ = b._steady_newton(kin, L.u, np.zeros_like(L.u), 40)
        p, th = b.law.p_theta(u)
        return np.asarray(_force(b, p, th, kin))

    print("Z(0) [N/m]:\n", Z0.real)
    for rel in (1e-3, 1e-4):
        c = b.c
        steps = [rel * c, rel * c, rel * c * w, rel * c * w]
        D = np.empty((2, 4))
        for j in range(4):
            zp = [q[0], q[1], 0.0, 0.0]
            zm = list(zp)
            zp[j] += steps[j]
            zm[j] -= steps[j]
            D[:, j] = -(fz(zp) - fz(zm)) / (2 * steps[j])
        print(f"(a) steady solves, central differences rel {rel:g}: K_fd - Z(0) max rel "
              f"{np.abs(D[:, :2] - Z0.real).max() / np.abs(Z0).max():.1e}; C_fd (steady squeeze) - C_qs max rel "
              f"{np.abs(D[:, 2:] - C0).max() / np.abs(C0).max():.1e}")
    print("quasi-steady damping C_qs [N s/m]:\n", C0)
    dZ = L.slope0()
    print("dZ/ds(0) [N s/m] = C_qs - F_u J_s^-1 M J_s^-1 R_q:\n", dZ)
    for h in (1e-2 * w, 1e-3 * w):
        fd = (L.impedance(h) - L.impedance(-h)) / (2 * h)
        print(f"(b) central difference of Z in s, h = {h / w:g} omega: max rel diff to dZ/ds(0) "
              f"{np.abs(fd - dZ).max() / np.abs(dZ).max():.1e}")
    print(f"(b) dZ/ds(0) - C_qs, max rel to C_qs: {np.abs(dZ - C0).max() / np.abs(C0).max():.2f}")
    for r in (0.1, 0.45, 1.0):
        print(f"Z(i {r} omega) [N/m]:\n", L.impedance(1j * r * w))
    print("film poles (journal held), largest Re [1/s]:", np.round(L.poles()[:7], 1))


def td_column(params, q0, omega, nu, delta, direction, u0, n_per, settle=0.02, n_meas=2):
    """Column ``direction`` of Z(i nu) from the transient film: x_d = q0_d +- delta sin(nu t)
    (both signs; their half difference cancels the even orders in delta and the base film's
    drift), the kinematics held over each step at their value at the step's midpoint, the
    force after the step attributed to that midpoint (the full film's response is
    instantaneous; at the step's end it lags by dt / 2), Fourier at nu over n_meas whole
    periods after ``settle`` seconds."""
    T = 2 * math.pi / nu
    dt = T / n_per
    n_settle = int(math.ceil(settle / T))
    n_tot = (n_settle + n_meas) * n_per
    F = []
    for sg in (1.0, -1.0):
        b = BearingModel(params)
        b.initialize(q0[0], q0[1], 0.0, 0.0, omega)
        b.film.init_state(u0.copy())
        Fs = np.empty((n_tot, 2))
        for k in range(n_tot):
            tm = (k + 0.5) * dt
            z = [q0[0], q0[1], 0.0, 0.0]
            z[direction] += sg * delta * math.sin(nu * tm)
            z[direction + 2] = sg * delta * nu * math.cos(nu * tm)
            b.step(dt, *z, omega)
            Fs[k] = b.outputs["Fx"], b.outputs["Fy"]
        F.append(Fs)
    tm = (np.arange(n_tot) + 0.5) * dt
    dF = (F[0] - F[1]) / 2.0
    m = slice(n_settle * n_per, n_tot)
    c = 2.0 / (n_meas * n_per) * (dF[m] * np.exp(-1j * nu * tm[m])[:, None]).sum(axis=0)
    return c / (1j * delta)      # x = Im(delta e^{i nu t}) = -i delta e^{i nu t}/..., F = -Z x


def timedomain(scenario, f, rel_delta, n_per, theta_atol=1e-5):
    S = System(scenario)
    w = 2 * math.pi * f
    q0 = S.st[0].equilibrium(w)
    prm = S.system.bearings[0].params.replace(theta_atol=theta_atol, newton_atol=1e-7, newton_rtol=1e-8)
    b = BearingModel(prm)
    b.initialize(q0[0], q0[1], 0.0, 0.0, w, init="stationary")
    L = MCFilmLinear(b)
    print(f"(c) {scenario} {f} Hz, eps {np.hypot(*q0) / b.c:.4f}: delta {rel_delta:g} c, {n_per} steps per "
          f"period, theta_atol {theta_atol:g}")
    for r in (0.1, 0.45, 1.0):
        nu = r * w
        Zl = L.impedance(1j * nu)
        for d in (0, 1):
            col = td_column(prm, q0, w, nu, rel_delta * b.c, d, L.u, n_per)
            err = np.abs(col - Zl[:, d]).max() / np.abs(Zl[:, d]).max()
            print(f"  nu {r:.2f} omega, {'xy'[d]}: time domain {col[0]:.4e} {col[1]:.4e}; Z(i nu) "
                  f"{Zl[0, d]:.4e} {Zl[1, d]:.4e}; max rel diff {err:.2e}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    cmd, scen = sys.argv[1], sys.argv[2]
    if cmd == "threshold":
        threshold(scen, sys.argv[3], sys.argv[4:])
    elif cmd == "track":      # track SCEN F_LO F_HI SIGMA_RE SIGMA_IM [sets]: sparse, near the last root
        track(scen, float(sys.argv[3]), float(sys.argv[4]), complex(float(sys.argv[5]), float(sys.argv[6])),
              sys.argv[7:])
    elif cmd == "checks":
        checks(scen, float(sys.argv[3]))
    elif cmd == "timedomain":
        timedomain(scen, float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5]),
                   *(float(a) for a in sys.argv[6:7]))
    else:
        raise SystemExit(__doc__)
