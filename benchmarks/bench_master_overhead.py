"""Orchestrator overhead per macro step: rotorcosim master vs a bare fmpy loop vs libcosim.

Same FMUs, same run for all three: two trivial PythonFMU FMUs (``Trivial``:
y = u, no physics, built from tests/fmus_src/trivial.py) connected in a loop
a.y -> b.u, b.y -> a.u, macro step 1 ms, ``--steps`` macro steps after
initialization. Only the stepping loop is timed (not loading/initialization).

* ``fmpy loop``: what a user writes by hand with fmpy's FMU2Slave:
  per step and FMU one setReal, one doStep, one getReal.
* ``rotorcosim``: MasterAlgorithm.step() with Jacobi (k=0) and Gauss-Seidel
  (k=2, q=2: polynomial evaluation on the hot path), recording only at the end.
* ``libcosim``: libcosimpy (fixed-step algorithm), run in a subprocess so that
  the two FMI hosts never share a process.

A second table does the same with mixed-type connections (issue 13): two
``TypedPorts`` PythonFMU FMUs (tests/fmus_src/typed_ports.py) coupled both ways
by a Real, an Integer and a Boolean connection (the non-Real ones held over the
step), Jacobi with zero-order hold in all three hosts; the fmpy loop then makes
one set and one get call per type and FMU per step. "master overhead" is the
master's time minus the hand-written loop's, as a fraction of libcosim's time per
step.

Each variant runs ``--repeats`` times; the table shows the median time per
macro step and ratios. Timings on a shared machine are noisy: the load
(``os.getloadavg``) is printed with the table.

    .venv/bin/python benchmarks/bench_master_overhead.py [--steps 2000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TRIVIAL_SRC = ROOT / "tests" / "fmus_src" / "trivial.py"
TYPED_SRC = ROOT / "tests" / "fmus_src" / "typed_ports.py"
MIXED = (("y", "u"), ("n_out", "n_in"), ("b_out", "b_in"))      # (output, input) coupled a <-> b
H = 1e-3


def build_trivial(dest: Path) -> Path:
    from pythonfmu.builder import FmuBuilder
    return Path(FmuBuilder.build_FMU(TRIVIAL_SRC, dest=dest))


def build_typed(dest: Path) -> Path:
    from pythonfmu.builder import FmuBuilder
    return Path(FmuBuilder.build_FMU(TYPED_SRC, dest=dest))


def time_fmpy_mixed(fmu: Path, n: int) -> float:
    """Hand-written Jacobi loop over Real, Integer and Boolean connections (fmpy FMU2Slave)."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    d = extract(str(fmu))
    slaves = []
    for name in ("a", "b"):
        s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName=name)
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        slaves.append(s)
    (ry, ru), (iy, iu), (by, bu) = ([[vr[o]], [vr[i]]] for o, i in MIXED)
    out = [(s.getReal(ry), s.getInteger(iy), s.getBoolean(by)) for s in slaves]
    t0 = time.perf_counter()
    for k in range(n):
        t = k * H
        for s, (r, i, b) in zip(slaves, out[::-1]):
            s.setReal(ru, r)
            s.setInteger(iu, i)
            s.setBoolean(bu, b)
            s.doStep(t, H)
        out = [(s.getReal(ry), s.getInteger(iy), s.getBoolean(by)) for s in slaves]
    dt = time.perf_counter() - t0
    for s in slaves:
        s.terminate()
        s.freeInstance()
    return dt / n


def time_fmpy(fmu: Path, n: int) -> float:
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    d = extract(str(fmu))
    slaves = []
    for name in ("a", "b"):
        s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName=name)
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        slaves.append(s)
    a, b = slaves
    u, y = [vr["u"]], [vr["y"]]
    ya = a.getReal(y)
    yb = b.getReal(y)
    t0 = time.perf_counter()
    for i in range(n):
        t = i * H
        a.setReal(u, yb)
        a.doStep(t, H)
        b.setReal(u, ya)
        b.doStep(t, H)
        ya = a.getReal(y)
        yb = b.getReal(y)
    dt = time.perf_counter() - t0
    for s in slaves:
        s.terminate()
        s.freeInstance()
    return dt / n


def time_master(fmu: Path, n: int, scheme: str, k: int, mixed: bool = False) -> float:
    from orchestrator.coupling.execution import MasterAlgorithm
    from orchestrator.scenario import ConnectionSpec, CouplingSpec, FmuSpec, OutputSpec, Scenario
    T = n * H
    pairs = MIXED if mixed else (("y", "u"),)
    conns = tuple(ConnectionSpec(src=f"{a}.{o}", dst=f"{b}.{i}") for o, i in pairs for a, b in (("a", "b"), ("b", "a")))
    sc = Scenario(name="overhead", stop_time=T,
                  fmus=(FmuSpec(name="a", path=fmu), FmuSpec(name="b", path=fmu)),
                  connections=conns,
                  coupling=CouplingSpec(scheme=scheme, macro_step=H, extrapolation_order=k, interpolation_order=k),
                  output=OutputSpec(interval=T, signals=("a.y",)))
    m = MasterAlgorithm(sc)
    m.setup()
    m.initialize()
    for _ in range(4):          # past the start-up steps
        m.step()
    t0 = time.perf_counter()
    step = m.step
    for _ in range(n - 4):
        step()
    dt = time.perf_counter() - t0
    m.terminate()
    return dt / (n - 4)


def time_libcosim(fmu: Path, n: int, mixed: bool = False) -> float:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimSlave import CosimLocalSlave
    ex = CosimExecution.from_step_size(step_size=int(H * 1e9))
    idx = {}
    for name in ("a", "b"):
        idx[name] = ex.add_local_slave(CosimLocalSlave(fmu_path=str(fmu), instance_name=name))
    vr = {v.name.decode(): v.reference for v in ex.slave_variables(idx["a"])}
    ex.connect_real_variables(idx["a"], vr["y"], idx["b"], vr["u"])
    ex.connect_real_variables(idx["b"], vr["y"], idx["a"], vr["u"])
    if mixed:
        # libcosimpy 0.0.6's connect_integer_variables calls a misspelt private attribute; this one works
        con_int = ex._CosimExecution__connect_int_variables
        for a, b in (("a", "b"), ("b", "a")):
            con_int(ex._CosimExecution__ptr, idx[a], vr["n_out"], idx[b], vr["n_in"])
            ex.connect_boolean_variables(idx[a], vr["b_out"], idx[b], vr["b_in"])
    ex.step(4)                  # initialization happens on the first step
    t0 = time.perf_counter()
    ok = ex.step(n)
    dt = time.perf_counter() - t0
    if not ok:
        raise RuntimeError("libcosim step failed")
    del ex
    return dt / n


def libcosim_subprocess(fmu: Path, n: int, mixed: bool = False) -> float | str:
    r = subprocess.run([sys.executable, __file__, "--libcosim-child", str(fmu), "--steps", str(n)]
                       + (["--mixed"] if mixed else []),
                       capture_output=True, text=True, timeout=600)
    try:
        return float(json.loads(r.stdout.strip().splitlines()[-1])["per_step"])
    except Exception:
        return f"failed: {(r.stderr or r.stdout).strip()[-300:]}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--libcosim-child", metavar="FMU")
    ap.add_argument("--mixed", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.libcosim_child:
        print(json.dumps({"per_step": time_libcosim(Path(args.libcosim_child), args.steps, args.mixed)}))
        return 0
    with tempfile.TemporaryDirectory(prefix="bench-overhead-") as d:
        fmu = build_trivial(Path(d))
        typed = build_typed(Path(d))
        runs: dict[str, list] = {"fmpy loop (hand-written)": [], "rotorcosim jacobi k=0": [],
                                 "rotorcosim gauss-seidel k=2": [], "libcosim (libcosimpy)": []}
        mixed: dict[str, list] = {"fmpy loop (hand-written)": [], "rotorcosim jacobi k=0": [],
                                  "libcosim (libcosimpy)": []}
        load0 = os.getloadavg()[0]
        for _ in range(args.repeats):
            runs["fmpy loop (hand-written)"].append(time_fmpy(fmu, args.steps))
            runs["rotorcosim jacobi k=0"].append(time_master(fmu, args.steps, "jacobi", 0))
            runs["rotorcosim gauss-seidel k=2"].append(time_master(fmu, args.steps, "gauss-seidel", 2))
            runs["libcosim (libcosimpy)"].append(libcosim_subprocess(fmu, args.steps))
            mixed["fmpy loop (hand-written)"].append(time_fmpy_mixed(typed, args.steps))
            mixed["rotorcosim jacobi k=0"].append(time_master(typed, args.steps, "jacobi", 0, mixed=True))
            mixed["libcosim (libcosimpy)"].append(libcosim_subprocess(typed, args.steps, mixed=True))
        load1 = os.getloadavg()[0]
    _table(runs, args, load0, load1, "two trivial PythonFMU FMUs in a loop (Real)")
    _table(mixed, args, load0, load1, "two TypedPorts PythonFMU FMUs, Real + Integer + Boolean both ways (Jacobi)")
    return 0


def _table(runs, args, load0, load1, title) -> None:
    med = {}
    for k, v in runs.items():
        nums = [x for x in v if isinstance(x, float)]
        med[k] = statistics.median(nums) if nums else None
    base, lib = med["fmpy loop (hand-written)"], med["libcosim (libcosimpy)"]
    print(f"{title}, {args.steps} macro steps, median of {args.repeats} runs, "
          f"load average {load0:.1f} -> {load1:.1f} on {os.cpu_count()} cores")
    print(f"| variant | us per macro step | vs fmpy loop | vs libcosim |")
    print(f"|---|---|---|---|")
    for k, v in med.items():
        if v is None:
            print(f"| {k} | {runs[k][-1]} | | |")
            continue
        r1 = f"{v / base:.2f}x" if base else ""
        r2 = f"{v / lib:.2f}x" if lib else ""
        print(f"| {k} | {v * 1e6:.1f} | {r1} | {r2} |")
    if base and med["rotorcosim jacobi k=0"]:
        over = med["rotorcosim jacobi k=0"] - base
        frac = f" = {over / lib:.2f}x libcosim's time per step" if lib else ""
        print(f"master overhead over the hand-written loop: {over * 1e6:.1f} us/step (jacobi k=0){frac}"
              + (f", {(med['rotorcosim gauss-seidel k=2'] - base) * 1e6:.1f} us/step (gauss-seidel k=2)"
                 if "rotorcosim gauss-seidel k=2" in med else ""))
    print()


if __name__ == "__main__":
    sys.exit(main())
