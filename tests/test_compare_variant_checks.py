"""``rotorcosim compare``: every variant's values go through the scenario loader's checks when the
comparison file is loaded, before anything runs, and a problem names the comparison file's line of
the value, the variant, what was expected, what came and the fix.

Before, a variant's values (``set: {bearing1.n_phi: 2.5}``, ``macro_step: 5e-3``) were applied to
the already checked base scenario and checked by no one: a bad value was found when that variant's
FMU started (after the reference and the earlier variants had run), or not at all (a variant that
changed an analysed bearing's psi was analysed against the base's clearance). No FMU is run here:
the runner given to ``main_compare`` fails the test if it is ever called.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hostile_builders import cli
from orchestrator.compare import CompareSpecError, load_compare, main_compare

SCENARIO = """\
name: variants
start_time: 0.5
stop_time: 0.502
fmus:
  rotor:
    fmu: JeffcottRotor
    parameters: {{f_max: 800.0, t_ramp: 2.0}}
  bearing1:
    fmu: {bearing}
    parameters: {params}
connections:
  - {{from: rotor.x_1, to: bearing1.x}}
  - {{from: bearing1.Fx, to: rotor.Fx_1}}
coupling: {{scheme: gauss-seidel, macro_step: 1.0e-4}}
{analysis}"""

ANALYSIS = """\
analysis:
  speed: rotor.omega
  journals:
    bearing1: {x: rotor.x_1, y: rotor.y_1, eps: bearing1.eps{clearance}}
"""

COMPARE = """\
compare:
  scenario: s.yaml
  signals: [rotor.x_1]
  reference: {{scheme: gauss-seidel, macro_step: 1.0e-5}}
  variants:
    - {{macro_step: 1.0e-4}}
    - {{name: bad, macro_step: 1.0e-4,
       set: {{{values}}}}}
"""
#        line 8 of the comparison file: the 'set' of variant 'bad' (variants[1])


def _never_runs(scenario, out_dir: Path) -> None:
    raise AssertionError("a run was started although the comparison file is invalid")


def _files(tmp_path: Path, values: str, *, bearing: str = "JournalBearing", analysis: str = "",
           compare: str = COMPARE) -> Path:
    params = "{cavitation: 0}" if bearing == "JournalBearing" else "{}"
    (tmp_path / "s.yaml").write_text(SCENARIO.format(bearing=bearing, params=params, analysis=analysis))
    path = tmp_path / "cmp.yaml"
    path.write_text(compare.format(values=values))
    return path


def _write(tmp_path: Path, values: str) -> Path:
    path = tmp_path / "cmp.yaml"
    path.write_text(COMPARE.format(values=values))
    return path


def _problems(path: Path) -> str:
    with pytest.raises(CompareSpecError) as exc:
        load_compare(path)
    return str(exc.value)


BAD = "cmp.yaml:8: 'compare.variants[1].set' variant 'bad' sets "


@pytest.mark.parametrize("values, words", [
    ("bearing1.psi: 0.5",
     ["bearing1.psi: 0.5: parameter 'bearing1.psi' = 0.5 is outside its declared range [0.0001, 0.1]",
      "give a value inside the range"]),
    ("bearing1.psi: 1.0e-6",
     ["bearing1.psi: 1e-06: parameter 'bearing1.psi' = 1e-06 is outside its declared range [0.0001, 0.1]"]),
    ("bearing1.n_phi: 4",
     ["bearing1.n_phi: 4: parameter 'bearing1.n_phi' = 4 is outside its declared range [8, 8192]"]),
    ("bearing1.n_phi: 9000",
     ["bearing1.n_phi: 9000: parameter 'bearing1.n_phi' = 9000 is outside its declared range [8, 8192]"]),
], ids=["real-above-max", "real-below-min", "integer-below-min", "integer-above-max"])
def test_a_variant_parameter_outside_the_fmu_range_is_refused_at_load(tmp_path, values, words):
    msg = _problems(_files(tmp_path, values))
    assert BAD + words[0] in msg, msg
    for w in words[1:]:
        assert w in msg, msg


@pytest.mark.parametrize("values, words", [
    ("rotor.t_ramp: fast", "rotor.t_ramp: 'fast': parameter 'rotor.t_ramp' is Real (got 'fast', a string); "
                           "write a Real value such as 1.5"),
    ("bearing1.n_phi: 2.5", "bearing1.n_phi: 2.5: parameter 'bearing1.n_phi' is Integer (got 2.5, a number)"),
    ("rotor.t_ramp: true", "rotor.t_ramp: True: parameter 'rotor.t_ramp' is Real (got True, a boolean)"),
    ("bearing1.n_phi: true", "bearing1.n_phi: True: parameter 'bearing1.n_phi' is Integer (got True, a boolean)"),
], ids=["string-for-real", "fraction-for-integer", "bool-for-real", "bool-for-integer"])
def test_a_variant_parameter_of_the_wrong_type_is_refused_at_load(tmp_path, values, words):
    msg = _problems(_files(tmp_path, values))
    assert BAD + words in msg, msg


def test_an_unknown_parameter_of_a_variant_is_refused_with_the_closest_names(tmp_path):
    msg = _problems(_files(tmp_path, "bearing1.n_ph: 40"))
    assert BAD + "bearing1.n_ph: 40: 'bearing1' has no parameter 'n_ph'; parameters of 'bearing1' (closest " \
                 "first): n_phi" in msg, msg


def test_every_problem_of_every_variant_is_listed_at_once(tmp_path):
    msg = _problems(_files(tmp_path, "bearing1.psi: 0.5, rotor.t_ramp: fast, bearing1.nope: 1"))
    for w in ("bearing1.psi: 0.5:", "rotor.t_ramp: 'fast':", "bearing1.nope: 1:"):
        assert BAD + w in msg, msg
    assert "gs-e0i0-h0.0001" not in msg, msg            # the good variant is not named


@pytest.mark.parametrize("values, grid, words", [
    ("bearing1.n_phi: 8000", "n_phi x n_z = 8000 x 40 = 320000 film cells",
     ["; n_z = 40 is the FMU's default;", "n_phi <= 6553 at n_z = 40"]),
    ("bearing1.n_phi: 4096, bearing1.n_z: 100", "n_phi x n_z = 4096 x 100 = 409600 film cells",
     ["; n_phi from bearing1.n_phi: 4096; n_z from bearing1.n_z: 100;"]),
], ids=["n_z-default", "both-set"])
def test_a_journal_bearing_grid_over_the_cell_limit_in_a_variant_is_refused(tmp_path, values, grid, words):
    spec = load_compare(_files(tmp_path, "bearing1.n_phi: 4096, bearing1.n_z: 64"))    # exactly the limit: loads
    assert spec.variants[1].changes["bearing1.n_phi"] == 4096
    msg = _problems(_files(tmp_path, values))
    assert BAD + values.split(",")[0] + ": " in msg and grid in msg, msg
    assert "more than the 262144 a film grid may have (MAX_FILM_CELLS, bearing_fmu/limits.py)" in msg, msg
    for w in words:
        assert w in msg, msg


@pytest.mark.parametrize("side", ["inner", "outer"])
def test_a_floating_ring_grid_over_the_cell_limit_in_a_variant_is_refused(tmp_path, side):
    msg = _problems(_files(tmp_path, f"bearing1.n_phi_{side}: 8000", bearing="FloatingRingBearing"))
    assert BAD + f"bearing1.n_phi_{side}: 8000: " in msg, msg
    assert f"n_phi_{side} x n_z_{side} = 8000 x 40 = 320000 film cells" in msg, msg


def test_a_variant_macro_step_longer_than_the_run_is_refused_at_its_line(tmp_path):
    compare = COMPARE.replace("- {{macro_step: 1.0e-4}}", "- {{macro_step: [1.0e-4, 5.0e-3]}}")
    msg = _problems(_files(tmp_path, "rotor.t_ramp: 2.0", compare=compare))
    assert ("cmp.yaml:6: 'compare.variants[0].macro_step' variant 'gs-e0i0-h0.005' sets macro_step: 0.005: "
            "'coupling.macro_step' must not exceed stop_time - start_time") in msg, msg
    assert "use a smaller step" in msg, msg


@pytest.mark.parametrize("values, words", [
    ("coupling.discard_retries: 99", "coupling.discard_retries: 99: 'coupling.discard_retries' must be between 0 and 30"),
    ("coupling.call_timeout: -1", "coupling.call_timeout: -1: 'coupling.call_timeout' must be positive"),
    ("output.interval: 1.0", "output.interval: 1.0: 'output.interval' must not exceed stop_time - start_time"),
], ids=["discard_retries", "call_timeout", "output-interval"])
def test_coupling_and_output_keys_of_a_variant_are_checked_as_the_loader_checks_them(tmp_path, values, words):
    msg = _problems(_files(tmp_path, values))
    assert BAD + words in msg, msg


def test_a_problem_of_the_comparisons_own_set_is_reported_once_at_its_line(tmp_path):
    compare = COMPARE.replace("  signals: [rotor.x_1]\n", "  signals: [rotor.x_1]\n  set: {{bearing1.psi: 0.5}}\n")
    msg = _problems(_files(tmp_path, "rotor.t_ramp: 2.0", compare=compare))
    line = "cmp.yaml:4: 'compare.set' sets bearing1.psi: 0.5: parameter 'bearing1.psi' = 0.5 is outside its declared"
    assert msg.count(line) == 1 and msg.count("bearing1.psi: 0.5:") == 1, msg


@pytest.mark.parametrize("clearance", [", clearance: 1.372e-5", ""], ids=["written", "left-out"])
def test_a_variant_that_changes_an_analysed_bearings_clearance_is_refused(tmp_path, clearance):
    analysis = ANALYSIS.replace("{clearance}", clearance)
    (tmp_path / "s.yaml").write_text(SCENARIO.format(bearing="JournalBearing", analysis=analysis,
                                                     params="{cavitation: 0, R: 4.9e-3, psi: 2.8e-3}"))
    load_compare(_write(tmp_path, "bearing1.psi: 1.4e-3, bearing1.R: 9.8e-3"))   # psi R unchanged: loads
    msg = _problems(_write(tmp_path, "bearing1.psi: 2.0e-3"))
    assert BAD + "bearing1.psi: 0.002: 'analysis.journals.bearing1.clearance' is 1.372e-05 m, but the bearing it " \
                 "analyses, 'bearing1'" in msg, msg
    assert "c = psi R = 0.002 x 0.0049 m = 9.8e-06 m" in msg, msg
    assert ("every run of a comparison is analysed with the base scenario's clearance (1.372e-05 m): change psi "
            "and R together") in msg, msg


def test_compare_exits_2_before_any_run(tmp_path, capsys):
    path = _files(tmp_path, "bearing1.n_phi: 2.5")
    assert main_compare(path, out_dir=tmp_path / "out", runner=_never_runs, workers=1) == 2
    err = capsys.readouterr().err
    assert BAD + "bearing1.n_phi: 2.5: parameter 'bearing1.n_phi' is Integer" in err, err
    assert not (tmp_path / "out" / "runs").exists()


def test_the_cli_names_the_variant_line(tmp_path, capsys):
    rc, out = cli(capsys, "compare", _files(tmp_path, "bearing1.psi: 0.5"), "--out", tmp_path / "out")
    assert rc == 2 and BAD + "bearing1.psi: 0.5: parameter 'bearing1.psi' = 0.5 is outside" in out, out
    assert not (tmp_path / "out" / "runs").exists()


def test_variants_of_an_ssp_base_are_checked_with_the_archive_extracted_once(tmp_path, monkeypatch):
    import warnings

    from orchestrator.scenario import load_scenario, ssp
    from orchestrator.scenario.ssp import export_ssp
    _files(tmp_path, "bearing1.n_phi: 8000")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                  # export-ssp's note on the coupling scheme
        export_ssp(load_scenario(tmp_path / "s.yaml"), tmp_path / "s.ssp")
    extracted = []
    real = ssp.scenario_from_ssp
    monkeypatch.setattr(ssp, "scenario_from_ssp", lambda *a, **k: extracted.append(a) or real(*a, **k))
    compare = COMPARE.replace("scenario: s.yaml", "scenario: s.ssp").replace(
        "- {{macro_step: 1.0e-4}}", "- {{macro_step: [1.0e-4, 5.0e-5, 2.5e-5]}}")
    path = tmp_path / "cmp.yaml"
    path.write_text(compare.format(values="bearing1.n_phi: 8000"))
    msg = _problems(path)
    assert (BAD + "bearing1.n_phi: 8000: " + str(tmp_path / "s.ssp") + " [fmus.bearing1]: fmus.bearing1.parameters."
            "n_phi x n_z = 8000 x 40 = 320000 film cells") in msg, msg
    assert len(extracted) == 2, extracted               # the base, then once for its 5 runs (not once each)


def test_each_run_is_given_the_values_the_loader_checked(tmp_path):
    # a quoted number for a Real and 40.0 for an Integer pass the loader's checks as they pass a
    # scenario's; the run was given the text "2.0e-3" and failed when it started ("setup failed: ...
    # parameter 'bearing1.psi' is of type Real, got '2.0e-3' (str)"), listed as an unstable variant
    # with infinite error while the comparison passed
    compare = COMPARE.replace("  signals: [rotor.x_1]\n", "  signals: [rotor.x_1]\n  set: {{rotor.t_ramp: '3.0'}}\n")
    spec = load_compare(_files(tmp_path, "bearing1.psi: '2.0e-3', bearing1.n_phi: 40.0", compare=compare))
    bad = spec.variants[1].changes
    assert (bad["bearing1.psi"], bad["bearing1.n_phi"]) == (0.002, 40) and type(bad["bearing1.n_phi"]) is int
    sc = spec.scenario(spec.variants[1].changes)
    assert {f.name: f.parameters for f in sc.fmus}["rotor"]["t_ramp"] == 3.0
