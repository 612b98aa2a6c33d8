"""The run folder's life cycle (orchestrator.coupling.lifecycle.RunFolder), without FMUs.

Lock (also against a second process), earlier files moved aside, summary.json at start and
on failure, no writing through symbolic links, SIGTERM like Ctrl-C.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from orchestrator.coupling.lifecycle import LOCK_NAME, RunFolder, RunStopped
from orchestrator.results.safe_write import open_no_follow, write_text_no_follow
from orchestrator.errors import LifecycleError


def _sc(name="a"):
    return SimpleNamespace(name=name, source=Path(f"/scen/{name}.yaml"))


def _summary(d: Path) -> dict:
    return json.loads((d / "summary.json").read_text())


def test_summary_running_at_start_and_final_at_finish(tmp_path):
    with RunFolder(tmp_path, _sc()) as f:
        s = _summary(tmp_path)
        assert (s["status"], s["scenario"], s["scenario_file"], s["pid"]) == ("running", "a", "/scen/a.yaml",
                                                                             os.getpid())
        assert s["started_at"].endswith("+00:00")
        f.finish({"scenario": "a", "status": "finished", "message": "done"})
    s = _summary(tmp_path)
    assert s["status"] == "finished" and s["started_at"] and s["finished_at"] >= s["started_at"]


def test_an_earlier_run_is_moved_aside(tmp_path):
    (tmp_path / "results.csv").write_text("time,x\n0,1\n")
    (tmp_path / "summary.json").write_text(json.dumps({"scenario": "old", "status": "finished"}))
    (tmp_path / "notes.txt").write_text("mine")
    with RunFolder(tmp_path, _sc("new")):
        assert not (tmp_path / "results.csv").exists()
        assert _summary(tmp_path)["status"] == "running"
        assert json.loads((tmp_path / "previous" / "summary.json").read_text())["scenario"] == "old"
        assert (tmp_path / "previous" / "results.csv").read_text() == "time,x\n0,1\n"
    assert (tmp_path / "notes.txt").read_text() == "mine"         # only the run's own files move
    # the run never called finish(): leaving the block without an exception is a bug of the caller,
    # but an exception inside writes a failed summary (next test)


def test_an_earlier_runs_figures_and_fields_are_moved_aside_with_it(tmp_path):
    # found by running stationary_oil_bath and then quickstart into one folder: `rotorcosim plot`
    # drew the stationary run's bearing_fields.npz as "quickstart: bearing_fields", and plots/
    # kept the earlier run's figures beside the new results
    (tmp_path / "results.csv").write_text("time,x\n0,1\n")
    (tmp_path / "summary.json").write_text(json.dumps({"scenario": "old", "status": "finished"}))
    (tmp_path / "bearing_fields.npz").write_bytes(b"old fields")
    (tmp_path / "plots").mkdir()
    (tmp_path / "plots" / "signals_a.png").write_bytes(b"old figure")
    prev = tmp_path / "previous"
    prev.mkdir()
    (prev / "plots").mkdir()                                   # an even older run's, replaced
    (prev / "plots" / "stale.png").write_bytes(b"older")
    (prev / "other_fields.npz").write_bytes(b"older fields")
    with RunFolder(tmp_path, _sc("new")) as f:
        assert not (tmp_path / "plots").exists() and not list(tmp_path.glob("*_fields.npz"))
        assert (prev / "bearing_fields.npz").read_bytes() == b"old fields"
        assert sorted(p.name for p in (prev / "plots").iterdir()) == ["signals_a.png"]
        assert not (prev / "other_fields.npz").exists()
        f.finish({"status": "finished"})
    # a folder with no earlier run: figures that are not a run's are left alone
    other = tmp_path / "fresh"
    (other / "plots").mkdir(parents=True)
    with RunFolder(other, _sc()) as f:
        f.finish({"status": "finished"})
    assert (other / "plots").is_dir() and not (other / "previous").exists()


def test_a_failure_inside_writes_a_failed_summary_and_unlocks(tmp_path):
    with pytest.raises(ValueError):
        with RunFolder(tmp_path, _sc()):
            raise ValueError("bearing1: no such FMU file")
    s = _summary(tmp_path)
    assert s["status"] == "failed" and s["message"] == "setup failed: bearing1: no such FMU file"
    assert s["error"] == "ValueError" and s["finished_at"]
    with RunFolder(tmp_path, _sc()) as f:                       # the lock was released
        f.finish({"status": "finished"})


def test_a_second_run_into_a_locked_folder_is_refused(tmp_path):
    with RunFolder(tmp_path, _sc("first")) as f:
        with pytest.raises(LifecycleError) as info:
            RunFolder(tmp_path, _sc("second")).__enter__()
        msg = str(info.value)
        assert f"output folder {tmp_path} is in use by another run: scenario 'first'" in msg
        assert f"pid {os.getpid()}" in msg and "--out" in msg
        # another process is refused too (flock is per open file, across processes)
        code = ("import sys; from types import SimpleNamespace as N; from orchestrator.coupling.lifecycle import "
                "RunFolder\ntry:\n    RunFolder(sys.argv[1], N(name='p', source=None)).__enter__()\n"
                "except Exception as e:\n    print(e); sys.exit(3)")
        r = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=120)
        assert r.returncode == 3 and "in use by another run: scenario 'first'" in r.stdout, r
        assert _summary(tmp_path)["scenario"] == "first"        # the refused run wrote nothing
        f.finish({"status": "finished"})
    assert (tmp_path / LOCK_NAME).read_text() == ""


# a lock holder in another process: takes the lock, says so, then (after a pause) writes its details,
# or lets go, or never writes them; it holds the lock until its stdin closes
HOLDER = """
import fcntl, json, os, sys, time
fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT, 0o644)
fcntl.flock(fd, fcntl.LOCK_EX)
print("locked", flush=True)
time.sleep(float(sys.argv[3]))
if sys.argv[2] == "write":
    os.ftruncate(fd, 0)
    os.pwrite(fd, json.dumps({"scenario": "late", "scenario_file": None, "pid": os.getpid(),
                              "started_at": "2026-12-06T19:50:00+00:00"}).encode(), 0)
elif sys.argv[2] == "leave":
    sys.exit(0)
sys.stdin.read()
"""


def _holder(tmp_path: Path, what: str, pause: float) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", HOLDER, str(tmp_path / LOCK_NAME), what, str(pause)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "locked"
    return proc


@pytest.mark.parametrize("left_before", ["nothing", "details of a run that was killed"])
def test_a_refused_run_waits_for_the_details_the_holder_has_not_written_yet(tmp_path, left_before):
    """A run refused within microseconds of the holder's start read the lock file before the holder
    had written its details into it and said "another run (details unreadable)"; if a run killed
    hard had left its details there, it named that dead run instead. Now the refused run waits
    (at most lifecycle.HOLDER_WAIT_S) until the details are there and are not those of a process
    that has ended, and names the holder."""
    if left_before != "nothing":
        dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                              text=True, check=True)
        (tmp_path / LOCK_NAME).write_text(json.dumps({"scenario": "killed", "scenario_file": None,
                                                      "pid": int(dead.stdout), "started_at": "earlier"}))
    holder = _holder(tmp_path, "write", 0.15)           # writes its details 0.15 s after taking the lock
    try:
        with pytest.raises(LifecycleError) as info:
            RunFolder(tmp_path, _sc("second")).__enter__()
    finally:
        holder.communicate("", timeout=60)
    msg = str(info.value)
    assert f"output folder {tmp_path} is in use by another run: scenario 'late' (None), pid {holder.pid}, " \
           "started 2026-12-06T19:50:00+00:00 UTC; wait until it ends" in msg, msg
    assert "unreadable" not in msg and "killed" not in msg


def test_a_holder_that_never_says_who_it_is_is_named_after_a_bounded_wait(tmp_path, monkeypatch):
    import time

    from orchestrator.coupling import lifecycle
    monkeypatch.setattr(lifecycle, "HOLDER_WAIT_S", 0.3)
    holder = _holder(tmp_path, "silent", 0.0)
    try:
        t0 = time.monotonic()
        with pytest.raises(LifecycleError) as info:
            RunFolder(tmp_path, _sc("second")).__enter__()
        waited = time.monotonic() - t0
    finally:
        holder.communicate("", timeout=60)
    msg = str(info.value)
    assert 0.3 <= waited < 5, waited
    assert f"output folder {tmp_path} is in use by another process: it holds {tmp_path / LOCK_NAME} but had not " \
           "written which run it is after 0.3 s (a run writes its scenario, pid and start time there right after " \
           "it takes the lock and clears them as it ends, so it is starting or ending, or it is not a rotorcosim " \
           f"run; `fuser -v {tmp_path / LOCK_NAME}` names it); wait until it ends or stop it, or choose another " \
           "output folder (--out)" == msg


def test_a_holder_that_lets_go_while_the_run_waits_leaves_the_folder_to_it(tmp_path):
    holder = _holder(tmp_path, "leave", 0.1)            # a run ending: no details, then the lock freed
    try:
        with RunFolder(tmp_path, _sc("second")) as f:
            assert json.loads((tmp_path / LOCK_NAME).read_text())["scenario"] == "second"
            f.finish({"status": "finished"})
    finally:
        holder.communicate("", timeout=60)


def test_results_are_never_written_through_a_symlink(tmp_path):
    target = tmp_path / "precious.csv"
    target.write_text("keep me")
    out = tmp_path / "run"
    out.mkdir()
    (out / ".rotorcosim.lock").touch()     # a run folder (files no run wrote: tests/test_hostile_probe3.py)
    (out / "results.csv").symlink_to(target)
    with RunFolder(out, _sc()) as f:
        assert (out / "previous" / "results.csv").is_symlink()   # the link moved aside, not followed
        (out / "results.csv").symlink_to(target)                  # planted during the run
        with pytest.raises(LifecycleError, match="is a symbolic link; rotorcosim does not write results"):
            open_no_follow(out / "results.csv")
        (out / "summary.json.tmp").symlink_to(target)
        f.finish({"status": "finished"})
    assert target.read_text() == "keep me"
    assert _summary(out)["status"] == "finished" and not (out / "summary.json").is_symlink()
    (out / "summary.json").unlink()
    (out / "summary.json").symlink_to(target)
    write_text_no_follow(out / "summary.json", "{}")               # replaces the link, not the target
    assert target.read_text() == "keep me" and (out / "summary.json").read_text() == "{}"


def test_sigterm_stops_like_ctrl_c(tmp_path):
    master = SimpleNamespace(interrupt_requested=False)
    with RunFolder(tmp_path, _sc()) as f:
        with f.stop_signals(master):
            os.kill(os.getpid(), signal.SIGTERM)                  # first: stop after this macro step
            assert master.interrupt_requested and f.stop_signal == signal.SIGTERM
            assert f.stop_message(0.25) == "terminated by signal SIGTERM at t=0.25 s"
            with pytest.raises(RunStopped) as info:
                os.kill(os.getpid(), signal.SIGTERM)              # second: at once
            assert info.value.exit_code == 143
        f.finish({"status": "failed"})
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL or callable(signal.getsignal(signal.SIGTERM))


def test_sigterm_during_setup_writes_a_failed_summary(tmp_path):
    previous = signal.getsignal(signal.SIGTERM)
    with pytest.raises(RunStopped):
        with RunFolder(tmp_path, _sc()):
            os.kill(os.getpid(), signal.SIGTERM)
    s = _summary(tmp_path)
    assert s["status"] == "failed" and s["message"] == ("terminated by signal SIGTERM before the co-simulation "
                                                        "started")
    assert signal.getsignal(signal.SIGTERM) is previous


REPO = Path(__file__).resolve().parents[1]

_AFTER_A_RUN = """
import sys
from dataclasses import replace
from pathlib import Path
from orchestrator import load_scenario, run
assert "rotor_fmu" not in sys.modules, "rotor_fmu imported before the run: the check would not bite"
sc = load_scenario(Path(sys.argv[1]) / "scenarios" / "turbocharger_runup_half_sommerfeld.yaml")
res = run(replace(sc, stop_time=sc.start_time + 1e-3), out_dir=Path(sys.argv[2]), progress=False)
assert res.success, res.message
import rotor_fmu.floating_ring_growth                # a submodule the run did not import
from rotor_fmu.rotor_file import load_rotor_file     # and a data file of the package
load_rotor_file()
print("imports ok after the run")
from orchestrator.cli import exit_process
exit_process(0)     # as rotorcosim leaves: PythonFMU 0.7 can abort in the interpreter's teardown (cli.console_main)
"""


def test_the_process_imports_our_packages_after_a_run_removed_its_fmus(tmp_path):
    """A run imports rotor_fmu from the extracted rotor FMU when the process has not imported it
    yet; the run folder is removed at the end. Later imports of its submodules and data files
    in the same process must still work (they failed with "cannot read the file
    .../resources/rotor_fmu/data/turbocharger.yaml" before the pool forgot those modules)."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "-c", _AFTER_A_RUN, str(REPO), str(tmp_path / "run")],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "imports ok after the run" in proc.stdout


def test_folder_in_use_tells_a_live_run_from_a_dead_one(tmp_path):
    """The lock of a run folder: held by a live run (True), left by a run that is gone (False),
    none (None); plot uses it to say whether a "running" summary is a live or a dead run."""
    import fcntl
    import os
    from orchestrator.coupling.lifecycle import LOCK_NAME, folder_in_use
    assert folder_in_use(tmp_path) is None
    fd = os.open(tmp_path / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert folder_in_use(tmp_path) is True
        fcntl.flock(fd, fcntl.LOCK_UN)
        assert folder_in_use(tmp_path) is False
    finally:
        os.close(fd)
    (tmp_path / "sub").mkdir()
    os.symlink(tmp_path / LOCK_NAME, tmp_path / "sub" / LOCK_NAME)
    assert folder_in_use(tmp_path / "sub") is None          # a link is not followed


def test_the_call_record_tells_the_fmi_call_that_never_returned(tmp_path):
    """orchestrator/fmi/call_record.py: what a crashed run's folder says about where it died;
    a damaged or planted record file gives nothing, never an error."""
    import math
    from orchestrator.fmi.call_record import CODE, CallRecord, describe_calls, read_calls
    path = tmp_path / ".rotorcosim.calls"
    rec = CallRecord(path, ["rotor", "bearing1"], {"pid": 1})
    a, k = rec.slot("bearing1")
    a[k + 1], a[k] = 0.004, CODE["fmi2DoStep"]
    assert read_calls(path) == [("bearing1", "fmi2DoStep", 0.004)]
    assert describe_calls(read_calls(path)) == "'bearing1' in fmi2DoStep at t=0.004 s"
    a[k] = 0.0
    r, j = rec.slot("rotor")
    r[j + 1], r[j] = math.nan, CODE["fmi2Instantiate"]
    assert describe_calls(read_calls(path)) == "'rotor' in fmi2Instantiate"
    rec.remove()
    assert not path.exists() and read_calls(path) == []
    a[k] = CODE["fmi2DoStep"]                  # an adapter that still holds its slot: no SIGBUS
    for junk in (b"", b"\0" * 100, b'{"instances": ["x"], "calls_at": 99999999}', b'{"instances": 3}',
                 b'{"instances": ["x"], "calls_at": 4096}' + b"\0" * 5000, b"\xff" * 9000):
        path.write_bytes(junk)
        assert read_calls(path) == []
    path.unlink()
    path.symlink_to(tmp_path / "elsewhere")
    assert read_calls(path) == []
    with pytest.raises(OSError):               # never written through a planted link
        CallRecord(path, ["x"])
    assert not (tmp_path / "elsewhere").exists()
