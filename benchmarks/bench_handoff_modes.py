"""Which hand-off of the stage threads pays, along a run-up (orchestrator.coupling.threads).

Runs a shipped threaded scenario in this process twice, with the hand-offs fixed to
watching and to sleeping (``ROTORCOSIM_STAGE_HANDOFF``), each in a fresh process, and records
the period of every stage step (the time from one stage step's start to the next, so the
master's serial work is in it). Prints the mean period per phase for both modes, then replays
the recorded periods through :class:`orchestrator.coupling.threads.HandoffChooser`: the
total it would give, against always watching, always sleeping and the better mode of every
window of 64 steps (the best any chooser of windows could do). The replay leaves out what a
switch itself costs.

Run:
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_handoff_modes.py \
        --scenario jeffcott_runup_oil_bath --stop 1.2
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

RECORD = """
import sys, time, tempfile
from dataclasses import replace
import numpy as np
import orchestrator.coupling.threads as threads
from orchestrator import load_scenario, run
starts = []
stage_run = threads.StageThreads.run
def timed(self, jobs):
    starts.append(time.perf_counter())
    return stage_run(self, jobs)
threads.StageThreads.run = timed
scenario, stop, out = sys.argv[1], float(sys.argv[2]), sys.argv[3]
sc = replace(load_scenario(scenario), stop_time=stop)
with tempfile.TemporaryDirectory() as d:
    run(sc, out_dir=d, progress=False)
np.save(out, np.diff(np.array(starts)))
"""


def record(scenario: Path, stop: float, mode: str, out: Path) -> np.ndarray:
    env = dict(os.environ, ROTORCOSIM_STAGE_HANDOFF=mode, OPENBLAS_NUM_THREADS="1",
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    subprocess.run([sys.executable, "-c", RECORD, str(scenario), repr(stop), str(out)], check=True, env=env)
    return np.load(out)


def replay(watch: np.ndarray, sleep: np.ndarray, **kw) -> tuple[float, float]:
    """(total seconds, share of steps watched) of the chooser on the recorded periods."""
    from orchestrator.coupling.threads import HandoffChooser
    c = HandoffChooser(**kw)
    clock = total = 0.0
    watched = 0
    for w, s in zip(watch, sleep):
        on = c.tick(clock)
        d = w if on else s
        clock += d
        total += d
        watched += on
    return total, watched / len(watch)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="jeffcott_runup_oil_bath")
    ap.add_argument("--stop", type=float, default=1.2, help="stop time [s]")
    ap.add_argument("--phases", type=int, default=3, help="phases (equal numbers of steps) to print")
    a = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    scenario = ROOT / "scenarios" / f"{a.scenario}.yaml"
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        watch = record(scenario, a.stop, "watch", Path(d) / "watch.npy")
        sleep = record(scenario, a.stop, "sleep", Path(d) / "sleep.npy")
        wall = time.perf_counter() - t0
    n = min(len(watch), len(sleep))
    watch, sleep = watch[:n], sleep[:n]
    print(f"{a.scenario} to {a.stop} s: {n} stage steps per run, two runs in {wall:.0f} s")
    print("| steps | watching: mean period [ms] | sleeping [ms] |")
    print("|---|---|---|")
    for part in np.array_split(np.arange(n), a.phases):
        print(f"| {part[0]}-{part[-1]} | {watch[part].mean() * 1e3:.3f} | {sleep[part].mean() * 1e3:.3f} |")
    best = sum(min(watch[i:i + 64].sum(), sleep[i:i + 64].sum()) for i in range(0, n, 64))
    chosen, share = replay(watch, sleep)
    print(f"always watching {watch.sum():.2f} s, always sleeping {sleep.sum():.2f} s, better mode of every "
          f"64-step window {best:.2f} s; HandoffChooser (defaults) {chosen:.2f} s, watching {share:.0%} of the steps")


if __name__ == "__main__":
    main()
