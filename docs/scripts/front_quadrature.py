"""Study (issue 16 item 2, 2026-12-07, fifth session): the force quadrature across the
reformation front. A study script, NOT a library option; nothing in bearing_fmu/ changes.

The film's force is the midpoint rule over the cells (``bearing_fmu.film.integrals``). Across
the reformation front the pressure has a kink: p = p_cav in the cavity, then the full film
rises with gradient G. The upwind scheme encodes each row's front at ``phi_E - f h`` (E the
first full cell, f the fill fraction of the front cell F, ``(theta_F - theta_W) / (1 -
theta_W)``; docs/bearing-validation.md, "The reformation front's alignment error"), and
``p_E - p_cav = G f h`` on the F|E face. Integrating that piecewise-linear profile exactly
over F and E instead of by their centre values adds, per row,

    G h^2 (f - 1/2)^2 / 2     (per unit width; between 0 and G h^2 / 8)

to the cell that holds the front (F if f >= 1/2, else E): a second-order error of the
midpoint rule whose coefficient depends on where the front falls in its cell, i.e. on the
grid's alignment, the analogue for the mass-conserving film of the half-Sommerfeld sub-cell
quadrature (``hs_force_pressure``) that the section "Groove of its true width" says was not
attempted. G from the front cell itself (``--g implied``, the default: ``(p_E - p_cav) / (f
h)``, the scheme's own front; below f = 0.05 the next option) or from the full film past E
(``--g gradient``: ``(p_EE - p_E) / h``).

Films: those of free_rupture_2d.py (exit-layer and free-rupture corrections: the prototypes
whose square-grid Fx / Fy orders are 1.45, 2.78 / 1.33, 1.81) and, with ``library``, the
library's own film (grid_convergence.py ``air``, no prototype). The correction is applied to
the converged fields; the solution is not changed.

Run (from the repository root): ``nice -n 10 .venv/bin/python docs/scripts/front_quadrature.py
[square] [shift] [library] [stiffness] [--g implied|gradient]`` (square: 20 ... 160, about 3
minutes; shift: the five shifted 40 x 40 films, about 3 minutes; library: the library's film
on 20 ... 160, about 2 minutes; stiffness: force and the four stiffness coefficients by central
differences (free_rupture_2d.stiffness), both quadratures from the same solves, about 40
minutes).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import free_rupture_2d as fr  # noqa: E402
import grid_convergence as gc  # noqa: E402
from bearing_fmu.linearize import _force  # noqa: E402
from bearing_fmu.model import BearingModel  # noqa: E402

#: how G is taken: "implied" (the front cell's own, (p_E - p_cav) / (f h)) or "gradient"
G_FROM = "implied"
#: the front is looked for between these physical angles [deg] (the reformation of this film:
#: 207-221 deg on the 384 x 40 reference)
FRONT_DEG = (150.0, 290.0)
FULL = 0.999            # theta at or above this: a full cell


def front_excess(b, p, th, alpha=0.0):
    """(dp, per-row [(row, f, excess)]): the cell pressures to add so that the midpoint rule
    integrates each row's piecewise-linear front profile exactly (module docstring)."""
    g = b.grid
    n = g.n_phi
    P = p.reshape(g.n_z, n)
    T = th.reshape(g.n_z, n)
    phys = np.degrees((g.phi - alpha) % (2 * math.pi))
    order = np.argsort(phys)
    h = 2 * math.pi / n
    dp = np.zeros_like(P)
    rows = []
    for j in range(g.n_z):
        for k in range(1, n - 2):
            i, e, w, ee = order[k], order[k + 1], order[k - 1], order[k + 2]
            if FRONT_DEG[0] <= phys[i] <= FRONT_DEG[1] and T[j, i] < FULL <= T[j, e]:
                f = (T[j, i] - T[j, w]) / (1.0 - T[j, w])
                if G_FROM == "implied" and f > 0.05:
                    G = (P[j, e] - P[j, w]) / (f * h)          # W is in the cavity: p_cav
                else:
                    G = (P[j, ee] - P[j, e]) / h
                exc = G * h * (f - 0.5) ** 2 / 2.0              # cell mean over h
                dp[j, i if f >= 0.5 else e] += exc
                rows.append((j, f, exc))
                break
    return dp.ravel(), rows


def both_forces(b, p, th, kin, alpha=0.0):
    """(midpoint-rule force, force with the front quadrature) in the journal frame."""
    dp, _ = front_excess(b, p, th, alpha)
    ca, sa = math.cos(alpha), math.sin(alpha)
    out = []
    for pp in (p, p + dp):
        F = _force(b, pp, th, kin)
        out.append(np.array([ca * F[0] + sa * F[1], -sa * F[0] + ca * F[1]]))
    return out


def library_fields(n, q, omega):
    b = BearingModel(gc.params("air", n, n))
    kin = b._kinematics(q[0], q[1], 0.0, 0.0, omega)
    b.initialize(q[0], q[1], 0.0, 0.0, omega, init="stationary")
    p, th = b.law.p_theta(b.film.u.copy())
    return b, p, th, kin


def square(q, omega, library=False):
    rows = []
    print("| grid | Fx midpoint | Fx front quadrature | Fy midpoint | Fy front quadrature |")
    print("|---|---|---|---|---|")
    for n in (20, 40, 80, 160):
        b, p, th, kin = library_fields(n, q, omega) if library else fr.solve(n, n, q, omega, True, fields=True)
        F0, F1 = both_forces(b, p, th, kin)
        rows.append((F0, F1))
        print(f"| {n} x {n} | {F0[0]:.5f} | {F1[0]:.5f} | {F0[1]:.5f} | {F1[1]:.5f} |", flush=True)
    for k, name in ((0, "Fx"), (1, "Fy")):
        print(f"\n{name} orders: midpoint {fr.orders([r[0][k] for r in rows])}; front quadrature "
              f"{fr.orders([r[1][k] for r in rows])}")


def shift(q, omega):
    res = []
    for frac in (0.1, 0.3, 0.5, 0.7, 0.9):
        alpha, xy = fr._shift(40, 40, q, frac)
        b, p, th, kin = fr.solve(40, 40, xy, omega, True, alpha=alpha, fields=True)
        res.append(both_forces(b, p, th, kin, alpha))
    print("| quadrature | Fx at shift 0.1 / 0.3 / 0.5 / 0.7 / 0.9 [N] | spread Fx / Fy |")
    print("|---|---|---|")
    for k, name in ((0, "midpoint"), (1, "front")):
        X = np.array([r[k] for r in res])
        sp = 100 * (X.max(0) - X.min(0)) / np.abs(X.mean(0))
        print(f"| {name} | " + " / ".join(f"{v:.5f}" for v in X[:, 0]) + f" | {sp[0]:.3f} / {sp[1]:.3f} % |")


def stiffness(q, omega):
    names = ("Fx [N]", "Fy [N]", "kxx [N/m]", "kxy [N/m]", "kyx [N/m]", "kyy [N/m]")
    raw_force = fr._force
    got = {}

    def recording(b, p, th, kin, film=True):
        F0, F1 = both_forces(b, p, th, kin)
        got["mid"].append(F0)
        got["front"].append(F1)
        return F0

    table = {"mid": [], "front": []}
    fr._force = recording
    try:
        for n in (20, 40, 80, 160):
            got["mid"], got["front"] = [], []
            fr.stiffness(n, q, omega, True)
            c = BearingModel(gc.params("air", n, n)).c
            for key in table:
                F = got[key]
                K = np.empty((2, 2))
                for j in range(2):
                    K[:, j] = -(F[1 + 2 * j] - F[2 + 2 * j]) / (2e-3 * c)
                table[key].append(np.concatenate([F[0], K.ravel()]))
            print(f"({n} x {n} done)", flush=True)
    finally:
        fr._force = raw_force
    for key, label in (("mid", "midpoint rule"), ("front", "front quadrature")):
        print(f"\n{label}:\n\n| quantity | 20 | 40 | 80 | 160 | orders |\n|---|---|---|---|---|---|")
        for k, name in enumerate(names):
            v = [r[k] for r in table[key]]
            print(f"| {name} | " + " | ".join(f"{a:.6g}" for a in v) + f" | {fr.orders(v)} |")


def main(argv):
    global G_FROM
    if "--g" in argv:
        k = argv.index("--g")
        G_FROM = argv[k + 1]
        argv = argv[:k] + argv[k + 2:]
    parts = argv or ["square"]
    q = gc.hs_equilibrium(40)
    omega = 2 * math.pi * gc.F_HZ
    if "square" in parts:
        print(f"\n### square grids, prototype films (G {G_FROM})\n")
        square(q, omega)
    if "library" in parts:
        print(f"\n### square grids, the library's film (G {G_FROM})\n")
        square(q, omega, library=True)
    if "shift" in parts:
        print(f"\n### 40 x 40 shifted, prototype films (G {G_FROM})\n")
        shift(q, omega)
    if "stiffness" in parts:
        print(f"\n### square grids, force and stiffness, prototype films (G {G_FROM})\n")
        stiffness(q, omega)


if __name__ == "__main__":
    main(sys.argv[1:])
