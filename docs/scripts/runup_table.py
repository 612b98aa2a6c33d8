"""Run-up table of docs/runups.md section 2 from finished run directories.

For journal 1 of each DIR: "decay -> growth" (speed of the minimum of the forward
sub-synchronous amplitude before the detected onset, 16-revolution windows; in the
detection band 0.15-0.85 and, in brackets, the growth band 0.25-0.75 of the threshold
estimate), onset and vanish (summary.json analysis, as the run wrote it), maximum eps,
mean eps over +-5 Hz at 150 / 200 / 250 Hz, and the dominant whirl / speed ratio.

Run: ``.venv/bin/python docs/scripts/runup_table.py [--min-hz F] DIR...``; with ``--min-hz``
the maximum eps is taken over speeds >= F only (the from-rest run-ups start on the shell,
eps 0.985 at 0 Hz: ``--min-hz 100`` compares them with the shipped runs, which start there).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from orchestrator.results.run_directory import read_results  # noqa: E402
from orchestrator.results.whirl import WhirlParams, order_spectra  # noqa: E402


def row(d: Path, journal: str = "bearing1", min_hz: float = 0.0) -> str:
    sm = json.loads((d / "summary.json").read_text())
    spec = sm["analysis"]["spec"]
    js = spec["journals"][journal]
    a = sm["analysis"]["journals"][journal]
    c = read_results(d / "results.csv")
    p = WhirlParams()
    s = order_spectra(c["time"], c[js["x"]] + 1j * c[js["y"]], c[spec["speed"]], p)
    onset = a.get("onset_speed_hz")
    mins = []
    for band in (p.band, p.growth_band):
        amp = s.band_amplitude(*band) / js["clearance"]
        m = s.speed_hz < (onset if onset else np.inf)
        mins.append(s.speed_hz[m][int(np.argmin(amp[m]))] if m.any() else float("nan"))
    f = c[spec["speed"]] / (2 * np.pi)
    eps = c[js["eps"]]
    me = []
    for x in (150.0, 200.0, 250.0):
        m = (f > x - 5) & (f < x + 5)
        me.append(f"{eps[m].mean():.3f}" if m.any() else "-")
    if min_hz > 0:
        m = f >= min_hz
        k = int(np.argmax(eps[m]))
        max_eps, max_at = float(eps[m][k]), float(f[m][k])
    else:
        max_eps, max_at = a["max_eps"], a["max_eps_speed_hz"]
    on = f"{a['onset_time_s']:.3f} / {onset:.1f}" if onset else "none"
    va = f"{a['vanish_time_s']:.3f} / {a['vanish_speed_hz']:.1f}" if a.get("vanish_time_s") else "-"
    ratio = a.get("dominant_ratio")
    return (f"| {d.name} | {mins[0]:.0f} ({mins[1]:.0f}) | {on} | {va} | "
            f"{max_eps:.3f} ({max_at:.0f}) | {' / '.join(me)} | "
            + (f"{ratio:.2f}" if ratio else "-") + " |")


def main(argv=None):
    dirs = list(argv if argv is not None else sys.argv[1:])
    min_hz = 0.0
    if dirs[:1] == ["--min-hz"]:
        min_hz = float(dirs[1])
        dirs = dirs[2:]
    print("| run | decay -> growth [Hz] | onset [s] / [Hz] | vanish [s] / [Hz] | max eps (at [Hz]) "
          "| mean eps at 150 / 200 / 250 Hz | whirl / speed (median) |")
    print("|---|---|---|---|---|---|---|")
    for d in dirs:
        print(row(Path(d), min_hz=min_hz))


if __name__ == "__main__":
    main()
