"""Session (2026-12-07 fourth session): square grids 20 ... 160 of free_rupture_2d.py with the
rupture correction and the front treatment ``--front {sw,ghost,cut}`` (``--no-ramp``); only
the corrected films (the exit-only columns do not depend on the front treatment)."""
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import free_rupture_2d as fr  # noqa: E402
import grid_convergence as gc  # noqa: E402

argv = fr.front_args(sys.argv[1:], "--front", "--no-ramp")
grids = [int(a) for a in argv] or [20, 40, 80, 160]
q = gc.hs_equilibrium(40)
omega = 2 * math.pi * gc.F_HZ
res = []
for n in grids:
    t = time.time()
    film = fr.Film(n, n, omega)
    u, kin, its, info, _ = film.steady(q, True)
    F = fr._force(film.b, *film.b.law.p_theta(u), kin)
    res.append(F)
    print(f"| {n} x {n} | {F[0]:.5f} | {F[1]:.5f} | {its} | {max(film.newton_its)} | "
          f"{time.time() - t:.0f} s |", flush=True)
for k, name in ((0, "Fx"), (1, "Fy")):
    print(f"{name} orders: {fr.orders([r[k] for r in res])}")
