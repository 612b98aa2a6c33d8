"""Why the free-to-air force with the true-width groove is not monotone on 20/40/80/160
(issue 16, docs/bearing-validation.md "Groove of its true width").

Steady mass-conserving film of the Jeffcott run-up bearing (free to air, 15 deg groove at
90 deg), journal at the 250 Hz point of docs/scripts/grid_convergence.py, n_phi = n_z = n,
tight Newton tolerances. The film is axisymmetric except for the groove, so rotating the
groove AND the journal by alpha and the force back by -alpha is the same physical problem
on a grid shifted by alpha: that separates the grid's cut of the groove edge (fraction
``d / dphi`` of the film cell next to the edge) from the refinement.

Sequences
  cut     n = 20, 40, 80, 160, alpha = 0 (what docs/bearing-validation.md measured);
  faces   n = 24, 48, 96, 192, alpha chosen so that both groove edges lie on cell faces
          (15 deg = an integer number of cells): no cut cell at all;
  frac    n = 40, alpha such that d / dphi = 0.1 ... 0.9: the cut's effect at one grid.

Run: ``nice -n 19 .venv/bin/python docs/scripts/groove_cut_study.py [cut faces frac] [--cav-width W]``
(``--cav-width``: the model's cav_width [Pa] instead of the default 1 kPa, penalty_smoothing
min(10, W / 10) Pa).
Prints one JSON line per solve (n, alpha_deg, d_over_dphi, Fx, Fy, wall_s).
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))          # repo root

from bearing_fmu.model import BearingParams, solve_stationary  # noqa: E402

R = 4.9e-3
W = math.radians(float(__import__("os").environ.get("GROOVE_DEG", "15")))
X0, Y0 = 2.547003e-06, -4.683927e-07          # tests/test_groove_width.py (250 Hz point)
OMEGA = 2 * math.pi * 250


CAV = {}
NS = [int(v) for v in __import__("os").environ.get("GROOVE_NS", "20,40,80,160").split(",")]


def force(n, alpha):
    p = BearingParams(R=R, B=1.6 * R, psi=2.8e-3, eta0=0.012, p0=1e5, p_feed=1e5, **CAV,
                      n_phi=n, n_z=n, cavitation=1, axial_bc=1, groove_width=W,
                      groove_angle=math.pi / 2 + alpha, newton_atol=1e-10, newton_rtol=1e-11)
    ca, sa = math.cos(alpha), math.sin(alpha)
    b = solve_stationary(p, ca * X0 - sa * Y0, sa * X0 + ca * Y0, OMEGA)
    Fx, Fy = b.outputs["Fx"], b.outputs["Fy"]
    return ca * Fx + sa * Fy, -sa * Fx + ca * Fy


def cut_fraction(n, alpha):
    """d / dphi of the film cell west of the groove (grid.groove_weights)."""
    dphi = 2 * math.pi / n
    edge = math.pi / 2 + alpha - W / 2
    phi = dphi * np.arange(n)
    inside = np.abs((phi - (math.pi / 2 + alpha) + math.pi) % (2 * math.pi) - math.pi) <= W / 2 + 1e-12
    i = max(k for k in range(n) if not inside[k] and phi[k] < edge)
    return ((edge - phi[i]) % (2 * math.pi)) / dphi


def run(n, alpha):
    t = time.time()
    Fx, Fy = force(n, alpha)
    print(json.dumps(dict(**CAV, n=n, alpha_deg=math.degrees(alpha), d_over_dphi=cut_fraction(n, alpha),
                          Fx=Fx, Fy=Fy, wall_s=round(time.time() - t, 1))), flush=True)


def main(argv):
    if "--cav-width" in argv:
        k = argv.index("--cav-width")
        w = float(argv[k + 1])
        CAV.update(cav_width=w, penalty_smoothing=min(10.0, w / 10))
        argv = argv[:k] + argv[k + 2:]
    if "--tt" in argv:
        k = argv.index("--tt")
        CAV.update(theta_transport=int(argv[k + 1]))
        argv = argv[:k] + argv[k + 2:]
    which = argv or ["cut", "faces", "frac"]
    if "frac" in which:
        n = 40
        dphi = 2 * math.pi / n
        for f in (0.1, 0.3, 0.5, 0.7, 0.9):
            # west edge at phi_i + f dphi for the film cell i west of it: edge = 81 deg + f dphi
            run(n, math.radians(81.0) + f * dphi - (math.pi / 2 - W / 2))
    if "cut" in which:
        for n in NS:
            run(n, 0.0)
    if "faces" in which:
        for n in (24, 48, 96, 192):
            dphi = 2 * math.pi / n
            k = (math.pi / 2 - W / 2) / dphi          # edges on faces: edge = (m + 1/2) dphi
            run(n, (math.floor(k) + 0.5) * dphi - (math.pi / 2 - W / 2))


if __name__ == "__main__":
    main(sys.argv[1:])
