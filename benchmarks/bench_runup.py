"""Wall time of the Jeffcott run-ups of the paper (section 3.2) through the real FMUs.

    nice -n 5 .venv/bin/python benchmarks/bench_runup.py [--models hs,air,bath]
        [--start 0.25] [--stop 2.0] [--macro-step 1e-4] [--grid 80,80] [--repeat 1] [--out /tmp/bench_runup]
        [--repo DIR]   # scenarios (and, with PYTHONPATH=DIR, code) of another checkout: the old-code peer
    .venv/bin/python benchmarks/bench_runup.py --table DIR [DIR ...]   # tabulate finished runs

Each model is the shipped scenario (scenarios/jeffcott_runup_{half_sommerfeld,oil_bath,
free_to_air}.yaml: interface-Jacobian coupling, 0.1 ms macro steps, 40 x 40 films) with
``--set`` overrides for start/stop time, macro step and grid. A full mass-conserving run-up
costs most of an hour on this shared machine, so ``--start/--stop`` time a stretch; the table
extrapolates the wall time linearly to the 1.75 s run-up (0.25 -> 2.0 s) and says so.

Wall time is ``summary.json: wall_time_s`` (master loop incl. FMU start-up); the median is
taken over ``--repeat`` runs. The load average (``/proc/loadavg``) is printed with every run:
the machine is shared (up to 9 engineers on 2 cores) and the numbers are noisy. Each run also
records the process CPU time (the FMUs run in this process, so it covers film, rotor and
master; less sensitive to other users than wall time), the UTC date and the load before and
after, as one JSON line in ``OUT/bench.jsonl``.

Old-code peer (same session, same machine): check the old commit out in a worktree and run
this script with its code and scenarios, e.g.
``git worktree add /tmp/old <commit> && PYTHONPATH=/tmp/old .venv/bin/python
benchmarks/bench_runup.py --repo /tmp/old ...`` (the FMUs are then built from /tmp/old).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCEN = {"hs": "half_sommerfeld", "bath": "oil_bath", "air": "free_to_air"}
FULL_SPAN = 1.75   # s, 0.25 -> 2.0 (100 -> 800 Hz) as shipped


def scenario_path(model: str, repo: Path = REPO) -> Path:
    return Path(repo) / "scenarios" / f"jeffcott_runup_{SCEN[model]}.yaml"


def git_commit(repo) -> str:
    """HEAD of the checkout whose code runs (+ '-dirty' with uncommitted changes), or '?'."""
    import subprocess
    try:
        head = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(repo), "status", "--porcelain", "--untracked-files=no",
                                "--", "bearing_fmu", "rotor_fmu", "orchestrator"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return (head + ("-dirty" if dirty else "")) or "?"
    except (OSError, subprocess.SubprocessError):
        return "?"


def loadavg() -> str:
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "?"


def row(run_dir: Path) -> dict:
    s = json.loads((Path(run_dir) / "summary.json").read_text())
    span = float(s["end_time"]) - float(s["start_time"])
    a = s.get("analysis") or {}
    j = (a.get("journals") or {}).get("bearing1") or {}
    return {"run": str(run_dir), "status": s["status"], "span_s": span,
            "macro_step": s["coupling"].get("macro_step"), "macro_steps": s["macro_steps"],
            "wall_s": s["wall_time_s"],
            "wall_per_sim_s": s["wall_time_s"] / span if span > 0 else float("nan"),
            "full_runup_est_s": s["wall_time_s"] / span * FULL_SPAN if span > 0 else float("nan"),
            "onset_hz": j.get("onset_speed_hz")}


def print_table(rows):
    print("| run | status | simulated [s] | macro step [s] | steps | wall [s] | wall / simulated s | "
          "est. full 1.75 s run-up [min] | onset [Hz] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        onset = "-" if r["onset_hz"] is None else f"{r['onset_hz']:.1f}"
        print(f"| {r['run']} | {r['status']} | {r['span_s']:.3f} | {r['macro_step']:g} | "
              f"{r['macro_steps']} | {r['wall_s']:.0f} | {r['wall_per_sim_s']:.0f} | "
              f"{r['full_runup_est_s'] / 60:.1f} | {onset} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", default="hs")
    ap.add_argument("--start", type=float, default=0.25)
    ap.add_argument("--stop", type=float, default=2.0)
    ap.add_argument("--macro-step", type=float, default=1e-4)
    ap.add_argument("--grid", default=None, help="n_phi,n_z (default: the scenario's 40,40)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--out", default="/tmp/bench_runup")
    ap.add_argument("--repo", default=str(REPO),
                    help="checkout whose scenarios are run (default: this one)")
    ap.add_argument("--table", nargs="*", help="only tabulate these finished run directories")
    a = ap.parse_args(argv)
    if a.table:
        print_table([row(Path(d)) for d in a.table])
        return 0

    import orchestrator
    from orchestrator import load_scenario, run

    print(f"code: {Path(orchestrator.__file__).parent}, scenarios: {a.repo}, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}", flush=True)

    out = Path(a.out)
    rows = []
    for model in a.models.split(","):
        path = scenario_path(model, Path(a.repo))
        overrides = [f"start_time={a.start}", f"stop_time={a.stop}",
                     f"coupling.macro_step={a.macro_step}"]
        if a.grid:
            n_phi, n_z = a.grid.split(",")
            for b in ("bearing1", "bearing2"):
                overrides += [f"fmus.{b}.parameters.n_phi={n_phi}", f"fmus.{b}.parameters.n_z={n_z}"]
        walls = []
        for k in range(a.repeat):
            d = out / f"{model}_{k}"
            load0 = loadavg()
            date0 = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S")
            commit = git_commit(Path(orchestrator.__file__).parents[1])   # before the run
            t0 = time.perf_counter()
            c0 = time.process_time()
            res = run(load_scenario(str(path), overrides=overrides, build_fmus=True), out_dir=d, progress=False)
            cpu = time.process_time() - c0
            wall = time.perf_counter() - t0
            walls.append(wall)
            load1 = loadavg()
            print(f"{model} run {k}: {res.status.name} {wall:.1f} s wall (process), {cpu:.1f} s CPU, "
                  f"started {date0} UTC, load before {load0}, after {load1}", flush=True)
            r = row(d)
            rows.append(r)
            rec = dict(r, model=model, repeat=k, process_wall_s=wall, cpu_s=cpu, date_utc=date0,
                       load_before=load0, load_after=load1, repo=str(a.repo),
                       code=str(Path(orchestrator.__file__).parent),
                       commit=commit,
                       ms_per_step_wall=1e3 * r["wall_s"] / max(r["macro_steps"], 1),
                       ms_per_step_cpu=1e3 * cpu / max(r["macro_steps"], 1))
            out.mkdir(parents=True, exist_ok=True)
            with open(out / "bench.jsonl", "a") as f:
                f.write(json.dumps(rec) + "\n")
        print(f"{model}: median wall {statistics.median(walls):.1f} s over {len(walls)} run(s)")
    print_table(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
