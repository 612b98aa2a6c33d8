"""Benchmark of the bearing film solver (issue 3, Performance).

Case: mass-conserving model, 15 deg feed groove at the top, oil bath, journal
orbiting at 800 Hz on a circle of radius 0.15 c around (0, -0.6 c) (so |eps|
runs 0.45 ... 0.75, synchronous whirl that carries load), macro step
dt = 1e-5 s (125 per revolution), started from the stationary film. Reported:
CPU time (process, all threads) per call, median and 90th percentile wall
time per ``step`` call and per internal
(micro) step, Newton iterations, LU factorisations and GMRES iterations per
micro-step, memory (tracemalloc peak over 10 further steps, and the solver's arrays).
The peer is the same discretisation solved with plain scipy ``splu`` and a
full Newton (refactorisation every iteration). Also: the half-Sommerfeld
quasi-static solve on 40 x 40.

Run:  nice -n 10 .venv/bin/python benchmarks/bench_bearing.py [--quick]
The machine is shared: the load (uptime) is printed with the numbers.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import time
import tracemalloc

import numpy as np

from bearing_fmu.model import BearingParams, BearingModel


def orbit(c, w, t):
    return (0.15 * c * math.cos(w * t), -0.6 * c + 0.15 * c * math.sin(w * t),
            -0.15 * c * w * math.sin(w * t), 0.15 * c * w * math.cos(w * t), w)


def run_case(n_phi, n_z, n_steps, *, peer=False, warmup=20, dt=1e-5):
    p = BearingParams(n_phi=n_phi, n_z=n_z, groove_width=math.radians(15),
                      groove_angle=math.pi / 2,
                      linear_solver="splu" if peer else "band")
    b = BearingModel(p)
    w = 2 * math.pi * 800
    b.initialize(*orbit(p.c, w, 0.0), init="stationary")
    if peer:
        b.film.full_newton = True
    k = 0
    for _ in range(warmup):
        k += 1
        b.step(dt, *orbit(p.c, w, k * dt))
    s0 = dict(b.stats)
    times = []
    cpu0 = time.process_time()
    for _ in range(n_steps):
        k += 1
        kin = orbit(p.c, w, k * dt)
        t0 = time.perf_counter()
        b.step(dt, *kin)
        times.append(time.perf_counter() - t0)
    cpu = (time.process_time() - cpu0) / n_steps * 1e3
    st = {key: b.stats[key] - s0[key] for key in s0}
    tracemalloc.start()                 # memory in a separate, untimed pass
    for _ in range(10):
        k += 1
        b.step(dt, *orbit(p.c, w, k * dt))
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    ms = np.array(times) * 1e3
    f = b.film
    arrays = sum(a.nbytes for a in (f.ab, f.jst, f.u, f.th_nm1, f.th_nm2, f.u_prev))
    micro = st["steps"] / n_steps
    return dict(grid=f"{n_phi}x{n_z}", solver="splu full Newton (peer)" if peer else "band LU full Newton (half width)",
                bw=b.grid.bw, cpu=cpu, med=float(np.median(ms)), p90=float(np.percentile(ms, 90)),
                micro=micro, med_micro=float(np.median(ms)) / micro,
                newton=st["newton"] / st["steps"], factor=st["factor"] / st["steps"],
                krylov=st["krylov"] / st["steps"], rejected=st["rejected"],
                peak_mb=peak / 2**20, arrays_mb=arrays / 2**20,
                eps=b.outputs["eps"], Fy=b.outputs["Fy"])


def run_hs(n=500):
    p = BearingParams(cavitation=0, groove_width=math.radians(15), groove_angle=math.pi / 2)
    b = BearingModel(p)
    w = 2 * math.pi * 800
    b.initialize(*orbit(p.c, w, 0.0))
    t_solve, t_step = [], []
    for k in range(n):
        kin = orbit(p.c, w, (k + 1) * 1e-5)
        K = b._kinematics(*kin)
        t0 = time.perf_counter()
        b.hs.solve(*K)
        t1 = time.perf_counter()
        b.step(1e-5, *kin)
        t2 = time.perf_counter()
        t_solve.append(t1 - t0)
        t_step.append(t2 - t1)
    return float(np.median(t_solve) * 1e3), float(np.median(t_step) * 1e3)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer steps (smoke run)")
    ap.add_argument("--small", action="store_true", help="only the 40 x 40 cases")
    a = ap.parse_args(argv)
    up = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"# bench_bearing  {time.strftime('%Y-%m-%d %H:%M:%S')}  cores={os.cpu_count()}")
    print(f"# uptime before: {up}")
    q = 0.25 if a.quick else 1.0
    cases = [(40, 40, int(300 * q), False), (40, 40, int(40 * q), True),
             (80, 80, int(100 * q), False), (160, 40, int(100 * q), False)]
    if a.small:
        cases = cases[:2]
    rows = [run_case(nphi, nz, n, peer=peer) for nphi, nz, n, peer in cases]
    hs_solve, hs_step = run_hs(int(500 * q))
    hdr = ("grid", "solver", "bw", "CPU ms/call (mean)", "wall ms/call med", "p90", "micro/call", "ms/micro",
           "newton/micro", "LU/micro", "gmres/micro", "rejected", "peak MB", "arrays MB")
    print("| " + " | ".join(hdr) + " |")
    print("|" + "---|" * len(hdr))
    for r in rows:
        print(f"| {r['grid']} | {r['solver']} | {r['bw']} | {r['cpu']:.2f} | {r['med']:.2f} | {r['p90']:.2f} | "
              f"{r['micro']:.2f} | {r['med_micro']:.2f} | {r['newton']:.2f} | "
              f"{r['factor']:.2f} | {r['krylov']:.1f} | {r['rejected']} | "
              f"{r['peak_mb']:.1f} | {r['arrays_mb']:.1f} |")
    print(f"\nhalf-Sommerfeld 40x40: DST solve median {hs_solve:.3f} ms, "
          f"full step (solve + outputs) median {hs_step:.3f} ms")
    up = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"# uptime after: {up}")


if __name__ == "__main__":
    main()
