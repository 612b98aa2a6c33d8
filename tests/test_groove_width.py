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
    with the groove at its true width Fy changes by < 0.3 % from 20 to 80 cells (measured
    26.273 / 26.338 / 26.289 N, and 26.264 N at 160; whole columns: 24.21 / 24.93 / 26.37,
    +8.9 %). NOT the issue's monotone order >= 1.5: the remaining 0.2 % is not monotone
    (docs/bearing-validation.md, 'Groove of its true width')."""
    f = [_air_fy(n) for n in (20, 40, 80)]
    assert max(f) / min(f) - 1 < 0.003
