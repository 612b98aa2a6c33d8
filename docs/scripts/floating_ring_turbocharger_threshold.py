"""Linear stability of the turbocharger rotor in two floating-ring bearings
(scenarios/turbocharger_runup_floating_ring_half_sommerfeld.yaml; docs/floating-ring.md):

    .venv/bin/python docs/scripts/floating_ring_turbocharger_threshold.py

Prints, at a few speeds, the ring speed ratios and eccentricities of both stations and the
least-damped eigenvalues, then the thresholds (Brent on max Re = 0) where the rotor loses and
regains stability between 30 and 110 Hz.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from rotor_fmu.floating_ring_growth import turbocharger_floating_ring
from rotor_fmu.floating_ring_stability import ring_system_eigen


def max_re(rotor, rings, f):
    lam, pts = ring_system_eigen(rotor, rings, 2 * math.pi * f)
    k = int(np.argmax(lam.real))
    return lam[k], pts


def main():
    rotor, rings = turbocharger_floating_ring()
    for f in (30, 40, 50, 60, 80, 100, 110, 150):
        lam, pts = ring_system_eigen(rotor, rings, 2 * math.pi * f)
        k = np.argsort(-lam.real)[:4:2]
        print(f"{f:5.0f} Hz: ring ratio " + ", ".join(f"{p.outputs['omega_ring'] / (2 * math.pi * f):.3f}" for p in pts)
              + "; eps " + ", ".join(f"{p.outputs['eps']:.3f}/{p.outputs['eps_outer']:.3f}" for p in pts)
              + "; least damped " + ", ".join(f"{lam[i].real:+.2f} 1/s at {abs(lam[i].imag) / (2 * math.pi):.1f} Hz"
                                             for i in k))
    g = lambda f: max_re(rotor, rings, f)[0].real
    for lo, hi in ((30.0, 60.0), (100.0, 103.0), (104.0, 108.0)):
        f0 = brentq(g, lo, hi, xtol=1e-3)
        lam, _ = max_re(rotor, rings, f0)
        print(f"crossing at {f0:.2f} Hz, whirl {abs(lam.imag) / (2 * math.pi):.2f} Hz (order {abs(lam.imag) / (2 * math.pi * f0):.3f})")


if __name__ == "__main__":
    main()
