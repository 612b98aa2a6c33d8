"""Session probe (issue 16 item 2, 2026-12-07 fourth session): the reformation front of the
shifted 40 x 40 films of free_rupture_2d.py ``shift`` per row, against a fine n_phi x 40 film.

Per row j (the film's symmetric half, 0 = edge): the front cell F (the first cell at >= 150 deg
whose east neighbour E has theta >= 0.999 and which itself has theta < 0.999), its fill
fraction ``f = (theta_F - theta_W) / (1 - theta_W)`` (W the cell before F), the front's place
implied by the F|E face (``phi_E - f h``: the upwind scheme's face flux gives the same
gradient as a full film from that place), and the full film's pressure at E and at the next
cells against the fine film's row profile interpolated there."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import free_rupture_2d as fr  # noqa: E402
import grid_convergence as gc  # noqa: E402


def fronts(b, p, th, alpha):
    g = b.grid
    n = g.n_phi
    p = p.reshape(g.n_z, n)
    th = th.reshape(g.n_z, n)
    phys = np.degrees((g.phi - alpha) % (2 * math.pi))
    out = []
    for j in range(g.n_z):
        order = np.argsort(phys)
        for k in range(len(order) - 1):
            i = order[k]
            e = order[k + 1]
            w = order[k - 1]
            if phys[i] >= 150 and th[j, i] < 0.999 and th[j, e] >= 0.999:
                f = (th[j, i] - th[j, w]) / (1 - th[j, w])
                h = 360.0 / n
                out.append((j, phys[i], f, phys[e] - f * h, th[j, w], th[j, i]))
                break
    return out


def main():
    q = gc.hs_equilibrium(40)
    omega = 2 * math.pi * gc.F_HZ
    n_ref = int(sys.argv[1]) if len(sys.argv) > 1 else 384
    ref = fr.solve(n_ref, 40, q, omega, True, fields=True)
    b_r, p_r, th_r, _ = ref
    fr_ref = fronts(b_r, p_r, th_r, 0.0)
    g_r = b_r.grid
    P_r = p_r.reshape(g_r.n_z, g_r.n_phi) - b_r.p0
    x_r = np.degrees(g_r.phi)
    print("reference", n_ref, "x 40: front (implied) per row:",
          " ".join(f"{r[3]:.2f}" for r in fr_ref))
    np.save("/tmp/fp/ref_front.npy", np.array(fr_ref))
    for frac in (0.1, 0.3, 0.5, 0.7, 0.9):
        alpha, xy = fr._shift(40, 40, q, frac)
        b, p, th, kin = fr.solve(40, 40, xy, omega, True, alpha=alpha, fields=True)
        F = fr._force(b, p, th, kin)
        ca, sa = math.cos(alpha), math.sin(alpha)
        fx = ca * F[0] + sa * F[1]
        g = b.grid
        P = p.reshape(g.n_z, g.n_phi) - b.p0
        phys = np.degrees((g.phi - alpha) % (2 * math.pi))
        fr40 = fronts(b, p, th, alpha)
        print(f"\nshift {frac}: Fx {fx:.5f}")
        print("| row | front cell [deg] | f | implied front [deg] | ref front [deg] | diff [deg] | "
              "p_E err [Pa] | p_E+1 err | p_E+2 err | p_E+4 err |")
        for (j, pf, f, xf, thw, thf), rr in zip(fr40, fr_ref):
            i = int(np.argmin(np.abs(phys - pf)))
            errs = []
            for k in (1, 2, 3, 5):
                ii = (i + k) % g.n_phi
                pref = np.interp(phys[ii], x_r, P_r[j], period=360)
                errs.append(P[j, ii] - pref)
            if j % 3 == 0 or j == g.n_z - 1:
                print(f"| {j} | {pf:.1f} | {f:.3f} | {xf:.2f} | {rr[3]:.2f} | {xf - rr[3]:+.2f} | "
                      + " | ".join(f"{e:+.0f}" for e in errs) + " |")
        d = np.array([a[3] - r[3] for a, r in zip(fr40, fr_ref)])
        print(f"front place error over rows: mean {d.mean():+.3f} deg, min {d.min():+.2f}, max {d.max():+.2f}",
              flush=True)


if __name__ == "__main__":
    main()
