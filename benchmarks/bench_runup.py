"""Wall time of the Jeffcott run-ups of the paper (section 3.2) through the real FMUs.

    nice -n 5 .venv/bin/python benchmarks/bench_runup.py [--models hs,air,bath]
        [--start 0.25] [--stop 2.0] [--macro-step 1e-4] [--grid 80,80] [--repeat 1] [--out /tmp/bench_runup]
    .venv/bin/python benchmarks/bench_runup.py --table DIR [DIR ...]   # tabulate finished runs

Each model is the shipped scenario (scenarios/jeffcott_runup_{half_sommerfeld,oil_bath,
free_to_air}.yaml: interface-Jacobian coupling, 0.1 ms macro steps, 40 x 40 films) with
``--set`` overrides for start/stop time, macro step and grid. A full mass-conserving run-up
costs most of an hour on this shared machine, so ``--start/--stop`` time a stretch; the table
extrapolates the wall time linearly to the 1.75 s run-up (0.25 -> 2.0 s) and says so.

Wall time is ``summary.json: wall_time_s`` (master loop incl. FMU start-up); the median is
taken over ``--repeat`` runs. The load average (``/proc/loadavg``) is printed with every run:
the machine is shared (up to 9 engineers on 2 cores) and the numbers are noisy.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCEN = {"hs": "half_sommerfeld", "bath": "oil_bath", "air": "free_to_air"}
FULL_SPAN = 1.75   # s, 0.25 -> 2.0 (100 -> 800 Hz) as shipped


def scenario_path(model: str) -> Path:
    return REPO / "scenarios" / f"jeffcott_runup_{SCEN[model]}.yaml"


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
    ap.add_argument("--table", nargs="*", help="only tabulate these finished run directories")
    a = ap.parse_args(argv)
    if a.table:
        print_table([row(Path(d)) for d in a.table])
        return 0

    from orchestrator import load_scenario, run

    out = Path(a.out)
    rows = []
    for model in a.models.split(","):
        path = scenario_path(model)
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
            t0 = time.perf_counter()
            res = run(load_scenario(str(path), overrides=overrides), out_dir=d, progress=False)
            wall = time.perf_counter() - t0
            walls.append(wall)
            print(f"{model} run {k}: {res.status.name} {wall:.1f} s wall (process), load before "
                  f"{load0}, after {loadavg()}", flush=True)
            rows.append(row(d))
        print(f"{model}: median wall {statistics.median(walls):.1f} s over {len(walls)} run(s)")
    print_table(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
