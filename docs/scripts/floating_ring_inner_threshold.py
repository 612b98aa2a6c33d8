"""Linear threshold of the INNER-film whirl of the Jeffcott rotor in floating rings
(docs/floating-ring.md, "The inner-film whirl near its threshold").

    .venv/bin/python docs/scripts/floating_ring_inner_threshold.py [f_lo f_hi] [--spin]

The inner-film mode is the least-damped eigenvalue whose whirl frequency lies in 0.5-0.8 x the
journal speed (near 0.5 (journal + ring)); the outer-film whirl (order ~0.13) is unstable from
712.9 Hz on and is left out. Prints that mode on a speed grid, its zero crossing (Brent), and
the journal and ring equilibria at f_lo (the seed of the run-up window).
"""

from __future__ import annotations

import math
import sys

import numpy as np
from scipy.optimize import brentq

from rotor_fmu.floating_ring_growth import jeffcott_floating_ring
from rotor_fmu.floating_ring_stability import ring_system_eigen

TWO_PI = 2 * math.pi


def inner_mode(rotor, rings, f, spin=False):
    lam, pts = ring_system_eigen(rotor, rings, TWO_PI * f, spin=spin)
    order = np.abs(lam.imag) / (TWO_PI * f)
    k = np.flatnonzero((order > 0.5) & (order < 0.8) & (lam.imag > 0))
    i = k[np.argmax(lam[k].real)]
    return lam[i], pts


def main(argv):
    spin = "--spin" in argv
    a = [float(v) for v in argv if not v.startswith("--")]
    f_lo, f_hi = (a + [840.0, 900.0][len(a):])[:2]
    rotor, rings = jeffcott_floating_ring()
    grid = np.linspace(f_lo, f_hi, 4)
    vals = []
    for f in grid:
        lam, pts = inner_mode(rotor, rings, f, spin)
        o = pts[0].outputs
        vals.append(lam.real)
        print(f"{f:7.1f} Hz: ring ratio {o['omega_ring'] / (TWO_PI * f):.4f}, inner mode "
              f"{lam.real:+.3f} 1/s at {lam.imag / TWO_PI:.2f} Hz (order {lam.imag / (TWO_PI * f):.4f})")
        if f == grid[0]:
            fr = pts[0]
            print(f"   equilibrium at {f:.1f} Hz: journal ({fr._journal[0]:.6e}, {fr._journal[1]:.6e}) m, "
                  f"ring ({o['x_ring']:.6e}, {o['y_ring']:.6e}) m, omega_ring {o['omega_ring']:.3f} rad/s")
    s = np.sign(vals)
    j = np.flatnonzero(s[:-1] != s[1:])
    if not j.size:
        print("no crossing of the inner mode in the range")
        return
    g = lambda f: inner_mode(rotor, rings, f, spin)[0].real  # noqa: E731
    f0 = brentq(g, grid[j[0]], grid[j[0] + 1], xtol=0.01)
    lam, _ = inner_mode(rotor, rings, f0, spin)
    print(f"inner-film threshold {f0:.2f} Hz{' (ring spin free)' if spin else ''}, whirl "
          f"{lam.imag / TWO_PI:.2f} Hz (order {lam.imag / (TWO_PI * f0):.4f})")


if __name__ == "__main__":
    main(sys.argv[1:])
