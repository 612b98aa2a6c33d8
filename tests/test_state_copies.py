"""Models whose class sets ``STATE_IS_COPY`` promise that ``get_state`` returns arrays and
values they do not keep: the FMU wrappers then store that state without a second deep copy
(fmu_common.slave.get_slave_state; it was 5 % of the main thread of a run-up with
discard retries, which saves every macro step). The promise is checked here: a state taken,
then more steps, and the state is still what it was."""

import copy
import math

import numpy as np
import pytest

from bearing_fmu.model import BearingModel, BearingParams
from rotor_fmu.jeffcott import JeffcottModel, JeffcottParams

C = 4.9e-3 * 2.8e-3
W = 2 * math.pi * 300.0


def _same(a, b):
    assert a.keys() == b.keys()
    for k in a:
        assert np.array_equal(np.asarray(a[k]), np.asarray(b[k])), k


@pytest.mark.parametrize("extra", [{"cavitation": 1}, {"cavitation": 0}])
def test_bearing_state_is_its_own_copy(extra):
    b = BearingModel(BearingParams(R=4.9e-3, B=7.84e-3, psi=2.8e-3, eta0=0.012, p0=1e5,
                                   p_feed=1e5, n_phi=24, n_z=8, groove_width=math.radians(15),
                                   **extra))
    assert BearingModel.STATE_IS_COPY
    b.initialize(0.3 * C, -0.2 * C, 0.0, 0.0, W, init="stationary")
    for k in range(3):
        b.step(1e-4, 0.3 * C, -0.2 * C + 1e-3 * C * k, 0.0, 1e-3 * C / 1e-4, W)
    s = b.get_state()
    kept = copy.deepcopy(s)
    for k in range(3, 8):
        b.step(1e-4, 0.3 * C + 2e-3 * C * k, -0.2 * C, 2e-3 * C / 1e-4, 0.0, W)
    _same(s, kept)


def test_rotor_state_is_its_own_copy():
    r = JeffcottModel(JeffcottParams(initial_sag=False, journal_x0=2e-6))
    assert JeffcottModel.STATE_IS_COPY
    r.initialize()
    s = r.get_state()
    kept = copy.deepcopy(s)
    for _ in range(5):
        r.step(1e-4, np.array([1.0, -2.0, 0.5, 3.0]))
    _same(s, kept)
