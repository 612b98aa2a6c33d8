"""Catalogue of hostile input, part 3: the smaller items a probe of the CLI found (2026-12-06).

Each case runs what a user runs and checks the message (file, line or field, what came, the
fix), the exit code, and that no "internal error" or traceback appears.
"""

from __future__ import annotations

import errno

import pytest

from hostile_builders import cli, md_scenario, scenario_text, write_fmu


# --------------------------------------------------------------------------- --out
def test_out_that_is_a_file_is_named_as_such(tmp_path, capsys):
    p = md_scenario(tmp_path)
    (tmp_path / "taken").write_text("not a folder")
    rc, out = cli(capsys, "run", p, "--out", tmp_path / "taken")
    assert rc == 1
    assert f"output folder {tmp_path / 'taken'}: there is a file of that name, not a folder" in out
    assert "give --out a new folder" in out
    assert (tmp_path / "taken").read_text() == "not a folder"


@pytest.mark.parametrize("verb", [["run", "s.yaml"], ["build-fmus"], ["sweep", "w.yaml"], ["compare", "c.yaml"]])
def test_empty_out_is_refused_not_taken_for_the_default(tmp_path, capsys, monkeypatch, verb):
    monkeypatch.chdir(tmp_path)           # (the old code built FMUs into a folder ' ' here)
    with pytest.raises(SystemExit) as e:
        cli(capsys, *verb, "--out", " ")
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "argument --out: an empty folder name: give a folder, or leave --out out for the default" in err


@pytest.mark.parametrize("code, words", [
    (errno.EEXIST, "a file of that name is in the way where a folder is needed"),
    (errno.ENOTDIR, "a part of that path is a file, not a folder"),
    (errno.EACCES, "permission denied: choose a place you can write to"),
    (errno.ENOSPC, "the disk is full"),
])
def test_os_errors_say_what_to_do(code, words):
    from orchestrator.cli import _describe
    text = _describe(OSError(code, "os text", "some/path"))
    assert text.startswith("error: some/path: os text; ") and words in text


def test_os_error_the_cli_meets_gets_its_fix(tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    rc, out = cli(capsys, "build-fmus", "--out", tmp_path / "afile" / "sub")
    assert rc == 1 and "a part of that path is a file, not a folder: choose another path" in out


# --------------------------------------------------------------------------- scenario keys
@pytest.mark.parametrize("key, reads", [("~", "None"), ("null", "None"), ("true", "True"), ("no", "False"),
                                        ("on", "True")])
def test_instance_names_yaml_reads_as_null_or_boolean(tmp_path, capsys, key, reads):
    write_fmu(tmp_path / "m.fmu")
    p = tmp_path / "s.yaml"
    p.write_text(scenario_text().replace("  a: {path: m.fmu}", f"  {key}: {{path: m.fmu}}"))
    rc, out = cli(capsys, "validate", p)
    assert rc == 1
    assert f"{p}:4: keys of 'fmus' must be names (got {key!r}, which YAML reads as {reads})" in out
    assert f"in quotes if it must be {key!r}" in out


def test_quoted_such_name_is_a_name(tmp_path, capsys):
    write_fmu(tmp_path / "m.fmu")
    p = tmp_path / "s.yaml"
    p.write_text(scenario_text().replace("  a: {path: m.fmu}", "  'on': {path: m.fmu}"))
    from orchestrator import load_scenario
    assert [f.name for f in load_scenario(p).fmus] == ["on"]


@pytest.mark.parametrize("key", ["....", "a..b", "coupling..macro_step", ".x", "coupling.", " .x"])
def test_set_with_an_empty_part_of_the_key_path(tmp_path, capsys, key):
    p = md_scenario(tmp_path)
    rc, out = cli(capsys, "validate", p, "--set", f"{key}=1")
    assert rc == 1
    assert f"--set {key}=1: the key path {key.strip()!r} has an empty part" in out
    assert "e.g. --set coupling.macro_step=5e-5" in out


# --------------------------------------------------------------------------- names
@pytest.mark.parametrize("name, code", [("\\u202eevil", "U+202E (RIGHT-TO-LEFT OVERRIDE)"),
                                        ("ab\\u200bc", "U+200B (ZERO WIDTH SPACE)"),
                                        ("x\\u2028y", "U+2028 (LINE SEPARATOR)")])
def test_names_with_invisible_or_direction_changing_characters(tmp_path, capsys, name, code):
    p = md_scenario(tmp_path, top="")
    p.write_text(p.read_text().replace("name: hostile", f'name: "{name}"'))
    rc, out = cli(capsys, "validate", p)
    assert rc == 1 and f"{p}:1: 'name'" in out
    assert "invisible or direction-changing characters" in out and code in out


def test_names_in_other_scripts_are_fine(tmp_path, capsys):
    p = md_scenario(tmp_path)
    p.write_text(p.read_text().replace("name: hostile", "name: Läufer-轴承"))
    from orchestrator import load_scenario
    assert load_scenario(p).name == "Läufer-轴承"


# --------------------------------------------------------------------------- YAML itself
@pytest.mark.parametrize("char, hint", [("\x00", "save it as UTF-8 text"), ("\x07", "delete it")])
def test_a_character_yaml_forbids_gets_line_and_column(tmp_path, capsys, char, hint):
    p = md_scenario(tmp_path)
    lines = p.read_text().splitlines()
    lines[1] = lines[1] + char                          # "stop_time: 0.01<char>"
    p.write_text("\n".join(lines) + "\n")
    rc, out = cli(capsys, "validate", p)
    assert rc == 1
    assert f"{p}:2:{len(lines[1])}: a character YAML does not allow (U+{ord(char):04X})" in out
    assert hint in out and "position" not in out


def test_a_big_flat_file_is_too_big_not_an_alias_bomb(tmp_path, capsys, monkeypatch):
    import orchestrator.untrusted as untrusted
    monkeypatch.setattr(untrusted, "MAX_YAML_NODES", 60)
    p = md_scenario(tmp_path, extra="description: >\n  x\n")
    p.write_text(p.read_text() + "".join(f"x_{i}: {i}\n" for i in range(40)))
    rc, out = cli(capsys, "validate", p)
    assert rc == 1
    assert "the YAML has more than 60 values (the limit" in out and "split it" in out
    assert "alias bomb" not in out


def test_an_alias_bomb_is_still_called_one(tmp_path, capsys, monkeypatch):
    import orchestrator.untrusted as untrusted
    monkeypatch.setattr(untrusted, "MAX_YAML_NODES", 60)
    p = md_scenario(tmp_path)
    p.write_text(p.read_text() + "x: &a [1, 2, 3, 4, 5, 6, 7, 8]\ny: [*a, *a, *a, *a, *a, *a, *a, *a]\n")
    rc, out = cli(capsys, "validate", p)
    assert rc == 1 and "looks like an alias bomb" in out


# --------------------------------------------------------------------------- {out_dir} paths
@pytest.mark.parametrize("value, words", [
    ("{out_dir}/../../escape.npz", "'..' climbs out of the run folder"),
    ("{out_dir}/a/../../b.npz", "'..' climbs out of the run folder"),
    ("{out_dir}/x/{out_dir}", "'{out_dir}' may appear once, at the start"),
])
def test_out_dir_paths_that_leave_the_run_folder(tmp_path, capsys, value, words):
    p = md_scenario(tmp_path)
    p.write_text(p.read_text().replace("  a: {path: m.fmu}", f"  a: {{path: m.fmu, parameters: {{f: '{value}'}}}}"))
    rc, out = cli(capsys, "validate", p)
    assert rc == 1 and f"{p}:4: parameter 'a.f' is a path in the run folder, but {words}" in out


@pytest.mark.parametrize("value", ["{out_dir}/fields.npz", "{out_dir}/a/../b.npz", "{out_dir}", "/abs/x.npz",
                                   "plain text"])
def test_paths_that_stay_or_are_not_run_folder_paths(value):
    from orchestrator.untrusted import out_dir_escape
    assert out_dir_escape(value) is None


# --------------------------------------------------------------------------- DefaultExperiment
def _de_scenario(tmp_path, de: str, *, drop: str):
    from hostile_builders import md_xml
    md = md_xml().replace("<ModelVariables>", f"<DefaultExperiment {de}/><ModelVariables>")
    write_fmu(tmp_path / "m.fmu", md)
    p = tmp_path / "s.yaml"
    text = scenario_text(top="start_time: 0.0\n")
    for key in drop.split(","):
        text = {"start_time": text.replace("start_time: 0.0\n", ""),
                "stop_time": text.replace("stop_time: 0.01\n", ""),
                "macro_step": text.replace("coupling:\n  macro_step: 1.0e-3\n", "")}[key]
    p.write_text(text)
    return p


@pytest.mark.parametrize("de, drop, key, shown", [
    ('startTime="NaN"', "start_time", "start_time", "nan"),
    ('startTime="abc"', "start_time", "start_time", "'abc'"),
    ('stopTime="inf"', "stop_time", "stop_time", "inf"),
    ('stepSize="0"', "macro_step", "coupling.macro_step", "0.0"),
    ('stepSize="-1e-3"', "macro_step", "coupling.macro_step", "-0.001"),
])
def test_unusable_default_experiment_values_are_named(tmp_path, capsys, de, drop, key, shown):
    p = _de_scenario(tmp_path, de, drop=drop)
    rc, out = cli(capsys, "validate", p)
    assert rc == 1
    attr = de.split("=")[0]
    assert f"'{key}' is missing and the DefaultExperiment {attr} of 'a' is {shown}, not a finite number" in out
    assert f"add '{key}: <seconds>' to the scenario" in out
    assert "no FMU declares" not in out


def test_unusable_default_experiment_values_do_not_matter_when_the_scenario_gives_them(tmp_path):
    from orchestrator import load_scenario
    p = _de_scenario(tmp_path, 'startTime="abc" stopTime="NaN" stepSize="0"', drop="start_time")
    p.write_text("start_time: 0.0\n" + p.read_text())
    sc = load_scenario(p)
    assert sc.start_time == 0.0 and sc.stop_time == 0.01 and sc.coupling.macro_step == 1e-3


# --------------------------------------------------------------------------- composed-tree cache
def test_loads_of_one_file_do_not_share_changes(tmp_path):
    """The composed YAML tree of a file is kept for the next load (a sweep loads one scenario
    per run); each load gets its own copy: an override or a merge key of one load is not seen
    by the next, an aliased value stays shared within a load, and a changed file is read anew."""
    from orchestrator import load_scenario
    from orchestrator.untrusted import _COMPOSED
    p = md_scenario(tmp_path)
    p.write_text(p.read_text().replace("  a: {path: m.fmu}", "  a: {path: m.fmu, parameters: &k {k: 2.0}}\n"
                                       "  b: {path: m.fmu, parameters: *k}"))
    first = load_scenario(p, ["fmus.a.parameters.k=5.0"])
    assert any(text == p.read_text() for text, *_ in _COMPOSED)     # kept for the next load
    second = load_scenario(p)
    third = load_scenario(p, ["fmus.b.parameters.k=7.0"])
    par = {sc_i: {f.name: f.parameters["k"] for f in sc.fmus} for sc_i, sc in enumerate((first, second, third))}
    assert par == {0: {"a": 5.0, "b": 2.0}, 1: {"a": 2.0, "b": 2.0}, 2: {"a": 2.0, "b": 7.0}}
    p.write_text(p.read_text().replace("{k: 2.0}", "{k: 3.0}"))
    assert {f.parameters["k"] for f in load_scenario(p).fmus} == {3.0}


# --------------------------------------------------------------------------- FMU log messages
def test_python_exceptions_pythonfmu_reports_are_shown_as_their_message():
    from orchestrator.fmi.subsystem import log_message_text
    raw = ("[fatal] Fatal py exception encountered: [getReal] PyObject_CallMethod\n"
           "ValueError('invalid bearing parameters:\\n  BearingParams.psi must be a positive finite number "
           "(got -0.0028)')")
    assert log_message_text(raw) == ("ValueError in the FMU's getReal: invalid bearing parameters: / "
                                     "BearingParams.psi must be a positive finite number (got -0.0028)")
    raw = 'Fatal py exception encountered: [doStep] PyObject_CallMethod RuntimeError("it\'s broken")'
    assert log_message_text(raw) == "RuntimeError in the FMU's doStep: it's broken"


def test_a_long_log_message_keeps_its_start_and_its_end():
    from orchestrator.fmi.subsystem import log_message_text
    text = log_message_text("START " + "x" * 5000 + " END")
    assert text.startswith("START ") and text.endswith(" END") and " ... " in text and len(text) < 1700


# --------------------------------------------------------------------------- model description values
@pytest.mark.parametrize("var, words", [
    ('<ScalarVariable name="b" valueReference="3" causality="parameter" variability="fixed">'
     '<Boolean start="maybe"/></ScalarVariable>', "variable 'b': start 'maybe' is not a Boolean"),
    ('<ScalarVariable name="i" valueReference="3" causality="parameter" variability="fixed">'
     '<Integer start="99999999999999"/></ScalarVariable>', "variable 'i' (Integer): start 99999999999999 is outside"),
    ('<ScalarVariable name="r" valueReference="3" causality="parameter" variability="fixed">'
     '<Real start="1" min="abc"/></ScalarVariable>', "variable 'r' (Real): min 'abc' is not a number"),
    ('<ScalarVariable name="r" valueReference="3" causality="parameter" variability="fixed">'
     '<Real start="abc"/></ScalarVariable>', "variable 'r' (Real): start 'abc' is not a number"),
    ('<ScalarVariable name="r" valueReference="3" causality="parameter" variability="fixed">'
     '<Real start="1" min="10" max="1"/></ScalarVariable>', "variable 'r': min 10.0 is greater than max 1.0"),
    ('<ScalarVariable name=" " valueReference="3" causality="output"><Real/></ScalarVariable>',
     "a ScalarVariable (valueReference 3) has an empty name"),
])
def test_model_description_values_that_are_not_of_their_type(tmp_path, capsys, var, words):
    from hostile_builders import VARS, md_xml
    fmu = write_fmu(tmp_path / "m.fmu", md_xml(variables=VARS + var))
    rc, out = cli(capsys, "info", fmu)
    assert rc == 1 and f"{fmu}: {words}" in out and "re-export the FMU" in out


def test_model_description_values_of_their_type_are_read(tmp_path, capsys):
    from hostile_builders import VARS, md_xml
    var = ('<ScalarVariable name="r" valueReference="3" causality="parameter" variability="fixed">'
           '<Real start="INF" min="-1e3" max="INF" nominal="2"/></ScalarVariable>'
           '<ScalarVariable name="b" valueReference="4" causality="parameter" variability="fixed">'
           '<Boolean start="1"/></ScalarVariable>')
    fmu = write_fmu(tmp_path / "m.fmu", md_xml(variables=VARS + var))
    rc, out = cli(capsys, "info", fmu)
    assert rc == 0, out
