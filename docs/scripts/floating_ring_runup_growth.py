"""Outer-film whirl growth rate over a floating-ring run-up, and the threshold estimate
(docs/floating-ring.md, "Run-up threshold"):

    .venv/bin/python docs/scripts/floating_ring_runup_growth.py DIR|NPZ [...] [--fit 690,820]

For each run directory (results.csv of scenarios/jeffcott_runup_floating_ring_half_sommerfeld_seeded.yaml
or a variant; or an .npz of t, R = rotor_fmu.floating_ring_growth.runup_cosim(...) and H): the growth rate of the 60-140 Hz band (outer-film whirl) of journal 1 and ring 1
in sliding 25 ms windows (matrix pencil, rotor_fmu.floating_ring_growth.sliding_growth), the
speed where a line fitted over the --fit speed range crosses zero, and, for two runs given
with macro steps H and H/2 (from summary.json), the Richardson extrapolation to H -> 0 of that
speed (the coupling error is first order in H, docs/floating-ring.md).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path

import numpy as np

from rotor_fmu.floating_ring_growth import sliding_growth, zero_crossing


def read(d):
    with open(Path(d) / "results.csv") as fh:
        r = csv.reader(fh)
        head = next(r)
        data = np.array([[float(v) for v in row] for row in r])
    return {h: data[:, i] for i, h in enumerate(head)}


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--fit", default="690,820")
    ap.add_argument("--band", default="60,140",
                    help="whirl frequency band [Hz] of the pole followed (default 60,140: the outer-film "
                         "whirl; 480,650 for the inner-film whirl near 0.5 (journal + ring) at 800-900 Hz)")
    a = ap.parse_args(argv)
    band = tuple(float(v) for v in a.band.split(","))
    lo, hi = (float(v) for v in a.fit.split(","))
    found = []
    for d in a.dirs:
        if d.endswith(".npz"):            # rotor_fmu.floating_ring_growth.runup_cosim, saved as t, R, H
            z = np.load(d)
            t, H = z["t"], float(z["H"])
            c = dict(zip(("rotor.omega", "rotor.x_1", "rotor.y_1", "bearing1.x_ring", "bearing1.y_ring"), z["R"]))
        else:
            c = read(d)
            sm = json.loads((Path(d) / "summary.json").read_text())
            H = sm.get("coupling", {}).get("macro_step", float("nan"))     # nan: run still going
            t = c["time"]
        Y = np.array([c["rotor.x_1"], c["rotor.y_1"], c["bearing1.x_ring"], c["bearing1.y_ring"]])
        tm, sig, frq = sliding_growth(t, Y, band)
        spd = np.interp(tm, t, c["rotor.omega"]) / (2 * math.pi)
        f0, slope = zero_crossing(spd, sig, lo, hi)
        found.append((H, f0))
        print(f"{d}: H = {H:g} s")
        for f in range(int(lo // 20 + 1) * 20, int(hi) + 1, 20):   # every 20 Hz of the fit range
            k = int(np.argmin(abs(spd - f)))
            if abs(spd[k] - f) < 3:
                print(f"  {spd[k]:6.1f} Hz: sigma {sig[k]:+7.2f} 1/s, whirl {frq[k]:6.1f} Hz")
        print(f"  growth rate crosses 0 at {f0:.1f} Hz (line over {lo:g}-{hi:g} Hz, slope {slope:.3f} 1/s/Hz)")
    if len(found) == 2:
        (H1, f1), (H2, f2) = sorted(found, reverse=True)
        fr = f2 + (f2 - f1) * H2 / (H1 - H2)
        print(f"Richardson (first order) from H = {H1:g}, {H2:g} s: threshold {fr:.1f} Hz")


if __name__ == "__main__":
    main()
