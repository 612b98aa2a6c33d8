"""The ``sweep`` verb: every run of a sweep file on Dask, and its table (docs/sweeps.md)."""

from __future__ import annotations

import sys
from pathlib import Path

from orchestrator.cli.common import PROG, _folder


def _add_sweep(sub) -> None:
    p = sub.add_parser("sweep", help="run a parameter sweep (stability map) on Dask", description=(
        "Run every run of a sweep file (docs/sweeps.md) as a Dask task, in a run process of its worker (not "
        "the worker itself), into DIR/runs/<run_id>/, and write DIR/sweep.csv. Default: a local cluster, one "
        "worker per core."))
    p.add_argument("file", metavar="FILE", help="sweep YAML file")
    p.add_argument("--out", metavar="DIR", type=_folder, help="output folder (default: runs/sweep_<file name>)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="address of a running Dask scheduler, e.g. "
                   "tcp://10.0.0.5:8786 (default: $DASK_SCHEDULER_ADDRESS, else a local cluster)")
    p.add_argument("--workers", metavar="N", type=int, help="runs at once on the local cluster: its workers, "
                   "threads of this process, each running its runs in a run process of its own (default: one "
                   "per core)")
    p.add_argument("--resume", action="store_true", help="skip runs whose folder holds a finished summary")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (on a terminal) and no line per "
                   "run done (otherwise)")
    p.add_argument("--fresh-processes", action="store_true", help="a new Python process for every run instead "
                   "of one warm run process per worker that runs many (slower; docs/sweeps.md section 2)")
    p.set_defaults(func=_cmd_sweep)


def _cmd_sweep(args) -> int:
    from orchestrator.sweep import default_out_dir, load_sweep
    from orchestrator.sweep.plan import PROGRESS_FROM_RUNS, count_runs, plan_sweep
    from orchestrator.sweep.runner import check_cluster_options, run_sweep

    check_cluster_options(args.scheduler, args.workers)   # before validating every run (1-2 min for 10 000)
    spec = load_sweep(args.file)
    n = count_runs(spec)                               # refuses too many runs before expanding any
    if n >= PROGRESS_FROM_RUNS:                        # 5-12 ms per run: say why nothing runs yet
        print(f"sweep {args.file}: validating the scenario of each of its {n} runs before the first starts",
              file=sys.stderr, flush=True)
    runs = plan_sweep(spec, progress=False if args.no_progress else None)
    out = Path(args.out) if args.out else default_out_dir(args.file)
    print(f"sweep {args.file}: {len(runs)} runs of {spec.scenario.name} ({spec.mode}) -> {out}", flush=True)
    o = run_sweep(spec, runs, out, scheduler=args.scheduler, workers=args.workers, resume=args.resume,
                  progress=False if args.no_progress else None, warm=not args.fresh_processes)
    counts = {s: sum(r["status"] == s for r in o.rows) for s in dict.fromkeys(r["status"] for r in o.rows)}
    print(f"table: {o.table}" + (f" ({o.skipped} runs resumed)" if o.skipped else ""))
    print("runs: " + ", ".join(f"{n} {s}" for s, n in counts.items()))
    if spec.collect and not o.interrupted:
        print(f"maps: `{PROG} plot {out}` draws each collected value over the parameters")
    for r in o.rows:
        if r["status"] != "finished" and (r["status"] != "cancelled" or not r["message"].startswith("not run")):
            print(f"  {r['run_id']} {r['status']}: {r['message']}", file=sys.stderr)
    if o.interrupted:
        term = o.stopped_by == "SIGTERM"
        print(f"{'terminated by signal SIGTERM' if term else 'interrupted'}: pending runs cancelled, finished "
              f"runs kept; continue with `{PROG} sweep {args.file} --out {out} --resume`", file=sys.stderr)
        return 143 if term else 130
    return 0 if counts.get("finished", 0) == len(o.rows) else 1
