"""FMUs in worker processes, end to end: crash reports, run life cycle, identical results.

The misbehaving native FMU (tests/fmus_c, MisbehavingBearing: abort, segfault, _exit(3), hang,
NaN, fmi2Error at its 5th doStep) is coupled to a LinearBearing; macro step 1 ms, so the 5th
step runs from t = 4 ms to 5 ms and the rows at t = 0..4 ms must be in results.csv.
With ``isolation: process`` the run must stop cleanly with a failed summary naming the
instance, FMU file, FMI function, time and cause; without isolation a crash kills the
master (a subprocess here), and the folder must then hold a "running" summary of this
run, never the "finished" summary of an earlier one.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from tests.fmus_c.build_c_fmu import build_c_fmu

pytestmark = [pytest.mark.integration,
              pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")]

FAULTS = {"abort": 1, "segfault": 2, "exit": 3, "hang": 4, "nan": 5, "error": 6, "free": 7, "init": 8, "inithang": 15}


@pytest.fixture(scope="module")
def fmu_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("isolation_fmus")
    build_c_fmu(d, "LinearBearing")
    build_c_fmu(d, "MisbehavingBearing")
    return d


def _scenario(fmu_dir: Path, *, fault: str | None, isolation: str, stop=0.01, timeout=None, parallel=True,
              fault_step=5, name="misbehaving") -> Path:
    coupling = f"{{scheme: jacobi, macro_step: 1.0e-3, isolation: {isolation}, parallel: {str(parallel).lower()}"
    coupling += f", call_timeout: {timeout}}}" if timeout else "}"
    text = "\n".join([
        f"name: {name}",
        f"stop_time: {stop}",
        "fmus:",
        f"  bearing1: {{path: MisbehavingBearing.fmu, parameters: {{fault: {FAULTS.get(fault, 0)}, "
        f"fault_step: {fault_step}}}}}",
        "  bearing2: {path: LinearBearing.fmu}",
        "connections:",
        "  - {from: bearing1.Fx, to: bearing2.x, gain: 1.0e-9}",
        "  - {from: bearing2.Fx, to: bearing1.x, gain: 1.0e-9, offset: 1.0e-6}",
        f"coupling: {coupling}",
        "output: {interval: 1.0e-3, signals: [bearing1.Fx, bearing2.Fx]}",
        ""])
    path = fmu_dir / f"{name}_{fault}_{isolation}_{timeout}_{stop}.yaml"
    path.write_text(text)
    return path


def _rows(out: Path) -> list[list[str]]:
    with open(out / "results.csv", newline="") as f:
        return list(csv.reader(f))[1:]


def _summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def _worker_children() -> list[int]:
    """Live (not zombie) worker processes started by this process."""
    me, out = str(os.getpid()), []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            stat = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:
            continue
        if stat[1] == me and stat[0] != "Z" and b"orchestrator.fmi.worker" in cmd:
            out.append(int(pid))
    return out


@pytest.fixture
def tmp_root(tmp_path, monkeypatch) -> Path:
    """The run's temporary folder (tempfile.tempdir), to check that nothing is left there."""
    d = tmp_path / "tmp"
    d.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(d))
    return d


CAUSES = {"abort": "killed by signal SIGABRT", "segfault": "killed by signal SIGSEGV",
          "exit": "exited with code 3", "hang": "no answer within coupling.call_timeout = 1 s"}


@pytest.mark.parametrize("fault", ["abort", "segfault", "exit", "hang"])
def test_a_crashing_isolated_fmu_stops_the_run_cleanly(fmu_dir, tmp_path, tmp_root, fault):
    from orchestrator import load_scenario, run

    out = tmp_path / "out"
    sc = load_scenario(_scenario(fmu_dir, fault=fault, isolation="process", timeout=1 if fault == "hang" else None))
    res = run(sc, out_dir=out, progress=False)
    assert not res.success
    msg = res.message
    for part in ("'bearing1'", "MisbehavingBearing.fmu", "fmi2DoStep", "t=0.004 s", CAUSES[fault]):
        assert part in msg, (part, msg)
    s = _summary(out)
    assert s["status"] == "failed" and s["message"] == msg and s["end_time"] == pytest.approx(0.004)
    f = s["failure"]
    assert (f["instance"], Path(f["fmu"]).name, f["function"]) == ("bearing1", "MisbehavingBearing.fmu", "fmi2DoStep")
    assert f["time"] == pytest.approx(0.004)
    assert f["cause"] == {"abort": "SIGABRT", "segfault": "SIGSEGV", "exit": "exit code 3",
                          "hang": "timeout after 1 s"}[fault]
    assert [float(r[0]) for r in _rows(out)] == pytest.approx([0.0, 0.001, 0.002, 0.003, 0.004])
    assert _worker_children() == []                       # bearing2's worker was stopped too
    assert list(tmp_root.iterdir()) == []                 # no extraction folder left
    assert s["started_at"] and s["finished_at"]


@pytest.mark.parametrize("fault", ["nan", "error"])
def test_nan_and_fmi2error_of_an_isolated_fmu_fail_as_in_process(fmu_dir, tmp_path, tmp_root, fault):
    """... and as in a threaded stage (parallel: threads, both FMUs in the master)."""
    from orchestrator import load_scenario, run

    results = {}
    for isolation, parallel in (("none", True), ("process", True), ("none", "threads")):
        key = isolation if parallel is True else "threads"
        out = tmp_path / key
        res = run(load_scenario(_scenario(fmu_dir, fault=fault, isolation=isolation, parallel=parallel,
                                          name=f"misbehaving_{key}")), out_dir=out, progress=False)
        assert not res.success
        results[key] = (res.message, (out / "results.csv").read_bytes(), _summary(out))
    assert results["none"][0] == results["process"][0] == results["threads"][0]
    assert results["none"][1] == results["process"][1] == results["threads"][1]
    assert results["threads"][2]["threaded_stage_steps"] == 5     # the 5th failed, rows 0..4 ms kept
    assert results["process"][2]["status"] == "failed"
    assert "fmi2Error" in results["process"][0] if fault == "error" else "nan" in results["process"][0]
    assert len(_rows(tmp_path / "process")) == 5
    assert list(tmp_root.iterdir()) == [] and _worker_children() == []


_CHILD = """
import sys
from orchestrator import load_scenario, run
res = run(load_scenario(sys.argv[1]), out_dir=sys.argv[2], progress=False)
print(res.status.short)
"""


@pytest.mark.parametrize("fault", ["abort", "segfault", "exit"])
def test_without_isolation_a_crash_never_leaves_a_stale_finished_summary(fmu_dir, tmp_path, fault):
    out = tmp_path / "out"
    ok = subprocess.run([sys.executable, "-c", _CHILD, str(_scenario(fmu_dir, fault=None, isolation="none",
                                                                     name="earlier")), str(out)],
                        capture_output=True, text=True, timeout=300)
    assert ok.returncode == 0 and _summary(out)["status"] == "finished", ok.stderr
    r = subprocess.run([sys.executable, "-c", _CHILD, str(_scenario(fmu_dir, fault=fault, isolation="none")),
                        str(out)], capture_output=True, text=True, timeout=300)
    assert r.returncode == {"abort": -6, "segfault": -11, "exit": 3}[fault], r
    s = _summary(out)
    assert (s["status"], s["scenario"]) == ("running", "misbehaving")     # this run's, not the earlier one's
    assert _summary(out / "previous")["scenario"] == "earlier"
    # the folder is not locked by the dead run
    ok = subprocess.run([sys.executable, "-c", _CHILD, str(_scenario(fmu_dir, fault=None, isolation="none",
                                                                     name="again")), str(out)],
                        capture_output=True, text=True, timeout=300)
    assert ok.returncode == 0 and _summary(out)["scenario"] == "again", ok.stderr


@pytest.mark.parametrize("fault", ["abort", "segfault"])
def test_an_in_process_crash_keeps_the_first_rows_and_plot_says_the_run_ended(fmu_dir, tmp_path, fault):
    """An FMU in the master's process that crashes at its 5th step (t = 4 ms) took the rows of
    t = 0 .. 3 ms with it (they were still in the writer's buffer: results.csv had the header
    and at most the first row), and `plot` drew what was there without saying that the run had
    died. Now the first rows are written out one by one, and `plot` says the run ended without a
    final summary (its lock is free) and what to do."""
    import warnings
    from orchestrator.results.plots import plot_run
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-c", _CHILD, str(_scenario(fmu_dir, fault=fault, isolation="none")),
                        str(out)], capture_output=True, text=True, timeout=300)
    assert r.returncode == {"abort": -6, "segfault": -11}[fault], r
    rows = _rows(out)
    assert [float(row[0]) for row in rows] == pytest.approx([0.0, 1e-3, 2e-3, 3e-3, 4e-3]), rows
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert plot_run(out)
    said = [str(w.message) for w in caught if "ended without a final summary" in str(w.message)]
    assert len(said) == 1 and "isolation: process" in said[0], [str(w.message) for w in caught]
    # and where it died: the FMI call that never returned, from the run folder's call record
    assert "it died in an FMI call that never returned: 'bearing1' in fmi2DoStep at t=0.004 s" in said[0], said


def test_a_crash_while_freeing_after_a_complete_run_keeps_the_final_summary(fmu_dir, tmp_path):
    """An FMU that segfaults in fmi2FreeInstance (fault 7), in the master's process: the run was
    complete, and summary.json (written before the FMUs are freed) says so; it said "running"."""
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-c", _CHILD, str(_scenario(fmu_dir, fault="free", isolation="none")),
                        str(out)], capture_output=True, text=True, timeout=300)
    assert r.returncode == -11, r                         # the crash itself is not hidden
    s = _summary(out)
    assert s["status"] == "finished" and s["end_time"] == pytest.approx(0.01), s
    assert s["output"]["rows"] == 11 and len(_rows(out)) == 11 and s["finished_at"]


def _validate(scenario: Path) -> subprocess.CompletedProcess:
    """``rotorcosim validate`` in a child process (on a validate that loads the FMUs into its own
    process, a crashing FMU kills it: return code -11)."""
    return subprocess.run([sys.executable, "-m", "orchestrator", "validate", str(scenario)],
                          capture_output=True, text=True, timeout=300, cwd=scenario.parent)


def test_validate_reports_an_fmu_that_crashes_while_initializing(fmu_dir):
    """fault 8: SIGSEGV in fmi2ExitInitializationMode. validate loaded the FMUs into its own
    process and died with it (-11, no message); now each FMU is checked in a worker process."""
    r = _validate(_scenario(fmu_dir, fault="init", isolation="none"))
    assert r.returncode == 1, r
    assert ("FMU instance 'bearing1'" in r.stdout and "crashed in fmi2ExitInitializationMode" in r.stdout
            and "SIGSEGV" in r.stdout and "set fmus.bearing1.isolation: process" in r.stdout), r.stdout
    assert "1 problem found" in r.stderr, r.stderr
    # with isolation: process the run reports it itself: no hint to set it
    r = _validate(_scenario(fmu_dir, fault="init", isolation="process"))
    assert r.returncode == 1 and "crashed in fmi2ExitInitializationMode" in r.stdout, r
    assert "isolation: process to have it reported" not in r.stdout, r.stdout


def test_validate_warns_of_an_fmu_that_crashes_while_it_is_freed(fmu_dir):
    """fault 7: SIGSEGV in fmi2FreeInstance: the scenario is valid (a run keeps its record),
    and validate says so with a warning line instead of dying at its end."""
    r = _validate(_scenario(fmu_dir, fault="free", isolation="none"))
    assert r.returncode == 0, r
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("warning: ")]
    assert any("'bearing1'" in ln and "crashed in fmi2FreeInstance" in ln and "SIGSEGV" in ln
               and "exit code shows the crash" in ln for ln in lines), r.stdout
    assert ": valid (" in r.stdout and "Traceback" not in r.stdout + r.stderr, r


def test_validate_reports_an_fmu_that_hangs_while_initializing(fmu_dir, monkeypatch, capsys):
    """fault 15: fmi2ExitInitializationMode never returns. validate waited forever; now, without a
    coupling.call_timeout, it waits VALIDATE_CALL_TIMEOUT (600 s; 2 s here), kills the worker and
    says so, with what to set for `run`."""
    from orchestrator import preflight
    from orchestrator.cli import main
    monkeypatch.setattr(preflight, "VALIDATE_CALL_TIMEOUT", 2.0)
    rc = main(["validate", str(_scenario(fmu_dir, fault="inithang", isolation="none"))])
    out = capsys.readouterr().out
    assert rc == 1, out
    assert ("FMU instance 'bearing1'" in out and "did not answer in fmi2ExitInitializationMode" in out
            and "validate waits at most 2 s" in out and "set coupling.call_timeout and "
            "fmus.bearing1.isolation: process" in out), out
    assert _worker_children() == []


def test_validate_reports_an_fmu_library_that_crashes_when_loaded(fmu_dir, tmp_path):
    """A shared library whose constructor segfaults (dlopen never returns): reported as a crash
    in fmi2Instantiate naming the instance, not a dead validate."""
    import zipfile
    src = tmp_path / "ctor.c"
    src.write_text("__attribute__((constructor)) static void boom(void) { volatile int *p = 0; *p = 1; }\n"
                   "int fmi2GetVersion(void) { return 0; }\n")
    so = tmp_path / "LinearBearing.so"
    subprocess.run([shutil.which("gcc"), "-shared", "-fPIC", "-o", str(so), str(src)], check=True)
    with zipfile.ZipFile(fmu_dir / "LinearBearing.fmu") as zin, \
            zipfile.ZipFile(tmp_path / "LinearBearing.fmu", "w") as zout:
        for item in zin.infolist():
            data = so.read_bytes() if item.filename.endswith(".so") else zin.read(item)
            zout.writestr(item.filename, data)
    shutil.copy(fmu_dir / "MisbehavingBearing.fmu", tmp_path)
    sc = _scenario(fmu_dir, fault=None, isolation="none")
    target = tmp_path / sc.name
    target.write_text(sc.read_text())
    r = _validate(target)
    assert r.returncode == 1, r
    assert ("FMU instance 'bearing2'" in r.stdout and "crashed in fmi2Instantiate" in r.stdout
            and "SIGSEGV" in r.stdout and "set fmus.bearing2.isolation: process" in r.stdout), r.stdout


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_second_signal_stops_a_run_whose_fmu_hangs_in_the_masters_process(fmu_dir, tmp_path, sig):
    """An FMU hanging inside fmi2DoStep in the master's process (fault 4, isolation none): Python
    runs no signal handler while the main thread is in the C call, so two Ctrl-C or SIGTERM did
    nothing and only SIGKILL ended the run, summary.json at "running". The stop watchdog
    (coupling/lifecycle.py) stops it STOP_GRACE_S after the second signal, rows and summary kept."""
    out = tmp_path / "out"
    child = subprocess.Popen([sys.executable, "-c", _CHILD, str(_scenario(fmu_dir, fault="hang", isolation="none",
                                                                          fault_step=3)), str(out)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:             # rows of the first steps written: it hangs now
            if (out / "results.csv").is_file() and len(_rows(out)) >= 1:
                break
            time.sleep(0.2)
        time.sleep(1.0)
        assert child.poll() is None, child.communicate()
        child.send_signal(sig)
        time.sleep(0.5)
        child.send_signal(sig)
        _, err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()
    assert child.returncode == 128 + int(sig), err
    s = _summary(out)
    assert s["status"] == "failed" and s["stopped_by"] == signal.Signals(sig).name, s
    assert "stopped at once by a second" in s["message"] and "had not returned" in s["message"], s
    assert "isolation: process" in err
    assert len(_rows(out)) >= 1


def test_a_second_run_into_a_busy_folder_is_refused(fmu_dir, tmp_path):
    from orchestrator import load_scenario, run
    from orchestrator.errors import LifecycleError

    out = tmp_path / "out"
    first = subprocess.Popen([sys.executable, "-c", _CHILD, str(_scenario(fmu_dir, fault="hang", isolation="process",
                                                                          fault_step=2, name="first")), str(out)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        for _ in range(600):
            if (out / "summary.json").exists() and _summary(out).get("status") == "running":
                break
            time.sleep(0.1)
        with pytest.raises(LifecycleError) as info:
            run(load_scenario(_scenario(fmu_dir, fault=None, isolation="none", name="second")), out_dir=out,
                progress=False)
        assert "is in use by another run: scenario 'first'" in str(info.value)
        assert f"pid {first.pid}" in str(info.value)
        assert _summary(out)["scenario"] == "first"
    finally:
        first.kill()
        first.wait()


def test_sigterm_stops_like_ctrl_c(fmu_dir, tmp_path):
    """The first SIGTERM stops after the current macro step, a second one at once (here the
    FMU hangs at step 30, so only the second can stop it): rows kept, summary says why."""
    out, tmp = tmp_path / "out", tmp_path / "tmp"
    tmp.mkdir()
    for hang in (False, True):
        sc = _scenario(fmu_dir, fault="hang" if hang else None, isolation="process", fault_step=30, stop=100.0,
                       name=f"long{hang}")
        p = subprocess.Popen([sys.executable, "-m", "orchestrator", "run", str(sc), "--out", str(out),
                              "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env={**os.environ, "TMPDIR": str(tmp)})
        for _ in range(1200):        # this run's summary (the earlier run's files are moved aside first) and rows
            try:
                if _summary(out)["scenario"] == f"long{hang}" and len(_rows(out)) > 20:
                    break
            except (OSError, ValueError, KeyError):
                pass
            time.sleep(0.1)
        time.sleep(0.5)
        p.send_signal(signal.SIGTERM)
        if hang:
            time.sleep(1.0)
            p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=120)
        assert p.returncode == 143, (hang, err)          # the CLI's exit code for SIGTERM (128 + 15)
        assert "terminated by signal SIGTERM" in err
        s = _summary(out)
        assert s["status"] == "failed" and s["message"].startswith("terminated by signal SIGTERM at t="), s
        rows = _rows(out)
        assert float(rows[-1][0]) == pytest.approx(s["end_time"])
        if hang:
            assert s["end_time"] == pytest.approx(0.029)
        assert list(tmp.iterdir()) == []


def _jeffcott_yaml(fmu_dir: Path, scheme: str, isolation: dict, parallel: bool, k: int = 1, pin: bool = False) -> Path:
    conns = []
    for i in (1, 2):
        conns += [f"  - {{from: rotor.{v}_{i}, to: bearing{i}.{v}}}" for v in ("x", "y", "vx", "vy")]
        conns += [f"  - {{from: rotor.omega, to: bearing{i}.omega}}",
                  f"  - {{from: bearing{i}.Fx, to: rotor.Fx_{i}}}", f"  - {{from: bearing{i}.Fy, to: rotor.Fy_{i}}}"]
    iso = {n: (f", isolation: {isolation[n]}" if n in isolation else "") for n in ("rotor", "bearing1", "bearing2")}
    text = "\n".join([
        "name: jeffcott_isolation", "start_time: 0.25", "stop_time: 0.26", "fmus:",
        f"  rotor: {{path: JeffcottRotor.fmu, parameters: {{unbalance: 1.0e-4}}{iso['rotor']}}}",
        f"  bearing1: {{path: LinearBearing.fmu{iso['bearing1']}}}",
        f"  bearing2: {{path: LinearBearing.fmu{iso['bearing2']}}}",
        "connections:", *conns,
        f"coupling: {{scheme: {scheme}, macro_step: 2.0e-5, extrapolation_order: {k}, "
        f"parallel: {str(parallel).lower()}, pin_workers: {str(pin).lower()}}}",
        "output: {interval: 1.0e-4}", ""])
    path = fmu_dir / f"jeffcott_{scheme}_{'_'.join(f'{n}{v}' for n, v in isolation.items())}_{parallel}_k{k}_{pin}.yaml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def jeffcott_dir(fmu_dir) -> Path:
    from orchestrator.fmi.build import build_fmus

    build_fmus(fmu_dir, names=["JeffcottRotor"])
    return fmu_dir


@pytest.mark.parametrize("scheme, k", [("gauss-seidel", 1), ("jacobi", 1), ("jacobi", 2)])
def test_isolated_and_parallel_runs_are_byte_identical(jeffcott_dir, tmp_path, scheme, k):
    """k = 2: the start-up iteration, in which Jacobi's linked stage must step sequentially."""
    from orchestrator import load_scenario, run

    variants = {"in-process": ({}, False),
                "bearings in workers, parallel": ({"bearing1": "process", "bearing2": "process"}, True),
                "one bearing in a pinned worker, parallel": ({"bearing2": "process"}, True, True),
                "all in workers, sequential": ({"rotor": "process", "bearing1": "process", "bearing2": "process"},
                                               False),
                "all in workers, parallel": ({"rotor": "process", "bearing1": "process", "bearing2": "process"},
                                             True),
                "in-process, threads": ({}, "threads"),
                "one bearing in a worker, threads": ({"bearing2": "process"}, "threads")}
    got = {}
    for label, (iso, par, *pin) in variants.items():
        out = tmp_path / label.replace(" ", "_").replace(",", "")
        res = run(load_scenario(_jeffcott_yaml(jeffcott_dir, scheme, iso, par, k, pin=bool(pin))), out_dir=out,
                  progress=False)
        assert res.success, (label, res.message)
        got[label] = ((out / "results.csv").read_bytes(), res.stats["fmu_calls"])
    ref_csv, ref_calls = got["in-process"]
    assert len(ref_csv) > 10000
    for label, (data, calls) in got.items():
        assert data == ref_csv, label
        assert calls == ref_calls, label
    t = np.loadtxt(tmp_path / "in-process" / "results.csv", delimiter=",", skiprows=1)[:, 0]
    assert t[-1] == pytest.approx(0.26)


def test_an_fmu_instantiable_once_per_process_serves_isolated_instances(fmu_dir, tmp_path):
    """canBeInstantiatedOnlyOncePerProcess limits the master's process, not the workers'."""
    import zipfile

    from orchestrator import load_scenario, run
    from orchestrator.errors import ScenarioError

    once = tmp_path / "Once.fmu"
    with zipfile.ZipFile(fmu_dir / "LinearBearing.fmu") as src, zipfile.ZipFile(once, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'canBeInstantiatedOnlyOncePerProcess="false"',
                                    b'canBeInstantiatedOnlyOncePerProcess="true"')
                assert b'canBeInstantiatedOnlyOncePerProcess="true"' in data
            dst.writestr(item, data)

    def scenario(a: str, b: str, default: str = "none") -> Path:
        path = tmp_path / f"once_{a}_{b}_{default}.yaml"
        path.write_text("\n".join([
            "name: once", "stop_time: 0.005", "fmus:",
            f"  a: {{path: Once.fmu{a}}}", f"  b: {{path: Once.fmu{b}}}",
            "connections:", "  - {from: a.Fx, to: b.x, gain: 1.0e-9}", "  - {from: b.Fx, to: a.x, gain: 1.0e-9}",
            f"coupling: {{scheme: jacobi, macro_step: 1.0e-3, isolation: {default}}}", ""]))
        return path

    with pytest.raises(ScenarioError, match="all use it in the master's process; use it for one instance only, "
                                            "or give the others 'isolation: process'"):
        load_scenario(scenario("", ""))
    for sc in (scenario("", ", isolation: process"), scenario("", "", "process")):
        res = run(load_scenario(sc), out_dir=tmp_path / sc.stem, progress=False)
        assert res.success and len(res.t) == 6, res.message
