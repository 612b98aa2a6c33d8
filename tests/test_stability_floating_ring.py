"""`rotorcosim stability` on rotors in floating-ring bearings (orchestrator/stability.py).

The linear model itself (rotor_fmu/floating_ring_stability.py) is checked in docs/floating-ring.md
against run-ups through the master: the Jeffcott rotor's outer-ring whirl at 712.9 Hz (the
run-up's growth-rate threshold extrapolated to H -> 0: 722.1 Hz, +1.3 %; along the run, with the
run's ring speed and the spin free: 724.1 Hz against the run-up's 722.8 Hz), the turbocharger's
inner-film whirl at 42.19 Hz (run-up threshold estimate 42.57 Hz, +0.9 %). What is new here is the
path from a scenario file to that model: each ring's parameters from the FloatingRingBearing's
start values and the scenario's `parameters`, the rotor without its ring masses, the stations by
the connection convention. So the checks compare the command with the model built by hand from
the parameters the docs list (rotor_fmu/floating_ring_growth.py), and with the documented numbers.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pytest

from hostile_builders import run_verb

REPO = Path(__file__).resolve().parents[1]
TC_RING = REPO / "scenarios" / "turbocharger_runup_floating_ring_half_sommerfeld.yaml"
JC_RING = REPO / "scenarios" / "jeffcott_runup_floating_ring_half_sommerfeld.yaml"
JC_HS = REPO / "scenarios" / "jeffcott_runup_half_sommerfeld.yaml"


def _run(capsys, *args):
    return run_verb(capsys, "stability", *args)


def _load(path, *sets):
    from orchestrator.scenario import load_scenario
    return load_scenario(str(path), list(sets), build_fmus=True)


def test_turbocharger_in_floating_rings_cli(capsys, tmp_path):
    """The shipped turbocharger in two floating rings: the inner-film whirl of docs/floating-ring.md
    ("Turbocharger in floating rings": 42.19 Hz, whirl 26.88 Hz, order 0.637), and the same number
    from the model built by hand (rotor_fmu.floating_ring_growth.turbocharger_floating_ring)."""
    from rotor_fmu.floating_ring_growth import turbocharger_floating_ring
    from rotor_fmu.floating_ring_stability import ring_threshold_speed
    out = tmp_path / "r.json"
    code, text, err = _run(capsys, TC_RING, "--speeds", "30:60", "--json", out)
    assert code == 0, err
    r = json.loads(out.read_text())
    assert r["status"] == "threshold"
    assert r["threshold_hz"] == pytest.approx(42.19, abs=0.01)
    assert r["whirl_ratio"] == pytest.approx(0.637, abs=0.001)
    rotor, rings = turbocharger_floating_ring()
    wt, nu = ring_threshold_speed(rotor, rings, 2 * math.pi * 40.0, 2 * math.pi * 45.0, n_scan=3)
    assert r["threshold_hz"] == pytest.approx(wt / (2 * math.pi), rel=1e-5)
    assert r["whirl_hz"] == pytest.approx(nu / (2 * math.pi), rel=1e-4)
    b1, b2 = r["bearings"]["bearing1"], r["bearings"]["bearing2"]
    assert b1["kind"] == b2["kind"] == "floating_ring" and b1["floating"] == 1
    assert b1["load_n"] == pytest.approx(1.49, abs=0.01) and b2["load_n"] == pytest.approx(57.37, abs=0.01)
    # the turbine-side ring runs slower and more eccentric (docs: ring ratios 0.31 / 0.13 near 40 Hz)
    assert 0.30 < b1["ring_speed_ratio_at_threshold"] < 0.33 and 0.12 < b2["ring_speed_ratio_at_threshold"] < 0.15
    assert b2["eps_outer_at_threshold"] > b1["eps_outer_at_threshold"]
    assert "threshold speed: 42.19 Hz" in text and "ring speed 0.313 x journal speed" in text
    assert "spin held at its steady value" in text


def test_jeffcott_outer_whirl_and_ring_spin():
    """The Jeffcott rotor in floating rings: outer-ring whirl at 712.9 Hz, 96.0 Hz (docs/floating-ring.md,
    the classical eigenvalue threshold), and with the ring spin free slightly higher (715.3 Hz in the docs'
    line fit of eigenvalues along the run)."""
    from orchestrator.stability import stability
    sc = _load(JC_RING)
    held = stability(sc, speeds=(700.0, 730.0), n_scan=4)
    assert held["threshold_hz"] == pytest.approx(712.9, abs=0.05)
    assert held["whirl_hz"] == pytest.approx(96.0, abs=0.1)
    free = stability(sc, speeds=(700.0, 730.0), n_scan=4, ring_spin=True)
    assert free["threshold_hz"] == pytest.approx(715.3, abs=0.3)
    assert free["threshold_hz"] > held["threshold_hz"]


def test_scenario_parameters_reach_the_rings():
    """--set of a ring parameter gives the threshold of the hand-built model with that parameter."""
    from orchestrator.stability import stability
    from rotor_fmu.floating_ring_growth import turbocharger_floating_ring
    from rotor_fmu.floating_ring_stability import ring_threshold_speed
    sets = [f"fmus.{b}.parameters.{k}={v}" for b in ("bearing1", "bearing2")
            for k, v in (("eta0_outer", 0.02), ("m_ring", 0.01))]
    r = stability(_load(TC_RING, *sets), speeds=(30.0, 60.0), n_scan=6)
    rotor, rings = turbocharger_floating_ring()
    rings = [dataclasses.replace(p, outer=dataclasses.replace(p.outer, eta0=0.02), m_ring=0.01) for p in rings]
    wt, _ = ring_threshold_speed(rotor, rings, 2 * math.pi * 30.0, 2 * math.pi * 60.0, n_scan=6)
    assert r["threshold_hz"] == pytest.approx(wt / (2 * math.pi), rel=1e-5)
    assert abs(r["threshold_hz"] - 42.19) > 0.1          # the parameters changed the answer


def test_short_film_refused_for_rings(capsys):
    code, text, err = _run(capsys, TC_RING, "--film", "short")
    assert code == 1
    assert "--film short" in err and "no floating ring" in err and "--film hs" in err


def test_ring_spin_without_rings_refused(capsys):
    code, text, err = _run(capsys, JC_HS, "--ring-spin")
    assert code == 1
    assert "--ring-spin" in err and "no floating-ring bearings" in err


def test_semi_floating_ring_refused(capsys):
    # the outer film of a ring that does not spin carries no static load (singular stiffness at rest):
    # every speed failed, and the message advised raising the lower end of --speeds, which cannot help
    code, text, err = _run(capsys, TC_RING, "--speeds", "40:45", "--set", "fmus.bearing1.parameters.floating=0")
    assert code == 1
    assert "'bearing1' is semi-floating (floating = 0)" in err and "at any speed" in err
    assert "raise the lower end" not in err


def test_mixed_bearings_refused(capsys, tmp_path):
    """A floating ring at station 1 and a plain journal bearing at station 2: refused, naming both."""
    import yaml
    doc = yaml.safe_load(JC_RING.read_text())
    doc["fmus"]["bearing2"] = {"fmu": "JournalBearing", "parameters": {
        "R": 4.9e-3, "B": 7.84e-3, "psi": 2.8e-3, "eta0": 0.012, "p0": 1.0e5, "n_phi": 40, "n_z": 40,
        "cavitation": 0, "axial_bc": 0, "linearize": 1}}
    del doc["fmus"]["rotor"]["parameters"]["m_ring_2"]
    plain_out = {"Fx", "Fy", *(f"{k}{i}{j}" for k in "kc" for i in "xy" for j in "xy")}
    doc["connections"] = [c for c in doc["connections"] if not (c["from"].startswith("bearing2.") and
                                                                 c["from"].split(".")[1] not in plain_out)]
    ring_outputs = ("eps_outer", "omega_ring", "x_ring", "y_ring", "P_loss")
    doc["output"]["signals"] = [v for v in doc["output"]["signals"]
                                  if not (v.startswith("bearing2.") and v.split(".")[1] in ring_outputs)]
    f = tmp_path / "mixed.yaml"
    f.write_text(yaml.safe_dump(doc, sort_keys=False))
    code, out, err = _run(capsys, f)
    assert code == 1, err
    assert "floating-ring bearings ('bearing1')" in err and "plain journal bearings ('bearing2')" in err
    assert "one kind at every station" in err


def test_sideways_load_on_a_ring_refused(capsys):
    code, text, err = _run(capsys, TC_RING, "--load", "bearing1=5,0")
    assert code == 1
    assert "floating-ring bearing 'bearing1'" in err and "downward load" in err


def test_turbocharger_both_crossings_and_speeds_without_equilibrium():
    """Over 15-104 Hz: no ring operating point at the low end (the turbine-side ring's outer film would
    need more than 0.98 of its clearance), the inner-film whirl from 42.19 Hz and stable again from
    101.87 Hz (docs/scripts/floating_ring_turbocharger_threshold.py, the hand-built model: crossings at
    42.19 and 101.87 Hz, whirl 26.88 and 60.59 Hz)."""
    from orchestrator.stability import stability
    r = stability(_load(TC_RING), speeds=(15.0, 104.0), n_scan=30)
    assert r["status"] == "threshold"
    (up, down) = r["crossings"]
    assert up["speed_hz"] == pytest.approx(42.19, abs=0.01) and up["whirl_hz"] == pytest.approx(26.88, abs=0.01)
    assert down["becomes"] == "stable"
    assert down["speed_hz"] == pytest.approx(101.87, abs=0.01) and down["whirl_hz"] == pytest.approx(60.59, abs=0.01)
    bad = r["speeds_without_equilibrium_hz"]
    assert bad and bad[0] == pytest.approx(15.0) and max(bad) < 30.0
    note = next(n for n in r["notes"] if "no static equilibrium at" in n)
    assert "at low speed a ring's outer film may not carry its load" in note
    assert "raise the lower end" not in note         # the speeds were left out: advice for an error, not a note
