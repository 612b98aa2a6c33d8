"""The film's time tolerance ``theta_atol`` on recorded run-up kinematics (issue 16).

Replays the journal kinematics that a shipped Jeffcott run-up delivered to ``bearing1``
(:mod:`bench_newton_reuse` records them) over short windows, on one film, for several local
error tolerances of theta per internal step (``BearingParams.theta_atol``, default 1e-3), and
prints per window and tolerance: CPU time, internal steps, Newton iterations and LU
factorisations per macro step, and the largest distance of the film force from a run with
``theta_atol`` 1e-5 (Newton tolerances 100x tighter), relative to the largest force.

The whole-run-up effect (onset, vanish, max eps, wall) is measured with ``rotorcosim run
... --set fmus.bearing1.parameters.theta_atol=X --set fmus.bearing2.parameters.theta_atol=X``
(BENCHMARKS.md, session 17).

Run:
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_theta_atol.py --scenario oil_bath \
        --windows 0.3:0.4,0.7:0.8 --atols 1e-3,2e-3,4e-3 [--kin /tmp/kin_oil_bath]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import bench_newton_reuse as nr  # noqa: E402
from bearing_fmu.solver import JACOBIAN_REUSE_BELOW  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="oil_bath", choices=["free_to_air", "oil_bath"])
    ap.add_argument("--windows", default="0.3:0.4,0.7:0.8", help="t0:t1 [s] of the run-up, comma-separated")
    ap.add_argument("--atols", default="1e-3,2e-3,4e-3", help="theta_atol values")
    ap.add_argument("--kin", default=None, help="folder of a recorded run (made if missing)")
    a = ap.parse_args(argv)
    windows = [tuple(float(x) for x in w.split(":")) for w in a.windows.split(",")]
    atols = [float(x) for x in a.atols.split(",")]
    kin_dir = Path(a.kin) if a.kin else Path(tempfile.mkdtemp(prefix="kin_"))
    csv = nr.record(a.scenario, max(t1 for _, t1 in windows) + 0.01, kin_dir)
    from orchestrator.results.run_directory import RunDirectory
    data = RunDirectory(csv.parent).columns()
    print(f"scenario {a.scenario}, bearing1, kinematics {csv}")
    print("| window [s] | theta_atol | CPU ms / macro step | internal steps | Newton | LU | force distance |")
    print("|---|---|---|---|---|---|---|")
    for t0, t1 in windows:
        _, _, F_ref = nr.replay(a.scenario, data, t0, t1, JACOBIAN_REUSE_BELOW, theta_atol=1e-5,
                                newton_atol=1e-6, newton_rtol=1e-7)
        scale = np.abs(F_ref).max()
        for atol in atols:
            c, cpu, F = nr.replay(a.scenario, data, t0, t1, JACOBIAN_REUSE_BELOW, theta_atol=atol)
            err = np.abs(F - F_ref).max() / scale
            print(f"| {t0:g}-{t1:g} | {atol:g} | {cpu:.3f} | {c['steps']:.3f} | {c['newton']:.3f} | "
                  f"{c['factor']:.3f} | {err:.1e} |", flush=True)


if __name__ == "__main__":
    main()
