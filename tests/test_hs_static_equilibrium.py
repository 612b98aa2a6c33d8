"""bearing_fmu.linearize.hs_static_equilibrium: the one half-Sommerfeld static equilibrium (journal
at rest where the film force balances a static load), used by ``rotorcosim stability``, the docs
scripts and the floating ring's films.

References independent of its Newton iteration:
* the root found by MINPACK's hybrid method (scipy.optimize.root, its own finite-difference
  Jacobian) on the same force :func:`bearing_fmu.linearize.hs_force`;
* for a short bearing (B/D = 0.1) Ocvirk's closed-form equilibrium
  (:func:`rotor_fmu.stability.short_bearing_equilibrium`, Ocvirk 1952; Childs 1993 sec. 3.6),
  which the finite-length half-Sommerfeld film approaches as B/D -> 0.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import root

from bearing_fmu.linearize import HSEquilibriumError, hs_force, hs_static_equilibrium
from bearing_fmu.model import BearingModel, BearingParams

R, PSI, ETA = 4.9e-3, 2.8e-3, 0.012
C = R * PSI
OMEGA = 2 * math.pi * 250.0
LOAD = 29.43                      # (m_disc / 2 + m_journal) g of the paper's Jeffcott rotor


def bearing(**kw):
    base = dict(R=R, B=1.6 * R, psi=PSI, eta0=ETA, p0=1e5, p_feed=1e5, n_phi=40, n_z=40,
                cavitation=0, axial_bc=0)
    base.update(kw)
    return BearingModel(BearingParams(**base))


def test_balances_the_load_and_matches_an_independent_root_finder():
    b = bearing()
    q = hs_static_equilibrium(b, (0.0, LOAD), OMEGA)
    F = hs_force(b, *q, 0.0, 0.0, OMEGA)
    assert np.max(np.abs(F - [0.0, LOAD])) <= 1e-9 * LOAD
    assert q[0] > 0.0 > q[1]                        # below the centre, in the direction of rotation
    ref = root(lambda z: (hs_force(b, z[0] * C, z[1] * C, 0.0, 0.0, OMEGA) - [0.0, LOAD]) / LOAD,
               [0.3, -0.5], method="hybr", options={"xtol": 1e-12})
    assert ref.success
    assert q / C == pytest.approx(ref.x, abs=1e-8)
    # the same root from another start (default guess, and a start near the wall)
    for guess in (None, (-0.2 * C, -0.9 * C)):
        assert hs_static_equilibrium(b, (0.0, LOAD), OMEGA, guess=guess) / C == pytest.approx(ref.x, abs=1e-8)


def test_short_bearing_approaches_ocvirk():
    from rotor_fmu.stability import short_bearing_equilibrium
    B = 0.2 * R                                    # B/D = 0.1
    b = bearing(B=B, n_phi=120, n_z=20)
    load = 5.0
    q = hs_static_equilibrium(b, (0.0, load), OMEGA)
    eps, psi = short_bearing_equilibrium((0.0, -load), OMEGA, R=R, L=B, C=C, eta=ETA)
    assert math.hypot(*q) / C == pytest.approx(eps, rel=0.01)          # 0.857 vs 0.853
    assert math.atan2(q[1], q[0]) == pytest.approx(psi, abs=0.01)   # -1.119 vs -1.122 rad


def test_clear_errors():
    b = bearing()
    with pytest.raises(ValueError, match="nonzero"):
        hs_static_equilibrium(b, (0.0, 0.0), OMEGA)
    with pytest.raises(ValueError, match="max_iter must be at least 1"):      # was an UnboundLocalError
        hs_static_equilibrium(b, (0.0, LOAD), OMEGA, max_iter=0)
    with pytest.raises(ValueError, match="outside"):
        hs_static_equilibrium(b, (0.0, LOAD), OMEGA, guess=(0.0, -C))
    with pytest.raises(HSEquilibriumError, match="singular"):      # a film at rest carries nothing
        hs_static_equilibrium(b, (0.0, LOAD), 0.0)
    with pytest.raises(HSEquilibriumError, match="no journal position carries"):
        hs_static_equilibrium(b, (0.0, 1e6), OMEGA, max_iter=20)
