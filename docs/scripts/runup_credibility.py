"""Tabulate run-up credibility numbers from finished run directories (docs/runups.md section 3).

For journal 1 of each DIR: onset speed (summary.json analysis, as the run wrote it), the
instability threshold estimate of the current ``orchestrator.results.whirl`` (growth rate of
the sub-synchronous amplitude crosses zero; re-analysed from results.csv), its
``threshold_snr``, and the growth rate sigma [1/s] and amplitude a / c of the
sub-synchronous motion (order band 0.25-0.75) at a few speeds.

Run: ``.venv/bin/python docs/scripts/runup_credibility.py DIR... [--speeds 280,300,320,340]``
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from orchestrator.results.run_directory import read_results  # noqa: E402
from orchestrator.results.whirl import (WhirlParams, analyze_run, growth_rate,  # noqa: E402
                                        order_spectra)


def subsync_series(d: Path, journal: str = "bearing1", p: WhirlParams | None = None, centres: bool = False):
    """(order spectra, amplitude / c, growth rate [1/s]) of ``journal``'s forward sub-synchronous
    motion in the growth band of a finished run ``d`` (16-revolution windows, slope over
    ``growth_fit_revs``), as the whirl analysis computes them; with ``centres=True`` a fourth item,
    the rotor speed [Hz] each growth rate belongs to (its fit's mean time: the frame's own speed
    except within half a fit of the ends, where the fit is one-sided, docs/analysis.md step 6)."""
    p = p or WhirlParams()
    spec = json.loads((d / "summary.json").read_text())["analysis"]["spec"]
    js = spec["journals"][journal]
    cols = read_results(d / "results.csv")
    s = order_spectra(cols["time"], cols[js["x"]] + 1j * cols[js["y"]], cols[spec["speed"]], p)
    amp = s.band_amplitude(*p.growth_band) / js["clearance"]
    fit = 2 * max(int(round(p.growth_fit_revs / p.hop_revs / 2)), 1) + 1
    sig, t_fit = growth_rate(s.t, amp, fit, centres=True)
    if not centres:
        return s, amp, sig
    return s, amp, sig, np.interp(t_fit, s.t, s.speed_hz) if s.n_frames else np.empty(0)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--speeds", default="280,300,320,340")
    ap.add_argument("--journal", default="bearing1")
    a = ap.parse_args(argv)
    speeds = [float(s) for s in a.speeds.split(",")]
    p = WhirlParams()
    print("| run | H [s] | grid | onset [Hz] | threshold [Hz] (snr) | "
          + " | ".join(f"sigma, a/c at {s:g} Hz" for s in speeds) + " |")
    print("|---|---|---|---|---|" + "---|" * len(speeds))
    for d in a.dirs:
        d = Path(d)
        sm = json.loads((d / "summary.json").read_text())
        spec = sm["analysis"]["spec"]
        old = sm["analysis"]["journals"][a.journal]
        new = analyze_run(d, spec)["journals"][a.journal]
        s, amp, sig, sig_hz = subsync_series(d, a.journal, p, centres=True)
        cells = []
        for f in speeds:
            if s.n_frames and s.speed_hz.min() <= f <= s.speed_hz.max():
                k = int(np.argmin(np.abs(s.speed_hz - f)))
                ks = int(np.nanargmin(np.abs(sig_hz - f)))      # the growth rate that belongs to f
                cells.append(f"{sig[ks]:+.1f}, {amp[k]:.2e}")
            else:
                cells.append("-")
        macro = sm.get("macro_step") or (sm.get("coupling") or {}).get("macro_step")
        on = old.get("onset_speed_hz")
        th = new.get("threshold_speed_hz")
        snr = new.get("threshold_snr")
        print(f"| {d.name} | {macro if macro else '?'} | ? | {on:.1f} | " if on else f"| {d.name} | {macro if macro else '?'} | ? | none | ",
              end="")
        print((f"{th:.1f} ({snr:.1f})" if th else "none") + " | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
