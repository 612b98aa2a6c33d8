"""Lagrange predictors: exactness on polynomials, derivatives, history rollback."""

from __future__ import annotations

import numpy as np
import pytest

from orchestrator.coupling.signals import History, LagrangePredictor, lagrange_derivative_weights, lagrange_weights


def poly(c, t):
    return sum(ci * t ** i for i, ci in enumerate(c))


@pytest.mark.parametrize("k", [0, 1, 2, 3])
def test_lagrange_weights_reproduce_polynomials_up_to_degree_k(k):
    rng = np.random.default_rng(k)
    nodes = np.array([0.0, -1.0, -2.0, -3.0])[: k + 1]
    x = np.linspace(0.0, 1.0, 7)
    W = lagrange_weights(nodes, x)
    for deg in range(k + 1):
        c = rng.normal(size=deg + 1)
        assert np.allclose(W @ poly(c, nodes), poly(c, x), atol=1e-12)
    # and NOT a polynomial of degree k+1 (the test could fail if weights were of higher order)
    c = np.zeros(k + 2)
    c[-1] = 1.0
    assert not np.allclose(W @ poly(c, nodes), poly(c, x), atol=1e-6)
    # weights sum to one (constants reproduced)
    assert np.allclose(W.sum(axis=1), 1.0)


@pytest.mark.parametrize("k", [1, 2, 3])
def test_derivative_weights_exact(k):
    rng = np.random.default_rng(10 + k)
    nodes = np.array([1.0, 0.0, -1.0, -2.0])[: k + 1]
    c = rng.normal(size=k + 1)
    D = lagrange_derivative_weights(nodes, 0.25, 3)
    y = poly(c, nodes)
    # analytic derivatives of sum c_i s^i at s = 0.25
    for d in range(1, 4):
        dc = np.polynomial.polynomial.polyder(c, d) if d <= k else np.zeros(1)
        expect = np.polynomial.polynomial.polyval(0.25, dc)
        assert D[d - 1] @ y == pytest.approx(expect, abs=1e-10)


def make_history(values, times):
    """History whose past levels hold ``values`` at ``times`` (newest first)."""
    h = History()
    b = h.block(1)
    for t, v in zip(times[::-1], values[::-1]):
        b[0, 0] = v
        if h.count == 0 and np.isnan(h.times[1]):
            h.start(t)
        else:
            h.times[0] = t
            h.commit()
    return h, b


@pytest.mark.parametrize("k", [0, 1, 2, 3])
def test_predictor_extrapolates_polynomial_exactly_and_limits_order_at_start(k):
    H = 0.1
    c = [0.3, -1.0, 2.0, 0.5][: k + 1]
    times = [1.0 - j * H for j in range(4)]           # newest first: T(n) = 1.0
    h, b = make_history([poly(c, t) for t in times], times)
    pred = LagrangePredictor(extrapolation_order=k, interpolation_order=0)
    w = pred.weights(h, 1.0, H, 4)
    mids = 1.0 + (np.arange(4) + 0.5) / 4 * H
    got = w.extrap @ b[w.e0:w.e1, 0]
    assert np.allclose(got, poly(c, mids), atol=1e-10)
    assert w.extrap_end @ b[w.e0:w.e1, 0] == pytest.approx(poly(c, 1.0 + H), abs=1e-10)
    # derivative weights at the sub-step starts are exact too
    starts = 1.0 + np.arange(4) / 4 * H
    dpoly = np.polynomial.polynomial.polyder(c, 1) if k >= 1 else [0.0]
    for i, s in enumerate(starts):
        assert w.extrap_der[i][0] @ b[w.e0:w.e1, 0] == pytest.approx(
            np.polynomial.polynomial.polyval(s, dpoly), abs=1e-8)
    # start-up: with only 2 levels the order is limited to 1
    h2, b2 = make_history([poly(c, t) for t in times[:2]], times[:2])
    w2 = pred.weights(h2, 1.0, H, 1)
    assert w2.p == min(k, 1)


@pytest.mark.parametrize("q", [0, 1, 2, 3])
def test_interpolation_through_new_value_exact(q):
    H = 0.05
    c = [1.0, 0.5, -3.0, 4.0][: q + 1]
    times = [2.0 - j * H for j in range(4)]
    h, b = make_history([poly(c, t) for t in times], times)
    b[0, 0] = poly(c, 2.0 + H)                        # the new value at T(n+1)
    pred = LagrangePredictor(extrapolation_order=0, interpolation_order=q)
    w = pred.weights(h, 2.0, H, 3)
    mids = 2.0 + (np.arange(3) + 0.5) / 3 * H
    assert np.allclose(w.interp @ b[: w.q + 1, 0], poly(c, mids), atol=1e-10)
    assert w.interp_end @ b[: w.q + 1, 0] == pytest.approx(poly(c, 2.0 + H))


def test_history_snapshot_restore_and_nonuniform_times():
    h = History()
    b = h.block(2)
    b[0] = [1.0, 2.0]
    h.start(0.0)
    b[0] = [3.0, 4.0]
    h.times[0] = 0.1
    h.commit()
    snap = h.snapshot()
    b[0] = [9.0, 9.0]
    h.times[0] = 0.15                                 # a shorter (last) step
    h.commit()
    assert h.count == 3 and b[1, 0] == 9.0
    h.restore(snap)
    assert h.count == 2 and list(b[1]) == [3.0, 4.0] and list(b[2]) == [1.0, 2.0]
    # linear extrapolation over a non-uniform grid is still exact for lines
    pred = LagrangePredictor(extrapolation_order=1, interpolation_order=0)
    w = pred.weights(h, 0.1, 0.05, 1)
    # line through (0, 1) and (0.1, 3): value at 0.125 (midpoint) = 3.5
    assert w.extrap[0] @ b[w.e0:w.e1, 0] == pytest.approx(3.5)


def test_orders_are_validated():
    with pytest.raises(ValueError, match="0..3"):
        LagrangePredictor(extrapolation_order=4, interpolation_order=0)


def test_step_weights_reuse_the_previous_step_until_the_steps_change():
    """The master's hot path: same weights object while order and step sizes are unchanged."""
    from orchestrator.coupling.signals import History, LagrangePredictor
    h = History(4)
    h.allocate([1])
    h.start(0.0)
    p = LagrangePredictor(extrapolation_order=2, interpolation_order=1)
    for i in range(1, 4):
        h.times[0] = i * 0.1
        h.commit()
    h.times[0] = 0.4
    a = p.step_weights(h, 0.3, 0.1, 2)
    assert a is p.step_weights(h, 0.3, 0.1, 2) and a is p.weights(h, 0.3, 0.1, 2)
    h.commit()
    h.times[0] = 0.5
    assert p.step_weights(h, 0.4, 0.1, 2) is a              # constant steps: nothing recomputed
    h.commit()
    h.times[0] = 0.55                                       # a shorter last step: new weights
    b = p.step_weights(h, 0.5, 0.05, 2)
    assert b is not a and b.extrap.shape == a.extrap.shape
    assert p.step_weights(h, 0.5, 0.05, 2, q=1) is not b    # the start-up iteration keys apart


def test_derivative_weights_follow_the_step_size_not_only_the_normalised_nodes():
    """Constant steps of H, later constant steps of 2H: the normalised nodes (0, -1, -2) are the
    same, the derivative weights (scaled by h**-d) are not. The weight cache reused those of the
    first step size for the second, so an FMU with canInterpolateInputs received derivatives
    off by 2**-d after the step changed (order 1 instead of k + 1,
    test_master.py::test_input_derivatives_keep_the_order_when_the_step_size_changes)."""
    c = [0.3, -1.0, 2.0]
    pred = LagrangePredictor(extrapolation_order=2, interpolation_order=2)
    for H in (0.1, 0.2):
        times = [1.0 - j * H for j in range(3)]
        h, b = make_history([poly(c, t) for t in times], times)
        h.times[0] = 1.0 + H
        b[0, 0] = poly(c, 1.0 + H)
        w = pred.step_weights(h, 1.0, H, 1)
        for d in (1, 2):
            expect = np.polynomial.polynomial.polyval(1.0, np.polynomial.polynomial.polyder(c, d))
            assert w.extrap_der[0][d - 1] @ b[w.e0:w.e1, 0] == pytest.approx(expect, rel=1e-9), (H, d)
            assert w.interp_der[0][d - 1] @ b[: w.q + 1, 0] == pytest.approx(expect, rel=1e-9), (H, d)
