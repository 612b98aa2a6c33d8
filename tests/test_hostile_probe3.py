"""Third hostile-input probe (after tests/test_hostile_probe2.py and the other catalogues): FMUs
misbehaving at run time (native C test FMU MisbehavingBearing, faults 9-13), the Python API from
scripts, full disks and odd output paths. One test per finding, each failing on the code before
its fix."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from tests.fmus_c.build_c_fmu import build_c_fmu

from hostile_builders import cli, md_scenario, write_fmu


def test_export_ssp_never_replaces_a_file_that_is_not_an_ssp(tmp_path, capsys):
    """`rotorcosim export-ssp s.yaml s.yaml` (a slip of the keyboard) replaced the scenario itself
    with the zip archive, exit 0; so did any other existing file (an FMU, results). Now an existing
    OUT is replaced only when it is an SSP archive (or empty); anything else is refused, named,
    with a new name to give, and left as it was."""
    scenario = md_scenario(tmp_path)
    text_before = scenario.read_bytes()
    rc, text = cli(capsys, "export-ssp", scenario, scenario)
    assert rc == 1, text
    assert f"{scenario}: exists and is not an SSP archive (it holds text, e.g. a scenario)" in text
    assert f"e.g. {scenario.with_suffix('.ssp')}" in text
    assert scenario.read_bytes() == text_before

    fmu = tmp_path / "m.fmu"
    fmu_before = fmu.read_bytes()
    rc, text = cli(capsys, "export-ssp", scenario, fmu)
    assert rc == 1 and "it is an FMU without SystemStructure.ssd" in text, text
    assert fmu.read_bytes() == fmu_before

    other = write_fmu(tmp_path / "other.ssp", md=False, members=[("a.txt", "x")])
    rc, text = cli(capsys, "export-ssp", scenario, other)
    assert rc == 1 and "it is a zip archive without SystemStructure.ssd" in text, text
    assert f"e.g. {tmp_path / 'other-new.ssp'}" in text

    # an earlier export and an empty file are replaced
    for name in ("x.ssp", "empty.ssp"):
        (tmp_path / name).write_bytes(b"")
        rc, text = cli(capsys, "export-ssp", scenario, tmp_path / name)
        assert rc == 0, text
        rc, text = cli(capsys, "export-ssp", scenario, tmp_path / name)
        assert rc == 0, text
        assert "SystemStructure.ssd" in zipfile.ZipFile(tmp_path / name).namelist()


class _FullFile:
    """A file object whose every write fails with ENOSPC, after ``keep`` characters of it reached
    the disk (a write that filled the disk part way)."""

    def __init__(self, f, keep: int = 0):
        self.f, self.keep = f, keep

    def __enter__(self):
        return self

    def __exit__(self, *a):
        self.f.close()

    def write(self, text):
        if self.keep:
            self.f.write(text[:self.keep])
            self.f.flush()
        raise _enospc()


def _disk_full_after(monkeypatch, rows: int):
    """results.csv fails with ENOSPC after its header and ``rows`` rows, leaving half a row in it."""
    import errno

    from orchestrator.results import safe_write
    real_open = safe_write.open_no_follow

    class Full:
        def __init__(self, f):
            self.f, self.lines = f, 0

        def write(self, text):
            if self.lines > rows:
                self.f.write("0.00")              # part of a row reached the disk
                self.f.flush()
                raise OSError(errno.ENOSPC, "No space left on device")
            self.lines += text.count("\n")
            return self.f.write(text)

        def __getattr__(self, name):
            return getattr(self.f, name)

    def open_full(path, *a, **k):
        f = real_open(path, *a, **k)
        return Full(f) if str(path).endswith("results.csv") else f
    monkeypatch.setattr(safe_write, "open_no_follow", open_full)


def test_a_full_disk_mid_run_stops_it_keeping_the_complete_rows_and_saying_why(tmp_path, capsys, monkeypatch,
                                                                              test_fmus):
    """results.csv hitting a full disk mid-run ended in "error: No space left on device; the disk is
    full" (no file, no time), or with a partly written last row in "internal error: ValueError: the
    number of columns changed" while the rows were read back; summary.json said "running" and an
    empty summary.json.tmp was left. Now the run stops there: the message names results.csv, the
    time and the rows kept, the partial row is cut off (plot and CoSimResult.load read the file),
    and the failed summary gives the same reason."""
    import json

    from hostile_builders import two_mass_dir
    from orchestrator import CoSimResult
    d = two_mass_dir(tmp_path, test_fmus)
    _disk_full_after(monkeypatch, 6)
    out = tmp_path / "out"
    rc, text = cli(capsys, "run", d / "two_mass.yaml", "--out", out)
    assert rc == 1, text
    assert (f"error: cannot write {out / 'results.csv'} at t=0.006 s (No space left on device); the run "
            "stopped there and the rows up to t=0.005 s are kept in it; free some space") in text, text
    lines = (out / "results.csv").read_text().splitlines()
    assert len(lines) == 7 and lines[-1].startswith("0.005,"), lines
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and "cannot write" in summary["message"], summary
    assert summary["end_time"] == 0.006
    assert not (out / "summary.json.tmp").exists()
    assert len(CoSimResult.load(out).t) == 6


def test_a_disk_too_full_for_the_summary_says_so_and_leaves_no_temporary_file(tmp_path, capsys, monkeypatch,
                                                                             test_fmus, caplog):
    """When summary.json could not be written at the end either, the OSError of that write replaced
    the run's own reason ("error: No space left on device"). Now the run's reason is the error, and
    an ERROR line says that summary.json still says 'running' and what the outcome was."""
    import errno

    from hostile_builders import two_mass_dir
    from orchestrator.results import safe_write
    d = two_mass_dir(tmp_path, test_fmus)
    _disk_full_after(monkeypatch, 6)
    real_fdopen = safe_write.os.fdopen
    calls = {"n": 0}

    def fdopen(fd, mode="r", *a, **k):
        f = real_fdopen(fd, mode, *a, **k)
        if mode != "w" or not str(safe_write.os.readlink(f"/proc/self/fd/{fd}")).endswith("summary.json.tmp"):
            return f
        calls["n"] += 1
        return f if calls["n"] == 1 else _FullFile(f)     # the "running" summary fits, no later one
    monkeypatch.setattr(safe_write.os, "fdopen", fdopen)
    out = tmp_path / "out"
    rc, text = cli(capsys, "run", d / "two_mass.yaml", "--out", out)
    assert rc == 1, text
    assert f"error: cannot write {out / 'results.csv'} at t=0.006 s" in text, text
    assert (f"cannot write {out / 'summary.json'} (No space left on device); free some space on that disk or "
            "give another output folder (--out); it still says 'running'. The run's outcome (failed): ") in caplog.text
    assert not (out / "summary.json.tmp").exists()


# -- native C test FMU (tests/fmus_c: MisbehavingBearing faults 9-13) --------------------------

HERE = Path(__file__).resolve().parent
needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")
FAULTS = {"log-flood": 9, "log-hostile": 10, "pending": 11, "status-42": 12, "no-state": 13, "other-name": 14}


@pytest.fixture(scope="module")
def c_fmus(tmp_path_factory):
    d = tmp_path_factory.mktemp("probe3_fmus")
    build_c_fmu(d, "LinearBearing")
    build_c_fmu(d, "MisbehavingBearing")
    return d


def _c_scenario(d, fault: str, isolation: str = "none", scheme: str = "jacobi"):
    path = d / f"{fault}_{isolation}_{scheme}.yaml"
    path.write_text("\n".join([
        f"name: {fault}", "stop_time: 0.01", "fmus:",
        f"  bearing1: {{path: MisbehavingBearing.fmu, parameters: {{fault: {FAULTS[fault]}, fault_step: 5}}}}",
        "  bearing2: {path: LinearBearing.fmu}",
        "connections:",
        "  - {from: bearing1.Fx, to: bearing2.x, gain: 1.0e-9}",
        "  - {from: bearing2.Fx, to: bearing1.x, gain: 1.0e-9, offset: 1.0e-6}",
        f"coupling: {{scheme: {scheme}, macro_step: 1.0e-3, isolation: {isolation}}}",
        "output: {interval: 1.0e-3, signals: [bearing1.Fx, bearing2.Fx]}", ""]))
    return path


def _run_cli(tmp_path, *args) -> tuple[int, str]:
    env = {**os.environ, "PYTHONPATH": str(HERE.parent)}
    p = subprocess.run([sys.executable, "-m", "orchestrator", *map(str, args)], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=120)
    return p.returncode, p.stdout + p.stderr


@needs_gcc
@pytest.mark.parametrize("isolation", ["none", "process"])
def test_an_fmu_flooding_its_log_does_not_flood_the_terminal(tmp_path, c_fmus, isolation):
    """An FMU logging 2000 warnings of 1000 characters per step printed every one: 12 MB on the
    terminal for 6 steps (a long run: gigabytes; in a worker process all of a call's messages were
    also held in memory and sent to the master). Now the first LOG_SHOWN (20) are shown, then one
    line says the rest are not, and when the instance is freed one line gives their number and
    the last message; an FMU error still gets its last messages in the error."""
    rc, text = _run_cli(tmp_path, "run", _c_scenario(c_fmus, "log-flood", isolation), "--out", tmp_path / "out")
    assert rc == 0, text[-2000:]
    assert len(text) < 100_000, len(text)
    assert text.count("[warning] fault 9: ") == 21          # 20 shown + the last one in the count line
    assert "bearing1: the FMU's further log messages are not shown (20 shown)" in text
    assert "bearing1: 11980 more log messages of the FMU were not shown (20 shown); the last: [warning] fault 9" in text


@needs_gcc
@pytest.mark.parametrize("isolation", ["none", "process"])
def test_an_fmu_that_gives_no_state_is_stopped_at_once(tmp_path, c_fmus, isolation):
    """fmi2GetFMUstate returning fmi2OK without a state (NULL) was taken: the iterative scheme
    finished "successfully" with NULL states, which it would hand back to fmi2SetFMUstate (a crash
    in most FMUs, a silent no-op in others). Now the first such call stops the run naming the
    instance, the function and a coupling that saves no states."""
    out = tmp_path / "out"
    rc, text = _run_cli(tmp_path, "run", _c_scenario(c_fmus, "no-state", isolation, "iterative"), "--out", out)
    assert rc == 1, text[-2000:]
    assert ("FMU instance 'bearing1' returned no state in fmi2GetFMUstate during the macro step from t=0 s" in text
            and "gave no FMU state (NULL), although the FMU declares canGetAndSetFMUstate" in text), text[-2000:]
    assert "This breaks the FMI 2.0 standard" in text and "smaller coupling.macro_step" not in text


@needs_gcc
@pytest.mark.parametrize("fault, said", [
    ("pending", "returned fmi2Pending (an asynchronous step) in fmi2DoStep"),
    ("status-42", "returned illegal status 42 in fmi2DoStep")])
def test_pending_or_an_unknown_status_is_not_blamed_on_the_macro_step(tmp_path, c_fmus, fault, said):
    """fmi2DoStep returning fmi2Pending or 42 ended in "... also try a smaller coupling.macro_step
    or more substeps", advice that cannot help; now the message says what the FMU did and that
    no macro step changes it."""
    rc, text = _run_cli(tmp_path, "run", _c_scenario(c_fmus, fault), "--out", tmp_path / "out")
    assert rc == 1, text[-2000:]
    assert f"FMU instance 'bearing1' {said} during the macro step from t=0.004 s to t=0.005 s" in text, text[-2000:]
    assert "whatever the macro step" in text and "smaller coupling.macro_step" not in text, text[-2000:]


def test_the_python_api_names_a_wrong_argument_and_the_fix(tmp_path):
    """From a script, None, a number or bytes for a path ended in pathlib's "expected str, bytes or
    os.PathLike object, not NoneType" (no function, no argument); overrides given as a dict were
    read as its keys ("--set coupling.macro_step: expected KEY.PATH=VALUE"); an int among
    run()'s observers failed mid-run ("'int' object has no attribute 'on_initialized'") after the
    output folder was set up; run(progress='no') was taken as True; CoSimResult.load of a missing
    folder, a file or an empty folder returned a 'failed' result with no message; MasterAlgorithm(None)
    raised AttributeError. Each now raises a TypeError (a CosimError for the folder) naming the call,
    the argument, what came and an example."""
    import orchestrator as o
    from orchestrator.compare.runner import main_compare
    from orchestrator.errors import CosimError
    from orchestrator.results.plots import plot_run
    from orchestrator.sweep import prepare, sweep
    from orchestrator.sweep.plot import plot_sweep
    scenario = md_scenario(tmp_path)
    sc = o.load_scenario(scenario)
    cases = [
        (lambda: o.load_scenario(None), "load_scenario(path) takes a file or folder name as str or pathlib.Path "
                                        "(got NoneType None); e.g. load_scenario("),
        (lambda: o.load_scenario(str(scenario).encode()), "(got bytes b'"),
        (lambda: o.validate_scenario(3), "validate_scenario(path) takes a file or folder name"),
        (lambda: o.load_scenario(scenario, overrides={"coupling.macro_step": 1e-5}),
         "load_scenario(overrides=...) takes a list of 'key.path=value' texts (got a dict); write "
         "overrides=['coupling.macro_step=1e-05']"),
        (lambda: o.run(sc, out_dir=None), "run(out_dir=...) takes a file or folder name"),
        (lambda: o.run(sc, out_dir=tmp_path / "r", progress="no"), "run(progress=...) takes True, False or None"),
        (lambda: o.run(sc, out_dir=tmp_path / "r", observers=object()),
         "run(observers=...) takes a list of Observer objects (got object)"),
        (lambda: o.run(sc, out_dir=tmp_path / "r", observers=[1]),
         "run(observers=...): item 0 (int 1) is no observer: it has no on_initialized() method"),
        (lambda: o.CoSimResult.load(None), "CoSimResult.load(out_dir) takes a file or folder name"),
        (lambda: o.MasterAlgorithm(None), "MasterAlgorithm() takes a Scenario from load_scenario() (got NoneType"),
        (lambda: o.MasterAlgorithm(sc, observers=[None]),
         "MasterAlgorithm(observers=...): item 0 (NoneType None) is no observer"),
        (lambda: sweep(None), "sweep(path) takes a file or folder name"),
        (lambda: prepare(3), "prepare(path) takes a file or folder name"),
        (lambda: main_compare(None), "main_compare(path) takes a file or folder name"),
        (lambda: main_compare(tmp_path / "c.yaml", workers="2"),
         "main_compare(workers=...) takes a whole number of at least 1, or None"),
        (lambda: main_compare(tmp_path / "c.yaml", runner="run"), "main_compare(runner=...) takes a function"),
        (lambda: plot_sweep(None), "plot_sweep(out_dir) takes a file or folder name"),
        (lambda: plot_run(None), "plot_run(run_dir) takes a file or folder name"),
    ]
    for call, said in cases:
        with pytest.raises(TypeError) as info:
            call()
        assert said in str(info.value), str(info.value)
    assert not (tmp_path / "r").exists()                       # refused before the folder was made
    (tmp_path / "empty").mkdir()
    for folder, what in [(tmp_path / "nothing", "no such folder"), (scenario, "not a folder"),
                         (tmp_path / "empty", "no results.csv, results.parquet or summary.json in it")]:
        with pytest.raises(CosimError) as info:
            o.CoSimResult.load(folder)
        assert f"{folder}: no run folder ({what}); give the out_dir of a run" in str(info.value)
    (tmp_path / "empty" / "results.csv").write_text("time,a.y\n0.0,1.0\n")
    res = o.CoSimResult.load(tmp_path / "empty")                # rows but no summary: said, not ''
    assert res.message.startswith(f"{tmp_path / 'empty' / 'summary.json'} is missing: the run was killed"), res


def test_init_with_an_empty_folder_name_is_refused(tmp_path, capsys, monkeypatch):
    """`rotorcosim init ""` (an unset shell variable) copied every shipped scenario into the current
    folder and suggested `rotorcosim run /jeffcott_....yaml`, a path at the root; now it is a usage
    error (exit 2) and nothing is copied."""
    monkeypatch.chdir(tmp_path)
    for empty in ("", " "):
        with pytest.raises(SystemExit) as e:
            cli(capsys, "init", empty)
        assert e.value.code == 2
        assert "argument DIR: an empty folder name: give the folder to copy the scenarios into" in \
            capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def _liar_fmu(c_fmus: Path) -> Path:
    """LinearBearing whose model description also declares a parameter 'extra' (vr 20) and a local
    'ghost' (vr 21), which its binary does not know ("unknown value reference")."""
    liar = c_fmus / "Liar.fmu"
    if not liar.exists():
        extra = ('<ScalarVariable name="extra" valueReference="20" causality="parameter" variability="fixed" '
                 'initial="exact"><Real start="1"/></ScalarVariable>'
                 '<ScalarVariable name="ghost" valueReference="21" causality="local" variability="continuous" '
                 'initial="calculated"><Real/></ScalarVariable></ModelVariables>')
        with zipfile.ZipFile(c_fmus / "LinearBearing.fmu") as src, zipfile.ZipFile(liar, "w") as dst:
            for info in src.infolist():
                data = src.read(info.filename)
                if info.filename == "modelDescription.xml":
                    data = data.decode().replace("</ModelVariables>", extra, 1).encode()
                dst.writestr(info, data)
    return liar


@needs_gcc
@pytest.mark.parametrize("isolation", ["none", "process"])
def test_an_fmu_refusing_a_variable_it_declares_is_traced_to_the_variable(tmp_path, c_fmus, isolation):
    """An FMU whose model description declares variables its binary then refuses failed with
    "FMU instance 'b': fmi2SetReal returned error: FMU log: ... unknown value reference 20": no
    parameter, no value, no scenario line (and for a recorded variable no name). Now the refused
    parameter is named with its value, type, value reference and the scenario line that sets
    it, and a failed get/set names the variables the call passed."""
    _liar_fmu(c_fmus)
    coupling = f"coupling: {{macro_step: 1.0e-3, isolation: {isolation}}}"
    (c_fmus / f"liar_p_{isolation}.yaml").write_text(
        f"name: liar\nstop_time: 0.01\nfmus:\n  b: {{path: Liar.fmu, parameters: {{extra: 2.0}}}}\n{coupling}\n"
        "output: {signals: [b.Fx]}\n")
    rc, text = _run_cli(tmp_path, "run", c_fmus / f"liar_p_{isolation}.yaml", "--out", tmp_path / "p")
    assert rc == 1, text[-2000:]
    assert ("error: FMU instance 'b': fmi2SetReal returned error: the FMU refused parameter 'extra' = 2.0 "
            "(Real, value reference 20), which its model description declares") in text, text[-2000:]
    assert f"'b' gets extra from {c_fmus / f'liar_p_{isolation}.yaml'}:4" in text, text[-2000:]
    (c_fmus / f"liar_g_{isolation}.yaml").write_text(
        f"name: liar\nstop_time: 0.01\nfmus:\n  b: {{path: Liar.fmu}}\n{coupling}\n"
        "output: {signals: [b.Fx, b.ghost]}\n")
    rc, text = _run_cli(tmp_path, "run", c_fmus / f"liar_g_{isolation}.yaml", "--out", tmp_path / "g")
    assert rc == 1, text[-2000:]
    assert ("FMU instance 'b': fmi2GetReal returned error: the call read Fx (value reference 7), ghost (value "
            "reference 21); FMU log: ") in text, text[-2000:]


def _enospc():
    import errno
    return OSError(errno.ENOSPC, "No space left on device")


@pytest.mark.parametrize("code, fix", [("ENOSPC", "free some space on that disk"),
                                       ("EDQUOT", "free some of your disk quota"),
                                       ("EACCES", "check that disk")])
def test_the_disk_full_fix_is_one_text_for_every_writer(code, fix):
    """safe_write.space_fix is the one text of the full-disk (or full-quota) fix; the results
    writer had its own copy of it (with the quota case the shared one lacked)."""
    import errno

    from types import SimpleNamespace

    from orchestrator.results.safe_write import space_fix
    from orchestrator.results.writer import ResultsWriter
    e = OSError(getattr(errno, code), "x")
    assert space_fix(e, "check that disk") == fix
    # and the results writer says it (it had its own copy of the text): its failure message, as a run gets it
    writer = SimpleNamespace(_f=None, _pq=None, _csv=None, _buf=[], _t=0.5, format="parquet",
                             path=Path("/nowhere/results.parquet"))
    said = str(ResultsWriter._failed(writer, e, None))
    assert said.endswith(f"; {fix} or give another output folder (--out)"), said


def test_an_exhausted_quota_reaching_the_cli_gets_a_fix():
    """An OSError the CLI reports itself (a path it opens) had a fix for a full disk and none for
    an exhausted quota (EDQUOT), which the writers name since space_fix learnt it."""
    import errno

    from orchestrator.cli import _describe
    said = _describe(OSError(errno.EDQUOT, "Disk quota exceeded", "/x/out.csv"))
    assert said == ("error: /x/out.csv: Disk quota exceeded; your disk quota is used up: free some of it or "
                    "choose another place"), said


def test_a_full_disk_while_writing_plots_fmus_or_an_ssp_names_the_file_and_leaves_no_debris(
        tmp_path, capsys, monkeypatch):
    """A full disk under `rotorcosim plot` left an empty signals_*.png and said "error: No space left
    on device" (no file); under `build-fmus --out` it left an empty .JournalBearing.fmu.<pid>.tmp and
    named the build's temporary FMU in /tmp instead of the target; under `export-ssp` the message
    named no file. Each now names the file it could not write, says what to do, and leaves no
    partial file."""
    import subprocess
    from types import SimpleNamespace

    from matplotlib.figure import Figure

    from orchestrator.fmi import build

    # plot: the figure is written to a temporary name, removed when the disk is full
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.csv").write_text("time,a.y\n0.0,1.0\n0.1,2.0\n")
    real_savefig = Figure.savefig

    def full_savefig(self, f, *a, **k):
        if isinstance(f, (str, Path)):             # (the old code gave savefig the file name)
            with open(f, "wb") as fh:
                fh.write(b"\x89PNG")
        else:
            f.write(b"\x89PNG")
        raise _enospc()
    monkeypatch.setattr(Figure, "savefig", full_savefig)
    rc, text = cli(capsys, "plot", run)
    assert rc == 1 and (f"error: cannot write {run / 'plots' / 'signals_a.png'} (No space left on device); free "
                        "some space on that disk, then run the command again") in text, text
    assert [p.name for p in (run / "plots").iterdir()] == []
    monkeypatch.setattr(Figure, "savefig", real_savefig)

    # build-fmus --out: the PythonFMU build itself is faked (fast); copying the result fails
    def fake_build(cmd, **kw):
        import json
        dest = json.loads(cmd[-1])["dest"]
        with zipfile.ZipFile(dest, "w") as zf:
            zf.writestr("modelDescription.xml", "<x/>")
        return SimpleNamespace(returncode=0, stderr="", stdout=dest)

    real_copy = build.shutil.copyfile

    def full_copy(src, dst, **kw):
        if not str(dst).endswith(".tmp"):          # staging the sources still works
            return real_copy(src, dst, **kw)
        Path(dst).write_bytes(b"PK")
        raise _enospc()
    monkeypatch.setattr(build.subprocess, "run", fake_build)
    monkeypatch.setattr(build.shutil, "copyfile", full_copy)
    out = tmp_path / "fmus"
    with pytest.raises(build.FmuError) as info:
        build.build_one(build.RECIPES["JeffcottRotor"], out)
    assert str(info.value).startswith(f"cannot write {out / 'JeffcottRotor.fmu'} (No space left on device); "
                                      "free some space on that disk"), str(info.value)
    assert list(out.iterdir()) == []
    monkeypatch.setattr(build.subprocess, "run", subprocess.run)
    monkeypatch.setattr(build.shutil, "copyfile", real_copy)

    # export-ssp
    scenario = md_scenario(tmp_path)

    def full_write(self, *a, **k):
        raise _enospc()
    monkeypatch.setattr(zipfile.ZipFile, "write", full_write)
    rc, text = cli(capsys, "export-ssp", scenario, tmp_path / "x.ssp")
    assert rc == 1 and (f"error: {tmp_path / 'x.ssp'}: cannot write the archive (No space left on device); free "
                        "some space on that disk") in text, text
    assert not any(p.name.startswith(".x.ssp") for p in tmp_path.iterdir())


def test_plot_of_a_signal_spanning_more_than_the_largest_float(tmp_path, capsys):
    """A recorded signal from -1e308 to 1e308 (an FMU's DBL_MAX 'no value' marker, or a blown-up
    output) ended `rotorcosim plot` in "internal error: ValueError: arange: cannot compute length"
    (matplotlib's ticks). Now that signal is skipped with a warning naming it and its range, and
    the others are drawn."""
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.csv").write_text("time,a.y,a.z\n0.0,1e308,1.0\n0.1,-1e308,2.0\n0.2,0.0,3.0\n")
    with pytest.warns(UserWarning) as warned:
        rc, text = cli(capsys, "plot", run)
    assert rc == 0, text
    said = " ".join(str(w.message) for w in warned)
    assert ("signal plots: 'a.y' spans more than the largest floating-point number (from -1e+308 to 1e+308; "
            "an FMU's 'no value' marker such as DBL_MAX?); not drawn") in said, said
    assert [p.name for p in (run / "plots").iterdir()] == ["signals_a.png"]


def test_sweep_api_workers_and_scheduler_of_the_wrong_type(tmp_path):
    """sweep(path, workers="4") ended in "'<' not supported between instances of 'str' and 'int'"
    after every run's scenario was validated, workers=2.5 reached Dask, scheduler=3 was taken for
    an address. Now each is a TypeError naming the argument and an example, before anything else."""
    from orchestrator.sweep import sweep
    path = tmp_path / "never_read.yaml"
    for kw, said in [({"workers": "4"}, "sweep(workers=...) takes a whole number of at least 1, or None for one "
                                        "per core (got '4'); e.g. workers=4"),
                     ({"workers": 2.5}, "(got 2.5)"), ({"workers": True}, "(got True)"),
                     ({"scheduler": 3}, "sweep(scheduler=...) takes the address of a Dask scheduler as a text")]:
        with pytest.raises(TypeError) as info:
            sweep(path, **kw)
        assert said in str(info.value), str(info.value)


def test_files_no_run_wrote_are_never_moved_aside_or_deleted(tmp_path):
    """`--out` a folder holding someone's own results.csv: the first run moved it into previous/
    without a word, the second deleted it. Now a folder whose run files no rotorcosim run wrote
    (no .rotorcosim.lock, no summary.json of a run) is refused before anything is written, so a
    second try is refused the same way; a run folder (lock file, or a run's summary.json from
    before lock files) still has its files moved aside."""
    import json

    from orchestrator.coupling.lifecycle import RunFolder
    from orchestrator.errors import LifecycleError
    sc = type("Sc", (), {"name": "s", "source": None})()
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "results.csv").write_text("precious lab data\n")
    for _ in range(2):
        with pytest.raises(LifecycleError) as info:
            with RunFolder(mine, sc):
                pass
        assert (f"output folder {mine} holds results.csv, which no rotorcosim run wrote (no .rotorcosim.lock, no "
                "summary.json of a run); a run would move it into previous/") in str(info.value)
    assert sorted(p.name for p in mine.iterdir()) == ["results.csv"]
    assert (mine / "results.csv").read_text() == "precious lab data\n"

    old = tmp_path / "old_run"                       # a run's folder from before lock files
    old.mkdir()
    (old / "results.csv").write_text("time,a.y\n0.0,1.0\n")
    (old / "summary.json").write_text(json.dumps({"scenario": "s", "status": "finished"}))
    with RunFolder(old, sc) as f:
        f.finish({"status": "finished"})
    assert (old / "previous" / "results.csv").read_text() == "time,a.y\n0.0,1.0\n"


@needs_gcc
def test_an_fmu_logging_under_another_instance_name_is_capped_and_escaped(tmp_path, c_fmus):
    """The cap on shown log messages keyed on the instance name the FMU passes; an FMU logging
    under a name of its own (or after it was freed) printed every message (500 a step here), and
    that name reached the terminal raw: "other\\x1b[2J" cleared the screen. Now such names are
    capped the same way, per name, and shown escaped."""
    rc, text = _run_cli(tmp_path, "run", _c_scenario(c_fmus, "other-name"), "--out", tmp_path / "out")
    assert rc == 0, text[-2000:]
    assert "\x1b" not in text
    assert text.count("other\\x1b[2J: [warning] fault 14: a message under another instance name") == 20, text[-3000:]
    assert ("other\\x1b[2J: the FMU's further log messages are not shown (20 shown) (no instance of the run has "
            "this name: the FMU logs under a name of its own)") in text


def test_a_full_disk_under_a_sweep_table_or_a_compare_report_names_the_file(tmp_path, monkeypatch):
    """sweep.csv hitting a full disk left a partial sweep.csv.tmp and "No space left on device"
    without a file; so did compare's report.md. Now the table and the reports are written
    atomically and the error names the file; nothing partial is left."""
    from types import SimpleNamespace

    from orchestrator.errors import OutputWriteError
    from orchestrator.results import safe_write
    from orchestrator.sweep.table import write_table
    real_fdopen = safe_write.os.fdopen

    def fdopen(fd, mode="r", *a, **k):
        f = real_fdopen(fd, mode, *a, **k)
        return _FullFile(f, 10) if "w" in mode and "sweep" in safe_write.os.readlink(f"/proc/self/fd/{fd}") else f
    real_open = Path.open

    def path_open(self, mode="r", *a, **k):       # (the old code wrote sweep.csv.tmp through Path.open)
        f = real_open(self, mode, *a, **k)
        return _FullFile(f, 10) if "w" in mode and "sweep" in self.name else f
    monkeypatch.setattr(safe_write.os, "fdopen", fdopen)
    monkeypatch.setattr(Path, "open", path_open)
    spec = SimpleNamespace(parameters=[SimpleNamespace(name="speed", paths=("a.b",))], collect=[],
                           source="s.yaml", scenario="x.yaml", mode="grid")
    with pytest.raises(OutputWriteError) as info:
        write_table([{"run_id": "r1", "speed": 1.0, "status": "finished"}], spec, tmp_path)
    assert str(info.value).startswith(f"cannot write {tmp_path / 'sweep.csv'} (No space left on device); free "
                                      "some space on that disk"), str(info.value)
    assert list(tmp_path.iterdir()) == []


def test_a_full_disk_under_a_parquet_results_file_keeps_the_runs_reason(tmp_path, capsys, monkeypatch, test_fmus):
    """With output.format parquet a full disk left results.parquet without its footer, and reading
    the rows back ended the run in "internal error: ArrowInvalid: ... Parquet magic bytes not
    found", hiding why it stopped. Now the error names the file and the time; the rows that cannot
    be read back are a warning."""
    pytest.importorskip("pyarrow")
    from hostile_builders import two_mass_dir
    from orchestrator.results import writer
    d = two_mass_dir(tmp_path, test_fmus)

    def full(self, rows):
        raise _enospc()
    monkeypatch.setattr(writer._ParquetSink, "write", full)
    monkeypatch.setattr(writer._ParquetSink, "close", lambda self: (_ for _ in ()).throw(_enospc()))  # no footer
    out = tmp_path / "out"
    rc, text = cli(capsys, "run", d / "two_mass.yaml", "--out", out, "--set", "output.format=parquet")
    assert rc == 1, text
    assert (f"error: cannot write {out / 'results.parquet'} at t=0 s (No space left on device); the run stopped "
            "there and the Parquet file is incomplete") in text, text


def test_the_number_of_fmu_instances_and_of_worker_processes_is_bounded(tmp_path, capsys, monkeypatch, test_fmus):
    """A 10 kB scenario listing 2000 instances of one FMU made `rotorcosim validate` (which loads
    every FMU in a worker process of its own) start 2000 Python processes of ~35 MB at once, and
    `run` with isolation: process the same. Now 'fmus' holds at most MAX_FMU_INSTANCES (256)
    entries, a run puts at most ROTORCOSIM_MAX_WORKERS (32) instances into worker processes, and
    validate loads more than that as run does, with a warning."""
    from hostile_builders import two_mass_dir
    from orchestrator.scenario.limits import MAX_FMU_INSTANCES
    write_fmu(tmp_path / "m.fmu")
    many = tmp_path / "many.yaml"
    many.write_text("name: many\nstop_time: 0.01\nfmus:\n" + "".join(
        f"  a{i}: {{path: m.fmu}}\n" for i in range(MAX_FMU_INSTANCES + 1)) + "coupling: {macro_step: 1.0e-3}\n")
    rc, text = cli(capsys, "validate", many)
    assert rc == 1 and (f"many.yaml:4: 'fmus' lists {MAX_FMU_INSTANCES + 1} FMU instances, more than "
                        f"{MAX_FMU_INSTANCES}") in text, text[-2000:]

    (tmp_path / "two").mkdir()
    d = two_mass_dir(tmp_path / "two", test_fmus)
    monkeypatch.setenv("ROTORCOSIM_MAX_WORKERS", "1")
    rc, text = cli(capsys, "validate", d / "two_mass.yaml")
    assert rc == 0, text
    assert ("warning: validate loads the 2 FMU instances as `run` does, not each in a worker process of its own "
            "(more than ROTORCOSIM_MAX_WORKERS = 1)") in text, text
    rc, text = cli(capsys, "run", d / "two_mass.yaml", "--out", tmp_path / "out", "--set", "coupling.isolation=process")
    assert rc == 1 and ("2 FMU instances run in worker processes (isolation: process), more than 1 at once" in text), text


def test_a_results_file_too_wide_for_its_readers_is_refused_when_loading(tmp_path):
    """An FMU with 45 000 outputs, recorded by default (every output of every FMU), made a run that
    finished but wrote rows longer than the 1 MiB line limit of results.csv's reader: `plot`,
    `compare`, CoSimResult.load and the analysis then refused the file. Now loading the scenario
    says so, with the numbers and the fix (fewer signals, or Parquet)."""
    from orchestrator import load_scenario
    from orchestrator.errors import ScenarioError
    from hostile_builders import md_xml
    n = 45_000
    variables = "".join(f'<ScalarVariable name="y{i}" valueReference="{i}" causality="output"><Real/>'
                        "</ScalarVariable>" for i in range(n))
    structure = ("<ModelStructure><Outputs>" + "".join(f'<Unknown index="{i + 1}" dependencies=""/>' for i in range(n))
                 + "</Outputs></ModelStructure>")
    write_fmu(tmp_path / "wide.fmu", md_xml(variables=variables, structure=structure))
    path = tmp_path / "wide.yaml"
    path.write_text("name: wide\nstop_time: 0.01\nfmus:\n  a: {path: wide.fmu}\ncoupling: {macro_step: 1.0e-3}\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert ("results.csv would have 45000 columns (output.signals not given: every output of every FMU): a row can "
            "be 1125025 bytes long, more than the 1048576 bytes") in str(info.value), str(info.value)
    path.write_text(path.read_text() + "output: {signals: ['a.y1*'], format: parquet}\n")
    assert load_scenario(path).output.signals[0] == "a.y1"       # fewer signals (or Parquet): loads


def test_string_values_too_long_together_for_a_line_are_cut_to_fit_and_said_once(tmp_path, caplog):
    """Each String value is cut at 4096 characters, but 300 of them in a row made a line longer than
    the 1 MiB a line of results.csv may have: the run finished with a file plot, compare and
    CoSimResult.load refuse (the row-width check at load counts String values as empty). Now
    such a row's String values are cut to fit, with one warning; and the per-column warnings of
    cut values stop after a few columns (300 columns gave 300 lines)."""
    import logging

    from orchestrator.results.run_directory import MAX_LINE_BYTES, read_results
    from orchestrator.results.writer import SAID_COLUMNS, ResultsWriter
    n = 300
    path = tmp_path / "results.csv"
    w = ResultsWriter(path, [f"s{i}" for i in range(n)] + ["x"], ["String"] * n + ["Real"])
    w.open()
    with caplog.at_level(logging.WARNING):
        w.write(0.0, ['é"' * 3000] * n + [1.5])
        w.write(0.1, ["short"] * n + [2.5])
    w.close()
    assert max(len(line) for line in path.read_bytes().split(b"\n")) <= MAX_LINE_BYTES
    assert list(read_results(path)["x"]) == [1.5, 2.5]
    said = [r.getMessage() for r in caplog.records]
    assert len([m for m in said if "holds 6000 characters" in m]) == SAID_COLUMNS, said[:8]
    assert sum("would be longer than a line of results.csv may be" in m for m in said) == 1, said[-3:]
    assert len(said) <= SAID_COLUMNS + 2, len(said)
