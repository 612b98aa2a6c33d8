"""atol of the error-controlled step from the FMUs' ``nominal`` attribute
(orchestrator/coupling/signal_scales.py, docs/coupling.md "Error-controlled macro step")."""

from __future__ import annotations

import json
import re
import zipfile
from pathlib import Path

import numpy as np

from orchestrator import run
from orchestrator.coupling.signal_scales import atol_vector, signal_nominals
from orchestrator.fmi.model_description import Variable
from orchestrator.scenario import ConnectionSpec, load_scenario


def _var(name, nominal=None):
    return Variable(name=name, value_reference=0, type="Real", causality="output", variability="continuous",
                    nominal=nominal)


def test_nominal_of_the_producer_times_gain_else_of_the_consumer_else_none():
    conns = [ConnectionSpec(src="b.F", dst="r.F", gain=-2.0), ConnectionSpec(src="r.x", dst="b.x"),
             ConnectionSpec(src="r.v", dst="b.v")]
    md = {("b", "F"): _var("F", 30.0), ("b", "x"): _var("x", 1e-5), ("r", "x"): _var("x"),
          ("r", "v"): _var("v"), ("b", "v"): _var("v")}
    noms = signal_nominals(["r.F", "b.x", "b.v"], conns, lambda i, n: md.get((i, n)))
    assert noms == [60.0, 1e-5, None]


def test_atol_key_beats_nominal_beats_default():
    names = ["r.F", "b.x", "b.v"]
    noms = [60.0, 1e-5, None]
    # atol not given: rtol * nominal, 1e-8 where there is none
    np.testing.assert_allclose(atol_vector(None, names, rtol=1e-3, nominals=noms), [0.06, 1e-8, 1e-8])
    # a key that names a signal wins over its nominal; unnamed ones keep rtol * nominal
    np.testing.assert_allclose(atol_vector((("r.*", 0.5),), names, rtol=1e-3, nominals=noms), [0.5, 1e-8, 1e-8])
    np.testing.assert_allclose(atol_vector((("b.v", 2.0),), names, rtol=1e-3, nominals=noms), [0.06, 1e-8, 2.0])
    # an explicit number applies to every signal (nominals unused)
    np.testing.assert_allclose(atol_vector(1e-6, names, rtol=1e-3, nominals=noms), [1e-6] * 3)


def _with_nominal(fmu: Path, dest: Path, variable: str, nominal: float) -> Path:
    """A copy of ``fmu`` whose modelDescription.xml declares ``nominal`` on ``variable``'s Real."""
    with zipfile.ZipFile(fmu) as z:
        items = {n: z.read(n) for n in z.namelist()}
    xml = items["modelDescription.xml"].decode()
    pat = re.compile(r'(<ScalarVariable[^>]*name="%s"[^>]*>\s*<Real)' % re.escape(variable))
    xml, n = pat.subn(r'\1 nominal="%r"' % nominal, xml)
    assert n == 1, f"{variable} not found in {fmu}"
    items["modelDescription.xml"] = xml.encode()
    dest.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in items.items():
            z.writestr(name, data)
    return dest


SCENARIO = """
name: two-mass-nominal
stop_time: 0.05
fmus:
  left: {{path: {left}, parameters: {{m1: 1.0, k1: 100.0, x1_0: 0.01}}}}
  right: {{path: {right}, parameters: {{m2: 1.0, k2: 100.0, kc: 1.0e4, dc: 10.0, x2_0: 0.0101}}}}
connections:
  - {{from: left.x1, to: right.x1}}
  - {{from: left.v1, to: right.v1}}
  - {{from: right.F, to: left.F}}
coupling:
  scheme: gauss-seidel
  sequence: [left, right]
  macro_step: 1.0e-5
  extrapolation_order: 1
  interpolation_order: 1
  step_control: {{type: error, rtol: 1.0e-2}}
output: {{interval: 1.0e-2, signals: [left.x1]}}
"""


def test_declared_nominals_set_the_atol_of_a_real_fmu_run(test_fmus, tmp_path):
    """Without atol, the signals take rtol * nominal: the spring force F (nominal 1 N declared in
    the patched RightMass) and x1, v1 (nominal 0.01 m, 1 m/s in LeftMass). Against the same run
    on the unpatched FMUs with ``atol: {'*': 1e-8}`` (the default before the running scale; v1
    and F pass zero) the step is larger, so fewer
    doSteps; summary.json lists the signals that took their atol from a nominal."""
    left = _with_nominal(test_fmus["LeftMass"], tmp_path / "nom" / "LeftMass.fmu", "x1", 0.01)
    left = _with_nominal(left, tmp_path / "nom2" / "LeftMass.fmu", "v1", 1.0)
    right = _with_nominal(test_fmus["RightMass"], tmp_path / "nom" / "RightMass.fmu", "F", 1.0)
    runs = {}
    for tag, (lf, rf) in {"plain": (test_fmus["LeftMass"], test_fmus["RightMass"]), "nominal": (left, right)}.items():
        f = tmp_path / f"{tag}.yaml"
        text = SCENARIO.format(left=lf, right=rf)
        if tag == "plain":    # the old default, now explicit (without atol the plain FMUs take a running scale)
            text = text.replace("rtol: 1.0e-2}", "rtol: 1.0e-2, atol: {'*': 1.0e-8}}")
        f.write_text(text)
        res = run(load_scenario(f), out_dir=tmp_path / tag)
        assert res.status.name == "FINISHED", res.message
        runs[tag] = json.loads((tmp_path / tag / "summary.json").read_text())
    sc_plain, sc_nom = (runs[k]["step_control"] for k in ("plain", "nominal"))
    assert sc_plain["atol_from_nominal"] == []
    assert sorted(sc_nom["atol_from_nominal"]) == ["left.F", "right.v1", "right.x1"]
    n_plain = runs["plain"]["fmu_calls"]["left"]["doStep"]
    n_nom = runs["nominal"]["fmu_calls"]["left"]["doStep"]
    assert n_nom < n_plain


def test_the_rotor_speed_declares_a_nominal_so_a_run_from_rest_is_not_held_on_it(tmp_path):
    """Our rotors' ``omega`` output and the bearings' input declare nominal 1000 rad/s
    (fmu_common/slave.py NOMINALS). The from-rest run-up starts at omega = 0: with only the
    running scale (the size the signal has had so far) its first defect was 1/rtol of itself
    whatever the step, and the first 4 steps were forced to min_step on bearing1.omega (shipped
    scenario before the nominal). Now omega takes rtol x 1000 rad/s and limits no step."""
    root = Path(__file__).resolve().parents[1]
    sc = load_scenario(root / "scenarios" / "jeffcott_runup_free_to_air_from_rest.yaml",
                       ["stop_time=0.0005", "coupling.step_control={type: error, rtol: 0.05}",
                        "coupling.discard_retries=0", "coupling.defect_retries=0"], build_fmus=True)
    res = run(sc, out_dir=tmp_path / "run")
    assert res.status.name == "FINISHED", res.message
    ctl = json.loads((tmp_path / "run" / "summary.json").read_text())["step_control"]
    assert sorted(ctl["atol_from_nominal"]) == ["bearing1.omega", "bearing2.omega"]
    assert not any("omega" in s for s in ctl["limiting_signals"])   # bearing1.omega: 4 before
