"""The FMU logger that formats an FMU's printf message without trusting it (orchestrator/fmi/safe_log.py).

Before it, fmpy's logger proxy handed the message to vsnprintf: a PythonFMU slave raising an
exception whose text held ``%s`` segfaulted ``rotorcosim run`` (exit 139, nothing said).
"""

from __future__ import annotations

import ctypes
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from orchestrator.fmi import safe_log

ROOT = Path(__file__).resolve().parents[1]

needs_library = pytest.mark.skipif(safe_log.library() is None,
                                   reason="no C compiler: the safe logger cannot be built here")


def _format(fmt: bytes, *args) -> bytes:
    buf = ctypes.create_string_buffer(4096)
    safe_log.library().rotorcosim_format(buf, fmt, *args)
    return buf.value


def _libc_format(fmt: bytes, *args) -> bytes:
    buf = ctypes.create_string_buffer(4096)
    ctypes.CDLL(None).snprintf(buf, 4096, fmt, *args)
    return buf.value


C = ctypes
WELL_FORMED = [
    (b"plain text, 100%% done",),
    (b"x=%d y=%5.2f s=%s", C.c_int(3), C.c_double(2.5), b"str"),
    (b"%-8s|%08.3e|%x|%X|%o|%lld|%zu|%c|%+i|% d", b"ab", C.c_double(12345.678), C.c_int(255), C.c_int(255),
     C.c_int(8), C.c_longlong(-5), C.c_size_t(7), C.c_int(65), C.c_int(4), C.c_int(5)),
    (b"%*d|%-*d|%.*f", C.c_int(5), C.c_int(1), C.c_int(4), C.c_int(2), C.c_int(3), C.c_double(3.14159)),
    (b"%.3s|%10.2s|%g %G %e %a", b"abcdef", b"xyz", C.c_double(1e-7), C.c_double(2e20), C.c_double(-0.5),
     C.c_double(1.0)),
    (b"%hhd %hd %lu %#x %#o", C.c_int(300), C.c_int(70000), C.c_ulong(2 ** 40), C.c_int(31), C.c_int(8)),
    (b"Variable reference %u of instance %s out of range [%d, %d]", C.c_uint(42), b"bearing1", C.c_int(0),
     C.c_int(17)),
    (b"%Ld %Lu %jd %td %Lg", C.c_longlong(-7), C.c_ulonglong(9), C.c_longlong(-8), C.c_ssize_t(-9),
     C.c_longdouble(0.25)),
]


@needs_library
@pytest.mark.parametrize("case", WELL_FORMED, ids=lambda c: c[0].decode()[:24])
def test_well_formed_messages_read_as_printf_prints_them(case):
    assert _format(*case) == _libc_format(*case)


@needs_library
def test_conversions_without_arguments_and_bad_pointers_do_not_crash():
    """Run in a child process: on a formatter that trusts the FMU this dies by SIGSEGV."""
    code = textwrap.dedent("""
        import ctypes
        from orchestrator.fmi import safe_log
        lib = safe_log.library()
        buf = ctypes.create_string_buffer(4096)
        target = ctypes.c_long(12345)
        cases = [b"%s" * 40 + b"%n" * 8 + b" end", b"%n", b"%s%s%s%s%s%s%s%s%s%s%s%s%s%s%s%s%s%s%s%s",
                 b"%999999999d|%.999999999f|", b"%1$s positional", b"trailing %", b"%q %ls %"]
        for fmt in cases:
            lib.rotorcosim_format(buf, fmt)
            print(repr(buf.value))
        lib.rotorcosim_format(buf, b"%s|%s|%n|%s", ctypes.c_void_p(16), None, ctypes.byref(target), b"ok")
        print(repr(buf.value), target.value)
        lib.rotorcosim_format(buf, ctypes.c_void_p(16))
        print(repr(buf.value))
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].endswith(" end'") and "%n" not in lines[0]
    assert len(lines[3]) < 2000             # widths and precisions capped at 512: no 1e9 characters
    assert lines[4] == "b'%1$s positional'"
    assert lines[5] == "b'trailing %'"
    assert lines[7] == "b'(unreadable)|(null)||ok' 12345"      # nothing written through %n
    assert lines[8] == "b'(unreadable message)'"


def _scenario(tmp_path: Path, fmu: Path, mode: int) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(f"""\
        name: percent
        version: 1
        start_time: 0
        stop_time: 0.5
        fmus:
          a: {{path: {fmu}, parameters: {{t_fail: 0.2, mode: {mode}}}}}
        coupling: {{macro_step: 0.01}}
        output: {{signals: [a.y]}}
        """))
    return path


@needs_library
def test_python_fmu_exception_with_printf_conversions_stops_the_run_with_its_message(tmp_path, test_fmus):
    """A PythonFMU slave whose exception text holds %s and %n (mode 6 of the Faulty test FMU):
    the run stops at the failure with the FMU's message and keeps its rows. Before: the process
    died by SIGSEGV in fmpy's logger proxy (exit -11), nothing said and no summary."""
    out = tmp_path / "out"
    env = dict(os.environ, ROTORCOSIM_CACHE=str(tmp_path / "cache"))        # the library built afresh
    done = subprocess.run([sys.executable, "-m", "orchestrator", "run", str(_scenario(tmp_path, test_fmus["Faulty"], 6)),
                           "--out", str(out), "--no-progress"], capture_output=True, text=True, cwd=ROOT,
                          env=env, timeout=300)
    assert done.returncode == 1, (done.returncode, done.stderr[-2000:])
    assert "Faulty FMU: 100" in done.stderr and "done, " in done.stderr
    assert "the run stopped at t = 0.2 s" in done.stderr
    assert (out / "summary.json").is_file()
    rows = (out / "results.csv").read_text().splitlines()
    assert rows[0] == "time,a.y" and float(rows[-1].split(",")[0]) == pytest.approx(0.2)
    assert list((tmp_path / "cache" / "native").glob("safe_logger-*.so"))


def test_library_file_others_may_write_is_not_loaded_but_built_anew(tmp_path, monkeypatch):
    if safe_log._compiler() is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("ROTORCOSIM_CACHE", str(tmp_path))
    monkeypatch.setattr(safe_log, "_tried", False)
    monkeypatch.setattr(safe_log, "_lib", None)
    path = safe_log.library_path(safe_log._compiler())
    path.parent.mkdir(parents=True)
    path.write_bytes(b"not a library")
    path.chmod(0o666)                           # group and others may write it: not trusted as code
    lib = safe_log.library()
    assert lib is not None
    assert not path.stat().st_mode & 0o022
    assert path.read_bytes() != b"not a library"


def test_fmpy_proxy_when_asked_or_without_a_compiler(monkeypatch):
    for key, value in (("ROTORCOSIM_SAFE_LOGGER", "0"), ("CC", "/nonexistent/cc")):
        monkeypatch.setattr(safe_log, "_tried", False)
        monkeypatch.setattr(safe_log, "_lib", None)
        monkeypatch.setenv(key, value)
        assert safe_log.library() is None
        monkeypatch.delenv(key)


def test_a_value_other_than_0_or_1_is_a_setting_error(monkeypatch):
    from orchestrator.untrusted import SettingError
    monkeypatch.setattr(safe_log, "_tried", False)
    monkeypatch.setattr(safe_log, "_lib", None)
    monkeypatch.setenv("ROTORCOSIM_SAFE_LOGGER", "yes")
    with pytest.raises(SettingError, match=r"ROTORCOSIM_SAFE_LOGGER must be 1 .* or 0 .*\(got 'yes'\)"):
        safe_log.library()


@needs_library
@pytest.mark.skipif(sys.platform != "linux", reason="the native test FMU is built for linux64")
@pytest.mark.parametrize("isolation", ["none", "process"])
def test_an_fmu_logging_from_its_own_thread_or_while_it_is_freed(tmp_path, isolation):
    """MisbehavingBearing fault 17 logs 200 warnings from a thread of its own while the master
    steps it, fault 18 logs in fmi2FreeInstance after freeing its instance: both are formatted,
    capped and counted as any message (probe 5 found no defect here; this keeps it so)."""
    import importlib.util
    import shutil
    if shutil.which("gcc") is None:
        pytest.skip("gcc not installed (native test FMU)")
    spec = importlib.util.spec_from_file_location("build_c_fmu", ROOT / "tests" / "fmus_c" / "build_c_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    fmu = mod.build_c_fmu(tmp_path, "MisbehavingBearing")
    for fault, said in ((17, "bearing1: 180 more log messages of the FMU were not shown (20 shown); the last: "
                              "[warning] fault 17: message 199 of 200 from a thread of the FMU"),
                        (18, "bearing1: [warning] fault 18: logged in fmi2FreeInstance after freeing its memory")):
        path = tmp_path / f"s{fault}.yaml"
        path.write_text(textwrap.dedent(f"""\
            name: threads
            stop_time: 0.01
            fmus:
              bearing1: {{path: {fmu}, parameters: {{fault: {fault}, fault_step: 2}}}}
            coupling: {{macro_step: 1.0e-3, isolation: {isolation}}}
            """))
        done = subprocess.run([sys.executable, "-m", "orchestrator", "run", str(path), "--out",
                               str(tmp_path / f"out{fault}"), "--no-progress"], capture_output=True, text=True,
                              cwd=ROOT, timeout=120)
        assert done.returncode == 0, done.stderr[-2000:]
        assert said in done.stderr, done.stderr[-2000:]


@needs_library
def test_a_percent_s_argument_with_colour_codes_is_text():
    """ANSI colour codes (ESC [ ... m) in a %s argument are text: shown (escaped by the log line),
    not replaced by "(not text)"; other control characters are what random memory holds."""
    assert _format(b"[%s]", b"\x1b[31mred\x1b[0m\ttab") == b"[\x1b[31mred\x1b[0m\ttab]"
    assert _format(b"[%s]", b"a\x01b") == b"[(not text)]"


def test_a_failed_build_is_not_tried_again_by_every_process(tmp_path, monkeypatch, caplog):
    """A compiler that cannot build the library (here: one that always fails) made every process
    and every worker of a sweep compile again and warn again. The first says why and leaves a
    marker; the next ones within RETRY_AFTER fall back to fmpy's proxy quietly."""
    fake = tmp_path / "bin" / "cc"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\necho 'fatal error: stdio.h: No such file or directory' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setenv("CC", str(fake))
    monkeypatch.setenv("ROTORCOSIM_CACHE", str(tmp_path / "cache"))
    for attempt in range(2):
        monkeypatch.setattr(safe_log, "_tried", False)
        monkeypatch.setattr(safe_log, "_lib", None)
        caplog.clear()
        with caplog.at_level("DEBUG", logger="orchestrator.fmi.safe_log"):
            assert safe_log.library() is None
        warned = [r for r in caplog.records if r.levelname == "WARNING"]
        if attempt == 0:
            assert len(warned) == 1 and "stdio.h" in warned[0].getMessage()
            assert list((tmp_path / "cache" / "native").glob("*.failed"))
        else:
            assert warned == [] and "failed to build less than" in caplog.text
