"""CPU time of the film's kernels, this checkout against an older one (issue 16, speed).

Builds the shipped oil-bath film (40 x 40, mass-conserving, second-order theta transport, no
groove) with this checkout's ``bearing_fmu`` and an older checkout's (``bearing_fmu_old``, a
symlink, as ``bench_bearing_ab.py`` does), advances both 50 macro steps on an orbit of 0.45 c at
300 Hz, and then times, in turn, each kernel a film step is made of on the same state: the
residual with its stencil Jacobian, a full factorisation (zero, scatter, band LU), the band
solve of a Newton step, the Newton update in each cell's own variable, the cavitation law, and
the interface coefficients (``linearization``). Prints the best of 5 repetitions per kernel
and the ratio new / old, and checks that the two give the same values bit for bit.

Run:
    git worktree add --detach /tmp/old <commit>
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_film_kernels.py --old /tmp/old
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
C = 4.9e-3 * 2.8e-3
PRM = dict(R=4.9e-3, B=7.84e-3, psi=2.8e-3, eta0=0.012, p0=1e5, p_feed=1e5, n_phi=40, n_z=40,
           cavitation=1, axial_bc=0, groove_width=0.0, cav_width=9e4, theta_transport=1)


def orbit(n):
    t, w = (n + 1) * 1e-4, 2 * math.pi * 300
    r, wh, x0, y0 = 0.45 * C, 0.45 * w, 0.1 * C, -0.2 * C
    return (r * math.cos(wh * t) + x0, r * math.sin(wh * t) + y0, -wh * r * math.sin(wh * t),
            wh * r * math.cos(wh * t), w)


def kernels(pkg):
    """{name: (call, result)} of the film kernels of package ``pkg`` on a film after 50 steps."""
    import importlib
    M = importlib.import_module(f"{pkg}.model")
    S = importlib.import_module(f"{pkg}.solver")
    F = importlib.import_module(f"{pkg}.fused")
    L = importlib.import_module(f"{pkg}.linearize")
    cav = importlib.import_module(f"{pkg}.cavitation")
    b = M.BearingModel(M.BearingParams(**PRM))
    b.initialize(*orbit(-1), init="stationary")
    for n in range(50):
        b.step(1e-4, *orbit(n))
    f = b.film
    (muscl, groove, film, u_feed, a_phi, a_z, dphi, dz, bath, p0, p_cav, K, delta, pa, pb, s_pen,
     sym, wrel, frel, n_phi, order, pos, bw, ab, jst, r, p, dp, th, dth, *_rest) = f._fused_args()
    jst_f = np.empty_like(jst)
    H, He, Hdot, om = b._kin
    n = f.n
    u, th_dot1 = f.u.copy(), np.zeros(n)
    e, l1, valid = np.empty(n), np.empty(n), np.zeros(n, np.uint8)
    work, dx, un = np.empty(n), np.empty(n), np.empty(n)
    wp, wth = np.empty(n_phi), np.empty(n_phi)
    S.dominant_weights(H, He, Hdot, 1e4, om, a_phi, a_z, dphi, dz, wrel, frel, wp, wth)
    s1, s2, s3, s4 = (np.empty(n) for _ in range(4))

    def residual():
        F._residual(muscl, u, 1e4, th_dot1, H, He, Hdot, groove, u_feed, om, a_phi, a_z, dphi, dz,
                    bath, p0, p_cav, K, delta, pa, pb, s_pen, r, jst, p, dp, th, dth, sym, wrel,
                    frel, e, l1, valid)
        return r.copy(), jst.copy()

    def factor():
        S.factor_full(jst, jst_f, n_phi, pos, bw, ab, S.PIVOT_THRESHOLD)
        return ab[bw:].copy()

    def solve():
        S.band_newton_step_nopivot(ab, bw, r, order, pos, work, dx)
        return dx.copy()

    def update():
        S.dominant_update(u, 1e-3 * dx, wp, wth, n_phi, p_cav, K, delta, un, e, l1, e, l1, valid)
        return un.copy()

    def law():
        cav.law_eval(u, p_cav, K, delta, s1, s2, s3, s4)
        return s1.copy(), s3.copy()

    def lin():
        return L.linearization(b)
    residual()
    factor()
    return {"residual + Jacobian": residual, "full factorisation": factor, "Newton step (solve)": solve,
            "own-variable update": update, "cavitation law": law, "interface coefficients": lin}


def best(fn, reps):
    fn()
    ts = []
    for _ in range(5):
        t0 = time.thread_time()
        for _ in range(reps):
            fn()
        ts.append((time.thread_time() - t0) / reps)
    return min(ts) * 1e6


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", required=True, help="root of the old checkout (git worktree)")
    ap.add_argument("--reps", type=int, default=200)
    a = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="bench_kernels_"))
    (tmp / "bearing_fmu_old").symlink_to(Path(a.old).resolve() / "bearing_fmu")
    sys.path.insert(0, str(tmp))
    old, new = kernels("bearing_fmu_old"), kernels("bearing_fmu")
    print("| kernel | old [us] | new [us] | new / old | values |")
    print("|---|---|---|---|---|")
    for name in new:
        # each pair of calls on the same inputs (the solve and update read what factor/solve left)
        vo, vn = old[name](), new[name]()
        same = all(np.array_equal(x, y) for x, y in zip(np.atleast_1d(vo) if not isinstance(vo, tuple) else vo,
                                                        np.atleast_1d(vn) if not isinstance(vn, tuple) else vn))
        to, tn = best(old[name], a.reps), best(new[name], a.reps)
        print(f"| {name} | {to:.1f} | {tn:.1f} | {tn / to:.3f} | {'identical' if same else 'DIFFER'} |")


if __name__ == "__main__":
    main()
