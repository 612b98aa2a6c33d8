"""Session: the 40 x 40 shift spread of free_rupture_2d.py with the rupture correction, with
(``--front``) or without the front treatment; n_phi, n_z from argv."""
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import free_rupture_2d as fr  # noqa: E402
import grid_convergence as gc  # noqa: E402

argv = fr.front_args(sys.argv[1:], "--front", "--no-ramp")
n_phi, nz = (int(a) for a in (argv or ["40", "40"])[:2])
q = gc.hs_equilibrium(40)
omega = 2 * math.pi * gc.F_HZ
t = time.time()
v = []
for f in (0.1, 0.3, 0.5, 0.7, 0.9):
    v.append(fr.shifted(n_phi, nz, q, omega, True, f))
    print(f"  shift {f}: Fx {v[-1][0]:.5f} Fy {v[-1][1]:.5f} ({time.time() - t:.0f} s)", flush=True)
fx, fy = [a[0] for a in v], [a[1] for a in v]
print(f"| {n_phi} x {nz} | front {fr.FRONT} | " + " / ".join(f"{a:.5f}" for a in fx)
      + f" | {100 * (max(fx) - min(fx)) / abs(np.mean(fx)):.3f} / "
      f"{100 * (max(fy) - min(fy)) / abs(np.mean(fy)):.3f} % | {time.time() - t:.0f} s |",
      flush=True)
