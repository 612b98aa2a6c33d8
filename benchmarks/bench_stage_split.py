"""Where a macro step of a threaded run-up goes: the parallel stage against the serial rest.

Runs a shipped scenario in this process (``coupling.parallel: threads``, as shipped) up to
``--stop`` and times, per macro step: the whole step (``MasterAlgorithm.step``), the stage
run on the threads (``StageThreads.run``: the two bearings at once), the first job of that
stage (the bearing stepped on the master's thread) and the film solve inside each bearing
(``TransientFilm.advance_restarting``, per thread). The serial rest (rotor, exchange, result
rows) is the step minus the stage. ``--handoff``: how the stage threads hand over
(:mod:`orchestrator.coupling.threads`): chosen by measurement (auto), always watching, always
sleeping.

Run:
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_stage_split.py \
        --scenario jeffcott_runup_oil_bath --stop 0.45 [--handoff auto|watch|sleep]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import threading
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="jeffcott_runup_oil_bath")
    ap.add_argument("--stop", type=float, default=0.45, help="stop time [s]")
    ap.add_argument("--handoff", choices=["auto", "watch", "sleep"], default=None,
                    help="hand-offs of the stage threads (ROTORCOSIM_STAGE_HANDOFF; default: as set, else auto)")
    a = ap.parse_args(argv)

    import bearing_fmu.solver as solver
    import orchestrator.coupling.execution as execution
    import orchestrator.coupling.threads as threads
    from orchestrator import load_scenario, run

    acc = {"step": 0.0, "stage": 0.0, "job0": 0.0, "n": 0}
    film: dict[str, float] = {}
    stage_run, master_step, advance = (threads.StageThreads.run, execution.MasterAlgorithm.step,
                                       solver.TransientFilm.advance_restarting)

    def timed_stage(self, jobs):
        t0 = time.perf_counter()
        first = jobs[0]

        def job0():
            s = time.perf_counter()
            try:
                first()
            finally:
                acc["job0"] += time.perf_counter() - s
        try:
            return stage_run(self, [job0, *jobs[1:]])
        finally:
            acc["stage"] += time.perf_counter() - t0

    def timed_step(self, *args, **kw):
        t0 = time.perf_counter()
        try:
            return master_step(self, *args, **kw)
        finally:
            acc["step"] += time.perf_counter() - t0
            acc["n"] += 1

    def timed_film(self, *args, **kw):
        t0 = time.perf_counter()
        try:
            return advance(self, *args, **kw)
        finally:
            name = threading.current_thread().name
            film[name] = film.get(name, 0.0) + time.perf_counter() - t0

    if a.handoff:
        os.environ["ROTORCOSIM_STAGE_HANDOFF"] = a.handoff
    threads.StageThreads.run = timed_stage
    execution.MasterAlgorithm.step = timed_step
    solver.TransientFilm.advance_restarting = timed_film
    sc = load_scenario(ROOT / "scenarios" / f"{a.scenario}.yaml")
    sc = replace(sc, stop_time=a.stop)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        res = run(sc, out_dir=out, progress=False)
    total = time.perf_counter() - t0
    n = max(acc["n"], 1)
    us = 1e6 / n
    print(f"{a.scenario} to {a.stop} s: {res.status}, {acc['n']} macro steps, {total:.2f} s in all, "
          f"{total - acc['step']:.2f} s outside the steps")
    print(f"per macro step: {acc['step'] * us:.0f} us; stage {acc['stage'] * us:.0f} us (its first job "
          f"{acc['job0'] * us:.0f} us); serial rest {(acc['step'] - acc['stage']) * us:.0f} us")
    pool = getattr(res, "stats", {}) or {}
    if "threaded_stage_steps" in pool:
        print(f"stage steps in threads {pool['threaded_stage_steps']}, of them with watching hand-offs "
              f"{pool.get('threaded_stage_steps_watched', 'n/a')}")
    for name, s in sorted(film.items()):
        print(f"film solve on {name}: {s * us:.0f} us per macro step")


if __name__ == "__main__":
    main()
