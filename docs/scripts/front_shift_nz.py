"""Session probe (2026-12-07 fourth session): the shift spread of free_rupture_2d.py (with
the rupture correction) at n_phi = 40 and n_z = 20 / 40 / 80 / 160: does refining the rows
(more rows across the front's staircase) shrink the 40-cell alignment spread?"""
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import free_rupture_2d as fr  # noqa: E402
import grid_convergence as gc  # noqa: E402

q = gc.hs_equilibrium(40)
omega = 2 * math.pi * gc.F_HZ
n_phi = int(sys.argv[1]) if len(sys.argv) > 1 else 40
for nz in [int(a) for a in sys.argv[2:]] or [20, 80, 160]:
    t = time.time()
    v = [fr.shifted(n_phi, nz, q, omega, True, f) for f in (0.1, 0.3, 0.5, 0.7, 0.9)]
    fx, fy = [a[0] for a in v], [a[1] for a in v]
    print(f"| {n_phi} x {nz} | " + " / ".join(f"{a:.5f}" for a in fx)
          + f" | {100 * (max(fx) - min(fx)) / abs(np.mean(fx)):.3f} / "
          f"{100 * (max(fy) - min(fy)) / abs(np.mean(fy)):.3f} % | {time.time() - t:.0f} s |",
          flush=True)
