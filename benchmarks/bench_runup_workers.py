"""The shipped mass-conserving Jeffcott run-up with the bearings in worker processes vs in process.

    .venv/bin/python benchmarks/bench_runup_workers.py [--scenario oil_bath] [--stop 0.40]
        [--repeat 3] [--out /tmp/bench_runup_workers] [--variants all|main|inproc,par,pinned,one,seq,threads]
    .venv/bin/python benchmarks/bench_runup_workers.py --split [--stop 0.27]   # CPU per FMU and step

Variants of scenarios/jeffcott_runup_<scenario>.yaml (Gauss-Seidel [rotor, bearing1,
bearing2], two 40 x 40 mass-conserving films, 0.1 ms macro steps), run from 0.25 s to
``--stop``, each in a fresh child process (``orchestrator.run``, the path of ``rotorcosim
run``, with single-threaded BLAS), interleaved, ``--repeat`` times:

* ``in-process``: every FMU in the master, one after the other (the peer);
* ``workers, parallel``: bearing1 and bearing2 with ``isolation: process``,
  ``coupling.parallel: true`` (the two films step at the same time; the rotor stays in
  the master);
* ``workers, parallel, pinned``: the same with ``coupling.pin_workers: true`` (each worker
  on a CPU of its own, see orchestrator/fmi/channel.py ``_pin``);
* ``one worker, parallel, pinned``: only bearing2 in a worker (pinned); bearing1 steps in the
  master while the worker steps bearing2 (one process fewer, one round trip per step);
* ``workers, sequential``: both in workers, ``parallel: false`` (what the channel costs alone);
* ``in-process, threads``: every FMU in the master, ``coupling.parallel: threads`` (bearing1 in
  the master's thread, bearing2 in a thread of the master at the same time; one process);
* ``machine control``: no FMU at all: the same pattern of work with CPU-time busy loops
  (the master ``R`` ms, then two child processes ``F`` ms each at once, over a
  multiprocessing pipe; R, F from ``--split``), against the same work in one process. It
  shows what this machine gives a two-process parallel stage at that moment (wake-up
  latency, other sessions' load), so a poor worker ratio can be told from a poor machine.

Recorded per run: wall time of the child, its CPU time (user + system of the run and of the
workers it waited for, ``RUSAGE_CHILDREN``), the time to the first macro step (start-up:
interpreter, workers, FMU instantiation and initialization), the median wall time of one
macro step after it (insensitive to start-up and to the odd long step), the median time per
macro step the master spends waiting for (blocked on or polling) worker replies (about the
worker path's excess over the master's own share of the stage: near 0 when the master's side
is the critical path), the load average
before and after; results.csv of every variant is compared with the in-process one byte
for byte. The table gives medians and ratios. Read the wall ratios with the load: on a
shared machine other processes take a share of both cores (Linux autogroups: ``nice`` only
orders the processes of one session, so a niced run of another session still takes half a
busy core) and a parallel stage loses the most; the CPU ratio is the cost of isolation.
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

import numpy as np

REPO = Path(__file__).resolve().parents[1]
BOTH = ["fmus.bearing1.isolation=process", "fmus.bearing2.isolation=process"]
VARIANTS = {
    "in-process": [],
    "workers, parallel": [*BOTH, "coupling.parallel=true"],
    "workers, parallel, pinned": [*BOTH, "coupling.parallel=true", "coupling.pin_workers=true"],
    "one worker, parallel, pinned": ["fmus.bearing2.isolation=process", "coupling.parallel=true",
                                     "coupling.pin_workers=true"],
    "workers, sequential": [*BOTH, "coupling.parallel=false"],
    "in-process, threads": ["coupling.parallel=threads"],
}
KEYS = dict(zip(("inproc", "par", "pinned", "one", "seq", "threads"), VARIANTS))  # --variants inproc,one ...
MAIN = ("inproc", "pinned", "one", "threads")
SINGLE = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
CONTROL_STEPS = 300


def child(scenario: Path, stop: float, sets: list[str], out: Path) -> None:
    """One run in this (fresh) process; writes out/timing.json (start-up, per-step walls)."""
    t_start = time.perf_counter()
    from orchestrator import load_scenario, run
    from orchestrator.coupling.observers import Observer

    class StepTimer(Observer):
        def __init__(self):
            self.t0, self.times, self.waits = None, [], []

        def on_initialized(self, view):
            self.t0 = time.perf_counter()

        def on_step_complete(self, view):
            self.times.append(time.perf_counter())
            self.waits.append(waited[0])

    waited = _time_worker_waits()
    timer = StepTimer()
    res = run(load_scenario(scenario, [f"stop_time={stop}", *sets]), out_dir=out, progress=False,
              observers=[timer])
    t_end = time.perf_counter()
    if not res.success:
        raise SystemExit(f"run failed: {res.message}")
    steps = [b - a for a, b in zip([timer.t0, *timer.times], timer.times)]
    (out / "timing.json").write_text(json.dumps({
        "startup": timer.t0 - t_start, "step_ms": 1e3 * statistics.median(steps[20:] or steps), "steps": len(steps),
        "first20": sum(steps[:20]), "finish": t_end - timer.times[-1],
        "wait_ms": 1e3 * statistics.median(np.diff(timer.waits)[19:] if len(timer.waits) > 21 else [0.0])}))


def _time_worker_waits() -> list:
    """Accumulate the master's time blocked (or polling) for worker replies: [seconds]. How long
    the master idles per macro step after its own share of a parallel stage tells whether the
    worker's side (channel, wake-up, a slower film) or the master's is the critical path."""
    from orchestrator.fmi.channel import WorkerChannel
    waited = [0.0]
    wait = WorkerChannel._wait

    def timed(self, function):
        t0 = time.perf_counter()
        try:
            return wait(self, function)
        finally:
            waited[0] += time.perf_counter() - t0
    WorkerChannel._wait = timed
    return waited


def one_run(scenario: Path, stop: float, sets: list[str], out: Path) -> dict:
    cmd = [sys.executable, __file__, "--child", "--scenario-path", str(scenario), "--stop", str(stop),
           "--out", str(out)] + [a for s in sets for a in ("--set", s)]
    load0 = os.getloadavg()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **SINGLE})
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    timing = json.loads((out / "timing.json").read_text())
    return {"wall": wall, "cpu": (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime),
            "startup": timing["startup"], "step_ms": timing["step_ms"], "steps": timing["steps"],
            "first20": timing["first20"], "finish": timing["finish"], "wait_ms": timing["wait_ms"],
            "load": (load0[0], os.getloadavg()[0]), "csv": (out / "results.csv").read_bytes()}


# -- machine control: the same pattern of work without FMUs ------------------------------
def _burn(ms: float) -> None:
    end = time.thread_time() + ms * 1e-3
    while time.thread_time() < end:
        pass


def _control_worker(conn) -> None:
    while (ms := conn.recv()) is not None:
        _burn(ms)
        conn.send(None)


def control(r_ms: float, f_ms: float, steps: int = CONTROL_STEPS) -> dict:
    """Per-step wall [ms] of R + F + F in one process and of R then F || F in two children."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    pipes, procs = [], []
    for _ in range(2):
        a, b = ctx.Pipe()
        p = ctx.Process(target=_control_worker, args=(b,), daemon=True)
        p.start()
        pipes.append(a)
        procs.append(p)
    for a in pipes:                      # both children up before timing
        a.send(0.0)
        a.recv()
    t0 = time.perf_counter()
    for _ in range(steps):
        _burn(r_ms + 2 * f_ms)
    serial = (time.perf_counter() - t0) / steps
    t0 = time.perf_counter()
    for _ in range(steps):
        _burn(r_ms)
        for a in pipes:
            a.send(f_ms)
        for a in pipes:
            a.recv()
    parallel = (time.perf_counter() - t0) / steps
    for a, p in zip(pipes, procs):
        a.send(None)
        p.join(5)
    return {"serial_ms": serial * 1e3, "parallel_ms": parallel * 1e3}


def split(scenario: Path, stop: float, out: Path) -> None:
    """CPU time per macro step of each FMU and of the master, in process (``time.thread_time``
    around each FMU's calls). Predicts the idle-machine wall time of the parallel
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
    for _ in range(20):                      # past the first steps
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


def _table(runs: dict, controls: list, repeat: int) -> bool:
    ref = runs["in-process"]
    same = all(r["csv"] == ref[0]["csv"] for rs in runs.values() for r in rs)
    keys = ("wall", "cpu", "startup", "step_ms", "wait_ms")
    med = {k: {m: statistics.median(r[m] for r in rs) for m in keys} for k, rs in runs.items()}
    loads = [x for rs in runs.values() for r in rs for x in r["load"]]
    base = med["in-process"]
    print(f"\n{ref[0]['steps']} macro steps, median of {repeat} interleaved runs; load average "
          f"{min(loads):.1f}..{max(loads):.1f} on {os.cpu_count()} cores; results.csv identical in every run: {same}")
    print("| variant | wall | vs in-process | CPU incl. workers | vs in-process | start-up | per macro step | vs in-process "
          "| master waits for workers, per step |")
    print("|---|---|---|---|---|---|---|---|---|")
    for k, m in med.items():
        print(f"| {k} | {m['wall']:.1f} s | {m['wall'] / base['wall']:.2f}x | {m['cpu']:.1f} s | "
              f"{m['cpu'] / base['cpu']:.2f}x | {m['startup']:.2f} s | {m['step_ms']:.2f} ms | "
              f"{m['step_ms'] / base['step_ms']:.2f}x | {m['wait_ms']:.2f} ms |")
    if controls:
        s = statistics.median(c["serial_ms"] for c in controls)
        p = statistics.median(c["parallel_ms"] for c in controls)
        print(f"| machine control (no FMU: R, then F || F in two processes) | | | | | | {p:.2f} ms | "
              f"{p / s:.2f}x of {s:.2f} ms | |")
    return same


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", default="oil_bath")
    ap.add_argument("--scenario-path", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--stop", type=float, default=0.40)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path("/tmp/bench_runup_workers"))
    ap.add_argument("--variants", default="all",
                    help="all, main (inproc,pinned,one) or a comma list of " + ",".join(KEYS)
                         + " (in-process is always run: the peer)")
    ap.add_argument("--control", default="1.4,5.1", metavar="R,F",
                    help="machine control: master and film CPU ms per step (from --split); 'off' to skip")
    ap.add_argument("--split", action="store_true", help="only the CPU split per FMU and macro step, in process")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--set", action="append", default=[], help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    scenario = args.scenario_path or REPO / "scenarios" / f"jeffcott_runup_{args.scenario}.yaml"
    if args.child:
        child(scenario, args.stop, args.set, args.out)
        sys.stdout.flush()
        os._exit(0)       # no interpreter teardown with PythonFMU FMUs loaded (orchestrator.cli.console_main)
    if args.split:
        split(scenario, args.stop, args.out / "split")
        return 0
    picked = KEYS if args.variants == "all" else MAIN if args.variants == "main" else args.variants.split(",")
    bad = [k for k in picked if k not in KEYS]
    if bad:
        ap.error(f"--variants: unknown {bad}; choose from all, main or {', '.join(KEYS)}")
    variants = {label: VARIANTS[label] for k, label in KEYS.items() if k in picked or k == "inproc"}
    runs: dict[str, list[dict]] = {k: [] for k in variants}
    controls: list[dict] = []
    print(f"{scenario.name}, 0.25 -> {args.stop} s; uptime: {os.popen('uptime').read().strip()}; "
          f"{open('/proc/self/autogroup').read().strip() if os.path.exists('/proc/self/autogroup') else ''}",
          flush=True)
    for i in range(args.repeat):
        for label, sets in variants.items():
            r = one_run(scenario, args.stop, sets, args.out / f"{label.replace(', ', '_').replace(' ', '_')}_{i}")
            runs[label].append(r)
            print(f"  run {i} {label}: wall {r['wall']:.1f} s, cpu {r['cpu']:.1f} s, start-up {r['startup']:.2f} s, "
                  f"step {r['step_ms']:.2f} ms, waits {r['wait_ms']:.2f} ms (first 20: {r['first20']:.2f} s, after the last: {r['finish']:.2f} s), load {r['load'][0]:.1f} -> {r['load'][1]:.1f}", flush=True)
        if args.control != "off":
            r_ms, f_ms = (float(x) for x in args.control.split(","))
            c = control(r_ms, f_ms)
            controls.append(c)
            print(f"  run {i} machine control: serial {c['serial_ms']:.2f} ms, parallel {c['parallel_ms']:.2f} ms "
                  f"({c['parallel_ms'] / c['serial_ms']:.2f}x)", flush=True)
    return 0 if _table(runs, controls, args.repeat) else 1


if __name__ == "__main__":
    sys.exit(main())
