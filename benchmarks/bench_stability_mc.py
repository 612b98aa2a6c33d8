"""Seconds of one speed of `rotorcosim stability --film mc` (BENCHMARKS.md session 24): the static
equilibrium from a speed 0.5 Hz below (as a scan step) and the least-damped eigenvalue, in the
checkout REPO (old or new, one process per run), on GRID x GRID films of the oil-bath Jeffcott rotor.

    python benchmarks/bench_stability_mc.py REPO GRID F      # prints: seconds, max Re [1/s], |Im| [rad/s]
"""

import math
import sys
import time

repo, grid, f = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
sys.path.insert(0, repo)
from orchestrator.scenario import load_scenario  # noqa: E402
from orchestrator.stability.films import _MCFilm  # noqa: E402
from orchestrator.stability.system import build_system  # noqa: E402
from rotor_fmu.stability import static_bearing_loads  # noqa: E402

sets = [f"fmus.{b}.parameters.{k}={grid}" for b in ("bearing1", "bearing2") for k in ("n_phi", "n_z")]
system = build_system(load_scenario(f"{repo}/scenarios/jeffcott_runup_oil_bath.yaml", sets, build_fmus=True))
fn = _MCFilm(system, static_bearing_loads(system.rotor))
fn.max_re(2 * math.pi * (f - 0.5))           # warm: numba, the equilibrium near f
t = time.perf_counter()
re, im = fn.max_re(2 * math.pi * f)
print(f"{time.perf_counter() - t:.3f} {re:.6f} {im:.4f}")
