"""Old vs new bearing cost per macro step, interleaved in ONE process (load-robust A/B).

    git worktree add /tmp/perf_old <old commit>
    nice -n 5 .venv/bin/python benchmarks/bench_bearing_ab.py --old /tmp/perf_old [--case bath|air|whirl] [--steps 600]

Imports the old checkout's ``bearing_fmu`` as ``bearing_fmu_old`` (a symlink in a temporary
folder) next to this checkout's, builds the Jeffcott run-up bearing (40 x 40, mass-conserving;
``bath``: oil bath, no groove, cav_width 0.9 p0, orbit 0.25 c at 300 Hz; ``air``: free to air,
15 deg groove, same orbit; ``whirl``: free to air, eps 0.55 whirl at 0.45 x 500 Hz) in both,
and advances them over the same 0.1 ms macro steps, alternating which goes first, timing
``step`` (film) and ``linearization`` (interface-Jacobian coefficients, what the FMU does with
``linearize: 1``) in CPU time. ``bath2``: the ``bath`` orbit with the shipped oil-bath film
(second-order theta transport, ``theta_transport: 1``). Prints the medians, their ratio, the operation counts, and
how far apart the two films end (``--same`` asserts bit identity, for changes that must
not change the numbers). Both codes share the machine's state at every step, so the ratio
is meaningful even on a loaded machine.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

C = 4.9e-3 * 2.8e-3
BASE = dict(R=4.9e-3, B=7.84e-3, psi=2.8e-3, eta0=0.012, p0=1e5, p_feed=1e5, n_phi=40, n_z=40,
            cavitation=1)
CASES = {
    "bath": dict(axial_bc=0, groove_width=0.0, cav_width=9e4),
    "bath2": dict(axial_bc=0, groove_width=0.0, cav_width=9e4, theta_transport=1),
    "air": dict(axial_bc=1, groove_width=math.radians(15), groove_angle=math.pi / 2),
    "whirl": dict(axial_bc=1, groove_width=math.radians(15), groove_angle=math.pi / 2),
}


def kinematics(case, n):
    t = (n + 1) * 1e-4
    if case == "whirl":
        w = 2 * math.pi * 500
        r, wh, x0, y0 = 0.55 * C, 0.45 * w, 0.0, 0.0
    else:
        w = 2 * math.pi * 300
        r, wh, x0, y0 = 0.25 * C, 0.45 * w, 0.1 * C, -0.2 * C
    return (r * math.cos(wh * t) + x0, r * math.sin(wh * t) + y0,
            -wh * r * math.sin(wh * t), wh * r * math.cos(wh * t), w)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--old", required=True, help="root of the old checkout (git worktree)")
    ap.add_argument("--case", default="bath", choices=sorted(CASES))
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--warmup", type=int, default=30)
    ap.add_argument("--same", action="store_true", help="fail unless both films end bit for bit equal")
    a = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="bench_ab_"))
    (tmp / "bearing_fmu_old").symlink_to(Path(a.old).resolve() / "bearing_fmu")
    sys.path.insert(0, str(tmp))
    import bearing_fmu.linearize as LN
    import bearing_fmu.model as MN
    import bearing_fmu_old.linearize as LO
    import bearing_fmu_old.model as MO

    kw = dict(BASE, **CASES[a.case])
    x, y, vx, vy, w = kinematics(a.case, -1)
    beds = {}
    for name, M, L in (("old", MO, LO), ("new", MN, LN)):
        cls = getattr(M, "BearingModel", None) or M.JournalBearing   # renamed in 892d6f5
        b = cls(M.BearingParams(**kw))
        b.initialize(x, y, vx, vy, w, init="stationary")
        beds[name] = (b, L, [], [])
    for n in range(a.steps):
        kin = kinematics(a.case, n)
        for name in (("old", "new") if n % 2 else ("new", "old")):
            b, L, ts, tl = beds[name]
            t0 = time.process_time()
            b.step(1e-4, *kin)
            t1 = time.process_time()
            L.linearization(b)
            t2 = time.process_time()
            if n >= a.warmup:
                ts.append(t1 - t0)
                tl.append(t2 - t1)
    same = np.array_equal(beds["old"][0].film.u, beds["new"][0].film.u)
    print(f"case {a.case}, {a.steps} macro steps of 0.1 ms, load {Path('/proc/loadavg').read_text().split()[:3]}")
    tot = {}
    for name, (b, L, ts, tl) in beds.items():
        tot[name] = np.median(np.add(ts, tl))
        n = a.steps
        print(f"{name}: film step median {np.median(ts) * 1e3:.3f} ms, coefficients median "
              f"{np.median(tl) * 1e3:.3f} ms, step + coefficients median {tot[name] * 1e3:.3f} ms CPU "
              f"per bearing and macro step; per macro step: internal steps "
              f"{b.stats['steps'] / n:.3f}, Newton {b.stats['newton'] / n:.3f}, LU {b.stats['factor'] / n:.3f}")
    Fo = np.array([beds["old"][0].outputs[k] for k in ("Fx", "Fy")])
    Fn = np.array([beds["new"][0].outputs[k] for k in ("Fx", "Fy")])
    print(f"ratio new/old (median step + coefficients): {tot['new'] / tot['old']:.3f}; "
          f"final force old {Fo}, new {Fn}, |dF|/|F| {np.linalg.norm(Fn - Fo) / np.linalg.norm(Fo):.2e}; "
          f"film states identical: {same}")
    return 0 if (same or not a.same) else 1


if __name__ == "__main__":
    raise SystemExit(main())
