"""Setup cost against the number of FMU variables (issue 19: setup was quadratic).

Times ``orchestrator.coupling.plan.make_plan`` for one plain-Python subsystem with N Real
outputs (all recorded, ``output.signals`` unset) and ``load_scenario`` of a scenario that
sets 2000 parameters of a model-description-only FMU with N parameters. Median of 3.

    nice .venv/bin/python benchmarks/bench_setup_wide.py [N ...]      (default 10000 40000 200000)
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
import zipfile
from pathlib import Path

from orchestrator.coupling.plan import make_plan
from orchestrator.coupling.schemes import scheme_from_spec
from orchestrator.fmi.archive import Variable
from orchestrator.fmi.subsystem import SubsystemBase
from orchestrator.scenario import load_scenario
from orchestrator.scenario.model import CouplingSpec, FmuSpec, Scenario


class Wide(SubsystemBase):
    """N Real outputs, no physics."""

    def __init__(self, name: str, n: int):
        super().__init__(name)
        self.vars = {f"y{i}": Variable(f"y{i}", i, "Real", "output", "continuous") for i in range(n)}
        self.output_names = list(self.vars)

    def variable(self, name):
        return self.vars[name]

    def set_real(self, batch):
        pass

    def get_real(self, batch):
        return batch.values

    def do_step(self, t, h):
        pass


def time_plan(n: int) -> float:
    sc = Scenario(name="w", stop_time=1.0, fmus=(FmuSpec(name="w", path=Path("w.fmu")),),
                  coupling=CouplingSpec(macro_step=0.1))
    subs = {"w": Wide("w", n)}
    t = time.perf_counter()
    make_plan(sc, subs, scheme_from_spec("gauss-seidel", ("w",)))
    return time.perf_counter() - t


def time_load(n: int, folder: Path) -> float:
    vars_ = "".join(f'<ScalarVariable name="v{i}" valueReference="{i}" causality="parameter" variability="fixed">'
                    '<Real start="1"/></ScalarVariable>' for i in range(n))
    md = ('<?xml version="1.0" encoding="UTF-8"?><fmiModelDescription fmiVersion="2.0" modelName="M" guid="{1}">'
          f'<CoSimulation modelIdentifier="M"/><ModelVariables>{vars_}</ModelVariables></fmiModelDescription>')
    with zipfile.ZipFile(folder / f"m{n}.fmu", "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("modelDescription.xml", md)
    params = ", ".join(f"v{i}: 2.0" for i in range(0, n, max(1, n // 2000)))
    s = folder / f"s{n}.yaml"
    s.write_text(f"name: wide\nstop_time: 0.01\nfmus:\n  a: {{path: m{n}.fmu, parameters: {{{params}}}}}\n"
                 "coupling: {macro_step: 1.0e-3}\n")
    t = time.perf_counter()
    load_scenario(s, build_fmus=False)
    return time.perf_counter() - t


def main(sizes: list[int]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            plan = statistics.median(time_plan(n) for _ in range(3))
            load = statistics.median(time_load(n, Path(tmp)) for _ in range(3))
            print(f"N = {n:7d}: make_plan {plan:7.2f} s, load_scenario (2000 parameters set) {load:7.2f} s")


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [10000, 40000, 200000])
