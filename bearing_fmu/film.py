"""Finite-volume residual and Jacobian of the transient Reynolds equation, and
the film's integral quantities (forces, torque, flows).

Equation (paper eq. 2 with eq. 3, divided by rho0; rho/eta = rho0/eta0 so the
Poiseuille term carries no theta), in conservative form on the developed film
(phi, zbar), unknown the universal variable u (see :mod:`.cavitation`):

    2 H dtheta/dt + 2 theta dH/dt + d/dphi q_phi + d/dzbar q_z = 0
    q_phi = omega theta H - a_phi H^3 dp/dphi,     a_phi = psi^2 / (6 eta0)
    q_z   =               - a_z   H^3 dp/dzbar,    a_z   = (R/B)^2 psi^2 / (6 eta0)

The time term is written as in paper eq. (4): the journal kinematics (x, y,
vx, vy) are inputs held over a step, so H is frozen and dH/dt is the input
squeeze velocity; theta is the dynamic state.

Finite volumes (cell (j, i), area dphi*dz, fluxes through its four faces):

* Poiseuille: two-point flux with the exact gap at the face, ``-a H_f^3
  (p_nb - p)/d`` (second order).
* Couette: ``omega H_f theta_upwind`` -- theta is taken from the upwind cell
  (cell i for omega >= 0). First-order upwinding of the convected fluid
  fraction is the stabilisation the paper obtains from artificial diffusion
  (Kuzmin 2010): it adds a numerical diffusion ``omega H dphi / 2`` acting on
  theta only. Because theta = 1 in the full film, the pressure region keeps the
  central, second-order discretisation; in the cavity it transports the
  striated film downstream without oscillation, keeps theta monotone (an
  M-matrix Jacobian column-wise) and makes the rupture/reformation mass
  balance exact at the discrete level (Elrod 1981 uses the same upwind
  Couette term in the cavity).
* Couette, option ``theta_transport = 1`` (:func:`assemble_muscl`): limited
  second-order (MUSCL) face value. For omega >= 0 at face i+1/2
  ``theta_f = theta_i + L(theta_i - theta_{i-1}, theta_{i+1} - theta_i) / 2``
  (mirrored for omega < 0) with the smooth limiter of :func:`limiter`,
  ``L(a, b) = 2 a^2 b^2 (a + b) / ((a^2 + b^2)^2 + eps)`` for a b > 0, else 0:
  van Albada's ``a b (a + b) / (a^2 + b^2)`` times the switch ``2 a b / (a^2 +
  b^2)``, i.e. ``phi(r) = 2 r^2 (1 + r) / (1 + r^2)^2`` (r = a / b) in Sweby's
  form: phi(1) = 1 (second order where theta is smooth and monotone),
  0 <= phi <= min(2 r, 2) (TVD region), and C1 across a b = 0 (L and both
  derivatives vanish there), so Newton sees a differentiable residual. A face
  next to a groove cell (Dirichlet) keeps the first-order upwind value, so no
  flux couples cells across a groove (the band ordering stays valid). Each face
  flux is computed once per face value and enters both cells with opposite
  signs, so the discrete mass balance is exact as before. The Jacobian gains
  the couplings i +- 2 (stencil columns 5, 6). Full film: theta = 1, the
  Couette flux is unchanged.
* Axial edges: oil bath (eq. 5) p = p0 at zbar = 0, 1 through a half-cell
  two-point flux; free to air (eq. 6) outward flux g(p_edge) at the edge itself, the edge
  pressure from the flux continuity through the same half cell
  (:func:`.cavitation.penalty_edge`; second order, the Dirichlet flux for b -> infinity).
* Groove cells: Dirichlet ``u = u_feed`` (p = p_feed).

Half-Sommerfeld force quadrature (:func:`hs_force_pressure`): the force of the
clipped pressure ``max(P, 0)`` is integrated with the rupture located inside the
cells (piecewise-linear P in phi), not at cell resolution, so that the force is a
smooth function of the journal position and its derivatives (the dynamic
coefficients) converge at second order.

Residuals are the cell balances times the cell area (units 1/s); the sum of
all non-groove residuals telescopes to (feed inflow - side outflow - film
volume change), which is how q_feed and q_side balance to solver tolerance.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .cavitation import law_eval, penalty_edge


#: columns of the per-column coefficient table of :func:`_column_terms` (``+ side`` for the
#: per-face ones: side 0 the east face i + 1/2, side 1 the west face i - 1/2)
C_AREA, C_2H, C_2HDOT, C_DIAG_T, C_DPHI_W, C_CZ, C_MCZ, C_DCZ, C_MDCZ = range(9)
C_COND, C_SOM, C_DZSOM, C_MDZC, C_DZC, C_FR = 9, 11, 13, 15, 17, 19
N_COLUMN_TERMS = 21


@nb.njit(cache=True, nogil=True)
def _column_terms(H, He, Hdot, groove, th_dot0, omega, a_phi, a_z, dphi, dz, wr, fr,
                  true_groove):
    """The coefficients of a cell's balance that depend on its column only (H is uniform in
    z), once per column instead of once per cell: ``cf`` (n_phi, N_COLUMN_TERMS), columns
    ``C_*``, and ``leaves`` (n_phi, 2) -- does the Couette flow leave the groove through
    this face (:func:`groove_exit`). Each entry is the expression the cell loop of
    :func:`assemble` evaluated for itself before (the same operands in the same order), so
    the residual and Jacobian are the same bit for bit; hoisting them out of the loop over
    rows makes the assembly ~2.5x faster (BENCHMARKS.md, issue 16)."""
    n_phi = H.size
    cf = np.empty((n_phi, N_COLUMN_TERMS))
    leaves = np.zeros((n_phi, 2), dtype=np.bool_)
    A = dphi * dz
    up_e = omega >= 0.0
    for i in range(n_phi):
        Hi = H[i]
        Ai = A * wr[i]
        cf[i, C_AREA] = Ai
        cf[i, C_2H] = 2.0 * Hi
        cf[i, C_2HDOT] = 2.0 * Hdot[i]
        cf[i, C_DIAG_T] = Ai * (2.0 * Hi * th_dot0 + 2.0 * Hdot[i])
        for side in range(2):
            if side == 0:
                i2 = i + 1 if i + 1 < n_phi else 0
                Hf = He[i]
                sgn = 1.0
                fi = i
            else:
                i2 = i - 1 if i > 0 else n_phi - 1
                Hf = He[i2]
                sgn = -1.0
                fi = i2
            cond = a_phi * Hf * Hf * Hf / (dphi * fr[fi])
            cf[i, C_COND + side] = cond
            cf[i, C_SOM + side] = sgn * omega * Hf
            cf[i, C_DZSOM + side] = dz * sgn * omega * Hf
            cf[i, C_MDZC + side] = -dz * cond
            cf[i, C_DZC + side] = dz * cond
            cf[i, C_FR + side] = fr[fi]
            own_up = up_e if side == 0 else not up_e
            leaves[i, side] = true_groove and groove[i2] and not own_up
        dw = dphi * wr[i]
        condz = a_z * Hi * Hi * Hi / dz
        cf[i, C_DPHI_W] = dw
        cf[i, C_CZ] = condz
        cf[i, C_MCZ] = -condz
        cf[i, C_DCZ] = dw * condz
        cf[i, C_MDCZ] = -dw * condz
    return cf, leaves


@nb.njit(cache=True, nogil=True)
def _axial_faces(r, jst, want_jac, cf, p, dp, groove, n_phi, n_z, p0, bath, sym, pa, pb,
                 s_pen, a_z):
    """Add the north/south (axial) face fluxes of every film cell to its residual ``r`` and,
    if ``want_jac``, Jacobian diagonal ``jst[:, 0]`` and set its north/south stencil entries
    (0 where there is no neighbour): Poiseuille between cells, oil bath (eq. 5: p = p0
    through a half cell) or free to air (eq. 6: penalty flux) at the edges, no flux at a
    symmetry plane. ``cf``: the column terms of :func:`_column_terms`.

    A pass of its own after the phi faces of :func:`assemble` / :func:`assemble_muscl`: each
    cell's sums gain the same terms in the same order as when the cell loop added them
    itself, so the values are the same bit for bit, and the loop is ~1.4x faster than the
    same code inlined into the cell loop (BENCHMARKS.md, issue 16)."""
    for j in range(n_z):
        for i in range(n_phi):
            if groove[i]:
                continue
            g = j * n_phi + i
            res = r[g]
            diag = jst[g, 0] if want_jac else 0.0
            for side in range(2):
                j2 = j + 1 if side == 0 else j - 1
                if 0 <= j2 < n_z:
                    g2 = j2 * n_phi + i
                    res += cf[i, C_DPHI_W] * (cf[i, C_MCZ] * (p[g2] - p[g]))
                    diag += cf[i, C_DCZ] * dp[g]
                    if want_jac:
                        jst[g, 3 + side] = cf[i, C_MDCZ] * dp[g2]
                else:
                    if want_jac:
                        jst[g, 3 + side] = 0.0
                    if sym and side == 0:
                        pass                      # mid-plane: symmetry, no flux
                    elif bath:
                        res += cf[i, C_DPHI_W] * 2.0 * cf[i, C_CZ] * (p[g] - p0)
                        diag += cf[i, C_DPHI_W] * 2.0 * cf[i, C_CZ] * dp[g]
                    else:                          # eq. 6 at the edge, through the half cell
                        gv, dgv = penalty_edge(p[g] - p0, 2.0 * cf[i, C_CZ], pa, pb, s_pen, a_z)
                        res += cf[i, C_DPHI_W] * gv
                        diag += cf[i, C_DPHI_W] * dgv * dp[g]
            r[g] = res
            if want_jac:
                jst[g, 0] = diag


@nb.njit(cache=True, inline="always")
def groove_exit(He, n_phi, i, side, fr, dphi, omega, a_phi, cond, dpg, c, K):
    """Poiseuille flux B from the groove into the film cell i downstream of it (the face
    where the Couette flow leaves the groove; ``side`` 1: groove west of i, 0: east), with
    dB/dp_i and dB/dc; ``cond`` = a H_f^3 / d the two-point conductance over the centre
    distance d = ``fr`` dphi, ``dpg`` = p_groove - p_i, ``c`` = dtheta/du of cell i (0 in the
    incompressible full film, -> 1 in the cavity), ``K`` the law's dp/du scale
    (issue 16, groove of its true width).

    Where the film leaving the groove enters the partly filled film of a diverging gap
    (theta(p) < 1, p between p_cav and p0), it is advection-dominated on the grid scale:
    linearised, the Reynolds flux is ``q = omega H theta(p) - a H^3 p'``, an
    advection-diffusion of p with velocity ``omega H dtheta/dp``, ``dtheta/dp = c / (K (1 -
    c))``, and diffusion ``a H^3``; its cell Peclet number over half a cell,
    ``Pe = |omega| (dphi / 2) dtheta/dp / (a H^2)``, is ~20 at p0 and ~100 at p0 - 500 Pa
    (Jeffcott bearing, 40 cells). With the upwinded Couette theta the value of such a cell
    is that of its OUTFLOW face, not of its centre, so the two-point gradient to the groove
    must be taken over the distance to that face, L = d + dphi / 2, not over d: over d the
    flux ``a H^3 (p_groove - p_i) / d`` grows without bound as the grid puts the edge close
    to the cell centre (d -> 0), a spurious, cut-dependent supply into the cavity (the
    force 1.8 % off at d = 0.03 dphi, n = 40; docs/bearing-validation.md). In the
    incompressible full film (Pe -> 0) the centre value and the Shortley-Weller distance d
    are right. The effective distance blends the two with the exact one-dimensional
    (Scharfetter-Gummel) weight: ``1/d_eff = (1 - lam) / d + lam / L``, ``lam = 1 -
    Pe / (e^Pe - 1)``: 0 for Pe -> 0, 1 for Pe >> 1, smooth in u for Newton."""
    d = fr * dphi
    L = d + 0.5 * dphi
    Hf = He[i - 1 if i > 0 else n_phi - 1] if side == 1 else He[i]
    # cell Peclet number of the p-advection over half a cell: v = |omega| H dtheta/dp,
    # dtheta/dp = c / (K (1 - c)), diffusion a H^3
    cc = min(c, 1.0 - 1e-12)
    kq = abs(omega) * 0.5 * dphi / (K * a_phi * Hf * Hf)
    Pe = kq * cc / (1.0 - cc)
    dPe = kq / ((1.0 - cc) * (1.0 - cc))
    if Pe < 1e-6:
        bern, dbern = 1.0 - 0.5 * Pe, -0.5
    elif Pe > 700.0:
        bern, dbern = 0.0, 0.0
    else:
        em = math.expm1(Pe)
        bern = Pe / em
        dbern = (em - Pe * (em + 1.0)) / (em * em)
    lam = 1.0 - bern                         # 0: centre value (elliptic), 1: outflow-face value
    ginv = (1.0 - lam) / d + lam / L         # 1 / effective distance
    k = cond * d * ginv
    B = k * dpg
    dk_dc = cond * d * (1.0 / L - 1.0 / d) * (-dbern) * dPe
    return B, -k, dk_dc * dpg


@nb.njit(cache=True, inline="always")
def _poiseuille_out(He, n_phi, i, side, cf, dphi, dz, omega, a_phi, p, dp, dth, g, g2, K,
                    delta, leaves_groove):
    """(P, d): the Poiseuille flux P from g2 into cell g through their face, and the
    increment of cell g's Jacobian diagonal, ``dz dP/du`` (with the factors rounded as the
    callers always did), for both assemblies: the two-point flux, or :func:`groove_exit`
    where the film leaves the groove (``leaves_groove``); ``cf`` the column terms of
    :func:`_column_terms`."""
    if leaves_groove:
        B, dBdp, dBdc = groove_exit(He, n_phi, i, side, cf[i, C_FR + side], dphi, omega,
                                    a_phi, cf[i, C_COND + side], p[g2] - p[g], dth[g], K)
        return B, dz * -1.0 * (dBdp * dp[g] - dBdc * dth[g] * (1.0 - dth[g]) / delta)
    return cf[i, C_COND + side] * (p[g2] - p[g]), cf[i, C_DZC + side] * dp[g]


@nb.njit(cache=True, nogil=True)
def _weights(wrel, frel, n_phi):
    """(column widths, east-face distances) relative to dphi: ``wrel``, ``frel`` or ones."""
    if wrel is None:
        return np.ones(n_phi), np.ones(n_phi)
    return wrel, frel


@nb.njit(cache=True, nogil=True)
def assemble(u, th_dot0, th_dot1, H, He, Hdot, groove, u_feed, omega, a_phi, a_z,
             dphi, dz, bath, p0, p_cav, K, delta, pa, pb, s_pen,
             r, want_jac, jst, p, dp, th, dth, sym, wrel=None, frel=None,
             e_out=None, l1_out=None, valid=None):
    """Residual r(u) (flat cell order) and, if ``want_jac``, the Jacobian.

    The time derivative of theta is ``th_dot0 * theta(u) + th_dot1`` (BDF
    coefficients folded in by the caller; zero for the steady equations).
    The Jacobian is stored as a 5-point stencil ``jst`` (N, 5): derivative of
    r[g] with respect to u at [centre, east (i+1), west (i-1), north (j+1),
    south (j-1)]. Couplings into groove cells are zero (their increments are
    zero), as are couplings across the axial edges.

    ``wrel``, ``frel`` (n_phi,), optional: the groove of its true width
    (:func:`.grid.groove_weights`): column widths and east-face centre distances
    relative to dphi (1 everywhere when omitted: whole-cell groove columns).
    ``e_out``, ``l1_out`` (N,), optional: receive :func:`.cavitation.law_eval`'s e and
    log1p(e) of u; ``valid``: where set, they already hold them (law_eval's ``valid``).
    """
    n_phi = H.size
    n_z = u.size // n_phi
    wr, fr = _weights(wrel, frel, n_phi)
    law_eval(u, p_cav, K, delta, p, dp, th, dth, e_out, l1_out, valid)
    cf, leaves = _column_terms(H, He, Hdot, groove, th_dot0, omega, a_phi, a_z, dphi, dz,
                               wr, fr, wrel is not None)
    up_e = omega >= 0.0
    for j in range(n_z):
        for i in range(n_phi):
            g = j * n_phi + i
            if want_jac:
                for k in range(5, jst.shape[1]):      # a wider stencil buffer: unused columns
                    jst[g, k] = 0.0
            if groove[i]:
                r[g] = u[g] - u_feed
                if want_jac:
                    jst[g, 0] = 1.0
                    for k in range(1, 5):
                        jst[g, k] = 0.0
                continue
            # time and squeeze terms (eq. 4 left/right)
            res = cf[i, C_AREA] * (cf[i, C_2H] * (th_dot0 * th[g] + th_dot1[g])
                                   + cf[i, C_2HDOT] * th[g])
            diag = cf[i, C_DIAG_T] * dth[g]
            # east face (i + 1/2) and west face (i - 1/2)
            for side in range(2):
                if side == 0:
                    i2 = i + 1 if i + 1 < n_phi else 0
                else:
                    i2 = i - 1 if i > 0 else n_phi - 1
                g2 = j * n_phi + i2
                # outward flux through this face: Couette (upwinded theta) + Poiseuille
                own_up = up_e if side == 0 else not up_e
                th_up = th[g] if own_up else th[g2]
                # where the film leaves the groove: the upwind-consistent edge flux (groove_exit)
                pq, dd = _poiseuille_out(He, n_phi, i, side, cf, dphi, dz, omega, a_phi, p, dp,
                                         dth, g, g2, K, delta, leaves[i, side])
                res += dz * (cf[i, C_SOM + side] * th_up - pq)
                diag += dd
                off = cf[i, C_MDZC + side] * dp[g2]
                if own_up:
                    diag += cf[i, C_DZSOM + side] * dth[g]
                else:
                    off += cf[i, C_DZSOM + side] * dth[g2]
                if want_jac:
                    jst[g, 1 + side] = 0.0 if groove[i2] else off
            r[g] = res
            if want_jac:
                jst[g, 0] = diag
    # north / south faces (H uniform in z)
    _axial_faces(r, jst, want_jac, cf, p, dp, groove, n_phi, n_z, p0, bath, sym, pa, pb,
                 s_pen, a_z)


#: regularisation of the limiter's denominator (theta differences are O(1) or smaller;
#: differences below ~1e-6 switch the reconstruction smoothly off)
LIM_EPS = 1.0e-24


@nb.njit(cache=True, inline="always")
def limiter(a, b):
    """Smooth TVD limiter L(a, b) and its partial derivatives (L, dL/da, dL/db).

    ``L = 2 a^2 b^2 (a + b) / ((a^2 + b^2)^2 + eps)`` for a b > 0, else 0 (module doc):
    L(a, a) = a, 0 <= L / b <= 2, 0 <= L / a <= 2, C1 at a b = 0.
    """
    ab = a * b
    if ab <= 0.0:
        return 0.0, 0.0, 0.0
    s = a * a + b * b
    d = s * s + LIM_EPS
    num = 2.0 * ab * ab * (a + b)
    L = num / d
    dn_da = 4.0 * ab * b * (a + b) + 2.0 * ab * ab
    dn_db = 4.0 * ab * a * (a + b) + 2.0 * ab * ab
    La = (dn_da - L * 4.0 * s * a) / d
    Lb = (dn_db - L * 4.0 * s * b) / d
    return L, La, Lb


@nb.njit(cache=True, inline="always")
def face_theta(th, groove, i, row, n_phi, up_e):
    """Couette theta at the east face of cell (row, i) (i + 1/2), second order
    limited (module doc), and its stencil: returns (theta_f, k_uu, k_u, k_d, d_uu,
    d_u, d_d) with the flat cells upwind-upwind, upwind, downwind and the partial
    derivatives of theta_f with respect to their theta (k_uu = -1, d_uu = 0: first
    order next to a groove cell)."""
    i2 = i + 1 if i + 1 < n_phi else 0
    if up_e:
        iu, id_ = i, i2
        iuu = i - 1 if i > 0 else n_phi - 1
    else:
        iu, id_ = i2, i
        iuu = i2 + 1 if i2 + 1 < n_phi else 0
    ku = row + iu
    if groove[i] or groove[i2]:
        return th[ku], -1, ku, -1, 0.0, 1.0, 0.0
    kuu = row + iuu
    kd = row + id_
    a = th[ku] - th[kuu]
    b = th[kd] - th[ku]
    L, La, Lb = limiter(a, b)
    return th[ku] + 0.5 * L, kuu, ku, kd, -0.5 * La, 1.0 + 0.5 * (La - Lb), 0.5 * Lb


@nb.njit(cache=True, inline="always")
def _col(k, g, n_phi):
    """Stencil column of flat cell k (same row as g) in row g's 7-point stencil:
    0 centre, 1 east, 2 west, 5 east-east, 6 west-west."""
    d = (k - g) % n_phi
    if d == 0:
        return 0
    if d == 1:
        return 1
    if d == n_phi - 1:
        return 2
    if d == 2:
        return 5
    return 6


@nb.njit(cache=True, nogil=True)
def assemble_muscl(u, th_dot0, th_dot1, H, He, Hdot, groove, u_feed, omega, a_phi, a_z,
                   dphi, dz, bath, p0, p_cav, K, delta, pa, pb, s_pen,
                   r, want_jac, jst, p, dp, th, dth, sym, wrel=None, frel=None,
                   e_out=None, l1_out=None, valid=None):
    """:func:`assemble` with the limited second-order Couette transport of theta
    (``theta_transport = 1``, module doc). Same arguments; ``jst`` is (N, 7): the
    5-point columns of :func:`assemble` plus [east-east (i+2), west-west (i-2)]."""
    n_phi = H.size
    n_z = u.size // n_phi
    wr, fr = _weights(wrel, frel, n_phi)
    law_eval(u, p_cav, K, delta, p, dp, th, dth, e_out, l1_out, valid)
    cf, leaves = _column_terms(H, He, Hdot, groove, th_dot0, omega, a_phi, a_z, dphi, dz,
                               wr, fr, wrel is not None)
    up_e = omega >= 0.0
    # the east face of each column of a row, once: the cells on both sides of a face read it
    # (face_theta is a function of theta alone, so the values are those each cell computed
    # for itself before, bit for bit; half the limiter evaluations, issue 16 speed)
    f_th = np.empty(n_phi)
    f_k = np.empty((n_phi, 3), dtype=np.int64)
    f_d = np.empty((n_phi, 3))
    for j in range(n_z):
        row = j * n_phi
        for fi in range(n_phi):
            thf, k1, k2, k3, d1, d2, d3 = face_theta(th, groove, fi, row, n_phi, up_e)
            f_th[fi] = thf
            f_k[fi, 0], f_k[fi, 1], f_k[fi, 2] = k1, k2, k3
            f_d[fi, 0], f_d[fi, 1], f_d[fi, 2] = d1, d2, d3
        for i in range(n_phi):
            g = row + i
            if want_jac:
                for k in range(1, jst.shape[1]):
                    jst[g, k] = 0.0
            if groove[i]:
                r[g] = u[g] - u_feed
                if want_jac:
                    jst[g, 0] = 1.0
                continue
            res = cf[i, C_AREA] * (cf[i, C_2H] * (th_dot0 * th[g] + th_dot1[g])
                                   + cf[i, C_2HDOT] * th[g])
            diag = cf[i, C_DIAG_T] * dth[g]
            for side in range(2):
                if side == 0:
                    i2 = i + 1 if i + 1 < n_phi else 0
                    fi = i
                else:
                    i2 = i - 1 if i > 0 else n_phi - 1
                    fi = i2
                g2 = row + i2
                thf = f_th[fi]
                k1, k2, k3 = f_k[fi, 0], f_k[fi, 1], f_k[fi, 2]
                d1, d2, d3 = f_d[fi, 0], f_d[fi, 1], f_d[fi, 2]
                # where the film leaves the groove: the upwind-consistent edge flux (groove_exit)
                pq, dd = _poiseuille_out(He, n_phi, i, side, cf, dphi, dz, omega, a_phi, p, dp,
                                         dth, g, g2, K, delta, leaves[i, side])
                res += dz * (cf[i, C_SOM + side] * thf - pq)
                diag += dd
                if want_jac:
                    if not groove[i2]:
                        jst[g, 1 + side] += cf[i, C_MDZC + side] * dp[g2]
                    cfs = cf[i, C_DZSOM + side]
                    for kk, dk in ((k1, d1), (k2, d2), (k3, d3)):
                        if kk >= 0 and dk != 0.0 and not groove[kk - row]:
                            col = _col(kk, g, n_phi)
                            if col == 0:
                                diag += cfs * dk * dth[kk]
                            else:
                                jst[g, col] += cfs * dk * dth[kk]
            r[g] = res
            if want_jac:
                jst[g, 0] = diag
    # north / south faces (H uniform in z)
    _axial_faces(r, jst, want_jac, cf, p, dp, groove, n_phi, n_z, p0, bath, sym, pa, pb,
                 s_pen, a_z)


@nb.njit(cache=True, inline="always")
def _neighbours(g, n_phi, n_z):
    i = g % n_phi
    j = g // n_phi
    e = j * n_phi + (i + 1 if i + 1 < n_phi else 0)
    w = j * n_phi + (i - 1 if i > 0 else n_phi - 1)
    nn = g + n_phi if j + 1 < n_z else -1
    ss = g - n_phi if j > 0 else -1
    return e, w, nn, ss


@nb.njit(cache=True, inline="always")
def _neighbours2(g, n_phi):
    """Flat cells i + 2 and i - 2 (periodic) of cell g."""
    i = g % n_phi
    row = g - i
    return row + (i + 2) % n_phi, row + (i - 2) % n_phi


@nb.njit(cache=True, nogil=True)
def stencil_to_band(jst, n_phi, pos, bw, ab):
    """Scatter the stencil (5 or 7 columns) into LAPACK band storage (entry (g, g2) at
    ``ab[2 bw + pos[g] - pos[g2], pos[g2]]``, shape (3 bw + 1, N)); ``ab``
    must be zeroed by the caller (a memset in numpy is faster)."""
    stencil_rows_to_band(jst, n_phi, pos, bw, ab, 0)


@nb.njit(cache=True, nogil=True)
def stencil_rows_to_band(jst, n_phi, pos, bw, ab, row_from):
    """:func:`stencil_to_band` for the rows at band positions ``>= row_from`` only (the
    partial refactorisation of :func:`.solver.refactor_partial`); their entries in ``ab``
    must be zero."""
    n = jst.shape[0]
    n_z = n // n_phi
    for g in range(n):
        pg = pos[g]
        if pg < row_from:
            continue
        e, w, nn, ss = _neighbours(g, n_phi, n_z)
        ab[2 * bw, pg] += jst[g, 0]
        nb_ = (e, w, nn, ss)
        for k in range(4):
            g2 = nb_[k]
            if g2 >= 0 and jst[g, 1 + k] != 0.0:
                ab[2 * bw + pg - pos[g2], pos[g2]] += jst[g, 1 + k]
        if jst.shape[1] > 5:           # 7-point stencil (theta_transport = 1): i + 2, i - 2
            ee, ww = _neighbours2(g, n_phi)
            if jst[g, 5] != 0.0:
                ab[2 * bw + pg - pos[ee], pos[ee]] += jst[g, 5]
            if jst[g, 6] != 0.0:
                ab[2 * bw + pg - pos[ww], pos[ww]] += jst[g, 6]


@nb.njit(cache=True, nogil=True)
def stencil_matvec(jst, n_phi, x, y):
    """y = J x for the stencil Jacobian (5 or 7 columns)."""
    n = jst.shape[0]
    n_z = n // n_phi
    for g in range(n):
        e, w, nn, ss = _neighbours(g, n_phi, n_z)
        v = jst[g, 0] * x[g] + jst[g, 1] * x[e] + jst[g, 2] * x[w]
        if nn >= 0:
            v += jst[g, 3] * x[nn]
        if ss >= 0:
            v += jst[g, 4] * x[ss]
        if jst.shape[1] > 5:
            ee, ww = _neighbours2(g, n_phi)
            v += jst[g, 5] * x[ee] + jst[g, 6] * x[ww]
        y[g] = v


@nb.njit(cache=True, nogil=True)
def integrals(p, th, H, He, groove, phi, omega, a_phi, a_z, dphi, dz, bath, p0,
              pa, pb, s_pen, R, B, c, eta0, sym, order=0, wrel=None, frel=None,
              delta=1.0, K=0.0):
    """Film force on the journal, torque on the journal, feed and side flows.

    Returns (Fx, Fy, torque, q_feed, q_side):

    * ``F = -int (p - p0) (cos phi, sin phi) R dphi B dzbar`` (midpoint rule);
    * torque about +z ON the journal from the wall shear at the journal
      surface, ``tau = theta eta0 omega R / h + (h / 2) dp/(R dphi)`` (eta =
      theta eta0 by eq. 3), evaluated at the phi-faces with the upwind theta
      of the Couette flux (``order`` = theta_transport: 0 upwind, 1 the limited
      face value of :func:`face_theta`, as in the residual); ``T = -R int tau R dphi B dzbar``;
    * ``q_feed`` volume flow leaving the groove columns into the film and
      ``q_side`` the net outflow through both axial edges [m^3/s], both from
      the discrete fluxes times ``R c B / 2`` (the scale between eq. 2 fluxes
      and volume flows).

    ``sym``: the fields are the lower half of a film symmetric about the
    mid-plane; every integral is doubled and only the zbar = 0 edge is an edge.
    ``wrel``, ``frel``: the true-width groove weights of :func:`assemble` (the force and
    side flow weight each column by its width, the face fluxes use the face distances).
    """
    n_phi = H.size
    n_z = p.size // n_phi
    wr, fr = _weights(wrel, frel, n_phi)
    Fx = 0.0
    Fy = 0.0
    T = 0.0
    qf = 0.0
    qs = 0.0
    up_e = omega >= 0.0
    for i in range(n_phi):
        cs = math.cos(phi[i])
        sn = math.sin(phi[i])
        i2 = i + 1 if i + 1 < n_phi else 0
        Hf = He[i]
        cond = a_phi * Hf * Hf * Hf / (dphi * fr[i])
        condz = a_z * H[i] ** 3 / dz
        wi = wr[i]
        for j in range(n_z):
            g = j * n_phi + i
            g2 = j * n_phi + i2
            Fx -= (p[g] - p0) * cs * wi
            Fy -= (p[g] - p0) * sn * wi
            if order == 0:
                th_up = th[g] if up_e else th[g2]
            else:
                th_up = face_theta(th, groove, i, j * n_phi, n_phi, up_e)[0]
            T += th_up * eta0 * omega * R / (c * Hf) + 0.5 * c * Hf * (p[g2] - p[g]) / (R * dphi * fr[i])
            if groove[i] != groove[i2]:
                if wrel is not None and K > 0.0 and groove[i] == up_e:
                    # the film leaves the groove: the edge flux of assemble (groove_exit)
                    gf, gg, side = (g2, g, 1) if groove[i] else (g, g2, 0)
                    cf = -math.expm1(-(1.0 - th[gf]) / delta)     # dtheta/du of the film cell
                    Bq = groove_exit(He, n_phi, gf % n_phi, side, fr[i], dphi, omega, a_phi,
                                     cond, p[gg] - p[gf], cf, K)[0]
                    flux = omega * Hf * th_up + (Bq if groove[i] else -Bq)
                else:
                    flux = omega * Hf * th_up - cond * (p[g2] - p[g])
                qf += flux if groove[i] else -flux
            n_edge = (j == 0) + (j == n_z - 1 and not sym)
            if not groove[i] and n_edge > 0:
                if bath:
                    qs += n_edge * 2.0 * condz * (p[g] - p0) * wi
                else:
                    gv, dgv = penalty_edge(p[g] - p0, 2.0 * condz, pa, pb, s_pen, a_z)
                    qs += n_edge * gv * wi
    area = R * dphi * B * dz
    scale = 0.5 * R * c * B
    if sym:
        area *= 2.0
        scale *= 2.0
    return (Fx * area, Fy * area, -R * T * area, qf * scale * dz, qs * scale * dphi)


@nb.njit(cache=True, inline="always")
def _half_cell_pos(a, m):
    """Mean of max(L, 0) and the fraction where L > 0 over a half cell on which L is
    linear from ``a`` (cell centre) to ``m`` (face)."""
    if a >= 0.0 and m >= 0.0:
        return 0.5 * (a + m), 1.0
    if a <= 0.0 and m <= 0.0:
        return 0.0, 0.0
    mx = a if a > m else m
    d = abs(a - m)
    return 0.5 * mx * mx / d, mx / d


@nb.njit(cache=True, nogil=True)
def hs_force_pressure(P, out):
    """Cell pressures for the half-Sommerfeld FORCE integral from the unclipped gauge
    pressure ``P`` (n_z, n_phi), into ``out``.

    The half-Sommerfeld pressure is ``max(P, 0)``. With the midpoint rule on the
    clipped cell values the rupture line is resolved to whole cells: the force is
    second order, but as the journal moves cells switch in and out of the positive
    set and its derivatives (the dynamic coefficients) carry an O(h) error that
    jumps with the grid (measured 1-3 % at 40 x 40, orders -0.8 ... 1.2;
    docs/bearing-validation.md). Here P is taken piecewise linear in phi within each
    cell (centre value to the face mean on either side) and each cell gets

        out = <max(L, 0)> + (P - <L>) * f+,

    ``<.>`` the cell mean, ``f+`` the positive fraction of the cell. In the full film
    (L > 0 over the cell) this is exactly P, in the cavitated region (L <= 0) exactly
    0; across the rupture it is continuous in P and locates the zero crossing inside
    the cell (the ``(P - <L>) f+`` term keeps the full-film value P, so the
    midpoint quadrature of the full film is unchanged). Measured (Jeffcott bearing,
    eps 0.19, 20 ... 320 cells): force and the 8 coefficients converge at order 2.
    """
    n_z, n_phi = P.shape
    for j in range(n_z):
        for i in range(n_phi):
            pc = P[j, i]
            pw = P[j, i - 1 if i > 0 else n_phi - 1]
            pe = P[j, i + 1 if i + 1 < n_phi else 0]
            if pc > 0.0 and pw > 0.0 and pe > 0.0:
                out[j, i] = pc
                continue
            if pc <= 0.0 and pw <= 0.0 and pe <= 0.0:
                out[j, i] = 0.0
                continue
            v1, f1 = _half_cell_pos(pc, 0.5 * (pc + pw))
            v2, f2 = _half_cell_pos(pc, 0.5 * (pc + pe))
            mean_pos = 0.5 * (v1 + v2)
            frac = 0.5 * (f1 + f2)
            mean_lin = 0.75 * pc + 0.125 * (pw + pe)
            out[j, i] = mean_pos + (pc - mean_lin) * frac
