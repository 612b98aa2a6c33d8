"""Catalogue of hostile input (issue 19), part 2: compare specs, run folders for ``plot``,
the public API and the CLI's smaller items.

As in part 1: each case builds its files, runs what a user runs and checks the message
(file, field, fix) and that no "internal error" or traceback appears.
"""

from __future__ import annotations

import json
import os
import warnings

import pytest

import orchestrator
from hostile_builders import bomb, cli, md_scenario, two_mass_dir
from orchestrator.compare import main_compare
from test_cli import _with_func

needs_dev_zero = pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")


def compare_file(tmp, body: str, scenario: str = "two_mass.yaml") -> os.PathLike:
    p = tmp / "cmp.yaml"
    p.write_text(f"compare:\n  scenario: {scenario}\n  signals: [left.x1]\n  reference: {{macro_step: 1.0e-4}}\n"
                 f"{body}")
    return p


def run_compare(capsys, path, tmp) -> tuple[int, str]:
    def never(scenario, out_dir):                      # the cases fail before any run
        raise AssertionError("no run expected")
    rc = main_compare(path, out_dir=tmp / "out", runner=never, workers=1)
    cap = capsys.readouterr()
    text = cap.out + cap.err
    assert "internal error" not in text and "Traceback" not in text, text
    return rc, text


# --------------------------------------------------------------------------- compare
@pytest.mark.parametrize("name, words", [
    ("../../../../elsewhere/x{macro_step:g}", "contains '/'"),
    ("x{macro_step.__class__}", "not a field"),
    ("x{scheme[0]}", "not a field"),
    ("x{macro_step:99999999}", "format spec"),
    ("x{}", "not a field"),
])
def test_variant_names_stay_in_out(tmp_path, capsys, test_fmus, name, words):
    two_mass_dir(tmp_path, test_fmus)
    p = compare_file(tmp_path, f"  variants:\n    - {{name: '{name}', macro_step: 1.0e-3}}\n")
    rc, out = run_compare(capsys, p, tmp_path)
    assert rc == 2 and f"{p}" in out and "compare.variants[0].name" in out and words in out
    assert not (tmp_path.parent / "elsewhere").exists()


def test_compare_alias_bomb(tmp_path, capsys, test_fmus):
    two_mass_dir(tmp_path, test_fmus)
    p = compare_file(tmp_path, "  set:\n" + bomb(9) + "  variants:\n    - {macro_step: 1.0e-3}\n")
    rc, out = run_compare(capsys, p, tmp_path)
    assert rc == 2 and f"{p}:" in out and "expands to more than" in out


def test_compare_not_utf8(tmp_path, capsys, test_fmus):
    two_mass_dir(tmp_path, test_fmus)
    p = compare_file(tmp_path, "  variants:\n    - {macro_step: 1.0e-3}\n")
    p.write_bytes(p.read_bytes() + b"# \xff\xfe\n")
    rc, out = run_compare(capsys, p, tmp_path)
    assert rc == 2 and f"{p}:7:3" in out and "not UTF-8" in out


@needs_dev_zero
def test_compare_scenario_dev_zero(tmp_path, capsys):
    p = compare_file(tmp_path, "  variants:\n    - {macro_step: 1.0e-3}\n", scenario="/dev/zero")
    rc, out = run_compare(capsys, p, tmp_path)
    assert rc == 2 and "/dev/zero" in out and "character device" in out


def test_compare_too_many_variants(tmp_path, capsys, test_fmus):
    two_mass_dir(tmp_path, test_fmus)
    steps = ", ".join(f"{1e-3 / (i + 1):.6g}" for i in range(30))
    p = compare_file(tmp_path, f"  variants:\n    - {{macro_step: [{steps}], extrapolation_order: [0, 1, 2, 3], "
                               "interpolation_order: [0, 1, 2, 3], substeps: [1, 2]}\n")
    rc, out = run_compare(capsys, p, tmp_path)
    assert rc == 2 and "expands to 960 variants" in out and "the limit is 500" in out


@pytest.mark.parametrize("content, words", [
    (None, "does not exist, so the regression gate cannot run"),
    ("root:x:0:0:root:/root:/bin/bash\n", "not valid JSON"),
    ('{"variants": [1, 2]}', "has no 'variants' mapping"),
    ('{"variants": {"a": {"errors": {"rms": "big"}}}}', "malformed entry for variant 'a'"),
])
def test_baseline_missing_or_not_a_baseline(tmp_path, capsys, test_fmus, content, words):
    two_mass_dir(tmp_path, test_fmus)
    if content is not None:
        (tmp_path / "b.json").write_text(content)
    p = compare_file(tmp_path, "  baseline: b.json\n  variants:\n    - {macro_step: 1.0e-3}\n")
    rc, out = run_compare(capsys, p, tmp_path)
    assert rc == 2 and str(tmp_path / "b.json") in out and words in out and "--update-baseline" in out


def test_baseline_etc_passwd(tmp_path, capsys, test_fmus):
    if not os.path.isfile("/etc/passwd"):
        pytest.skip("needs /etc/passwd")
    two_mass_dir(tmp_path, test_fmus)
    p = compare_file(tmp_path, "  baseline: /etc/passwd\n  variants:\n    - {macro_step: 1.0e-3}\n")
    rc, out = run_compare(capsys, p, tmp_path)
    assert rc == 2 and "/etc/passwd" in out and "not valid JSON" in out


# --------------------------------------------------------------------------- plot
def write_run(tmp, summary) -> os.PathLike:
    run = tmp / "run"
    run.mkdir()
    rows = "\n".join(f"{i * 1e-3},{1e-6 * i},{-1e-6 * i},{100.0 + i}" for i in range(50))
    (run / "results.csv").write_text("time,rotor.x_1,rotor.y_1,rotor.omega\n" + rows + "\n")
    (run / "summary.json").write_text(json.dumps(summary))
    return run


@pytest.mark.parametrize("summary", [
    {"analysis": {"journals": [1, 2]}},
    {"analysis": {"journals": "b1"}},
    {"analysis": {"journals": 3}},
    {"analysis": {"journals": {"b1": {"onset": {"time_s": "soon"}}}}},
    {"analysis": {"spec": {"journals": [1]}}},
    {"analysis": {"spec": {"journals": {"b1": {"x": "rotor.x_1", "y": "rotor.y_1", "clearance": "tight"}}}}},
    {"analysis": {"spec": {"journals": {"b1": "x"}, "speed": 7}}},
    [1, 2, 3],
    "text",
])
def test_plot_crafted_summary(tmp_path, capsys, summary):
    run = write_run(tmp_path, summary)
    rc, out = cli(capsys, "plot", run)
    assert rc in (0, 1)
    assert "plots" in out or "nothing to plot" in out or "skipped" in out


@needs_dev_zero
def test_plot_scenario_file_dev_zero_is_not_read(tmp_path, capsys, monkeypatch):
    from orchestrator import untrusted
    seen = []
    real = untrusted.open_regular

    def spy(path, what="file"):
        f = real(path, what=what)                 # raises for /dev/zero before reading a byte
        seen.append(str(path))
        return f
    monkeypatch.setattr(untrusted, "open_regular", spy)
    run = write_run(tmp_path, {"scenario_file": "/dev/zero"})
    with pytest.warns(UserWarning, match="character device"):
        cli(capsys, "plot", run)
    assert "/dev/zero" not in seen                 # never opened for reading


# --------------------------------------------------------------------------- CLI and API
@pytest.mark.parametrize("argv", [["--debug", "validate", "x.yaml"], ["validate", "x.yaml", "--debug"]])
def test_debug_before_or_after_the_verb(monkeypatch, argv):
    from orchestrator import cli as cli_mod

    def bug(args):
        raise RuntimeError("a bug")
    parser = cli_mod.build_parser
    monkeypatch.setattr(cli_mod, "build_parser", lambda: _with_func(parser(), bug))
    with pytest.raises(RuntimeError, match="a bug"):              # --debug: the traceback, not a message
        cli_mod.main(argv)


def test_warnings_print_as_one_line(tmp_path, capsys, monkeypatch):
    """While a verb runs, a warning's text is one line 'warning: ...' (no source line, no
    category); afterwards the default format is back."""
    import sys
    from orchestrator import cli as cli_mod
    default = warnings.formatwarning

    def warn(args):
        sys.stderr.write(warnings.formatwarning("output.interval 0.3 is not\n a multiple of the macro step",
                                                UserWarning, "/x/master.py", 12))
        return 0
    parser = cli_mod.build_parser
    monkeypatch.setattr(cli_mod, "build_parser", lambda: _with_func(parser(), warn))
    rc = cli_mod.main(["validate", "x.yaml"])
    err = capsys.readouterr().err
    assert rc == 0 and err == "warning: output.interval 0.3 is not a multiple of the macro step\n"
    assert warnings.formatwarning is default


def test_run_with_a_path_is_refused_before_creating_out(tmp_path):
    with pytest.raises(TypeError, match=r"run\(load_scenario\('s.yaml'\)"):
        orchestrator.run("s.yaml", out_dir=tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_overrides_as_one_text_is_refused(tmp_path):
    s = md_scenario(tmp_path)
    with pytest.raises(TypeError, match=r"write overrides=\['coupling.macro_step=5e-4'\]"):
        orchestrator.load_scenario(s, overrides="coupling.macro_step=5e-4")


def test_user_error_mid_run_is_not_terminated_by_the_caller(tmp_path, test_fmus, monkeypatch):
    from orchestrator.coupling import execution as master_mod
    from orchestrator.errors import ScenarioError
    two_mass_dir(tmp_path, test_fmus)
    sc = orchestrator.load_scenario(tmp_path / "two_mass.yaml")
    m = master_mod.MasterAlgorithm(sc, out_dir=tmp_path / "out")
    real = m.step
    calls = {"n": 0}

    def step():
        calls["n"] += 1
        if calls["n"] == 3:
            raise ScenarioError("s.yaml:3: a user error found mid-run")
        return real()
    monkeypatch.setattr(m, "step", step)
    with pytest.raises(ScenarioError):
        m.run()
    assert "by the caller" not in m.message and "stopped by an error" in m.message


# --------------------------------------------------------------------------- FMU code cache
def _code_cache_setup(tmp_path, monkeypatch):
    from bearing_fmu import journal_bearing as jb
    res = tmp_path / "resources"
    (res / "pkg").mkdir(parents=True)
    (res / "pkg" / "__init__.py").write_text("VALUE = 1\n")
    (res / "rotorcosim_build.json").write_text(json.dumps({"source_sha256": "ab" * 32}))
    monkeypatch.setenv("ROTORCOSIM_FMU_CODE_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr("sys.path", list(__import__("sys").path))
    return jb, res


def test_fmu_code_cache_is_rechecked_on_every_use(tmp_path, monkeypatch):
    jb, res = _code_cache_setup(tmp_path, monkeypatch)
    base = jb.use_stable_code_copy(str(res), package="pkg")
    assert base is not None and (base / "pkg" / "__init__.py").read_text() == "VALUE = 1\n"
    (base / "pkg" / "__init__.py").write_text("import os; os.system('evil')\n")    # tampered after the marker
    again = jb.use_stable_code_copy(str(res), package="pkg")
    assert again == base and (base / "pkg" / "__init__.py").read_text() == "VALUE = 1\n"   # replaced


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="POSIX permissions")
def test_fmu_code_cache_not_private_is_not_used(tmp_path, monkeypatch):
    jb, res = _code_cache_setup(tmp_path, monkeypatch)
    base = jb.use_stable_code_copy(str(res), package="pkg")
    os.chmod(tmp_path / "cache", 0o777)                     # anyone could plant code there
    assert jb.use_stable_code_copy(str(res), package="pkg") is None
    assert base.is_dir()


@pytest.mark.parametrize("extra, words", [
    ("  derived: [1]\n", "'compare.derived' must be a mapping"),
    ("  derived: {d: {key: a.b, scale: x}}\n", "scale of 'd' must be a positive number"),
    ("  set: {coupling.macro_step: x}\n", "gives 'coupling.macro_step' the value 'x'"),
    ("  set: {stop_time: 1.0e300}\n", "too small for the time 1e+300 s"),
    ("  output_interval: x\n", "'compare.output_interval' must be a positive number"),
    ("  workers: 1000000000\n", "between 1 and 64"),
    ("  name: [1]\n", "'compare.name' must be a text"),
    ("  reference: {macro_step: 1.0e-5, check: [1]}\n", "'check' must be true or false"),
])
def test_compare_spec_values(tmp_path, capsys, test_fmus, extra, words):
    """Values of the wrong type or size in a comparison file: a message, not an internal error."""
    two_mass_dir(tmp_path, test_fmus)
    p = compare_file(tmp_path, "  variants:\n    - {macro_step: 1.0e-3, sequence: [left, right]}\n" + extra)
    if "reference:" in extra:
        p.write_text(p.read_text().replace("  reference: {macro_step: 1.0e-4}\n", ""))
    rc, out = run_compare(capsys, p, tmp_path)
    assert rc == 2 and str(p) in out and words in out, out


def test_compare_variant_sequence_must_be_names(tmp_path, capsys, test_fmus):
    two_mass_dir(tmp_path, test_fmus)
    p = compare_file(tmp_path, "  variants:\n    - {macro_step: 1.0e-3, sequence: 5}\n")
    rc, out = run_compare(capsys, p, tmp_path)
    assert rc == 2 and "'compare.variants[0].sequence' must be a list of names (got 5)" in out
