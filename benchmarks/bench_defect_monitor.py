"""Cost of the coupling-defect monitor (orchestrator/coupling/defect.py) inside a real run.

Runs a scenario with the master in this process, with ``DefectMonitor.before`` and ``after``
wrapped by ``time.perf_counter``, and prints the steps monitored, the run's wall time and the
monitor's share of it (the wrappers add ~0.3 us a step). The peer is the run itself: the
monitor's time is measured inside the same run, so the shared machine's load cancels.

Run:  nice -n 10 .venv/bin/python benchmarks/bench_defect_monitor.py scenarios/quickstart.yaml
      nice -n 10 .venv/bin/python benchmarks/bench_defect_monitor.py scenarios/jeffcott_runup_free_to_air.yaml \
          stop_time=0.45
(extra arguments are ``--set`` overrides).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from orchestrator.coupling import defect                      # noqa: E402
from orchestrator.coupling.execution import MasterAlgorithm   # noqa: E402
from orchestrator.scenario import load_scenario               # noqa: E402


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__)
        return 2
    spent = {"s": 0.0, "n": 0}
    before, after = defect.DefectMonitor.before, defect.DefectMonitor.after

    def timed_before(self, *a, **k):
        t = time.perf_counter()
        before(self, *a, **k)
        spent["s"] += time.perf_counter() - t

    def timed_after(self, *a, **k):
        t = time.perf_counter()
        after(self, *a, **k)
        spent["s"] += time.perf_counter() - t
        spent["n"] += 1

    defect.DefectMonitor.before, defect.DefectMonitor.after = timed_before, timed_after
    try:
        master = MasterAlgorithm(load_scenario(argv[0], argv[1:]))
        wall = time.perf_counter()
        res = master.run()
        wall = time.perf_counter() - wall
    finally:
        defect.DefectMonitor.before, defect.DefectMonitor.after = before, after
    n = spent["n"]
    if not n:
        print(f"{argv[0]}: no step monitored (no interface-Jacobian forces, or not a constant step)")
        return 1
    print(f"{argv[0]} {' '.join(argv[1:])}: {res.status.short}, {n} steps monitored, run {wall:.2f} s wall, "
          f"monitor {spent['s']:.4f} s = {spent['s'] / n * 1e6:.1f} us/step = {100 * spent['s'] / wall:.2f} % "
          f"of the run; load {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
