"""The oracle of benchmarks/bench_goal_oracle.py (issue 18's bound on the seeded run-up): the
Lagrange step schedule against its closed form, and the scheduled controller's grid."""

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

spec = importlib.util.spec_from_file_location(
    "bench_goal_oracle", Path(__file__).resolve().parents[1] / "benchmarks" / "bench_goal_oracle.py")
oracle = importlib.util.module_from_spec(spec)
spec.loader.exec_module(oracle)


def test_lagrange_schedule_matches_the_closed_form_and_the_constraint():
    w = np.array([1.0, 8.0, 27.0, 0.5])
    T = np.array([0.1, 0.1, 0.2, 0.1])
    p = 2.0
    H = oracle.optimal_steps(w, T, p, target=1e-6, h_min=1e-9, h_max=1.0)
    assert np.sum(w * H ** p) == pytest.approx(1e-6, rel=1e-9)
    # stationarity: H_k^(p+1) w_k / T_k is the same for every window
    c = H ** (p + 1) * w / T
    assert np.allclose(c, c[0], rtol=1e-9)
    # the cost ratio against the constant step with the same error: the power-mean formula
    h = (1e-6 / w.sum()) ** (1 / p)
    om, r = w / T, 1 / (p + 1)
    formula = (np.sum(T * om) / T.sum() / (np.sum(T * om ** r) / T.sum()) ** (1 / r)) ** (1 / p)
    assert (T.sum() / h) / np.sum(T / H) == pytest.approx(formula, rel=1e-9)
    assert formula > 1.0
    # equal weight densities: no schedule beats the constant step
    H1 = oracle.optimal_steps(2 * T, T, p, target=1e-6, h_min=1e-9, h_max=1.0)
    assert np.allclose(H1, H1[0], rtol=1e-9)


def test_lagrange_schedule_respects_the_step_bounds():
    w = np.array([1e-6, 1.0, 1.0])
    T = np.full(3, 0.1)
    H = oracle.optimal_steps(w, T, 2.0, target=1e-7, h_min=1e-6, h_max=1e-3)
    assert H[0] == pytest.approx(1e-3) and np.all(H <= 1e-3 * (1 + 1e-12)) and np.all(H >= 1e-6)
    assert np.sum(w * H ** 2) == pytest.approx(1e-7, rel=1e-6) and H[1] < 1e-3


def test_scheduled_step_takes_each_windows_step_and_lands_on_edges_and_output_times():
    g = oracle.ScheduledStep([0.0, 0.0016, 0.0048], [1e-4, 4e-4], interval=1.6e-3)
    taken = []

    class Stepper:
        def step(self, t, t_end):
            taken.append((t, t_end))

    t = 0.0
    while t < 0.0048 - 1e-12:
        t, on_out = g.take_variable_step(Stepper(), t)
        assert on_out == any(math.isclose(t, s, abs_tol=1e-12) for s in (0.0016, 0.0032, 0.0048))
    h = np.diff(np.array(taken), axis=1).ravel()
    assert len(taken) == 16 + 8
    assert np.allclose(h[:16], 1e-4) and np.allclose(h[16:], 4e-4)
    assert math.isclose(taken[15][1], 0.0016, abs_tol=1e-15)
