"""Choose the bearing radius R of the paper's run-ups by linear stability (docs/paper-cases.md).

The paper gives B/R = 1.6, psi = 2.8e-3, eta0 = 12 mPa s, p0 = 1 bar and the
rotor, but not R. We pick R so that the half-Sommerfeld (HS) Jeffcott rotor
loses stability near the paper's onset (640 ms of the 0 -> 800 Hz ramp in 2 s,
i.e. 256 Hz):

1. at each speed, the static equilibrium of a journal under its share of the
   weight, (m_disc / 2 + m_journal) g, on the HS film of
   :class:`bearing_fmu.model.BearingModel` (40 x 40, Newton on x, y:
   :func:`bearing_fmu.linearize.hs_static_equilibrium`);
2. the eight linear film coefficients by central differences of the HS force
   (K = -dF/dq, D = -dF/dv);
3. the Jeffcott rotor's M, C, K (:meth:`rotor_fmu.jeffcott.JeffcottModel.system_matrices`)
   plus the film coefficients at both journals; the largest real part of the
   eigenvalues of the first-order system decides stability;
4. the threshold speed by bisection on that sign, and R by bisection on the
   threshold.

Run: ``.venv/bin/python docs/paper_cases_radius.py [--target-hz 256] [--n 40]``
(about a minute). Prints a table of threshold speed against R.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

PSI, ETA0, P0 = 2.8e-3, 0.012, 1.0e5


def hs_bearing(R: float, n: int):
    from bearing_fmu.model import BearingParams, BearingModel
    b = BearingModel(BearingParams(R=R, B=1.6 * R, psi=PSI, eta0=ETA0, p0=P0, p_feed=P0,
                                     n_phi=n, n_z=n, cavitation=0, axial_bc=0))
    b.initialize(0.0, -0.5 * PSI * R, 0.0, 0.0, 1.0)
    return b


def film_force(b, x, y, vx, vy, omega) -> np.ndarray:
    b.step(1e-6, x, y, vx, vy, omega)        # half-Sommerfeld: evaluation at the kinematics
    return np.array([b.outputs["Fx"], b.outputs["Fy"]])


def equilibrium(b, load: float, omega: float, guess=(0.3, -0.5)) -> np.ndarray:
    """Journal centre (x, y) [m] where the film carries ``load`` [N] upwards: Newton from
    ``guess`` [c] (:func:`bearing_fmu.linearize.hs_static_equilibrium`, the one HS static
    equilibrium of the repository; raises its ``HSEquilibriumError``, a RuntimeError, when it
    finds none)."""
    from bearing_fmu.linearize import hs_static_equilibrium
    return hs_static_equilibrium(b, (0.0, load), omega, guess=np.asarray(guess, float) * b.c)


def coefficients(b, q, omega):
    """Stiffness K = -dF/dq [N/m] and damping D = -dF/dv [N s/m] (2 x 2)."""
    c = b.c
    K, D = np.empty((2, 2)), np.empty((2, 2))
    for j in range(2):
        e = np.zeros(2)
        e[j] = 1e-5 * c
        K[:, j] = -(film_force(b, *(q + e), 0.0, 0.0, omega) - film_force(b, *(q - e), 0.0, 0.0, omega)) / (2 * e[j])
        v = np.zeros(2)
        v[j] = 1e-5 * c * max(omega, 1.0)
        D[:, j] = -(film_force(b, *q, *v, omega) - film_force(b, *q, *(-v), omega)) / (2 * v[j])
    return K, D


def max_real_part(rotor, b, omega, state) -> float:
    p = rotor.params
    load = (0.5 * p.m_disc + p.m_journal) * p.g
    state["q"] = equilibrium(b, load, omega, guess=state.get("q", np.array([0.3, -0.5]) * b.c) / b.c)
    K_b, D_b = coefficients(b, state["q"], omega)
    M, C, K = rotor.system_matrices(omega)
    for ix, iy in rotor.bearing_dofs:
        idx = np.ix_([ix, iy], [ix, iy])
        K[idx] += K_b
        C[idx] += D_b
    n = M.shape[0]
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ K, -Mi @ C]])
    lam = np.linalg.eigvals(A)
    i = int(np.argmax(lam.real))
    state["whirl_hz"] = abs(lam[i].imag) / (2 * math.pi)
    state["eps"] = float(np.hypot(*state["q"]) / b.c)
    return float(lam[i].real)


ROTOR = {"m_disc": 5.0, "m_journal": 0.5}    # as in scenarios/jeffcott_runup_*.yaml


def threshold_hz(R: float, n: int = 40, f_lo: float = 20.0, f_hi: float = 800.0, df: float = 20.0):
    """Lowest speed [Hz] at which the HS Jeffcott rotor is linearly unstable (None if stable up to f_hi)."""
    from rotor_fmu.jeffcott import JeffcottParams, JeffcottModel
    rotor = JeffcottModel(JeffcottParams(**ROTOR))
    b = hs_bearing(R, n)
    state: dict = {}
    prev = f_lo
    for f in np.arange(f_lo, f_hi + 1e-9, df):
        if max_real_part(rotor, b, 2 * math.pi * f, state) > 0:
            lo, hi = prev, f
            for _ in range(12):
                mid = 0.5 * (lo + hi)
                if max_real_part(rotor, b, 2 * math.pi * mid, state) > 0:
                    hi = mid
                else:
                    lo = mid
            max_real_part(rotor, b, 2 * math.pi * hi, state)
            return hi, state["eps"], state["whirl_hz"]
        prev = f
    return None, state.get("eps"), state.get("whirl_hz")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--target-hz", type=float, default=256.0)
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--radii", type=str, default="0.003,0.004,0.005,0.006,0.008,0.010,0.020")
    ap.add_argument("--m-disc", type=float, default=ROTOR["m_disc"])
    ap.add_argument("--m-journal", type=float, default=ROTOR["m_journal"])
    args = ap.parse_args(argv)
    ROTOR.update(m_disc=args.m_disc, m_journal=args.m_journal)
    print(f"Jeffcott rotor: m_disc = {args.m_disc} kg, m_journal = {args.m_journal} kg; HS film {args.n} x {args.n}\n")
    print(f"| R [mm] | HS threshold [Hz] | eps at threshold | whirl frequency [Hz] |")
    print("|---|---|---|---|")
    rows = []
    for R in [float(r) for r in args.radii.split(",")]:
        f, eps, fw = threshold_hz(R, args.n)
        rows.append((R, f))
        print(f"| {R * 1e3:.2f} | {f if f is None else round(f, 1)} | {eps:.3f} | {fw:.1f} |", flush=True)
    # bisection on R for the target (threshold decreases with R)
    good = [(R, f) for R, f in rows if f is not None]
    above = [R for R, f in good if f >= args.target_hz]
    below = [R for R, f in good if f < args.target_hz]
    if above and below:
        lo, hi = max(above), min(below)
        for _ in range(8):
            mid = 0.5 * (lo + hi)
            f, eps, fw = threshold_hz(mid, args.n)
            if f is not None and f >= args.target_hz:
                lo = mid
            else:
                hi = mid
        f, eps, fw = threshold_hz(0.5 * (lo + hi), args.n)
        print(f"\nR for a {args.target_hz:g} Hz HS threshold: {0.5 * (lo + hi) * 1e3:.3f} mm "
              f"(threshold {f:.1f} Hz, eps {eps:.3f}, whirl {fw:.1f} Hz)")


if __name__ == "__main__":
    main()
