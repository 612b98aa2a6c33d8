"""``compare`` and the monolithic reference with the real master and real FMUs.

* The observed orders of the two-mass oscillator agree with the orders the
  orchestrator documents for FMUs with held inputs (docs/coupling.md,
  tests/test_master_fmus.py): k = 0 -> 1, k = 1 -> 2.
* The monolithic reference matches the closed-form solution of the two-mass
  oscillator, and for the CI Jeffcott comparison halving its tolerance changes
  it by far less than the smallest tolerance in use.
* Models the reference cannot represent, and a mass-conserving film with a ``solve_ivp``
  method, are rejected with a clear message.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from orchestrator.compare import load_compare, parse_compare, run_comparison
from orchestrator.compare.metrics import signal_errors
from orchestrator.errors import ScenarioError
from orchestrator.reference.monolithic import run_monolithic
from orchestrator.scenario import ConnectionSpec, CouplingSpec, FmuSpec, OutputSpec, Scenario

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[1]
P = dict(m1=1.0, k1=10.0, m2=1.0, k2=1000.0, d2=1.0, kc=100.0, dc=1.0)   # as tests/test_master_fmus.py


def two_mass(fmus, **coupling) -> Scenario:
    return Scenario(
        name="two-mass", stop_time=0.5,
        fmus=(FmuSpec(name="left", path=fmus["LeftMass"], parameters=dict(m1=P["m1"], k1=P["k1"], x1_0=1.0)),
              FmuSpec(name="right", path=fmus["RightMass"],
                      parameters={k: P[k] for k in ("m2", "k2", "d2", "kc", "dc")})),
        connections=(ConnectionSpec(src="left.x1", dst="right.x1"), ConnectionSpec(src="left.v1", dst="right.v1"),
                     ConnectionSpec(src="right.F", dst="left.F")),
        coupling=CouplingSpec(sequence=("left", "right"), **coupling),
        output=OutputSpec(interval=4e-3, signals=("left.x1", "right.x2")))


def exact(t):
    m1, k1, m2, k2, d2, kc, dc = (P[k] for k in ("m1", "k1", "m2", "k2", "d2", "kc", "dc"))
    A = np.array([[0, 1, 0, 0], [-(k1 + kc) / m1, -dc / m1, kc / m1, dc / m1],
                  [0, 0, 0, 1], [kc / m2, dc / m2, -(k2 + kc) / m2, -(d2 + dc) / m2]])
    return np.array([expm(A * ti) @ [1.0, 0, 0, 0] for ti in t])


def test_monolithic_two_mass_matches_the_closed_form(test_fmus, tmp_path):
    res = run_monolithic(two_mass(test_fmus, scheme="monolithic", options={"rtol": 1e-10}), tmp_path)
    assert res.success, res.message
    X = exact(res.t)
    assert res.t[-1] == pytest.approx(0.5) and len(res.t) == 126
    assert np.abs(res.outputs["left.x1"] - X[:, 0]).max() < 1e-8
    assert np.abs(res.outputs["right.x2"] - X[:, 2]).max() < 1e-8
    assert (tmp_path / "results.csv").read_text().startswith("time,left.x1,right.x2\n")


def test_two_mass_observed_orders_agree_with_documented_orders(test_fmus, tmp_path):
    section = {
        "signals": ["left.x1", "right.x2"],
        "reference": {"scheme": "monolithic", "set": {"coupling.options.rtol": 1e-10}, "check": False},
        "order_metric": "max", "order_tolerance": 0.25,
        "variants": [
            {"scheme": ["jacobi", "gauss-seidel"], "extrapolation_order": 0, "interpolation_order": 0,
             "macro_step": [4e-3, 2e-3, 1e-3], "expect_order": 1},
            {"scheme": ["jacobi", "gauss-seidel"], "extrapolation_order": 1, "interpolation_order": 1,
             "macro_step": [4e-3, 2e-3, 1e-3], "expect_order": 2},
        ]}
    spec = parse_compare(section, two_mass(test_fmus, scheme="jacobi", macro_step=1e-3))
    rep = run_comparison(spec, tmp_path, workers=1)
    orders = {o["family"]: o["order"] for o in rep.orders}
    assert set(orders) == {"jac-e0i0", "gs-e0i0", "jac-e1i1", "gs-e1i1"}
    for fam, p in orders.items():
        expected = 1.0 if "e0" in fam else 2.0
        assert abs(p - expected) < 0.25, (fam, p)
    # Gauss-Seidel uses the new value of the first subsystem: more accurate than Jacobi
    err = {v["name"]: v["errors"]["max"] for v in rep.variants}
    assert err["gs-e1i1-h0.001"] < err["jac-e1i1-h0.001"]
    assert all(v["stable"] for v in rep.variants)


def test_monolithic_reference_of_the_ci_jeffcott_comparison_converges(tmp_path):
    """Halving rtol/atol of the reference changes it by much less than the smallest
    tolerance the comparison uses (over the first 0.5 ms, where the journals
    drop onto the film and the dynamics are fastest)."""
    spec = load_compare(REPO / "compare" / "ci_jeffcott.yaml")
    small = spec.smallest_tolerance()
    assert small is not None
    runs = []
    for i, changes in enumerate((spec.reference.changes, spec.reference.halved(spec.base))):
        sc = spec.scenario({**changes, "stop_time": 5e-4})
        runs.append(run_monolithic(sc, tmp_path / str(i)))
    assert all(r.success for r in runs), [r.message for r in runs]
    a, b = runs
    for s, scale in spec.signals.items():
        scale = scale or float(np.abs(a.outputs[s]).max())
        e = signal_errors(a.t, a.outputs[s], b.t, b.outputs[s], scale)
        assert e["max"] < small, (s, e)


def test_mass_conserving_bearing_needs_the_bdf2_integrator(tmp_path):
    # the mass-conserving film is supported by the BDF2 path (tests/test_monolithic_mc.py);
    # a solve_ivp method cannot advance its state and is refused with a clear message
    spec = load_compare(REPO / "compare" / "ci_jeffcott.yaml")
    sc = spec.scenario({"coupling.scheme": "monolithic", "bearing1.cavitation": 1,
                        "coupling.options.method": "Radau"})
    with pytest.raises(ScenarioError, match=r"\['bearing1'\].*mass-conserving film.*method: BDF2"):
        run_monolithic(sc, tmp_path)


def test_unknown_model_is_refused_naming_it(test_fmus, tmp_path):
    sc = two_mass(test_fmus, scheme="monolithic")
    sc = dataclasses.replace(sc, fmus=(*sc.fmus, FmuSpec(name="g", path=test_fmus["Gain"])))
    with pytest.raises(ScenarioError, match=r"'g'.*model 'Gain'.*cannot build"):
        run_monolithic(sc, tmp_path)
