"""Tables of a turbocharger run-up in floating rings (docs/floating-ring.md).

    .venv/bin/python docs/scripts/floating_ring_turbocharger_table.py RUN_DIR [HZ,HZ,...]

From RUN_DIR/results.csv: per bearing the shipped whirl analysis (orchestrator.results.whirl
analyze_journal, defaults: 16-revolution windows), then at each listed journal speed (means
over +-1 Hz of ramp) the ring speed ratio, inner and outer eccentricity (mean and max), the
friction power, and the dominant sub-synchronous order of the journal (0.15-0.85 band, the
window nearest that speed) with its amplitude / c_i, beside the film orders 0.5 (1 + ring
ratio) (inner-film whirl) and 0.5 ring ratio (outer-film whirl).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from orchestrator.results.run_directory import read_results
from orchestrator.results.whirl import analyze_journal, dominant_ratio, order_spectra

C_I = 1.372e-5
TWO_PI = 2 * np.pi


def main(run_dir, speeds="30,40,45,50,55,60,70,80,90,100,105"):
    cols = read_results(Path(run_dir) / "results.csv")
    t, om = cols["time"], cols["rotor.omega"]
    f = om / TWO_PI
    print(f"{run_dir}: t {t[0]:.4f} -> {t[-1]:.4f} s, {f[0]:.2f} -> {f[-1]:.2f} Hz, {t.size} rows")
    for b, st in (("bearing1", "1"), ("bearing2", "2")):
        x, y = cols[f"rotor.x_{st}"], cols[f"rotor.y_{st}"]
        r = analyze_journal(t, x, y, om, C_I, eps=cols[f"{b}.eps"])
        keys = ("whirl", "threshold_speed_hz", "threshold_snr", "onset_speed_hz", "vanish_speed_hz",
                "dominant_ratio", "ratio_range", "max_eps", "max_eps_speed_hz", "max_subsync_rel")
        print(b, {k: (round(r[k], 4) if isinstance(r.get(k), float) else r.get(k)) for k in keys})
        s = order_spectra(t, x + 1j * y, om)
        dom = dominant_ratio(s)
        sub = s.subsync_amplitude() / C_I
        sync = s.sync_amplitude() / C_I
        print(f"  {'Hz':>5} {'ring':>6} {'eps_i':>6} {'max':>5} {'eps_o':>6} {'max':>5} {'P[W]':>6} "
              f"{'order':>6} {'sub/c':>6} {'1x/c':>6} {'.5(1+r)':>7} {'.5r':>6}")
        for hz in (float(v) for v in speeds.split(",")):
            m = np.abs(f - hz) <= 1.0
            if m.sum() < 5:
                continue
            ratio = np.mean(cols[f"{b}.omega_ring"][m] / om[m])
            k = int(np.argmin(np.abs(s.speed_hz - hz))) if s.n_frames else None
            o, a, a1 = (dom[k], sub[k], sync[k]) if k is not None else (np.nan,) * 3
            print(f"  {hz:5.0f} {ratio:6.3f} {np.mean(cols[f'{b}.eps'][m]):6.3f} "
                  f"{np.max(cols[f'{b}.eps'][m]):5.2f} {np.mean(cols[f'{b}.eps_outer'][m]):6.3f} "
                  f"{np.max(cols[f'{b}.eps_outer'][m]):5.2f} {np.mean(cols[f'{b}.P_loss'][m]):6.2f} "
                  f"{o:6.3f} {a:6.3f} {a1:6.3f} {0.5 * (1 + ratio):7.3f} {0.5 * ratio:6.3f}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
