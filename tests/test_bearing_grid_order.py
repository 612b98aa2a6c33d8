"""Observed order of the spatial discretisation on the Jeffcott run-up bearing (issue 5,
numerical credibility; docs/bearing-validation.md "Grid convergence").

Bearing of scenarios/jeffcott_runup_half_sommerfeld.yaml (R = 4.9 mm, B = 1.6 R,
psi = 2.8e-3, eta0 = 12 mPa s, oil bath, no groove), journal at eps = 0.19 (the static
equilibrium at 250 Hz, near the linear threshold), the same position on every grid.
The finite-volume scheme is second order (two-point fluxes, exact face gaps, half-cell
Dirichlet edges), so force, dynamic coefficients and the linear stability threshold
must converge at order 2 on 40/80/160 cells. Before the half-Sommerfeld force located
the rupture inside the cells (film.hs_force_pressure) the coefficients converged
erratically (observed orders -0.8 ... 1.2, 40 x 40 errors up to 3.3 %): cells switching
in and out of the clipped region as the journal moves make the derivative of a
cell-resolution quadrature jump by O(h).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from bearing_fmu.linearize import linearization
from bearing_fmu.model import BearingParams, BearingModel

R = 4.9e-3
C = 2.8e-3 * R
OMEGA = 2 * math.pi * 250.0
X, Y = 2.547e-6, -4.684e-7          # HS static equilibrium at 250 Hz under 29.43 N (40 x 40)
GRIDS = (40, 80, 160)


def bearing(n):
    b = BearingModel(BearingParams(R=R, B=1.6 * R, psi=2.8e-3, eta0=0.012, p0=1e5, p_feed=1e5,
                                     n_phi=n, n_z=n, cavitation=0, axial_bc=0))
    b.initialize(X, Y, 0.0, 0.0, OMEGA)
    return b


def order(v):
    d1, d2 = v[0] - v[1], v[1] - v[2]
    return math.log2(d1 / d2) if d1 / d2 > 0 else float("nan")


@pytest.fixture(scope="module")
def values():
    out = []
    for n in GRIDS:
        b = bearing(n)
        K, Cd = linearization(b)
        out.append(dict(Fy=b.outputs["Fy"], kxx=K[0, 0], kxy=K[0, 1], kyx=K[1, 0], kyy=K[1, 1],
                        cxx=Cd[0, 0], cxy=Cd[0, 1], cyx=Cd[1, 0], cyy=Cd[1, 1]))
    return out


@pytest.mark.parametrize("name", ["Fy", "kxx", "kyx", "cxx", "cxy", "cyy"])
def test_hs_force_and_coefficients_second_order(values, name):
    """Observed order 2 (accepted 1.7 to 2.3) for the force and the coefficients whose
    error is not already at round-off level (kxy, cyx: 40 x 40 within 0.4 % of 160 x 160,
    no clean order; kyy order 2.5; all eight are checked for size below)."""
    p = order([v[name] for v in values])
    assert 1.7 < p < 2.3, (name, p, [v[name] for v in values])


def test_hs_coefficients_40_within_one_percent_of_160(values):
    """All eight coefficients at 40 x 40 within 1 % of 160 x 160 (measured <= 0.8 %;
    with the cell-resolution clip kxy, kyy, cxx, cxy were 2.6-3.6 % off)."""
    for name in ("kxx", "kxy", "kyx", "kyy", "cxx", "cxy", "cyx", "cyy"):
        a, b = values[0][name], values[2][name]
        assert abs(a - b) / abs(b) < 0.01, (name, a, b)


def test_hs_linear_threshold_second_order():
    """Linear HS stability threshold of the Jeffcott rotor (docs/paper_cases_radius.py)
    converges at order 2 (measured 256.10, 255.78, 255.70 Hz; Richardson 255.67 Hz)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs"))
    import paper_cases_radius as pcr
    th = [pcr.threshold_hz(R, n, f_lo=240.0, f_hi=280.0, df=20.0)[0] for n in GRIDS]
    p = order(th)
    assert 1.7 < p < 2.3, th
    rich = th[2] + (th[2] - th[1]) / (2 ** p - 1)
    assert abs(th[0] - rich) / rich < 0.005, th


def test_hs_force_quadrature_exact_for_linear_pressure():
    """film.hs_force_pressure integrates max(P, 0) exactly for P linear in phi (the
    zero crossing anywhere inside a cell); the cell-resolution clip does not."""
    from bearing_fmu.film import hs_force_pressure
    n, h = 64, 2 * math.pi / 64
    phi = h * np.arange(n)
    for phi_r in (1.0, 1.0 + 0.3 * h, 1.0 + 0.49 * h):
        P = (phi_r - phi)[None, :] * np.ones((2, 1))      # rupture at phi_r, falling P
        P[:, phi > 3.0] = -1.0                          # far side negative, away from phi_r
        P[:, phi < 0.2] = (phi_r - 0.2)                  # keep the wrap-around positive/flat
        out = np.empty_like(P)
        hs_force_pressure(P, out)
        sel = (phi > 0.5) & (phi < 2.0)                 # cells around the rupture only
        exact = 0.5 * (phi_r - (phi[sel][0] - 0.5 * h)) ** 2     # int of max(phi_r - phi, 0)
        assert np.sum(out[0, sel]) * h == pytest.approx(exact, rel=1e-12)
