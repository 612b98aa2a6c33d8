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

Run: ``nice -n 10 .venv/bin/python docs/scripts/exit_layer_2d.py [phi] [fine] [square] [flux]``
(``phi``: n_phi = 48 ... 768 at n_z = 40, about 2 minutes; ``fine``: 1536 and 3072 at n_z =
40, about 8 minutes; ``square``: 20 ... 160 square grids, about 3 minutes; prints markdown
tables of Fx, Fy without and with the correction; ``flux``: the cavity flux Q of the corrected
film on 96 ... 768 x 40 against the layer model's, about a minute).
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
from bearing_fmu.film import groove_exit  # noqa: E402
from bearing_fmu.model import BearingModel  # noqa: E402


def exit_correction(b, kin, xy):
    """(n,) residual correction of the film of BearingModel ``b`` at kinematics ``kin``
    (journal at ``xy``), and (P0, phi_far, number of corrected faces)."""
    g, prm, law = b.grid, b.params, b.law
    H, He, Hdot, omega = kin
    x, y = xy
    c = b.c
    n_phi = g.n_phi
    groove = g.groove
    i0 = next(i for i in range(n_phi) if groove[i - 1] and not groove[i])   # first film column
    a0 = prm.groove_angle + 0.5 * prm.groove_width

    def gap(phi):
        return 1.0 - (x * np.cos(phi) + y * np.sin(phi)) / c
    dH = (x * math.sin(a0) - y * math.cos(a0)) / c
    P0, sol, phi_far = rf.layer_solution(gap, dH, a0, b.a_phi, omega, law, prm.p_feed)
    u_feed = float(law.u_from_p(prm.p_feed))
    th_feed = float(rf.evaluate(np.array([u_feed]), law)[2][0])
    fe = i0 - 1                                  # the exit face: east face of the groove column
    q_L = omega * He[fe] * th_feed + P0
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
            F = omega * He[i] * th[k] - cond * (p[k + 1] - p[k])
            delta[i] = q_L - F
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


def solve(n_phi, n_z, q, omega, corrected, model=False):
    b = BearingModel(gc.params("air", n_phi, n_z))
    info = None
    if corrected:
        kin = b._kinematics(q[0], q[1], 0.0, 0.0, omega)
        corr, info = exit_correction(b, kin, q)
        f = b.film
        orig = f.residual

        def residual(*args, **kw):
            r = orig(*args, **kw)
            r += corr
            return r
        f.residual = residual
        f.fused = False                 # any Newton of this film goes through f.residual
    b.initialize(q[0], q[1], 0.0, 0.0, omega, init="stationary")
    if model:
        return b
    return b.outputs["Fx"], b.outputs["Fy"], info


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


def main(argv):
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


if __name__ == "__main__":
    main(sys.argv[1:])
