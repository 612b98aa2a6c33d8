"""The feed groove of its true angular width on any grid (bearing_fmu.grid.groove_weights,
issue 16): the column widths, the held strip, and the free-to-air film force nearly grid-independent (it diverged
with whole groove columns: Fy 24.21, 24.93, 26.37 N on 20/40/80, docs/runups.md 3.1)."""

import math

import numpy as np
import pytest

from bearing_fmu.grid import groove_columns, groove_weights, make_grid
from bearing_fmu.model import BearingParams, BearingModel, solve_stationary

W15 = math.radians(15.0)


@pytest.mark.parametrize("n", [20, 37, 40, 80, 96])
@pytest.mark.parametrize("angle", [math.pi / 2, 0.0, 1.0])
def test_weights_hold_exactly_the_groove_width(n, angle):
    dphi = 2 * math.pi / n
    gr = groove_columns(n, W15, angle)
    phi_f, wrel, frel = groove_weights(n, W15, angle, gr)
    assert wrel.sum() * dphi == pytest.approx(2 * math.pi, rel=1e-12)
    assert wrel[gr].sum() * dphi == pytest.approx(W15, rel=1e-12)
    # the film ends at the groove edges: two faces moved there, at the centre distance d
    moved = np.flatnonzero(np.abs(phi_f - (dphi * np.arange(n) + 0.5 * dphi)) > 1e-12)
    edges = {round((angle - W15 / 2) % (2 * math.pi), 9), round((angle + W15 / 2) % (2 * math.pi), 9)}
    assert {round(v % (2 * math.pi), 9) for v in phi_f[moved]} <= edges
    assert np.all((frel > 0) & (frel <= 1.0 + 1e-12)) and np.all(wrel[~gr] <= 1.5 + 1e-12)


def test_without_groove_the_grid_is_unchanged():
    g = make_grid(40, 40, 0.0, 0.0, true_groove=True)
    assert g.wrel is None and g.frel is None and g.phi_f is None


def _air_fy(n):
    p = BearingParams(R=4.9e-3, B=7.84e-3, n_phi=n, n_z=n, cavitation=1, axial_bc=1,
                      groove_width=W15, groove_angle=math.pi / 2)
    return solve_stationary(p, 2.547003e-06, -4.683927e-07, 2 * math.pi * 250).outputs["Fy"]


@pytest.mark.slow
def test_free_to_air_force_grid_spread_small():
    """Jeffcott run-up bearing, free to air, 15 deg groove, 250 Hz equilibrium (eps 0.19):
    with the groove at its true width and the groove exit flux of film.groove_exit, Fy
    changes by < 0.3 % from 20 to 80 cells and decreases monotonically (measured 26.2602 /
    26.2334 / 26.2220 N, 26.2250 N at 160; before groove_exit 26.273 / 26.338 / 26.289, not
    monotone; whole columns: 24.21 / 24.93 / 26.37, +8.9 %). The issue's order >= 1.5 is NOT
    met (order 1.24 on 20/40/80, the 160 value 0.01 % back up; docs/bearing-validation.md)."""
    f = [_air_fy(n) for n in (20, 40, 80)]
    assert max(f) / min(f) - 1 < 0.003
    assert f[0] > f[1] > f[2]


def _air_fy_rotated(n, alpha):
    """Fy of the same physical problem on a grid shifted by alpha: groove and journal rotated
    by alpha, the force rotated back (docs/scripts/groove_cut_study.py)."""
    p = BearingParams(R=4.9e-3, B=7.84e-3, n_phi=n, n_z=n, cavitation=1, axial_bc=1,
                      groove_width=W15, groove_angle=math.pi / 2 + alpha)
    x0, y0 = 2.547003e-06, -4.683927e-07
    ca, sa = math.cos(alpha), math.sin(alpha)
    o = solve_stationary(p, ca * x0 - sa * y0, sa * x0 + ca * y0, 2 * math.pi * 250).outputs
    return -sa * o["Fx"] + ca * o["Fy"]


def test_free_to_air_force_does_not_depend_on_where_the_grid_cuts_the_groove():
    """n = 40, the groove edge at 0.1 / 0.3 / 0.5 of the west film cell (east edge 0.23 /
    0.03 / 0.83 dphi from its cell centre): the film cell downstream of the groove is in the
    partly filled, advection-dominated film, and its two-point flux to the groove over the
    centre distance d fed a cut-dependent supply into the cavity (Fy spread 1.79 % over
    0.1 ... 0.9, +1.1 % at 0.3). With film.groove_exit (distance to the outflow face) the
    spread is 0.08 % (docs/scripts/groove_cut_study.py frac)."""
    dphi = 2 * math.pi / 40
    f = [_air_fy_rotated(40, math.radians(81.0) + c * dphi - (math.pi / 2 - W15 / 2))
         for c in (0.1, 0.3, 0.5)]
    assert max(f) / min(f) - 1 < 0.002
