"""Prototype: the free-rupture defect correction of docs/scripts/reformation_front_1d.py
(``rupture_correction``) in the 2-D steady free-to-air film, per row, on top of the exit-layer
correction of exit_layer_2d.py (issue 16 item 2). A study script, NOT a library option: it
patches one BearingModel instance's film residual; the solver's defaults are untouched.

The bearing, journal position and Newton tolerances are those of grid_convergence.py ``air``
(Jeffcott run-up bearing, 15 deg groove at 90 deg, 250 Hz; the minimum gap at -10.4 deg, the
full film ruptures freely after it). Per grid:

1. the film with the exit-layer correction (exit_layer_2d.exit_corrected) is solved;
2. per row j, the circumferential flux through the cavity, q_j (per unit width, at the east
   face of the column nearest 50 deg: in the cavity between the rupture and the groove on
   every row, where p is flat and q_j is constant along the row), the film's own face flux
   (with ``theta_transport = 1`` the limited face value of theta: the upwind cell value is
   off by O(h) there, 1.3 % at 40 x 40, and put phi_r up to 14 deg late until 2026-12-07);
3. per row, the rupture's local 1-D problem given q_j (reformation_front_1d.rupture_layer's
   construction with the circumferential conductance a_phi, the axial flow left out): phi_r
   from ``omega H(phi_r) = q_j``, the gap linearised there, the window ``max(2 h, 8 ell)``;
   per phi face of the row ``Delta = w (q_j - F(u_R))``, the scheme's face flux (film.py:
   upwind or limited theta, two-point Poiseuille) on the local profile, with a weight w that
   is 1 inside the window and falls linearly to 0 over the next cell (a hard window made the
   iteration below cycle between two face sets at 40 x 40);
4. the residual of each film cell of the row gains ``dz (Delta_east - Delta_west)`` (mass
   exact, Jacobian unchanged), the film is solved again (warm), q_j updated by substitution
   until it changes by < 1e-11 relative (4 to 25 solves; the per-row secant of the 1-D script
   cycled here). q_j is the flux the corrected film conserves: where the face at 50 deg lies
   inside the window (20 x 20 only) its Delta is added (before 2026-12-07 it was not: 60
   solves to 1.1e-10 and phi_r 24 deg at mid-width on 20 x 20 with upwind theta).

Run: ``nice -n 10 .venv/bin/python docs/scripts/free_rupture_2d.py [square] [phi] [axial]
[shift]`` (``square``: 20 ... 160 square grids, about 6 minutes; ``phi``: n_phi 48 ... 384 at
n_z = 40, about 3 minutes; ``axial``: n_z 20 ... 80 at n_phi = 96, about 2 minutes;
``shift``: 40 and 80 x 40 with the grid shifted by 0.1 ... 0.9 cells as in exit_layer_2d.py
``shift``, about 8 minutes; ``sectors``: where the 40 x 40 shifted films' Fx error sits, per
phi sector, against 768 x 40, about 6 minutes; ``stiffness``: force and the four stiffness
coefficients on 20 ... 160 square grids, central differences of positions +- 1e-3 c, each
perturbed state warm from the base state, about 20 minutes; ``flux``: the rows' cavity flux
of the exit-corrected films, the film's face flux against the upwind formula, both transports,
square grids and n_phi 48 ... 768 at n_z = 40, about 5 minutes). Markdown tables of Fx, Fy,
exit correction only and with the rupture correction. ``--tt 1``: the films with the limited
second-order theta transport (as exit_layer_2d.py); ``--upwind-q``: q_j from the upwind cell
value of theta whatever the transport (the old formula, to reproduce its numbers).

``--front {sw,ghost,cut}`` (2026-12-07 fourth session, :func:`front_correction`): a treatment
of the reformation front's axial faces inside the Newton system (the residual and its
Jacobian, less the entries outside the band); ``--no-ramp``: sw / ghost without the C1 ramp.
The session's drivers: ``front_probe_2d.py`` (per-row front on the shifted 40 x 40 films),
``front_shift_nz.py`` and ``front_shift40.py`` (shift spreads), ``front_square.py`` (square
grids with a front treatment).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.special import expit

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import exit_layer_2d as el  # noqa: E402
import grid_convergence as gc  # noqa: E402
import reformation_front_1d as rf  # noqa: E402
from bearing_fmu.film import face_theta, limiter  # noqa: E402
from bearing_fmu.linearize import _force  # noqa: E402
from bearing_fmu.model import BearingModel  # noqa: E402

#: where the rows' cavity flux is taken [deg, physical]
Q_DEG = 50.0
#: True: the rows' cavity flux from the upwind cell value of theta whatever the transport (the
#: prototype before 2026-12-07; ``--upwind-q``, to reproduce its theta_transport 1 numbers)
UPWIND_Q = False
#: True: the rows' cavity flux at Q_DEG includes the rupture correction Delta of that face (the
#: flux the corrected film conserves); False (``--q-without-delta``, the prototype before
#: 2026-12-07): the film's face flux alone, which differs where the face lies inside the
#: window (20 x 20: the window reaches ~70 deg)
Q_WITH_DELTA = True
#: window half width in units of the soft rupture's width ell, and at least MIN_CELLS cells
N_LEN = 8.0
MIN_CELLS = 2.0
#: ``--front``: the ghost-fluid treatment of the reformation front's axial faces
#: (:func:`front_correction`, 2026-12-07 fourth session); None = off
FRONT = None
#: the columns where it applies [deg, physical]: around the reformation front only
FRONT_DEG = (150.0, 290.0)
#: where the front treatment takes the rows' cavity flux [deg, physical]: after the groove
#: (which feeds the cavity, so q_j at Q_DEG is not the flux that reaches the front)
FRONT_Q_DEG = 150.0
#: blend the front treatment in over P's distance to the front (C1 ramp over one cell)
RAMP = True
#: sw-lag: the frozen s relaxed as s <- (1 - DAMP) s_new + DAMP s_old (same face set)
DAMP = 0.0


def front_args(argv: list[str], *options: str) -> list[str]:
    """The front treatment's options a driver script takes (``options``: of "--front" (NAME: FRONT)
    and "--no-ramp" (RAMP false)), set from ``argv``; returns the rest of argv."""
    global FRONT, RAMP
    argv = list(argv)
    if "--front" in options and "--front" in argv:
        k = argv.index("--front")
        FRONT = argv[k + 1]
        del argv[k:k + 2]
    if "--no-ramp" in options and "--no-ramp" in argv:
        RAMP = False
        argv.remove("--no-ramp")
    return argv


#: floor of the ghost-fluid distance fraction s (a priori, not tuned)
S_MIN = 1e-2


def row_layer(b, xy, omega, q, margin):
    """The rupture's local problem of one row with cavity flux q: (u(phi), phi_r, W, H)."""
    x, y = xy
    law = b.law

    def gap(phi):
        return 1.0 - (x * np.cos(phi) + y * np.sin(phi)) / b.c
    phi_min = math.atan2(y, x)
    phi_r = brentq(lambda p: omega * gap(p) - q, phi_min + 1e-9, phi_min + math.pi - 1e-6,
                   xtol=1e-15)
    Hr = float(gap(phi_r))
    dH = (x * math.sin(phi_r) - y * math.cos(phi_r)) / b.c
    A = omega * dH / (2 * b.a_phi * Hr ** 3)
    W = max(MIN_CELLS * margin / 3, N_LEN * math.sqrt(law.K * law.delta / A))

    def H(p):
        return Hr + dH * (p - phi_r)
    x_far, x_near = phi_r + W + margin, phi_r - W - margin
    target = q / (omega * float(H(x_far)))
    u_far = brentq(lambda v: rf.evaluate(np.array([v]), law)[2][0] - target, -5.0, 1e3,
                   xtol=1e-14)
    rhs, jac = rf._ode(H, b.a_phi, omega, law)
    r = solve_ivp(rhs, (x_far, x_near), [u_far], method="Radau", args=(q,), rtol=rf.RTOL,
                  atol=0.1 * rf.RTOL, dense_output=True, jac=jac)
    return (lambda p: r.sol(np.clip(p, x_near, x_far))[0]), phi_r, W, H


def rupture_correction(b, xy, omega, q_rows):
    """(n,) residual correction of the film for the rows' cavity fluxes q_rows, per row
    (phi_r [deg], corrected faces), and the (n_z, n_phi) face corrections Delta (east face of
    each column); rows from the edge (0) to the mid-width (the film holds the symmetric
    half)."""
    g = b.grid
    n_phi, h = g.n_phi, g.dphi
    muscl = b.params.theta_transport == 1
    corr = np.zeros((g.n_z, n_phi))
    deltas = np.zeros((g.n_z, n_phi))
    info = []
    for j in range(g.n_z):
        sol, phi_r, W, H = row_layer(b, xy, omega, q_rows[j], 3 * h)
        d = (g.phi - phi_r + math.pi) % (2 * math.pi) - math.pi
        wt = np.clip((W + h - np.abs(d + 0.5 * h)) / h, 0.0, 1.0)      # east face of column i
        p, _, th, _ = rf.evaluate(sol(phi_r + d), b.law)
        delta = np.zeros(n_phi)
        for i in np.flatnonzero(wt > 0.0):
            e, w = (i + 1) % n_phi, (i - 1) % n_phi
            He = float(H(phi_r + d[i] + 0.5 * h))
            thf = th[i] + 0.5 * limiter(th[i] - th[w], th[e] - th[i])[0] if muscl else th[i]
            F = omega * He * thf - b.a_phi * He ** 3 * (p[e] - p[i]) / (g.frel[i] * h)
            delta[i] = wt[i] * (q_rows[j] - F)
        corr[j] = g.dz * (delta - np.roll(delta, 1))
        deltas[j] = delta
        info.append((math.degrees(phi_r), int(np.count_nonzero(delta))))
    return corr.ravel(), info, deltas


def front_correction(b, u, kin, q_rows, alpha, want_jac, mode=None):
    """The reformation front's axial faces as a ghost-fluid (Shortley-Weller) Dirichlet
    condition at the front (2026-12-07 fourth session).

    Per cell the fill indicator ``c = (theta - theta_c) / (1 - theta_c)``, theta_c = q_j /
    (omega H_e) the cavity's theta of the row (q_j the rows' cavity flux after the groove, at
    FRONT_Q_DEG, lagged like the rupture correction's q_j): 0 in the cavity, 1 in the full
    film, the front cell F's fill fraction f in between (the upwind F|E face carries the
    gradient of a full film whose front lies f h before E's centre). Per row the signed
    distance to the front along phi, ``phi_ji = h (c_{i-1} + c_i - 1)``: f h at E, -(1 - f) h
    at F (exact for both), -h / +h deeper in the cavity / full film. On an axial face between
    a cell P with phi > 0 and a cell C with phi <= 0 (a step of the front's staircase, where
    the film puts the front at C's centre) the front crosses the face's column at the
    fraction ``s = phi_P / (phi_P - phi_C)`` of the centre distance from P, and the face's
    Poiseuille flux becomes (FRONT "sw") ``a_z H^3 (p_P - p_C) / (s dz)`` (s >= S_MIN; C's
    own pressure as the front's), or (FRONT "ghost") ``a_z H^3 (p_P - p_g) / dz`` with C's
    ghost pressure ``p_g = p_cav + G phi_C``, the full film extended across the front with
    the jump condition's gradient ``G = omega (1 - theta_c) / (a_phi H^2)`` (front normal
    along phi). Both blended in by the C1 ramp ``rho = x^2 (3 - 2 x)``, x = min(phi_P / h, 1)
    (the flux field itself jumps where P's centre crosses the front; the ramp keeps Newton's
    residual continuous). One flux per face, both cells (mass exact). Returns (dr (n,),
    Jacobian entries [(row g, column g2, value)], with the derivatives through phi)."""
    mode = FRONT if mode is None else mode
    g = b.grid
    n_phi, n_z = g.n_phi, g.n_z
    law = b.law
    p, th = law.p_theta(u)
    dp = law.K * expit(u / law.delta)                      # dp/du, as law_eval
    dth = expit(-u / law.delta)                            # dtheta/du
    p, th, dp, dth = (a.reshape(n_z, n_phi) for a in (p, th, dp, dth))
    He, om = kin[1], kin[3]
    H = kin[0]
    thc = np.clip(q_rows[:, None] / (om * He[None, :]), 0.0, 0.999)
    c = (th - thc) / (1.0 - thc)
    dc = dth / (1.0 - thc)
    h = g.dphi
    phi = h * (np.roll(c, 1, axis=1) + c - 1.0)
    deg = np.degrees((g.phi - alpha) % (2 * math.pi))
    colmask = (deg >= FRONT_DEG[0]) & (deg <= FRONT_DEG[1]) & ~g.groove
    wr = g.wrel if g.wrel is not None else np.ones(n_phi)
    pos_ = phi > 0.0
    if mode == "sw-lag":       # the staircase faces and s frozen from the outer iteration
        dr = np.zeros((n_z, n_phi))
        jac = []
        for jp, jc, i, s in front_correction.frozen:
            cz = g.dphi * wr[i] * b.a_z * H[i] ** 3 / g.dz
            k = 1.0 / s - 1.0
            d = cz * (p[jp, i] - p[jc, i]) * k
            dr[jp, i] += d
            dr[jc, i] -= d
            if want_jac:
                for (jr, v) in ((jp, cz * k * dp[jp, i]), (jc, -cz * k * dp[jc, i])):
                    jac.append((jp * n_phi + i, jr * n_phi + i, v))
                    jac.append((jc * n_phi + i, jr * n_phi + i, -v))
        return dr.ravel(), jac
    if mode == "geometry":     # (jp, jc, i, s) of the staircase faces, for sw-lag
        jj, ii = np.nonzero((pos_[:-1] != pos_[1:]) & colmask[None, :])
        out = []
        for j, i in zip(jj, ii):
            jp, jc = (j, j + 1) if pos_[j, i] else (j + 1, j)
            out.append((jp, jc, i, max(phi[jp, i] / (phi[jp, i] - phi[jc, i]), S_MIN)))
        return out
    if mode == "cut":
        return _front_cut(b, g, law, p, dp, dc, thc, phi, colmask, wr, H, om, h, want_jac)
    jj, ii = np.nonzero((pos_[:-1] != pos_[1:]) & colmask[None, :])
    dr = np.zeros((n_z, n_phi))
    jac = []
    info = []
    for j, i in zip(jj, ii):
        cz = g.dphi * wr[i] * b.a_z * H[i] ** 3 / g.dz
        jp, jc = (j, j + 1) if pos_[j, i] else (j + 1, j)
        fp, fc = phi[jp, i], phi[jc, i]
        if mode == "sw":       # Dirichlet at the front crossing (Shortley-Weller), 1/s
            s0 = fp / (fp - fc)
            s = max(s0, S_MIN)
            dpp = p[jp, i] - p[jc, i]
            ext = dpp * (1.0 / s - 1.0)
            d_ext = {(jp, i): dp[jp, i] * (1.0 / s - 1.0), (jc, i): -dp[jc, i] * (1.0 / s - 1.0)}
            if s0 >= S_MIN:     # through s (phi_P, phi_C)
                den = (fp - fc) ** 2
                for jr, ds in ((jp, -fc / den), (jc, fp / den)):
                    for k in ((i - 1) % n_phi, i):
                        d_ext[(jr, k)] = d_ext.get((jr, k), 0.0) - dpp / s ** 2 * ds * h * dc[jr, k]
        else:                   # "ghost": C's ghost pressure p_cav + G phi_C, G from the jump
            G = om * (1.0 - thc[jc, i]) / (b.a_phi * H[i] ** 2)
            ext = p[jc, i] - (law.p_cav + G * fc)
            im = (i - 1) % n_phi
            d_ext = {(jc, i): dp[jc, i] - G * h * dc[jc, i], (jc, im): -G * h * dc[jc, im]}
        x = min(fp / h, 1.0)
        if RAMP:
            rho = x * x * (3.0 - 2.0 * x)                  # C1 ramp over P's distance
            drho = 6.0 * x * (1.0 - x) / h if x < 1.0 else 0.0
        else:
            rho, drho = 1.0, 0.0
        d = cz * rho * ext                                  # extra outflow P -> C
        dr[jp, i] += d
        dr[jc, i] -= d
        info.append((jp, jc, i, fp / h, fc / h, rho, d))
        if want_jac:
            ent = {k: cz * rho * v for k, v in d_ext.items()}
            for k in ((jp, (i - 1) % n_phi), (jp, i)):       # through rho (phi_P)
                ent[k] = ent.get(k, 0.0) + cz * ext * drho * h * dc[k]
            for (jr, k), v in ent.items():
                jac.append((jp * n_phi + i, jr * n_phi + k, v))
                jac.append((jc * n_phi + i, jr * n_phi + k, -v))
    front_correction.last = info
    return dr.ravel(), jac


def _front_cut(b, g, law, p, dp, dc, thc, phi, colmask, wr, H, om, h, want_jac):
    """FRONT "cut": every axial face near the front as a cut face with ghost pressures.

    The face between rows j and j + 1 of column i spans phi_i +- h / 2; the front crosses the
    face's level at the mean of the two rows' front places, so the part of the face on the
    full side is the aperture ``A = clip(1/2 + (phi_a + phi_b) / (2 h), 0, 1)``. The face flux
    is ``A a_z H^3 (p~_a - p~_b) / dz`` with p~ = p on the full side (phi >= 0) and the ghost
    pressure ``p + G phi`` on the cavity side (the full film extended across the front with
    the jump condition's gradient G = omega (1 - theta_c) / (a_phi H^2), from the cell's own
    p, p_cav up to the law's soft part: with p_cav instead the flux jumped by the soft part,
    ~1 kPa, where a centre crossed the front, and Newton stalled). Continuous as the front
    moves: A -> 0 as it leaves the face, and at phi = 0 the ghost is the cell's p. Deep in the
    full film A = 1 and p~ = p: the film's own flux. One flux per face, both cells."""
    n_z, n_phi = p.shape
    Gc = om * (1.0 - thc) / (b.a_phi * H[None, :] ** 2)
    t = 0.5 + (phi[:-1] + phi[1:]) / (2.0 * h)
    act = (t < 1.0) & (t > 0.0) & colmask[None, :]
    act |= ((phi[:-1] < 0.0) != (phi[1:] < 0.0)) & colmask[None, :]
    jj, ii = np.nonzero(act)
    dr = np.zeros((n_z, n_phi))
    jac = []
    info = []
    for j, i in zip(jj, ii):
        cz = g.dphi * wr[i] * b.a_z * H[i] ** 3 / g.dz
        A = min(max(t[j, i], 0.0), 1.0)
        dA = 1.0 / (2.0 * h) if 0.0 < t[j, i] < 1.0 else 0.0
        im = (i - 1) % n_phi
        pt, dpt = [], []
        for r_ in (j, j + 1):
            if phi[r_, i] >= 0.0:
                pt.append(p[r_, i])
                dpt.append({(r_, i): dp[r_, i]})
            else:
                G = Gc[r_, i]
                pt.append(p[r_, i] + G * phi[r_, i])
                dpt.append({(r_, im): G * h * dc[r_, im], (r_, i): G * h * dc[r_, i] + dp[r_, i]})
        d = cz * (A * (pt[0] - pt[1]) - (p[j, i] - p[j + 1, i]))     # extra outflow j -> j+1
        dr[j, i] += d
        dr[j + 1, i] -= d
        info.append((j, i, phi[j, i] / h, phi[j + 1, i] / h, A, d))
        if want_jac:
            ent = {(j, i): -cz * dp[j, i], (j + 1, i): cz * dp[j + 1, i]}
            for k, v in dpt[0].items():
                ent[k] = ent.get(k, 0.0) + cz * A * v
            for k, v in dpt[1].items():
                ent[k] = ent.get(k, 0.0) - cz * A * v
            if dA:
                for r_ in (j, j + 1):
                    for k in (im, i):
                        ent[(r_, k)] = ent.get((r_, k), 0.0) + cz * (pt[0] - pt[1]) * dA * h * dc[r_, k]
            for (jr, k), v in ent.items():
                jac.append((j * n_phi + i, jr * n_phi + k, v))
                jac.append(((j + 1) * n_phi + i, jr * n_phi + k, -v))
    front_correction.last = info
    return dr.ravel(), jac


def row_flux(b, u, kin, alpha=0.0, deg=None, scheme=None, delta=None):
    """Per row the circumferential flux per unit width at the east face of the column nearest
    ``deg`` (default Q_DEG; physical angle; the grid rotated by alpha): the film's own face
    flux, i.e. with ``theta_transport = 1`` the limited face value of theta (film.py
    ``face_theta``), the flux that the scheme conserves along the row. ``scheme=False``: the
    upwind cell value whatever the transport (the prototype's formula before 2026-12-07,
    kept for the ``flux`` part; with ``theta_transport = 1`` it is not the film's flux).
    ``delta``: the rupture correction's (n_z, n_phi) face terms, added at that face."""
    g = b.grid
    p, th_flat = b.law.p_theta(u)
    p, th = p.reshape(g.n_z, g.n_phi), th_flat.reshape(g.n_z, g.n_phi)
    He, om = kin[1], kin[3]
    deg = Q_DEG if deg is None else deg
    i = int(np.argmin(np.abs((g.phi - math.radians(deg) - alpha + math.pi) % (2 * math.pi)
                             - math.pi)))
    if np.any(th[:, i] >= 0.999):
        raise RuntimeError(f"column at {deg} deg not in the cavity on every row")
    if scheme is None:
        scheme = not UPWIND_Q
    if scheme and b.params.theta_transport == 1:
        thf = np.array([face_theta(th_flat, g.groove, i, j * g.n_phi, g.n_phi, om >= 0.0)[0]
                        for j in range(g.n_z)])
    else:
        thf = th[:, i]
    q = om * He[i] * thf - b.a_phi * He[i] ** 3 * (p[:, (i + 1) % g.n_phi] - p[:, i]) / (
        g.frel[i] * g.dphi)
    return q if delta is None else q + delta[:, i]


class Film:
    """One BearingModel with the exit-layer correction and a slot for the rupture correction in
    its film residual (groove and journal frame rotated by alpha)."""

    def __init__(self, n_phi, n_z, omega, alpha=0.0):
        prm = gc.params("air", n_phi, n_z, **el.TT)
        if alpha:
            prm = prm.replace(groove_angle=prm.groove_angle + alpha)
        self.b = b = BearingModel(prm)
        self.omega, self.alpha = omega, alpha
        self.prepare = el.exit_corrected(b, True)
        self.box = {"corr": np.zeros(b.grid.n_phi * b.grid.n_z), "q": None}   # symmetric half
        with_exit = b.film.residual
        self.newton_its = []
        self.geoms = []

        def residual(u, th_dot0, th_dot1, kin, want_jac=False):
            r = with_exit(u, th_dot0, th_dot1, kin, want_jac=want_jac)
            r += self.box["corr"]
            if FRONT and self.box["q"] is not None:
                dr, jac = front_correction(b, u, kin, self.box["q"], alpha, want_jac)
                r += dr
                if want_jac:
                    self.box["jac"] = jac
            elif want_jac:
                self.box["jac"] = []
            return r
        b.film.residual = residual
        scatter = b.film._scatter
        self.box["jac"] = []
        self.box["dropped"] = 0

        def scatter_front():
            """The stencil's band, plus the front treatment's entries that lie in the band
            (those outside it are dropped and counted)."""
            scatter()
            g = b.grid
            ab, pos, bw = b.film.ab, g.pos, g.bw
            for r_, c_, v in self.box["jac"]:
                dpos = pos[r_] - pos[c_]
                if abs(dpos) <= bw:
                    ab[2 * bw + dpos, pos[c_]] += v
                else:
                    self.box["dropped"] += 1
        b.film._scatter = scatter_front

    def steady(self, xy, rupture, u0=None, q0=None, max_iter=60):
        """(u, kin, substitutions, per-row info, q) of the steady film at the journal position
        xy: cold (``init="stationary"``) or warm from u0 (and q0, the rows' cavity fluxes)."""
        b = self.b
        kin = b._kinematics(xy[0], xy[1], 0.0, 0.0, self.omega)
        self.prepare(kin, (xy[0], xy[1], 0.0, 0.0))
        self.box["corr"][:] = 0.0
        zero = np.zeros_like(self.box["corr"])
        if u0 is None:
            b.initialize(xy[0], xy[1], 0.0, 0.0, self.omega, init="stationary")
            u = b.film.u.copy()
        else:           # as grid_convergence.py mc_quantities: a warm Newton, else the cold path
            u, _ = b._steady_newton(kin, u0, zero, 40)
            if u is None:
                u = b._steady(kin, u0)
        its, info, q = 0, None, None
        if rupture:
            q = row_flux(b, u, kin, self.alpha) if q0 is None else q0.copy()
            qf = row_flux(b, u, kin, self.alpha, deg=FRONT_Q_DEG) if FRONT else None
            geom = None
            for its in range(1, max_iter + 1):
                if FRONT == "sw-lag":       # freeze the staircase's faces and s from this u
                    new = front_correction(b, u, kin, qf, self.alpha, False, mode="geometry")
                    dgeom = (0.0 if geom is not None and [a[:3] for a in geom]
                             == [a[:3] for a in new] and
                             max([abs(a[3] - c_[3]) for a, c_ in zip(geom, new)] or [0.0]) < 1e-9
                             else 1.0)
                    if DAMP and geom is not None and [a[:3] for a in geom] == [a[:3] for a in new]:
                        new = [a[:3] + ((1 - DAMP) * a[3] + DAMP * c_[3],)
                               for a, c_ in zip(new, geom)]
                    geom = front_correction.frozen = new
                self.box["q"] = qf.copy() if FRONT else None
                self.box["corr"][:], info, deltas = rupture_correction(b, xy, self.omega, q)
                # the front treatment's Jacobian lacks the band's outside entries (an inexact
                # Newton, linear convergence): more iterations before the cold path
                un, nits = b._steady_newton(kin, u, zero, 300 if FRONT else 40)
                self.newton_its.append(nits if un is not None else -1)
                u = b._steady(kin, u) if un is None else un
                dq = row_flux(b, u, kin, self.alpha,
                              delta=deltas if Q_WITH_DELTA else None) - q
                q = q + dq
                dqf = 0.0
                if FRONT:
                    qn = row_flux(b, u, kin, self.alpha, deg=FRONT_Q_DEG)
                    dqf = np.max(np.abs(qn - qf)) / np.max(np.abs(qn))
                    qf = qn
                if FRONT == "sw-lag":
                    dqf = max(dqf, dgeom)
                    self.geoms.append((tuple(round(a[3], 4) for a in geom),
                                       round(float(_force(b, *b.law.p_theta(u), kin)[0]), 5)))
                if np.max(np.abs(dq)) < 1e-11 * np.max(np.abs(q)) and dqf < 1e-11:
                    break
            else:
                print(f"  ({b.grid.n_phi} x {b.params.n_z}: q changed by "
                      f"{np.max(np.abs(dq / q)):.1e} at the last substitution)", flush=True)
        return u, kin, its, info, q


def solve(n_phi, n_z, xy, omega, rupture, alpha=0.0, max_iter=60, fields=False):
    """(Fx, Fy) of the steady film with the exit-layer correction and, if ``rupture``, the
    free-rupture correction; groove and journal frame rotated by alpha; and
    (substitutions, per-row info); ``fields``: (b, p, theta, kin) instead."""
    film = Film(n_phi, n_z, omega, alpha)
    u, kin, its, info, _ = film.steady(xy, rupture, max_iter=max_iter)
    p, th = film.b.law.p_theta(u)
    if fields:
        return film.b, p, th, kin
    return _force(film.b, p, th, kin), its, info


def stiffness(n, q, omega, rupture, rel=1e-3):
    """(Fx, Fy, kxx, kxy, kyx, kyy) on n x n cells: central differences of the steady film at
    positions moved by rel c (grid_convergence.py ``mc_quantities``' steps), each warm from the
    base state (and, with the rupture correction, from its rows' cavity fluxes)."""
    film = Film(n, n, omega)
    b = film.b
    u0, kin, _, _, q0 = film.steady(q, rupture)
    F0 = _force(b, *b.law.p_theta(u0), kin)
    K = np.empty((2, 2))
    for j in range(2):
        fs = []
        for sgn in (1, -1):
            xy = list(q)
            xy[j] += sgn * rel * b.c
            u, kin_j, _, _, _ = film.steady(xy, rupture, u0=u0, q0=q0)
            fs.append(_force(b, *b.law.p_theta(u), kin_j))
        K[:, j] = -(fs[0] - fs[1]) / (2 * rel * b.c)
    return np.concatenate([F0, K.ravel()])


def _shift(n_phi, n_z, q, frac):
    """(alpha, journal position in the rotated frame) of the grid shifted by ``frac``."""
    prm = gc.params("air", n_phi, n_z)
    dphi = 2 * math.pi / n_phi
    edge0 = prm.groove_angle + 0.5 * prm.groove_width
    alpha = (math.ceil(edge0 / dphi + 1e-9) - frac) * dphi - edge0
    ca, sa = math.cos(alpha), math.sin(alpha)
    return alpha, (ca * q[0] - sa * q[1], sa * q[0] + ca * q[1])


#: phi sectors [deg] of the attribution (``sectors``): around the minimum gap and the free
#: rupture, cavity, groove, exit layer and cavity, reformation front, full film
SECTORS = ((-40, 40), (40, 80), (80, 100), (100, 180), (180, 250), (250, 320))


def sectors(n_phi, n_z, q, omega, rupture, n_ref=768):
    """Where the shifted n_phi x n_z film's force error sits: per SECTOR the Fx [N] that the
    cell pressures' difference to the n_ref x n_z film (same correction; interpolated per row
    at the shifted grid's physical angles) carries there (the film's own force integral on
    the reference pressures plus the masked difference, rotated back)."""
    ref = solve(n_ref, n_z, q, omega, rupture, fields=True)
    g_r = ref[0].grid
    p_r = ref[1].reshape(g_r.n_z, g_r.n_phi)
    x_r = np.concatenate([g_r.phi - 2 * math.pi, g_r.phi, g_r.phi + 2 * math.pi])
    rows = []
    for frac in (0.1, 0.3, 0.5, 0.7, 0.9):
        alpha, xy = _shift(n_phi, n_z, q, frac)
        b, p, th, kin = solve(n_phi, n_z, xy, omega, rupture, alpha=alpha, fields=True)
        g = b.grid
        phys = (g.phi - alpha) % (2 * math.pi)
        pref = np.concatenate([np.interp(phys, x_r, np.tile(p_r[j], 3)) for j in range(g.n_z)])
        base = _force(b, pref, th, kin)
        deg = (np.degrees(np.tile(phys, g.n_z)) + 40.0) % 360.0 - 40.0
        out = []
        for lo, hi in SECTORS:
            m = (deg >= lo) & (deg < hi)
            dF = _force(b, np.where(m, p, pref), th, kin) - base
            out.append(math.cos(alpha) * dF[0] + math.sin(alpha) * dF[1])
        rows.append((frac, out))
    return rows


def shifted(n_phi, n_z, q, omega, rupture, frac):
    """(Fx, Fy) in the journal frame, the grid shifted so that the first film cell's centre
    after the groove exit lies ``frac`` cells after the exit (exit_layer_2d.shifted_force)."""
    alpha, xy = _shift(n_phi, n_z, q, frac)
    ca, sa = math.cos(alpha), math.sin(alpha)
    F, _, _ = solve(n_phi, n_z, xy, omega, rupture, alpha=alpha)
    return ca * F[0] + sa * F[1], -sa * F[0] + ca * F[1]


def rupture_angle(b, xy, omega, q):
    """phi_r [deg] of ``omega H(phi_r) = q`` after the minimum gap (row_layer's root)."""
    x, y = xy
    phi_min = math.atan2(y, x)
    return math.degrees(brentq(
        lambda p: omega * (1.0 - (x * math.cos(p) + y * math.sin(p)) / b.c) - q,
        phi_min + 1e-9, phi_min + math.pi - 1e-6, xtol=1e-15))


def flux_probe(n_phi, n_z, xy, omega, rupture):
    """The rows' cavity flux of one film (exit correction, and the rupture correction if
    ``rupture``): mid-width q at Q_DEG from the film's face flux and from the upwind formula,
    the spread of each over the faces nearest 30 ... 70 deg, the half film's total Q = sum_j
    dz q_j, and phi_r of the mid-width row from each q."""
    film = Film(n_phi, n_z, omega)
    b = film.b
    u, kin, its, info, _ = film.steady(xy, rupture)
    out = {}
    for name, sch in (("scheme", True), ("upwind", False)):
        qs = np.array([row_flux(b, u, kin, deg=d, scheme=sch) for d in (30, 40, 50, 60, 70)])
        q50 = qs[2]
        out[name] = (q50[-1], float(np.ptp(qs[:, -1]) / q50[-1]), float(b.grid.dz * q50.sum()),
                     rupture_angle(b, xy, omega, q50[-1]))
    return out, info


def flux_table(shapes, xy, omega, rupture):
    print("| grid | tt | q mid-width (film's face flux) | spread 30..70 deg | Q | phi_r mid [deg] | "
          "q mid-width (upwind formula) | spread 30..70 deg | Q | phi_r mid [deg] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    res, saved = {}, dict(el.TT)
    for tt in (0, 1):
        el.TT["theta_transport"] = tt
        for n_phi, n_z in shapes:
            o, _ = flux_probe(n_phi, n_z, xy, omega, rupture)
            res[(tt, n_phi, n_z)] = o
            a, c = o["scheme"], o["upwind"]
            print(f"| {n_phi} x {n_z} | {tt} | {a[0]:.6f} | {a[1]:.1e} | {a[2]:.6f} | {a[3]:.2f} | "
                  f"{c[0]:.6f} | {c[1]:.1e} | {c[2]:.6f} | {c[3]:.2f} |", flush=True)
    el.TT.clear()
    el.TT.update(saved)
    for tt in (0, 1):
        for name in ("scheme", "upwind"):
            v = [res[(tt, a, b)][name][2] for a, b in shapes]
            print(f"\ntt {tt}, Q from the {name} flux: orders {orders(v)}")
    return res


def orders(vals):
    d = np.diff(vals)
    return ", ".join(f"{math.log2(d[i] / d[i + 1]):.2f}" if d[i] * d[i + 1] > 0 else "nan"
                     for i in range(len(d) - 1))


def table(shapes, q, omega):
    print("| grid | Fx exit only | Fy exit only | Fx with rupture | Fy with rupture | "
          "substitutions | phi_r edge / quarter / mid-width [deg], faces at mid-width | wall [s] |")
    print("|---|---|---|---|---|---|---|---|")
    res = []
    for n_phi, n_z in shapes:
        t = time.time()
        F0, _, _ = solve(n_phi, n_z, q, omega, False)
        F1, its, info = solve(n_phi, n_z, q, omega, True)
        res.append((F0, F1))
        mid, quarter = info[-1], info[len(info) // 2]
        print(f"| {n_phi} x {n_z} | {F0[0]:.5f} | {F0[1]:.5f} | {F1[0]:.5f} | {F1[1]:.5f} | "
              f"{its} | {info[0][0]:.2f} / {quarter[0]:.2f} / {mid[0]:.2f}, {mid[1]} | "
              f"{time.time() - t:.0f} |",
              flush=True)
    for k, name in ((0, "Fx"), (1, "Fy")):
        print(f"\n{name} orders: exit only {orders([r[0][k] for r in res])}; with rupture "
              f"{orders([r[1][k] for r in res])}")
    return res


def main(argv):
    if "--tt" in argv:          # as exit_layer_2d.py: the films' theta_transport
        k = argv.index("--tt")
        el.TT["theta_transport"] = int(argv[k + 1])
        argv = argv[:k] + argv[k + 2:]
    global UPWIND_Q, Q_WITH_DELTA, FRONT
    if "--front" in argv:
        k = argv.index("--front")
        FRONT = argv[k + 1]
        argv = argv[:k] + argv[k + 2:]
    global RAMP
    if "--no-ramp" in argv:
        RAMP = False
        argv = [a for a in argv if a != "--no-ramp"]
    if "--upwind-q" in argv:
        UPWIND_Q = True
        argv = [a for a in argv if a != "--upwind-q"]
    if "--q-without-delta" in argv:
        Q_WITH_DELTA = False
        argv = [a for a in argv if a != "--q-without-delta"]
    parts = argv or ["square"]
    q = gc.hs_equilibrium(40)
    omega = 2 * math.pi * gc.F_HZ
    if "square" in parts:
        print("\n### square grids\n")
        table([(n, n) for n in (20, 40, 80, 160)], q, omega)
    if "phi" in parts:
        print("\n### n_z = 40, n_phi refined\n")
        table([(n, 40) for n in (48, 96, 192, 384)], q, omega)
    if "axial" in parts:
        print("\n### n_phi = 96, n_z refined\n")
        table([(96, n) for n in (20, 40, 80)], q, omega)
    if "shift" in parts:
        print("\n### grid shifted by a fraction of a cell, n_z = 40\n")
        print("| grid | film | Fx at 0.1 / 0.3 / 0.5 / 0.7 / 0.9 cells | spread Fx / Fy |")
        print("|---|---|---|---|")
        for n in (40, 80):
            for rup in (False, True):
                v = [shifted(n, 40, q, omega, rup, fr) for fr in (0.1, 0.3, 0.5, 0.7, 0.9)]
                fx, fy = [a[0] for a in v], [a[1] for a in v]
                print(f"| {n} x 40 | {'with rupture' if rup else 'exit only'} | "
                      + " / ".join(f"{a:.5f}" for a in fx)
                      + f" | {100 * (max(fx) - min(fx)) / abs(np.mean(fx)):.3f} / "
                      f"{100 * (max(fy) - min(fy)) / abs(np.mean(fy)):.3f} % |", flush=True)


    if "flux" in parts:     # both transports whatever --tt; the exit-corrected films
        print("\n### the rows' cavity flux at 50 deg, exit correction only, square grids\n")
        flux_table([(n, n) for n in (20, 40, 80, 160)], q, omega, False)
        print("\n### the same, n_z = 40, n_phi refined\n")
        flux_table([(n, 40) for n in (48, 96, 192, 384, 768)], q, omega, False)
    if "stiffness" in parts:
        print("\n### square grids: force and stiffness coefficients\n")
        names = ("Fx [N]", "Fy [N]", "kxx [N/m]", "kxy [N/m]", "kyx [N/m]", "kyy [N/m]")
        for rup in (False, True):
            rows = [stiffness(n, q, omega, rup) for n in (20, 40, 80, 160)]
            print(f"\n{'with rupture' if rup else 'exit only'}:\n")
            print("| quantity | 20 | 40 | 80 | 160 | orders |")
            print("|---|---|---|---|---|---|")
            for k, name in enumerate(names):
                v = [r[k] for r in rows]
                print(f"| {name} | " + " | ".join(f"{a:.6g}" for a in v) + f" | {orders(v)} |",
                      flush=True)
    if "sectors" in parts:
        print("\n### 40 x 40 shifted: Fx [N] of the cell pressures' difference to 768 x 40, per "
              "sector\n")
        print("| film | shift [cells] | " + " | ".join(f"{a} .. {b} deg" for a, b in SECTORS)
              + " | sum |")
        print("|---|---|" + "---|" * (len(SECTORS) + 1))
        for rup in (False, True):
            for frac, out in sectors(40, 40, q, omega, rup):
                print(f"| {'with rupture' if rup else 'exit only'} | {frac} | "
                      + " | ".join(f"{v:+.5f}" for v in out) + f" | {sum(out):+.5f} |",
                      flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
