"""Study (issue 16 item 2): a steady front-tracking prototype of the SHARP JFO film on the
free-to-air Jeffcott run-up bearing of grid_convergence.py ``air``. Not a library option:
bearing_fmu/ is not used for the film, only for the bearing constants and the journal
position.

The model (Jakobsson-Floberg-Olsson, sharp, p_cav = p_feed = p0)
-------------------------------------------------------------------
Units and conventions of bearing_fmu/film.py: developed film (phi, zbar), zbar in [0, 1],
``q_phi = omega theta H - a_phi H^3 p_phi``, ``q_z = -a_z H^3 p_zbar``, steady
``d_phi q_phi + d_z q_z = -2 theta dH/dt``, ``H = 1 - (x cos phi + y sin phi)/c``.

* The library's law cavitates between p0 - cav_width and p0; its sharp limit (cav_width -> 0)
  has the cavity at p0, which is also p_feed and the edge pressure. With p_cav = p_feed the
  film leaving the groove (at 90 deg, in the diverging gap) ruptures AT the groove's
  downstream edge phi_g = 97.5 deg: the cavity after it starts with theta = 1, i.e. carries
  per row the Couette content m = theta H = H(phi_g) (the groove's true width enters only
  here, exactly), transported without axial flow (p is flat) with the squeeze term
  ``omega dm/dphi = -2 m Hdot / H``.
* One full film per row, from the reformation front phi_f(z) (206.6 deg at mid-width, 222 deg
  next to the edges) through the minimum gap (-10 deg) to the rupture front phi_r(z) (16.4 deg
  at mid-width, 4 deg next to the edges; unwrapped + 2 pi); it does
  not touch the groove. Edges zbar = 0, 1: p = p0 (Dirichlet; the library's penalty edge,
  b = 1e4, is the Dirichlet value +0.03 % in load, docs/bearing-validation.md).
  The cavity between the rupture and the groove (up to 82.5 deg) is at p0 and carries no load.
* Rupture (Reynolds / Swift-Stieber): p = p_cav and grad p = 0 (p_phi = 0 suffices: p_z
  vanishes along the front).
* Reformation, the jump condition with the front's full normal (front phi = Phi(z), flux
  continuity [q_phi - Phi' q_z] = 0, p_z = -Phi' p_phi along the front):
  ``H^3 (a_phi + a_z Phi'^2) p_phi = omega (H - m)`` at phi_f (nothing neglected; the front
  is steady).

The discretisation: the full film on a FRONT-FITTED grid
-------------------------------------------------------
Per row j (cell centres zbar_j = (j + 1/2)/n_z as the library's rows) the full film is
mapped onto xi in [0, 1]: ``phi = F(z) + xi L(z)``, F = phi_f, L = phi_r - phi_f, with
M intervals in xi (nodes xi_k = k/M, p = p_cav at k = 0 and k = M, unknowns k = 1..M-1).
The conservation law in (xi, z) (Jacobian L): ``d_xi (q_phi - P q_z) + d_z (L q_z) = -2 Hdot
L`` with ``P = phi_z|_xi = F' + xi L'``, ``p_phi = p_xi / L``, ``p_z|_phi = p_z|_xi - (P/L)
p_xi``; finite volumes around the nodes, two-point xi differences on xi faces (H at the
face), central z differences averaged to the face for the cross term, z faces with the
front positions averaged from the two rows and Phi' as their difference, the edge face at
p0 (half-row distance, F and L extrapolated linearly to the edge). Front equations per row:
rupture ``(3 p_M - 4 p_{M-1} + p_{M-2}) = 0`` (one-sided p_xi = 0), reformation the jump
condition with the one-sided second-order p_xi. Phi' in the cross terms: 3-point central
differences (one-sided on the first and last row); Phi'^2 in the jump condition (``--slope``):
"faces", the weighted mean of the squared slopes of the two adjacent row faces (the first
version), or "upwind", the square of the one-sided 3-point derivative towards the mid-plane.
Near the edges the slope term dominates the jump condition, which then is a first-order
equation for the front along z; with "faces" odd and even rows decouple next to the edges
(the front zig-zags and Newton fails on edge-clustered rows), with "upwind" they do not. The
unknowns are p at the nodes and the
2 n_z front angles; the discrete problem is a smooth (C-infinity) function of them and of the
journal state: no cell switches on or off as a front moves (this is a moving-mesh front
tracking, not a cut cell on the library's fixed grid).

Force ``F = -R B int (p - p0) (cos, sin) dphi dzbar`` = ``-R B sum_j dz sum_k (p - p0)
(cos, sin)(phi_jk) L_j dxi`` (trapezoid in xi, its end values are 0; midpoint in z like the
library's rows). Newton with a sparse Jacobian by coloured forward differences (19 residual
evaluations: the residual is linear in p, so the p columns are exact), scipy.sparse spsolve.
Coefficients by central differences of the journal state +- 1e-3 c (positions) and +- 1e-3
c omega (velocities: the squeeze source in the full film and in the cavity's m), each
perturbed state warm from the base state, as grid_convergence.py.

"Square grid n": n_z = n rows and M = n / 2 intervals across the full film (which spans
144 deg next to the edges to 170 deg at mid-width, so the circumferential spacing is about
that of n cells over 2 pi).

Run (from the repository root; docs/bearing-validation.md, "Front tracking", has the results):
``PYTHONPATH=. nice -n 10 .venv/bin/python docs/scripts/front_tracking_2d.py [options]``

* default: force and the 8 coefficients on ``--grids`` (default 20,40,80,160; the study used
  20,40,80,160,320: 74 s with ``--mfac 0.5``, 202 s with 1.0, 33 s with 0.25), a markdown table
  with successive differences and orders;
* ``--mfac F``: M = F n xi intervals (default 0.5); ``--no-coef``: force only;
* ``--directions``: M = 20 ... 320 at n_z = 80 and n_z = 20 ... 640 at M = 80 (about 3 minutes;
  22 s with ``--no-coef``);
* ``--sweep``: force along x = x0 + i 1e-4 c, i = -8..8, on 40 x 40, first and second
  differences, front tracking and the library film (5 s);
* ``--check``: front tracking with theta_feed 0.99745 (40 rows, M = 320) against the library
  film at cav_width 100 Pa on 768 x 40, force and coefficients (about 2 minutes);
* ``--theta-feed T``: theta of the oil leaving the groove (1 in the sharp model; 0.99745 is the
  library law's theta(p_feed), the check against the library film in the study);
* ``--slope faces|upwind``: Phi'^2 of the jump condition (default faces, the first version;
  upwind: every table of part B of the study);
* ``--grading cos`` (or a blend 0..1): rows at z = (1 - cos(pi zeta)) / 2, clustered towards
  the edges (with ``--slope faces`` Newton fails from a blend of about 0.7 on; with upwind it
  converges: 81 s for 20 ... 320 with the coefficients).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import grid_convergence as gc  # noqa: E402

R = gc.BASE["R"]
B = gc.BASE["B"]
PSI = gc.BASE["psi"]
ETA0 = gc.BASE["eta0"]
P0 = gc.BASE["p0"]
C = PSI * R
A_PHI = PSI ** 2 / (6 * ETA0)
A_Z = (R / B) ** 2 * A_PHI
PHI_G = gc.CASES["air"]["groove_angle"] + 0.5 * gc.CASES["air"]["groove_width"]   # 97.5 deg
GL_X, GL_W = np.polynomial.legendre.leggauss(40)
THETA_FEED = [1.0]      # theta of the oil leaving the groove (sharp JFO: 1; --theta-feed)
SLOPE = ["faces"]       # Phi'^2 of the jump condition: "faces" or "upwind" (--slope)


class FrontFilm:
    """Steady sharp-JFO full film between per-row fronts on a front-fitted grid.

    Unknown vector U = [g (n_z, M-1) row-major, F (n_z), Rr (n_z)], g = p - p0 [Pa],
    F = phi_f, Rr = phi_r + 2 pi [rad]."""

    def __init__(self, n_z, M, grading="none"):
        self.nz, self.M = n_z, M
        self.dz = 1.0 / n_z
        zeta_f = np.arange(n_z + 1) / n_z
        zeta_c = (np.arange(n_z) + 0.5) / n_z
        beta = {"none": 0.0, "cos": 1.0}.get(grading, None)
        beta = float(grading) if beta is None else beta
        Z = lambda s: (1 - beta) * s + beta * 0.5 * (1.0 - np.cos(np.pi * s))   # noqa: E731
        self.zf = Z(zeta_f)                      # row faces (edges at 0 and 1)
        self.zc = Z(zeta_c)                      # row centres
        self.hz = np.diff(self.zf)               # row heights
        # 3-point derivative weights at each row centre: rows (j-1, j, j+1); the first/last row
        # use the edge (value 0 for g) as the outer point ("edge") or rows (0, 1, 2) ("front")
        zc = self.zc
        ext = np.concatenate([[0.0], zc, [1.0]])
        self.w_edge = np.array([self._w3(ext[j], ext[j + 1], ext[j + 2], ext[j + 1]) for j in range(n_z)])
        wf = [self._w3(zc[j - 1], zc[j], zc[j + 1], zc[j]) for j in range(1, n_z - 1)]
        lo = [(j, j + 1, j + 2) for j in range(n_z // 2)]
        hi = [(j - 2, j - 1, j) for j in range(n_z // 2, n_z)]
        self.up_idx = np.array(lo + hi)
        self.w_up = np.array([self._w3(zc[a], zc[b], zc[c], zc[j])
                              for j, (a, b, c) in enumerate(lo + hi)])
        self.w_front = np.array([self._w3(zc[0], zc[1], zc[2], zc[0])] + wf
                                + [self._w3(zc[-3], zc[-2], zc[-1], zc[-1])])
        self.dxi = 1.0 / M
        self.xi = np.arange(M + 1) / M
        self.xf = (np.arange(M) + 0.5) / M
        self.NP = n_z * (M - 1)
        self.N = self.NP + 2 * n_z
        self._colouring()

    # ------------------------------------------------------------------ kinematics
    def set_kin(self, x, y, vx, vy, omega):
        self.kin = (x, y, vx, vy, omega)

    def H(self, phi):
        x, y = self.kin[:2]
        return 1.0 - (x * np.cos(phi) + y * np.sin(phi)) / C

    def Hdot(self, phi):
        vx, vy = self.kin[2:4]
        return -(vx * np.cos(phi) + vy * np.sin(phi)) / C

    def m_cavity(self, F):
        """theta H at the reformation front: H(phi_g) exp(-(2/omega) int_{phi_g}^{F} Hdot/H)."""
        omega = self.kin[4]
        a = PHI_G
        half = 0.5 * (F - a)
        ph = a + half[:, None] * (GL_X[None, :] + 1.0)
        integ = (self.Hdot(ph) / self.H(ph)) @ GL_W * half
        return THETA_FEED[0] * self.H(np.array(PHI_G)) * np.exp(-2.0 / omega * integ)

    # ------------------------------------------------------------------ helpers
    @staticmethod
    def _w3(a, b, c, x):
        """Weights of the derivative at x of the parabola through points a, b, c."""
        return np.array([((x - b) + (x - c)) / ((a - b) * (a - c)),
                         ((x - a) + (x - c)) / ((b - a) * (b - c)),
                         ((x - a) + (x - b)) / ((c - a) * (c - b))])

    def dz_rows(self, v):
        """d v / dz at the row centres (front angles): 3-point, one-sided on the first/last row."""
        w = self.w_front
        d = np.empty_like(v)
        d[1:-1] = w[1:-1, 0] * v[:-2] + w[1:-1, 1] * v[1:-1] + w[1:-1, 2] * v[2:]
        d[0] = w[0] @ v[:3]
        d[-1] = w[-1] @ v[-3:]
        return d

    def slope2_rows(self, v):
        """(d v / dz)^2 at the row centres for the jump condition: the weighted mean of the
        squared slopes of the two adjacent row faces (the weights of the 3-point derivative;
        second order), not the square of the central difference, which is blind to an
        odd-even zig-zag of the front (Newton cycled on it on graded rows); one-sided 3-point
        derivative squared on the first and last row."""
        w = self.w_front
        s = np.diff(v) / np.diff(self.zc)
        d2 = np.empty_like(v)
        wm = self.w_front[1:-1, 0] * (self.zc[:-2] - self.zc[1:-1])   # = -(weight of F_{j-1}) * dz_-
        d2[1:-1] = wm * s[:-1] ** 2 + (1 - wm) * s[1:] ** 2
        d2[0] = (w[0] @ v[:3]) ** 2
        d2[-1] = (w[-1] @ v[-3:]) ** 2
        return d2

    def slope2_upwind(self, v):
        """(d v / dz)^2 at the row centres from the one-sided 3-point derivative towards the
        mid-plane (rows j, j+1, j+2 in the lower half, j-2, j-1, j in the upper half). Near the
        edges the slope term dominates the jump condition (a_z Phi'^2 / a_phi up to 1.9), which
        then is a first-order equation for the front along z; centred differences of it let odd
        and even rows decouple (the front zig-zags next to the edges, and Newton fails on
        edge-clustered rows), a one-sided difference does not."""
        w = self.w_up
        idx = self.up_idx
        return (w * v[idx]).sum(axis=1) ** 2

    def dz_field(self, g):
        """d g / dz at fixed xi at every node, g = 0 on the edges (3-point, non-uniform)."""
        w = self.w_edge
        ge = np.vstack([np.zeros(g.shape[1]), g, np.zeros(g.shape[1])])
        return w[:, 0, None] * ge[:-2] + w[:, 1, None] * ge[1:-1] + w[:, 2, None] * ge[2:]

    def unpack(self, U):
        nz, M = self.nz, self.M
        g = np.zeros((nz, M + 1))
        g[:, 1:M] = U[:self.NP].reshape(nz, M - 1)
        F = U[self.NP:self.NP + nz]
        Rr = U[self.NP + nz:]
        return g, F, Rr

    # ------------------------------------------------------------------ residual
    def residual(self, U):
        nz, M, dxi = self.nz, self.M, self.dxi
        omega = self.kin[4]
        g, F, Rr = self.unpack(U)
        L = Rr - F
        dF = self.dz_rows(F)
        dL = self.dz_rows(L)
        # z derivative of g at fixed xi, at every node (nz, M+1)
        gz = self.dz_field(g)
        hz = self.hz[:, None]
        # xi faces (nz, M)
        phif = F[:, None] + self.xf[None, :] * L[:, None]
        Hf = self.H(phif)
        Hf3 = Hf ** 3
        gxi = (g[:, 1:] - g[:, :-1]) / dxi
        gzf = 0.5 * (gz[:, 1:] + gz[:, :-1])
        Pf = dF[:, None] + self.xf[None, :] * dL[:, None]
        Lc = L[:, None]
        qphi = omega * Hf - A_PHI * Hf3 * gxi / Lc
        qz = -A_Z * Hf3 * (gzf - Pf / Lc * gxi)
        Gxi = (qphi - Pf * qz) * hz                     # (nz, M)
        # z faces at the interior nodes k = 1..M-1: faces 0..nz (nz+1, M-1)
        xi_i = self.xi[1:M]
        gxi_c = (g[:, 2:] - g[:, :-2]) / (2 * dxi)      # (nz, M-1) central xi derivative at nodes
        Gz = np.empty((nz + 1, M - 1))
        dzc = np.diff(self.zc)
        wl = (self.zc[1:] - self.zf[1:-1]) / dzc        # linear interpolation to the face
        Fm = wl * F[:-1] + (1 - wl) * F[1:]
        Lm = wl * L[:-1] + (1 - wl) * L[1:]
        dFm = (F[1:] - F[:-1]) / dzc
        dLm = (L[1:] - L[:-1]) / dzc
        ph = Fm[:, None] + xi_i[None, :] * Lm[:, None]
        Hm3 = self.H(ph) ** 3
        gzm = (g[1:, 1:M] - g[:-1, 1:M]) / dzc[:, None]
        gxim = wl[:, None] * gxi_c[:-1] + (1 - wl[:, None]) * gxi_c[1:]
        Pm = dFm[:, None] + xi_i[None, :] * dLm[:, None]
        Gz[1:-1] = Lm[:, None] * (-A_Z * Hm3 * (gzm - Pm / Lm[:, None] * gxim)) * dxi
        z0, z1 = self.zc[0], self.zc[1]
        for e, (r0, r1, sgn) in enumerate(((0, 1, 1.0), (nz - 1, nz - 2, -1.0))):
            # F, L extrapolated linearly to the edge; edge distance z0 (symmetric grid)
            Fe = F[r0] + (F[r0] - F[r1]) * z0 / (z1 - z0)
            Le = L[r0] + (L[r0] - L[r1]) * z0 / (z1 - z0)
            He3 = self.H(Fe + xi_i * Le) ** 3
            # flux in +z through the edge face: bottom -a_z H^3 g0/z0, top +a_z H^3 g/z0
            val = -A_Z * He3 * sgn * g[r0, 1:M] / z0 * Le * dxi
            Gz[0 if e == 0 else nz] = val
        src = 2.0 * self.Hdot(F[:, None] + xi_i[None, :] * Lc) * Lc * dxi * hz
        res_cv = Gxi[:, 1:] - Gxi[:, :-1] + Gz[1:] - Gz[:-1] + src
        # front equations
        Hr = self.H(Rr)
        res_r = A_PHI * Hr ** 3 / L * (3 * g[:, M] - 4 * g[:, M - 1] + g[:, M - 2]) / (2 * dxi) * self.hz
        Hfr = self.H(F)
        gxi0 = (-3 * g[:, 0] + 4 * g[:, 1] - g[:, 2]) / (2 * dxi)
        m = self.m_cavity(F)
        s2 = self.slope2_rows(F) if SLOPE[0] == "faces" else self.slope2_upwind(F)
        res_f = ((A_PHI + A_Z * s2) * Hfr ** 3 * gxi0 / L - omega * (Hfr - m)) * self.hz
        return np.concatenate([res_cv.ravel(), res_f, res_r])

    # ------------------------------------------------------------------ Jacobian
    def _colouring(self):
        nz, M, NP = self.nz, self.M, self.NP
        groups = {}
        rows_of = [None] * self.N
        cv = lambda j, k: j * (M - 1) + (k - 1)                       # noqa: E731
        for j in range(nz):
            for k in range(1, M):
                col = cv(j, k)
                rs = [cv(jj, kk) for jj in range(j - 1, j + 2) for kk in range(k - 1, k + 2)
                      if 0 <= jj < nz and 1 <= kk <= M - 1]
                if k <= 2:
                    rs.append(NP + j)
                if k >= M - 2:
                    rs.append(NP + nz + j)
                rows_of[col] = np.array(rs)
                groups.setdefault(("p", j % 3, k % 3), []).append(col)
        for which in (0, 1):
            for j in range(nz):
                col = NP + which * nz + j
                jj = [r for r in range(j - 2, j + 3) if 0 <= r < nz]
                rs = [cv(r, k) for r in jj for k in range(1, M)]
                rs += [NP + r for r in jj] + [NP + nz + r for r in jj]
                rows_of[col] = np.array(rs)
                groups.setdefault(("f", which, j % 5), []).append(col)
        self.groups = [np.array(v) for v in groups.values()]
        self.rows_of = rows_of

    def jacobian(self, U, r0):
        NP = self.NP
        I, Jc, V = [], [], []
        for cols in self.groups:
            h = np.where(cols < NP, 100.0, 1e-7)
            Up = U.copy()
            Up[cols] += h
            dr = self.residual(Up) - r0
            for c, hc in zip(cols, h):
                rs = self.rows_of[c]
                I.append(rs)
                Jc.append(np.full(rs.size, c))
                V.append(dr[rs] / hc)
        I = np.concatenate(I)
        Jc = np.concatenate(Jc)
        V = np.concatenate(V)
        keep = V != 0.0
        return sp.csc_matrix((V[keep], (I[keep], Jc[keep])), shape=(self.N, self.N))

    # ------------------------------------------------------------------ Newton
    def solve(self, U0, tol_front=1e-13, tol_p=1e-7, maxit=60, verbose=False):
        U = U0.copy()
        NP = self.NP
        for it in range(maxit):
            r = self.residual(U)
            Jm = self.jacobian(U, r)
            dU = -spla.spsolve(Jm, r)
            dfr = np.max(np.abs(dU[NP:]))
            lam = min(1.0, 0.05 / dfr) if dfr > 0 else 1.0
            # backtracking on the residual's 2-norm (the fronts' basin is small from an
            # interpolated guess); a full step whenever it reduces the residual
            r2 = np.linalg.norm(r)
            dp = np.max(np.abs(dU[:NP]))
            if dfr < tol_front and dp < tol_p:
                return U + dU, it + 1
            while lam > 1.0 / 256 and np.linalg.norm(self.residual(U + lam * dU)) > (1 - 1e-4 * lam) * r2:
                lam *= 0.5
            U = U + lam * dU
            dp = np.max(np.abs(dU[:NP]))
            if verbose:
                print(f"    it {it}: |r| {np.max(np.abs(r)):.3e} |dp| {dp:.3e} |dfront| {dfr:.3e} lam {lam}")
        raise RuntimeError(f"Newton did not converge: |dp| {dp:.3e} |dfront| {dfr:.3e}")

    def force(self, U):
        g, F, Rr = self.unpack(U)
        L = Rr - F
        phi = F[:, None] + self.xi[None, :] * L[:, None]
        w = g * L[:, None] * self.dxi * self.hz[:, None]
        return np.array([-(w * np.cos(phi)).sum(), -(w * np.sin(phi)).sum()]) * R * B

    def initial(self, F, Rr):
        U = np.zeros(self.N)
        U[self.NP:self.NP + self.nz] = F
        U[self.NP + self.nz:] = Rr
        return U

    def interp_from(self, other, Uo):
        """Initial guess on this grid from a solution on another (linear interpolation)."""
        go, Fo, Ro = other.unpack(Uo)
        zo = other.zc
        z = self.zc
        F = np.interp(z, zo, Fo)
        Rr = np.interp(z, zo, Ro)
        # g on (z, xi): interpolate in xi per old row, then in z
        gx = np.array([np.interp(self.xi, other.xi, row) for row in go])
        zo_e = np.concatenate([[0.0], zo, [1.0]])
        gx_e = np.vstack([np.zeros(self.M + 1), gx, np.zeros(self.M + 1)])
        g = np.array([np.interp(z, zo_e, gx_e[:, k]) for k in range(self.M + 1)]).T
        U = self.initial(F, Rr)
        U[:self.NP] = g[:, 1:self.M].ravel()
        return U


def quantities(n, q, omega, U_guess=None, guess_film=None, mfac=0.5, coefficients=True,
               rel=1e-3, verbose=False, grading="none", M=None):
    M = max(6, int(round(mfac * n))) if M is None else M
    ff = FrontFilm(n, M, grading)
    ff.set_kin(q[0], q[1], 0.0, 0.0, omega)
    if U_guess is None:
        U0 = ff.initial(np.full(n, math.radians(212.0)), np.full(n, 2 * math.pi + math.radians(20.0)))
        if grading != "none":          # Newton from the crude guess fails on graded rows
            fu = FrontFilm(n, M)
            fu.set_kin(q[0], q[1], 0.0, 0.0, omega)
            U0 = ff.interp_from(fu, fu.solve(fu.initial(U0[ff.NP:ff.NP + n], U0[ff.NP + n:]))[0])
    else:
        U0 = ff.interp_from(guess_film, U_guess)
    U, its = ff.solve(U0, verbose=verbose)
    F0 = ff.force(U)
    out = dict(ff=ff, U=U, its=its, F=F0)
    if not coefficients:
        return out
    def force_at(z):
        ff.set_kin(z[0], z[1], z[2], z[3], omega)
        return ff.force(ff.solve(U)[0])

    D = gc.central_coefficients(force_at, q, omega, C, rel)
    ff.set_kin(q[0], q[1], 0.0, 0.0, omega)
    out["coef"] = np.concatenate([D[:, :2].ravel(), D[:, 2:].ravel()])
    return out


def _print_rows(label, grids, rows, names):
    for k, name in enumerate(names):
        v = np.array([r[k] for r in rows])
        d = np.diff(v)
        o = [math.log2(d[i] / d[i + 1]) if d[i + 1] != 0 and d[i] / d[i + 1] > 0 else float("nan")
             for i in range(len(d) - 1)]
        print(f"| {label} | {name} | " + " | ".join(f"{x:.7g}" for x in v) + " | "
              + ", ".join(f"{x:+.2e}" for x in d) + " | " + ", ".join(f"{x:.2f}" for x in o) + " |")


def directions(q, omega, coefficients=True):
    """Refinement in one direction at a time: M = 20 ... 320 at n_z = 80, n_z = 20 ... 640 at
    M = 80 (force and, if ``coefficients``, the 8 coefficients)."""
    for label, pairs in (("xi (n_z = 80)", [(80, m) for m in (20, 40, 80, 160, 320)]),
                         ("z (M = 80)", [(n, 80) for n in (20, 40, 80, 160, 320, 640)])):
        prev = (None, None)
        rows = []
        for nz, M in pairs:
            t0 = time.time()
            o = quantities(nz, q, omega, *prev, M=M, coefficients=coefficients)
            prev = (o["U"], o["ff"])
            rows.append(list(o["F"]) + (list(o["coef"]) if coefficients else []))
            print(f"  {label}: {nz} x {M} ({time.time() - t0:.1f} s): "
                  + ", ".join(f"{x:.8g}" for x in rows[-1]), flush=True)
        _print_rows(label, pairs, rows, gc.NAMES[:len(rows[0])])


def sweep(q, omega, n=40, mfac=0.5, k=8, step=1e-4):
    """Force along x = x0 + i step c, i = -k..k, on one grid: its first and second differences
    (smoothness in the journal position), and the same for the library film."""
    M = max(6, int(round(mfac * n)))
    ff = FrontFilm(n, M)
    ff.set_kin(q[0], q[1], 0.0, 0.0, omega)
    U0 = quantities(n, q, omega, M=M, coefficients=False)["U"]
    Fs = []
    for i in range(-k, k + 1):
        ff.set_kin(q[0] + i * step * C, q[1], 0.0, 0.0, omega)
        Fs.append(ff.force(ff.solve(U0)[0]))
    Flib = [gc.mc_quantities("air", n, (q[0] + i * step * C, q[1]), omega, coefficients=False)
            for i in range(-k, k + 1)]
    for label, F in ((f"front tracking {n} x {n} (M = {M})", np.array(Fs)),
                     (f"library film {n} x {n} (steady, Newton 1e-10 / 1e-11)", np.array(Flib))):
        d1 = np.diff(F, axis=0) / (step * C)
        d2 = np.diff(F, 2, axis=0) / (step * C) ** 2
        print(f"{label}, x = x0 + i {step} c, i = -{k}..{k}")
        print("  -dFx/dx [N/m]: " + " ".join(f"{-x:.5e}" for x in d1[:, 0]))
        print("  -dFy/dx [N/m]: " + " ".join(f"{-x:.5e}" for x in d1[:, 1]))
        print("  d2Fx/dx2 [N/m^2]: " + " ".join(f"{x:.3e}" for x in d2[:, 0]))
        print("  d2Fy/dx2 [N/m^2]: " + " ".join(f"{x:.3e}" for x in d2[:, 1]))


def check_library(q, omega, theta_feed=0.99745):
    """Force and coefficients of front tracking with the library law's theta(p_feed) (40 rows,
    M = 320) against the library film at cav_width 100 Pa on 768 x 40 (about 2 minutes)."""
    THETA_FEED[0] = theta_feed
    t0 = time.time()
    o1 = quantities(40, q, omega, M=40, coefficients=False)
    o = quantities(40, q, omega, o1["U"], o1["ff"], M=320)
    a = list(o["F"]) + list(o["coef"])
    print(f"front tracking, 40 rows, M = 320, theta_feed {theta_feed} ({time.time() - t0:.1f} s): "
          + ", ".join(f"{n} {x:.6g}" for n, x in zip(gc.NAMES, a)), flush=True)
    t0 = time.time()
    b = gc.mc_quantities("air", 768, q, omega, n_z=40, cav_width=100.0)
    print(f"library film, 768 x 40, cav_width 100 Pa ({time.time() - t0:.1f} s): "
          + ", ".join(f"{n} {x:.6g}" for n, x in zip(gc.NAMES, b)))
    print("front tracking / library - 1: " + ", ".join(f"{n} {x / y - 1:+.2%}" for n, x, y in zip(gc.NAMES, a, b)))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--grids", default="20,40,80,160")
    ap.add_argument("--mfac", type=float, default=0.5)
    ap.add_argument("--no-coef", action="store_true")
    ap.add_argument("-v", action="store_true")
    ap.add_argument("--grading", default="none", choices=["none", "cos"],
                    help="rows uniform in zbar (as the library) or z = (1 - cos(pi zeta)) / 2")
    ap.add_argument("--directions", action="store_true",
                    help="refine xi and z separately (with --no-coef: force only)")
    ap.add_argument("--slope", default="faces", choices=["faces", "upwind"],
                    help="Phi'^2 in the jump condition: mean of the squared face slopes (the first "
                         "tables) or the one-sided derivative towards the mid-plane")
    ap.add_argument("--check", action="store_true",
                    help="theta_feed 0.99745 against the library film at cav_width 100 Pa")
    ap.add_argument("--sweep", action="store_true",
                    help="force along x on 40 x 40: first and second differences")
    ap.add_argument("--theta-feed", type=float, default=1.0,
                    help="theta of the oil leaving the groove (a check against the library's law, "
                         "whose theta(p_feed) is below 1)")
    a = ap.parse_args(argv)
    THETA_FEED[0] = a.theta_feed
    SLOPE[0] = a.slope
    if a.directions:
        directions(gc.hs_equilibrium(40), 2 * math.pi * gc.F_HZ, not a.no_coef)
        return
    if a.check:
        check_library(gc.hs_equilibrium(40), 2 * math.pi * gc.F_HZ)
        return
    if a.sweep:
        sweep(gc.hs_equilibrium(40), 2 * math.pi * gc.F_HZ, mfac=a.mfac)
        return
    grids = [int(s) for s in a.grids.split(",")]
    omega = 2 * math.pi * gc.F_HZ
    q = gc.hs_equilibrium(40)
    print(f"fixed kinematics: x = {q[0]:.6e} m, y = {q[1]:.6e} m, {gc.F_HZ} Hz; a_phi {A_PHI:.6e}, "
          f"a_z {A_Z:.6e}, phi_g {math.degrees(PHI_G):.2f} deg, M = {a.mfac} n, rows {a.grading}")
    rows = []
    prev = None
    for n in grids:
        t0 = time.time()
        o = quantities(n, q, omega, *(prev if prev else (None, None)), mfac=a.mfac,
                       coefficients=not a.no_coef, verbose=a.v, grading=a.grading)
        prev = (o["U"], o["ff"])
        g, F, Rr = o["ff"].unpack(o["U"])
        vals = list(o["F"]) + (list(o["coef"]) if "coef" in o else [])
        rows.append(vals)
        print(f"  {n}: {time.time() - t0:.1f} s, Newton {o['its']} it; phi_f edge/mid "
              f"{math.degrees(F[0]):.3f}/{math.degrees(F[n // 2]):.3f} deg, phi_r edge/mid "
              f"{math.degrees(Rr[0]) - 360:.3f}/{math.degrees(Rr[n // 2]) - 360:.3f} deg, "
              f"min p - p0 {g.min():.3e} Pa; " + ", ".join(f"{v:.8g}" for v in vals), flush=True)
    names = gc.NAMES[:len(rows[0])]
    print("\n| quantity | " + " | ".join(f"{n}" for n in grids) + " | differences | orders |")
    print("|---|" + "---|" * (len(grids) + 2))
    for k, name in enumerate(names):
        v = [r[k] for r in rows]
        d = [v[i + 1] - v[i] for i in range(len(v) - 1)]
        o = [math.log2(d[i] / d[i + 1]) if d[i + 1] != 0 and d[i] / d[i + 1] > 0 else float("nan")
             for i in range(len(d) - 1)]
        print(f"| {name} | " + " | ".join(f"{x:.7g}" for x in v) + " | "
              + ", ".join(f"{x:+.3e}" for x in d) + " | " + ", ".join(f"{x:.2f}" for x in o) + " |")


if __name__ == "__main__":
    main()
