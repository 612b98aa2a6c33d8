"""Command line: every verb, clean errors (no traceback) and exit codes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from orchestrator import cli
from orchestrator.cli import common as cli_common
from orchestrator.cli import run as cli_run
from orchestrator.cli import main
from test_scenario_loader import scenario_dir

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def sdir(tmp_path, test_fmus) -> Path:
    return scenario_dir(tmp_path, test_fmus)


def run_cli(*args, cwd=None, timeout=120) -> subprocess.CompletedProcess:
    """``python -m orchestrator ARGS`` in a subprocess (what a user sees)."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.run([sys.executable, "-m", "orchestrator", *map(str, args)], cwd=cwd or REPO,
                          capture_output=True, text=True, timeout=timeout, env=env)


def assert_clean_failure(proc: subprocess.CompletedProcess) -> None:
    assert proc.returncode != 0, proc
    assert "Traceback" not in proc.stderr and "Traceback" not in proc.stdout, proc.stderr


# ------------------------------------------------------------------ validate
@pytest.mark.parametrize("name, needle", [
    ("malformed.yaml", "malformed YAML"),
    ("unknown_keys.yaml", "did you mean 'stop_time'?"),
    ("missing_fmu.yaml", "FMU file of 'right' not found"),
    ("bad_variable.yaml", "outputs of 'left' (closest first): x1, v1"),
    ("input_twice.yaml", "input 'right.x1' is connected twice"),
    ("type_mismatch.yaml", "type mismatch: 'mixed.count' is Integer but 'left.F' is Real"),
    ("nonpositive_step.yaml", "'coupling.macro_step' must be positive"),
])
def test_validate_bad_files_exit_1_with_every_problem(sdir, capsys, name, needle):
    assert main(["validate", str(sdir / name)]) == 1
    out, err = capsys.readouterr()
    assert needle in out
    assert f"{sdir / name}:" in out                    # file:line on every problem line
    assert all(line.startswith(f"{sdir / name}:") for line in out.splitlines())
    assert "problem" in err and "Traceback" not in err


def test_validate_subprocess_no_traceback(sdir):
    proc = run_cli("validate", sdir / "bad_variable.yaml")
    assert_clean_failure(proc)
    assert proc.returncode == 1
    assert "'left' has no variable 'x'" in proc.stdout and "2 problems found" in proc.stderr


def test_console_exit_without_teardown_keeps_output_and_code(sdir, tmp_path):
    """With an FMU loaded in-process the command leaves through os._exit (cli.console_main):
    the piped (block-buffered) output is still flushed, atexit handlers still run, and the
    exit code is the command's."""
    proc = run_cli("validate", sdir / "two_mass.yaml")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.rstrip().endswith("macro step 0.001 s)")
    marker = tmp_path / "atexit-ran"
    code = ("import atexit, pathlib, sys; from orchestrator import cli; "
            f"atexit.register(lambda: pathlib.Path({str(marker)!r}).write_text("
            "str(sys.modules['orchestrator.fmi.subsystem'].native_fmu_loaded))); "
            f"sys.argv = ['rotorcosim', 'run', {str(sdir / 'two_mass.yaml')!r}, '--out', {str(tmp_path / 'o')!r}, "
            "'--no-progress']; cli.console_main()")
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "status: finished" in proc.stdout, proc.stderr
    assert marker.read_text() == "True"     # the os._exit path was taken, after the atexit handlers


def test_validate_good_file(sdir, capsys):
    assert main(["validate", str(sdir / "two_mass.yaml")]) == 0
    out = capsys.readouterr().out
    assert "valid (2 FMU instances, 3 connections, gauss-seidel, macro step 0.001 s)" in out


def test_validate_with_overrides(sdir, capsys):
    assert main(["validate", str(sdir / "two_mass.yaml"), "--set", "coupling.macro_step=5e-4"]) == 0
    assert "macro step 0.0005 s" in capsys.readouterr().out
    assert main(["validate", str(sdir / "two_mass.yaml"), "--set", "coupling.macro_step=-1"]) == 1
    out = capsys.readouterr().out
    assert out.startswith("--set coupling.macro_step=-1: 'coupling.macro_step' must be positive")


# ------------------------------------------------------------------ run: bad input never gives a traceback
@pytest.mark.parametrize("name", ["malformed.yaml", "missing_fmu.yaml", "input_twice.yaml", "nonpositive_step.yaml"])
def test_run_bad_scenario_fails_cleanly(sdir, capsys, name):
    assert main(["run", str(sdir / name), "--out", str(sdir / "out")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: invalid scenario")
    assert f"{sdir / name}:" in err
    assert not (sdir / "out").exists()


def test_run_bad_override_subprocess(sdir):
    proc = run_cli("run", sdir / "two_mass.yaml", "--out", sdir / "out", "--set", "coupling.macro_stp=1e-4")
    assert_clean_failure(proc)
    assert "--set coupling.macro_stp=1e-4: unknown key 'macro_stp' in 'coupling'; did you mean 'macro_step'?" \
        in proc.stderr


def test_run_missing_file(tmp_path, capsys):
    assert main(["run", str(tmp_path / "nope.yaml")]) == 1
    err = capsys.readouterr().err
    assert "nope.yaml: scenario file not found" in err and "Traceback" not in err


def test_usage_error_exits_2(capsys):
    with pytest.raises(SystemExit) as info:
        main(["run"])
    assert info.value.code == 2
    assert "FILE" in capsys.readouterr().err
    with pytest.raises(SystemExit) as info:
        main(["frobnicate"])
    assert info.value.code == 2


def _have_run() -> bool:
    import orchestrator
    if getattr(orchestrator, "run", None) is not None:
        return True
    try:
        import orchestrator.coupling.execution as m
    except ModuleNotFoundError:
        return False
    return hasattr(m, "run")


@pytest.mark.skipif(not _have_run(), reason="orchestrator.run (master) is not in this checkout yet")
def test_run_writes_results_and_reports(sdir):
    out = sdir / "out"
    proc = run_cli("run", sdir / "two_mass.yaml", "--out", out, "--no-progress")
    assert proc.returncode == 0, proc.stderr
    assert f"results: {out}" in proc.stdout and "status: finished" in proc.stdout
    assert "macro steps: 20" in proc.stdout
    header = (out / "results.csv").read_text().splitlines()[0]
    assert header == "time,left.x1,right.F"
    assert json.loads((out / "summary.json").read_text())["status"] == "finished"


@pytest.mark.skipif(not _have_run(), reason="orchestrator.run (master) is not in this checkout yet")
def test_run_default_out_dir_and_failed_run(sdir, test_fmus):
    import shutil
    shutil.copy(test_fmus["Faulty"], sdir / "fmus" / "Faulty.fmu")
    (sdir / "faulty.yaml").write_text(
        "name: faulty-run\nstop_time: 0.1\nfmus:\n  f: {path: fmus/Faulty.fmu, parameters: {t_fail: 0.05, mode: 1}}\n"
        "  g: {path: fmus/Gain.fmu}\nconnections:\n  - {from: f.y, to: g.u}\ncoupling: {macro_step: 0.01}\n")
    proc = run_cli("run", sdir / "faulty.yaml", "--no-progress", cwd=sdir)
    assert_clean_failure(proc)
    assert proc.returncode == 1
    assert f"runs{os.sep}faulty-run" in proc.stdout                # default: runs/<name> under the cwd
    assert "rows written so far are kept in" in proc.stderr
    assert (sdir / "runs" / "faulty-run" / "results.csv").is_file()
    assert json.loads((sdir / "runs" / "faulty-run" / "summary.json").read_text())["status"] == "failed"


# ------------------------------------------------------------------ info
def test_info_shows_variables_and_flags(test_fmus, capsys):
    assert main(["info", str(test_fmus["LeftMass"])]) == 0
    out = capsys.readouterr().out
    assert "model: LeftMass (FMI 2.0" in out
    for flag in ("canHandleVariableCommunicationStepSize: yes", "canInterpolateInputs: no",
                 "canGetAndSetFMUstate: yes", "maxOutputDerivativeOrder: 0"):
        assert flag in out
    rows = {line.split()[0]: line.split() for line in out.split("variables (")[1].splitlines()[2:]}
    assert rows["m1"][1:4] == ["parameter", "tunable", "Real"]
    assert rows["F"][1:4] == ["input", "continuous", "Real"]
    assert rows["x1"][1:4] == ["output", "continuous", "Real"]
    assert "position [m]" in out                              # descriptions shown
    # parameters before inputs before outputs
    order = [line.split()[1] for line in out.split("variables (")[1].splitlines()[2:]]
    assert order == sorted(order, key=["parameter", "input", "output"].index)


def test_info_on_a_non_fmu_fails_cleanly(tmp_path):
    bad = tmp_path / "x.fmu"
    bad.write_text("hello")
    proc = run_cli("info", bad)
    assert_clean_failure(proc)
    assert proc.stderr.startswith(f"error: {bad}: not a valid zip archive")


# ------------------------------------------------------------------ delegating verbs
def test_plot_missing_dir(tmp_path, capsys):
    assert main(["plot", str(tmp_path / "nope")]) == 1
    assert "no such run folder" in capsys.readouterr().err


def test_plot_of_a_comparison_folder_names_its_figure_and_runs(tmp_path, capsys):
    """`rotorcosim plot out/compare/X` (where compare wrote its report) said twice that results.csv was
    not found "(the run wrote no results)" and exited 1; it now prints error_vs_cost.png and says how to
    draw one of the comparison's runs."""
    d = tmp_path / "cmp"
    for run in ("reference", "gs-e0i0-h0.1"):
        (d / "runs" / run).mkdir(parents=True)
    (d / "report.json").write_text("{}")
    (d / "report.md").write_text("# Comparison")
    assert main(["plot", str(d)]) == 1                       # no figure: said why, with the hint
    err = capsys.readouterr().err
    assert "is the folder of a comparison" in err and "no error_vs_cost.png" in err
    (d / "error_vs_cost.png").write_bytes(b"png")
    assert main(["plot", str(d)]) == 0
    cap = capsys.readouterr()
    assert cap.out.strip() == str(d / "error_vs_cost.png")
    assert f"rotorcosim plot {d / 'runs' / 'reference'}" in cap.err and "gs-e0i0-h0.1" in cap.err
    assert "the run wrote no results" not in cap.err


def test_missing_feature_module_is_reported_cleanly(capsys, monkeypatch):
    real = cli_common._feature

    def fake_feature(module, attr, verb):
        return real("orchestrator.no_such_module_xyz", attr, verb)
    monkeypatch.setattr(cli_common, "_feature", fake_feature)
    assert main(["build-fmus"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: `rotorcosim build-fmus` is not available in this installation: the module "
                          "orchestrator.no_such_module_xyz is missing")


def test_missing_dependency_is_named(monkeypatch):
    import importlib

    def fake_import(name):
        raise ModuleNotFoundError("No module named 'matplotlib.pyplot'", name="matplotlib.pyplot")
    monkeypatch.setattr(importlib, "import_module", fake_import)
    with pytest.raises(cli_common._Unavailable, match=r"needs the Python package 'matplotlib'.*pip install matplotlib"):
        cli_common._feature("orchestrator.results.plots", "plot_run", "plot")


def test_verbs_call_the_owners_functions(monkeypatch, tmp_path, capsys):
    calls = []

    def feature(module, attr, verb):
        def fn(*a, **kw):
            calls.append((module, attr, a, kw))
            return 3 if attr == "main_compare" else [tmp_path / "a.png"]
        return fn
    monkeypatch.setattr(cli_common, "_feature", feature)
    assert main(["build-fmus", "--force", "--out", str(tmp_path)]) == 0
    assert calls[-1] == ("orchestrator.fmi.build", "build_fmus", (), {"out_dir": str(tmp_path), "force": True})
    assert main(["plot", str(tmp_path)]) == 0
    assert calls[-1][:3] == ("orchestrator.results.plots", "plot_run", (tmp_path,))
    assert str(tmp_path / "a.png") in capsys.readouterr().out
    assert main(["compare", "c.yaml", "--update-baseline"]) == 3         # compare's exit code passes through
    assert calls[-1] == ("orchestrator.compare", "main_compare", ("c.yaml",),
                         {"out_dir": None, "update_baseline": True})


def test_unexpected_exception_is_one_line_unless_debug(monkeypatch, capsys):
    def boom(args):
        raise ZeroDivisionError("oops")
    monkeypatch.setattr(cli_run, "_cmd_validate", boom)
    parser_func = cli.build_parser
    monkeypatch.setattr(cli, "build_parser", lambda: _with_func(parser_func(), boom))
    assert main(["validate", "x.yaml"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("internal error: ZeroDivisionError: oops") and "--debug" in err
    with pytest.raises(ZeroDivisionError):
        main(["validate", "x.yaml", "--debug"])


def _with_func(parser, func):
    parse = parser.parse_args

    def parse_args(argv=None):
        args = parse(argv)
        args.func = func
        return args
    parser.parse_args = parse_args
    return parser


def test_version_and_help(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0 and capsys.readouterr().out.startswith("rotorcosim ")
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for verb in ("run", "validate", "info", "build-fmus", "plot", "compare"):
        assert verb in out


def test_run_prints_the_whirl_analysis():
    analysis = {"journals": {
        "bearing1": {"whirl": True, "onset": {"present_at_start": False}, "onset_speed_hz": 256.04,
                     "onset_time_s": 0.64, "dominant_ratio": 0.47, "vanish_speed_hz": 560.0,
                     "max_eps": 0.81, "max_eps_speed_hz": 400.0, "warnings": []},
        "bearing2": {"whirl": False, "max_eps": 0.2, "max_eps_speed_hz": 100.0},
        "bearing3": {"error": "no signal rotor.x_3"}}}
    lines = cli_run._analysis_lines(analysis)
    assert lines[1] == ("  bearing1: onset at 256.0 Hz (t = 0.6400 s), whirl/speed ratio 0.47, vanishes at "
                        "560.0 Hz; max eps 0.810 at 400.0 Hz")
    assert lines[2] == ("    (the onset is where the whirl orbit reached the detection level "
                        "(analysis.whirl.threshold); no instability threshold found before it, see warnings "
                        "in summary.json)")
    assert lines[3] == "  bearing2: no sub-synchronous whirl; max eps 0.200 at 100.0 Hz"
    assert lines[4] == "  bearing3: not analysed: no signal rotor.x_3"
    assert cli_run._analysis_lines({"error": "results.csv: not found"}) == [
        "analysis: not available: results.csv: not found"]


def test_run_prints_the_instability_threshold_beside_the_onset():
    """My pump rotor: onset (whirl at 5 % of c) 325.7 Hz, growth turning positive at 249.2 Hz
    (Ocvirk linear threshold 256.8 Hz). Before, only the onset was printed, which on a ramp lies
    far above the speed where the rotor became unstable."""
    j = {"whirl": True, "onset": {"present_at_start": False}, "onset_speed_hz": 325.70, "onset_time_s": 1.6285,
         "dominant_ratio": 0.499, "vanish_speed_hz": None, "max_eps": 0.97, "max_eps_speed_hz": 370.7,
         "threshold_speed_hz": 249.18, "threshold_time_s": 1.2459, "threshold_snr": 4.6, "warnings": []}
    lines = cli_run._analysis_lines({"parameters": {"threshold": 0.05}, "journals": {"bearing1": j}})
    assert lines[2] == ("    (the onset is where the whirl orbit reached 5 % of the clearance; it became unstable "
                        "earlier: the whirl's growth rate turns positive at 249.2 Hz (t = 1.2459 s), the "
                        "estimate of the linear stability threshold)")
    weak = cli_run._analysis_lines({"parameters": {"threshold": 0.05},
                                "journals": {"b": dict(j, threshold_snr=1.9)}})[2]
    assert weak.endswith("threshold; unreliable, the growing mode is within the noise floor there "
                         "(threshold_snr 1.9 < 3))")



_SESSION = """
import atexit, pathlib
import orchestrator.cli as cli
import orchestrator.fmi.subsystem as subsystem

MARKER = pathlib.Path({marker!r})
leave = cli.exit_process

def recorded(code):                              # what the plugin calls, recorded
    MARKER.write_text(f"exit_process({{code}})")
    leave(code)

def test_loads_an_fmu():
    subsystem.native_fmu_loaded = True          # what loading an FMU in-process sets
    cli.exit_process = recorded
    atexit.register(lambda: MARKER.write_text(MARKER.read_text() + " atexit"))
    assert {ok}
"""


@pytest.mark.parametrize("ok, code", [(True, 0), (False, 1)])
def test_pytest_session_with_an_fmu_leaves_through_exit_process_with_its_status(tmp_path, ok, code):
    """tests/exit_plugin.py: a test session that loaded an FMU in-process ends through
    cli.exit_process (no interpreter teardown, where PythonFMU can abort) with pytest's own
    exit status, its summary printed and the atexit handlers run after it."""
    marker = tmp_path / "marker"
    test = tmp_path / "test_session.py"
    test.write_text(_SESSION.format(marker=str(marker), ok=ok))
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "tests.exit_plugin",
                           "-p", "no:cacheprovider", "--rootdir", str(tmp_path), "-c", os.devnull,
                           str(test)], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == code, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert ("1 passed" if ok else "1 failed") in proc.stdout
    assert marker.read_text() == f"exit_process({code}) atexit"


def test_run_names_the_pressure_fields_a_stationary_scenario_writes(tmp_path):
    """`run` listed results.csv and summary.json only; a stationary scenario also writes
    bearing_fields.npz (what `plot` draws the pressure fields from)."""
    import subprocess
    import sys
    done = subprocess.run([sys.executable, "-m", "orchestrator", "run", "stationary_oil_bath", "--out",
                           str(tmp_path / "s"), "--no-progress"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert f"results: {tmp_path / 's'} (results.csv, summary.json, bearing_fields.npz)" in done.stdout


@pytest.mark.parametrize("args", [["scenarios"], ["--help"]])
def test_closed_output_pipe_is_no_error(args):
    """``rotorcosim scenarios | head -1`` (or ``info X.fmu | less`` quit early): the reader
    closed the pipe, the command did not fail. It used to print "error: Broken pipe" and exit 1;
    now it stops quietly with 141 (128 + SIGPIPE, what `seq 1 100000 | head -1` gives under
    `set -o pipefail`), and says nothing, because there is nobody left to read the rest."""
    r, w = os.pipe()
    os.close(r)                          # the reader is gone before the first write: EPIPE at once
    try:
        proc = subprocess.run([sys.executable, "-m", "orchestrator", *args], cwd=REPO, stdout=w,
                              stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(w)
    expected = 0 if args == ["--help"] else 141      # argparse drops a --help it cannot write and exits 0
    assert "Broken pipe" not in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.strip() == "", proc.stderr
    assert proc.returncode == expected, (proc.returncode, proc.stderr)


def test_every_out_option_says_its_default():
    """Each verb's --out help names where the output goes without it, as docs/compare.md and
    README.md do (compare's said only "report folder"; its default is out/compare/<name>)."""
    import argparse
    parser = cli.build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    missing = []
    for verb, p in subs.items():
        for a in p._actions:
            if "--out" in a.option_strings and "default" not in (a.help or ""):
                missing.append(f"{verb}: {a.help!r}")
    assert not missing, missing
    out = next(a for a in subs["compare"]._actions if "--out" in a.option_strings)
    assert "out/compare/<name>" in out.help


@pytest.mark.parametrize("verb", ["run", "validate", "stability"])
def test_misspelt_shipped_scenario_name_gets_did_you_mean(verb, tmp_path, monkeypatch, capsys):
    """`rotorcosim run quickstar` (README: "a file, or a shipped scenario by name") said only
    "quickstar: scenario file not found; check the path"; a name close to a shipped scenario's
    now gets that name, as every other key and name of rotorcosim does."""
    monkeypatch.chdir(tmp_path)
    assert main([verb, "quickstar"]) == 1
    err = capsys.readouterr().err
    assert "did you mean 'quickstart'?" in err and "rotorcosim scenarios" in err and "Traceback" not in err
    assert not (tmp_path / "runs").exists()
