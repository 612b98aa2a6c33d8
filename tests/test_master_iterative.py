"""Iterative coupling (coupling.scheme: iterative) and the algebraic-loop solver of the initial
exchange, with the plain-Python fakes of test_master.py (exact integration for polynomial inputs)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from orchestrator.scenario.model import IterationSpec
from orchestrator.errors import ScenarioError
from orchestrator.coupling.execution import MasterAlgorithm
from orchestrator.results import Status
from orchestrator.scenario import ConnectionSpec, CouplingSpec, FmuSpec, OutputSpec, Scenario
from test_master import LinearFake

STIFF = dict(m1=1.0, k1=100.0, m2=1.0, k2=100.0, d2=0.0, kc=1.0e6, dc=20.0)
SOFT = dict(m1=1.0, k1=10.0, m2=1.0, k2=1000.0, d2=1.0, kc=100.0, dc=1.0)
X0 = (0.01, 0.0, 0.0101, 0.0)      # x1, v1, x2, v2: coupling spring stretched by 0.1 mm


def fakes(P, x0=X0, *, interpolate=True, state=True):
    m1, k1, m2, k2, d2, kc, dc = (P[k] for k in ("m1", "k1", "m2", "k2", "d2", "kc", "dc"))
    left = LinearFake("left", [[0, 1], [-k1 / m1, 0]], [[0], [1 / m1]], np.eye(2), np.zeros((2, 1)), x0[:2],
                      ["F"], ["x1", "v1"], interpolate=interpolate, state=state)
    right = LinearFake("right", [[0, 1], [-(k2 + kc) / m2, -(d2 + dc) / m2]], [[0, 0], [kc / m2, dc / m2]],
                       [[kc, dc], [1, 0], [0, 1]], [[-kc, -dc], [0, 0], [0, 0]], x0[2:],
                       ["x1", "v1"], ["F", "x2", "v2"], interpolate=interpolate, state=state)
    return {"left": left, "right": right}


def exact(P, t, x0=X0):
    m1, k1, m2, k2, d2, kc, dc = (P[k] for k in ("m1", "k1", "m2", "k2", "d2", "kc", "dc"))
    A = np.array([[0, 1, 0, 0], [-(k1 + kc) / m1, -dc / m1, kc / m1, dc / m1],
                  [0, 0, 0, 1], [kc / m2, dc / m2, -(k2 + kc) / m2, -(d2 + dc) / m2]])
    return np.array([expm(A * ti) @ np.asarray(x0) for ti in t])


def scenario(scheme, H, *, T=0.2, k=0, q=1, iteration=None):
    return Scenario(
        name="two-mass", stop_time=T,
        fmus=(FmuSpec(name="left", path=Path("left")), FmuSpec(name="right", path=Path("right"))),
        connections=(ConnectionSpec(src="left.x1", dst="right.x1"), ConnectionSpec(src="left.v1", dst="right.v1"),
                     ConnectionSpec(src="right.F", dst="left.F")),
        coupling=CouplingSpec(scheme=scheme, sequence=("left", "right"), macro_step=H, extrapolation_order=k,
                              interpolation_order=q, iteration=iteration or IterationSpec()),
        output=OutputSpec(signals=("left.x1", "right.x2", "right.F")))


def error(P, res, x0=X0):
    X = exact(P, res.t, x0)
    return max(np.abs(res.outputs["left.x1"] - X[:, 0]).max(), np.abs(res.outputs["right.x2"] - X[:, 2]).max())


def decays(res) -> bool:
    F = np.abs(res.outputs["right.F"])
    n = len(F) // 5
    return bool(np.all(np.isfinite(F)) and F[-n:].max() < F[:n].max())


@pytest.mark.parametrize("H", [4e-3, 1.6e-2, 6.4e-2])
def test_iterative_coupling_is_stable_where_explicit_gauss_seidel_blows_up(H):
    """kc = 1e6 N/m (fast mode 1414 rad/s). Inputs held over the step (as PythonFMU FMUs get
    them): Gauss-Seidel at H/40 already diverges; iterative coupling (IQN-ILS) with the iterate's
    line sampled at the step midpoint -- the average of both ends, i.e. Newmark's average-
    acceleration rule for the force, unconditionally stable -- stays bounded for 2 s and the
    fast mode decays as it physically does, even at H = 64 ms (H omega = 90)."""
    gs = MasterAlgorithm(scenario("gauss-seidel", H / 40, q=0), subsystems=fakes(STIFF, interpolate=False)).run()
    assert gs.status is Status.FAILED or not decays(gs) or np.nanmax(np.abs(gs.outputs["left.x1"])) > 0.1
    it = MasterAlgorithm(scenario("iterative", H, T=2.0), subsystems=fakes(STIFF, interpolate=False)).run()
    assert it.status is Status.FINISHED, it.message
    assert decays(it)
    assert np.abs(it.outputs["left.x1"]).max() < 0.0105           # amplitude 0.01 m: no growth
    st = it.stats["iterations"]
    assert st["max_per_step"] <= 6 and st["total"] == sum(int(k) * v for k, v in st["histogram"].items())
    assert it.stats["fmu_calls"]["left"]["doStep"] == st["total"]      # one doStep per pass (substeps 1)


def test_iterative_coupling_converges_at_second_order_on_the_stiff_problem():
    """Stable is not accurate: the error against the exact solution is O(H^2) with a constant set
    by the fast mode ((H omega_fast)^2), so accuracy still needs H omega_fast < 1."""
    errs = []
    Hs = [4e-4, 2e-4, 1e-4]
    for H in Hs:
        res = MasterAlgorithm(scenario("iterative", H, T=0.05), subsystems=fakes(STIFF, interpolate=False)).run()
        errs.append(error(STIFF, res))
    slope = float(np.polyfit(np.log(Hs), np.log(errs), 1)[0])
    assert slope == pytest.approx(2.0, abs=0.25), errs
    assert errs[-1] < 1e-5


def test_exact_line_inputs_are_only_conditionally_stable():
    """With input derivatives the FMU gets the iterate's line exactly: the force is then linear over
    the step, Newmark's linear-acceleration rule, stable only for H omega < 2 sqrt(3) (Newmark 1959):
    at omega_fast = 1414 rad/s that is H < 2.4 ms. Documented in docs/coupling.md."""
    ok = MasterAlgorithm(scenario("iterative", 1e-3, T=2.0), subsystems=fakes(STIFF)).run()
    assert ok.success and decays(ok)
    bad = MasterAlgorithm(scenario("iterative", 4e-3, T=2.0), subsystems=fakes(STIFF)).run()
    assert not decays(bad)


@pytest.mark.parametrize("q, expected", [(1, 2.0), (2, 3.0)])
def test_converged_iterative_coupling_orders(q, expected):
    """With the inputs following the iterate's interpolation polynomial of order q (fakes get it
    exactly as input derivatives), the converged coupling error is O(H^(q+1))."""
    Hs = [8e-3, 4e-3, 2e-3]
    errs = []
    for H in Hs:
        spec = IterationSpec(tol=1e-12, max_iterations=30)
        res = MasterAlgorithm(scenario("iterative", H, T=0.4, q=q, iteration=spec),
                              subsystems=fakes(SOFT, (1.0, 0.0, 0.0, 0.0))).run()
        assert res.success, res.message
        errs.append(error(SOFT, res, (1.0, 0.0, 0.0, 0.0)))
    slope = float(np.polyfit(np.log(Hs), np.log(errs), 1)[0])
    assert slope == pytest.approx(expected, abs=0.25), errs


def test_accelerations_converge_to_the_same_solution():
    """Where plain iteration converges (soft coupling) all three accelerations reach the same
    fixed point; IQN-ILS needs the fewest passes (Aitken starts every step at relaxation 0.5,
    which costs passes when plain iteration contracts fast)."""
    runs = {}
    for acc in ("none", "aitken", "iqn-ils"):
        spec = IterationSpec(acceleration=acc, tol=1e-10, max_iterations=60)
        runs[acc] = MasterAlgorithm(scenario("iterative", 5e-3, T=0.2, iteration=spec),
                                    subsystems=fakes(SOFT, (1.0, 0.0, 0.0, 0.0))).run()
        assert runs[acc].success, (acc, runs[acc].message)
    for acc in ("none", "aitken"):
        np.testing.assert_allclose(runs[acc].outputs["left.x1"], runs["iqn-ils"].outputs["left.x1"], atol=1e-8)
    it = {a: r.stats["iterations"]["total"] for a, r in runs.items()}
    assert it["iqn-ils"] < min(it["aitken"], it["none"]), it


def test_no_convergence_fails_with_the_signal_named():
    spec = IterationSpec(acceleration="none", max_iterations=3)
    res = MasterAlgorithm(scenario("iterative", 4e-3, iteration=spec), subsystems=fakes(STIFF)).run()
    assert res.status is Status.FAILED
    assert "did not converge" in res.message and "max_iterations = 3" in res.message
    assert "right.x1" in res.message or "right.v1" in res.message or "left.F" in res.message
    assert "iqn-ils" in res.message and res.end_time == 0.0


def test_iterative_needs_fmu_states():
    with pytest.raises(ScenarioError, match="canGetAndSetFMUstate"):
        MasterAlgorithm(scenario("iterative", 1e-3), subsystems=fakes(STIFF, state=False)).setup()


def test_held_end_value_is_first_order():
    """interpolation_order 0 holds the end value over the step (implicit-Euler-like): converged
    on the soft problem, first order (and on the stiff one unstable: docs/coupling.md)."""
    errs = []
    for H in (4e-3, 2e-3):
        res = MasterAlgorithm(scenario("iterative", H, T=0.2, q=0), subsystems=fakes(SOFT, (1.0, 0, 0, 0))).run()
        assert res.success
        errs.append(error(SOFT, res, (1.0, 0, 0, 0)))
    assert np.log2(errs[0] / errs[1]) == pytest.approx(1.0, abs=0.2)


# ---- algebraic loops in the initial exchange ---------------------------------------

def gain_loop(k, offset, scheme="gauss-seidel"):
    g = LinearFake("g", [[0.0]], [[0.0]], [[0.0]], [[k]], [0.0], ["u"], ["y"], interpolate=False)
    sc = Scenario(name="loop", stop_time=0.01, fmus=(FmuSpec(name="g", path=Path("g")),),
                  connections=(ConnectionSpec(src="g.y", dst="g.u", offset=offset),),
                  coupling=CouplingSpec(scheme=scheme, macro_step=1e-3), output=OutputSpec(signals=("g.y",)))
    return sc, {"g": g}


@pytest.mark.parametrize("scheme", ["gauss-seidel", "iterative"])
def test_gain_two_self_loop_is_solved_at_t0(scheme):
    """u = 2 u + 1 (a gain-2 FMU fed back with offset 1): the consistent initial value is u = -1,
    y = -2 (the old exchange doubled y ten times per pass and ended 'finished' near 2^30). The
    explicit run keeps it (the loop's fixed point is also the delayed map's); the iterative
    scheme solves the loop in every step."""
    sc, subs = gain_loop(2.0, 1.0, scheme)
    res = MasterAlgorithm(sc, subsystems=subs).run()
    assert res.success, res.message
    np.testing.assert_allclose(res.outputs["g.y"], -2.0, rtol=1e-7)


def test_loop_without_solution_fails_naming_the_loop():
    sc, subs = gain_loop(1.0, 1.0)          # u = u + 1
    res = MasterAlgorithm(sc, subsystems=subs).run()
    assert res.status is Status.FAILED
    assert "algebraic loop" in res.message and "g.y -> g.u" in res.message
    assert len(res.t) == 0


def test_loop_message_follows_the_declared_dependencies():
    """With a ModelStructure that declares y <- u, the loop is named variable by variable."""
    from types import SimpleNamespace
    sc, subs = gain_loop(1.0, 1.0)
    subs["g"].md = SimpleNamespace(direct_feedthrough=lambda: {"y": ("u",)})
    res = MasterAlgorithm(sc, subsystems=subs).run()
    assert res.status is Status.FAILED
    assert "g.y -> g.u (g: u -> y)" in res.message and "declared direct dependencies" in res.message


def test_signal_loop():
    from orchestrator.coupling.loops import signal_loop
    cs = (ConnectionSpec(src="a.y1", dst="b.v"), ConnectionSpec(src="b.z", dst="a.u1"),
          ConnectionSpec(src="a.y2", dst="b.w"), ConnectionSpec(src="c.q", dst="a.u2"))
    feed = {"a": {"y1": ("u1",), "y2": ()}, "b": {"z": ("v",), "z2": ("w",)}, "c": {"q": ()}}
    assert signal_loop(cs, "a.u1", feed) == ["a.y1 -> b.v (b: v -> z)", "b.z -> a.u1 (a: u1 -> y1)"]
    assert signal_loop(cs, "b.z", feed) == signal_loop(cs, "a.u1", feed)
    assert signal_loop(cs, "b.w", feed) == []              # a.y2 depends on no input: no cycle through it
    assert signal_loop(cs, "c.q", feed) == []              # not on an instance-level loop either
    cut = {"a": {"y1": (), "y2": ()}, "b": feed["b"], "c": feed["c"]}
    assert signal_loop(cs, "a.u1", cut) == []              # a instance loop, but no variable cycle
    assert signal_loop(cs, "a.u1", {**feed, "b": None}) is None                 # b declares nothing
    assert signal_loop(cs, "a.u1", {**feed, "b": {"z": None, "z2": ()}}) is None


def test_feedthrough_chain_settles_without_the_loop_solver():
    """A chain src -> g1 -> g2 (no loop) settles in plain passes: exactly the chain's values."""
    from test_master import Ramp
    subs = {"src": Ramp("src"),
            "g1": LinearFake("g1", [[0.0]], [[0.0]], [[0.0]], [[3.0]], [0.0], ["u"], ["y"], interpolate=False),
            "g2": LinearFake("g2", [[0.0]], [[0.0]], [[0.0]], [[0.5]], [0.0], ["u"], ["y"], interpolate=False)}
    subs["src"].x0 = np.array([2.0])
    sc = Scenario(name="chain", stop_time=0.1,
                  fmus=tuple(FmuSpec(name=n, path=Path(n)) for n in ("src", "g1", "g2")),
                  connections=(ConnectionSpec(src="src.y", dst="g1.u"), ConnectionSpec(src="g1.y", dst="g2.u")),
                  coupling=CouplingSpec(scheme="jacobi", sequence=("g2", "g1", "src"), macro_step=0.1),
                  output=OutputSpec(signals=("g1.y", "g2.y")))
    res = MasterAlgorithm(sc, subsystems=subs).run()
    assert res.outputs["g1.y"][0] == 6.0 and res.outputs["g2.y"][0] == 3.0


def test_iteration_spec_rejects_unknown_acceleration():
    with pytest.raises(ValueError, match="iqn-ils"):
        IterationSpec(acceleration="anderson")
    assert dataclasses.replace(IterationSpec(), tol=1e-6).tol == 1e-6
