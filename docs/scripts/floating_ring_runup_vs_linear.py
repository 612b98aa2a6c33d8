"""The seeded floating-ring run-up's outer-whirl growth rate against the linear model evaluated
along the run (docs/floating-ring.md, "Why the run-up threshold sat +13 Hz high"):

    .venv/bin/python docs/scripts/floating_ring_runup_vs_linear.py DIR [--fit 690,790] [--step 10] [--plot PNG]

For the run in DIR (results.csv of jeffcott_runup_floating_ring_half_sommerfeld_seeded or a
variant): the growth rate sigma of the 60-140 Hz band (journal 1, ring 1; sliding matrix pencil,
as floating_ring_runup_growth.py) and, every --step Hz, the least-damped outer-whirl eigenvalue
(whirl 60-140 Hz) of the linear model (rotor_fmu.floating_ring_stability) four ways:

* steady:      ring speed from the torque balance, spin held (the eigenvalue threshold 712.9 Hz);
* steady+spin: the same with the ring-spin perturbation as a DOF (spin free, as in the run);
* run:         the ring speeds the run has at that journal speed (both rings), spin held;
* run+spin:    the run's ring speeds, spin free: the linear model of the run-up's own state.

Each column's zero crossing (a line over --fit as for the run). The run's ring lags its steady
speed on the ramp (spin-up time constant tau = J / (2 pi (a + b)) ~ 20 ms times the ring's
acceleration), which lowers the outer-film wedge and the growth rate.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from floating_ring_runup_growth import read  # noqa: E402

from rotor_fmu.floating_ring_growth import jeffcott_floating_ring, sliding_growth, zero_crossing  # noqa: E402
from rotor_fmu.floating_ring_stability import ring_system_eigen  # noqa: E402


def outer_whirl(rotor, rings, w, spin, omega_ring=None, band=(60.0, 140.0)):
    """Least-damped eigenvalue with whirl frequency in ``band`` [Hz]: (Re [1/s], whirl [Hz])."""
    lam, _ = ring_system_eigen(rotor, rings, w, spin=spin, omega_ring=omega_ring)
    f = np.abs(lam.imag) / (2 * math.pi)
    sel = lam[(f >= band[0]) & (f <= band[1])]
    k = int(np.argmax(sel.real))
    return float(sel[k].real), float(abs(sel[k].imag) / (2 * math.pi))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--fit", default="690,790")
    ap.add_argument("--step", type=float, default=10.0)
    ap.add_argument("--plot", help="PNG: the run-up's sigma and the four linear curves over speed")
    a = ap.parse_args(argv)
    lo, hi = (float(v) for v in a.fit.split(","))
    c = read(a.dir)
    t, w = c["time"], c["rotor.omega"]
    Y = np.array([c["rotor.x_1"], c["rotor.y_1"], c["bearing1.x_ring"], c["bearing1.y_ring"]])
    tm, sig, _ = sliding_growth(t, Y, (60.0, 140.0))
    spd = np.interp(tm, t, w) / (2 * math.pi)
    rotor, rings = jeffcott_floating_ring()
    fs = np.arange(math.ceil(lo / a.step) * a.step, hi + 1e-9, a.step)
    cols = {k: [] for k in ("steady", "steady+spin", "run", "run+spin")}
    print(f"{a.dir}\n  speed  ring ratio run/steady   sigma: run-up  steady  steady+spin  run  run+spin [1/s]")
    for f in fs:
        wf = 2 * math.pi * f
        om = [float(np.interp(wf, w, c[f"bearing{i}.omega_ring"])) for i in (1, 2)]
        _, pts = ring_system_eigen(rotor, rings, wf)
        vals = [outer_whirl(rotor, rings, wf, False), outer_whirl(rotor, rings, wf, True),
                outer_whirl(rotor, rings, wf, False, om), outer_whirl(rotor, rings, wf, True, om)]
        for k, v in zip(cols, vals):
            cols[k].append(v[0])
        s_run = float(np.interp(f, spd, sig))
        print(f"  {f:6.1f}  {om[0] / wf:.4f} / {pts[0]._Om / wf:.4f}   {s_run:+7.2f}  "
              + "  ".join(f"{v[0]:+7.2f}" for v in vals))
    f_run, _ = zero_crossing(spd, sig, lo, hi)
    print(f"  growth rate crosses 0: run-up {f_run:.1f} Hz; linear "
          + ", ".join(f"{k} {zero_crossing(fs, np.array(v), lo, hi)[0]:.1f} Hz" for k, v in cols.items()))
    if a.plot:
        plot(a.plot, a.dir, spd, sig, fs, cols, lo, hi)


def plot(png, title, spd, sig, fs, cols, lo, hi):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.2))
    m = (spd >= lo - 10) & (spd <= hi + 10)
    ax.plot(spd[m], sig[m], "k.", ms=3, label="run-up (sliding matrix pencil)")
    for (k, v), st in zip(cols.items(), ("C0--", "C0-", "C3--", "C3-")):
        ax.plot(fs, v, st, label=f"linear, {k}")
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("journal speed [Hz]")
    ax.set_ylabel("outer-whirl growth rate [1/s]")
    ax.set_title(Path(title).name, fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


if __name__ == "__main__":
    main()
