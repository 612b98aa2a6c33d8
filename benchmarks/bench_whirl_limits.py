"""What limits the film's cost in the oil-bath whirl (issue 16): three measurements.

``errh``: the film's local error estimate (Milne, :mod:`bearing_fmu.solver`) of one internal
step of size h = 12.5, 25, 50, 100 us taken from the same state at the start of five
successive macro steps (recorded kinematics of ``bearing1``). For BDF2 on a smooth solution
the estimate grows like h^3 (x8 per doubling); the step-size rule assumes that.

``kink``: the same estimates with the internal step capped at 25 us (``h_max``), for the four
internal steps of two macro steps. If the jump of the held kinematics at each macro-step
boundary (H, dH/dt are constant over a macro step) caused the large estimates, the first
steps after a boundary would carry them.

``rows``: at every LU of a Newton solve, how many rows of the stencil Jacobian moved by more
than 10 / 30 / 100 % (sum of |change| over the row's factored diagonal) since the last LU;
"first" = the first LU of an internal step (against the previous step's last LU), "later" =
a refactorisation within the solve (:func:`bearing_fmu.solver.refactor_partial`). A
low-rank update of the LU (Woodbury) would pay for k rows with k band solves.

The Python loop of the film (``fused = False``: the same scheme and results as the fused
kernel) is used so that the estimates and LUs can be observed.

Run:
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_whirl_limits.py errh --at 0.7,0.75 [--kin DIR]
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_whirl_limits.py kink --at 0.7,0.72,0.75
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_whirl_limits.py rows --at 0.35,0.7,0.75,1.4,1.5
(``--kin``: a folder recorded by :mod:`bench_newton_reuse` for the oil bath; made if missing,
one run-up to the last time asked + 0.02 s.)
"""

from __future__ import annotations

import argparse
import inspect
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import bench_newton_reuse as nr  # noqa: E402
import bearing_fmu.solver as S  # noqa: E402
from bearing_fmu.model import BearingModel  # noqa: E402

SCENARIO = "oil_bath"
KIN = ("rotor.x_1", "rotor.y_1", "rotor.vx_1", "rotor.vy_1", "rotor.omega")


def _logging_loop(log: list):
    """TransientFilm._advance_loop with every error estimate appended to ``log`` as
    (film time, h, err): the method's own source with one line added, so it cannot drift."""
    src = textwrap.dedent(inspect.getsource(S.TransientFilm._advance_loop))
    anchor = "            fac = 0.9 * err"
    if anchor not in src:
        raise SystemExit("bench_whirl_limits: TransientFilm._advance_loop changed; update the anchor")
    src = src.replace(anchor, "            LOG.append((self.t, h, err))\n" + anchor, 1)
    ns = dict(vars(S))
    ns["LOG"] = log
    exec(src, ns)             # noqa: S102 - the module's own source
    return ns["_advance_loop"]


def _film_at(data, t_at, **params):
    """A bearing film warmed up on 30 recorded macro steps, ready to take the one at ``t_at``."""
    t = data["time"]
    i0 = int(np.searchsorted(t, t_at))

    def kin(i):
        return tuple(float(data[k][i]) for k in KIN)
    b = BearingModel(nr.bearing_params(SCENARIO, **params))
    b.film.fused = False
    b.initialize(*kin(i0 - 30), init="stationary")
    for i in range(i0 - 30, i0):
        b.step(1e-4, *kin(i + 1))
    return b, i0, kin


def errh(data, times):
    log: list = []
    S.TransientFilm._advance_loop = _logging_loop(log)
    hs = (12.5e-6, 25e-6, 50e-6, 100e-6)
    print("| t [s] | macro step | " + " | ".join(f"err at {h * 1e6:g} us" for h in hs) + " | growth per doubling |")
    print("|---|---|" + "---|" * (len(hs) + 1))
    for t_at in times:
        b, i0, kin = _film_at(data, t_at)
        for k in range(5):
            saved = b.get_state()
            errs = []
            for h in hs:
                b.set_state(saved)
                b.film.h_next = h
                log.clear()
                b.film.advance(h, b._kinematics(*kin(i0 + k + 1)))
                errs.append(log[0][2])
            b.set_state(saved)
            b.step(1e-4, *kin(i0 + k + 1))
            growth = ", ".join(f"{errs[j + 1] / errs[j]:.1f}" for j in range(len(errs) - 1))
            print(f"| {t_at:g} | {k} | " + " | ".join(f"{e:.3f}" for e in errs) + f" | {growth} |")


def kink(data, times):
    log: list = []
    S.TransientFilm._advance_loop = _logging_loop(log)
    print("| t [s] | err of the internal steps (h_max 25 us), macro step 1 / macro step 2 |")
    print("|---|---|")
    for t_at in times:
        b, i0, kin = _film_at(data, t_at, h_max=25e-6)
        out = []
        for k in range(2):
            log.clear()
            b.step(1e-4, *kin(i0 + k + 1))
            out.append(", ".join(f"{e:.3f}" for _, _, e in log))
        print(f"| {t_at:g} | {' / '.join(out)} |")


def rows(data, times):
    rec: list = []

    def moved(film):
        d = np.abs(film.jst - film.jst_f).sum(axis=1) / np.abs(film.jst_f[:, 0])
        return [int((d > b).sum()) for b in (0.1, 0.3, 1.0)]
    factor, partial = S.TransientFilm._factor, S.TransientFilm._refactor_partial

    def _factor(self, u, th_dot0, kin, jst_ready=False):
        if self._factored:
            rec.append(("first", *moved(self)))
        return factor(self, u, th_dot0, kin, jst_ready)

    def _refactor_partial(self, u, th_dot0, kin):
        rec.append(("later", *moved(self)))
        return partial(self, u, th_dot0, kin)
    S.TransientFilm._factor, S.TransientFilm._refactor_partial = _factor, _refactor_partial
    print("| t [s] (100 macro steps) | LU | count | rows moved > 10 / 30 / 100 %: median | p90 |")
    print("|---|---|---|---|---|")
    for t_at in times:
        b, i0, kin = _film_at(data, t_at)
        rec.clear()
        for i in range(i0, i0 + 100):
            b.step(1e-4, *kin(i + 1))
        for which in ("first", "later"):
            a = np.array([r[1:] for r in rec if r[0] == which])
            if len(a):
                med = " / ".join(f"{v:g}" for v in np.median(a, axis=0))
                p90 = " / ".join(f"{v:.0f}" for v in np.percentile(a, 90, axis=0))
                print(f"| {t_at:g} | {which} | {len(a)} | {med} | {p90} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["errh", "kink", "rows"])
    ap.add_argument("--at", default="0.7,0.75", help="run-up times [s], comma-separated")
    ap.add_argument("--kin", default=None, help="folder of a recorded oil-bath run (made if missing)")
    a = ap.parse_args(argv)
    times = [float(x) for x in a.at.split(",")]
    kin_dir = Path(a.kin) if a.kin else Path(tempfile.mkdtemp(prefix="kin_"))
    csv = nr.record(SCENARIO, max(times) + 0.02, kin_dir)
    from orchestrator.results.run_directory import RunDirectory
    data = RunDirectory(csv.parent).columns()
    print(f"oil bath, bearing1, kinematics {csv}")
    {"errh": errh, "kink": kink, "rows": rows}[a.what](data, times)


if __name__ == "__main__":
    main()
