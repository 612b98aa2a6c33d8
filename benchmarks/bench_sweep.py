"""Sweep speed (issue 15): an 8-run sweep on Dask against the same 8 runs in one process,
and the cost per task.

Modes (``sweep``, ``sequential``: one per process, timed from outside, start-up included):

* ``sweep``: ``rotorcosim sweep``'s code path (:func:`orchestrator.sweep.runner.run_sweep`) on
  a LocalCluster of ``--workers`` (default: one per core) for ``benchmarks/sweep_bench.yaml``:
  8 seeded half-Sommerfeld Jeffcott run-ups (220 -> 260 Hz, 1000 macro steps each, eta0 over 8
  values); cluster start-up, the workers' run processes and the table included. Warm run
  processes (the default); ``--fresh`` for a fresh process per run (``--fresh-processes``).
* ``sequential``: the same 8 runs (the same plans and overrides) one after another in this
  process with ``orchestrator.load_scenario`` + ``orchestrator.run``: the peer.
* ``pair``: runs ``sweep``, ``sweep --fresh`` and ``sequential`` as child processes in turn,
  ``--repeats`` times, and prints each one's wall and CPU (``getrusage`` of the reaped
  children: the cluster and the run processes included), the medians, the ratios of each round
  and the load average before each run; all three with single-threaded BLAS (as the sweep's run
  processes have it).
* ``overhead``: (a) ``--tasks`` trivial tasks (:func:`orchestrator.sweep.task.trivial_run`,
  nothing inside) through the LocalCluster: Dask's scheduling overhead per task; (b) one
  ``execute_run`` of a 2-macro-step run in a warm run process, in a fresh process and in this
  process: what the run process costs per run.

    nice -n 5 .venv/bin/python benchmarks/bench_sweep.py pair --repeats 3
    .venv/bin/python benchmarks/bench_sweep.py overhead
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SWEEP = ROOT / "benchmarks" / "sweep_bench.yaml"


def bench_sweep(workers: int | None, warm: bool = True) -> float:
    from orchestrator.sweep import prepare
    from orchestrator.sweep.runner import run_sweep
    spec, runs = prepare(SWEEP)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        out = run_sweep(spec, runs, tmp, workers=workers, progress=False, warm=warm)
        wall = time.perf_counter() - t0
    bad = [r for r in out.rows if r["status"] != "finished"]
    assert not bad, bad
    print("run walls [s]: " + " ".join(f"{r['wall_time_s']:.1f}" for r in out.rows))
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
    fresh, inproc, fresh_cpu, inproc_cpu, warm = [], [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        execute_run(str(scen), one, str(Path(tmp) / "runs" / "w"))            # start the warm process
        for i in range(repeats):
            rec = execute_run(str(scen), one, str(Path(tmp) / "runs" / f"w{i}"))
            assert rec["status"] == "finished", rec
            warm.append(rec["wall_time_s"])
            c0 = _children_cpu()
            rec = execute_run(str(scen), one, str(Path(tmp) / f"f{i}"), warm=False)
            fresh_cpu.append(_children_cpu() - c0)
            assert rec["status"] == "finished", rec
            fresh.append(rec["wall_time_s"])
            t0, c0 = time.perf_counter(), time.process_time()
            run(load_scenario(scen, one, build_fmus=False), out_dir=Path(tmp) / f"i{i}", progress=False)
            inproc.append(time.perf_counter() - t0)
            inproc_cpu.append(time.process_time() - c0)
    from orchestrator.sweep.warm import close_warm
    close_warm()
    m = statistics.median
    print(f"2-macro-step HS Jeffcott run (median of {repeats}): warm run process {m(warm):.2f} s wall; fresh process {m(fresh):.2f} s wall / "
          f"{m(fresh_cpu):.2f} s CPU; in-process (warm) {m(inproc):.2f} s wall / {m(inproc_cpu):.2f} s CPU: "
          f"a fresh process costs {m(fresh) - m(inproc):.2f} s wall, {m(fresh_cpu) - m(inproc_cpu):.2f} s CPU per run")


def bench_pair(repeats: int, workers: int | None) -> None:
    """sweep (warm), sweep (fresh) and sequential in turn, each a child process (module doc)."""
    me = [sys.executable, str(Path(__file__).resolve())]
    w = ["--workers", str(workers)] if workers else []
    variants = {"sweep": me + ["sweep"] + w, "sweep-fresh": me + ["sweep", "--fresh"] + w,
                "sequential": me + ["sequential"]}
    res = {k: [] for k in variants}
    from orchestrator.sweep.task import run_env
    env = run_env()          # single-threaded BLAS for all three, as the sweep's run processes have it
    for i in range(repeats):
        for name, cmd in variants.items():
            load = os.getloadavg()[0]
            c0, t0 = _children_cpu(), time.perf_counter()
            subprocess.run(cmd, check=True, env=env)
            wall, cpu = time.perf_counter() - t0, _children_cpu() - c0
            res[name].append((wall, cpu))
            print(f"round {i + 1} {name:12s} wall {wall:7.2f} s  cpu {cpu:7.2f} s  (load before {load:.2f})",
                  flush=True)
        seq = res["sequential"][-1][0]
        print(f"round {i + 1} ratio sequential/sweep wall: warm {seq / res['sweep'][-1][0]:.2f}x, fresh "
              f"{seq / res['sweep-fresh'][-1][0]:.2f}x", flush=True)
    m = statistics.median
    for name, rows in res.items():
        print(f"median {name:12s} wall {m(r[0] for r in rows):7.2f} s  cpu {m(r[1] for r in rows):7.2f} s")
    seq = m(r[0] for r in res["sequential"])
    print(f"speed-up of the sweep over sequential (median walls): warm {seq / m(r[0] for r in res['sweep']):.2f}x, "
          f"fresh {seq / m(r[0] for r in res['sweep-fresh']):.2f}x")


def _children_cpu() -> float:
    import resource
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("sweep", "sequential", "overhead", "pair"))
    ap.add_argument("--fresh", action="store_true", help="sweep: a fresh process per run")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--tasks", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    load = os.getloadavg()
    if args.mode == "sweep":
        print(f"sweep wall {bench_sweep(args.workers, warm=not args.fresh):.2f} s (load {load[0]:.1f})")
    elif args.mode == "pair":
        bench_pair(args.repeats, args.workers)
    elif args.mode == "sequential":
        print(f"sequential wall {bench_sequential():.2f} s (load {load[0]:.1f})")
    else:
        bench_overhead(args.tasks, args.workers, args.repeats)
        print(f"load average at start: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
