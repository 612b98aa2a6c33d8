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

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import bench_newton_reuse as nr  # noqa: E402
from bearing_fmu.solver import JACOBIAN_REUSE_BELOW  # noqa: E402


def main(argv=None):
    scenario, windows, atols, data = nr.windows_cli(__doc__.splitlines()[0], "atols",
                                                    "1e-3,2e-3,4e-3", "theta_atol values", argv)
    print("| window [s] | theta_atol | CPU ms / macro step | internal steps | Newton | LU | force distance |")
    print("|---|---|---|---|---|---|---|")
    for t0, t1 in windows:
        _, _, F_ref = nr.replay(scenario, data, t0, t1, JACOBIAN_REUSE_BELOW, theta_atol=1e-5,
                                newton_atol=1e-6, newton_rtol=1e-7)
        scale = np.abs(F_ref).max()
        for atol in atols:
            c, cpu, F = nr.replay(scenario, data, t0, t1, JACOBIAN_REUSE_BELOW, theta_atol=atol)
            err = np.abs(F - F_ref).max() / scale
            print(f"| {t0:g}-{t1:g} | {atol:g} | {cpu:.3f} | {c['steps']:.3f} | {c['newton']:.3f} | "
                  f"{c['factor']:.3f} | {err:.1e} |", flush=True)


if __name__ == "__main__":
    main()
