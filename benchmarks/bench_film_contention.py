"""What this machine gives two films stepping at the same time (issue 14, the 0.6x goal).

    .venv/bin/python benchmarks/bench_film_contention.py [--steps 1500] [--repeat 3] [--bath]

The worker mode's parallel stage runs two mass-conserving films at once, one per core. Its
best wall time per macro step is the serial part (rotor and master) plus the time ONE film
step takes while the other core runs the other film. On a 2-core virtual machine that is not
the film's time alone: the two vCPUs share the host's caches and memory bandwidth (and may be
hyperthreads of one host core). This benchmark measures that factor with the run-up's own
film (``benchmarks/bench_bearing_whirl.py``, the whirl orbit of the Jeffcott bearing, 40 x
40): each round runs the film alone in one process, then two identical processes at once,
interleaved ``--repeat`` times. It prints the median wall ms per film step alone and together,
their ratio (the slowdown of a film step when both cores work), and, with the run-up's CPU
split from ``bench_runup_workers.py --split`` (``--split R,F``: serial ms, in-process total
ms per macro step), the best ratio a two-core parallel stage can reach on this machine:
``(R + F1 * slowdown) / total`` where F1 is the larger film's share.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _cmd(steps: int, bath: bool) -> list[str]:
    return [sys.executable, str(REPO / "benchmarks" / "bench_bearing_whirl.py"), "--steps", str(steps),
            *(["--bath"] if bath else [])]


def _ms_per_call(out: str) -> float:
    """The median wall ms per call from bench_bearing_whirl's key=value line."""
    fields = dict(kv.split("=", 1) for kv in out.split() if "=" in kv)
    for key in ("med_ms",):
        if key in fields:
            return float(fields[key])
    raise SystemExit(f"bench_bearing_whirl printed no median ms per call: {out!r}")


def _run(n: int, steps: int, bath: bool) -> list[float]:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    procs = [subprocess.Popen(_cmd(steps, bath), stdout=subprocess.PIPE, text=True, env=env, cwd=REPO)
             for _ in range(n)]
    outs = [p.communicate()[0] for p in procs]
    if any(p.returncode for p in procs):
        raise SystemExit(f"bench_bearing_whirl failed: {[p.returncode for p in procs]}")
    return [_ms_per_call(o.strip().splitlines()[-1]) for o in outs]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--bath", action="store_true", help="the oil-bath film (the shipped run-up's)")
    ap.add_argument("--split", default="", metavar="R,F1,TOTAL",
                    help="serial ms, larger film ms, in-process total ms per macro step (bench_runup_workers --split)")
    a = ap.parse_args(argv)
    alone, together = [], []
    print(f"load before: {os.getloadavg()[0]:.2f}")
    for k in range(a.repeat):
        t0 = time.perf_counter()
        alone += _run(1, a.steps, a.bath)
        together += _run(2, a.steps, a.bath)
        print(f"  round {k}: alone {alone[-1]:.3f} ms, together {together[-2]:.3f} / {together[-1]:.3f} ms "
              f"({time.perf_counter() - t0:.0f} s, load {os.getloadavg()[0]:.2f})")
    m1, m2 = statistics.median(alone), statistics.median(together)
    print(f"film step, median of {len(alone)} / {len(together)}: alone {m1:.3f} ms, both cores busy {m2:.3f} ms, "
          f"slowdown {m2 / m1:.3f}x; load after {os.getloadavg()[0]:.2f}")
    if a.split:
        r, f1, total = (float(v) for v in a.split.split(","))
        best = (r + f1 * m2 / m1) / total
        print(f"best two-core parallel stage on this machine: ({r} + {f1} x {m2 / m1:.3f}) / {total} = {best:.3f}x "
              f"(no channel cost; {(r + f1) / total:.3f}x if both cores ran as one alone)")


if __name__ == "__main__":
    main()
