"""Growth rate of the inner-film whirl in a Jeffcott floating-ring run-up window from the
envelope of the journal motion relative to its ring (docs/floating-ring.md, "The inner-film whirl
near its threshold"):

    .venv/bin/python docs/scripts/floating_ring_inner_envelope.py RUN_DIR [LO,HI Hz band] [F1,F2 fit]

z = (x_1 - x_ring1) + i (y_1 - y_ring1), forward frequencies in the band kept (FFT band-pass of
the whole record: the inner whirl near 0.5 (journal + ring) = 540-560 Hz, the 1x at 850-890 Hz and
the outer whirl near 100 Hz outside), |z| the envelope; its log's slope in 2 ms-spaced 10 ms
windows (growth rate, 1/s) against journal speed, and the line fitted over F1-F2 Hz and its zero.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from orchestrator.results.run_directory import read_results


def main(run_dir, band="500,620", fit="860,880"):
    lo, hi = (float(v) for v in band.split(","))
    f1, f2 = (float(v) for v in fit.split(","))
    c = read_results(Path(run_dir) / "results.csv")
    t = c["time"]
    z = (c["rotor.x_1"] - c["bearing1.x_ring"]) + 1j * (c["rotor.y_1"] - c["bearing1.y_ring"])
    z = z - np.polyval(np.polyfit(t - t[0], z, 2), t - t[0])       # slow drift of the equilibrium
    Z = np.fft.fft(z)
    fr = np.fft.fftfreq(t.size, t[1] - t[0])
    Z[(fr < lo) | (fr > hi)] = 0.0
    env = np.abs(np.fft.ifft(Z))
    spd = c["rotor.omega"] / (2 * math.pi)
    dt = t[1] - t[0]
    nw, nh = int(round(0.010 / dt)), int(round(0.002 / dt))
    edge = int(round(0.010 / dt))                   # the band-pass's wrap-around at both ends
    rows = []
    for i0 in range(edge, t.size - nw - edge, nh):
        s = slice(i0, i0 + nw)
        a = np.polyfit(t[s], np.log(env[s]), 1)[0]
        rows.append((float(np.mean(spd[s])), float(a), float(np.mean(env[s]))))
    rows = np.array(rows)
    print(f"{run_dir}: envelope growth rate of the {lo:g}-{hi:g} Hz band (journal relative to ring)")
    for f, a, e in rows[::2]:
        print(f"  {f:6.1f} Hz: {a:+7.2f} 1/s, amplitude {e / 1.372e-5:.2e} c_i")
    m = (rows[:, 0] >= f1) & (rows[:, 0] <= f2)
    k, b = np.polyfit(rows[m, 0], rows[m, 1], 1)
    print(f"  line over {f1:g}-{f2:g} Hz: crosses 0 at {-b / k:.1f} Hz (slope {k:.3f} 1/s/Hz)")


if __name__ == "__main__":
    main(*sys.argv[1:4])
