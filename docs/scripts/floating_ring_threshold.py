"""Linear stability threshold of the Jeffcott rotor in two floating-ring bearings
(scenarios/jeffcott_runup_floating_ring_half_sommerfeld.yaml), docs/floating-ring.md.

    .venv/bin/python docs/scripts/floating_ring_threshold.py [f_lo f_hi]

Prints the least-damped eigenvalues on a speed grid and the threshold (Brent on max Re = 0).
"""

from __future__ import annotations

import math
import sys

import numpy as np

from rotor_fmu.floating_ring_growth import jeffcott_floating_ring
from rotor_fmu.floating_ring_stability import ring_system_eigen, ring_threshold_speed


def main(f_lo=690.0, f_hi=760.0):
    rotor, rings = jeffcott_floating_ring()
    for f in np.linspace(f_lo, f_hi, 3):
        lam, pts = ring_system_eigen(rotor, rings, 2 * math.pi * f)
        k = np.argsort(-lam.real)[:4:2]
        o = pts[0].outputs
        print(f"{f:7.1f} Hz: ring ratio {o['omega_ring'] / (2 * math.pi * f):.4f}, eps {o['eps']:.4f}, "
              f"eps_outer {o['eps_outer']:.4f}; least damped "
              + ", ".join(f"{lam[i].real:+.2f} 1/s at {abs(lam[i].imag) / (2 * math.pi):.1f} Hz" for i in k))
    w, nu = ring_threshold_speed(rotor, rings, 2 * math.pi * f_lo, 2 * math.pi * f_hi, n_scan=3)
    if w is None:
        print(f"stable from {f_lo} to {f_hi} Hz")
    else:
        print(f"threshold {w / (2 * math.pi):.2f} Hz, whirl {nu / (2 * math.pi):.2f} Hz "
              f"(ratio {nu / w:.4f})")


if __name__ == "__main__":
    main(*(float(a) for a in sys.argv[1:3]))
