"""Grid order of the paper's stationary oil-bath film (section 3.1, cav_width 0.9 p0) with
first-order (theta_transport 0) and limited second-order (1) Couette transport of theta.

Bearing of scenarios/stationary_oil_bath.yaml (R = 20 mm, B = 1.6 R, psi = 2.8e-3,
eta0 = 12 mPa s, p0 = 1 bar, no groove, oil bath), eps = 0.7 at phi = pi, 100 Hz,
cav_width = 9e4 Pa; steady film (solve_stationary). Prints Fx, Fy, |F|, p_max and the
cavity share per grid and the observed orders.

Run: ``nice -n 5 .venv/bin/python docs/scripts/theta_transport_paper31.py [--grids 20,40,80,160]``
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))          # repo root

from bearing_fmu.model import BearingParams, solve_stationary  # noqa: E402


def run(n, tt):
    p = BearingParams(cav_width=9.0e4, n_phi=n, n_z=n, theta_transport=tt,
                      newton_atol=1e-10, newton_rtol=1e-11)
    t0 = time.time()
    b = solve_stationary(p, -0.7 * p.c, 0.0, 2 * math.pi * 100.0)
    o = b.outputs
    th = b.fields()["theta"]
    return dict(Fx=o["Fx"], Fy=o["Fy"], F=math.hypot(o["Fx"], o["Fy"]), p_max=o["p_max"],
                torque=o["torque"], cavity=float((th < 0.999).mean()), wall=time.time() - t0)


def order(v):
    d1, d2 = v[-3] - v[-2], v[-2] - v[-1]
    return math.log2(d1 / d2) if d2 != 0 and d1 / d2 > 0 else float("nan")


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--grids", default="20,40,80,160")
    ap.add_argument("--tt", default="0,1")
    a = ap.parse_args(argv)
    grids = [int(g) for g in a.grids.split(",")]
    for tt in (int(t) for t in a.tt.split(",")):
        rows = []
        for n in grids:
            rows.append(run(n, tt))
            print(f"theta_transport {tt} {n} x {n}: " + ", ".join(
                f"{k} {v:.7g}" for k, v in rows[-1].items()), flush=True)
        for k in ("Fx", "Fy", "F", "p_max", "torque"):
            vals = [r[k] for r in rows]
            pw = [order(vals[: i + 3]) for i in range(len(vals) - 2)]
            print(f"  {k}: orders (consecutive triples) " + ", ".join(f"{o:.2f}" for o in pw),
                  flush=True)


if __name__ == "__main__":
    main()
