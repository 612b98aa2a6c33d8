"""Two film bearings stepped one after the other against the same two in two threads,
without the master (issue 16: how much of a bearing step runs without the GIL).

Case: the whirl orbit of ``bench_bearing_whirl.py`` (40 x 40, free to air, 500 Hz, eps 0.55,
0.1 ms steps) for two independent ``BearingModel`` s; each call is what the bearing FMU does
per macro step: ``get_state``, ``step`` and (unless ``--no-coefficients``) the interface
coefficients. Sequential: both in this thread; threads: the second in a pool thread at the
same time (``coupling.parallel: threads`` does the same with the FMUs). Prints, per repeat,
the wall ms per macro step of both variants and their ratio (interleaved).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_bearing_threads.py [--steps 200] [--repeats 3]
"""

from __future__ import annotations

import argparse
import math
import time
from concurrent.futures import ThreadPoolExecutor

from bench_bearing_whirl import orbit

from bearing_fmu.linearize import linearization
from bearing_fmu.model import BearingModel, BearingParams


def make():
    p = BearingParams(R=4.9e-3, B=7.84e-3, psi=2.8e-3, eta0=0.012, p0=1e5, p_feed=1e5, n_phi=40,
                      n_z=40, cavitation=1, axial_bc=1, groove_width=math.radians(15),
                      groove_angle=math.pi / 2)
    b = BearingModel(p)
    b.initialize(*orbit(p.c, 500.0, 0.45, 0.55, 0.0), init="stationary")
    return b


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--warmup", type=int, default=60)
    ap.add_argument("--no-coefficients", action="store_true")
    a = ap.parse_args(argv)
    films = [make(), make()]
    lin = not a.no_coefficients
    k = [0]

    def job(b, n):
        b.get_state()
        b.step(1e-4, *orbit(b.c, 500.0, 0.45, 0.55, n * 1e-4))
        if lin:
            linearization(b)

    pool = ThreadPoolExecutor(1)

    def sequential(n):
        t = time.perf_counter()
        for _ in range(n):
            k[0] += 1
            for b in films:
                job(b, k[0])
        return (time.perf_counter() - t) / n * 1e3

    def threads(n):
        t = time.perf_counter()
        for _ in range(n):
            k[0] += 1
            f = pool.submit(job, films[1], k[0])
            job(films[0], k[0])
            f.result()
        return (time.perf_counter() - t) / n * 1e3

    sequential(a.warmup)
    for r in range(a.repeats):
        s = sequential(a.steps)
        q = threads(a.steps)
        print(f"repeat {r}: sequential {s:.3f} ms, threads {q:.3f} ms per macro step, ratio {q / s:.2f}")
    pool.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
