"""Stability thresholds quoted in docs/rotor-models.md (short pi-film bearings, linear).

Run:  cd /work/main && nice -n 10 .venv/bin/python benchmarks/bench_rotor_stability.py
"""

import numpy as np

from rotor_fmu.jeffcott import JeffcottParams, JeffcottModel
from rotor_fmu.stability import (bearing_radius_for_threshold, lund_threshold_speed,
                                 short_bearing_coefficient_fn, static_bearing_loads,
                                 threshold_speed)
from rotor_fmu.turbocharger import TurbochargerRotor


def main():
    R = 0.02
    brg = dict(R=R, L=1.6 * R, C=2.8e-3 * R, eta=0.012)
    hz = lambda w: w / (2 * np.pi)
    for label, kw, ks in (("near-rigid", dict(k_shaft=1e11), None), ("Jeffcott 4000 N/mm", {}, 2e6)):
        p = JeffcottParams(d_external=0.0, d_internal=0.0, m_journal=1e-3, **kw)
        r = JeffcottModel(p)
        wt, nu = threshold_speed(r, short_bearing_coefficient_fn(r, **brg))
        wl = lund_threshold_speed((p.m_disc + 2 * p.m_journal) / 2, k_shaft=ks, **brg)
        print(f"{label:22s} eigen {hz(wt):9.3f} Hz  Lund {hz(wl):9.3f} Hz  whirl ratio {nu / wt:.3f}")
    r = JeffcottModel()
    wt, nu = threshold_speed(r, short_bearing_coefficient_fn(r, **brg))
    print(f"{'paper Jeffcott R=20mm':22s} eigen {hz(wt):9.3f} Hz  whirl ratio {nu / wt:.3f}")
    Rt = bearing_radius_for_threshold(JeffcottModel, 256.0, R_lo=0.003, R_hi=0.01)
    print(f"paper Jeffcott: R for a 256 Hz onset = {Rt * 1e3:.3f} mm")
    t = TurbochargerRotor()
    print("turbocharger static bearing loads [N]:", static_bearing_loads(t).round(3).tolist())
    R49 = 4.9e-3     # the scenarios' bearing (the rotor file has 9.8 mm journals)
    wt, nu = threshold_speed(t, short_bearing_coefficient_fn(t, R=R49, L=1.6 * R49, C=2.8e-3 * R49, eta=0.012),
                             omega_max=2 * 3.141592653589793 * 300.0)
    print(f"turbocharger R=4.9mm: eigen {hz(wt):9.3f} Hz  whirl ratio {nu / wt:.3f} "
          f"(40 x 40 HS film: docs/turbocharger_threshold.py)")


if __name__ == "__main__":
    main()
