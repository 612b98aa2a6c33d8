"""The Floquet growth rate of docs/scripts/turbocharger_unbalance_floquet.py, and the finding it
documents (docs/runups.md section 4, "Why the HS run-ups cross below the linear threshold"): the
turbocharger's half-speed whirl of the lightly loaded compressor-side journal is parametrically
excited by a synchronous orbit of that journal, so its growth rate lies far above the eigenvalue
of the static equilibrium.

About 8 s (the 40 x 40 HS films of the seeded scenario, 3 x 48 linearisations and exponentials)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs" / "scripts"))
fl = pytest.importorskip("turbocharger_unbalance_floquet")

SCENARIO = str(Path(__file__).resolve().parents[1] / "scenarios" / "turbocharger_runup_half_sommerfeld_seeded.yaml")
C = 1.372e-5            # clearance psi R [m]


@pytest.fixture(scope="module")
def model():
    fn, system = fl.linear_model(SCENARIO)
    w = 2 * math.pi * 57.0
    re, _ = fn.max_re(w)           # also sets each journal's static equilibrium fn.q at 57 Hz
    return fn, system, w, re, [q.copy() for q in fn.q]


def _orbits(q, radius):
    """A forward circle of ``radius`` c (1x) at station 1 about its static equilibrium; station 2 at
    its equilibrium."""
    (q1, q2) = q
    return [(q1[0], q1[1], [radius * C, 0.0, 0.0, 0.0], [0.0, radius * C, 0.0, 0.0]),
            (q2[0], q2[1], [0.0] * 4, [0.0] * 4)]


def test_without_orbit_the_floquet_rate_is_the_eigenvalue(model):
    fn, system, w, re, q = model
    sigma, _ = fl.floquet_rate(fn, system.rotor, _orbits(q, 0.0), w)
    assert re == pytest.approx(0.202, abs=0.01)           # linear threshold 56.59 Hz: just unstable at 57 Hz
    assert sigma == pytest.approx(re, abs=1e-6)


def test_a_synchronous_orbit_excites_the_half_speed_whirl(model):
    # measured: +2.24 / +3.58 1/s for 0.0125 / 0.025 c (the run-up's own orbit at 57 Hz, 0.023 x
    # 0.025 c: +3.53-3.60; the constant-speed run's growth rate +4.0 with its orbit of 0.028 c),
    # multiplier real and near -1: the principal parametric resonance (whirl at half the speed of
    # the 1x modulation of the film coefficients)
    fn, system, w, re, q = model
    half, _ = fl.floquet_rate(fn, system.rotor, _orbits(q, 0.0125), w)
    full, mu = fl.floquet_rate(fn, system.rotor, _orbits(q, 0.025), w)
    assert re + 1.5 < half < full - 0.8
    assert 3.0 < full < 4.2
    assert mu.imag == 0.0 and -1.1 < mu.real < -1.0
