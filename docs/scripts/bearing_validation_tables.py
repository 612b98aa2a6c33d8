"""Print every table of docs/bearing-validation.md and draw its figures.

Usage (from the repository root)::

    nice -n 10 .venv/bin/python docs/scripts/bearing_validation_tables.py [SECTION ...]

SECTION is any of ``ocvirk long table flow grid paper smoothing plots`` (default:
all). Tables are printed as Markdown; figures go to ``docs/img/``. The references
are in ``bearing_fmu/reference.py``; the solver is ``bearing_fmu.model``.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

from bearing_fmu import model
from bearing_fmu import reference as ref

R, PSI, ETA, P0 = 0.02, 2.8e-3, 0.012, 1e5
C = PSI * R
OMEGA = 2 * math.pi * 100.0
PAPER_B = 1.6 * R
IMG = Path(__file__).resolve().parents[1] / "img"


def params(*, B, n_phi, n_z, cavitation=0, axial_bc=0, groove_width=0.0,
           groove_angle=math.pi / 2, **extra):
    return model.BearingParams(R=R, B=B, psi=PSI, eta0=ETA, p0=P0, p_feed=P0,
                               groove_width=groove_width, groove_angle=groove_angle,
                               n_phi=n_phi, n_z=n_z, cavitation=cavitation,
                               axial_bc=axial_bc, **extra)


def hs_force(p, x, y, vx, vy):
    b = model.BearingModel(p)
    b.initialize(x, y, vx, vy, OMEGA)
    return np.array([b.outputs["Fx"], b.outputs["Fy"]])


def steady(p, x, y, omega=OMEGA):
    """Stationary mass-conserving film at fixed kinematics (the solver's steady
    Newton, ``bearing_fmu.model.solve_stationary``; paper section 3.1 solves eq. 4
    "with constant kinematic input variables")."""
    return model.solve_stationary(p, x, y, omega)


def rel(a, b):
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b))


def md(header, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    print("\n".join(out) + "\n", flush=True)


SQUEEZE = {
    "rotation": (0.0, -0.6 * C, 0.0, 0.0),
    "squeeze+whirl": (0.25 * C, -0.45 * C, 0.08 * C * OMEGA, 0.05 * C * OMEGA),
}


def sec_ocvirk():
    print("### HS vs Ocvirk short bearing (grid 180 x 20)\n")
    rows = []
    for name, (x, y, vx, vy) in SQUEEZE.items():
        for bd in (0.25, 0.125, 0.0625, 0.03125):
            B = bd * 2 * R
            f = hs_force(params(B=B, n_phi=180, n_z=20), x, y, vx, vy)
            fr = ref.short_bearing_force(x, y, vx, vy, OMEGA, R=R, B=B, c=C, eta=ETA)
            rows.append([name, f"1/{round(1 / bd)}", f"{f[0]:.5g}, {f[1]:.5g}",
                         f"{fr[0]:.5g}, {fr[1]:.5g}", f"{100 * rel(f, fr):.3f} %"])
    md(["case", "B/D", "ours Fx, Fy [N]", "Ocvirk Fx, Fy [N]", "|dF|/|F_ref|"], rows)


def sec_long():
    print("### HS vs Guembel long bearing (grid 72 x square cells)\n")
    rows = []
    for name, (x, y, vx, vy) in SQUEEZE.items():
        for bd in (2.0, 4.0, 8.0, 16.0):
            B = bd * 2 * R
            n_z = int(round(B / (R * 2 * math.pi / 72)))
            f = hs_force(params(B=B, n_phi=72, n_z=n_z), x, y, vx, vy)
            fr = ref.long_bearing_force(x, y, vx, vy, OMEGA, R=R, B=B, c=C, eta=ETA)
            e = rel(f, fr)
            rows.append([name, f"{bd:g}", f"72 x {n_z}", f"{f[0]:.5g}, {f[1]:.5g}",
                         f"{fr[0]:.5g}, {fr[1]:.5g}", f"{100 * e:.2f} %", f"{e * bd:.3f}"])
    md(["case", "B/D", "grid", "ours Fx, Fy [N]", "Guembel Fx, Fy [N]", "error",
        "error x B/D"], rows)


def finite_case(bd, eps, n_phi, n_z, **extra):
    B = bd * 2 * R
    x, y = 0.0, -eps * C
    p = params(B=B, n_phi=n_phi, n_z=n_z, cavitation=1, axial_bc=0, groove_width=1e-9,
               groove_angle=math.pi / 2, **extra)
    b = steady(p, x, y)
    fx, fy = b.outputs["Fx"], b.outputs["Fy"]
    s = ref.sommerfeld_number(math.hypot(fx, fy), R=R, B=B, c=C, eta=ETA, omega=OMEGA)
    return s, math.degrees(ref.attitude_angle(fx, fy, x, y)), b


def sec_table():
    print("### Mass-conserving model vs Khonsari & Booser Table 8.6 (Reynolds condition)\n")
    rows = []
    for bd in (1.0, 0.5, 0.25):
        for eps, s_tab, att_tab in ref.FINITE_BEARING_TABLE[bd]:
            if eps not in (0.4, 0.6, 0.8):
                continue
            for n_phi, n_z in ((90, 30), (180, 60)):
                t = time.time()
                s, att, _ = finite_case(bd, eps, n_phi, n_z)
                rows.append([f"{bd:g}", eps, f"{n_phi} x {n_z}", f"{s:.4f}", f"{s_tab:.4f}",
                             f"{100 * (s / s_tab - 1):+.2f} %", f"{att:.2f}", f"{att_tab:.2f}",
                             f"{att - att_tab:+.2f}", f"{time.time() - t:.1f}"])
    md(["L/D", "eps", "grid", "S ours", "S table", "dS", "att ours [deg]",
        "att table [deg]", "d att [deg]", "wall [s]"], rows)


def paper_case(axial_bc, n_phi=40, n_z=40, **extra):
    gw = 0.0 if axial_bc == 0 else math.radians(15.0)
    p = params(B=PAPER_B, n_phi=n_phi, n_z=n_z, cavitation=1, axial_bc=axial_bc,
               groove_width=gw, groove_angle=0.0, **extra)
    return steady(p, -0.7 * C, 0.0)


def cavity_stats(b):
    f = b.fields()
    th = f["theta"]
    return float(np.mean(th < 0.999)), float(th[[0, -1]].min()), float(th.min())


def sec_flow():
    print("### Mass balance in steady state (paper case, 40 x 40)\n")
    rows = []
    for bc, name in ((0, "oil bath, no groove"), (1, "free to air, 15 deg groove")):
        b = paper_case(bc)
        qf, qs = b.outputs["q_feed"], b.outputs["q_side"]
        rows.append([name, f"{qf:.6e}", f"{qs:.6e}", f"{qf - qs:.2e}",
                     f"{abs(qf - qs) / max(abs(qf), C * R * OMEGA * PAPER_B):.1e}"])
    md(["case", "q_feed [m^3/s]", "q_side [m^3/s]", "difference", "relative"], rows)


def _order_table(label, grids, vals, unit):
    rows = [[g, f"{v:.6g}"] for g, v in zip(grids, vals)]
    md(["grid", f"{label} [{unit}]"], rows)
    order = math.log2(abs(vals[-3] - vals[-2]) / abs(vals[-2] - vals[-1]))
    rich = vals[-1] + (vals[-1] - vals[-2]) / (2**order - 1)
    errs = ", ".join(f"{g}: {100 * abs(v - rich) / abs(rich):.2f} %" for g, v in zip(grids, vals))
    print(f"- observed order (three finest grids) {order:.2f}; Richardson estimate "
          f"{rich:.6g}; error against it: {errs}\n")
    return rich


def sec_grid():
    print("### Grid convergence\n")
    print("Half-Sommerfeld, paper geometry (B/R = 1.6, eps = 0.7), |F| [N]:\n")
    grids, vals = [], []
    for n in (20, 40, 80, 160, 320):
        f = hs_force(params(B=PAPER_B, n_phi=n, n_z=n), -0.7 * C, 0.0, 0.0, 0.0)
        grids.append(f"{n} x {n}")
        vals.append(float(np.linalg.norm(f)))
    _order_table("|F|", grids, vals, "N")
    print("Mass-conserving, table case (L/D = 1, eps = 0.6, flooded groove at h_max, "
          "oil bath), |F| [N]:\n")
    grids, vals = [], []
    for n in (40, 80, 160):
        t = time.time()
        _, _, b = finite_case(1.0, 0.6, n, n // 2)
        grids.append(f"{n} x {n // 2} ({time.time() - t:.1f} s)")
        vals.append(math.hypot(b.outputs["Fx"], b.outputs["Fy"]))
    rich = _order_table("|F|", grids, vals, "N")
    s_rich = ref.sommerfeld_number(rich, R=R, B=2 * R, c=C, eta=ETA, omega=OMEGA)
    print(f"- Sommerfeld number from the Richardson force: {s_rich:.5f} (table 0.1209)\n")
    print("Mass-conserving, paper case free to air (15 deg groove), |F| [N] and p_max [Pa]:\n")
    grids, vals, pm = [], [], []
    for n in (20, 40, 80, 160):
        t = time.time()
        b = paper_case(1, n, n)
        grids.append(f"{n} x {n} ({time.time() - t:.1f} s)")
        vals.append(math.hypot(b.outputs["Fx"], b.outputs["Fy"]))
        pm.append(b.outputs["p_max"])
    _order_table("|F|", grids, vals, "N")
    _order_table("p_max", grids, pm, "Pa")


def sec_paper():
    print("### Paper section 3.1 (40 x 40)\n")
    for width in (1e3, 0.9 * P0):
        rows = []
        res = {}
        for bc, name in ((0, "oil bath (eq. 5), no groove"),
                         (1, "free to air (eq. 6), 15 deg groove")):
            b = paper_case(bc, cav_width=width)
            o = b.outputs
            area, edge, thmin = cavity_stats(b)
            res[bc] = o["p_max"]
            rows.append([name, f"{o['p_max'] / 1e6:.4f}", f"{o['p_min'] / 1e5:.5f}",
                         f"{math.hypot(o['Fx'], o['Fy']):.1f}",
                         f"{math.degrees(o['attitude']):.2f}",
                         f"{100 * area:.1f} %", f"{edge:.3f}", f"{thmin:.3f}"])
        print(f"cav_width = {width:g} Pa:\n")
        md(["case", "p_max [MPa]", "p_min [bar]", "|F| [N]", "attitude [deg]",
            "cavity area (theta<0.999)", "min theta at edges", "min theta"], rows)
        print(f"p_max difference (bath - air)/air: {100 * (res[0] - res[1]) / res[1]:+.2f} % "
              f"(paper: 0.6 %)\n")


def sec_smoothing():
    print("### Effect of the smoothing width of theta(p) (paper case, 40 x 40)\n")
    rows = []
    for bc, name in ((1, "free to air"), (0, "oil bath")):
        for w in (1e2, 1e3, 1e4, 3e4, 9e4):
            try:
                b = paper_case(bc, cav_width=w)
            except model.StepFailed as e:
                rows.append([name, f"{w:g}", "no steady solution", "", "", "", "", str(e)[:40]])
                continue
            o = b.outputs
            area, edge, thmin = cavity_stats(b)
            rows.append([name, f"{w:g}", f"{o['p_max'] / 1e6:.4f}", f"{o['p_min'] / 1e5:.4f}",
                         f"{math.hypot(o['Fx'], o['Fy']):.1f}", f"{100 * area:.1f} %",
                         f"{edge:.3f}", f"{thmin:.3f}"])
    md(["case", "cav_width [Pa]", "p_max [MPa]", "p_min [bar]", "|F| [N]",
        "cavity area", "min theta at edges", "min theta"], rows)


def sec_plots():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    IMG.mkdir(parents=True, exist_ok=True)
    for bc, name, fig_no, width in ((0, "oil_bath", 5, 1e3), (1, "free_to_air", 7, 1e3),
                                    (0, "oil_bath_cav_width_90kPa", 5, 0.9 * P0)):
        b = paper_case(bc, cav_width=width)
        f = b.fields()
        phi = np.degrees(f["phi"])
        zb = np.asarray(f["z"]) / PAPER_B
        fig, ax = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
        m0 = ax[0].pcolormesh(phi, zb, f["p"] / 1e6, shading="nearest", cmap="viridis")
        fig.colorbar(m0, ax=ax[0], label="p [MPa]")
        ax[0].set_title(f"pressure (paper fig. {fig_no}a)")
        m1 = ax[1].pcolormesh(phi, zb, f["theta"], shading="nearest", cmap="viridis",
                              vmin=0, vmax=1)
        fig.colorbar(m1, ax=ax[1], label="theta [-]")
        ax[1].set_title(f"fluid fraction (paper fig. {fig_no}b)")
        for a in ax:
            a.set_xlabel("phi [deg]")
            a.set_ylabel("z / B")
        fig.suptitle(f"Stationary case, {name.split('_cav')[0].replace('_', ' ')}: 100 Hz, "
                     "eps = 0.7, "
                     f"h_min at phi = 180 deg, 40 x 40, cav_width = {width:g} Pa")
        out = IMG / f"bearing_stationary_{name}.png"
        fig.savefig(out, dpi=110)
        plt.close(fig)
        print(f"wrote {out}")


SECTIONS = {"ocvirk": sec_ocvirk, "long": sec_long, "table": sec_table, "flow": sec_flow,
            "grid": sec_grid, "paper": sec_paper, "smoothing": sec_smoothing,
            "plots": sec_plots}

if __name__ == "__main__":
    chosen = sys.argv[1:] or list(SECTIONS)
    for s in chosen:
        t0 = time.time()
        SECTIONS[s]()
        print(f"<!-- section {s}: {time.time() - t0:.1f} s -->\n", flush=True)
