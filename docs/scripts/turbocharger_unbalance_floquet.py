"""Why a turbocharger HS run-up goes unstable below the linear threshold: the growth rate of the
run's whirl against the eigenvalue of `rotorcosim stability`'s linear model and against the
Floquet exponent of the rotor linearised along the run's synchronous (unbalance) orbit
(docs/runups.md section 4, "Why the HS run-ups cross below the linear threshold").

    .venv/bin/python docs/scripts/turbocharger_unbalance_floquet.py RUN [--speeds F ...] [--journal J]
        [--orbit-scale S] [--n-per-rev N] [--scenario FILE]

RUN: a finished run of a turbocharger scenario with half-Sommerfeld JournalBearings (a run-up or a
constant-speed run, ``--set fmus.rotor.parameters.t_ramp=0``). Printed:

* per analysis frame of journal J (default 1), up to 62 Hz: the whirl's growth rate as the run's
  analysis computes it (``growth_rate(..., centres=True)`` of the ``growth_band`` amplitude,
  at the speed of its fit's mean time) and the largest real part of the linear model's eigenvalues
  there (the rotor with each film's HS coefficients at its static equilibrium, as
  ``rotorcosim stability --film hs``; ``--scenario``: the scenario that model is built from,
  default the ``scenario_file`` of RUN's summary.json; the unbalance, start position and
  ``--set`` overrides of the run do not enter it);
* at each of ``--speeds``: the journals' synchronous orbit in the run (harmonics 0, 1 and 2 of the
  shaft angle plus a linear drift, fitted over 10 revolutions centred there; an even number, so
  that a half-speed whirl averages out), and the largest Floquet growth rate ``ln|mu| f`` of the
  rotor at that constant speed with each film's HS coefficients taken along that orbit (its
  position and velocity at ``N`` points of a revolution, default 48; the monodromy matrix as
  the product of the exponentials of the frozen system). ``--orbit-scale`` multiplies the orbits'
  1x and 2x parts (0: the run's mean position, i.e. the eigenvalue there). A multiplier near -1
  is the principal parametric resonance: the whirl at exactly half the speed of the 1x modulation.

The Floquet rate is quasi-static (the orbit and the speed held over a revolution); it is the
growth rate the run approaches once the growing Floquet solution dominates its whirl.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import scipy.linalg as sla

TWO_PI = 2.0 * math.pi
F_TOP = 62.0        # frames listed up to this speed [Hz]


def linear_model(scenario_file: str):
    """(film model of `rotorcosim stability --film hs`, its System) for a scenario file."""
    from orchestrator import load_scenario
    from orchestrator.stability.films import film_model
    from orchestrator.stability.system import _static_loads, build_system
    system = build_system(load_scenario(scenario_file))
    _, _, total = _static_loads(system, None)
    return film_model(system, "hs", total), system


def film_coefficients(fn, j: int, x, y, vx, vy, omega):
    """(K, C) of station j's HS film at the kinematics (x, y, vx, vy), contact included as the
    FMU and `rotorcosim stability` add it."""
    from bearing_fmu.contact import contact_coefficients
    from bearing_fmu.linearize import hs_linearization
    m = fn.models[j]
    K, C = hs_linearization(m, x, y, vx, vy, omega)
    if m.params.contact:
        Kc, Cc = contact_coefficients(x, y, vx, vy, omega, **m.contact_kw)
        K, C = K + Kc, C + Cc
    return K, C


def floquet_rate(fn, rotor, orbits, omega: float, n_per_rev: int = 48, scale: float = 1.0):
    """(largest Floquet growth rate [1/s], its multiplier) of the rotor at constant speed ``omega``
    with each station's film linearised along a periodic orbit. ``orbits[j] = (mean_x, mean_y,
    hx, hy)``: station j's position [m] ``mean + scale * sum_m (h[2m-2] cos(m phi) + h[2m-1] sin(m phi))``
    over the shaft angle phi (m = 1, 2), its velocity the derivative at omega."""
    n = rotor.n_dof
    f = omega / TWO_PI
    dt = 1.0 / (f * n_per_rev)
    M, Cr, Kr = rotor.system_matrices(omega)
    Mi = np.linalg.inv(M)
    Phi = np.eye(2 * n)
    for k in range(n_per_rev):
        phi = omega * (k + 0.5) * dt
        K, Cm = Kr.copy(), Cr.copy()
        for j, (ix, iy) in enumerate(rotor.bearing_dofs):
            mx, my, hx, hy = orbits[j]
            kin = []
            for mean, h in ((mx, hx), (my, hy)):
                p = sum(h[2 * m - 2] * math.cos(m * phi) + h[2 * m - 1] * math.sin(m * phi) for m in (1, 2))
                v = sum(m * omega * (h[2 * m - 1] * math.cos(m * phi) - h[2 * m - 2] * math.sin(m * phi))
                        for m in (1, 2))
                kin.append((mean + scale * p, scale * v))
            Kb, Cb = film_coefficients(fn, j, kin[0][0], kin[1][0], kin[0][1], kin[1][1], omega)
            idx = np.ix_([ix, iy], [ix, iy])
            K[idx] += Kb
            Cm[idx] += Cb
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ K, -Mi @ Cm]])
        Phi = sla.expm(A * dt) @ Phi
    mu = np.linalg.eigvals(Phi)
    k = int(np.argmax(np.abs(mu)))
    return math.log(abs(mu[k])) * f, complex(mu[k])


def run_orbits(cols, n_stations: int, omega: float, n_revs: int = 10):
    """Each station's synchronous orbit in a run around the time it passes ``omega``: least squares
    of x and y over ``n_revs`` revolutions on (1, t - t_c, cos phi, sin phi, cos 2 phi, sin 2 phi);
    (mean_x, mean_y, hx, hy) per station (the means at t_c)."""
    from orchestrator.results.whirl import revolutions
    t, om = cols["time"], cols["rotor.omega"]
    r = revolutions(t, om)
    phi = TWO_PI * r
    tc = float(np.interp(omega, om, t)) if om[-1] > om[0] else float(t[len(t) // 2])
    rc = float(np.interp(tc, t, r))
    sel = (r >= rc - n_revs / 2) & (r < rc + n_revs / 2)
    B = np.array([np.ones(sel.sum()), t[sel] - tc]
                 + [g(m * phi[sel]) for m in (1, 2) for g in (np.cos, np.sin)]).T
    out = []
    for j in range(1, n_stations + 1):
        cx = np.linalg.lstsq(B, cols[f"rotor.x_{j}"][sel], rcond=None)[0]
        cy = np.linalg.lstsq(B, cols[f"rotor.y_{j}"][sel], rcond=None)[0]
        out.append((cx[0], cy[0], cx[2:], cy[2:]))
    return out


def run_growth_rates(cols, journal: int, clearance: float):
    """(speed [Hz] at each fit's mean time, growth rate [1/s]) of the run's analysis (default
    WhirlParams)."""
    from orchestrator.results.whirl import WhirlParams, growth_rate, order_spectra
    p = WhirlParams()
    t, om = cols["time"], cols["rotor.omega"]
    s = order_spectra(t, cols[f"rotor.x_{journal}"] + 1j * cols[f"rotor.y_{journal}"], om, p)
    fit_frames = 2 * max(int(round(p.growth_fit_revs / p.hop_revs / 2)), 1) + 1
    sigma, t_fit = growth_rate(s.t, s.band_amplitude(*p.growth_band) / clearance, fit_frames, centres=True)
    ok = np.isfinite(t_fit)
    return np.interp(t_fit[ok], t, om) / TWO_PI, sigma[ok]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run")
    ap.add_argument("--speeds", type=float, nargs="*", default=[])
    ap.add_argument("--journal", type=int, default=1)
    ap.add_argument("--orbit-scale", type=float, default=1.0)
    ap.add_argument("--n-per-rev", type=int, default=48)
    ap.add_argument("--scenario", default=None)
    a = ap.parse_args(argv)
    from orchestrator.results.run_directory import RunDirectory
    run = Path(a.run)
    import json
    fn, system = linear_model(a.scenario or json.loads((run / "summary.json").read_text())["scenario_file"])
    rotor = system.rotor
    c = system.bearings[a.journal - 1].params.psi * system.bearings[a.journal - 1].params.R
    cols = RunDirectory(run).columns()
    speeds, sigma = run_growth_rates(cols, a.journal, c)
    print(f"{run}: journal {a.journal}, growth rate of the run's analysis vs the linear model's eigenvalue")
    print("| speed [Hz] | run sigma [1/s] | eigenvalue Re [1/s] | difference |")
    print("|---|---|---|---|")
    for f, s in zip(speeds, sigma, strict=True):
        if f > F_TOP:
            break
        re = fn.max_re(TWO_PI * f)[0]
        print(f"| {f:.2f} | {s:+.2f} | {re:+.2f} | {s - re:+.2f} |", flush=True)
    if not a.speeds:
        return
    print(f"\nFloquet growth rate along the run's synchronous orbit (orbit scale {a.orbit_scale:g}, "
          f"{a.n_per_rev} points per revolution)")
    print("| speed [Hz] | journal eps: run mean (static equilibrium) | 1x orbit x, y / c | Floquet sigma [1/s] "
          "(multiplier) | eigenvalue Re [1/s] |")
    print("|---|---|---|---|---|")
    for f in a.speeds:
        w = TWO_PI * f
        orbits = run_orbits(cols, len(system.bearings), w)
        sF, mu = floquet_rate(fn, rotor, orbits, w, a.n_per_rev, a.orbit_scale)
        re = fn.max_re(w)[0]
        mx, my, hx, hy = orbits[a.journal - 1]
        q = fn.q[a.journal - 1]
        print(f"| {f:.2f} | {math.hypot(mx, my) / c:.4f} ({math.hypot(*q) / c:.4f}) | "
              f"{math.hypot(*hx[:2]) / c:.4f}, {math.hypot(*hy[:2]) / c:.4f} | {sF:+.2f} "
              f"({mu.real:+.4f}{mu.imag:+.4f}j) | {re:+.2f} |", flush=True)


if __name__ == "__main__":
    main()
