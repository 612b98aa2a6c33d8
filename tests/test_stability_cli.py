"""`rotorcosim stability`: the linear threshold of a scenario's rotor in its bearings.

References (independent of the eigenvalue path the command takes):
* short film: Lund's closed-form threshold of a Jeffcott rotor (disc on a flexible shaft, massless
  journals) on linear bearing coefficients (Lund 1974; Childs 1993 sec. 3.6,
  :func:`rotor_fmu.stability.lund_threshold_speed`);
* HS film: the documented threshold of the paper's Jeffcott rotor, docs/paper-cases.md "How R was
  chosen": R = 4.9 mm gives 256.1 Hz on the 40 x 40 film (eps 0.186, whirl 0.45 x speed), computed by
  docs/paper_cases_radius.py (the same Newton, bearing_fmu.linearize.hs_static_equilibrium, but its
  own central differences of the film force for the coefficients, and bisection for the threshold).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from hostile_builders import run_verb

from orchestrator.cli import main

REPO = Path(__file__).resolve().parents[1]
JEFFCOTT_HS = REPO / "scenarios" / "jeffcott_runup_half_sommerfeld.yaml"


def _run(capsys, *args):
    return run_verb(capsys, "stability", *args)


def test_short_film_matches_lund_closed_form(capsys, tmp_path):
    # massless journals (1e-4 kg against 2.5 kg of disc per bearing) and no damping outside the film:
    # the system of Lund's flexible-rotor criterion m nu^2 = K_eq k_s / (K_eq + k_s)
    from rotor_fmu.stability import lund_threshold_speed
    out = tmp_path / "r.json"
    code, text, err = _run(capsys, JEFFCOTT_HS, "--film", "short", "--speeds", "20:2000", "--json", out,
                           "--set", "fmus.rotor.parameters.m_journal=1e-4",
                           "--set", "fmus.rotor.parameters.d_external=0",
                           "--set", "fmus.rotor.parameters.d_internal=0")
    assert code == 0, err
    r = json.loads(out.read_text())
    m = 2.5 + 1e-4                      # mass (and gravity load) per bearing
    w = lund_threshold_speed(m, R=4.9e-3, L=7.84e-3, C=2.8e-3 * 4.9e-3, eta=0.012, k_shaft=0.5 * 4.0e6)
    assert r["threshold_hz"] == pytest.approx(w / (2 * math.pi), rel=1e-3)
    assert f"threshold speed: {r['threshold_hz']:.2f} Hz" in text
    assert r["film"] == "short" and r["status"] == "threshold"


def test_hs_film_reproduces_documented_threshold(capsys, tmp_path):
    out = tmp_path / "r.json"
    code, text, err = _run(capsys, JEFFCOTT_HS, "--json", out)
    assert code == 0, err
    r = json.loads(out.read_text())
    assert r["threshold_hz"] == pytest.approx(256.1, abs=0.3)      # docs/paper-cases.md
    assert r["whirl_ratio"] == pytest.approx(0.45, abs=0.01)
    for b in ("bearing1", "bearing2"):
        assert r["bearings"][b]["eps_at_threshold"] == pytest.approx(0.186, abs=0.005)
        assert r["bearings"][b]["load_n"] == pytest.approx((2.5 + 0.5) * 9.81, rel=1e-12)
        assert r["bearings"][b]["grid"] == [40, 40]
    assert "half-Sommerfeld" in r["method"] and "half-Sommerfeld" in text


def test_json_content_and_stable_range_exit(capsys, tmp_path):
    out = tmp_path / "r.json"
    code, text, err = _run(capsys, JEFFCOTT_HS, "--speeds", "100:200", "--json", out,
                           "--set", "fmus.bearing1.parameters.n_phi=16", "--set", "fmus.bearing1.parameters.n_z=8",
                           "--set", "fmus.bearing2.parameters.n_phi=16", "--set", "fmus.bearing2.parameters.n_z=8")
    assert code == 1
    assert "no eigenvalue crosses" in err and "100" in err and "200" in err
    r = json.loads(out.read_text())
    assert r["status"] == "stable" and r["threshold_hz"] is None and r["speed_range_hz"] == [100.0, 200.0]
    assert r["bearings"]["bearing1"]["grid"] == [16, 8]
    assert set(r) >= {"scenario", "rotor", "film", "method", "threshold_hz", "whirl_hz", "whirl_ratio",
                      "bearings", "notes", "status"}


def test_mass_conserving_bearing_is_said_to_be_hs_linearised(capsys):
    code, text, err = _run(capsys, REPO / "scenarios" / "jeffcott_runup_oil_bath.yaml", "--speeds", "150:400",
                           *[a for b in ("bearing1", "bearing2") for a in
                             ("--set", f"fmus.{b}.parameters.n_phi=16", "--set", f"fmus.{b}.parameters.n_z=8")])
    assert code == 0, err
    assert "mass-conserving (cavitation = 1)" in text and "HS linearisation" in text


def test_ring_mass_at_a_plain_bearing_refused(capsys):
    # m_ring_1 > 0 puts a ring into the rotor's step at station 1, where the scenario has a plain
    # JournalBearing: the scenario contradicts itself (floating-ring bearings: test_stability_floating_ring.py)
    code, text, err = _run(capsys, JEFFCOTT_HS, "--set", "fmus.rotor.parameters.m_ring_1=7.3e-3")
    assert code == 1
    assert "m_ring_1 is 0.0073 kg" in err and "plain JournalBearing 'bearing1'" in err and "set m_ring_1: 0" in err
    assert "supported: one of our JeffcottRotor or TurbochargerRotor FMUs" in err


def test_bearing_not_connected_by_station_convention_refused(capsys, tmp_path):
    text = JEFFCOTT_HS.read_text()
    line = "  - {from: rotor.vy_2, to: bearing2.vy}\n"
    assert line in text
    f = tmp_path / "no_vy2.yaml"
    f.write_text(text.replace(line, ""))
    code, out, err = _run(capsys, f)
    assert code == 1
    assert "lacks the connection rotor.vy_2 -> bearing2.vy" in err and "station convention" in err


def test_bad_speed_range_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["stability", str(JEFFCOTT_HS), "--speeds", "300:100"])
    assert exc.value.code == 2
    assert "LO:HI" in capsys.readouterr().err


def test_third_party_fmus_refused(capsys, tmp_path, test_fmus):
    from test_scenario_loader import scenario_dir
    d = scenario_dir(tmp_path, test_fmus)
    code, out, err = _run(capsys, d / "two_mass.yaml")
    assert code == 1
    assert "needs exactly one rotor FMU of ours" in err and "has 0" in err
    assert "supported: one of our JeffcottRotor or TurbochargerRotor FMUs" in err


def test_other_fmu_beside_rotor_and_bearings_refused(capsys, tmp_path, test_fmus):
    import shutil
    text = JEFFCOTT_HS.read_text()
    shutil.copy(test_fmus["Gain"], tmp_path / "Gain.fmu")
    text = text.replace("connections:\n", "  extra:\n    path: Gain.fmu\nconnections:\n", 1)
    text = text.replace("sequence: [rotor, bearing1, bearing2]", "sequence: [rotor, bearing1, bearing2, extra]")
    f = tmp_path / "extra.yaml"
    f.write_text(text)
    code, out, err = _run(capsys, f)
    assert code == 1
    assert "the FMU 'extra'" in err and "does not guess" in err


def test_load_option_sideways_load_gives_the_same_threshold(capsys, tmp_path):
    """--load with g = 0: the paper's Jeffcott rotor is isotropic and its bearings have no groove, so
    the weight share turned by 90 deg (sideways, 29.43 N in +x per bearing, a quarter turn = 10 of the
    40 cells of the film) is the same problem turned: the same threshold, whirl and eccentricity.
    The weight given as --load (g = 0, (0, -29.43) N) is the same problem outright."""
    base = tmp_path / "base.json"
    code, _, err = _run(capsys, JEFFCOTT_HS, "--speeds", "240:270", "--json", base)
    assert code == 0, err
    w = 29.43
    for k, (fx, fy) in enumerate(((w, 0.0), (0.0, -w))):
        out = tmp_path / f"r{k}.json"
        code, text, err = _run(capsys, JEFFCOTT_HS, "--speeds", "240:270", "--json", out,
                               "--set", "fmus.rotor.parameters.g=0",
                               "--load", f"bearing1={fx},{fy}", "--load", f"bearing2={fx},{fy}")
        assert code == 0, err
        a, b = json.loads(base.read_text()), json.loads(out.read_text())
        assert b["threshold_hz"] == pytest.approx(a["threshold_hz"], rel=1e-7)
        assert b["whirl_ratio"] == pytest.approx(a["whirl_ratio"], rel=1e-6)
        for name in ("bearing1", "bearing2"):
            assert b["bearings"][name]["eps_at_threshold"] == pytest.approx(a["bearings"][name]["eps_at_threshold"],
                                                                            rel=1e-6)
            assert b["bearings"][name]["load_vector_n"] == pytest.approx([fx, fy], abs=1e-9)
        assert "plus --load" in text


def test_load_option_errors(capsys):
    code, _, err = _run(capsys, JEFFCOTT_HS, "--load", "bearing9=0,-10")
    assert code == 1 and "no bearing 'bearing9'" in err and "bearing1, bearing2" in err
    with pytest.raises(SystemExit) as e:
        main(["stability", str(JEFFCOTT_HS), "--load", "bearing1=-10"])
    assert e.value.code == 2
    assert "expected BEARING=FX,FY" in capsys.readouterr().err
    code, _, err = _run(capsys, JEFFCOTT_HS, "--film", "short", "--set", "fmus.rotor.parameters.g=0",
                        "--load", "bearing1=0,-10")
    assert code == 1 and "'bearing2' (station 2) carries no static load" in err and "--load bearing2=FX,FY" in err


def test_whole_range_crossings_scan_and_plot(capsys, tmp_path):
    """The paper's Jeffcott rotor in HS films is unstable from 256.1 Hz and stable again higher up; the
    search evaluates the whole range (result["scan"]) and --plot draws it."""
    out, png = tmp_path / "r.json", tmp_path / "s.png"
    code, text, err = _run(capsys, JEFFCOTT_HS, "--json", out, "--plot", png)
    assert code == 0, err
    r = json.loads(out.read_text())
    up, down = r["crossings"]
    assert up["becomes"] == "unstable" and up["speed_hz"] == r["threshold_hz"]
    assert down["becomes"] == "stable" and 600.0 < down["speed_hz"] < 700.0
    scan = r["scan"]
    assert scan[0]["speed_hz"] == pytest.approx(80.0) and scan[-1]["speed_hz"] == pytest.approx(800.0)
    for s in scan:           # the sign of the largest real part agrees with the crossings found
        inside = up["speed_hz"] < s["speed_hz"] < down["speed_hz"]
        if abs(s["speed_hz"] - up["speed_hz"]) > 1e-6 and abs(s["speed_hz"] - down["speed_hz"]) > 1e-6:
            assert (s["max_re_per_s"] > 0) == inside, s
            assert s["log_decrement"] == pytest.approx(-s["max_re_per_s"] / s["whirl_hz"], rel=1e-12)
    assert f"then stable from {down['speed_hz']:.2f} Hz on" in text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"written: {png}" in text


def test_load_cancelling_the_weight_is_named(capsys):
    # the user gave the film's reaction (up) instead of the load (down): weight + load = rounding only
    code, _, err = _run(capsys, JEFFCOTT_HS, "--load", "bearing1=0,29.43")
    assert code == 1
    assert "--load bearing1=0,29.43 cancels the bearing's share of the rotor's weight" in err
    assert "not its reaction" in err


def test_already_unstable_at_the_lower_end_still_names_where_it_becomes_stable(capsys, tmp_path):
    """From 300 Hz (inside the paper rotor's unstable window 256.1 - 665.0 Hz) the first crossing is the
    one where it becomes stable again: printed and drawn like any crossing after a threshold (the CLI
    and the plot skipped the first crossing whatever it was, and so lost it)."""
    from orchestrator.stability import later_crossings
    out, png = tmp_path / "r.json", tmp_path / "s.png"
    code, text, err = _run(capsys, JEFFCOTT_HS, "--speeds", "300:800", "--json", out, "--plot", png)
    assert code == 1 and "already unstable at the lower end" in err
    r = json.loads(out.read_text())
    assert r["status"] == "unstable_at_lower_bound" and r["threshold_hz"] is None
    (down,) = r["crossings"]
    assert down["becomes"] == "stable" and 600.0 < down["speed_hz"] < 700.0
    assert later_crossings(r) == [down]
    assert f"then stable from {down['speed_hz']:.2f} Hz on" in text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_instability_beginning_where_no_equilibrium_is_found_is_not_a_threshold(capsys, tmp_path, monkeypatch):
    """The short-film paper rotor is unstable from 262.14 Hz and stable again from 575.04 Hz. With no
    static equilibrium between 240 and 300 Hz (here made so), the sign change lies across speeds left
    out: the threshold is not located there. It was taken as the first crossing found, the one where
    the system becomes *stable* (575 Hz), with exit 0 (and, without a later crossing, as "stable")."""
    import orchestrator.stability as st
    call = st._ShortFilm.__call__

    def gap(self, omega):
        if 240.0 <= omega / (2 * math.pi) <= 300.0:
            raise st._failed(self.system.bearings[0], omega, ValueError("made to fail here"))
        return call(self, omega)
    monkeypatch.setattr(st._ShortFilm, "__call__", gap)
    out, png = tmp_path / "r.json", tmp_path / "s.png"
    code, text, err = _run(capsys, JEFFCOTT_HS, "--film", "short", "--speeds", "100:800", "--json", out, "--plot", png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert code == 1 and "becomes unstable between" in err and "not located" in err
    r = json.loads(out.read_text())
    assert r["status"] == "threshold_not_located" and r["threshold_hz"] is None
    a, b = r["threshold_between_hz"]
    assert 230.0 < a < 240.0 and 300.0 < b < 310.0
    (down,) = r["crossings"]
    assert down["becomes"] == "stable" and down["speed_hz"] == pytest.approx(575.04, abs=0.01)
    assert f"then stable from {down['speed_hz']:.2f} Hz on" in text
    assert any("changes sign between" in n for n in r["notes"])
