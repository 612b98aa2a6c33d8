"""FMUs in worker processes at the adapter level (orchestrator.fmi.worker.WorkerSubsystem).

The native test FMUs (tests/fmus_c, built with gcc at test time): LinearBearing, and
MisbehavingBearing, the same bearing that aborts, segfaults, calls _exit(3), hangs, outputs
NaN or returns fmi2Error at its 5th fmi2DoStep. The worker must give the same values and call
counts as the in-process adapter, and turn every death of the worker into an FmuCrashError
that names the instance, the FMU file, the FMI function, the simulation time and the cause.
"""

from __future__ import annotations

import os
import shutil
import signal
from pathlib import Path

import numpy as np
import pytest

from tests.fmus_c.build_c_fmu import build_c_fmu

from orchestrator.errors import FmuCallError, FmuCrashError, ScenarioError
from orchestrator.fmi.worker import WorkerSubsystem, signal_name
from orchestrator.fmi.subsystem import Subsystem

pytestmark = [pytest.mark.integration,
              pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")]

H = 1.0e-3


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("worker_fmus")
    build_c_fmu(d, "LinearBearing")
    build_c_fmu(d, "MisbehavingBearing")
    return d


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:      # a zombie is dead too
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except OSError:
        return False


def _drive(sub, n: int, params=None) -> np.ndarray:
    """Parameters, initialization, n set/doStep/get cycles, a state round trip; returns the outputs."""
    sub.set_parameters({"k": 2.0e6, "c": 300.0, **(params or {})})
    sub.setup_experiment(0.0, 1.0)
    sub.enter_initialization_mode()
    inb, outb = sub.real_batch(["x", "y", "vx", "vy"]), sub.real_batch(["Fx", "Fy"])
    inb.values[:] = [1e-6, 0.0, 0.0, 0.0]
    sub.set_real(inb)
    out = [sub.get_real(outb).copy()]
    sub.exit_initialization_mode()
    for i in range(n):
        inb.values[:] = [1e-5 * np.sin(i), -2e-5, 0.01 * i, 0.02]
        sub.set_real(inb)
        inb.values[:] = np.nan              # the adapter took the values at set_real
        sub.do_step(i * H, H)
        out.append(sub.get_real(outb).copy())
    if sub.can_get_set_state:
        s = sub.get_state()
        inb.values[:] = [5e-5, 0, 0, 0]
        sub.set_real(inb)
        moved = sub.get_real(outb).copy()
        sub.set_state(s)
        sub.free_state(s)
        out += [moved, sub.get_real(outb).copy()]
    sub.terminate()
    return np.array(out)


def test_worker_gives_the_in_process_values_and_call_counts(fmus, tmp_path):
    ref = Subsystem("b", fmus / "LinearBearing.fmu", work_dir=tmp_path / "a")
    try:
        expected = _drive(ref, 20)
    finally:
        ref.free()
    w = WorkerSubsystem("b", fmus / "LinearBearing.fmu", work_dir=tmp_path / "b")
    try:
        got = _drive(w, 20)
    finally:
        w.free()
    assert got.tobytes() == expected.tobytes()
    assert dict(w.statistics()) == dict(ref.statistics())
    assert got[-2][0] == pytest.approx(-2.0e6 * 5e-5)          # the state round trip really moved and came back
    assert got[-1].tobytes() == got[-3].tobytes()
    assert not _alive(w.pid)


@pytest.mark.parametrize("fault, cause, sig, code", [(1, "SIGABRT", "SIGABRT", -6), (2, "SIGSEGV", "SIGSEGV", -11),
                                                     (3, "exit code 3", None, 3)])
def test_a_dying_worker_is_reported_with_function_time_and_cause(fmus, tmp_path, fault, cause, sig, code):
    w = WorkerSubsystem("bearing1", fmus / "MisbehavingBearing.fmu", work_dir=tmp_path)
    try:
        with pytest.raises(FmuCrashError) as info:
            _drive(w, 10, {"fault": fault})
        e = info.value
        assert (e.instance, e.function, e.status, e.cause, e.signal, e.exit_code) == (
            "bearing1", "fmi2DoStep", "crashed", cause, sig, code)
        assert e.time == pytest.approx(4 * H)                  # the 5th doStep starts at t = 4 ms
        assert e.fmu == str(fmus / "MisbehavingBearing.fmu")
        msg = str(e)
        assert "bearing1" in msg and "MisbehavingBearing.fmu" in msg and "fmi2DoStep" in msg and "t=0.004 s" in msg
        assert (sig or "exited with code 3") in msg
        assert e.report()["cause"] == cause
        assert not _alive(w.pid)
        w.terminate()                                          # a dead worker: nothing to do, no error
        with pytest.raises(FmuCrashError):                     # and every further call says why
            w.do_step(1.0, H)
    finally:
        w.free()
    w.free()                                                   # idempotent


def test_a_hanging_fmu_is_killed_after_call_timeout(fmus, tmp_path):
    w = WorkerSubsystem("bearing1", fmus / "MisbehavingBearing.fmu", work_dir=tmp_path, call_timeout=0.5)
    try:
        with pytest.raises(FmuCrashError) as info:
            _drive(w, 10, {"fault": 4})
        e = info.value
        assert (e.status, e.function, e.timeout, e.signal) == ("timeout", "fmi2DoStep", 0.5, None)
        assert e.time == pytest.approx(4 * H)
        assert "coupling.call_timeout = 0.5 s" in str(e) and "did not answer" in str(e)
        assert not _alive(w.pid)
    finally:
        w.free()


def test_ctrl_c_while_an_fmu_hangs_kills_its_worker(fmus, tmp_path):
    """No call_timeout: an interrupt (here SIGALRM raising KeyboardInterrupt) ends the wait."""
    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGALRM, interrupt)
    w = WorkerSubsystem("bearing1", fmus / "MisbehavingBearing.fmu", work_dir=tmp_path)
    try:
        w.set_parameters({"fault": 4, "fault_step": 1})
        w.setup_experiment(0.0, 1.0)
        w.enter_initialization_mode()
        w.exit_initialization_mode()
        signal.setitimer(signal.ITIMER_REAL, 0.5)
        w.do_step(0.0, H)                   # queued
        with pytest.raises(KeyboardInterrupt):
            w.flush()                       # sent: the FMU hangs in it
        assert not _alive(w.pid)
        assert w.crash is not None and "interrupted" in w.crash.cause
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        w.free()


def test_nan_output_and_fmi2error_come_through_as_in_process(fmus, tmp_path):
    w = WorkerSubsystem("b", fmus / "MisbehavingBearing.fmu", work_dir=tmp_path / "nan")
    try:
        out = _drive(w, 6, {"fault": 5})
    finally:
        w.free()
    assert np.isfinite(out[:5]).all() and np.isnan(out[5:, 0]).all() and np.isfinite(out[:, 1]).all()

    errors = []
    for cls, d in ((Subsystem, "e1"), (WorkerSubsystem, "e2")):
        sub = cls("b", fmus / "MisbehavingBearing.fmu", work_dir=tmp_path / d)
        try:
            with pytest.raises(FmuCallError) as info:
                _drive(sub, 10, {"fault": 6})
            errors.append(info.value)
        finally:
            sub.free()
    local, remote = errors
    assert type(remote) is FmuCallError
    assert (remote.instance, remote.function, remote.status) == (local.instance, local.function, local.status) == (
        "b", "fmi2DoStep", "error")
    assert str(remote) == str(local) and "fault 6: fmi2Error on purpose" in str(remote)


def test_bad_parameters_raise_the_same_scenario_error(fmus, tmp_path):
    messages = []
    for cls, d in ((Subsystem, "a"), (WorkerSubsystem, "b")):
        sub = cls("b", fmus / "LinearBearing.fmu", work_dir=tmp_path / d)
        try:
            with pytest.raises(ScenarioError) as info:
                sub.set_parameters({"k": "stiff"})
            messages.append(info.value.problems)
            with pytest.raises(ScenarioError):
                sub.variable("nope")
        finally:
            sub.free()
    assert messages[0] == messages[1] and "parameter 'b.k' is of type Real" in messages[0][0]


def test_signal_names():
    assert signal_name(-11) == "SIGSEGV" and signal_name(-6) == "SIGABRT" and signal_name(-9) == "SIGKILL"
    assert signal_name(3) is None and signal_name(0) is None and signal_name(None) is None


def test_request_and_receive_let_workers_step_at_the_same_time(fmus, tmp_path):
    """request_real sends the queued set/doStep/get without waiting; receive_real collects.
    Two workers driven that way give exactly the values of one driven call by call."""
    subs = [WorkerSubsystem(n, fmus / "MisbehavingBearing.fmu", work_dir=tmp_path) for n in ("a", "b")]
    ref = Subsystem("r", fmus / "MisbehavingBearing.fmu", work_dir=tmp_path / "ref")
    try:
        batches = []
        for s, fault in zip([*subs, ref], (6, 0, 0)):
            s.set_parameters({"fault": fault, "fault_step": 19})
            s.setup_experiment(0.0, None)
            s.enter_initialization_mode()
            s.exit_initialization_mode()
            batches.append((s.real_batch(["x", "vx"]), s.real_batch(["Fx"])))
        got, expected = [], []
        for i in range(6):
            for s, (inb, _) in zip([*subs, ref], batches):
                for j in range(3):                      # three sub-steps: three values of one batch queued
                    inb.values[:] = [1e-6 * (i + j), 1e-3 * j]
                    s.set_real(inb)
                    s.do_step(i * H + j * H / 3, H / 3)
            for s, (_, outb) in zip(subs, batches):
                s.request_real(outb)                    # both workers compute now
            got.append([s.receive_real(outb)[0] for s, (_, outb) in zip(subs, batches)])
            expected.append(ref.get_real(batches[2][1])[0])
        assert np.array(got)[:, 0].tobytes() == np.array(expected).tobytes()
        assert np.array(got)[:, 1].tobytes() == np.array(expected).tobytes()
        # a failure of a queued doStep comes with the receive, naming fmi2DoStep (a's 19th step)
        a, (inb, outb) = subs[0], batches[0]
        a.set_real(inb)
        a.do_step(1.0, H)
        a.request_real(outb)
        with pytest.raises(FmuCallError) as info:
            a.receive_real(outb)
        assert (info.value.function, info.value.status) == ("fmi2DoStep", "error")
        # a call between request and receive waits for the reply first
        b, (inb, outb) = subs[1], batches[1]
        b.request_real(outb)
        b.set_real(inb)
        assert b.get_real(outb)[0] == pytest.approx(-1e6 * 1e-6 * 7 - 200 * 2e-3)
    finally:
        for s in [*subs, ref]:
            s.free()


def test_workers_started_without_waiting_come_up_side_by_side(fmus, tmp_path):
    """wait=False returns before the worker is up; ready() (or the first call) waits for it.
    A worker never waited for is stopped by free(); one that died before it was up is
    reported by ready() as a crash, and the proxy is shut down."""
    ref = Subsystem("r", fmus / "LinearBearing.fmu", work_dir=tmp_path / "ref")
    try:
        expected = _drive(ref, 5)
    finally:
        ref.free()
    a, b, c, d = (WorkerSubsystem(n, fmus / "LinearBearing.fmu", work_dir=tmp_path / n, wait=False)
                  for n in "abcd")
    os.kill(d.pid, signal.SIGKILL)                                # long before its interpreter is up
    try:
        assert all(_alive(s.pid) for s in (a, b, c))
        a.ready()
        assert _drive(a, 5).tobytes() == expected.tobytes()
        assert _drive(b, 5).tobytes() == expected.tobytes()     # no ready(): the first call waits
        assert a.statistics()["instantiate"] == b.statistics()["instantiate"] == 1
        c.free()                                                  # never waited for
        assert not _alive(c.pid)
        with pytest.raises(FmuCrashError) as info:
            d.ready()
        assert (info.value.cause, info.value.instance, info.value.function) == (
            "SIGKILL", "d", "starting the worker process")
        assert not _alive(d.pid)
        d.free()                                                  # idempotent after the crash
    finally:
        for s in (a, b, c, d):
            s.free()


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="CPU affinity is Linux-only")
def test_a_pinned_worker_stays_on_its_cpu(fmus, tmp_path):
    """coupling.pin_workers: the worker process runs on the CPU it was given, and only there."""
    cpu = max(os.sched_getaffinity(0))
    w = WorkerSubsystem("p", fmus / "LinearBearing.fmu", work_dir=tmp_path, cpu=cpu)
    try:
        assert os.sched_getaffinity(w.pid) == {cpu}
        assert np.isfinite(_drive(w, 3)).all()
    finally:
        w.free()


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="CPU affinity is Linux-only")
def test_a_pinned_worker_and_its_master_poll_before_blocking(fmus, tmp_path):
    """A pinned worker gets channel.SPIN_WAIT (its command line) and the master's channel polls as
    long; an unpinned one blocks at once (spin 0); both step the same."""
    from orchestrator.fmi import channel
    cpu = max(os.sched_getaffinity(0))
    pinned = WorkerSubsystem("p", fmus / "LinearBearing.fmu", work_dir=tmp_path / "p", cpu=cpu)
    plain = WorkerSubsystem("u", fmus / "LinearBearing.fmu", work_dir=tmp_path / "u")
    still = WorkerSubsystem("s", fmus / "LinearBearing.fmu", work_dir=tmp_path / "s", cpu=cpu, spin=0.0)
    try:
        assert pinned._chan.spin == channel.SPIN_WAIT > 0 and plain._chan.spin == 0.0 == still._chan.spin
        for w, spin in ((pinned, channel.SPIN_WAIT), (still, 0.0)):
            with open(f"/proc/{w.pid}/cmdline", "rb") as f:
                assert f.read().split(b"\0")[-2] == repr(spin).encode()
        ref = _drive(plain, 5)
        assert np.array_equal(_drive(pinned, 5), ref) and np.array_equal(_drive(still, 5), ref)
    finally:
        pinned.free()
        plain.free()
        still.free()


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="CPU affinity is Linux-only")
def test_pinned_workers_poll_only_when_a_cpu_is_left_for_the_master():
    """With as many isolated FMUs as CPUs the master shares a CPU with a worker: nobody polls."""
    from types import SimpleNamespace as NS
    from orchestrator.coupling.execution import MasterAlgorithm
    n = len(os.sched_getaffinity(0))

    def master(k, default="none"):
        fmus = [NS(isolation="process")] * k + [NS(isolation=None)] * 2
        return NS(scenario=NS(coupling=NS(isolation=default), fmus=fmus))
    assert MasterAlgorithm._cpu_left(master(n - 1)) and not MasterAlgorithm._cpu_left(master(n))
    assert not MasterAlgorithm._cpu_left(master(n - 1, default="process"))   # the two without their own key


def test_spin_poll_returns_when_readable_and_gives_up_after_its_time():
    import select
    import socket
    import time
    from orchestrator.fmi.channel import spin_poll
    a, b = socket.socketpair()
    try:
        p = select.poll()
        p.register(a.fileno(), select.POLLIN)
        t0 = time.perf_counter()
        assert not spin_poll(p, 0.01)
        assert time.perf_counter() - t0 >= 0.01
        b.send(b"x")
        assert spin_poll(p, 10.0)
    finally:
        a.close()
        b.close()


def test_an_arena_with_a_live_view_closes_without_a_traceback():
    """At a worker's exit a view into its shared memory that is still alive (an instance left
    unfreed after fmi2Fatal, an exception holding a batch's buffer) made mmap.close raise
    BufferError, printed as a bare traceback at the end of `rotorcosim validate`."""
    import ctypes
    import mmap

    from orchestrator.fmi.worker_main import _close_arena
    arena = mmap.mmap(-1, 4096)
    view = (ctypes.c_double * 4).from_buffer(arena)      # what a RealBatch holds
    with pytest.raises(BufferError):
        arena.close()                                     # what the worker called
    _close_arena(arena)                                   # no exception
    del view
    _close_arena(arena)                                   # and closes once nothing points into it
    assert arena.closed


# Loaded into the worker process (sitecustomize on its PYTHONPATH): its initialization fails,
# and the frames of that failing call are kept alive after it, as a cache of compile errors
# (numba keeps the exceptions of a failed typing), an FMU's leaked traceback or an exception
# cycle not yet collected keep them; the cyclic GC is off so that it cannot run between the
# failure and the exit. mmap.close reports a BufferError on stderr even when the caller hides it.
_FAILING_INIT_HOOK = '''
import gc, mmap, sys
gc.disable()

class _ReportingMmap(mmap.mmap):
    def close(self):
        try:
            super().close()
        except BufferError as e:
            sys.stderr.write(f"worker arena close: BufferError: {e}\\n")
            sys.stderr.flush()
            raise

mmap.mmap = _ReportingMmap
KEPT = []
from orchestrator.errors import FmuCallError
from orchestrator.fmi import subsystem

def _failing_get(self, batch):
    # as the bearing does: its model is made at the first fmi2GetReal in initialization mode,
    # and fails there (journal outside the clearance, a bad parameter)
    KEPT.append(sys._getframe())
    raise FmuCallError(self.name, "fmi2GetReal", "error", "initialization failed (test hook)")

subsystem.Subsystem.get_real = _failing_get
sys.stderr.write("failing-initialization hook loaded\\n")
'''


def test_a_failing_initialization_leaves_no_view_into_the_shared_memory(fmus, tmp_path, monkeypatch, capfd):
    """The worker's path of a failing initialization (walkthrough: a bare 'BufferError: cannot
    close exported pointers exist' from worker_main at the end of `validate`, after the bearing's
    initialization failed). The worker's numpy/ctypes views into its shared memory were locals
    of _execute (``reg``, the batches' buffers): any frame of the failing call kept alive after it
    kept them, and mmap.close raised. The worker now holds every view in one ArenaViews that
    releases them (and empties the batches) before the close, and drops the traceback of a
    failed command; the worker exits by itself, with nothing on stderr."""
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(_FAILING_INIT_HOOK)
    monkeypatch.setenv("PYTHONPATH", str(hook) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    w = WorkerSubsystem("bearing1", fmus / "LinearBearing.fmu", work_dir=tmp_path / "w")
    try:
        w.set_parameters({"k": 2.0e6, "c": 300.0})
        w.setup_experiment(0.0, 1.0)
        w.enter_initialization_mode()
        inb, outb = w.real_batch(["x", "y", "vx", "vy"]), w.real_batch(["Fx", "Fy"])
        inb.values[:] = [1e-6, 0.0, 0.0, 0.0]
        w.set_real(inb)
        with pytest.raises(FmuCallError, match="initialization failed"):
            w.get_real(outb)
    finally:
        w.free()
    code = w._chan._proc.returncode
    err = capfd.readouterr().err
    assert "failing-initialization hook loaded" in err           # the worker ran with the hook
    assert "BufferError" not in err and "Traceback" not in err, err
    assert code == 0, (code, err)                                 # it exited by itself
