"""Ninth probe (after tests/test_hostile_probe8.py): the physical values of a rotor file and of the
rotor FMUs' parameters, then `stability`, `init`, sweep files and `--set` values as a hostile
user writes them. One test per finding, each failing on the code before its fix."""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest

from hostile_builders import cli, run_verb
from orchestrator.errors import ScenarioError
from rotor_fmu.rotor_file import RANGES, load_rotor_file
from tests.test_rotor_file_hostile import GOOD, refused

REPO = Path(__file__).resolve().parents[1]
JEFFCOTT_HS = REPO / "scenarios" / "jeffcott_runup_half_sommerfeld.yaml"
TURBO_HS = REPO / "scenarios" / "turbocharger_runup_half_sommerfeld.yaml"
COARSE = [a for b in ("bearing1", "bearing2") for a in
          ("--set", f"fmus.{b}.parameters.n_phi=16", "--set", f"fmus.{b}.parameters.n_z=8")]


def rotor(tmp_path, old: str, new: str, name: str = "r.yaml") -> Path:
    """The shipped turbocharger rotor file with ``old`` replaced by ``new``."""
    assert old in GOOD, old
    p = tmp_path / name
    p.write_text(GOOD.replace(old, new, 1))
    return p


# --------------------------------------------------------------------------- rotor files
@pytest.mark.parametrize("old, new, words", [
    # E: 1e300 built a rotor whose stability was "already unstable at 10.5 Hz" (silent garbage)
    ("E: 2.1e11", "E: 1.0e300", ["line 47: 'materials.steel.E' = 1e+300 is outside the accepted range "
                                 "[1e+07, 1e+14] Pa", "Young's modulus in Pa", "give a value inside the range"]),
    ("E: 2.1e11", "E: 210", ["'materials.steel.E' = 210 is outside", "210 GPa"]),           # GPa for Pa
    # nu: -1 ended in "internal error: ZeroDivisionError" (G = E / (2 (1 + nu)))
    ("nu: 0.3", "nu: -1", ["line 47: 'materials.steel.nu' = -1 is outside the accepted range [0, 0.5]"]),
    # rho: 1e-300 ended in "IndexError: index 0 is out of bounds" inside the Craig-Bampton basis
    ("rho: 7850.0", "rho: 1.0e-300", ["'materials.steel.rho' = 1e-300 is outside the accepted range "
                                      "[100, 30000] kg/m^3"]),
    ("rho: 7850.0", "rho: 7.85", ["'materials.steel.rho' = 7.85", "7.85 g/cm^3"]),          # g/cm^3 for kg/m^3
    ("rho: 7850.0", "rho: 0", ["'materials.steel.rho' must be > 0 (got 0)", "accepted range"]),
    ("rho: 7850.0", "rho: nan", ["'materials.steel.rho' must be a finite number in SI units (got 'nan')"]),
    ("rho: 7850.0", "rho: 7850.0, G: -5",
     ["'materials.steel.G' must be > 0 (got -5): it is outside the accepted range [1e+06, 1e+14] Pa"]),
    ("{length: 0.056, d_outer: 0.007", "{length: 1.0e300, d_outer: 7",
     ["line 52: 'shaft.sections[0].length' = 1e+300 is outside the accepted range [1e-06, 100] m",
      "line 52: 'shaft.sections[0].d_outer' = 7 is outside", "7 mm is 0.007"]),
    ("z_start: 0.0", "z_start: 1.0e300", ["line 49: 'shaft.z_start' = 1e+300 is outside"]),
    # a NaN element length ended in "ValueError: cannot convert float NaN to integer"
    ("max_element_length: 0.006", "max_element_length: .nan",
     ["line 50: 'shaft.max_element_length' must be a finite number"]),
    ("internal_damping: 0.0", "internal_damping: 5",
     ["line 65: 'internal_damping' = 5 is outside the accepted range [0, 0.1] s"]),
    # an unbalance in g mm (1.5 for 1.5e-6 kg m) and a phase in degrees were taken as they came
    ("unbalance: 1.5e-6, unbalance_phase: 0.0", "unbalance: 1.5, unbalance_phase: 90",
     ["'discs[0].unbalance_phase' = 90 is outside", "90 degrees is 1.5708",
      "'discs[0].unbalance' = 1.5 kg m on a disc of 1.65 kg is an eccentricity of 0.909091 m",
      "1.5 g mm is 1.5e-6"]),
    ("mass: 1.6500", "mass: 1.0e300", ["'discs[0].mass' = 1e+300 is outside the accepted range [0, 1e+06] kg"]),
    ("Ip: 2.7844e-3", "Ip: -1", ["'discs[0].Ip' = -1 is outside the accepted range [0, 1e+07] kg m^2"]),
])
def test_physical_fields_of_a_rotor_file_are_bounded(tmp_path, old, new, words):
    refused(rotor(tmp_path, old, new), *words)


@pytest.mark.parametrize("old, new, words", [
    # a disc named '1' made the FMU's y_1 (bearing station 1, coupled to bearing1) the compressor
    # wheel's y, 4.5 clearances below the journal; two discs named 'comp' made y_comp the second one's
    ("name: comp,", "name: '1',", ["line 58: 'discs[0].name' is '1', a number", "bearing station 1"]),
    ("name: turb,", "name: comp,", ["line 59: 'discs[1].name' is 'comp', the name of an earlier disc too"]),
])
def test_disc_names_that_would_replace_other_outputs_are_refused(tmp_path, old, new, words):
    refused(rotor(tmp_path, old, new), *words)


@pytest.mark.parametrize("digits", [401, 5001])
def test_a_huge_integer_in_a_rotor_file_is_named_by_its_line(tmp_path, digits):
    # 401 digits: "TypeError: ufunc 'isfinite' not supported"; 5001: "ValueError: Exceeds the limit
    # (4300 digits) for integer string conversion", both without the file
    refused(rotor(tmp_path, "E: 2.1e11", "E: 1" + "0" * (digits - 1)),
            f"line 47: an integer of {digits} digits (more than 40)")


def test_every_physical_field_has_a_range_and_the_shipped_rotor_is_inside():
    assert {"E", "G", "nu", "rho", "length", "d_outer", "d_inner", "z_start", "z", "mass", "Ip", "Id",
            "unbalance", "unbalance_phase", "internal_damping"} <= set(RANGES)
    assert len(load_rotor_file().elements) == 33


def test_stability_and_validate_name_the_rotor_file_field(capsys, tmp_path):
    bad = rotor(tmp_path, "E: 2.1e11", "E: 1.0e300")
    code, out, err = run_verb(capsys, "stability", TURBO_HS, "--film", "short",
                              "--set", f"fmus.rotor.parameters.rotor_file={bad}")
    assert code == 1 and "already unstable" not in err, err
    assert f"invalid rotor file {bad}" in err and "'materials.steel.E' = 1e+300 is outside" in err, err
    bad = rotor(tmp_path, "nu: 0.3", "nu: -1", "nu.yaml")
    rc, text = cli(capsys, "validate", TURBO_HS, "--set", f"fmus.rotor.parameters.rotor_file={bad}")
    assert rc == 1 and "ZeroDivisionError" not in text, text
    assert f"invalid rotor file {bad} (parameter 'rotor_file')" in text and "'materials.steel.nu' = -1" in text


# --------------------------------------------------------------------------- rotor FMU parameters
@pytest.mark.parametrize("setting, words", [
    # k_shaft=1e300: "already unstable at the lower end of the range (80 Hz)" (the threshold is 374 Hz
    # for any k_shaft from 1e11 to 1e15)
    ("k_shaft=1e300", ["'rotor.k_shaft' = 1e+300 is outside its declared range [1.0, 10000000000000.0]"]),
    ("m_journal=1e-300", ["'rotor.m_journal' = 1e-300 is outside its declared range"]),      # "stable"
    ("m_disc=1e300", ["'rotor.m_disc' = 1e+300 is outside"]),
    ("unbalance_phase=90", ["'rotor.unbalance_phase' = 90.0 is outside"]),
    # 1e-300 ended a run in numba's "TypingError ... Int value is too large"; 1e-9 hung it
    ("max_phase_per_substep=1e-300", ["'rotor.max_phase_per_substep' = 1e-300 is outside its declared range "
                                      "[0.001, inf]"]),
])
def test_rotor_parameters_are_bounded_when_the_scenario_is_loaded(capsys, setting, words):
    rc, text = cli(capsys, "validate", JEFFCOTT_HS, "--no-build", "--set", f"fmus.rotor.parameters.{setting}")
    assert rc == 1, text
    for w in words:
        assert w in text, text


def test_the_models_check_the_same_ranges_and_bound_their_substeps():
    from rotor_fmu.jeffcott import JeffcottModel, JeffcottParams
    from rotor_fmu.jeffcott_rotor import PARAMETER_RANGES
    from rotor_fmu.param_ranges import RANGES as ROTOR_RANGES
    from rotor_fmu.turbocharger import TurbochargerParams, TurbochargerRotor
    assert PARAMETER_RANGES["k_shaft"] == ROTOR_RANGES["k_shaft"][:2] == (1.0, 1e13)
    with pytest.raises(ValueError, match=r"JeffcottParams.k_shaft must be >= 1 and <= 1e\+13 N/m and finite"):
        JeffcottModel(JeffcottParams(k_shaft=1e300))
    with pytest.raises(ValueError, match=r"TurbochargerParams.n_modes must be an integer >= 0 and <= 500"):
        TurbochargerRotor(TurbochargerParams(n_modes=10**9))
    r = JeffcottModel(JeffcottParams(max_phase_per_substep=1e-3))
    with pytest.raises(ValueError, match="more than 10000000; use a smaller macro step"):
        r.n_substeps(1e3)
    assert r.n_substeps(1e-4) > 1


# --------------------------------------------------------------------------- stability
@pytest.mark.parametrize("option", ["--json", "--plot"])
def test_stability_refuses_an_empty_output_name(capsys, option):
    # `--json ''` / `--plot ''` wrote nothing and said nothing (exit 0)
    with pytest.raises(SystemExit) as exc:
        run_verb(capsys, "stability", JEFFCOTT_HS, "--film", "short", option, "")
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "an empty file name" in err and f"leave {option} out" in err, err


def test_stability_speeds_whose_angular_speed_overflows_are_refused(capsys):
    # --speeds 1:1e308: 2 pi HI overflowed, 79 of the 80 speeds were inf ("invalid value encountered
    # in multiply"), and the one left made it "linearly stable between 1 and 1e+308 Hz"
    code, out, err = run_verb(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--speeds", "1:1e308")
    assert code == 1 and "stable" not in out + err.replace("--speeds", ""), err
    assert "--speeds: need 0 < LO < HI <= 1e+07 in Hz (got 1:1e+308)" in err, err


def test_stability_film_too_stiff_at_high_speed_is_not_told_to_raise_the_lower_end(capsys):
    # the Newton search ended at eccentricity 0 (a film far stiffer than its load): the advice was
    # "raise the lower end of --speeds", which makes it worse
    code, out, err = run_verb(capsys, "stability", JEFFCOTT_HS, *COARSE, "--speeds", "1e5:1e6",
                              "--set", "fmus.bearing1.parameters.eta0=10", "--set", "fmus.bearing1.parameters.B=4")
    assert code == 1 and "no half-Sommerfeld static equilibrium" in err, err
    assert "raise the lower end" not in err and "nearer the rotor's running speeds" in err, err


# --------------------------------------------------------------------------- init
@pytest.mark.parametrize("force", [False, True])
def test_init_never_writes_through_a_link_in_the_folder(capsys, tmp_path, force):
    # a dangling link DIR/quickstart.yaml -> elsewhere made `init DIR` create the file it pointed to;
    # with --force a link to an existing file had that file overwritten by the scenario
    victim = tmp_path / "victim.yaml"
    if force:
        victim.write_text("mine\n")
    dest = tmp_path / "scen"
    dest.mkdir()
    (dest / "quickstart.yaml").symlink_to(victim)
    rc, text = cli(capsys, "init", dest, *(["--force"] if force else []))
    if force:
        assert rc == 0 and victim.read_text() == "mine\n", text
        copy = dest / "quickstart.yaml"
        assert not copy.is_symlink() and "name: quickstart" in copy.read_text()
    else:
        assert rc == 1 and not victim.exists(), text
        assert "1 scenario file(s) exist already (quickstart.yaml)" in text and "--force" in text, text


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs named pipes")
def test_init_names_a_fifo_in_the_folder_and_the_fix(capsys, tmp_path):
    dest = tmp_path / "scen"
    dest.mkdir()
    os.mkfifo(dest / "quickstart.yaml")
    rc, text = cli(capsys, "init", dest, "--force")
    assert rc == 1
    assert f"{dest / 'quickstart.yaml'}: is a named pipe (FIFO), where init would write the scenario" in text
    assert "remove it or pick another folder" in text, text


# --------------------------------------------------------------------------- quoted .nan / .inf
@pytest.mark.parametrize("setting, got", [
    ('fmus.rotor.parameters.d_internal=".nan"', "'rotor.d_internal' is Real and must be finite (got nan)"),
    ('stop_time=".inf"', "'stop_time' must be a finite number"),
])
def test_a_quoted_nan_or_inf_is_refused_not_an_internal_error(capsys, setting, got):
    # "internal error: ValueError: could not convert string to float: '.nan'"
    rc, text = cli(capsys, "validate", JEFFCOTT_HS, "--no-build", "--set", setting)
    assert rc == 1 and got in text, text


# --------------------------------------------------------------------------- sweep files
def _sweep(tmp_path, parameters: str) -> Path:
    (tmp_path / "q.yaml").write_text((REPO / "scenarios" / "quickstart.yaml").read_text())
    p = tmp_path / "s.yaml"
    p.write_text(f"sweep: 1\nscenario: q.yaml\nparameters:\n{parameters}")
    return p


def test_a_linspace_over_the_whole_float_range_has_its_real_values(tmp_path):
    # [-1e308, 1e308, 3] gave [nan, inf, inf] ("the values of parameter 'k' repeat")
    from orchestrator.sweep.spec import load_sweep
    spec = load_sweep(_sweep(tmp_path, "  - {name: k, set: [fmus.rotor.parameters.d_external], "
                                       "linspace: [-1.0e308, 1.0e308, 3]}\n"))
    assert spec.parameters[0].values == (-1e308, 0.0, 1e308)
    assert all(math.isfinite(v) for v in spec.parameters[0].values)


def test_sweep_values_that_are_one_number_are_a_repetition(tmp_path):
    # [1.0, "1.0", 1] made three runs of the same d_internal = 1.0, three rows of "different" values
    from orchestrator.sweep.spec import SweepError, load_sweep
    with pytest.raises(SweepError) as exc:
        load_sweep(_sweep(tmp_path, "  - {name: j, set: [fmus.rotor.parameters.d_internal], "
                                    "values: [1.0, '1.0', 1]}\n"))
    assert "s.yaml:4: the values of parameter 'j' repeat" in str(exc.value)
    spec = load_sweep(_sweep(tmp_path, "  - {name: j, set: [fmus.rotor.parameters.d_internal], "
                                       "values: [1.0, '.nan', 'a', true]}\n"))
    assert len(spec.parameters[0].values) == 4


def test_rotor_file_ranges_are_documented():
    text = (REPO / "docs" / "limits.md").read_text()
    assert "rotor_fmu.rotor_file.RANGES" in text
    assert "rotor_fmu.param_ranges.RANGES" in (REPO / "docs" / "fmus.md").read_text()


def test_scenario_error_is_what_a_bad_rotor_parameter_raises_from_the_api():
    from orchestrator.scenario import load_scenario
    with pytest.raises(ScenarioError, match=r"'rotor.k_shaft' = 1e\+300 is outside"):
        load_scenario(JEFFCOTT_HS, ["fmus.rotor.parameters.k_shaft=1e300"])


# --------------------------------------------------------------------------- floating rings
RING_HS = REPO / "scenarios" / "jeffcott_runup_floating_ring_half_sommerfeld.yaml"


@pytest.mark.parametrize("setting, words", [
    # h_ring=1e-300: 1e296 ring sub-steps per FMU step, the run hung (a first SIGTERM did not stop it)
    ("h_ring=1e-300", ["'bearing1.h_ring' = 1e-300 is outside its declared range [1e-08, 1.0]"]),
    # m_ring=1e300: `stability` said "at low speed a ring's outer film may not carry its load; raise the
    # lower end of --speeds"
    ("m_ring=1e300", ["'bearing1.m_ring' = 1e+300 is outside its declared range [1e-06, 1000.0]"]),
    ("J_ring=0", ["'bearing1.J_ring' = 0.0 is outside"]),
    ("gravity=1e300", ["'bearing1.gravity' = 1e+300 is outside"]),
])
def test_floating_ring_parameters_are_bounded_when_the_scenario_is_loaded(capsys, setting, words):
    rc, text = cli(capsys, "validate", RING_HS, "--no-build", "--set", f"fmus.bearing1.parameters.{setting}")
    assert rc == 1, text
    for w in words:
        assert w in text, text


def test_the_ring_model_checks_the_same_ranges_and_bounds_its_substeps():
    from bearing_fmu.floating_ring import FloatingRing
    from bearing_fmu.floating_ring_statics import MAX_RING_SUBSTEPS, RingParams
    from bearing_fmu.model import BearingParams
    films = {s: BearingParams(R=r, B=7.84e-3, psi=psi, eta0=0.012, n_phi=16, n_z=8, cavitation=0)
             for s, r, psi in (("inner", 4.9e-3, 2.8e-3), ("outer", 7.84e-3, 3.5e-3))}
    with pytest.raises(ValueError, match=r"RingParams.h_ring must be a finite number in \[1e-08, 1\] s"):
        RingParams(**films, h_ring=1e-300)
    m = FloatingRing(RingParams(**films, h_ring=1e-8))
    journal = (1.7e-5, -1.7e-5, 0.0, 0.0, 2 * math.pi * 300)
    m.initialize(*journal, ring="equilibrium")
    with pytest.raises(ValueError, match=f"more than {MAX_RING_SUBSTEPS}; use a larger h_ring"):
        m.step(1.0, *journal)


def test_stability_json_never_replaces_the_scenario_or_another_file(capsys, tmp_path):
    # `stability s.yaml --json s.yaml` replaced the scenario itself with the report (as `export-ssp
    # s.yaml s.yaml` once did); a run's summary.json was replaced the same way
    scen = tmp_path / "s.yaml"
    scen.write_text(JEFFCOTT_HS.read_text())
    summary = tmp_path / "summary.json"
    summary.write_text('{"status": "finished"}\n')
    for target, why in ((scen, "it is the scenario file"), (summary, "it is JSON of something else")):
        before = target.read_text()
        code, out, err = run_verb(capsys, "stability", scen, "--film", "short", "--json", target)
        assert code == 1 and target.read_text() == before, err
        assert f"{target}: exists and is not a stability report ({why}" in err and "give a new name" in err, err
    report = tmp_path / "r.json"
    for _ in range(2):                      # a new name, then the earlier report: written both times
        code, out, err = run_verb(capsys, "stability", scen, "--film", "short", "--json", report)
        assert code == 0 and f"written: {report}" in out, err


# --------------------------------------------------------------------------- rounding of the span
def test_a_step_or_interval_equal_to_the_run_up_to_rounding_is_accepted():
    # stop_time 0.5002, start 0.5: the span is 0.00019999999999997797, and an output interval (or
    # a macro step) of 2e-4 was refused as "must not exceed stop_time - start_time" (a sweep of short
    # runs refused every run)
    from orchestrator.scenario import load_scenario
    quick = REPO / "scenarios" / "quickstart.yaml"
    sc = load_scenario(quick, ["stop_time=0.5002", "output.interval=2e-4", "coupling.macro_step=2e-4"])
    assert sc.coupling.macro_step == 2e-4
    with pytest.raises(ScenarioError, match=r"'output.interval' must not exceed stop_time - start_time"):
        load_scenario(quick, ["stop_time=0.5002", "output.interval=2.0001e-4"])


def test_too_many_angle_bins_names_the_time_span_not_only_the_speed():
    # a results.csv with a time column of 1e305 s per row at 280 Hz was blamed on the speed's unit
    import numpy as np

    from orchestrator.results.whirl import too_many_bins
    t = np.arange(1000) * 1e305
    why = too_many_bins(t, np.full(1000, 1759.29), 32)
    assert "over 9.99e+307 s of recorded time" in why and "Is the time in s?" in why, why
    assert "is the speed in rad/s?" in why


# --------------------------------------------------------------------------- results.csv rows
def test_a_results_csv_longer_than_any_run_writes_is_refused(tmp_path, monkeypatch, capsys):
    # no bound on the rows: a tampered results.csv of 10^9 short rows was read until the memory ran out
    from orchestrator.results.run_directory import read_results
    from orchestrator.scenario import limits
    monkeypatch.setattr(limits, "MAX_OUTPUT_ROWS", 1000)
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.csv").write_text("time,a.y\n" + "".join(f"{i * 1e-3},1.0\n" for i in range(300_000)))
    with pytest.raises(ValueError) as exc:
        read_results(run / "results.csv")
    assert str(exc.value).startswith(f"{run / 'results.csv'}:1004: more than 1002 rows"), exc.value
    assert "orchestrator.scenario.limits.MAX_OUTPUT_ROWS" in str(exc.value)
    rc, text = cli(capsys, "plot", run)
    assert rc == 1 and "more than 1002 rows" in text, text
    (run / "results.csv").write_text("time,a.y\n" + "".join(f"{i * 1e-3},1.0\n" for i in range(1002)))
    assert len(read_results(run / "results.csv")["time"]) == 1002
