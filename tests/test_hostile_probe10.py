"""Hostile-input probe 10: the surfaces of 2026-12-05 to 12-07 as a careless or hostile user hits
them (`stability` stopped halfway, sweep value names, export-ssp's carried files and hostile .ssp
archives, compare goals, rotor files and bearing parameter ranges). One test per finding, each
failing on the code before its fix; its docstring says what happened before.
"""

from __future__ import annotations

import os
import signal
import zipfile
from pathlib import Path

import pytest

from hostile_builders import cli, two_mass_dir, write_fmu
from tests.test_stability_stop import _signal_at, safety_net, signal_first  # noqa: F401 (a fixture)

REPO = Path(__file__).resolve().parents[1]
JEFFCOTT_HS = REPO / "scenarios" / "jeffcott_runup_half_sommerfeld.yaml"
QUICKSTART = REPO / "scenarios" / "quickstart.yaml"
posix_only = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")


# ----------------------------------------------------------------------------- stability stopped halfway
@posix_only
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("during", ["plot", "json"])
@pytest.mark.usefixtures("safety_net")
def test_a_second_signal_while_the_result_is_written_lets_it_finish(tmp_path, capsys, monkeypatch, signum, during):
    """Ctrl-C pressed twice quickly: the first stops the scan after its speed, the second landed
    after the search, while --plot was drawn (or --json written), where the handlers were gone: no
    figure, no stop message and no ``--speeds`` of the rest, only "interrupted" (exit 130); a
    second SIGTERM there killed the process without a word."""
    import orchestrator.results.plots.stability as plots
    import orchestrator.results.safe_write as safe_write
    calls = _signal_at(monkeypatch, 10, [signum])               # the first: during speed 10 of the scan
    module, name = (plots, "draw") if during == "plot" else (safe_write, "write_report_file")
    signal_first(monkeypatch, module, name, signum)               # the second: as the output starts
    out, png = tmp_path / "r.json", tmp_path / "r.png"
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--speeds", "100:800", "--json", out,
                   "--plot", png)
    assert rc == 128 + signum and calls[0] == 10, text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import json
    r = json.loads(out.read_text())
    assert r["stopped"]["speeds_done"] == 10 and len(r["scan"]) == 10
    assert "stopping after writing what was computed" in text, text
    assert f"for the rest of the range run the same command with {r['stopped']['rest']['args']}" in text, text


@posix_only
@pytest.mark.usefixtures("safety_net")
def test_a_signal_while_a_complete_result_is_written_says_it_is_complete(tmp_path, capsys, monkeypatch):
    """A complete search whose output (here the figure) got a Ctrl-C lost the figure and ended
    "interrupted" (exit 130) without saying that the result printed and written is complete."""
    import orchestrator.results.plots.stability as plots
    signal_first(monkeypatch, plots, "draw", signal.SIGINT)
    png = tmp_path / "r.png"
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--speeds", "100:800", "--scan", "8",
                   "--plot", png)
    assert rc == 130 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", text
    assert "threshold speed: 262.14 Hz" in text
    assert "interrupted while the result was written: the result above is complete" in text, text


@pytest.mark.parametrize("json_name, plot_name", [("r.png", "r.png"), ("r.png", "./sub/../r.png")])
def test_stability_json_and_plot_naming_one_file_are_refused_before_the_computation(tmp_path, capsys, monkeypatch,
                                                                                     json_name, plot_name):
    """``--json r.png --plot r.png`` wrote the JSON report, then the figure over it ("written: r.png"
    twice, exit 0): the report was lost without a word."""
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path)
    import orchestrator.stability as st
    monkeypatch.setattr(st, "stability", lambda *a, **kw: pytest.fail("computed"))
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--json", json_name, "--plot", plot_name)
    assert rc == 1 and "--json and --plot name one file" in text and "--json stability.json" in text, text
    assert not (tmp_path / "r.png").exists()


def test_the_rest_command_of_a_stopped_refinement_prints_its_range_with_the_digits_that_tell_it_apart(capsys):
    """The ``--speeds 262.144607:262.144608 --scan 2`` that a stopped refinement gives, pasted back,
    printed its range as "262.145 - 262.145 Hz" (and a stable one "between 262.145 and 262.145 Hz:
    ... give a wider --speeds"): a range that reads as empty."""
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--speeds", "262.144607:262.144608",
                   "--scan", "2")
    assert rc == 0 and "(JeffcottRotor), 262.144607 - 262.144608 Hz" in text, text
    assert "threshold speed: 262.14 Hz" in text
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", "--speeds", "262.1446:262.1446073", "--scan",
                   "2")
    assert rc == 1 and "between 262.1446 and 262.1446073 Hz: the system is linearly stable" in text, text


@pytest.mark.parametrize("option, name", [("--json", "r.json"), ("--plot", "r.png")])
@pytest.mark.parametrize("folder", ["missing", "a-file"])
def test_stability_outputs_into_a_folder_that_is_none_are_refused_before_the_computation(tmp_path, capsys,
                                                                                        monkeypatch, option, name,
                                                                                        folder):
    """``--json nosuch/r.json`` (or ``--plot``, or a folder part that is a file) was found only when
    the result was written, after the whole search (minutes with --film mc, and the JSON of a
    stopped search is what keeps it): "cannot write nosuch/r.json (No such file or directory)"."""
    import orchestrator.stability as st
    monkeypatch.setattr(st, "stability", lambda *a, **kw: pytest.fail("computed"))
    if folder == "a-file":
        (tmp_path / "a-file").write_text("x")
    out = tmp_path / folder / name
    rc, text = cli(capsys, "stability", JEFFCOTT_HS, "--film", "short", option, out)
    assert rc == 1 and f"{option} {out}: " in text and str(tmp_path / folder) in text, text
    assert ("does not exist" if folder == "missing" else "is not a folder") in text, text


# ----------------------------------------------------------------------------- archives (FMU, SSP)
@pytest.mark.parametrize("members, words", [
    ([("zz", b"x"), ("zz/y", b"y")], "member 'zz' is a file, and member 'zz/y' needs it as its folder"),
    ([("zz/y", b"y"), ("zz", b"x")], "member 'zz' is a file, and member 'zz/y' needs it as its folder"),
    ([(".", b"x")], "member '.' names no file"),
    ([("resources//a.txt", b"x"), ("resources/a.txt", b"y")],
     "member 'resources/a.txt' appears twice in the archive (as 'resources//a.txt' and 'resources/a.txt')"),
], ids=["file-then-folder", "folder-then-file", "dot", "same-path-twice"])
def test_archive_members_that_collide_on_extraction_are_refused_naming_the_archive(tmp_path, capsys, members,
                                                                                 words):
    """Members of an SSP (or FMU) that land on one path when extracted ('zz' and 'zz/y', a member
    named '.', 'a//b' beside 'a/b') passed the archive checks: extraction then failed with the OS's
    "/tmp/rotorcosim-ssp-xxxx/ssp/zz: File exists; ... remove it or choose another name" (a
    temporary folder gone when the command ended, and a fix for the wrong file), or the second
    member silently replaced the first."""
    from hostile_builders import tampered_quickstart_ssp
    good = tampered_quickstart_ssp(tmp_path, lambda t: t).with_name("q.ssp")
    bad = tmp_path / "collide.ssp"
    with zipfile.ZipFile(good) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            zout.writestr(item, zin.read(item))
        for name, data in members:
            zout.writestr(name, data)
    rc, text = cli(capsys, "validate", bad)
    assert rc == 1 and f"{bad}: {words}" in text, text
    assert "rotorcosim-ssp-" not in text and "remove it" not in text, text
    # the same rule for an FMU (one archive check for both)
    from orchestrator.errors import FmuError
    from orchestrator.fmi.archive import safe_extract
    fmu = write_fmu(tmp_path / "m.fmu", members=members)
    with pytest.raises(FmuError) as exc:
        safe_extract(fmu, tmp_path / "x")
    assert f"{fmu}: {words}" in str(exc.value)


# ----------------------------------------------------------------------------- YAML tags
@pytest.mark.parametrize("value", ["!!int zz", "!!float .", "!!bool maybe", "!!timestamp xx", "!!int 0b2",
                                   "2001-13-45"])
def test_a_yaml_value_its_tag_cannot_read_is_named_with_its_line(tmp_path, capsys, value):
    """A value whose YAML tag's constructor cannot read it (an explicit ``!!int zz``, ``!!bool maybe``,
    ``!!timestamp xx``, or a date that is none, ``2001-13-45``) ended every reader of YAML in
    "internal error: ValueError: invalid literal for int()" (KeyError 'maybe', AttributeError
    'NoneType' object has no attribute 'groupdict', ValueError: month must be in 1..12): the
    scenario, --set, a comparison file and a rotor file."""
    text = QUICKSTART.read_text()
    scen = tmp_path / "s.yaml"
    scen.write_text(text.replace("name: quickstart", f"name: {value}", 1))
    rc, out = cli(capsys, "validate", scen)
    assert rc == 1 and f"{scen}:1: " in out and "cannot read" in out, out
    rc, out = cli(capsys, "validate", QUICKSTART, "--set", f"fmus.bearing1.parameters.eta0={value}")
    assert rc == 1 and f"--set fmus.bearing1.parameters.eta0={value}" in out and "cannot read" in out, out
    from orchestrator.compare import load_compare
    from orchestrator.compare.spec import CompareSpecError
    from tests.test_compare_hostile import compare_file
    tmp = tmp_path / "cmp"
    tmp.mkdir()
    cmp = compare_file(tmp, f"  name: {value}\n")
    with pytest.raises(CompareSpecError) as exc:
        load_compare(cmp)
    assert f"{cmp}:6" in str(exc.value) and "cannot read" in str(exc.value), str(exc.value)
    from rotor_fmu import rotor_file
    rotor = tmp_path / "r.yaml"
    rotor.write_text((rotor_file.DATA_DIR / "turbocharger.yaml").read_text().replace(
        "reduction: {n_modes: 4}", f"reduction: {{n_modes: {value}}}", 1))
    with pytest.raises(rotor_file.RotorFileError) as exc:
        rotor_file.load_rotor_file(rotor)
    line = next(i for i, t in enumerate(rotor.read_text().splitlines(), 1) if t.startswith("reduction:"))
    assert f"line {line}: " in str(exc.value) and "cannot read" in str(exc.value), str(exc.value)


# ----------------------------------------------------------------------------- rotor files
@pytest.mark.parametrize("edits, words", [
    ([("material: steel}    # compressor stub", "material: {}}    # compressor stub")],
     "'shaft.sections[0].material' must be one of ['steel'] (got {})"),
    ([("material: steel}    # compressor stub", "material: [steel]}    # compressor stub")],
     "'shaft.sections[0].material' must be one of ['steel'] (got ['steel'])"),
    ([("  steel: {E: 2.1e11, nu: 0.3, rho: 7850.0}", "  steel: {E: 2.1e11, nu: 0.3, rho: 7850.0}\n  1: {E: 2.1e11, "
       "rho: 7850.0}"), ("material: steel}    # compressor stub", "material: x}    # compressor stub")],
     "'materials': the name 1 is not a text"),
], ids=["mapping", "list", "number-name"])
def test_a_rotor_file_material_that_is_no_name_is_named(tmp_path, edits, words):
    """A section's ``material`` given as a mapping or a list (``material: {}``) raised "TypeError:
    unhashable type: 'dict'" out of load_rotor_file, and a material named by a number beside one
    named by a text (``1:`` and ``steel:``) raised "TypeError: '<' not supported between instances of
    'str' and 'int'" while the message listing the materials was written."""
    from rotor_fmu import rotor_file
    text = (rotor_file.DATA_DIR / "turbocharger.yaml").read_text()
    for old, new in edits:
        assert old in text
        text = text.replace(old, new, 1)
    path = tmp_path / "r.yaml"
    path.write_text(text)
    with pytest.raises(rotor_file.RotorFileError) as exc:
        rotor_file.load_rotor_file(path)
    assert words in str(exc.value), str(exc.value)


# ----------------------------------------------------------------------------- compare goals
@pytest.fixture
def two_mass(tmp_path, test_fmus):
    return two_mass_dir(tmp_path, test_fmus)


@pytest.mark.parametrize("key", ["goal", "tolerance", "set", "derived"])
@pytest.mark.parametrize("value", ["0", "[]", "''", "false"])
def test_a_compare_goal_that_is_no_mapping_is_refused_even_when_it_reads_as_false(two_mass, key, value):
    """``goal: 0``, ``goal: []``, ``goal: ''`` or ``goal: false`` (top level or in a variant) was taken
    for no goal without a word and the comparison ran (``goal: 0.01`` was refused: a mapping metric ->
    error is expected); so were ``tolerance``, ``set`` and ``derived`` given so (``x or {}``)."""
    from orchestrator.compare import load_compare
    from orchestrator.compare.spec import CompareSpecError
    from tests.test_compare_hostile import compare_file
    for where in ("compare", "compare.variants[0]"):
        if where != "compare" and key == "derived":
            continue                                   # a top-level key only
        path = (compare_file(two_mass, f"  {key}: {value}\n") if where == "compare" else
                compare_file(two_mass, "", variants=f"[{{macro_step: 1.0e-3, {key}: {value}}}]"))
        with pytest.raises(CompareSpecError) as exc:
            load_compare(path)
        assert f"'{where}.{key}' must be a mapping" in str(exc.value), str(exc.value)


# ----------------------------------------------------------------------------- bearing parameters (Python API)
@pytest.mark.parametrize("field, value, words", [
    ("p0", "1e5", "BearingParams.p0 must be a number (got '1e5', a str)"),
    ("p_feed", None, "BearingParams.p_feed must be a number (got None, a NoneType)"),
    ("groove_width", "0", "BearingParams.groove_width must be a number (got '0', a str)"),
    ("cav_width", [1.0], "BearingParams.cav_width must be a number (got [1.0], a list)"),
    ("R", True, "BearingParams.R must be a number (got True, a bool)"),
    ("cavitation", True, "BearingParams.cavitation must be an integer (got True, a bool)"),
    ("linear_solver", 1, "BearingParams.linear_solver must be a text (got 1, a int)"),
])
def test_bearing_params_of_the_wrong_type_are_named_not_a_type_error(field, value, words):
    """BearingParams(p0="1e5") (or p_feed=None, groove_width="0", ...) raised a bare "TypeError: '>='
    not supported between instances of 'str' and 'int'" from its own checks, and a boolean passed
    as a number (R=True: a 1 m journal; cavitation=True) was taken without a word."""
    from bearing_fmu.model import BearingParams
    with pytest.raises(ValueError) as exc:
        BearingParams(**{field: value})
    assert words in str(exc.value), str(exc.value)
    # ints where floats are expected, and every bound itself, are fine
    BearingParams(R=2, B=4, eta0=10, psi=0.1, p0=100_000, p_feed=100_000, cav_width=1000, mu_contact=10,
                  sigma_rough=1e-4, contact_KE=10**12, n_phi=8192, n_z=32, cavitation=0)


# ----------------------------------------------------------------------------- texts drawn in figures
def test_names_with_dollar_signs_are_drawn_as_written_in_run_and_stability_figures(tmp_path, capsys):
    """A scenario named 'a$_$b' (a folder name may hold '$'), or a signal from a third-party FMU
    named 'x$_$', was parsed as matplotlib mathtext in the figure's title or label: `rotorcosim plot`
    of the run ended in "internal error: ParseSyntaxException" and `stability --plot` did so after
    the whole computation, the figure not written (sweep maps were fixed the same way on 12-06)."""
    run = tmp_path / "a$_$b"
    run.mkdir()
    (run / "results.csv").write_text("time,o$s$c.x$_$,osc.v\n" + "".join(f"{i * 1e-3!r},{i % 7}.5,{i % 3}.25\n"
                                                                      for i in range(40)))
    rc, text = cli(capsys, "plot", run)
    assert rc == 0 and (run / "plots").is_dir() and list((run / "plots").glob("signals_*.png")), text
    from orchestrator.results.plots.stability import draw
    result = {"scenario": "cost_$a_$", "film": "short", "status": "stable", "speed_range_hz": [100.0, 200.0],
              "scan": [{"speed_hz": 100.0, "max_re_per_s": -5.0, "whirl_hz": 45.0, "log_decrement": 0.7},
                       {"speed_hz": 200.0, "max_re_per_s": -3.0, "whirl_hz": 90.0, "log_decrement": 0.2}],
              "crossings": [], "crossings_bracketed": [], "stopped": None, "threshold_hz": None}
    png = draw(result, tmp_path / "s.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("field, value", [("m_disc", True), ("k_shaft", False), ("g", True)])
def test_rotor_params_refuse_a_boolean_for_a_number(field, value):
    """JeffcottParams(m_disc=True) built a rotor with a 1 kg disc (k_shaft=False: a shaft of
    stiffness 0, below the declared 1 N/m): range_problems skipped booleans, so a flag passed for a
    number through the Python API was taken as 1 or 0 without a word."""
    from rotor_fmu.jeffcott import JeffcottModel, JeffcottParams
    with pytest.raises(ValueError) as exc:
        JeffcottModel(JeffcottParams(**{field: value}))
    assert f"JeffcottParams.{field} must be" in str(exc.value) and f"(got {value!r})" in str(exc.value)
    JeffcottModel(JeffcottParams(m_disc=1, k_shaft=10**13, g=0, unbalance_phase=-6.283185307179586))   # bounds, ints


def test_an_fmus_section_over_its_bound_is_not_followed_by_a_sequence_of_unknown_instances(tmp_path, capsys):
    """An SSP (or scenario) listing more FMU instances than MAX_FMU_INSTANCES was refused for that,
    then told "'coupling.sequence' must list every instance exactly once ('rotor' is not an instance
    (instances: ); ...); e.g. []": the sequence checked against the instances of the refused
    section, none, with an empty list as the fix."""
    from orchestrator.scenario.limits import MAX_FMU_INSTANCES
    write_fmu(tmp_path / "m.fmu")
    many = "".join(f"  g{i}: {{path: m.fmu}}\n" for i in range(MAX_FMU_INSTANCES + 1))
    scen = tmp_path / "s.yaml"
    scen.write_text(f"name: many\nstop_time: 0.01\nfmus:\n{many}coupling:\n  scheme: gauss-seidel\n"
                    "  sequence: [g0, g1]\n  macro_step: 1.0e-3\n")
    rc, text = cli(capsys, "validate", scen)
    assert rc == 1 and f"more than {MAX_FMU_INSTANCES}" in text, text
    assert "coupling.sequence" not in text and "e.g. []" not in text, text
