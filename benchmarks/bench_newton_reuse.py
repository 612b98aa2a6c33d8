"""LU reuse of the film's Newton iteration on recorded run-up kinematics (issue 16).

Replays the journal kinematics that a shipped Jeffcott run-up delivered to ``bearing1`` over
short windows (a quiet phase and the whirl) on one film, with the second simplified-Newton
rule (:data:`bearing_fmu.solver.JACOBIAN_REUSE_BELOW`) at several bounds (0: only the first
rule, the code before it), and prints per window and bound: CPU time, internal steps, Newton
iterations and LU factorisations per macro step, and the largest distance of the film force
from a run with 1000x tighter Newton tolerances (both rules off), relative to the largest force.

The kinematics come from a run of the shipped scenario with the journal velocities recorded
(``--kin DIR``: reuse a folder from an earlier call; by default made in a temporary folder:
one run-up to the end of the last window).

Run:
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_newton_reuse.py --scenario oil_bath \
        --windows 0.3:0.4,0.7:0.8 --bounds 0,0.1,0.2 [--kin /tmp/kin_oil_bath]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
SIGNALS = "[rotor.omega, rotor.x_1, rotor.y_1, rotor.x_2, rotor.y_2, rotor.vx_1, rotor.vy_1, bearing1.eps, bearing2.eps]"


def record(scenario: str, stop: float, out: Path) -> Path:
    """Run the shipped scenario to ``stop`` with the journal velocities recorded; results.csv."""
    csv = out / "results.csv"
    if not csv.is_file():
        subprocess.run([sys.executable, "-m", "orchestrator", "run",
                        str(ROOT / "scenarios" / f"jeffcott_runup_{scenario}.yaml"), "--out", str(out),
                        "--no-progress", "--set", f"stop_time={stop}", "--set", f"output.signals={SIGNALS}"],
                       check=True, cwd=ROOT)
    return csv


def bearing_params(scenario: str, **extra):
    from bearing_fmu.model import BearingParams
    fields = BearingParams.__dataclass_fields__
    raw = yaml.safe_load((ROOT / "scenarios" / f"jeffcott_runup_{scenario}.yaml").read_text())
    prm = {}
    for k, v in raw["fmus"]["bearing1"]["parameters"].items():
        if k in fields:
            default = fields[k].default
            prm[k] = v if isinstance(default, str) else type(default)(float(v))
    prm.update(extra)
    return BearingParams(**prm)


def replay(scenario, data, t0, t1, bound, warm=30, **extra):
    """(counts per macro step, CPU ms per macro step, forces (m, 2)) over [t0, t1]."""
    from bearing_fmu.model import BearingModel
    t = data["time"]
    i0, i1 = int(np.searchsorted(t, t0)), int(np.searchsorted(t, t1))

    def kin(i):
        return tuple(float(data[k][i]) for k in ("rotor.x_1", "rotor.y_1", "rotor.vx_1",
                                                 "rotor.vy_1", "rotor.omega"))
    b = BearingModel(bearing_params(scenario, **extra))
    b.film.jac_reuse_below = bound
    b.initialize(*kin(i0 - warm), init="stationary")
    for i in range(i0 - warm, i0):
        b.step(1e-4, *kin(i + 1))
    s0 = dict(b.stats)
    F = []
    c0 = time.process_time()
    for i in range(i0, i1):
        b.step(1e-4, *kin(i + 1))
        F.append((b.outputs["Fx"], b.outputs["Fy"]))
    n = i1 - i0
    cpu = (time.process_time() - c0) / n * 1e3
    counts = {k: (b.stats[k] - s0[k]) / n for k in ("steps", "newton", "factor")}
    return counts, cpu, np.array(F)


def windows_cli(description, name, default, help_, argv=None):
    """The command line of this benchmark and of bench_theta_atol.py: ``--scenario``,
    ``--windows``, ``--NAME`` (comma-separated values) and ``--kin``; records the kinematics
    if needed. Returns (scenario, windows, values, recorded columns)."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--scenario", default="oil_bath", choices=["free_to_air", "oil_bath"])
    ap.add_argument("--windows", default="0.3:0.4,0.7:0.8", help="t0:t1 [s] of the run-up, comma-separated")
    ap.add_argument(f"--{name}", default=default, help=help_)
    ap.add_argument("--kin", default=None, help="folder of a recorded run (made if missing)")
    a = ap.parse_args(argv)
    windows = [tuple(float(x) for x in w.split(":")) for w in a.windows.split(",")]
    values = [float(x) for x in getattr(a, name).split(",")]
    kin_dir = Path(a.kin) if a.kin else Path(tempfile.mkdtemp(prefix="kin_"))
    csv = record(a.scenario, max(t1 for _, t1 in windows) + 0.01, kin_dir)
    from orchestrator.results.run_directory import RunDirectory
    print(f"scenario {a.scenario}, bearing1, kinematics {csv}")
    return a.scenario, windows, values, RunDirectory(csv.parent).columns()


def main(argv=None):
    scenario, windows, bounds, data = windows_cli(__doc__.splitlines()[0], "bounds", "0,0.1,0.2",
                                                  "JACOBIAN_REUSE_BELOW values", argv)
    print("| window [s] | bound | CPU ms / macro step | internal steps | Newton | LU | force error |")
    print("|---|---|---|---|---|---|---|")
    for t0, t1 in windows:
        _, _, F_ref = replay(scenario, data, t0, t1, 0.0, newton_atol=1e-7, newton_rtol=1e-8)
        scale = np.abs(F_ref).max()
        for bound in bounds:
            c, cpu, F = replay(scenario, data, t0, t1, bound)
            err = np.abs(F - F_ref).max() / scale
            print(f"| {t0:g}-{t1:g} | {bound:g} | {cpu:.3f} | {c['steps']:.3f} | {c['newton']:.3f} | "
                  f"{c['factor']:.3f} | {err:.1e} |")


if __name__ == "__main__":
    main()
