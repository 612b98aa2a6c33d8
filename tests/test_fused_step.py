"""The film's macro step in one numba call (bearing_fmu/fused.py, issue 16 speed part)
against the Python loop it replaces (``TransientFilm.fused = False``).

A short whirl orbit of the Jeffcott bearing on a coarse grid: free to air with the groove of
its true width, oil bath, whole-cell groove columns (no groove weights), the limited
second-order theta transport. The two paths do the same arithmetic apart from two sums
(fused.py module doc), so forces and the solver's counters must agree; the PIVOT return
(an LU that needs row interchanges) must hand the macro step to the Python loop, and a
step size below h_min must fail as the Python loop fails, with the state kept.
"""

import dataclasses

import numpy as np
import pytest

from bearing_fmu.model import BearingModel, BearingParams
from bearing_fmu.solver import StepFailed
from tests.test_simplified_newton import KW, orbit     # the same bearing and whirl orbit

COUNTERS = ("steps", "rejected", "newton", "factor", "failed_newton", "reused")


def run(use_fused, steps=30, pivot_threshold=None, **extra):
    b = BearingModel(BearingParams(**dict(KW, **extra)))
    b.film.fused = use_fused
    if pivot_threshold is not None:
        b.film.pivot_threshold = pivot_threshold
    b.initialize(*orbit(0), init="stationary")
    F = []
    for k in range(1, steps + 1):
        b.step(1e-4, *orbit(k))
        F.append((b.outputs["Fx"], b.outputs["Fy"]))
    return b, np.array(F)


@pytest.mark.parametrize("case", [
    {},                                            # free to air, groove of its true width
    {"axial_bc": 0},                               # oil bath
    {"groove_width": 0.0, "axial_bc": 0},          # no groove weights (wrel None)
    {"theta_transport": 1},                        # 7-point stencil (assemble_muscl)
])
def test_fused_macro_step_is_the_python_loop(case):
    loop, F_loop = run(False, **case)
    one, F_one = run(True, **case)
    assert not loop.film.fused_eligible() and one.film.fused_eligible()
    assert {k: one.stats[k] for k in COUNTERS} == {k: loop.stats[k] for k in COUNTERS}
    assert one.stats["steps"] > 30 and one.stats["newton"] > one.stats["steps"]
    np.testing.assert_allclose(F_one, F_loop, rtol=1e-10, atol=1e-10 * np.abs(F_loop).max())
    for name in ("u", "u_prev", "th_nm1", "th_nm2"):
        np.testing.assert_allclose(getattr(one.film, name), getattr(loop.film, name), rtol=1e-10,
                                   atol=1e-12)
    assert (one.film.h_prev, one.film.h_prev2, one.film.n_hist, one.film.t) == \
        pytest.approx((loop.film.h_prev, loop.film.h_prev2, loop.film.n_hist, loop.film.t), rel=1e-12)


def test_a_pivot_that_needs_interchanges_hands_the_step_to_the_python_loop():
    loop, F_loop = run(False, steps=8)
    handed, F_handed = run(True, steps=8, pivot_threshold=1e300)    # no pivot meets it
    # every solve went through the Python loop: the same path, so the same numbers bit for bit
    assert {k: handed.stats[k] for k in COUNTERS} == {k: loop.stats[k] for k in COUNTERS}
    assert np.array_equal(F_handed, F_loop)


def test_a_step_below_h_min_fails_as_the_loop_does_and_keeps_the_state():
    msgs = {}
    for use_fused in (False, True):
        b, _ = run(use_fused, steps=3)
        before = b.get_state()
        # no internal step is this long (a macro step is 1e-4 s)
        b.params = dataclasses.replace(b.params, h_min=1.0, h_init=1.0, h_max=1.0)
        with pytest.raises(StepFailed) as info:
            b.step(1e-4, *orbit(4))
        msgs[use_fused] = str(info.value)
        after = b.get_state()
        for key, v in before.items():
            assert np.array_equal(np.asarray(after[key]), np.asarray(v)), key
    assert "fell below h_min = 1 s" in msgs[True]
    assert msgs[True] == msgs[False]


@pytest.mark.parametrize("case", [{}, {"theta_transport": 1}])
def test_kept_p_theta_is_the_law_of_the_current_state(case):
    """The fused call keeps p(u), theta(u) of the state it accepted (the outputs use them
    instead of evaluating the law again): bit for bit the law's values, after a fused step,
    after a restore (set_state), after a PIVOT hand-over to the Python loop and after
    init_state; and what p_theta hands out is a copy (changing it changes no state)."""
    def same_as_law(b):
        p, th = b.film.p_theta()
        p_law, th_law = b.law.p_theta(b.film.u)
        assert np.array_equal(p, p_law) and np.array_equal(th, th_law)
        return p, th

    b, _ = run(True, steps=5, **case)
    assert b.film._pth_of is b.film.u               # kept from the fused call
    p, th = same_as_law(b)
    p[:] = -1.0
    th[:] = -1.0
    same_as_law(b)
    s = b.get_state()
    b.step(1e-4, *orbit(6))
    same_as_law(b)
    b.set_state(s)                                  # u rebound: evaluated, not kept
    assert b.film._pth_of is not b.film.u
    same_as_law(b)
    b.film.pivot_threshold = 1e300                  # the loop finishes the macro step
    b.step(1e-4, *orbit(6))
    same_as_law(b)
    b.film.init_state(b.film.u * 0.5)
    same_as_law(b)


@pytest.mark.parametrize("case", [{}, {"theta_transport": 1}])
def test_kept_exp_and_log1p_belong_to_the_current_u_and_u_prev(case):
    """The fused call keeps e = exp(-|u/delta|) and log1p(e) of u and u_prev across macro
    steps (dominant_extrapolate uses them). Wherever the film says they belong to its
    current arrays (``_el_of``), they must be solver.law_el of those arrays bit for bit:
    after fused steps, a restore (set_state), a BDF restart, a PIVOT hand-over to the
    Python loop and init_state; and the steps after each must stay those of the Python loop."""
    from bearing_fmu.solver import law_el

    def check(f):
        kept = 0
        for rows, arr, of in (((0, 1), f.u, f._el_of[0]), ((2, 3), f.u_prev, f._el_of[1])):
            if of is arr:
                e, l1 = np.empty(f.n), np.empty(f.n)
                law_el(arr, f.ctx.law.delta, e, l1)
                assert np.array_equal(f._el[rows[0]], e) and np.array_equal(f._el[rows[1]], l1)
                kept += 1
        return kept

    b, _ = run(True, steps=5, **case)
    ref, _ = run(False, steps=5, **case)
    assert check(b.film) == 2
    s = b.get_state()
    k = 6
    for change in ("step", "set_state", "restart", "pivot", "init_state"):
        for m in (b, ref):
            if change == "set_state":
                m.set_state(s)
            elif change == "restart":
                m.film.restart_history()
            elif change == "init_state":
                m.film.init_state(m.film.u * 0.999)
        if change == "pivot":
            b.film.pivot_threshold = 1e300             # the loop finishes this macro step
        check(b.film)
        for m in (b, ref):
            m.step(1e-4, *orbit(k))
        b.film.pivot_threshold = ref.film.pivot_threshold
        check(b.film)              # after the Python loop: nothing is claimed to be kept
        for m in (b, ref):
            m.step(1e-4, *orbit(k + 1))
        assert check(b.film) == 2
        np.testing.assert_allclose(b.film.u, ref.film.u, rtol=1e-10, atol=1e-12)
        k += 2


@pytest.mark.parametrize("where", ["advance", "outputs"])
@pytest.mark.parametrize("cavitation", [1, 0])
def test_a_step_that_raises_leaves_the_model_as_it_was(where, cavitation, monkeypatch):
    """BearingModel.step is a transaction (the FMU's fmi2Discard keeps no copy of its own):
    whatever raises, after the film advanced in place or while the outputs are formed, the
    state, inputs, time and outputs are those before the call, and the next step gives what
    it gives without the failed attempt."""
    def fresh():
        b = BearingModel(BearingParams(**dict(KW, cavitation=cavitation)))
        b.initialize(*orbit(0), init="stationary")
        for k in range(1, 4):
            b.step(1e-4, *orbit(k))
        return b

    b = fresh()
    s0, out0, t0, inp0 = b.get_state(), dict(b.outputs), b.t, b._inputs
    cls = type(b)
    if where == "advance" and cavitation:
        real = type(b.film).advance_restarting

        def half_then_fail(self, dt, kin, saved):
            real(self, dt, kin, saved)              # the film has moved on in place ...
            raise FloatingPointError("overflow in a kernel")   # ... and then the step fails
        monkeypatch.setattr(type(b.film), "advance_restarting", half_then_fail)
    else:
        def fail(self):
            raise FloatingPointError("invalid value in the outputs")
        monkeypatch.setattr(cls, "_update_outputs", fail)
    with pytest.raises(FloatingPointError):
        b.step(1e-4, *orbit(4))
    monkeypatch.undo()
    assert b.t == t0 and b._inputs == inp0 and b.outputs == out0
    s1 = b.get_state()
    assert s1.keys() == s0.keys()
    for k in s0:
        assert np.array_equal(np.asarray(s1[k]), np.asarray(s0[k])), k
    b.step(1e-4, *orbit(4))
    ref = fresh()
    ref.step(1e-4, *orbit(4))
    assert b.outputs == ref.outputs
