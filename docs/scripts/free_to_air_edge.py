"""Free-to-air penalty edge (paper eq. 6) against the Reynolds-condition table (issue 16).

Mass-conserving film, a one-column flooded groove at the thickest film (journal displaced
downwards, groove at phi = 90 deg, p_feed = p0) as in the finite-bearing table test of
docs/bearing-validation.md, steady state (``solve_stationary``), 120 cells in phi and
n_z = 20/40/80/160 across the width, free to air (axial_bc = 1) and, on the same grid, the
oil bath (axial_bc = 0, the table's Dirichlet ends). Prints the Sommerfeld number error
against Khonsari & Booser Table 8.6 (``bearing_fmu.reference.FINITE_BEARING_TABLE``), the
observed order of the free-to-air load (log2 of the ratio of successive differences), the
free-to-air - oil-bath load difference, and the largest theta on the edge row inside the
cavity (no inflow: < 1).

    nice .venv/bin/python docs/scripts/free_to_air_edge.py [--bd 0.5,1] [--eps 0.5,0.6,0.7,0.8]
        [--nz 20,40,80,160] [--nphi 120] [--penalty-b B]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from bearing_fmu import model
from bearing_fmu import reference as ref

R, PSI, ETA, P0 = 0.02, 2.8e-3, 0.012, 1e5
C = PSI * R
OMEGA = 2 * math.pi * 100.0


def case(bd, eps, n_phi, n_z, axial_bc, **kw):
    B = bd * 2 * R
    p = model.BearingParams(R=R, B=B, psi=PSI, eta0=ETA, p0=P0, p_feed=P0, n_phi=n_phi,
                            n_z=n_z, cavitation=1, axial_bc=axial_bc, groove_width=1e-9,
                            groove_angle=math.pi / 2, **kw)
    b = model.solve_stationary(p, 0.0, -eps * C, OMEGA)
    load = math.hypot(b.outputs["Fx"], b.outputs["Fy"])
    s = ref.sommerfeld_number(load, R=R, B=B, c=C, eta=ETA, omega=OMEGA)
    f = b.fields()
    cav = f["p"][0] < P0 - 0.5 * p.cav_width          # edge row, inside the cavity
    th_edge = float(f["theta"][0][cav].max()) if cav.any() else float("nan")
    return s, load, th_edge


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bd", default="0.5,1")
    ap.add_argument("--eps", default="0.5,0.6,0.7,0.8")
    ap.add_argument("--nz", default="20,40,80,160")
    ap.add_argument("--nphi", type=int, default=120)
    ap.add_argument("--penalty-b", type=float, default=None, help="BearingParams.penalty_b")
    a = ap.parse_args(argv)
    nzs = [int(v) for v in a.nz.split(",")]
    print("| B/D | eps | n_z | S table | S air | dS air | order air | S bath | dS bath | air - bath | "
          "max theta edge cavity |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for bd in (float(v) for v in a.bd.split(",")):
        for eps in (float(v) for v in a.eps.split(",")):
            s_tab = next(r[1] for r in ref.FINITE_BEARING_TABLE[bd] if abs(r[0] - eps) < 1e-9)
            loads = []
            for nz in nzs:
                kw = {} if a.penalty_b is None else dict(penalty_b=a.penalty_b)
                s_a, w_a, th = case(bd, eps, a.nphi, nz, 1, **kw)
                s_b, w_b, _ = case(bd, eps, a.nphi, nz, 0)
                loads.append(w_a)
                order = float("nan")
                if len(loads) >= 3 and loads[-1] != loads[-2]:
                    order = math.log2(abs((loads[-3] - loads[-2]) / (loads[-2] - loads[-1])))
                print(f"| {bd:g} | {eps:g} | {nz} | {s_tab:.4f} | {s_a:.4f} | "
                      f"{100 * (s_a / s_tab - 1):+.2f} % | {order:.2f} | {s_b:.4f} | "
                      f"{100 * (s_b / s_tab - 1):+.2f} % | {100 * (w_a / w_b - 1):+.3f} % | "
                      f"{th:.4f} |", flush=True)


if __name__ == "__main__":
    main()
