"""Spatial convergence of the bearing discretisation for the Jeffcott run-up bearing
(issue 5, numerical credibility; docs/runups.md section 3, docs/bearing-validation.md).

Bearing of scenarios/jeffcott_runup_*.yaml: R = 4.9 mm, B = 1.6 R, psi = 2.8e-3,
eta0 = 12 mPa s, p0 = 1 bar. Fixed kinematics: the 40 x 40 half-Sommerfeld static
equilibrium of a journal carrying (m_disc / 2 + m_journal) g = 29.43 N at 250 Hz (near the
linear threshold), the same (x, y) on every grid.

Cases
  hs     half-Sommerfeld, oil bath, no groove (jeffcott_runup_half_sommerfeld.yaml):
         force, 8 coefficients (bearing_fmu.linearize.hs_linearization, what the FMU
         outputs) and the linear Jeffcott threshold (docs/paper_cases_radius.py) per grid.
  bath   mass-conserving steady film, oil bath, cav_width 0.9 p0, no groove
         (jeffcott_runup_oil_bath.yaml): force and 8 quasi-steady coefficients by central
         differences of the steady film (solve_stationary, warm-started Newton).
  air    mass-conserving steady film, free to air, 15 deg groove at the top
         (jeffcott_runup_free_to_air.yaml): the same.

Observed order from three grids h, h/2, h/4: p = log2((f_h - f_h2) / (f_h2 - f_h4)),
Richardson value f_h4 + (f_h4 - f_h2) / (2^p - 1) (p from the three finest grids).

Run: ``nice -n 10 .venv/bin/python docs/scripts/grid_convergence.py [hs bath air] [--grids 20,40,80,160]``
``--theta-transport 1``: the mass-conserving cases with the limited second-order Couette
transport of theta (BearingParams.theta_transport).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))          # docs/ (paper_cases_radius)
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))          # repo root

from bearing_fmu.linearize import hs_linearization  # noqa: E402
from bearing_fmu.model import BearingParams, BearingModel  # noqa: E402

R = 4.9e-3
BASE = dict(R=R, B=1.6 * R, psi=2.8e-3, eta0=0.012, p0=1.0e5, p_feed=1.0e5)
CASES = {
    "hs": dict(cavitation=0, axial_bc=0, groove_width=0.0),
    "bath": dict(cavitation=1, axial_bc=0, groove_width=0.0, cav_width=9.0e4),
    "air": dict(cavitation=1, axial_bc=1, groove_width=math.radians(15.0),
                groove_angle=math.pi / 2),
}
F_HZ = 250.0
LOAD = (0.5 * 5.0 + 0.5) * 9.81
EXTRA: dict = {}            # BearingParams overrides for the mass-conserving cases (--theta-transport)
NAMES = ["Fx", "Fy", "kxx", "kxy", "kyx", "kyy", "cxx", "cxy", "cyx", "cyy"]


def params(case, n, n_z=None, **kw):
    """BearingParams of ``case`` on n x n cells (``n_z``: n x n_z)."""
    extra = {"newton_atol": 1e-10, "newton_rtol": 1e-11,
             **(EXTRA if CASES[case]["cavitation"] == 1 else {}), **kw}
    return BearingParams(**BASE, **CASES[case], n_phi=n, n_z=n if n_z is None else n_z, **extra)


def hs_equilibrium(n=40):
    """(x, y) of the HS journal carrying LOAD at F_HZ (docs/paper_cases_radius.py)."""
    import paper_cases_radius as pcr
    b = pcr.hs_bearing(R, n)
    return pcr.equilibrium(b, LOAD, 2 * math.pi * F_HZ)


def central_coefficients(force_at, q, omega, c, rel=1e-3):
    """-dF/d(x, y, vx, vy) (2 x 4) of a steady film at the journal position q by central
    differences: ``force_at(z)`` solves the film at the journal state z = [x, y, vx, vy] and
    returns (Fx, Fy); steps rel * c for the positions and rel * c * omega for the velocities."""
    steps = [rel * c, rel * c, rel * c * omega, rel * c * omega]
    D = np.empty((2, 4))
    for j in range(4):
        fs = []
        for sgn in (1, -1):
            z = [q[0], q[1], 0.0, 0.0]
            z[j] += sgn * steps[j]
            fs.append(np.asarray(force_at(z)))
        D[:, j] = -(fs[0] - fs[1]) / (2 * steps[j])
    return D


def mc_quantities(case, n, q, omega, rel=1e-3, n_z=None, coefficients=True, prepare=None, **kw):
    """Force and quasi-steady coefficients of the steady mass-conserving film (n x n cells,
    ``n_z``: n x n_z; ``kw``: further BearingParams); only the force if not
    ``coefficients``.

    ``prepare``: a study script's change of the film (exit_layer_2d.py, its exit-layer
    residual correction), called once as ``prepare(b)`` with the BearingModel built, before
    anything is solved; it returns a callable ``(kin, z)`` that is called before each steady
    solve (the base state, then each perturbed one) with the kinematics about to be solved
    (``b._kinematics``) and the journal state z = [x, y, vx, vy]."""
    b = BearingModel(params(case, n, n_z, **kw))
    before_solve = prepare(b) if prepare is not None else None
    if before_solve is not None:
        before_solve(b._kinematics(q[0], q[1], 0.0, 0.0, omega), [q[0], q[1], 0.0, 0.0])
    b.initialize(q[0], q[1], 0.0, 0.0, omega, init="stationary")
    u0 = b.film.u.copy()
    F0 = np.array([b.outputs["Fx"], b.outputs["Fy"]])
    if not coefficients:
        return F0

    def force_at(z):
        kin = b._kinematics(z[0], z[1], z[2], z[3], omega)
        if before_solve is not None:
            before_solve(kin, z)
        u, _ = b._steady_newton(kin, u0, np.zeros_like(u0), 40)   # warm start
        if u is None:
            u = b._steady(kin, u0)
        p, th = b.law.p_theta(u)
        from bearing_fmu.linearize import _force
        return _force(b, p, th, kin)

    D = central_coefficients(force_at, q, omega, b.c, rel)
    return np.concatenate([F0, D[:, :2].ravel(), D[:, 2:].ravel()])


def hs_quantities(n, q, omega):
    b = BearingModel(params("hs", n))
    b.initialize(q[0], q[1], 0.0, 0.0, omega)
    K, C = hs_linearization(b, q[0], q[1], 0.0, 0.0, omega)
    F0 = np.array([b.outputs["Fx"], b.outputs["Fy"]])
    return np.concatenate([F0, K.ravel(), C.ravel()])


def hs_threshold(n):
    import paper_cases_radius as pcr
    f, eps, fw = pcr.threshold_hz(R, n, f_lo=200.0, f_hi=320.0, df=20.0)
    return f


def orders(vals):
    """(order, richardson, err of each grid vs richardson) from the last three values."""
    f1, f2, f3 = vals[-3:]
    d1, d2 = f1 - f2, f2 - f3
    if d2 == 0 or d1 / d2 <= 0:
        return float("nan"), float("nan"), [float("nan")] * len(vals)
    p = math.log2(d1 / d2)
    rich = f3 + (f3 - f2) / (2 ** p - 1)
    return p, rich, [(v - rich) / abs(rich) for v in vals]


def table(title, grids, rows, names):
    print(f"\n### {title}\n")
    print("| quantity | " + " | ".join(f"{g} x {g}" for g in grids)
          + " | order (last 3) | Richardson | 40 x 40 error |")
    print("|---|" + "---|" * (len(grids) + 3))
    out = {}
    for k, name in enumerate(names):
        vals = [r[k] for r in rows]
        p, rich, errs = orders(vals)
        i40 = grids.index(40) if 40 in grids else None
        e40 = errs[i40] if i40 is not None else float("nan")
        print(f"| {name} | " + " | ".join(f"{v:.6g}" for v in vals)
              + f" | {p:.2f} | {rich:.6g} | {100 * e40:+.2f} % |")
        # also pairwise orders over consecutive triples
        pw = [math.log2((vals[i] - vals[i + 1]) / (vals[i + 1] - vals[i + 2]))
              if (vals[i + 1] - vals[i + 2]) != 0 and (vals[i] - vals[i + 1]) / (vals[i + 1] - vals[i + 2]) > 0
              else float("nan") for i in range(len(vals) - 2)]
        out[name] = dict(values=vals, order=p, richardson=rich, err40=e40, orders=pw)
    print("\npairwise orders (consecutive triples): "
          + "; ".join(f"{k} " + ", ".join(f"{o:.2f}" for o in v["orders"]) for k, v in out.items()))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("cases", nargs="*", default=["hs", "bath", "air"])
    ap.add_argument("--grids", default="20,40,80,160")
    ap.add_argument("--threshold", action="store_true", help="HS linear threshold per grid")
    ap.add_argument("--json", default=None)
    ap.add_argument("--theta-transport", type=int, default=0)
    a = ap.parse_args(argv)
    EXTRA["theta_transport"] = a.theta_transport
    grids = [int(g) for g in a.grids.split(",")]
    omega = 2 * math.pi * F_HZ
    q = hs_equilibrium(40)
    print(f"fixed kinematics: x = {q[0]:.6e} m, y = {q[1]:.6e} m (eps "
          f"{math.hypot(*q) / (BASE['psi'] * R):.4f}), {F_HZ} Hz")
    res = {}
    for case in a.cases:
        rows = []
        for n in grids:
            t0 = time.time()
            rows.append(hs_quantities(n, q, omega) if case == "hs" else mc_quantities(case, n, q, omega))
            print(f"  {case} {n} x {n}: {time.time() - t0:.1f} s", flush=True)
        res[case] = table(case, grids, rows, NAMES)
    if a.threshold:
        th = []
        for n in grids:
            t0 = time.time()
            th.append(hs_threshold(n))
            print(f"  threshold {n} x {n}: {th[-1]:.3f} Hz ({time.time() - t0:.1f} s)", flush=True)
        res["hs_threshold"] = table("HS linear Jeffcott threshold [Hz]", grids, [[t] for t in th],
                                    ["threshold_hz"])
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
