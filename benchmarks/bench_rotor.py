"""Cost per macro step of the rotor models' step() (owner: rotor).

Run:  cd /work/main && OPENBLAS_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/bench_rotor.py
      (ROTORCOSIM_ROTOR_KERNEL=numba for the compiled kernel; default numpy)
Goal (issue 4): turbocharger step at dt = 2e-5 s below 10 % of one bearing step
(~3 ms target) -> < 0.3 ms.  Prints the machine load (shared machine: numbers are noisy).
"""

from __future__ import annotations

import os
import subprocess
import time

import numpy as np

from rotor_fmu.jeffcott import JeffcottModel
from rotor_fmu.linear_rotor import KERNEL
from rotor_fmu.turbocharger import TurbochargerParams, TurbochargerRotor


def bench(rotor, dt=2e-5, n=2000, repeat=5):
    rotor.initialize()
    F = np.array([[0.0, 30.0]] * rotor.n_bearings)
    for _ in range(20):                      # JIT warm-up
        rotor.step(dt, F)
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(n):
            rotor.step(dt, F)
        best = min(best, (time.perf_counter() - t0) / n)
    return best


def main():
    dt = 2e-5
    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"uptime: {load}")
    print(f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}  kernel={KERNEL}")
    a, x = np.eye(18), np.ones(18)
    t0 = time.perf_counter()
    for _ in range(20000):
        a @ x
    print(f"machine speed probe: 18x18 mat-vec {(time.perf_counter() - t0) / 20000 * 1e6:.2f} us "
          "(compare between runs: it scales with the machine load)")
    rows = [("jeffcott", JeffcottModel())]
    for nm in (2, 4, 6):
        rows.append((f"turbocharger CB n_modes={nm}", TurbochargerRotor(TurbochargerParams(n_modes=nm))))
    print(f"{'model':32s} {'n_dof':>5s} {'n_sub':>5s} {'us/step (best of 5)':>20s}")
    for name, r in rows:
        c = bench(r, dt)
        print(f"{name:32s} {r.n_dof:5d} {r.n_substeps(dt):5d} {c * 1e6:20.1f}")
    r = TurbochargerRotor(TurbochargerParams(reduce=False))
    c = bench(r, dt, n=2, repeat=1)
    print(f"{'turbocharger full FE':32s} {r.n_dof:5d} {r.n_substeps(dt):5d} {c * 1e6:20.1f}")


if __name__ == "__main__":
    main()
