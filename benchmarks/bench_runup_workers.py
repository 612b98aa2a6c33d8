"""The shipped mass-conserving Jeffcott run-up with the bearings in worker processes vs in process.

    nice -n 19 .venv/bin/python benchmarks/bench_runup_workers.py [--scenario oil_bath] [--stop 0.30]
        [--repeat 2] [--out /tmp/bench_runup_workers]
    nice -n 19 .venv/bin/python benchmarks/bench_runup_workers.py --split [--stop 0.27]   # CPU per FMU and step

Variants of scenarios/jeffcott_runup_<scenario>.yaml (Gauss-Seidel [rotor, bearing1,
bearing2], two 40 x 40 mass-conserving films, 0.1 ms macro steps), run from 0.25 s to
``--stop`` with ``rotorcosim run`` in a subprocess each, interleaved, ``--repeat`` times:

* ``in-process``: every FMU in the master, one after the other (the peer);
* ``workers, parallel``: bearing1 and bearing2 with ``isolation: process``,
  ``coupling.parallel: true`` (the two films step at the same time; the rotor stays in
  the master);
* ``workers, sequential``: the same, ``parallel: false`` (what the channel costs alone).

Recorded per run: wall time of the subprocess, its CPU time (user + system of the run and
of the workers it waited for, ``RUSAGE_CHILDREN``), ``wall_time_s`` of summary.json (the
master from setup to terminate), the load average before and after; results.csv of
every variant is compared with the in-process one byte for byte. The table gives medians
and ratios. On a loaded machine the wall ratio is not a parallel speed-up (three
runnable processes get a larger share of an overloaded CPU than one): read it with the
load, and the CPU ratio as the cost of isolation.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
VARIANTS = {
    "in-process": [],
    "workers, parallel": ["fmus.bearing1.isolation=process", "fmus.bearing2.isolation=process",
                          "coupling.parallel=true"],
    "workers, sequential": ["fmus.bearing1.isolation=process", "fmus.bearing2.isolation=process",
                            "coupling.parallel=false"],
}


def one_run(scenario: Path, stop: float, sets: list[str], out: Path) -> dict:
    cmd = [sys.executable, "-m", "orchestrator", "run", str(scenario), "--out", str(out), "--no-progress",
           "--set", f"stop_time={stop}"]
    for s in sets:
        cmd += ["--set", s]
    load0 = os.getloadavg()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    summary = json.loads((out / "summary.json").read_text())
    return {"wall": wall, "cpu": (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime),
            "master_wall": summary["wall_time_s"], "steps": summary["macro_steps"],
            "load": (load0[0], os.getloadavg()[0]), "csv": (out / "results.csv").read_bytes()}


def split(scenario: Path, stop: float, out: Path) -> None:
    """CPU time per macro step of each FMU and of the master, in process (``time.thread_time``
    around each FMU's calls; load-robust). Predicts the idle-machine wall time of the parallel
    run: master + rotor + the slower bearing, against master + rotor + both bearings."""
    from orchestrator import load_scenario
    from orchestrator.coupling.execution import MasterAlgorithm

    sc = load_scenario(scenario, [f"stop_time={stop}"], build_fmus=True)
    m = MasterAlgorithm(sc, out_dir=out)
    m.setup()
    m.initialize()
    spent = {u.name: 0.0 for u in m.units}
    for u in m.units:
        sub = u.sub
        for meth in ("set_real", "do_step", "get_real"):
            f = getattr(sub, meth)

            def timed(*a, _f=f, _n=u.name):
                c = time.thread_time()
                try:
                    return _f(*a)
                finally:
                    spent[_n] += time.thread_time() - c
            setattr(sub, meth, timed)
    for _ in range(20):                      # past the first steps (numba compiled at the first doStep)
        m.step()
    spent = dict.fromkeys(spent, 0.0)
    c0, n0 = time.thread_time(), m.n
    while m.status.name == "RUNNING":
        m.step()
    total = time.thread_time() - c0
    n = m.n - n0
    m.terminate()
    per = {k: v / n * 1e3 for k, v in spent.items()}
    master = total / n * 1e3 - sum(per.values())
    print(f"CPU ms per macro step over {n} steps (in process, thread_time): "
          + ", ".join(f"{k} {v:.3f}" for k, v in per.items()) + f", master {master:.3f}, total {total / n * 1e3:.3f}")
    bearings = [v for k, v in per.items() if k.startswith("bearing")]
    serial = total / n * 1e3
    ideal = serial - sum(bearings) + max(bearings)
    print(f"ideal wall per macro step with the two bearings in parallel on 2 idle cores (no channel cost): "
          f"{ideal:.3f} ms = {ideal / serial:.2f}x of {serial:.3f} ms")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", default="oil_bath")
    ap.add_argument("--stop", type=float, default=0.30)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("/tmp/bench_runup_workers"))
    ap.add_argument("--split", action="store_true", help="only the CPU split per FMU and macro step, in process")
    args = ap.parse_args(argv)
    scenario = REPO / "scenarios" / f"jeffcott_runup_{args.scenario}.yaml"
    if args.split:
        split(scenario, args.stop, args.out / "split")
        return 0
    runs: dict[str, list[dict]] = {k: [] for k in VARIANTS}
    print(f"{scenario.name}, 0.25 -> {args.stop} s; uptime: {os.popen('uptime').read().strip()}", flush=True)
    for i in range(args.repeat):
        for label, sets in VARIANTS.items():
            r = one_run(scenario, args.stop, sets, args.out / f"{label.replace(', ', '_').replace(' ', '_')}_{i}")
            runs[label].append(r)
            print(f"  run {i} {label}: wall {r['wall']:.1f} s, cpu {r['cpu']:.1f} s, master {r['master_wall']:.1f} s, "
                  f"load {r['load'][0]:.1f} -> {r['load'][1]:.1f}", flush=True)
    ref = runs["in-process"]
    same = all(r["csv"] == ref[0]["csv"] for rs in runs.values() for r in rs)
    med = {k: {m: statistics.median(r[m] for r in rs) for m in ("wall", "cpu", "master_wall")}
           for k, rs in runs.items()}
    loads = [x for rs in runs.values() for r in rs for x in r["load"]]
    print(f"\n{ref[0]['steps']} macro steps, median of {args.repeat} interleaved runs; load average "
          f"{min(loads):.1f}..{max(loads):.1f} on {os.cpu_count()} cores; results.csv identical in every run: {same}")
    print("| variant | wall (median) | vs in-process | CPU incl. workers | vs in-process | master wall (summary) |")
    print("|---|---|---|---|---|---|")
    for k, m in med.items():
        print(f"| {k} | {m['wall']:.1f} s | {m['wall'] / med['in-process']['wall']:.2f}x | {m['cpu']:.1f} s | "
              f"{m['cpu'] / med['in-process']['cpu']:.2f}x | {m['master_wall']:.1f} s |")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
