"""The critical path of one threaded macro step: who waits for whom (issue 16).

Runs a shipped scenario in this process (``coupling.parallel: threads``, as shipped) to
``--stop`` and stamps, per macro step, the start and end of the step, of the stage that steps
the two bearings at once, of each bearing's job (A on the master's thread, B on the stage
thread) and of each film solve (``TransientFilm.advance_restarting``), and sums the interface
coefficients (``bearing_fmu.linearize.linearization``) per thread. Prints medians over the
macro steps after ``--skip``: "pre" is a bearing's FMI calls and Python before its film solve,
"post" after it. BENCHMARKS.md, session 20.

Run:
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_stage_timeline.py --stop 0.45 --skip 200
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_stage_timeline.py --stop 0.85 --skip 4500
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="jeffcott_runup_oil_bath")
    ap.add_argument("--stop", type=float, default=0.45, help="stop time [s]")
    ap.add_argument("--skip", type=int, default=200, help="macro steps left out at the start")
    a = ap.parse_args(argv)

    import bearing_fmu.linearize as linearize
    import bearing_fmu.solver as solver
    import orchestrator.coupling.execution as execution
    import orchestrator.coupling.threads as threads
    from orchestrator import load_scenario, run

    pc = time.perf_counter
    rec: list[dict] = []
    cur: dict = {}
    stage_run, master_step = threads.StageThreads.run, execution.MasterAlgorithm.step
    advance, lin = solver.TransientFilm.advance_restarting, linearize.linearization

    def side() -> str:
        return "a" if threading.current_thread() is threading.main_thread() else "b"

    def timed_stage(self, jobs):
        cur["s0"] = pc()
        first, second = jobs[0], jobs[1]

        def job_a():
            cur["a0"] = pc()
            first()
            cur["a1"] = pc()

        def job_b():
            cur["b0"] = pc()
            second()
            cur["b1"] = pc()
        try:
            return stage_run(self, [job_a, job_b, *jobs[2:]])
        finally:
            cur["s1"] = pc()

    def timed_step(self, *args, **kw):
        cur.clear()
        cur["t0"] = pc()
        try:
            return master_step(self, *args, **kw)
        finally:
            cur["t1"] = pc()
            rec.append(dict(cur))

    def timed_film(self, *args, **kw):
        s = side()
        cur[f"f{s}0"] = pc()
        try:
            return advance(self, *args, **kw)
        finally:
            cur[f"f{s}1"] = pc()

    def timed_lin(*args, **kw):
        s, t0 = side(), pc()
        try:
            return lin(*args, **kw)
        finally:
            cur[f"l{s}"] = cur.get(f"l{s}", 0.0) + pc() - t0

    threads.StageThreads.run = timed_stage
    execution.MasterAlgorithm.step = timed_step
    solver.TransientFilm.advance_restarting = timed_film
    linearize.linearization = timed_lin
    sc = replace(load_scenario(ROOT / "scenarios" / f"{a.scenario}.yaml"), stop_time=a.stop)
    with tempfile.TemporaryDirectory() as out:
        res = run(sc, out_dir=out, progress=False)
    need = ("s0", "s1", "a0", "a1", "b0", "b1", "fa0", "fa1", "fb0", "fb1")
    steps = [r for r in rec[a.skip:] if all(k in r for k in need)]
    if not steps:
        sys.exit(f"no threaded stage steps after --skip {a.skip} (status {res.status}); lower --skip or raise --stop")
    print(f"{a.scenario} to {a.stop} s: {res.status}, {len(steps)} macro steps after the first {a.skip}")
    rows = [("whole step", lambda r: r["t1"] - r["t0"]), ("before the stage", lambda r: r["s0"] - r["t0"]),
            ("A pre", lambda r: r["fa0"] - r["a0"]), ("A film", lambda r: r["fa1"] - r["fa0"]),
            ("A post", lambda r: r["a1"] - r["fa1"]), ("B start after the stage starts", lambda r: r["b0"] - r["s0"]),
            ("B pre", lambda r: r["fb0"] - r["b0"]), ("B film", lambda r: r["fb1"] - r["fb0"]),
            ("B post", lambda r: r["b1"] - r["fb1"]), ("B ends after A", lambda r: r["b1"] - r["a1"]),
            ("after the stage", lambda r: r["t1"] - r["s1"]),
            ("coefficients A (sum)", lambda r: r.get("la", 0.0)), ("coefficients B (sum)", lambda r: r.get("lb", 0.0))]
    for name, f in rows:
        v = np.array([f(r) for r in steps]) * 1e6
        print(f"{name:32s} median {np.median(v):8.1f} us   mean {v.mean():8.1f} us")
    print(f"steps with coefficients: A {np.mean(['la' in r for r in steps]):.2f}, B {np.mean(['lb' in r for r in steps]):.2f}")


if __name__ == "__main__":
    main()
