"""Sweep speed (issue 15): an 8-run sweep on Dask against the same 8 runs in one process,
and the cost per task.

Modes (one per process, so that farm-bench times each from outside, start-up included):

* ``sweep``: ``rotorcosim sweep``'s code path (:func:`orchestrator.sweep.runner.run_sweep`) on
  a LocalCluster of ``--workers`` (default: one per core) for ``benchmarks/sweep_bench.yaml``:
  8 seeded half-Sommerfeld Jeffcott run-ups (220 -> 260 Hz, 1000 macro steps each, eta0 over 8
  values); cluster start-up, one fresh process per run and the table included.
* ``sequential``: the same 8 runs (the same plans and overrides) one after another in this
  process with ``orchestrator.load_scenario`` + ``orchestrator.run``: the peer.
* ``overhead``: (a) ``--tasks`` trivial tasks (:func:`orchestrator.sweep.task.trivial_run`,
  nothing inside) through the LocalCluster: Dask's scheduling overhead per task; (b) one
  ``execute_run`` of a 2-macro-step run (the fresh ``python -m orchestrator run`` process,
  read summary) against the same run in-process: what a fresh process costs per run.

    farm-bench -n 3 --timeout 3000 -- .venv/bin/python benchmarks/bench_sweep.py sweep \\
        --vs '.venv/bin/python benchmarks/bench_sweep.py sequential'
    .venv/bin/python benchmarks/bench_sweep.py overhead
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SWEEP = ROOT / "benchmarks" / "sweep_bench.yaml"


def bench_sweep(workers: int | None) -> float:
    from orchestrator.sweep import prepare
    from orchestrator.sweep.runner import run_sweep
    spec, runs = prepare(SWEEP)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        out = run_sweep(spec, runs, tmp, workers=workers, progress=False)
        wall = time.perf_counter() - t0
    bad = [r for r in out.rows if r["status"] != "finished"]
    assert not bad, bad
    return wall


def bench_sequential() -> float:
    from orchestrator import load_scenario, run
    from orchestrator.sweep import prepare
    spec, runs = prepare(SWEEP)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        for r in runs:
            res = run(load_scenario(spec.scenario, list(r.overrides), build_fmus=False),
                      out_dir=Path(tmp) / r.run_id, progress=False)
            assert res.success, res.message
        return time.perf_counter() - t0


def bench_overhead(n_tasks: int, workers: int | None, repeats: int) -> None:
    from orchestrator import load_scenario, run
    from orchestrator.sweep.runner import connect
    from orchestrator.sweep.task import execute_run, trivial_run
    client, cluster = connect(None, workers)
    try:
        n_w = len(client.scheduler_info()["workers"])
        client.gather(client.map(trivial_run, [0.0] * 20, pure=False))        # warm up
        per = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            client.gather(client.map(trivial_run, [0.0] * n_tasks, pure=False))
            per.append((time.perf_counter() - t0) / n_tasks)
    finally:
        client.close()
        cluster.close()
    print(f"dask trivial tasks: {n_tasks} tasks on {n_w} workers, median {statistics.median(per) * 1e3:.2f} ms "
          f"per task (wall / tasks; runs {', '.join(f'{p * 1e3:.2f}' for p in per)} ms)")
    scen = ROOT / "scenarios" / "jeffcott_runup_half_sommerfeld_seeded.yaml"
    one = ["stop_time=0.5502", "output.interval=1e-4"]   # 2 macro steps
    fresh, inproc, fresh_cpu, inproc_cpu = [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeats):
            c0 = _children_cpu()
            rec = execute_run(str(scen), one, str(Path(tmp) / f"f{i}"))
            fresh_cpu.append(_children_cpu() - c0)
            assert rec["status"] == "finished", rec
            fresh.append(rec["wall_time_s"])
            t0, c0 = time.perf_counter(), time.process_time()
            run(load_scenario(scen, one, build_fmus=False), out_dir=Path(tmp) / f"i{i}", progress=False)
            inproc.append(time.perf_counter() - t0)
            inproc_cpu.append(time.process_time() - c0)
    m = statistics.median
    print(f"2-macro-step HS Jeffcott run (median of {repeats}): fresh process {m(fresh):.2f} s wall / "
          f"{m(fresh_cpu):.2f} s CPU; in-process (warm) {m(inproc):.2f} s wall / {m(inproc_cpu):.2f} s CPU: "
          f"a fresh process costs {m(fresh) - m(inproc):.2f} s wall, {m(fresh_cpu) - m(inproc_cpu):.2f} s CPU per run")


def _children_cpu() -> float:
    import resource
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("sweep", "sequential", "overhead"))
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--tasks", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    load = os.getloadavg()
    if args.mode == "sweep":
        print(f"sweep wall {bench_sweep(args.workers):.2f} s (load {load[0]:.1f})")
    elif args.mode == "sequential":
        print(f"sequential wall {bench_sequential():.2f} s (load {load[0]:.1f})")
    else:
        bench_overhead(args.tasks, args.workers, args.repeats)
        print(f"load average at start: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
