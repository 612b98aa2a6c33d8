"""Cost of one floating-ring bearing step against plain bearing steps (issue 17, BENCHMARKS.md).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_floating_ring.py [--cav 0|1] [--steps N] [--repeats R]

Per repeat, interleaved: N steps of dt = 0.1 ms of (a) the FloatingRing model (both films,
the ring sub-step, the films' coefficients refreshed every step) and (b) one plain
JournalBearing of the inner film's geometry stepping the same journal and computing its
coefficients every step (what a plain bearing with ``linearize = 1`` does). The journal sits
at the static equilibrium of the Jeffcott floating-ring case at 100 Hz with a small orbit.
Prints the median ms per step of each and their ratio.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

from bearing_fmu.floating_ring import FloatingRing, RingParams, static_equilibrium
from bearing_fmu.linearize import linearization
from bearing_fmu.model import BearingParams, BearingModel


def cases(cav):
    kw = dict(n_phi=40, n_z=40, cavitation=cav, axial_bc=1 if cav else 0,
              groove_width=math.radians(15.0) if cav else 0.0)
    inner = BearingParams(R=4.9e-3, B=7.84e-3, psi=2.8e-3, eta0=0.012, **kw)
    outer = BearingParams(R=7.84e-3, B=7.84e-3, psi=3.5e-3, eta0=0.012, **kw)
    return inner, RingParams(inner=inner, outer=outer, m_ring=7.3e-3, J_ring=3.1e-7)


def run(cav, steps, repeats):
    inner, rp = cases(cav)
    om = 2 * math.pi * 100.0
    (xj, yj), ring = static_equilibrium(rp, 29.43, om)
    c = inner.c
    orbit = [(xj + 0.02 * c * math.cos(0.3 * k), yj + 0.02 * c * math.sin(0.3 * k)) for k in range(steps)]
    t_fr, t_jb = [], []
    for _ in range(repeats):
        fr = FloatingRing(rp)
        fr.initialize(xj, yj, 0.0, 0.0, om, ring=(*ring, 0.0, 0.0))
        t0 = time.perf_counter()
        for x, y in orbit:
            fr.step(1e-4, x, y, 0.0, 0.0, om)
        t_fr.append((time.perf_counter() - t0) / steps * 1e3)
        jb = BearingModel(inner)
        jb.initialize(xj - ring[0], yj - ring[1], 0.0, 0.0, om * 1.3)
        t0 = time.perf_counter()
        for x, y in orbit:
            jb.step(1e-4, x - ring[0], y - ring[1], 0.0, 0.0, om * 1.3)
            linearization(jb)
        t_jb.append((time.perf_counter() - t0) / steps * 1e3)
    a, b = statistics.median(t_fr), statistics.median(t_jb)
    print(f"cavitation {cav}: floating ring {a:.2f} ms/step (runs {', '.join(f'{v:.2f}' for v in t_fr)}), "
          f"plain bearing + coefficients {b:.2f} ms/step (runs {', '.join(f'{v:.2f}' for v in t_jb)}), "
          f"ratio {a / b:.2f}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cav", type=int, default=0)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    run(a.cav, a.steps, a.repeats)


if __name__ == "__main__":
    main()
