"""Fifth hostile and any-FMU probe (after tests/test_hostile_probe4.py and the other catalogues): the
FMU log formatter, worker processes and run folders. One test per finding, each failing on the
code before its fix."""

from __future__ import annotations

import json
import shutil
import signal
from pathlib import Path

import pytest

from tests.fmus_c.build_c_fmu import build_c_fmu

HERE = Path(__file__).resolve().parent
needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")


@pytest.fixture(scope="module")
def c_fmus(tmp_path_factory) -> Path:
    if shutil.which("gcc") is None:
        pytest.skip("gcc not installed (native test FMU)")
    d = tmp_path_factory.mktemp("probe5_fmus")
    build_c_fmu(d, "LinearBearing")
    build_c_fmu(d, "MisbehavingBearing")
    return d


def _bearing_scenario(d: Path, tmp_path: Path, *, fault: int = 0, isolation: str = "none", extra: str = "") -> Path:
    path = tmp_path / "s.yaml"
    path.write_text("\n".join([
        "name: probe5", "stop_time: 0.01", "fmus:",
        f"  bearing1: {{path: {d / 'MisbehavingBearing.fmu'}, parameters: {{fault: {fault}, fault_step: 5}}}}",
        f"  bearing2: {{path: {d / 'LinearBearing.fmu'}}}",
        "connections:",
        "  - {from: bearing1.Fx, to: bearing2.x, gain: 1.0e-9}",
        "  - {from: bearing2.Fx, to: bearing1.x, gain: 1.0e-9, offset: 1.0e-6}",
        f"coupling: {{macro_step: 1.0e-3, isolation: {isolation}}}",
        "output: {interval: 1.0e-3, signals: [bearing1.Fx, bearing2.Fx]}", extra]))
    return path


@pytest.mark.parametrize("raised, status, words", [
    ("signal", "failed", "terminated by signal SIGTERM before the co-simulation started"),
    ("error", "failed", "setup failed: FMU instance 'bearing1': no room"),
])
def test_a_run_that_never_started_says_why_in_its_summary(tmp_path, c_fmus, monkeypatch, raised, status, words):
    """A run whose initialization raised something other than an FMU call's error (a second
    Ctrl-C or SIGTERM while an FMU initializes, e.g. one that hangs there; an FmuError of the
    worker's shared memory) left summary.json at status "not_started" with an empty message:
    the master's release hook wrote the summary of a master that never started, and RunFolder
    then took the run as finished and did not write the failed summary with the reason (nor
    ``stopped_by``, by which a sweep counts a run as cancelled). Reproduced with the CLI:
    MisbehavingBearing fault 15 (hangs in fmi2ExitInitializationMode) in a worker, SIGTERM twice."""
    import orchestrator
    from orchestrator.coupling.lifecycle import RunStopped
    from orchestrator.errors import FmuError
    from orchestrator.fmi.subsystem import Subsystem

    def stop(self):
        if raised == "signal":
            raise RunStopped(signal.SIGTERM)
        raise FmuError(f"FMU instance '{self.name}': no room")

    monkeypatch.setattr(Subsystem, "exit_initialization_mode", stop)
    out = tmp_path / "out"
    sc = orchestrator.load_scenario(_bearing_scenario(c_fmus, tmp_path))
    with pytest.raises(RunStopped if raised == "signal" else FmuError):
        orchestrator.run(sc, out_dir=out, progress=False)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == status and words in summary["message"], summary
    if raised == "signal":
        assert summary["stopped_by"] == "SIGTERM"


def _wide_fmu(c_fmus: Path, tmp_path: Path, n: int) -> Path:
    """LinearBearing with ``n`` more Real variables: locals F0.. that alias its output Fx."""
    import zipfile
    with zipfile.ZipFile(c_fmus / "LinearBearing.fmu") as z:
        md = z.read("modelDescription.xml").decode()
        so = z.read("binaries/linux64/LinearBearing.so")
    extra = "".join(f'<ScalarVariable name="F{i}" valueReference="7" causality="local" variability="continuous" '
                    'initial="calculated"><Real/></ScalarVariable>' for i in range(n))
    path = tmp_path / "Wide.fmu"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", md.replace("</ModelVariables>", extra + "</ModelVariables>"))
        z.writestr("binaries/linux64/LinearBearing.so", so)
    return path


def test_an_fmu_recording_many_signals_runs_and_validates_in_a_worker(tmp_path, c_fmus, capsys):
    """A worker's shared memory was a fixed 1 MiB: an FMU recording more than about 16 000 Real
    signals (17 000 here) in a worker failed with "the value buffers exceed the worker's shared
    memory (1048576 bytes); record fewer signals or run it with isolation: none", and, since
    `validate` loads every FMU in a worker, validate refused the same scenario with
    isolation: none with that advice, while `run` finished it. Now the shared memory is sized
    from the Real variables of the FMU's model description (orchestrator.fmi.channel.arena_bytes)."""
    from hostile_builders import cli
    n = 17_000
    fmu = _wide_fmu(c_fmus, tmp_path, n)
    signals = ", ".join(f"b.F{i}" for i in range(n))
    for isolation in ("none", "process"):
        (tmp_path / f"{isolation}.yaml").write_text(
            f"name: wide\nstop_time: 0.002\nfmus:\n  b: {{path: {fmu}}}\n"
            f"coupling: {{macro_step: 1.0e-3, isolation: {isolation}}}\n"
            f"output: {{interval: 1.0e-3, signals: [{signals}]}}\n")
    rc, text = cli(capsys, "validate", tmp_path / "none.yaml")
    assert rc == 0 and "valid" in text and "shared memory" not in text, text[-2000:]
    out = tmp_path / "out"
    rc, text = cli(capsys, "run", tmp_path / "process.yaml", "--out", out, "--no-progress")
    assert rc == 0 and "shared memory" not in text, text[-2000:]
    rows = (out / "results.csv").read_text().splitlines()
    assert len(rows) == 4 and rows[0].count(",") == n


@pytest.mark.parametrize("var, value, said", [
    ("ROTORCOSIM_SAFE_LOGGER", "yes", "ROTORCOSIM_SAFE_LOGGER must be 1 (our logger formats FMU log messages, the "
                                      "default) or 0 (fmpy's proxy does) (got 'yes'); unset it for the default"),
    ("CC", 'gcc "-O2', "CC, the C compiler the FMU log formatter is built with (orchestrator/fmi/safe_log.py), cannot "
                       "be split into words as a shell would (No closing quotation; got 'gcc \"-O2'); close its "
                       "quotes, or unset CC to use cc, gcc or clang"),
])
def test_a_setting_the_fmu_loader_reads_is_named_not_blamed_on_the_fmu(tmp_path, c_fmus, capsys, monkeypatch,
                                                                        var, value, said):
    """An environment variable read where FMUs are loaded: a bad value was reported in a worker
    process (`isolation: process`, and always in `validate`) as the FMU's failure, "FMU instance
    'bearing1': fmi2Instantiate returned exception: SettingError in the worker: ...", and a CC
    with an unclosed quote ended every run in "internal error: ValueError: No closing quotation"
    (in a worker: "... returned exception: ValueError in the worker"). Now both are the setting's
    error, in the master's process and in a worker alike."""
    from hostile_builders import cli
    from orchestrator.fmi import safe_log, subsystem
    monkeypatch.setenv(var, value)
    monkeypatch.setattr(safe_log, "_tried", False)     # this process reads the setting afresh
    monkeypatch.setattr(safe_log, "_lib", None)
    monkeypatch.setattr(subsystem, "_CALLBACKS", None)
    scenario = _bearing_scenario(c_fmus, tmp_path)
    for args in (("validate", scenario), ("run", scenario, "--out", tmp_path / "out", "--no-progress")):
        rc, text = cli(capsys, *args)
        assert rc != 0 and said in text, text[-2000:]
        assert "returned exception" not in text and "in the worker" not in text, text[-2000:]


@pytest.mark.parametrize("isolation", ["none", "process"])
def test_a_long_percent_s_argument_of_an_fmu_log_message_keeps_its_end(tmp_path, c_fmus, isolation):
    """The FMU log formatter (orchestrator/fmi/safe_logger.c) read a %s argument up to 1023 bytes:
    a message the FMU formatted itself and passed as "%s" (a common way to log) lost everything
    after that, so the log line, which keeps a long message's start and its end ("the end says
    where"), showed neither the end nor any sign of the cut; fmpy's proxy before it kept 2047
    bytes, and docs/limits.md promised the message's 4096. "%.2000s" printed 512 characters (the
    cap on widths and on the precisions of numbers, which a string's precision, only shortening
    it, does not need). MisbehavingBearing fault 16 logs "%s" with 3000 characters ending in END."""
    import ctypes
    import subprocess
    import sys
    from orchestrator.fmi import safe_log
    lib = safe_log.library()
    if lib is None:
        pytest.skip("no C compiler: the safe logger cannot be built here")
    arg = b"a" * 2996 + b"END"
    for fmt, want in ((b"long: %s", b"long: " + arg), (b"%.2000s|", arg[:2000] + b"|"),
                      (b"%5.3s|", b"  aaa|")):
        buf = ctypes.create_string_buffer(4096)
        lib.rotorcosim_format(buf, fmt, arg)
        assert buf.value == want, (fmt, len(buf.value))
    env = {**__import__("os").environ, "PYTHONPATH": str(HERE.parent)}
    done = subprocess.run([sys.executable, "-m", "orchestrator", "run",
                           str(_bearing_scenario(c_fmus, tmp_path, fault=16, isolation=isolation)),
                           "--out", str(tmp_path / "out"), "--no-progress"],
                          capture_output=True, text=True, cwd=tmp_path, env=env, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    long_line = next(line for line in done.stderr.splitlines() if "fault 16 long: " in line)
    assert long_line.endswith("aaaEND") and " ... " in long_line, long_line[-200:]
    assert "fault 16 star: [3.250000    ] [42    ] [whole]" in done.stderr
    assert "fault 16 missing: (null) " in done.stderr and " end" in done.stderr
