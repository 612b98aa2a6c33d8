"""Forward sub-synchronous amplitude of a run-up at given speeds (docs/runups.md, "From rest").

For journal 1 of each DIR: the amplitude in the detection band of the analysis (16-revolution
windows, orchestrator.results.whirl.order_spectra), relative to the clearance, at the window
nearest to each speed. It shows how large the seed of the whirl is before the onset: a
start-up transient that seeds the whirl leaves a larger amplitude there than the numerical
floor of an undisturbed start.

Run: ``.venv/bin/python docs/scripts/subsync_floor.py DIR... [--hz 50,100,200,250,300,350]``
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from orchestrator.results.run_directory import read_results  # noqa: E402
from orchestrator.results.whirl import WhirlParams, order_spectra  # noqa: E402


def amplitudes(d: Path, speeds, journal: str = "bearing1") -> list[float]:
    spec = json.loads((d / "summary.json").read_text())["analysis"]["spec"]
    js = spec["journals"][journal]
    c = read_results(d / "results.csv")
    p = WhirlParams()
    s = order_spectra(c["time"], c[js["x"]] + 1j * c[js["y"]], c[spec["speed"]], p)
    amp = s.band_amplitude(*p.band) / js["clearance"]
    out = []
    for f in speeds:
        k = int(np.argmin(np.abs(s.speed_hz - f)))
        out.append(float(amp[k]) if abs(s.speed_hz[k] - f) < 10 else float("nan"))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--hz", default="50,100,150,200,250,300,350")
    a = ap.parse_args(argv)
    speeds = [float(x) for x in a.hz.split(",")]
    print("| run | " + " | ".join(f"{f:g} Hz" for f in speeds) + " |")
    print("|---|" + "---|" * len(speeds))
    for d in a.dirs:
        print(f"| {Path(d).name} | " + " | ".join(f"{v:.2e}" for v in amplitudes(Path(d), speeds)) + " |")


if __name__ == "__main__":
    main()
