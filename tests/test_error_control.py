"""Error norm and PI macro-step controller (orchestrator/coupling/error_control.py)."""

import math

import numpy as np
import pytest

from orchestrator.coupling.error_control import (
    ALPHA, BETA, PIController, next_stop, scaled_error_norm)


def test_scaled_error_norm_is_the_rms_of_errors_over_atol_plus_rtol_scale():
    pred = np.array([1.0, 10.0, 0.0])
    act = np.array([1.1, 10.0, 2e-6])
    prev = np.array([2.0, 5.0, 0.0])
    err, worst = scaled_error_norm(pred, act, prev, rtol=1e-2, atol=np.array([1e-3, 1e-3, 1e-6]))
    e = [0.1 / (1e-3 + 1e-2 * 2.0), 0.0, 2e-6 / (1e-6 + 1e-2 * 2e-6)]
    assert err == pytest.approx(math.sqrt(sum(x * x for x in e) / 3), rel=1e-12)
    assert worst == 0
    inf_err, i = scaled_error_norm(pred, np.array([1.0, math.nan, 0.0]), prev, rtol=1e-2, atol=np.ones(3))
    assert inf_err == math.inf and i == 1


@pytest.mark.parametrize("p", [1, 2, 3])
def test_pi_controller_settles_where_its_fixed_point_says(p):
    """With err(H) = (H / H0)^p the PI controller's steady state satisfies
    safety * err^(-(alpha - beta)/p) = 1, i.e. err* = safety^(p/(alpha - beta))."""
    c = PIController(order=p, min_step=1e-9, max_step=1.0)
    h0 = 1e-3
    h = 1e-5
    for _ in range(200):
        d = c.decide(h, (h / h0) ** p)
        h = d.h_next
    err = (h / h0) ** p
    assert err == pytest.approx(0.9 ** (p / (ALPHA - BETA)), rel=1e-3)
    assert c.rejected == 0


def test_the_order_of_one_decision_can_be_given():
    """``decide(..., order=q)`` is the decision of a controller of order q: a first-order
    controller told the order of a second-order error each time takes the step sequence of the
    second-order controller, bit for bit (ErrorControlled passes the order of the signal that
    limits the step, an interface-Jacobian force's 2 where the norm also holds first-order
    kinematics)."""
    told = PIController(order=1, min_step=1e-9, max_step=1.0)
    second = PIController(order=2, min_step=1e-9, max_step=1.0)
    h1 = h2 = 1e-5
    for _ in range(60):
        d1, d2 = told.decide(h1, (h1 / 1e-3) ** 2, order=2), second.decide(h2, (h2 / 1e-3) ** 2)
        assert (d1.accept, d1.h_next) == (d2.accept, d2.h_next)
        h1, h2 = d1.h_next, d2.h_next
    assert told.p == 1                   # the controller's own order is unchanged


def test_rejection_shrinks_the_step_and_the_next_step_does_not_grow():
    c = PIController(order=2, min_step=1e-9, max_step=1.0)
    d = c.decide(1e-2, 100.0)
    assert not d.accept and d.h_next == pytest.approx(1e-2 * max(0.2, 0.9 * 100.0 ** -0.5))
    d2 = c.decide(d.h_next, 1e-6)        # tiny error right after a rejection: accept, but no growth
    assert d2.accept and d2.h_next <= d.h_next
    d3 = c.decide(d2.h_next, 1e-6)       # afterwards growth is allowed again, up to fac_max
    assert d3.h_next == pytest.approx(5.0 * d2.h_next)
    assert c.rejected == 1


def test_limits_and_forced_acceptance_at_min_step():
    c = PIController(order=1, min_step=1e-4, max_step=1e-2)
    assert c.decide(1e-2, 0.0).h_next == 1e-2                  # capped at max_step
    d = c.decide(1e-4, 50.0)                                    # cannot go lower: accept, count
    assert d.accept and d.forced and d.h_next == 1e-4 and c.forced == 1
    d = c.decide(2e-4, 50.0)
    assert not d.accept and d.h_next == 1e-4                    # rejected, clipped at min_step


def test_a_step_stretched_onto_an_output_time_at_min_step_is_not_rejected_for_ever():
    """next_stop stretches a step by up to 1e-3 h onto an output time: at min_step the retry would be
    the same stretched step, rejected again (an endless loop before the rejection limit found it)."""
    c = PIController(order=1, min_step=1e-7, max_step=1e-2)
    t_out = 0.0032
    t = t_out - 1.0000001e-7
    t_end, on_out = next_stop(t, 1e-7, lambda _t: t_out)
    assert on_out and t_end - t > 1e-7
    d = c.decide(t_end - t, 4.7)
    assert d.accept and d.forced


def test_without_state_restore_the_controller_never_rejects():
    c = PIController(order=2, min_step=1e-9, max_step=1.0, can_reject=False)
    d = c.decide(1e-2, 1e3)
    assert d.accept and not d.forced and d.h_next == pytest.approx(2e-3)     # fac_min
    assert c.rejected == 0


def test_bad_limits_raise():
    with pytest.raises(ValueError, match="min_step"):
        PIController(order=1, min_step=1e-2, max_step=1e-3)
    with pytest.raises(ValueError, match="order"):
        PIController(order=0, min_step=1e-3, max_step=1e-2)


def test_next_stop_lands_on_the_output_grid():
    grid = lambda t: (math.floor(t / 0.1 + 1e-9) + 1) * 0.1      # noqa: E731
    assert next_stop(0.0, 0.03, grid) == (0.03, False)
    assert next_stop(0.09, 0.03, grid) == (pytest.approx(0.1), True)
    t, on = next_stop(0.07, 0.029999, grid)                    # would stop 1e-6 short: stretched
    assert on and t == pytest.approx(0.1)
    assert next_stop(0.07, 0.0299, grid)[1] is False           # 3e-3 short: not stretched


def test_a_jump_that_no_step_resolves_is_accepted():
    """err independent of h (a discontinuous signal): one rejection, then the smaller retry whose
    error did not shrink is accepted as a jump instead of shrinking to min_step."""
    c = PIController(order=2, min_step=1e-9, max_step=1.0)
    d = c.decide(1e-3, 50.0)
    assert not d.accept
    assert c.decide(d.h_next * 0.5, 0.5).accept           # closing in: a step short of the jump passes
    d2 = c.decide(d.h_next * 0.5, 45.0)                   # the next one across it fails as badly
    assert d2.accept and d2.jump and c.jumps == 1 and c.forced == 0
    # an error that does shrink with the step is an ordinary rejection sequence
    c = PIController(order=2, min_step=1e-9, max_step=1.0)
    d = c.decide(1e-3, 50.0)
    d2 = c.decide(d.h_next, 50.0 * (d.h_next / 1e-3) ** 2)
    assert not d2.jump
    c = PIController(order=2, min_step=1e-9, max_step=1.0)    # mild rejections never look like jumps
    d = c.decide(1e-3, 1.7)
    assert not c.decide(d.h_next, 1.05).jump
    c = PIController(order=2, min_step=1e-9, max_step=1.0)    # nor a stiffness limit (err ~ 1 at any h)
    d = c.decide(1e-3, 1.4)
    for _ in range(6):
        d = c.decide(d.h_next * 0.8, 1.3)
        assert not d.jump
