"""One figure for a run-up credibility pair: the sub-synchronous amplitude and its growth rate
over speed, for several run directories of the same scenario (base, macro step halved, grid
refined ...), with each run's onset and threshold estimate marked, and optionally the linear
growth rate of the least-damped sub-synchronous mode as a reference curve.

    .venv/bin/python docs/scripts/credibility_plot.py OUT.png DIR[=LABEL]... [--journal bearing1]
        [--linear FILE.csv] [--title TEXT]

The amplitude is the forward sub-synchronous orbit in the growth band of the whirl analysis
(``orchestrator.results.whirl``: order spectra in 16-revolution windows, band 0.25-0.75,
relative to the clearance), the growth rate its least-squares slope over 16 revolutions
(``growth_rate``), both as ``docs/scripts/runup_credibility.py`` tabulates them; the onset
(amplitude 0.05 c) and threshold (growth rate crosses 0) are the run's summary.json analysis.
``--linear``: a CSV of ``speed_hz,sigma`` rows (e.g. from ``ring_system_eigen``) drawn on the
growth-rate axis.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))      # runup_credibility (it adds the repository)

from runup_credibility import subsync_series  # noqa: E402


def series(d: Path, journal: str):
    """(speed_hz, amplitude / c, (speed_hz of each growth rate, growth rate [1/s]), onset_hz,
    threshold_hz) of one run; each growth rate drawn at the speed its fit belongs to."""
    res = json.loads((d / "summary.json").read_text())["analysis"]["journals"][journal]
    s, amp, sig, sig_hz = subsync_series(d, journal, centres=True)
    return s.speed_hz, amp, (sig_hz, sig), res.get("onset_speed_hz"), res.get("threshold_speed_hz")


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("dirs", nargs="+", help="run directories, each optionally DIR=LABEL")
    ap.add_argument("--journal", default="bearing1")
    ap.add_argument("--linear", help="CSV of speed_hz,sigma rows: the linear growth rate")
    ap.add_argument("--title", default="")
    a = ap.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 7))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, item in enumerate(a.dirs):
        d, _, label = item.partition("=")
        f, amp, sig, on, th = series(Path(d), a.journal)
        c = colours[i % len(colours)]
        lab = label or Path(d).name
        ax1.semilogy(f, amp, color=c, label=f"{lab}: onset {on:.2f} Hz" if on else f"{lab}: no onset")
        ax2.plot(*sig, color=c, label=f"{lab}: threshold {th:.2f} Hz" if th else f"{lab}: no threshold")
        if on:
            ax1.axvline(on, color=c, ls=":", lw=1)
        if th:
            ax2.axvline(th, color=c, ls=":", lw=1)
    if a.linear:
        lin = np.loadtxt(a.linear, delimiter=",", ndmin=2)
        ax2.plot(lin[:, 0], lin[:, 1], "k--", lw=1.2, label="linear (eigenvalue)")
    ax1.axhline(0.05, color="grey", lw=0.8)
    ax1.text(ax1.get_xlim()[0], 0.052, " onset level 0.05 c", color="grey", fontsize=8, va="bottom")
    ax2.axhline(0.0, color="grey", lw=0.8)
    ax1.set_ylabel("sub-synchronous orbit / clearance")
    ax2.set_ylabel("growth rate [1/s]")
    ax2.set_xlabel("rotor speed [Hz]")
    ax1.legend(fontsize=8)
    ax2.legend(fontsize=8)
    ax1.set_title(a.title or f"credibility runs, journal '{a.journal}'")
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(a.out)


if __name__ == "__main__":
    main()
