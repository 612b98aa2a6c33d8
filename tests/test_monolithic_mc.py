"""The monolithic BDF2 reference with the mass-conserving film (issue 6, acceptance 3).

``coupling.scheme: monolithic`` integrates the rotor and the mass-conserving films as one
BDF2 integrator (orchestrator/reference/monolithic.py). These tests check, on short runs of the CI
case ``compare/ci_jeffcott_mc.yaml`` (free to air, groove, film from its steady state) on a
coarse grid:

* step halving: observed order 2, and the change from halving the step is far below the
  smallest tolerance the CI comparison uses; halving rtol/atol changes nothing visible;
* the co-simulation converges to it as the macro step shrinks;
* on a half-Sommerfeld case the BDF2 path agrees with the Radau path (same answer to the
  BDF2 time-discretisation error, which is second order);
* ``solve_ivp`` methods are refused for the mass-conserving film with a clear message.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from orchestrator import run
from orchestrator.compare import load_compare
from orchestrator.errors import ScenarioError
from orchestrator.reference.monolithic import run_monolithic

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[1]
SIGNALS = ("rotor.x_1", "rotor.y_1", "rotor.x_2", "rotor.y_2", "bearing1.Fy")
COARSE = {f"bearing{i}.{k}": v for i in (1, 2) for k, v in (("n_phi", 16), ("n_z", 6))}


def _mc(**changes):
    spec = load_compare(REPO / "compare" / "ci_jeffcott_mc.yaml")
    return spec, spec.scenario({"coupling.scheme": "monolithic", "stop_time": 0.251, **COARSE,
                                **changes})


def _diff(a, b, scales) -> float:
    """Worst max-norm difference of the signals, each relative to its scale."""
    assert np.array_equal(a.t, b.t)
    return max(float(np.max(np.abs(a.outputs[s] - b.outputs[s]))) / scales[s] for s in SIGNALS)


def _scales(res):
    return {s: (1.372e-5 if s.startswith("rotor") else float(np.max(np.abs(res.outputs[s]))))
            for s in SIGNALS}


def test_mc_reference_converges_at_second_order(tmp_path):
    spec, _ = _mc()
    runs = {}
    for h in (2e-5, 1e-5, 5e-6):
        _, sc = _mc(**{"coupling.options.step": h})
        runs[h] = run_monolithic(sc, tmp_path / f"h{h:g}")
        assert runs[h].success, runs[h].message
        assert runs[h].stats["macro_steps"] == round(1e-3 / h) + 4    # + the start ramp
    sc_tol = _mc(**{"coupling.options.step": 1e-5, "coupling.options.rtol": 5e-9,
                    "coupling.options.atol": 5e-13})[1]
    tight = run_monolithic(sc_tol, tmp_path / "tight")
    assert tight.success, tight.message
    S = _scales(runs[5e-6])
    d1, d2 = _diff(runs[2e-5], runs[1e-5], S), _diff(runs[1e-5], runs[5e-6], S)
    order = np.log2(d1 / d2)
    # at least second order. Since issue 16's free-to-air edge (second order, penalty_b 1e4) and
    # true-width groove the observed order on these steps is 3.1 (d1 1.51e-3, d2 1.76e-4;
    # before: within 1.7-2.3): the coarse pair is not yet asymptotic. Upper bound dropped.
    # Reviewed (issue 16, 2026-12-02): one step further (2.5e-6) the differences are 1.51e-3,
    # 1.76e-4, 2.98e-5, orders 3.10 then 2.56: falling towards 2 under refinement, i.e.
    # pre-asymptotic second order (an upper bound would need the 2.5e-6 run: not in this test)
    assert order > 1.7, (d1, d2, order)
    # the reference's own error (Richardson: the 1e-5 -> 5e-6 change / 3 is the error at
    # 5e-6) is far below the smallest tolerance the CI comparison checks
    smallest = spec.smallest_tolerance()
    assert smallest is not None and d2 < smallest / 10, (d2, smallest)
    # the coupled Newton iteration is converged: tightening rtol/atol changes nothing
    # at the level of the time-discretisation error
    assert _diff(runs[1e-5], tight, S) < 1e-3 * d2


def test_cosimulation_converges_to_the_mc_reference(tmp_path):
    _, sc = _mc(**{"coupling.options.step": 2.5e-6})
    ref = run_monolithic(sc, tmp_path / "ref")
    assert ref.success, ref.message
    S = _scales(ref)
    errs, pos = [], []
    for H in (2e-5, 5e-6):
        spec, co = _mc(**{"coupling.scheme": "gauss-seidel", "coupling.macro_step": H})
        res = run(co, out_dir=tmp_path / f"co{H:g}", progress=False)
        assert res.success, res.message
        errs.append(_diff(res, ref, S))
        pos.append(max(float(np.max(np.abs(res.outputs[s] - ref.outputs[s]))) / S[s]
                       for s in SIGNALS[:4]))
    # the co-simulation error (coupling, and the film's own step control) falls with the
    # macro step, at about first order (measured: 4x smaller step -> 2.9x smaller worst
    # error, 4.4x smaller displacement error); the journals are within 1e-4 c at 5 us
    assert errs[1] < errs[0] / 2, errs
    assert pos[1] < pos[0] / 3 and pos[1] < 2e-4, pos


def test_bdf2_path_agrees_with_radau_on_half_sommerfeld(tmp_path):
    spec = load_compare(REPO / "compare" / "ci_jeffcott.yaml")
    base = {"coupling.scheme": "monolithic", "stop_time": 3e-4}
    radau = run_monolithic(spec.scenario({**base, "coupling.options.rtol": 1e-10}), tmp_path / "r")
    bdf = {h: run_monolithic(spec.scenario({**base, "coupling.options.method": "BDF2",
                                            "coupling.options.step": h}), tmp_path / f"b{h:g}")
           for h in (1e-6, 5e-7)}
    assert radau.success and all(r.success for r in bdf.values())
    keep = radau.t >= 1e-4 - 1e-12     # after the journals' landing (BDF1 start, stiff layer)
    S = {s: (5.6e-5 if s.startswith("rotor") else float(np.max(np.abs(radau.outputs[s]))))
         for s in SIGNALS}
    e = {h: max(float(np.max(np.abs(r.outputs[s] - radau.outputs[s])[keep])) / S[s] for s in SIGNALS)
         for h, r in bdf.items()}
    assert e[5e-7] < 1e-7, e
    assert 3.0 < e[1e-6] / e[5e-7] < 5.0, e      # second order: ratio 4


def test_solve_ivp_method_is_refused_for_the_mass_conserving_film(tmp_path):
    _, sc = _mc(**{"coupling.options.method": "Radau"})
    with pytest.raises(ScenarioError, match=r"bearing1.*mass-conserving film.*method: BDF2"):
        run_monolithic(sc, tmp_path)
