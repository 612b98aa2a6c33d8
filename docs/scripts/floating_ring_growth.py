"""Growth rate of the floating-ring Jeffcott rotor's whirl at constant speed: linear eigenvalue,
monolithic nonlinear model, co-simulation (rotor_fmu/floating_ring_growth.py; docs/floating-ring.md).

    .venv/bin/python docs/scripts/floating_ring_growth.py F_HZ mono [T]
    .venv/bin/python docs/scripts/floating_ring_growth.py F_HZ cosim H [T [J_ring [coeffs [n_sub [input_hold [ring_integrator]]]]]]

F_HZ "tc60": the turbocharger in floating rings at 60 Hz instead of the Jeffcott rotor.
T [s] default 0.1; J_ring default 1e3 kg m^2 (spin held, like ``mono`` and the linear model),
3.1e-7 the real ring (spin free); coeffs 0 the FMU's K_i, C_i, H the step coefficients, -1 the
velocity-slaved ones; n_sub ring sub-steps per macro step; input_hold, ring_integrator as the
FMU parameters (default: the FMU's defaults, 2 and 1).
"""

from __future__ import annotations

import math
import sys
import time

from rotor_fmu.floating_ring_growth import Case, turbocharger_floating_ring


def main(argv):
    tc = argv[0].startswith("tc")           # "tc60": the turbocharger in floating rings at 60 Hz
    f, how = float(argv[0].removeprefix("tc")), argv[1]
    case = Case(f, rotor=None if not tc else turbocharger_floating_ring(f_max=f, t_ramp=0.0)[0],
                rings=None if not tc else turbocharger_floating_ring()[1])
    print(f"{f:g} Hz linear: {case.lam.real:+.2f} 1/s at {abs(case.lam.imag) / (2 * math.pi):.2f} Hz")
    t0 = time.time()
    if how == "mono":
        t, Z = case.mono(float(argv[2]) if len(argv) > 2 else 0.1)
        label = "mono"
    else:
        H = float(argv[2])
        T = float(argv[3]) if len(argv) > 3 else 0.1
        Jr = float(argv[4]) if len(argv) > 4 else 1e3
        co = float(argv[5]) if len(argv) > 5 else 0.0
        ns = int(argv[6]) if len(argv) > 6 else 1
        ih = int(argv[7]) if len(argv) > 7 else None
        ri = int(argv[8]) if len(argv) > 8 else None
        t, Z = case.cosim(T, H, Jr, co, n_sub=ns, input_hold=ih, ring_integrator=ri)
        label = f"cosim H={H:g} J_ring={Jr:g} coeffs={co:g} n_sub={ns} input_hold={ih} ring_integrator={ri}"
    poles = case.rates(t, Z)
    print(f"{label} ({time.time() - t0:.0f} s): " + ", ".join(f"{a:+.2f} 1/s at {b:.1f} Hz (energy {e:.2g})" for a, b, e in poles[:4]))


if __name__ == "__main__":
    main(sys.argv[1:])
