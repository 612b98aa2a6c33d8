"""Round-trip cost of one set/doStep/get cycle: FMU in a worker process vs in-process vs libcosim.

The FMU is trivial on purpose, so that only the host's cost is measured: the native C
``LinearBearing`` of tests/fmus_c (Fx = -k x - c vx, a few flops per call; built with gcc
into a temporary folder). Two instances a, b in a loop (a.Fx -> b.x, b.Fx -> a.x), macro
step 1 ms, ``--steps`` macro steps after initialization; per macro step each FMU gets one
set (its 4 inputs), one doStep and one get (Fx, Fy). The figure is time per cycle = time
per macro step / 2. Variants:

* ``in-process``: orchestrator.fmi.subsystem.Subsystem (fmpy's ctypes functions, the master's adapter);
* ``worker``: orchestrator.fmi.worker.WorkerSubsystem, the same calls served by a worker
  process (set queued, doStep and get one round trip each);
* ``libcosim``: libcosimpy's fixed-step algorithm with the same two FMUs and connections,
  run in a subprocess so that the two FMI hosts never share a process.

Each variant runs ``--repeats`` times, interleaved; the table shows medians and ratios
and the load average (the machine is shared).

    .venv/bin/python benchmarks/bench_worker_roundtrip.py [--steps 5000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
H = 1e-3


def build_fmu(dest: Path) -> Path:
    spec = importlib.util.spec_from_file_location("build_c_fmu", ROOT / "tests" / "fmus_c" / "build_c_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.build_c_fmu(dest, "LinearBearing")


def cpu_ns(pid: int | str = "self") -> int:
    """CPU time a process (its main thread) has run, in ns (/proc/PID/schedstat): unlike wall time,
    not inflated by waiting for a CPU on a loaded machine."""
    return int(Path(f"/proc/{pid}/schedstat").read_text().split()[0])


def time_adapter(cls, fmu: Path, n: int, work_dir: Path, cpu: list | None = None) -> float:
    subs = [cls(name, fmu, work_dir=work_dir) for name in ("a", "b")]
    try:
        batches = []
        for s in subs:
            s.setup_experiment(0.0, None)
            s.enter_initialization_mode()
            s.exit_initialization_mode()
            batches.append((s.real_batch(["x", "y", "vx", "vy"]), s.real_batch(["Fx", "Fy"])))
        (ia, oa), (ib, ob) = batches
        a, b = subs
        ia.values[:] = [1e-6, 0.0, 0.0, 0.0]
        ib.values[:] = [-1e-6, 0.0, 0.0, 0.0]
        pids = ["self"] + [s.pid for s in subs if hasattr(s, "pid")]
        c0 = [cpu_ns(p) for p in pids]
        t0 = time.perf_counter()
        for i in range(n):
            t = i * H
            a.set_real(ia)
            a.do_step(t, H)
            b.set_real(ib)
            b.do_step(t, H)
            ib.values[0] = a.get_real(oa)[0] * 1e-12
            ia.values[0] = b.get_real(ob)[0] * 1e-12
        dt = time.perf_counter() - t0
        if cpu is not None:     # CPU per cycle: master, workers (sum)
            c1 = [cpu_ns(p) for p in pids]
            cpu.append(((c1[0] - c0[0]) / n / 2e9, sum(b - a for a, b in zip(c0[1:], c1[1:])) / n / 2e9))
        for s in subs:
            s.terminate()
    finally:
        for s in subs:
            s.free()
    return dt / n / 2


def time_libcosim(fmu: Path, n: int) -> float:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimSlave import CosimLocalSlave
    ex = CosimExecution.from_step_size(step_size=int(H * 1e9))
    idx = {name: ex.add_local_slave(CosimLocalSlave(fmu_path=str(fmu), instance_name=name)) for name in ("a", "b")}
    vr = {v.name.decode(): v.reference for v in ex.slave_variables(idx["a"])}
    ex.connect_real_variables(idx["a"], vr["Fx"], idx["b"], vr["x"])
    ex.connect_real_variables(idx["b"], vr["Fx"], idx["a"], vr["x"])
    ex.step(4)                  # initialization happens on the first step
    t0 = time.perf_counter()
    ok = ex.step(n)
    dt = time.perf_counter() - t0
    if not ok:
        raise RuntimeError("libcosim step failed")
    del ex
    return dt / n / 2


def libcosim_subprocess(fmu: Path, n: int) -> float | str:
    r = subprocess.run([sys.executable, __file__, "--libcosim-child", str(fmu), "--steps", str(n)],
                       capture_output=True, text=True, timeout=600)
    try:
        return float(json.loads(r.stdout.strip().splitlines()[-1])["per_cycle"])
    except Exception:
        return f"failed: {(r.stderr or r.stdout).strip()[-300:]}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--libcosim-child", metavar="FMU")
    args = ap.parse_args(argv)
    if args.libcosim_child:
        print(json.dumps({"per_cycle": time_libcosim(Path(args.libcosim_child), args.steps)}))
        return 0
    from orchestrator.fmi.worker import WorkerSubsystem
    from orchestrator.fmi.subsystem import Subsystem

    runs: dict[str, list] = {"in-process (Subsystem)": [], "worker process (WorkerSubsystem)": [],
                             "libcosim (libcosimpy)": []}
    cpu: dict[str, list] = {"in-process (Subsystem)": [], "worker process (WorkerSubsystem)": []}
    with tempfile.TemporaryDirectory(prefix="bench-worker-") as d:
        fmu = build_fmu(Path(d))
        load0 = os.getloadavg()
        for r in range(args.repeats):
            runs["in-process (Subsystem)"].append(time_adapter(Subsystem, fmu, args.steps, Path(d) / f"i{r}",
                                                               cpu["in-process (Subsystem)"]))
            runs["worker process (WorkerSubsystem)"].append(
                time_adapter(WorkerSubsystem, fmu, args.steps, Path(d) / f"w{r}", cpu["worker process (WorkerSubsystem)"]))
            runs["libcosim (libcosimpy)"].append(libcosim_subprocess(fmu, args.steps))
        load1 = os.getloadavg()
    med = {k: (statistics.median([x for x in v if isinstance(x, float)]) if any(isinstance(x, float) for x in v)
               else None) for k, v in runs.items()}
    base, lib = med["in-process (Subsystem)"], med["libcosim (libcosimpy)"]
    print(f"native C LinearBearing x2, one set/doStep/get cycle per FMU and macro step, {args.steps} macro steps, "
          f"median of {args.repeats} interleaved runs; load average {load0[0]:.2f} -> {load1[0]:.2f} "
          f"(5 min {load1[1]:.2f}) on {os.cpu_count()} cores")
    print("| variant | us per set/doStep/get cycle (median) | min | vs in-process | vs libcosim |")
    print("|---|---|---|---|---|")
    for k, v in med.items():
        if v is None:
            print(f"| {k} | {runs[k][-1]} | | | |")
            continue
        lo = min(x for x in runs[k] if isinstance(x, float))
        print(f"| {k} | {v * 1e6:.1f} | {lo * 1e6:.1f} | {v / base:.2f}x | "
              f"{(f'{v / lib:.2f}x' if lib else '')} |")
    print("\nCPU time per cycle (/proc/PID/schedstat, median; load-robust, unlike the wall times above):")
    for k, v in cpu.items():
        m = statistics.median(x[0] for x in v)
        w = statistics.median(x[1] for x in v)
        print(f"  {k}: master {m * 1e6:.1f} us" + (f" + worker {w * 1e6:.1f} us = {(m + w) * 1e6:.1f} us"
                                                     if "worker" in k else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
