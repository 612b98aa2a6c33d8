"""Prototype: the exit-layer defect correction of docs/scripts/reformation_front_1d.py in the
2-D steady free-to-air film (issue 16 item 2). A study script, NOT a library option: it
patches one BearingModel instance's film residual; the solver's defaults are untouched.

The bearing, journal position and Newton tolerances are those of grid_convergence.py ``air``
(Jeffcott run-up bearing, 15 deg groove at 90 deg, 250 Hz). What it does per grid:

1. the rupture layer after the groove exit (east edge, 97.5 deg) solved as the 1-D local
   problem of ``reformation_front_1d.layer_solution`` with the column gap ``H(phi) = 1 -
   (x cos phi + y sin phi) / c`` and a_phi (axial flow in the layer neglected);
2. per phi face inside the layer (both columns' centres before phi_far) and the groove-exit
   face: ``Delta = q_L - F(u_L)``, the layer's flux per unit width minus the film's own phi
   face flux (film.py: upwind Couette theta, two-point Poiseuille over ``frel dphi``,
   ``groove_exit`` at the exit face) evaluated on the layer profile at the column centres;
3. the residual of every film cell gains ``dz (Delta_east - Delta_west)`` (all rows alike),
   a constant: the Jacobian is unchanged.

Run: ``nice -n 10 .venv/bin/python docs/scripts/exit_layer_2d.py [phi] [fine] [square] [flux]
[shift] [points] [coef] [--tt 1]``
(``phi``: n_phi = 48 ... 768 at n_z = 40, about 2 minutes; ``fine``: 1536 and 3072 at n_z =
40, about 8 minutes; ``square``: 20 ... 160 square grids, about 3 minutes; prints markdown
tables of Fx, Fy without and with the correction; ``flux``: the cavity flux Q of the corrected
film on 96 ... 768 x 40 against the layer model's, about a minute).

Added 2026-12-07 (issue 16 item 2, the decision whether to build the correction into the
library):

* ``--tt 1``: the films with the limited second-order theta transport (``theta_transport =
  1``); the correction then takes the film's MUSCL face value on the layer profile
  (film.py ``face_theta``: first order at the groove-exit face, limited from the first film
  face on, whose upwind-upwind cell is the groove column at theta_feed).
* ``shift``: the same physical problem on grids shifted by a fraction of a cell (groove and
  journal rotated by alpha, the force rotated back; groove_cut_study.py's trick): the film
  cell after the groove exit starts 0.1 ... 0.9 cells after the exit; n_phi = 40 ... 320 at
  n_z = 40, without and with the correction. The spread is the part of the error that
  depends on where the grid cuts the film, which no 20/40/80/160 sequence can make monotone.
* ``points``: the row-mean pressure at the cell centres common to the 48 * 2^k grids (every
  7.5 deg), n_phi = 48 ... 768 at n_z = 40, corrected film: where the remaining
  circumferential change sits.
* ``coef``: square grids 20 ... 160, force and the eight quasi-steady coefficients
  (grid_convergence.py ``air``: central differences of the steady film, step 1e-3 c and
  1e-3 c omega), without and with the correction; the correction is recomputed at every
  perturbed state, with the squeeze term in the layer for the velocity perturbations
  (:func:`layer_solution_squeeze`).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import grid_convergence as gc  # noqa: E402
import reformation_front_1d as rf  # noqa: E402
from bearing_fmu.film import groove_exit, limiter  # noqa: E402
from bearing_fmu.model import BearingModel  # noqa: E402


def layer_solution_squeeze(gap, gap_dot, dH, a0, a, omega, law, p_feed, n_len=8.0):
    """:func:`reformation_front_1d.layer_solution` with the squeeze term: in the steady film
    with the journal moving, ``dq/dphi = -2 theta dH/dt`` (film.py's cell balance without
    the time term and axial flow), so the layer's flux varies along phi. The state (u, q) is
    integrated backward from phi_far (u on the cavity's manifold ``theta(u) = q / (omega
    H)``), and q(phi_far) is the root of p(a0) = p_feed. Returns (P0, sol, phi_far) with
    ``P0 = q(a0) - omega H(a0) theta_feed`` and ``sol(phi)`` = [u, q]."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq
    Hg = float(gap(a0))
    c = a * Hg ** 3
    L = math.sqrt(2 * c * law.width / (omega * dH))
    phi_far = a0 + n_len * L
    u_feed = float(law.u_from_p(p_feed))
    th_feed = float(rf.evaluate(np.array([u_feed]), law)[2][0])
    buf = [np.empty(1) for _ in range(4)]
    ua = np.empty(1)
    from bearing_fmu.cavitation import law_eval

    def ev(v):
        ua[0] = v
        law_eval(ua, law.p_cav, law.K, law.delta, *buf)
        return buf[1][0], buf[2][0], buf[3][0]

    def rhs(phi, y):
        dp, th, _ = ev(y[0])
        H = gap(phi)
        return [(omega * H * th - y[1]) / (a * H ** 3 * dp), -2.0 * th * gap_dot(phi)]

    def jac(phi, y):
        dp, th, dth = ev(y[0])
        H = gap(phi)
        d2p = dp * (1.0 - dp / law.K) / law.delta
        return [[(omega * H * dth * dp - (omega * H * th - y[1]) * d2p) / (a * H ** 3 * dp * dp),
                 -1.0 / (a * H ** 3 * dp)],
                [-2.0 * dth * gap_dot(phi), 0.0]]

    def u_on_manifold(q):
        target = q / (omega * float(gap(phi_far)))
        return brentq(lambda v: ev(v)[1] - target, -5.0, 1e3, xtol=1e-14)

    def run(q_far, dense=False):
        return solve_ivp(rhs, (phi_far, a0), [u_on_manifold(q_far), q_far], method="Radau",
                         rtol=rf.RTOL, atol=0.1 * rf.RTOL, dense_output=dense, jac=jac)
    P_jfo = math.sqrt(2 * c * omega * dH * law.width)
    # the static layer's q, shifted by the squeeze source over the layer (theta ~ 1)
    from scipy.integrate import quad
    q0 = omega * Hg * th_feed - 2.0 * quad(gap_dot, a0, phi_far)[0]
    lo, hi = q0 - 2 * P_jfo, q0 + 3 * P_jfo

    def f(q_far):
        return run(q_far).y[0, -1] - u_feed
    while f(lo) > 0:
        lo -= 2 * P_jfo
    while f(hi) < 0:
        hi += 2 * P_jfo
    q_far = brentq(f, lo, hi, xtol=1e-13 * P_jfo)
    sol = run(q_far, dense=True).sol
    return float(sol(a0)[1]) - omega * Hg * th_feed, sol, phi_far


def exit_correction(b, kin, xy, vel=(0.0, 0.0)):
    """(n,) residual correction of the film of BearingModel ``b`` at kinematics ``kin``
    (journal at ``xy``, moving at ``vel``), and (P0, phi_far, number of corrected faces).
    With ``theta_transport = 1`` the scheme's face flux on the layer profile takes film.py's
    limited face value (``face_theta``)."""
    g, prm, law = b.grid, b.params, b.law
    H, He, Hdot, omega = kin
    x, y = xy
    vx, vy = vel
    c = b.c
    n_phi = g.n_phi
    groove = g.groove
    muscl = prm.theta_transport == 1
    i0 = next(i for i in range(n_phi) if groove[i - 1] and not groove[i])   # first film column
    a0 = prm.groove_angle + 0.5 * prm.groove_width

    def gap(phi):
        return 1.0 - (x * np.cos(phi) + y * np.sin(phi)) / c
    dH = (x * math.sin(a0) - y * math.cos(a0)) / c
    u_feed = float(law.u_from_p(prm.p_feed))
    th_feed = float(rf.evaluate(np.array([u_feed]), law)[2][0])
    fe = i0 - 1                                  # the exit face: east face of the groove column
    if vx == 0.0 and vy == 0.0:
        P0, sol, phi_far = rf.layer_solution(gap, dH, a0, b.a_phi, omega, law, prm.p_feed)
        q_L = omega * He[fe] * th_feed + P0

        def q_at(phi):
            return q_L
    else:
        def gap_dot(phi):
            return -(vx * np.cos(phi) + vy * np.sin(phi)) / c
        P0, sol2, phi_far = layer_solution_squeeze(gap, gap_dot, dH, a0, b.a_phi, omega, law,
                                                   prm.p_feed)
        q_L = omega * He[fe] * th_feed + P0

        def sol(phi):
            return sol2(phi)[:1]

        def q_at(phi):
            return float(sol2(phi)[1])
    # film columns after the exit whose centres lie inside the layer
    cols = []
    i = i0
    while not groove[i] and ((g.phi[i] - a0) % (2 * math.pi)) <= phi_far - a0:
        cols.append(i)
        i = (i + 1) % n_phi
    delta = np.zeros(n_phi)                      # correction of the east face of column i
    if cols:
        uL = sol(a0 + (g.phi[cols] - a0) % (2 * math.pi))[0]
        p, _, th, dth = rf.evaluate(uL, law)
        fr = g.frel
        # exit face
        cond = b.a_phi * He[fe] ** 3 / (g.dphi * fr[fe])
        B, _, _ = groove_exit(He, n_phi, i0, 1, fr[fe], g.dphi, omega, b.a_phi, cond,
                              prm.p_feed - p[0], dth[0], law.K)
        delta[fe] = q_L - (omega * He[fe] * th_feed + B)
        for k in range(len(cols) - 1):           # faces between two columns inside
            i = cols[k]
            cond = b.a_phi * He[i] ** 3 / (g.dphi * fr[i])
            if muscl:       # film.py face_theta; upwind-upwind of the first face: the groove
                thw = th[k - 1] if k > 0 else th_feed
                lim = limiter(th[k] - thw, th[k + 1] - th[k])[0]
                thf = th[k] + 0.5 * lim
            else:
                thf = th[k]
            F = omega * He[i] * thf - cond * (p[k + 1] - p[k])
            delta[i] = q_at(a0 + (g.phi_e[i] - a0) % (2 * math.pi)) - F
    corr = np.zeros(g.n_z * n_phi)
    per_col = np.zeros(n_phi)
    for i in range(n_phi):
        if not groove[i]:
            per_col[i] = g.dz * (delta[i] - delta[i - 1])
    for j in range(g.n_z):
        corr[j * n_phi:(j + 1) * n_phi] = per_col
    return corr, (P0, phi_far, int(np.count_nonzero(delta)))


def cavity_flux(b, deg=180.0):
    """Q = sum_j dz (omega H_e theta - a_phi H_e^3 dp/dphi) at the east face of the column
    nearest ``deg`` (free_to_air_phi_refinement.py ``flux``)."""
    g = b.grid
    p, th = b.law.p_theta(b.film.u)
    p, th = p.reshape(g.n_z, g.n_phi), th.reshape(g.n_z, g.n_phi)
    He, om = b._kin[1], b._kin[3]
    i = int(np.argmin(np.abs(g.phi - math.radians(deg))))
    d = g.frel[i] * g.dphi
    return float(np.sum(g.dz * (om * He[i] * th[:, i] - b.a_phi * He[i] ** 3
                                * (p[:, (i + 1) % g.n_phi] - p[:, i]) / d)))


#: BearingParams overrides of the films (``--tt``: theta_transport)
TT: dict = {}


def exit_corrected(b, corrected):
    """The per-state hook of grid_convergence.mc_quantities's ``prepare`` for the film of
    BearingModel ``b``: if ``corrected``, the film residual gains the correction that the
    returned ``prepare(kin, z)`` computes for the kinematics about to be solved (journal state
    z = (x, y, vx, vy)) and ``prepare`` returns exit_correction's info; None otherwise."""
    if not corrected:
        return None
    box = {"corr": None}
    f = b.film
    orig = f.residual

    def residual(*args, **kw):
        r = orig(*args, **kw)
        r += box["corr"]
        return r
    f.residual = residual
    f.fused = False                 # any Newton of this film goes through f.residual

    def prepare(kin, z):
        box["corr"], info = exit_correction(b, kin, z[:2], z[2:])
        return info
    return prepare


def solve(n_phi, n_z, q, omega, corrected, model=False, alpha=0.0):
    """The steady film of grid_convergence.py's ``air`` case on n_phi x n_z cells at the
    journal position ``q`` (groove and journal frame rotated by ``alpha``), with the exit-layer
    correction if ``corrected``: (Fx, Fy, exit_correction's info or None), or the model."""
    prm = gc.params("air", n_phi, n_z, **TT)
    if alpha:
        prm = prm.replace(groove_angle=prm.groove_angle + alpha)
    b = BearingModel(prm)
    prepare = exit_corrected(b, corrected)
    info = None
    if prepare is not None:
        info = prepare(b._kinematics(q[0], q[1], 0.0, 0.0, omega), (q[0], q[1], 0.0, 0.0))
    b.initialize(q[0], q[1], 0.0, 0.0, omega, init="stationary")
    if model:
        return b
    return b.outputs["Fx"], b.outputs["Fy"], info


def quantities(n, q, omega, corrected, rel=1e-3):
    """Force and the eight quasi-steady coefficients on n x n cells: grid_convergence.py
    ``mc_quantities`` (central differences of the steady film, warm-started), with the
    correction recomputed at every perturbed state."""
    return gc.mc_quantities("air", n, q, omega, rel=rel, prepare=lambda b: exit_corrected(b, corrected), **TT)


def shifted_force(n_phi, n_z, q, omega, corrected, frac):
    """(Fx, Fy) in the journal frame of the film whose grid is shifted so that the first film
    cell's centre after the groove exit lies ``frac`` cells after the exit (groove and journal
    rotated by alpha, the force rotated back: the same physical problem)."""
    prm = gc.params("air", n_phi, n_z)
    dphi = 2 * math.pi / n_phi
    edge0 = prm.groove_angle + 0.5 * prm.groove_width
    i = math.ceil(edge0 / dphi + 1e-9)
    alpha = (i - frac) * dphi - edge0
    ca, sa = math.cos(alpha), math.sin(alpha)
    xy = (ca * q[0] - sa * q[1], sa * q[0] + ca * q[1])
    fx, fy, _ = solve(n_phi, n_z, xy, omega, corrected, alpha=alpha)
    return ca * fx + sa * fy, -sa * fx + ca * fy


def table(grids, n_z, q, omega):
    print("| grid | Fx today | Fy today | Fx corrected | Fy corrected | P0, phi_far [deg], faces | wall [s] |")
    print("|---|---|---|---|---|---|---|")
    res = {}
    for n in grids:
        t = time.time()
        nz = n if n_z is None else n_z
        fx0, fy0, _ = solve(n, nz, q, omega, False)
        fx1, fy1, info = solve(n, nz, q, omega, True)
        res[n] = (fx0, fy0, fx1, fy1)
        print(f"| {n} x {nz} | {fx0:.5f} | {fy0:.5f} | {fx1:.5f} | {fy1:.5f} | "
              f"{info[0]:.4g}, {math.degrees(info[1]):.1f}, {info[2]} | {time.time() - t:.0f} |",
              flush=True)
    return res


def orders(vals):
    d = np.diff(vals)
    return [math.log2(d[i] / d[i + 1]) if d[i + 1] != 0 and d[i] / d[i + 1] > 0
            else float("nan") for i in range(len(d) - 1)]


def main(argv):
    if "--tt" in argv:
        k = argv.index("--tt")
        TT["theta_transport"] = int(argv[k + 1])
        argv = argv[:k] + argv[k + 2:]
    parts = argv or ["phi"]
    q = gc.hs_equilibrium(40)
    omega = 2 * math.pi * gc.F_HZ
    if "phi" in parts:
        print("\n### n_z = 40, n_phi refined\n")
        table([48, 96, 192, 384, 768], 40, q, omega)
    if "fine" in parts:
        print("\n### n_z = 40, n_phi 1536 and 3072\n")
        table([1536, 3072], 40, q, omega)
    if "flux" in parts:
        print("\n### cavity flux Q(180 deg) of the corrected film, n_z = 40\n")
        print("| n_phi | Q corrected | q_L sum dz (the layer model) | Fy corrected |")
        print("|---|---|---|---|")
        for n in (96, 192, 384, 768):
            b = solve(n, 40, q, omega, True, model=True)
            kin = b._kinematics(q[0], q[1], 0.0, 0.0, omega)
            P0 = exit_correction(b, kin, q)[1][0]
            fe = next(i for i in range(n) if b.grid.groove[i - 1] and not b.grid.groove[i]) - 1
            u_feed = float(b.law.u_from_p(b.params.p_feed))
            th_feed = float(rf.evaluate(np.array([u_feed]), b.law)[2][0])
            q_L = omega * kin[1][fe] * th_feed + P0
            print(f"| {n} | {cavity_flux(b):.6f} | {q_L * b.grid.dz * b.grid.n_z:.6f} | "
                  f"{b.outputs['Fy']:.5f} |", flush=True)
    if "square" in parts:
        print("\n### square grids\n")
        table([20, 40, 80, 160], None, q, omega)
    if "shift" in parts:
        print(f"\n### grid shifted by a fraction of a cell, n_z = 40 ({TT or 'theta_transport 0'})\n")
        fracs = (0.1, 0.3, 0.5, 0.7, 0.9)
        print("| n_phi | correction | Fx at " + " / ".join(str(f) for f in fracs)
              + " | Fx spread | Fy at the same | Fy spread |")
        print("|---|---|---|---|---|---|")
        for n in (40, 80, 160, 320):
            for corrected in (False, True):
                v = np.array([shifted_force(n, 40, q, omega, corrected, f) for f in fracs])
                sp = 100 * np.ptp(v, axis=0) / np.abs(v.mean(axis=0))
                print(f"| {n} | {'yes' if corrected else 'no'} | "
                      + " / ".join(f"{x:.5f}" for x in v[:, 0]) + f" | {sp[0]:.3f} % | "
                      + " / ".join(f"{x:.5f}" for x in v[:, 1]) + f" | {sp[1]:.3f} % |",
                      flush=True)
    if "points" in parts:
        grids = [48, 96, 192, 384, 768]
        print(f"\n### corrected film, n_z = 40 ({TT or 'theta_transport 0'}): row-mean p - p0 "
              "at the common cell centres [Pa], change to the 768 x 40 film\n")
        mean = {}
        for n in grids:
            b = solve(n, 40, q, omega, True, model=True)
            g = b.grid
            p = b.law.p_theta(b.film.u)[0].reshape(g.n_z, n) - b.p0
            mean[n] = p.mean(axis=0)[:: n // 48]
            print(f"{n} x 40: Fx {b.outputs['Fx']:.6f}, Fy {b.outputs['Fy']:.6f}", flush=True)
        print("\n| phi [deg] | p(768) - p0 | " + " | ".join(f"p(768) - p({n})" for n in grids[:-1])
              + " |")
        print("|---|---|" + "---|" * (len(grids) - 1))
        for k in range(48):
            deg = 7.5 * k
            if deg >= 300 or deg <= 30 or 195 <= deg <= 270:
                print(f"| {deg:.1f} | {mean[768][k]:.1f} | "
                      + " | ".join(f"{mean[768][k] - mean[n][k]:+.1f}" for n in grids[:-1]) + " |")
    if "coef" in parts:
        grids = [20, 40, 80, 160]
        print(f"\n### square grids, force and coefficients ({TT or 'theta_transport 0'})\n")
        for corrected in (False, True):
            rows = []
            for n in grids:
                t = time.time()
                rows.append(quantities(n, q, omega, corrected))
                print(f"  {n} x {n} {'corrected' if corrected else 'today'}: "
                      f"{time.time() - t:.0f} s", flush=True)
            print(f"\n{'corrected' if corrected else 'today'}:\n")
            print("| quantity | " + " | ".join(str(n) for n in grids) + " | orders |")
            print("|---|" + "---|" * (len(grids) + 1))
            for k, name in enumerate(gc.NAMES):
                vals = [r[k] for r in rows]
                print(f"| {name} | " + " | ".join(f"{v:.6g}" for v in vals) + " | "
                      + ", ".join(f"{o:.2f}" for o in orders(vals)) + " |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
