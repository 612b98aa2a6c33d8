"""Session (2026-12-07 fourth session): does the 1-D reformation front's error for a given q
depend on where the grid cuts the front? reformation_front_1d.py's problem (1 kPa, upwind
theta) with the gap's maximum moved by frac * h (the groove stays on faces, so the front moves
against the cells; each shift is its own problem); per shift the discrete load against the
exact film with the DISCRETE q (the `split` table's last column), on n = 40 and 80."""
import math
import sys
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import reformation_front_1d as rf  # noqa: E402

base = rf.Problem()
print("| n | shift [cells] | front cell [deg] | Wx discrete / exact with discrete q - 1 | Wy ... | q [-] |")
print("|---|---|---|---|---|---|")
for n in (40, 80):
    h = (2 * math.pi - base.groove_width) / n
    for frac in (0.0, 0.2, 0.4, 0.6, 0.8):
        prob = replace(base, phi_hmax=base.phi_hmax + frac * h)
        sols = rf.solve_sequence(prob, [20, 40] if n == 40 else [20, 40, 80])
        f, u = sols[n]
        q = f.q(u)
        Wq = rf.semi_analytic_load(prob, rf.shoot(prob, q, dense=True).sol)
        W = f.load(u)
        _, _, th, _ = rf.evaluate(u, prob.law)
        k = next(i for i in range(n - 1, 0, -1) if th[i - 1] < 0.999 <= th[i]) - 1
        print(f"| {n} | {frac} | {math.degrees(f.phi[k]):.2f} (theta {th[k]:.3f}) | "
              f"{W[0] / Wq[0] - 1:+.3e} | {W[1] / Wq[1] - 1:+.3e} | {q:.8g} |", flush=True)
