"""Linear whirl thresholds of the Jeffcott sweep points (docs/sweeps.md, section 4).

For every (psi, eta0) of ``scenarios/sweeps/*.yaml`` the lowest speed at which the linearized
Jeffcott rotor of the paper's run-ups (``scenarios/jeffcott_runup_*_seeded.yaml``: 5 kg disc,
2 x 0.5 kg journals, 4000 N/mm shaft, d_external 500 N s/m, R = 4.9 mm, B = 1.6 R) has an
eigenvalue with a positive real part, by :func:`rotor_fmu.stability.threshold_speed`, with two
sets of bearing coefficients at the static equilibrium under gravity:

* ``short``: the closed-form short-bearing (Ocvirk) pi-film coefficients,
  :func:`rotor_fmu.stability.short_bearing_coefficient_fn` (B/R = 1.6 is not short: a bound);
* ``hs40``: the coefficients of our finite-length half-Sommerfeld film on the 40 x 40 grid of the
  run-ups (:class:`bearing_fmu.model.BearingModel`, central differences at the Newton
  equilibrium :func:`bearing_fmu.linearize.hs_static_equilibrium`, as ``docs/paper_cases_radius.py``
  does) - the same film the HS sweep integrates.

Run: ``.venv/bin/python docs/sweeps_threshold.py [--csv out.csv]`` (a few minutes).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

R, B_OVER_R = 4.9e-3, 1.6
PSIS = (2.4e-3, 2.8e-3, 3.2e-3)
ETAS = (0.008, 0.012, 0.016)


def rotor():
    from rotor_fmu.jeffcott import JeffcottModel, JeffcottParams
    return JeffcottModel(JeffcottParams(m_disc=5.0, m_journal=0.5))


def hs40_coefficient_fn(rot, psi: float, eta: float, n: int = 40):
    """omega -> (K, C) (n_b, 2, 2) of the 40 x 40 HS film at its equilibrium under each
    bearing's static load (both bearings carry the same load in this symmetric rotor)."""
    import paper_cases_radius as pcr
    from bearing_fmu.model import BearingModel, BearingParams
    from rotor_fmu.stability import static_bearing_loads

    b = BearingModel(BearingParams(R=R, B=B_OVER_R * R, psi=psi, eta0=eta, p0=1e5, p_feed=1e5,
                                   n_phi=n, n_z=n, cavitation=0, axial_bc=0))
    b.initialize(0.0, -0.5 * psi * R, 0.0, 0.0, 1.0)
    load = float(np.hypot(*static_bearing_loads(rot)[0]))
    state = {"q": np.array([0.3, -0.5]) * b.c}

    def fn(omega):
        state["q"] = pcr.equilibrium(b, load, omega, guess=state["q"] / b.c)
        K, D = pcr.coefficients(b, state["q"], omega)
        nb = len(rot.bearing_dofs)
        return np.array([K] * nb), np.array([D] * nb)
    return fn


def mc_params(psi: float, eta: float, n: int = 40):
    """The oil-bath mass-conserving film of scenarios/jeffcott_runup_oil_bath_seeded.yaml."""
    from bearing_fmu.model import BearingParams
    return BearingParams(R=R, B=B_OVER_R * R, psi=psi, eta0=eta, p0=1e5, p_feed=1e5, n_phi=n, n_z=n,
                         cavitation=1, axial_bc=0, cav_width=9.0e4, theta_transport=1)


def seed(psi: float, eta: float, f_hz: float, model: str, offset: float = 0.02) -> dict:
    """The seeded start of one sweep point: the journals' static equilibrium at ``f_hz`` under
    their gravity load on the film of ``model`` ('hs': 40 x 40 HS; 'mc': 40 x 40 oil bath,
    stationary film, Newton on the journal centre), moved ``offset`` c in +x (as the shipped
    seeded scenarios do at their nominal point)."""
    from bearing_fmu.model import solve_stationary
    from rotor_fmu.stability import static_bearing_loads
    load = float(np.hypot(*static_bearing_loads(rotor())[0]))
    omega, c = 2 * math.pi * f_hz, psi * R
    if model == "hs":
        import paper_cases_radius as pcr
        from bearing_fmu.model import BearingModel, BearingParams
        b = BearingModel(BearingParams(R=R, B=B_OVER_R * R, psi=psi, eta0=eta, p0=1e5, p_feed=1e5,
                                       n_phi=40, n_z=40, cavitation=0, axial_bc=0))
        b.initialize(0.0, -0.5 * c, 0.0, 0.0, 1.0)
        q = pcr.equilibrium(b, load, omega)
    else:
        params = mc_params(psi, eta)
        force = lambda q: np.array([(o := solve_stationary(params, q[0], q[1], omega).outputs)["Fx"],  # noqa: E731
                                    o["Fy"]])
        q = np.array([0.3, -0.3]) * c
        for _ in range(30):
            f = force(q) - np.array([0.0, load])
            if np.max(np.abs(f)) < 1e-7 * load:
                break
            d, J = 1e-5 * c, np.empty((2, 2))
            for j in range(2):
                e = np.zeros(2)
                e[j] = d
                J[:, j] = (force(q + e) - force(q - e)) / (2 * d)
            step, lam = np.linalg.solve(J, -f), 1.0
            while np.hypot(*(q + lam * step)) >= 0.95 * c:
                lam *= 0.5
            q = q + lam * step
        else:
            raise RuntimeError(f"no mass-conserving equilibrium at psi={psi}, eta={eta}, {f_hz} Hz")
    return {"psi": psi, "eta0": eta, "clearance": c, "x_eq": float(q[0]), "y_eq": float(q[1]),
            "eps_eq": float(np.hypot(*q) / c), "journal_x0": float(q[0] + offset * c), "journal_y0": float(q[1])}


def thresholds(psi: float, eta: float) -> dict:
    from rotor_fmu.stability import short_bearing_coefficient_fn, threshold_speed
    rot = rotor()
    out = {"psi": psi, "eta0": eta}
    short = short_bearing_coefficient_fn(rot, R=R, L=B_OVER_R * R, C=psi * R, eta=eta)
    w, nu = threshold_speed(rot, short, omega_min=2 * math.pi * 20, omega_max=2 * math.pi * 1500, n_scan=60)
    out["short_hz"] = w / (2 * math.pi) if w else None
    w, nu = threshold_speed(rot, hs40_coefficient_fn(rot, psi, eta), omega_min=2 * math.pi * 60,
                            omega_max=2 * math.pi * 900, n_scan=30)
    out["hs40_hz"] = w / (2 * math.pi) if w else None
    out["hs40_whirl_hz"] = nu / (2 * math.pi) if nu else None
    return out


def compare(dirs) -> None:
    import csv
    tables = []
    for d in dirs:
        with open(Path(d) / "sweep.csv", newline="") as fh:
            tables.append({(float(r["psi"]), float(r["eta0"])): r for r in csv.DictReader(fh)})
    num = lambda r, k: f"{float(r[k]):.1f}" if r and r.get(k) not in (None, "") else "-"   # noqa: E731
    head = "| psi | eta0 [mPa s] | linear short [Hz] | linear HS 40x40 [Hz] |"
    for d in dirs:
        head += f" {Path(d).name}: threshold est. [Hz] | onset [Hz] | ratio | status |"
    print(head)
    print("|" + "---|" * (4 + 4 * len(dirs)))
    for p in PSIS:
        for e in ETAS:
            if not any((p, e) in t for t in tables):
                continue
            lin = thresholds(p, e)
            line = f"| {p:.1e} | {e * 1e3:g} | {lin['short_hz']:.1f} | {lin['hs40_hz']:.1f} |"
            for t in tables:
                r = t.get((p, e))
                ratio = f"{float(r['whirl_ratio']):.2f}" if r and r.get("whirl_ratio") else "-"
                line += (f" {num(r, 'threshold_hz')} | {num(r, 'onset_hz')} | {ratio} | "
                         f"{r['status'] if r else 'not run'} |")
            print(line)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--csv", help="also write the table to this CSV file")
    ap.add_argument("--seeds", choices=("hs", "mc"), help="print the seeded starts (zip lists) instead")
    ap.add_argument("--at-hz", type=float, default=220.0, help="speed of the seeded start [Hz]")
    ap.add_argument("--points", default="all", help="'all' (3 x 3) or 'corners' (2 x 2)")
    ap.add_argument("--compare", nargs="+", metavar="SWEEP_DIR",
                    help="print the table of docs/sweeps.md: these sweep folders' onsets and run threshold "
                         "estimates beside the linear thresholds at the same points")
    args = ap.parse_args(argv)
    if args.compare:
        compare(args.compare)
        return
    if args.seeds:
        pts = [(p, e) for p in PSIS for e in ETAS]
        if args.points == "corners":
            pts = [(p, e) for p, e in pts if p != PSIS[1] and e != ETAS[1]]
        rows = [seed(p, e, args.at_hz, args.seeds) for p, e in pts]
        for key in ("psi", "eta0", "clearance", "journal_x0", "journal_y0", "eps_eq", "x_eq", "y_eq"):
            print(f"{key}: [{', '.join(f'{r[key]:.4g}' for r in rows)}]")
        return
    rows = [thresholds(p, e) for p in PSIS for e in ETAS]
    print("| psi | eta0 [Pa s] | short-bearing threshold [Hz] | HS 40x40 threshold [Hz] | whirl [Hz] |")
    print("|---|---|---|---|---|")
    fmt = lambda v: "-" if v is None else f"{v:.1f}"      # noqa: E731
    for r in rows:
        print(f"| {r['psi']:.1e} | {r['eta0']:g} | {fmt(r['short_hz'])} | {fmt(r['hs40_hz'])} | "
              f"{fmt(r['hs40_whirl_hz'])} |")
    if args.csv:
        import csv
        with open(args.csv, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)


if __name__ == "__main__":
    main()
