"""The channel between the master and one FMU worker process (see :mod:`orchestrator.fmi.worker`).

:class:`WorkerChannel` starts the worker (``python -m orchestrator.fmi.worker_main``),
owns the socket, the shared memory (``arena``) and the process, sends command lists and
waits for their replies, and turns a dead or silent worker into
:class:`~orchestrator.errors.FmuCrashError`. One message may be outstanding at a time:
:meth:`send` then :meth:`receive` (or :meth:`round_trip` for both). The constructor does not
wait for the worker's interpreter: its greeting is read before the first reply, so the
master can start several workers and send their first messages before any is up.
"""

from __future__ import annotations

import builtins
import logging
import mmap
import os
import select
import signal
import socket
import subprocess
import sys
import tempfile
import time
import warnings
import weakref
from multiprocessing import connection as mp_connection
from pathlib import Path
from typing import Any

import numpy as np

from orchestrator.errors import CosimError, CouplingError, FmuCallError, FmuCrashError, FmuError, LifecycleError, ScenarioError
from orchestrator.untrusted import InputError, SettingError, env_number

log = logging.getLogger(__name__)

ARENA_BYTES = 1 << 20            # least shared memory of one worker: 131 056 doubles after the call register
REGISTER_BYTES = 16                    # call register: int64 function code, float64 simulation time
# log records of warnings raised in a worker (worker_main._warning_to_master): shown by the master as warnings
WARNING_LOGGER = "rotorcosim.worker_warning"
# command -> FMI function (for the call register and error messages)
FUNCTIONS = ("idle", "fmi2Instantiate", "fmi2Set* (parameters)", "fmi2SetupExperiment",
             "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2SetReal", "fmi2GetReal",
             "fmi2SetRealInputDerivatives", "fmi2DoStep", "fmi2GetFMUstate", "fmi2SetFMUstate",
             "fmi2FreeFMUstate", "fmi2Terminate", "fmi2FreeInstance", "register",
             "fmi2SetInteger/Boolean/String", "fmi2GetInteger/Boolean/String", "fmi2GetBooleanStatus")
CODES = {"params": 2, "setup": 3, "enter": 4, "exit": 5, "set": 6, "get": 7, "der": 8, "step": 9,
         "gs": 10, "ss": 11, "fs": 12, "term": 13, "free": 14, "reg": 15, "setv": 16, "getv": 17, "ended": 18}
# errors of the worker rebuilt as themselves in the master (any other is the FMU's: "exception");
# a SettingError (an environment variable the worker reads, e.g. ROTORCOSIM_SAFE_LOGGER or CC)
# was reported as "fmi2Instantiate returned exception: SettingError in the worker"
_ERRORS = {c.__name__: c for c in (ScenarioError, FmuError, LifecycleError, CouplingError, InputError, SettingError)}


def signal_name(exit_code: int | None) -> str | None:
    """'SIGSEGV' for exit code -11 (a process killed by a signal), else None."""
    if exit_code is None or exit_code >= 0:
        return None
    try:
        return signal.Signals(-exit_code).name
    except ValueError:
        return f"signal {-exit_code}"


def arena_bytes(n_real: int, slots: int, max_order: int) -> int:
    """Bytes of shared memory a worker needs for an FMU with ``n_real`` Real variables (names):
    a batch of inputs, one of their derivatives (``max_order`` each) and one of outputs and
    recorded signals, each at most that long, ``slots`` copies of each; at least
    :data:`ARENA_BYTES`, whole pages. The memory is taken as it is touched: what no batch
    uses costs nothing. (A fixed 1 MiB refused an FMU with more than about 16 000 recorded
    signals in a worker, and so ``validate``, which loads every FMU in one, refused scenarios
    that run.)"""
    need = REGISTER_BYTES + slots * 8 * ((2 + max_order) * max(int(n_real), 0) + 3)
    return max(ARENA_BYTES, -(-need // mmap.PAGESIZE) * mmap.PAGESIZE)


def _arena(size: int = ARENA_BYTES) -> tuple[int, mmap.mmap]:
    """A shared memory block of ``size`` bytes for the value buffers: (file descriptor, mapping).

    A memfd on Linux (no name, nothing to clean up, gone when both processes close it),
    else an unlinked temporary file. The worker inherits the descriptor and maps it too
    (as long as the file is).
    """
    if hasattr(os, "memfd_create"):
        fd = os.memfd_create("rotorcosim-fmu-values", 0)     # not close-on-exec: the worker inherits it
    else:                                                   # pragma: no cover - non-Linux
        fd, path = tempfile.mkstemp(prefix="rotorcosim-fmu-values-")
        os.unlink(path)
    try:
        os.ftruncate(fd, size)
        return fd, mmap.mmap(fd, size)
    except BaseException:
        os.close(fd)
        raise


def start_error(name: str, e: OSError, *, always: bool = False) -> str | None:
    """Why instance ``name``'s worker process could not be started, and what to do, for the limits
    of the master's process (too many open files or processes; with ``always`` any other OSError
    too, else None for those). These were a bare "error: Too many open files" (or "error:
    /dev/null: Too many open files")."""
    import errno
    import resource
    if e.errno in (errno.EMFILE, errno.ENFILE):
        try:
            now = f", now {resource.getrlimit(resource.RLIMIT_NOFILE)[0]}"
        except (OSError, ValueError):      # pragma: no cover
            now = ""
        fix = (f"each worker process needs a few file descriptors of the master: raise the limit of open files "
               f"(`ulimit -n`{now}), or give fewer instances isolation: process")
        if e.errno == errno.ENFILE:
            fix = "the whole system is out of file descriptors: close programs, or give fewer instances isolation: process"
    elif e.errno == errno.EAGAIN:
        fix = ("no more processes may be started (`ulimit -u`, or the system's limit): raise the limit, or give "
               "fewer instances isolation: process")
    elif e.errno == errno.ENOMEM:
        fix = "the machine is out of memory: free memory, or give fewer instances isolation: process"
    elif always:
        fix = "check the limits of this process (ulimit -a), or give the instance isolation: none"
    else:
        return None
    return (f"FMU instance '{name}': cannot start its worker process (isolation: process): "
            f"{e.strerror or e}; {fix}")


def arena_error(name: str, size: int, e: OSError) -> str:
    """Why the shared memory of instance ``name``'s worker could not be made, and what to do (it
    was a bare "error: File too large" under a file size limit, ``ulimit -f``, below its size)."""
    import errno
    fix = {errno.EFBIG: f"the file size limit of this process (`ulimit -f`) is below its {size} bytes: raise "
                        "that limit (ulimit -f unlimited)",
           errno.ENOMEM: "the machine is out of memory (or this process's memory limit, `ulimit -v`, is too "
                         "low): free memory or raise the limit",
           errno.ENOSPC: "the shared memory of this machine is used up: free it or raise its limit"}.get(
        e.errno, "check the memory limits of this process")
    return (f"FMU instance '{name}': cannot make the shared memory ({size} bytes) of its worker process "
            f"(isolation: process): {e.strerror or e}; {fix}, or give the instance isolation: none")


def _worker_env() -> dict:
    """The worker's environment: ours, with this package importable (also from a source checkout)."""
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


# A worker is a process group of its own: the terminal's Ctrl-C (SIGINT to the whole foreground
# group) and a SIGTERM to the run's group (`kill -- -PGID`, a batch system cancelling a job) reach
# the master only, which stops its workers in order. The worker ignores both signals once its
# imports are done (worker_main._worker_setup), but a Ctrl-C in its first 0.3 s (the imports)
# killed it with a KeyboardInterrupt traceback, and the run ended "FMU instance 'rotor' crashed
# in starting the worker process ... the FMU's binary failed" instead of "interrupted by the user"
_OWN_GROUP = {"process_group": 0} if os.name == "posix" else {}

SPIN_WAIT = env_number("ROTORCOSIM_WORKER_SPIN", 0.002, minimum=0.0, maximum=1.0,
                       meaning="seconds a pinned worker polls before it blocks; 0 = off")
"""s: how long a pinned channel and its worker poll before they block (WorkerChannel.spin);
``ROTORCOSIM_WORKER_SPIN=0`` switches polling off (for a/b measurements)."""
FREE_TIMEOUT = 30.0       # s: longest wait for fmi2FreeInstance (and what is queued before it) in free()
STARTUP_TIMEOUT = 300.0   # s: the worker's interpreter must be up by then (imports only, no FMU code)



class WorkerChannel:
    """Socket, shared memory and process of one worker serving FMU instance ``name``.

    ``time`` is set by the owner (the simulation time of its last call) for crash reports
    of calls the call register does not cover; ``crash`` is the FmuCrashError once the
    worker is dead (every later call raises it).

    ``spin`` (s; default :data:`SPIN_WAIT` for a pinned worker, else 0): how long a wait for a reply,
    and the worker's wait for its next message, poll the socket before they block. Why: a
    blocked process is woken by an interrupt to its idle CPU, which on a VM is a world switch
    of tens to hundreds of microseconds, twice per macro step and worker on the critical path
    of a parallel stage; the waits are short (the master's serial work between a reply and
    the next request, the difference of two film steps), and a pinned worker has its CPU to
    itself (``coupling.pin_workers`` says the CPUs are the run's), so polling costs nobody.
    Not when every CPU has a pinned worker: then the master shares a CPU with a worker, and
    polling on either side would take that CPU from the other (the master passes 0).
    """

    def __init__(self, name: str, fmu_path: Path, work_dir: Path | str, call_timeout: float | None,
                 cpu: int | None = None, spin: float | None = None, arena_bytes: int = ARENA_BYTES):
        self.name, self.fmu_path, self.call_timeout = name, fmu_path, call_timeout
        self.time: float | None = None
        self.crash: FmuCrashError | None = None
        self.outstanding: tuple | None = None    # (message, function) sent, reply not yet read
        self._closed = False
        self.spin = (SPIN_WAIT if cpu is not None else 0.0) if spin is None else float(spin)
        try:
            self._arena_fd, self.arena = _arena(arena_bytes)
        except OSError as e:
            raise CosimError(start_error(name, e) or arena_error(name, arena_bytes, e)) from None
        self._register = np.ndarray((2,), dtype=np.float64, buffer=self.arena)
        self._code = np.ndarray((1,), dtype=np.int64, buffer=self.arena)
        try:
            mine, theirs = socket.socketpair()
        except OSError as e:
            self._release()
            raise CosimError(start_error(name, e, always=True)) from None
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "orchestrator.fmi.worker_main", str(theirs.fileno()), str(self._arena_fd),
                 name, str(fmu_path), str(work_dir), repr(self.spin)],
                pass_fds=(theirs.fileno(), self._arena_fd), env=_worker_env(), stdin=subprocess.DEVNULL,
                **_OWN_GROUP)
        except BaseException as e:
            mine.close()
            theirs.close()
            self._release()
            if isinstance(e, OSError):
                raise CosimError(start_error(name, e, always=True)) from None
            raise
        theirs.close()
        if cpu is not None:
            _pin(self._proc.pid, cpu, name)
        self._conn = mp_connection.Connection(mine.detach())
        self._poller = select.poll()
        self._poller.register(self._conn.fileno(), select.POLLIN)
        # at interpreter exit, kill a worker nobody closed (it ignores SIGTERM)
        self._finalizer = weakref.finalize(self, _kill_process, self._proc)
        self.greeted = False       # its "hello" is read with the first reply: workers start side by side

    @property
    def pid(self) -> int:
        return self._proc.pid

    def alive(self) -> bool:
        return self.crash is None and self._proc.poll() is None

    def round_trip(self, msg: list, function: str) -> Any:
        """Send ``msg``, wait for the reply, raise what it reports (a reply outstanding is read first)."""
        if self.outstanding is not None:
            self.receive()
        self.send(msg, function)
        return self.receive()

    def send(self, msg: list, function: str) -> None:
        if self.crash is not None:
            raise self.crash
        self.outstanding = (msg, function)
        try:
            self._conn.send(msg)
        except (BrokenPipeError, ConnectionResetError, OSError):
            self.outstanding = None
            raise self._died(function) from None

    def receive(self) -> Any:
        """Wait for the reply to the message sent last; raise what it reports."""
        msg, function = self.outstanding
        if not self.greeted:
            try:
                self._started()
            except BaseException:
                self.outstanding = None
                raise
            self.greeted = True
        try:
            reply = self._wait(function)
        except (EOFError, ConnectionResetError, OSError):
            raise self._died(function) from None
        finally:
            self.outstanding = None
        if reply[0] == "ok":
            self._relog(reply[2])
            return reply[1]
        _, index, kind, payload, logs = reply
        self._relog(logs)
        raise self._rebuild(kind, payload, msg[index])

    def _started(self) -> None:
        """Wait for the worker's interpreter to come up (not bounded by call_timeout: that is Python
        starting and importing numpy and fmpy, which a loaded machine makes slow, not the FMU)."""
        timeout, self.call_timeout = self.call_timeout, STARTUP_TIMEOUT
        try:
            if self._wait("starting the worker process") != ("hello",):    # pragma: no cover - defensive
                raise FmuError(f"FMU instance '{self.name}': the worker process answered nonsense at start-up")
        except (EOFError, OSError):
            raise self._died("starting the worker process") from None
        finally:
            self.call_timeout = timeout

    def _wait(self, function: str):
        # the worker holds the only other end of the socket: its death makes the socket
        # readable (EOF), so one wait covers answer, crash and timeout
        try:
            # Connection.poll builds a selector per call (~10 us); one poll object and a plain
            # blocking recv when there is no timeout cost next to nothing
            if self.spin and spin_poll(self._poller, self.spin):
                return self._conn.recv()
            if self.call_timeout is None or self._poller.poll(self.call_timeout * 1000.0):
                return self._conn.recv()         # EOFError if the worker died
        except (EOFError, OSError):
            raise
        except BaseException:                    # KeyboardInterrupt (second Ctrl-C) etc.: the reply never comes
            self._kill()
            self.crash = self._crash_error(function, "interrupted while waiting for the worker (killed)")
            raise
        self._kill()
        limit = f"coupling.call_timeout = {self.call_timeout:g} s" if function != "starting the worker process" \
            else f"{self.call_timeout:g} s (start-up)"
        self.crash = self._crash_error(function, f"timeout after {self.call_timeout:g} s",
                                       timeout=self.call_timeout,
                                       detail=f"no answer within {limit}; the worker process was killed (SIGKILL). "
                                              "The FMU hangs or is much slower than expected; raise "
                                              "coupling.call_timeout if it is only slow")
        raise self.crash

    def _died(self, function: str) -> FmuCrashError:
        try:
            code = self._proc.wait(5.0)
        except subprocess.TimeoutExpired:
            code = None
        sig = signal_name(code)
        if sig:
            cause, detail = sig, f"its worker process was killed by signal {sig} (exit code {code})"
        elif code is None:
            self._kill()
            cause, detail = "lost connection", "the connection to its worker process broke (worker killed)"
        else:
            cause, detail = f"exit code {code}", f"its worker process exited with code {code}"
        self.crash = self._crash_error(function, cause, signal=sig, exit_code=code, detail=detail + (
            "; the FMU's binary failed: check its log above, its inputs at this time and its parameters"))
        return self.crash

    def _crash_error(self, function: str, cause: str, **kw) -> FmuCrashError:
        code = int(self._code[0])
        if 0 < code < len(FUNCTIONS) and code != CODES["reg"]:
            function = FUNCTIONS[code]                  # what the worker was executing when it stopped
            t = float(self._register[1])
        else:
            t = self.time
        if function == "fmi2Instantiate":
            t = None
        return FmuCrashError(self.name, function, fmu=str(self.fmu_path), time=t, cause=cause, **kw)

    def _kill(self) -> None:
        _kill_process(self._proc)

    @staticmethod
    def _relog(records) -> None:
        for name, level, text in records:
            head, _, category = name.rpartition(".")
            if head == WARNING_LOGGER:                 # a warning in the worker (worker_main._warning_to_master)
                kind = getattr(builtins, category, None)
                from orchestrator.fmi import fmu_logging
                with fmu_logging.unattributed():       # attributed to its instance (and capped) in the worker
                    warnings.warn(text, kind if isinstance(kind, type) and issubclass(kind, Warning) else UserWarning,
                                  stacklevel=2)
            else:
                logging.getLogger(name).log(level, "%s", text)

    def _rebuild(self, kind: str, payload, cmd: tuple) -> CosimError:
        function = FUNCTIONS[CODES.get(cmd[0], 0)] if cmd[0] != "init" else "fmi2Instantiate"
        if kind == "FmuCallError":
            return FmuCallError(*payload)
        if kind == "ScenarioError":
            return ScenarioError(payload)
        if kind in _ERRORS:
            return _ERRORS[kind](payload)
        return FmuCallError(self.name, function, "exception", f"{kind} in the worker: {payload}")

    def close(self) -> None:
        """Kill the worker if it still runs, close the socket, release the shared memory."""
        if self._closed:
            return
        self._closed = True
        self._kill()
        self._conn.close()
        self._release()
        self._finalizer.detach()

    def wait_exit(self, timeout: float) -> None:
        try:
            self._proc.wait(timeout)
        except subprocess.TimeoutExpired:
            pass

    def _release(self) -> None:
        self._register = self._code = None
        try:
            self.arena.close()
        except BufferError as e:   # pragma: no cover - defensive
            log.warning("%s: releasing the shared memory failed: %s", self.name, e)
        os.close(self._arena_fd)


def spin_poll(poller, seconds: float) -> bool:
    """Poll ``poller`` (a select.poll) without blocking for up to ``seconds``; True when readable."""
    end = time.perf_counter() + seconds
    while True:
        if poller.poll(0):
            return True
        if time.perf_counter() >= end:
            return False


def _pin(pid: int, cpu: int, name: str) -> None:
    """Keep worker ``pid`` on ``cpu`` (``coupling.pin_workers``). Why: a write to a socket wakes the
    reader "synchronously" (the kernel assumes the writer will sleep next) and the scheduler
    then tends to put the woken worker on the master's CPU, beside the master or the other
    worker, while another CPU idles until the load balancer moves it (measured on the 2-core
    run-up: one worker beside a master that steps the other bearing took 12.4-12.8 ms per
    macro step, pinned 7.5-7.8 ms; BENCHMARKS.md)."""
    try:
        os.sched_setaffinity(pid, {cpu})
    except (AttributeError, OSError) as e:   # pragma: no cover - not Linux, or the CPU is not ours
        log.warning("FMU instance '%s': cannot keep its worker process on CPU %d (%s); it runs unpinned",
                    name, cpu, e)


def _kill_process(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.kill()
    try:
        proc.wait(5.0)
    except subprocess.TimeoutExpired:   # pragma: no cover - a process SIGKILL cannot stop
        log.warning("worker process %d did not exit after SIGKILL", proc.pid)
