"""Linear half-Sommerfeld stability of the turbocharger rotor on the paper's bearings
(docs/rotor-models.md, "Turbocharger rotor"; docs/paper-cases.md).

Method (the same as docs/paper_cases_radius.py for the Jeffcott rotor, with both
stations carrying their own static load):

1. the static bearing loads of the rotor file under gravity
   (:func:`rotor_fmu.stability.static_bearing_loads`, stations held at 0);
2. at each speed, the static equilibrium of each journal under its load on the HS
   film of :class:`bearing_fmu.model.BearingModel` (R = 4.9 mm, B = 1.6 R,
   psi = 2.8e-3, eta0 = 12 mPa s, 40 x 40; Newton on x, y,
   :func:`bearing_fmu.linearize.hs_static_equilibrium` via ``paper_cases_radius.equilibrium``);
3. the eight film coefficients of each journal by central differences
   (K = -dF/dq, D = -dF/dv);
4. the rotor's M, C + omega G, K (:meth:`TurbochargerRotor.system_matrices`, the
   Craig-Bampton model the FMU integrates, or the full FE model with ``--full``) plus the
   film coefficients at the bearing stations; the largest real part of the eigenvalues
   of the first-order system decides stability;
5. the threshold by a scan (``--df``) and bisection in speed.

Also printed: the undamped natural frequencies of the rotor on rigid supports
(pinned bearing stations) and the damped eigenvalues with the films at a few speeds.

Run: ``.venv/bin/python docs/turbocharger_threshold.py [--rotor-file F] [--full]``
(about a minute).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from paper_cases_radius import coefficients, equilibrium, hs_bearing  # noqa: E402

R_PAPER = 4.9e-3


def make_rotor(rotor_file=None, full=False):
    from rotor_fmu.turbocharger import TurbochargerParams, TurbochargerRotor
    return TurbochargerRotor(TurbochargerParams(rotor_file=rotor_file, reduce=not full))


def film_matrices(rotor, bearings, omega, state):
    """Film (K, D) per station at the HS equilibrium under the static loads."""
    from rotor_fmu.stability import static_bearing_loads
    loads = static_bearing_loads(rotor)          # force the rotor puts on the bearing
    out = []
    for j, b in enumerate(bearings):
        ld = -loads[j]                           # the film must carry the opposite
        assert abs(ld[0]) < 1e-9 * abs(ld[1])
        guess = state.get(("q", j), np.array([0.3, -0.5]) * b.c) / b.c
        q = equilibrium(b, float(ld[1]), omega, guess=guess)
        state[("q", j)] = q
        state[("eps", j)] = float(np.hypot(*q) / b.c)
        out.append(coefficients(b, q, omega))
    return out


def eigen(rotor, bearings, omega, state):
    M, C, K = rotor.system_matrices(omega)
    for (ix, iy), (Kb, Db) in zip(rotor.bearing_dofs, film_matrices(rotor, bearings, omega, state)):
        idx = np.ix_([ix, iy], [ix, iy])
        K[idx] += Kb
        C[idx] += Db
    n = M.shape[0]
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ K, -Mi @ C]])
    lam, V = np.linalg.eig(A)
    return lam, V


def max_real(rotor, bearings, omega, state):
    lam, V = eigen(rotor, bearings, omega, state)
    i = int(np.argmax(lam.real))
    state["whirl_hz"] = abs(lam[i].imag) / (2 * math.pi)
    state["vec"] = V[:rotor.M.shape[0], i]
    return float(lam[i].real)


def threshold_hz(rotor, bearings, f_lo=5.0, f_hi=105.0, df=5.0):
    state: dict = {}
    prev = f_lo
    for f in np.arange(f_lo, f_hi + 1e-9, df):
        if max_real(rotor, bearings, 2 * math.pi * f, state) > 0:
            lo, hi = prev, f
            for _ in range(14):
                mid = 0.5 * (lo + hi)
                if max_real(rotor, bearings, 2 * math.pi * mid, state) > 0:
                    hi = mid
                else:
                    lo = mid
            max_real(rotor, bearings, 2 * math.pi * hi, state)
            return hi, state
        prev = f
    return None, state


def rigid_support_frequencies(rotor, omega=0.0, n=6):
    """Natural frequencies [Hz] with the bearing stations pinned (x, y held)."""
    M, C, K = rotor.system_matrices(omega)
    keep = np.setdiff1d(np.arange(M.shape[0]), np.ravel(rotor.bearing_dofs))
    M, G, K = M[np.ix_(keep, keep)], C[np.ix_(keep, keep)], K[np.ix_(keep, keep)]
    m = M.shape[0]
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((m, m)), np.eye(m)], [-Mi @ K, -Mi @ G]])
    lam = np.linalg.eigvals(A)
    f = np.sort(np.abs(lam.imag[lam.imag > 0])) / (2 * math.pi)
    return f[:n]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rotor-file", default=None)
    ap.add_argument("--full", action="store_true", help="full FE model instead of Craig-Bampton")
    ap.add_argument("--R", type=float, default=R_PAPER)
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--df", type=float, default=5.0)
    ap.add_argument("--equilibrium-hz", type=float, default=None,
                    help="also print the HS static equilibrium of both journals at this speed "
                         "(scenario journal_x0/y0 and journal_dx0_2/dy0_2)")
    args = ap.parse_args(argv)
    from rotor_fmu.stability import static_bearing_loads
    rotor = make_rotor(args.rotor_file, args.full)
    rd = rotor.rotor_def
    print(f"rotor: {rd.name} ({rd.source}); total mass {rd.total_mass():.4f} kg "
          f"(shaft {rd.shaft_mass():.4f} kg); n_dof {rotor.n_dof}")
    loads = static_bearing_loads(rotor)
    print("static bearing loads [N]:", ", ".join(f"{n}: {-l[1]:.2f}" for n, l in zip(rd.bearing_names, loads)))
    print("natural frequencies, bearing stations pinned, 0 Hz spin [Hz]:",
          " ".join(f"{f:.1f}" for f in rigid_support_frequencies(rotor, 0.0)))
    print("same at 105 Hz spin (backward/forward split) [Hz]:",
          " ".join(f"{f:.1f}" for f in rigid_support_frequencies(rotor, 2 * math.pi * 105)))
    bearings = [hs_bearing(args.R, args.n) for _ in rd.bearing_names]
    print(f"\nHS films R = {args.R * 1e3:.2f} mm, B = 1.6 R, psi = 2.8e-3, eta0 = 12 mPa s, {args.n} x {args.n}")
    print("| speed [Hz] | eps bearing1 / bearing2 | max Re(lambda) [1/s] | its frequency [Hz] | lowest damped modes [Hz] (damping ratio) |")
    print("|---|---|---|---|---|")
    state: dict = {}
    for f in (10, 20, 30, 40, 50, 60, 70, 80, 90, 105):
        w = 2 * math.pi * f
        lam, _ = eigen(rotor, bearings, w, state)
        i = int(np.argmax(lam.real))
        osc = lam[lam.imag > 1e-6]
        osc = osc[np.argsort(osc.imag)][:4]
        modes = ", ".join(f"{z.imag / (2 * math.pi):.1f} ({-z.real / abs(z):.3f})" for z in osc)
        print(f"| {f} | {state[('eps', 0)]:.3f} / {state[('eps', 1)]:.3f} | {lam[i].real:+.2f} | "
              f"{abs(lam[i].imag) / (2 * math.pi):.1f} | {modes} |", flush=True)
    if args.equilibrium_hz:
        st0: dict = {}
        film_matrices(rotor, bearings, 2 * math.pi * args.equilibrium_hz, st0)
        q1, q2 = st0[("q", 0)], st0[("q", 1)]
        print(f"\nHS equilibrium at {args.equilibrium_hz:g} Hz: bearing1 x = {q1[0]:.4e}, y = {q1[1]:.4e} m "
              f"(eps {st0[('eps', 0)]:.3f}); bearing2 x = {q2[0]:.4e}, y = {q2[1]:.4e} m (eps {st0[('eps', 1)]:.3f})")
        print(f"  scenario: journal_x0: {q1[0]:.4e}, journal_y0: {q1[1]:.4e}, "
              f"journal_dx0_2: {q2[0] - q1[0]:.4e}, journal_dy0_2: {q2[1] - q1[1]:.4e}")
    fth, st = threshold_hz(rotor, bearings, df=args.df)
    if fth is None:
        print("\nHS threshold: stable up to 105 Hz")
        return
    v = st["vec"]
    bx = [abs(v[ix]) for ix, _ in rotor.bearing_dofs]
    print(f"\nHS threshold: {fth:.2f} Hz (t = {fth / 105 * 7:.3f} s on the 0 -> 105 Hz / 7 s ramp); "
          f"whirl {st['whirl_hz']:.2f} Hz = {st['whirl_hz'] / fth:.3f} x speed; "
          f"eps {st[('eps', 0)]:.3f} / {st[('eps', 1)]:.3f}; "
          f"|x| of the mode at bearing1 : bearing2 = {bx[0] / max(bx):.2f} : {bx[1] / max(bx):.2f}")
    for j, name in enumerate(rd.bearing_names):
        print(f"  {name}: equilibrium at {fth:.2f} Hz x = {st[('q', j)][0]:.4e} m, y = {st[('q', j)][1]:.4e} m")


if __name__ == "__main__":
    main()
