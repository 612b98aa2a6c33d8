"""Direction-split grid refinement of the free-to-air mass-conserving film (issue 16, item 2).

Why: on 20/40/80/160 square grids the free-to-air force and coefficients are not monotone
(docs/bearing-validation.md, "Free-to-air edge and groove of its true width"). This script
separates the two directions and the cavitation law's width, on the steady film of
docs/scripts/grid_convergence.py (Jeffcott run-up bearing, 15 deg groove at phi = 90 deg,
250 Hz, the 40 x 40 half-Sommerfeld equilibrium carrying 29.43 N, Newton tolerances 1e-10 /
1e-11):

* ``z``: n_phi = 40, n_z = 20 ... 320: the axial direction alone (the penalty edge of eq. 6);
* ``phi``: n_z = 40, n_phi = 48 ... 1536 (doubling; a steady solve of 1536 x 40 takes a few
  seconds), force and the eight quasi-steady coefficients;
* ``width``: Fy on the same phi sequence for several ``cav_width`` (the pressure width of
  the cavitation law theta(p), bearing_fmu/cavitation.py; 1 kPa is the default and what the
  shipped free-to-air scenarios use);
* ``split``: that Fy split into the part of the cells below p0 (the cavity, at about p0 -
  cav_width) and the part of the cells at or above p0 (the full film), with the film's own
  force quadrature (``linearize._force`` of the pressure with the other part set to p0).

* ``flux`` (not in the default set; about three minutes): Fy and the circumferential flux
  through the cavity, ``Q = sum_j dz (omega H_e theta_i - a_phi H_e^3 (p_i+1 - p_i) / d)`` at
  the east face of the column nearest 120 and 180 deg (the analogue of the 1-D film's q,
  docs/scripts/reformation_front_1d.py), on the n_phi sequence at n_z = 40.

Run: ``nice .venv/bin/python docs/scripts/free_to_air_phi_refinement.py [z] [phi] [width] [split]
[flux]`` (the first four by default; about two minutes on one core). Prints markdown tables.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import grid_convergence as gc  # noqa: E402

PHI_GRIDS = [48, 96, 192, 384, 768, 1536]
Z_GRIDS = [20, 40, 80, 160, 320]
WIDTHS = [1e2, 3e2, 1e3, 3e3]


def diffs_and_orders(vals):
    d = np.diff(vals)
    orders = [math.log2(d[i] / d[i + 1]) if d[i + 1] != 0 and d[i] / d[i + 1] > 0 else float("nan")
              for i in range(len(d) - 1)]
    return d, orders


def row(name, vals, fmt="{:.6g}"):
    d, orders = diffs_and_orders(vals)
    print(f"| {name} | " + " | ".join(fmt.format(v) for v in vals) + " | "
          + ", ".join(f"{x:+.2e}" for x in d) + " | " + ", ".join(f"{o:.2f}" for o in orders) + " |")


def header(label, grids):
    print(f"| quantity | " + " | ".join(label.format(g) for g in grids)
          + " | successive differences | orders |")
    print("|---|" + "---|" * (len(grids) + 2))


def main(argv):
    parts = argv or ["z", "phi", "width", "split"]
    q = gc.hs_equilibrium(40)
    omega = 2 * math.pi * gc.F_HZ
    if "z" in parts:
        print("\n### Axial direction: n_phi = 40, n_z refined (force only)\n")
        header("40 x {}", Z_GRIDS)
        vals = [gc.mc_quantities("air", 40, q, omega, n_z=nz, coefficients=False) for nz in Z_GRIDS]
        for k, name in enumerate(gc.NAMES[:2]):
            row(name, [v[k] for v in vals])
    if "phi" in parts:
        print("\n### Circumferential direction: n_z = 40, n_phi refined\n")
        header("{} x 40", PHI_GRIDS)
        vals = [gc.mc_quantities("air", n, q, omega, n_z=40) for n in PHI_GRIDS]
        for k, name in enumerate(gc.NAMES):
            row(name, [v[k] for v in vals])
    if "width" in parts:
        print("\n### Fy [N] against the cavitation law's width: n_z = 40, n_phi refined\n")
        header("{} x 40", PHI_GRIDS)
        for w in WIDTHS:
            vals = [gc.mc_quantities("air", n, q, omega, n_z=40, coefficients=False,
                                     cav_width=w)[1] for n in PHI_GRIDS]
            row(f"cav_width {w:g} Pa", vals)
    if "flux" in parts:
        from bearing_fmu.model import BearingModel
        print("\n### Fy and the cavity flux Q: n_z = 40\n")
        print("| n_phi | Fy [N] | Q(120 deg) | Q(180 deg) | dFy / dQ to the previous grid [N] |")
        print("|---|---|---|---|---|")
        prev = None
        for n in PHI_GRIDS:
            b = BearingModel(gc.params("air", n, 40))
            b.initialize(q[0], q[1], 0.0, 0.0, omega, init="stationary")
            g = b.grid
            p, th = b.law.p_theta(b.film.u)
            p, th = p.reshape(g.n_z, g.n_phi), th.reshape(g.n_z, g.n_phi)
            He, om = b._kin[1], b._kin[3]
            Q = []
            for deg in (120.0, 180.0):
                i = int(np.argmin(np.abs(g.phi - math.radians(deg))))
                d = g.frel[i] * g.dphi
                Q.append(float(np.sum(g.dz * (om * He[i] * th[:, i] - b.a_phi * He[i] ** 3
                                              * (p[:, (i + 1) % g.n_phi] - p[:, i]) / d))))
            fy = b.outputs["Fy"]
            ratio = "" if prev is None else f"{(fy - prev[0]) / (Q[1] - prev[1]):.4f}"
            print(f"| {n} | {fy:.5f} | {Q[0]:.6f} | {Q[1]:.6f} | {ratio} |", flush=True)
            prev = (fy, Q[1])
    if "split" in parts:
        from bearing_fmu.linearize import _force
        from bearing_fmu.model import BearingModel
        print("\n### Fy [N] of the cells below p0 and at or above p0: n_z = 40\n")
        print("| cav_width | n_phi | Fy | cells below p0 | cells at or above p0 |")
        print("|---|---|---|---|---|")
        for w in (1e2, 1e3, 3e3):
            for n in (48, 192, 768, 1536):
                b = BearingModel(gc.params("air", n, 40, cav_width=w))
                b.initialize(q[0], q[1], 0.0, 0.0, omega, init="stationary")
                p, th = b.law.p_theta(b.film.u)
                below = _force(b, np.minimum(p, b.p0), th, b._kin)[1]
                above = _force(b, np.maximum(p, b.p0), th, b._kin)[1]
                print(f"| {w:g} Pa | {n} | {b.outputs['Fy']:.5f} | {below:+.5f} | {above:.5f} |",
                      flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
