"""Figures of a floating-ring run-up (docs/floating-ring.md).

    .venv/bin/python docs/scripts/floating_ring_plots.py RUN_DIR OUT_PREFIX [bearing1]

From RUN_DIR/results.csv: (1) the order waterfall of the journal (x + i y relative to the
housing) with the journal and ring orders drawn: 1x, the ring speed Omega/omega, 0.5 (journal +
ring) (inner-film whirl) and 0.5 ring (outer-film whirl), Omega taken from the run; (2) the ring
speed ratio, the inner and outer eccentricities and the friction power over speed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from orchestrator.results.run_directory import read_results
from orchestrator.results.whirl import WhirlParams, waterfall


def main(run_dir, prefix, bearing="bearing1", station="1"):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cols = read_results(Path(run_dir) / "results.csv")
    t, om = cols["time"], cols["rotor.omega"]
    z = cols[f"rotor.x_{station}"] + 1j * cols[f"rotor.y_{station}"]
    wf = waterfall(t, z, om, WhirlParams(window_revs=32))
    ratio = cols[f"{bearing}.omega_ring"] / np.where(om > 0, om, np.nan)
    f_hz = om / (2 * np.pi)
    fig, ax = plt.subplots(figsize=(7, 5))
    keep = (wf["orders"] >= 0) & (wf["orders"] <= 1.2)
    amp = wf["amplitude"][:, keep]
    ax.pcolormesh(wf["orders"][keep], wf["speed_hz"], np.log10(amp + 1e-12), shading="nearest", cmap="viridis")
    r_at = np.interp(wf["speed_hz"], f_hz, ratio)
    for y, lab, st in ((np.ones_like(r_at), "1x", "w-"), (r_at, "ring speed", "c--"),
                       (0.5 * (1 + r_at), "0.5 (journal + ring)", "r--"), (0.5 * r_at, "0.5 ring", "m--")):
        ax.plot(y, wf["speed_hz"], st, lw=1, label=lab)
    ax.set_xlabel("order (frequency / journal speed)")
    ax.set_ylabel("journal speed [Hz]")
    ax.set_title(f"{Path(run_dir).name}: journal {station} order spectrum (log10 m)")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(f"{prefix}_waterfall.png", dpi=110)
    fig, axs = plt.subplots(3, 1, figsize=(7, 7), sharex=True)
    axs[0].plot(f_hz, ratio, lw=0.8)
    axs[0].set_ylabel("Omega_ring / omega")
    axs[1].plot(f_hz, cols[f"{bearing}.eps"], lw=0.5, label="inner eps")
    axs[1].plot(f_hz, cols[f"{bearing}.eps_outer"], lw=0.5, label="outer eps")
    axs[1].legend(fontsize=8)
    axs[1].set_ylabel("eccentricity")
    axs[2].plot(f_hz, cols[f"{bearing}.P_loss"], lw=0.8)
    axs[2].set_ylabel("P_loss [W]")
    axs[2].set_xlabel("journal speed [Hz]")
    fig.tight_layout()
    fig.savefig(f"{prefix}_ring.png", dpi=110)
    print(f"wrote {prefix}_waterfall.png, {prefix}_ring.png")


if __name__ == "__main__":
    main(*sys.argv[1:4])
