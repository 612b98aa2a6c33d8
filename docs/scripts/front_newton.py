"""Session (2026-12-07 fourth session): the Newton history of one 40 x 40 (argv[1]) film with a front
treatment switched on from the converged film without it (argv[2]: sw / ghost / cut; "noramp":
without the ramp): residual norm, line-search step, largest increment, dropped Jacobian entries."""
import math, sys
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy as np
import free_rupture_2d as fr, grid_convergence as gc
q = gc.hs_equilibrium(40); omega = 2*math.pi*gc.F_HZ
n = int(sys.argv[1]) if len(sys.argv) > 1 else 40
film = fr.Film(n, n, omega)
b = film.b
u, kin, its, info, qr = film.steady(q, True)
print("base its", its)
fr.FRONT = sys.argv[2] if len(sys.argv) > 2 else "ghost"
fr.RAMP = "noramp" not in sys.argv
qr = fr.row_flux(b, u, kin, 0.0, deg=150.0); film.box["q"] = qr.copy()
f = b.film; zero = np.zeros(f.n)
dr, jac = fr.front_correction(b, u, kin, qr, 0.0, True)
print("faces touched", len(jac)//4, "max |dr|", np.abs(dr).max(), "base res", np.abs(f.residual(u,0.0,zero,kin)).max())
for it in range(40):
    f._factor(u, 0.0, kin)
    r = f.residual(u, 0.0, zero, kin).copy()
    dx = f._solve(r)
    nr0 = np.linalg.norm(r)
    lam = 1.0
    while lam > 1e-3:
        un = u + lam*dx
        rn = np.linalg.norm(f.residual(un, 0.0, zero, kin))
        if rn < (1-1e-4*lam)*nr0: break
        lam *= 0.5
    print(it, f"{nr0:.3e} lam {lam} |dx| {np.abs(dx).max():.2e} dropped {film.box['dropped']}")
    u = un
info = []
for jp, jc, i, fp, fc, rho, d in info:
    G = omega * (1 - min(qr[jc] / (omega * kin[1][i]), 0.999)) / (b.a_phi * kin[0][i] ** 2)
    print(f"face P row {jp} C row {jc} col {i}: phiP/h {fp:.3f} phiC/h {fc:.3f} rho {rho:.3f} d {d:.3e} "
          f"G h {G*b.grid.dphi:.0f} Pa")
