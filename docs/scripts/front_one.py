"""Session (2026-12-07 fourth session): one film of free_rupture_2d.py with the rupture correction
and a front treatment. Usage: front_one.py N_PHIxN_Z {none,sw,ghost,cut,sw-lag} [shift|none]
[damp]; prints Fx, Fy, substitutions, Newton iterations per solve, Jacobian entries dropped
(outside the band); for sw / ghost the staircase faces (P row, C row, phi_P / h, phi_C / h, ramp
weight); for sw-lag the first and last frozen geometries (s per face) with the force."""
import math, sys, time
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parent))
import free_rupture_2d as fr, grid_convergence as gc
q = gc.hs_equilibrium(40); omega = 2*math.pi*gc.F_HZ
n, nz = (int(v) for v in sys.argv[1].split("x")); fr.FRONT = sys.argv[2] if sys.argv[2] != "none" else None
fr.DAMP = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
frac = float(sys.argv[3]) if len(sys.argv) > 3 and sys.argv[3] != "none" else None
alpha, xy = (0.0, q) if frac is None else fr._shift(n, nz, q, frac)
t = time.time()
film = fr.Film(n, nz, omega, alpha)
u, kin, its, info, qq = film.steady(xy, True)
F = fr._force(film.b, *film.b.law.p_theta(u), kin)
ca, sa = math.cos(alpha), math.sin(alpha)
print(f"geoms {film.geoms[:3]} ... {film.geoms[-4:]}")
print(f"{n}x{nz} front {fr.FRONT} shift {frac}: Fx {ca*F[0]+sa*F[1]:.5f} Fy {-sa*F[0]+ca*F[1]:.5f} subs {its} "
      f"newton {film.newton_its} dropped {film.box['dropped']} {time.time()-t:.0f} s")
if fr.FRONT in ("ghost", "sw"):
    last = getattr(fr.front_correction, "last", [])
    print("  staircase faces (P row, C row, phi_P/h, phi_C/h, rho):",
          "; ".join(f"{a},{b_},{fp:.3f},{fc:.3f},{rho:.4f}" for a, b_, i, fp, fc, rho, d in last))
