"""Sweep speed (issue 15): an 8-run sweep on Dask against the same 8 runs in one process,
and the cost per task.

Modes (``sweep``, ``sequential``: one per process, timed from outside, start-up included):

* ``sweep``: ``rotorcosim sweep``'s code path (:func:`orchestrator.sweep.runner.run_sweep`) on
  a LocalCluster of ``--workers`` (default: one per core) for 8 seeded half-Sommerfeld Jeffcott
  run-ups, eta0 over 8 values: ``--length short`` (default, ``benchmarks/sweep_bench.yaml``):
  220 -> 260 Hz, 1000 macro steps each (~2.5 s of work, shorter than any real run-up);
  ``--length long`` (``benchmarks/sweep_bench_long.yaml``): the shipped seeded run-up 220 ->
  380 Hz through the onset, 4000 macro steps each. Cluster start-up, the run processes and the
  table included. Warm run processes (the default); ``--fresh`` for a fresh process per run
  (``--fresh-processes``).
* ``sequential``: the same 8 runs (the same plans and overrides) one after another in this
  process with ``orchestrator.load_scenario`` + ``orchestrator.run``: the peer.
* ``pair``: runs ``sweep``, ``sweep --fresh`` and ``sequential`` as child processes in turn,
  ``--repeats`` times, and prints each one's wall and CPU (``getrusage`` of the reaped
  children: the cluster and the run processes included), the medians, the ratios of each round
  and the load average before each run; all three with single-threaded BLAS (as the sweep's run
  processes have it).
* ``startup``: the fixed costs before the runs: a 2-worker LocalCluster started and closed
  with worker processes (``processes=True``, the default before session 3) and with worker
  threads (now); and the first 2-macro-step run of a warm run process started at the request
  against one prestarted 6 s earlier (it preloads while it waits, as during a cluster start).
* ``contention``: a 1000-step run in a warm run process alone against two at once (two warm
  processes): how much of two cores two runs get on this machine (module ``bench_contention``).
* ``overhead``: (a) ``--tasks`` trivial tasks (:func:`orchestrator.sweep.task.trivial_run`,
  nothing inside) through the LocalCluster: Dask's scheduling overhead per task; (b) one
  ``execute_run`` of a 2-macro-step run in a warm run process, in a fresh process and in this
  process: what the run process costs per run.

    nice -n 5 .venv/bin/python benchmarks/bench_sweep.py pair --repeats 3
    .venv/bin/python benchmarks/bench_sweep.py pair --repeats 2 --length long --variants sweep,sequential
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
SWEEPS = {"short": ROOT / "benchmarks" / "sweep_bench.yaml",        # 1000 macro steps per run
          "long": ROOT / "benchmarks" / "sweep_bench_long.yaml"}    # 4000: the shipped run-up
SWEEP = SWEEPS["short"]


def bench_sweep(workers: int | None, warm: bool = True, path: Path = SWEEP) -> float:
    from orchestrator.sweep import prepare
    from orchestrator.sweep.runner import run_sweep
    spec, runs = prepare(path)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        out = run_sweep(spec, runs, tmp, workers=workers, progress=False, warm=warm)
        wall = time.perf_counter() - t0
    bad = [r for r in out.rows if r["status"] != "finished"]
    assert not bad, bad
    print("run walls [s]: " + " ".join(f"{r['wall_time_s']:.1f}" for r in out.rows))
    return wall


def bench_sequential(path: Path = SWEEP) -> float:
    from orchestrator import load_scenario, run
    from orchestrator.sweep import prepare
    spec, runs = prepare(path)
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


def bench_pair(repeats: int, workers: int | None, length: str = "short", which: str = "all") -> None:
    """sweep (warm), sweep (fresh) and sequential in turn, each a child process (module doc)."""
    me = [sys.executable, str(Path(__file__).resolve())]
    w = ["--workers", str(workers)] if workers else []
    ln = ["--length", length]
    variants = {"sweep": me + ["sweep"] + ln + w, "sweep-fresh": me + ["sweep", "--fresh"] + ln + w,
                "sequential": me + ["sequential"] + ln}
    if which != "all":
        variants = {k: v for k, v in variants.items() if k in which.split(",")}
    print(f"{length} runs ({SWEEPS[length].name}), variants {', '.join(variants)}", flush=True)
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
        if "sequential" in res:
            seq = res["sequential"][-1][0]
            print(f"round {i + 1} ratio sequential/sweep wall: " + ", ".join(
                f"{k} {seq / v[-1][0]:.2f}x" for k, v in res.items() if k != "sequential"), flush=True)
    m = statistics.median
    for name, rows in res.items():
        print(f"median {name:12s} wall {m(r[0] for r in rows):7.2f} s  cpu {m(r[1] for r in rows):7.2f} s")
    if "sequential" in res:
        seq, seq_cpu = m(r[0] for r in res["sequential"]), m(r[1] for r in res["sequential"])
        for k, v in res.items():
            if k != "sequential":
                print(f"{k}: speed-up over sequential (median walls) {seq / m(r[0] for r in v):.2f}x; CPU beyond "
                      f"sequential {m(r[1] for r in v) - seq_cpu:+.2f} s ({(m(r[1] for r in v) - seq_cpu) / 8:+.2f} s per run)")


def _cluster_cost(processes: bool) -> tuple[float, float]:
    """(wall, CPU incl. children) to start a 2-worker LocalCluster with a client and close it."""
    import logging
    import resource
    import dask
    from distributed import Client, LocalCluster
    from orchestrator.sweep.runner import QUIET_LOCAL_CLUSTER
    c0, s0, t0 = _children_cpu(), resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
    with dask.config.set(QUIET_LOCAL_CLUSTER):
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=processes, dashboard_address=None,
                               silence_logs=logging.ERROR, scheduler_kwargs={"dashboard_address": ":0"})
        client = Client(cluster)
    client.close()
    cluster.close()
    s1 = resource.getrusage(resource.RUSAGE_SELF)
    return time.perf_counter() - t0, _children_cpu() - c0 + (s1.ru_utime + s1.ru_stime - s0.ru_utime - s0.ru_stime)


def bench_startup(repeats: int) -> None:
    """The fixed costs a sweep pays before its runs: the cluster (worker processes, the old
    default, against worker threads, the new one) and a warm run process's first run (started
    at the request, the old way, against prestarted and preloaded)."""
    from orchestrator.sweep import warm as wm
    from orchestrator.sweep.task import execute_run
    m = statistics.median
    res = {True: [], False: []}
    for _ in range(repeats):
        for processes in (True, False):
            res[processes].append(_cluster_cost(processes))
    for processes, rows in res.items():
        print(f"LocalCluster(2 workers, processes={processes}) start + close: wall {m(r[0] for r in rows):.2f} s, "
              f"CPU {m(r[1] for r in rows):.2f} s (median of {repeats})")
    scen = ROOT / "scenarios" / "jeffcott_runup_half_sommerfeld_seeded.yaml"
    one = ["stop_time=0.5502", "output.interval=1e-4"]   # 2 macro steps
    first = {"cold": [], "prestarted": []}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeats):
            for how in first:
                label = Path(tmp) / f"{how}{i}" / "runs"
                c0 = _children_cpu()
                if how == "prestarted":
                    wm.prestart(str(label), 1)
                    time.sleep(6.0)            # as if the cluster were starting meanwhile
                rec = execute_run(str(scen), one, str(label / "r"))
                assert rec["status"] == "finished", rec
                wm.close_warm()
                first[how].append((rec["wall_time_s"], _children_cpu() - c0))
    for how, rows in first.items():
        print(f"first 2-step run of a warm run process, {how}: wall {m(r[0] for r in rows):.2f} s from the request; "
              f"the process's whole CPU {m(r[1] for r in rows):.2f} s (median of {repeats})")


def bench_contention(repeats: int) -> None:
    """What two runs at once cost each on this machine: a 1000-step run of the benchmark sweep
    in a warm run process alone, then two such runs at the same time in two warm run processes
    (all processes warmed by a first run). Per-run wall alone vs together bounds any 2-worker
    sweep's speed-up at 2 x alone / together, whatever the overheads."""
    from concurrent.futures import ThreadPoolExecutor
    from orchestrator.sweep import prepare
    from orchestrator.sweep import warm as wm
    from orchestrator.sweep.task import execute_run
    spec, runs = prepare(SWEEP)
    ov = [list(r.overrides) for r in runs]
    alone, together = [], []
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(2) as pool:
        label = Path(tmp) / "runs"
        wm.prestart(str(label), 2)
        n = iter(range(10 ** 6))

        def one(o):
            rec = execute_run(str(spec.scenario), o, str(label / f"r{next(n)}"))
            assert rec["status"] == "finished", rec
            return rec["wall_time_s"]
        list(pool.map(one, ov[:2]))                  # warm both processes
        for i in range(repeats):
            alone.append(one(ov[i % 8]))
            together.extend(pool.map(one, [ov[(i + 1) % 8], ov[(i + 2) % 8]]))
    wm.close_warm()
    m = statistics.median
    print(f"1000-step run in a warm process: alone {m(alone):.2f} s, two at once {m(together):.2f} s each "
          f"(median of {repeats} / {2 * repeats}): two runs at once do {2 * m(alone) / m(together):.2f}x the work "
          f"of one, the bound of a 2-worker sweep's speed-up")


def _children_cpu() -> float:
    import resource
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("sweep", "sequential", "overhead", "pair", "startup", "contention"))
    ap.add_argument("--fresh", action="store_true", help="sweep: a fresh process per run")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--tasks", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--length", choices=tuple(SWEEPS), default="short",
                    help="short: 1000 macro steps per run; long: 4000, the shipped seeded run-up")
    ap.add_argument("--variants", default="all", help="pair: comma-separated subset of sweep,sweep-fresh,sequential")
    args = ap.parse_args(argv)
    load = os.getloadavg()
    if args.mode == "sweep":
        print(f"sweep wall {bench_sweep(args.workers, warm=not args.fresh, path=SWEEPS[args.length]):.2f} s "
              f"(load {load[0]:.1f})")
    elif args.mode == "contention":
        bench_contention(args.repeats)
        print(f"load average at start: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    elif args.mode == "startup":
        bench_startup(args.repeats)
        print(f"load average at start: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    elif args.mode == "pair":
        bench_pair(args.repeats, args.workers, args.length, args.variants)
    elif args.mode == "sequential":
        print(f"sequential wall {bench_sequential(SWEEPS[args.length]):.2f} s (load {load[0]:.1f})")
    else:
        bench_overhead(args.tasks, args.workers, args.repeats)
        print(f"load average at start: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
