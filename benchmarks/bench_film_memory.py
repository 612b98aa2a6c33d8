"""Memory and time of the journal-bearing film at the grid's cell limit (session 19).

Each case runs in its own Python process (so that its peak RSS is its own): a tiny warm-up
model first (imports and numba's compiled kernels, the "base" column), then the bearing
model at the requested grid: construction, ``initialize`` (flooded film), and ``--steps``
macro steps of ``--dt`` on the whirl orbit of benchmarks/bench_bearing.py (eps 0.45 ... 0.75,
800 Hz). Reported per case: the grid the solver works on (half width when the mass-conserving
film is symmetric: even n_z), the band half width bw and ordering, the Newton band matrix
``ab`` ((3 bw + 1) x n doubles), the RSS after the warm-up ("base"; its peak, numba's
compiler included, in brackets), peak RSS (``ru_maxrss``) after each phase, peak - base (what
the film costs), the time of the first and of the later steps [s], the film's internal steps
per macro step and the time per internal step. ``est`` is
:func:`bearing_fmu.model.film_memory_estimate`.

The child runs under ``prlimit --as`` (``--limit-gb``, default 12) so that a case that needs
more fails with MemoryError instead of pushing the shared machine into swap/OOM.

Run:  PYTHONPATH=. .venv/bin/python benchmarks/bench_film_memory.py [--quick] [--cases NAME ...]
      (--list shows the cases; --one NAME is the child, not for direct use)
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import resource
import subprocess
import sys
import time

DEG15 = math.radians(15)
# name: (n_phi, n_z, cavitation, axial_bc, groove_width)
MC_AIR = dict(cavitation=1, axial_bc=1, groove_width=DEG15)     # free to air, fed by the groove
MC_BATH = dict(cavitation=1, axial_bc=0, groove_width=0.0)      # oil bath, no groove: widest band
HS = dict(cavitation=0, axial_bc=1, groove_width=DEG15)         # half-Sommerfeld
CASES = {
    "air-256x256": (256, 256, MC_AIR), "air-512x256": (512, 256, MC_AIR),
    "air-512x512": (512, 512, MC_AIR), "air-8192x32": (8192, 32, MC_AIR),
    "air-128x2048": (128, 2048, MC_AIR), "air-513x511": (513, 511, MC_AIR),
    "bath-256x256": (256, 256, MC_BATH), "bath-512x256": (512, 256, MC_BATH),
    "bath-512x512": (512, 512, MC_BATH), "bath-8192x32": (8192, 32, MC_BATH),
    "bath-128x2048": (128, 2048, MC_BATH),
    "hs-256x256": (256, 256, HS), "hs-512x512": (512, 512, HS),
    "hs-8192x32": (8192, 32, HS), "hs-128x2048": (128, 2048, HS),
}
QUICK = ["air-256x256", "bath-256x256", "hs-256x256"]


def _rss_mb():
    """Peak resident set size of this process so far [MiB]."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _rss_now_mb():
    """Resident set size now [MiB] (/proc/self/statm)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def _orbit(c, w, t):
    return (0.15 * c * math.cos(w * t), -0.6 * c + 0.15 * c * math.sin(w * t),
            -0.15 * c * w * math.sin(w * t), 0.15 * c * w * math.cos(w * t), w)


def child(name, steps, dt, init="flooded"):
    from bearing_fmu.model import BearingModel, BearingParams, film_memory_estimate
    n_phi, n_z, kw = CASES[name]
    w = 2 * math.pi * 800
    warm = BearingModel(BearingParams(n_phi=16, n_z=4, **kw))    # imports + compiled kernels
    warm.initialize(*_orbit(warm.c, w, 0.0))
    warm.step(dt, *_orbit(warm.c, w, dt))
    del warm
    gc.collect()
    out = dict(case=name, n_phi=n_phi, n_z=n_z, base_mb=_rss_now_mb(), warm_peak_mb=_rss_mb())
    p = BearingParams(n_phi=n_phi, n_z=n_z, **kw)
    out["est_mb"] = film_memory_estimate(p) / 2**20
    t0 = time.perf_counter()
    b = BearingModel(p)
    out.update(t_build=time.perf_counter() - t0, build_mb=_rss_mb(), bw=b.grid.bw,
               ordering=b.grid.ordering, n=b.grid.n,
               ab_mb=(b.film.ab.nbytes / 2**20 if b.film is not None else 0.0))
    t0 = time.perf_counter()
    b.initialize(*_orbit(p.c, w, 0.0), init=init)
    out.update(t_init=time.perf_counter() - t0, init_mb=_rss_mb())
    times = []
    micro = []
    for k in range(1, steps + 1):
        t0 = time.perf_counter()
        m0 = b.stats.get("steps", 0)
        b.step(dt, *_orbit(p.c, w, k * dt))
        times.append(time.perf_counter() - t0)
        micro.append(b.stats.get("steps", 0) - m0)
    later = sum(micro[1:])
    out.update(t_first=times[0], t_later=(sorted(times[1:])[len(times[1:]) // 2] if steps > 1 else None),
               micro=micro, t_micro=(sum(times[1:]) / later if later else None),
               peak_mb=_rss_mb(), stats=b.stats, Fy=b.outputs["Fy"], eps=b.outputs["eps"])
    print("RESULT " + json.dumps(out), flush=True)


def run_case(name, steps, dt, limit_gb, init="flooded"):
    cmd = [sys.executable, __file__, "--one", name, "--steps", str(steps), "--dt", str(dt), "--init", init]
    if limit_gb > 0:
        cmd = ["prlimit", f"--as={int(limit_gb * 2**30)}"] + cmd
    t0 = time.perf_counter()
    pr = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    for line in pr.stdout.splitlines():
        if line.startswith("RESULT "):
            r = json.loads(line[7:])
            r["wall"] = wall
            return r
    tail = (pr.stderr.strip().splitlines() or ["?"])[-1]
    return dict(case=name, error=f"exit {pr.returncode}: {tail}", wall=wall)


def fmt(r):
    if "error" in r:
        return f"| {r['case']} | | | | | | | | | | | | | failed: {r['error']} |"
    later = "" if r["t_later"] is None else f"{r['t_later']:.2f}"
    per = "" if r.get("t_micro") is None else f"{r['t_micro']:.2f}"
    return (f"| {r['case']} | {r['n_phi'] * r['n_z']} | {r['n']} | {r['bw']} ({r['ordering']}) | "
            f"{r['ab_mb']:.0f} | {r['est_mb']:.0f} | {r['base_mb']:.0f} ({r['warm_peak_mb']:.0f}) | "
            f"{r['build_mb']:.0f} | {r['init_mb']:.0f} | {r['peak_mb']:.0f} | "
            f"**{r['peak_mb'] - r['base_mb']:.0f}** | {r['t_build']:.2f} / {r['t_init']:.2f} | "
            f"{r['t_first']:.2f} / {later} | {'+'.join(map(str, r['micro']))} | {per} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--cases", nargs="*", help="case names (default: all; --list)")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--quick", action="store_true", help="the 256 x 256 cases only")
    ap.add_argument("--steps", type=int, default=3)
    ap.add_argument("--dt", type=float, default=2e-6, help="macro step [s] (2e-6: 1-2 micro steps)")
    ap.add_argument("--init", choices=("flooded", "stationary"), default="flooded",
                    help="initial film (stationary: the steady film by Newton, as the scenarios' init)")
    ap.add_argument("--limit-gb", type=float, default=12.0, help="address-space limit per case (0: none)")
    a = ap.parse_args(argv)
    if a.one:
        child(a.one, a.steps, a.dt, a.init)
        return
    if a.list:
        for k, (n_phi, n_z, kw) in CASES.items():
            print(k, n_phi, n_z, kw)
        return
    names = a.cases or (QUICK if a.quick else list(CASES))
    up = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"# bench_film_memory  {time.strftime('%Y-%m-%d %H:%M:%S')}  cores={os.cpu_count()}  "
          f"steps={a.steps} dt={a.dt:g}  init={a.init}  limit={a.limit_gb:g} GiB\n# uptime: {up}")
    print("| case | cells | solver n | bw (ordering) | ab MiB | est MiB | base MiB (peak) | peak after build | "
          "after init | after steps | peak - base | s build / init | s step 1 / later | film steps | "
          "s per film step (later) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in names:
        print(fmt(run_case(name, a.steps, a.dt, a.limit_gb, a.init)), flush=True)


if __name__ == "__main__":
    main()
