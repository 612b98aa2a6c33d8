"""Helper of docs/bearing-validation.md ("Front tracking"): front_tracking_2d.py part B
(--slope upwind) on 640 x 640 (M = 320), warm from 320; about 10 minutes. Run from the
repository root with PYTHONPATH=.
"""
import math
import sys
import time

sys.path.insert(0, "docs/scripts")
import front_tracking_2d as ft  # noqa: E402
import grid_convergence as gc  # noqa: E402

ft.SLOPE[0] = "upwind"
q = gc.hs_equilibrium(40)
om = 2 * math.pi * gc.F_HZ
o = ft.quantities(320, q, om, coefficients=False)
t = time.time()
o2 = ft.quantities(640, q, om, o["U"], o["ff"])
v = list(o2["F"]) + list(o2["coef"])
print(f"640 x 640 (M = 320), slope upwind ({time.time() - t:.0f} s): "
      + ", ".join(f"{n} {x:.8g}" for n, x in zip(gc.NAMES, v)), flush=True)
