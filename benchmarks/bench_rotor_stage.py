"""The rotor stage of an interface-Jacobian run-up alone: one FMU, its real inputs replayed.

    .venv/bin/python benchmarks/bench_rotor_stage.py [--scenario oil_bath_seeded] [--stop 0.65]
        [--inputs /tmp/rotor_stage_inputs.npy] [--fmu NAME=PATH ...] [--repeat 5] [--from-step 0]

Why: in Gauss-Seidel [rotor, bearing1, bearing2] with the bearings stepping in parallel the
rotor's set/doStep/get is the serial part of every macro step (issue 14). Its cost depends on
the film coefficients it gets (sub-steps ~ H ||M^-1 C_aug|| / 2), so it is measured on the
inputs of a real run: ``--inputs`` (made once if missing) holds, per macro step of
``scenarios/jeffcott_runup_<scenario>.yaml`` run in process up to ``--stop``, the time, step
size and the rotor's 20 inputs (forces, then K and C of each bearing) as the master set them.

Each ``--fmu`` (default: ``new=`` the repository's fmus/JeffcottRotor.fmu) is replayed in a
fresh child process (``orchestrator.fmi.subsystem.Subsystem``, the master's in-process FMU
path, single-threaded BLAS), the variants interleaved ``--repeat`` times: the scenario's rotor
parameters, initialization, then per step fmi2SetReal (20 values), fmi2DoStep, fmi2GetReal
(the 11 outputs the run-up reads). Reported: median wall and CPU (``thread_time``) per call
over the steps from ``--from-step`` on; the final rotor state of every variant is compared
with the first one's (the replay is open-loop: the inputs do not react to the state, so it
measures cost and round-off, not the coupled result).

An old FMU for an a/b: ``git archive <commit> | tar -x -C /tmp/old && (cd /tmp/old &&
PYTHONPATH=. python -c "from orchestrator.fmi.build import build_fmus; build_fmus()")``, then
``--fmu old=/tmp/old/fmus/JeffcottRotor.fmu --fmu new=fmus/JeffcottRotor.fmu``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SINGLE = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
INPUTS = ["Fx_1", "Fy_1", "Fx_2", "Fy_2"] + [f"{k}{a}{b}_{i}" for i in (1, 2) for k in "kc"
                                            for a in "xy" for b in "xy"]
OUTPUTS = ["x_1", "y_1", "vx_1", "vy_1", "omega", "x_2", "y_2", "vx_2", "vy_2", "x_disc", "y_disc"]


def capture(scenario: Path, stop: float, path: Path) -> None:
    """Run the scenario in process and save the rotor's inputs per macro step (module doc)."""
    from orchestrator import load_scenario
    from orchestrator.coupling.execution import MasterAlgorithm

    sc = load_scenario(scenario, [f"stop_time={stop}"], build_fmus=True)
    with tempfile.TemporaryDirectory() as out:
        m = MasterAlgorithm(sc, out_dir=Path(out))
        m.setup()
        m.initialize()
        u = next(u for u in m.units if u.name == "rotor")
        if list(u.inb.names) != INPUTS:
            raise SystemExit(f"rotor inputs {u.inb.names} are not the interface-Jacobian set {INPUTS}")
        rows, do_step = [], u.sub.do_step

        def recording(t, h):
            rows.append([t, h, *u.inb.values])
            return do_step(t, h)
        u.sub.do_step = recording
        while m.status.name == "RUNNING":
            m.step()
        m.terminate()
    np.save(path, np.array(rows))


def child(fmu: Path, scenario: Path, inputs: Path, from_step: int, out: Path) -> None:
    """Replay the inputs through one FMU instance in this process; timings to ``out`` (json)."""
    from orchestrator import load_scenario
    from orchestrator.fmi.subsystem import Subsystem

    sc = load_scenario(scenario)
    spec = next(f for f in sc.fmus if f.name == "rotor")
    d = np.load(inputs)
    with tempfile.TemporaryDirectory() as work:
        sub = Subsystem("rotor", fmu, work_dir=work)
        sub.set_parameters(dict(spec.parameters))
        sub.setup_experiment(float(d[0, 0]), None)
        sub.enter_initialization_mode()
        sub.exit_initialization_mode()
        inb, outb = sub.real_batch(INPUTS), sub.real_batch(OUTPUTS)
        walls = {k: [] for k in ("set", "step", "get")}
        cpus = {k: [] for k in walls}
        clock, cpu = time.perf_counter, time.thread_time
        for row in d:
            inb.values[:] = row[2:]
            w0, c0 = clock(), cpu()
            sub.set_real(inb)
            w1, c1 = clock(), cpu()
            sub.do_step(float(row[0]), float(row[1]))
            w2, c2 = clock(), cpu()
            sub.get_real(outb)
            w3, c3 = clock(), cpu()
            for k, a, b, x, y in (("set", w0, w1, c0, c1), ("step", w1, w2, c1, c2), ("get", w2, w3, c2, c3)):
                walls[k].append(b - a)
                cpus[k].append(y - x)
        final = outb.values.tolist()
        sub.terminate()
        sub.free()
    med = {f"{k}_{kind}": 1e6 * statistics.median(v[from_step:]) for kind, src in (("wall", walls), ("cpu", cpus))
           for k, v in src.items()}
    out.write_text(json.dumps({**med, "final": final, "steps": len(d)}))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", default="oil_bath_seeded")
    ap.add_argument("--stop", type=float, default=0.65)
    ap.add_argument("--inputs", type=Path, default=Path(tempfile.gettempdir()) / "rotor_stage_inputs.npy")
    ap.add_argument("--fmu", action="append", default=[], metavar="NAME=PATH")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--from-step", type=int, default=0, help="median over the steps from this one on")
    ap.add_argument("--child", nargs=2, metavar=("FMU", "OUT"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    scenario = REPO / "scenarios" / f"jeffcott_runup_{args.scenario}.yaml"
    if args.child:
        child(Path(args.child[0]), scenario, args.inputs, args.from_step, Path(args.child[1]))
        sys.stdout.flush()
        os._exit(0)       # no interpreter teardown with a PythonFMU FMU loaded (orchestrator.cli.console_main)
    if not args.inputs.exists():
        print(f"capturing the rotor inputs of {scenario.name} up to {args.stop} s into {args.inputs} ...", flush=True)
        capture(scenario, args.stop, args.inputs)
    fmus = dict(f.split("=", 1) for f in args.fmu) or {"new": str(REPO / "fmus" / "JeffcottRotor.fmu")}
    print(f"{scenario.name}, inputs {args.inputs} ({len(np.load(args.inputs))} steps); uptime: "
          f"{os.popen('uptime').read().strip()}", flush=True)
    res: dict[str, list[dict]] = {k: [] for k in fmus}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.repeat):
            for name, path in fmus.items():
                out = Path(tmp) / f"{name}_{i}.json"
                cmd = [sys.executable, __file__, "--scenario", args.scenario, "--inputs", str(args.inputs),
                       "--from-step", str(args.from_step), "--child", str(Path(path).resolve()), str(out)]
                p = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **SINGLE})
                if p.returncode != 0:
                    raise SystemExit(f"{name}: {' '.join(cmd)} failed:\n{p.stderr[-3000:]}")
                r = json.loads(out.read_text())
                res[name].append(r)
                print(f"  run {i} {name}: set {r['set_wall']:.1f} / step {r['step_wall']:.1f} / get "
                      f"{r['get_wall']:.1f} us wall, step {r['step_cpu']:.1f} us CPU", flush=True)
    first = next(iter(res))
    ref = np.array(res[first][0]["final"])
    print(f"\nmedians of {args.repeat} interleaved runs (per-step medians from step {args.from_step}); "
          f"load {os.getloadavg()[0]:.1f}")
    print("| FMU | fmi2SetReal | fmi2DoStep | fmi2GetReal | rotor stage wall | CPU | vs first | final state vs first (max rel) |")
    print("|---|---|---|---|---|---|---|---|")
    base = None
    for name, rs in res.items():
        m = {k: statistics.median(r[k] for r in rs) for k in rs[0] if k.endswith(("_wall", "_cpu"))}
        stage = m["set_wall"] + m["step_wall"] + m["get_wall"]
        cpu = m["set_cpu"] + m["step_cpu"] + m["get_cpu"]
        base = base or stage
        dev = float(np.max(np.abs(np.array(rs[0]["final"]) - ref) / np.maximum(np.abs(ref), 1e-300)))
        print(f"| {name} | {m['set_wall']:.1f} us | {m['step_wall']:.1f} us | {m['get_wall']:.1f} us | "
              f"{stage:.1f} us | {cpu:.1f} us | {stage / base:.2f}x | {dev:.2g} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
