"""Cost per film step in a whirl orbit, the film as the Jeffcott run-up uses it (issue 16).

Case: the bearing of ``scenarios/jeffcott_runup_free_to_air.yaml`` (R 4.9 mm, B/D 0.8, psi
2.8e-3, 15 deg groove at the top, 40 x 40, mass-conserving, free to air; ``--bath`` the oil
bath), spin 500 Hz, the journal on a circular whirl orbit of radius 0.55 c about the bearing
centre at 0.45 x the spin frequency (a forward sub-synchronous whirl as in the run-up's oil
whip; at exactly 0.5 a centred orbit carries no film pressure), macro step 0.1 ms. Each call
is what the bearing FMU does per macro step with ``linearize: 1``: ``get_state`` (kept for a
retry), ``step``, and the interface coefficients ``linearization``. The film starts from its
stationary solution and takes ``--warmup`` orbit steps (2 whirl periods) before timing.

Prints one line of key=value (parsed by the same script in ``--compare`` mode): median and
mean wall ms per call, the CPU ms per call (process time), and the film and coefficient
parts, with internal steps, Newton iterations and LU factorisations per call; the final
force (for a same-answer check between old and new code).

Run (old and new code, same session):
    nice .venv/bin/python benchmarks/bench_bearing_whirl.py [--steps 400] [--bath]
    PYTHONPATH=/tmp/film_old .venv/bin/python benchmarks/bench_bearing_whirl.py
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import bearing_fmu
from bearing_fmu.linearize import linearization
from bearing_fmu.model import BearingParams, BearingModel


def orbit(c, spin_hz, ratio, eps, t):
    w = 2 * math.pi * spin_hz
    nu = ratio * w
    r = eps * c
    return (r * math.cos(nu * t), r * math.sin(nu * t), -r * nu * math.sin(nu * t),
            r * nu * math.cos(nu * t), w)


def run(steps, warmup, bath, spin_hz=500.0, ratio=0.45, eps=0.55, dt=1e-4, n=40):
    p = BearingParams(R=4.9e-3, B=7.84e-3, psi=2.8e-3, eta0=0.012, p0=1e5, p_feed=1e5,
                      n_phi=n, n_z=n, cavitation=1, axial_bc=0 if bath else 1,
                      groove_width=math.radians(15), groove_angle=math.pi / 2)
    b = BearingModel(p)
    b.initialize(*orbit(p.c, spin_hz, ratio, eps, 0.0), init="stationary")
    k = 0
    for _ in range(warmup):
        k += 1
        b.get_state()
        b.step(dt, *orbit(p.c, spin_hz, ratio, eps, k * dt))
        linearization(b)
    s0 = dict(b.stats)
    wall, t_film, t_lin = [], 0.0, 0.0
    cpu0 = time.process_time()
    for _ in range(steps):
        k += 1
        kin = orbit(p.c, spin_hz, ratio, eps, k * dt)
        t0 = time.perf_counter()
        b.get_state()
        b.step(dt, *kin)
        t1 = time.perf_counter()
        linearization(b)
        t2 = time.perf_counter()
        wall.append(t2 - t0)
        t_film += t1 - t0
        t_lin += t2 - t1
    cpu = (time.process_time() - cpu0) / steps * 1e3
    st = {key: (b.stats[key] - s0[key]) / steps for key in s0}
    ms = np.array(wall) * 1e3
    return dict(med_ms=float(np.median(ms)), mean_ms=float(ms.mean()), cpu_ms=cpu,
                film_ms=t_film / steps * 1e3, coef_ms=t_lin / steps * 1e3,
                micro=st["steps"], newton=st["newton"], lu=st["factor"],
                Fx=b.outputs["Fx"], Fy=b.outputs["Fy"], eps=b.outputs["eps"])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--warmup", type=int, default=90)
    ap.add_argument("--bath", action="store_true", help="oil-bath edges instead of free to air")
    a = ap.parse_args(argv)
    r = run(a.steps, a.warmup, a.bath)
    code = bearing_fmu.__file__.rsplit("/", 2)[0]
    print(f"code={code} bc={'bath' if a.bath else 'air'} steps={a.steps} "
          + " ".join(f"{k}={v:.6g}" for k, v in r.items()))


if __name__ == "__main__":
    main()
