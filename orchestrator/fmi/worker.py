"""FMUs in worker processes: :class:`WorkerSubsystem`, the proxy, and :func:`_serve`, the worker.

``fmus.<name>.isolation: process`` runs an FMU in a process of its own, so that a crash
in its binary (abort, segfault, ``_exit``) or a hang cannot take the master down, and
so that independent FMUs can step at the same time on several cores.

The worker loads the FMU with the ordinary in-process adapter
(:class:`orchestrator.fmu.Subsystem`, fmpy underneath) and serves its calls. The proxy
implements the same :class:`~orchestrator.fmu.SubsystemBase` interface, so the master
cannot tell the two apart. The channel:

* control: a Unix socket pair wrapped in :class:`multiprocessing.connection.Connection`,
  carrying lists of small command tuples (pickled by multiprocessing); one list per
  round trip;
* values: one shared memory arena per worker (a memfd mapped by both processes).
  Every :class:`~orchestrator.fmu.RealBatch` gets a slot in it when first used; the
  worker's batch points its ctypes value buffer at that slot, so fmi2SetReal/GetReal in
  the worker read and write shared memory directly. ``set_real`` copies ``batch.values``
  into the slot (the caller may reuse its buffer at once, as in-process), ``get_real``
  copies the slot back;
* the arena's first 16 bytes are the worker's *call register*: the FMI function it is
  executing (a code, 0 when idle) and the simulation time of that call. After a crash
  the proxy reads it to name the function that crashed.

Round trips: ``set_real``, ``set_real_input_derivatives`` and ``do_step`` are queued
and travel with the next call that needs an answer (``get_real``, state calls,
``terminate`` ...), so a ``set/doStep/get`` cycle costs one round trip. Every FMI call
still runs in the worker in the order the master made it, and a failure is reported as
the function that failed (fmi2DoStep, fmi2SetReal), by the call that carried it. Each
queued set copies the values into the next of ``SLOTS`` buffers of its batch, so several
sets of one batch can wait in the queue (sub-steps).

Crashes: the proxy waits for a reply with ``Connection.poll(call_timeout)`` (seconds,
None = forever); the worker holds the only other end of the socket, so its death wakes
the wait too (end of file).
A dead worker becomes :class:`~orchestrator.errors.FmuCrashError` naming the instance,
FMU file, FMI function, simulation time and cause (the signal name for a negative exit
code, e.g. SIGSEGV; the exit code otherwise); a timeout kills the worker (SIGKILL) and
raises the same error with ``status='timeout'``. A KeyboardInterrupt while waiting
(the second Ctrl-C) kills the worker too. After that the proxy is dead: ``terminate``
does nothing and ``free`` only releases the arena.

Workers ignore SIGINT and SIGTERM (the master stops them in order: a Ctrl-C that the
terminal sends to the whole process group must not kill them in the middle of a step);
they exit when the socket closes, and on Linux they are killed when the master dies
(``PR_SET_PDEATHSIG``). A worker is a fresh interpreter (``python -m
orchestrator.fmi.worker``, :mod:`subprocess`), not a multiprocessing child: forking the
master would copy its threads and in-process FMUs, and multiprocessing's spawn and
forkserver methods re-run the user's ``__main__`` script in every child, which a script
without an ``if __name__ == "__main__":`` guard does not survive. Start-up costs about
0.3 s of CPU per worker (importing numpy and fmpy).
"""

from __future__ import annotations

import logging
import mmap
import os
import signal
import socket
import subprocess
import sys
import tempfile
import weakref
from multiprocessing import connection as mp_connection
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import CosimError, CouplingError, FmuCallError, FmuCrashError, FmuError, LifecycleError, ScenarioError
from ..fmu import RealBatch, SubsystemBase
from ..fmu_archive import ModelDescription, Variable, read_model_description

log = logging.getLogger(__name__)

ARENA_BYTES = 1 << 20            # value buffers of one worker: 131 056 doubles after the call register
_REGISTER = 16                    # call register: int64 function code, float64 simulation time
# command -> FMI function (for the call register and error messages)
FUNCTIONS = ("idle", "fmi2Instantiate", "fmi2Set* (parameters)", "fmi2SetupExperiment",
             "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2SetReal", "fmi2GetReal",
             "fmi2SetRealInputDerivatives", "fmi2DoStep", "fmi2GetFMUstate", "fmi2SetFMUstate",
             "fmi2FreeFMUstate", "fmi2Terminate", "fmi2FreeInstance", "register")
CODES = {"params": 2, "setup": 3, "enter": 4, "exit": 5, "set": 6, "get": 7, "der": 8, "step": 9,
         "gs": 10, "ss": 11, "fs": 12, "term": 13, "free": 14, "reg": 15}
_ERRORS = {c.__name__: c for c in (ScenarioError, FmuError, LifecycleError, CouplingError)}


def signal_name(exit_code: int | None) -> str | None:
    """'SIGSEGV' for exit code -11 (a process killed by a signal), else None."""
    if exit_code is None or exit_code >= 0:
        return None
    try:
        return signal.Signals(-exit_code).name
    except ValueError:
        return f"signal {-exit_code}"


def _arena() -> tuple[int, mmap.mmap]:
    """A shared memory block for the value buffers: (file descriptor, mapping).

    A memfd on Linux (no name, nothing to clean up, gone when both processes close it),
    else an unlinked temporary file. The worker inherits the descriptor and maps it too.
    """
    if hasattr(os, "memfd_create"):
        fd = os.memfd_create("rotorcosim-fmu-values", 0)     # not close-on-exec: the worker inherits it
    else:                                                   # pragma: no cover - non-Linux
        fd, path = tempfile.mkstemp(prefix="rotorcosim-fmu-values-")
        os.unlink(path)
    try:
        os.ftruncate(fd, ARENA_BYTES)
        return fd, mmap.mmap(fd, ARENA_BYTES)
    except BaseException:
        os.close(fd)
        raise


def _worker_env() -> dict:
    """The worker's environment: ours, with this package importable (also from a source checkout)."""
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


FREE_TIMEOUT = 30.0       # s: longest wait for fmi2FreeInstance (and what is queued before it) in free()
STARTUP_TIMEOUT = 300.0   # s: the worker's interpreter must be up by then (imports only, no FMU code)
SLOTS = 8      # value slots per batch: sets queued before a round trip use successive slots


class _Slot:
    """A RealBatch's place in the arena (proxy side): SLOTS buffers, used in turn by queued sets.

    Worker-side batch ids are ``bid * SLOTS + k``. ``pending`` counts the sets queued since
    the last round trip; when all slots hold unsent values the queue is sent first.
    """

    __slots__ = ("bid", "views", "k", "pending", "set_cmds", "der_cmds", "get_cmd")

    def __init__(self, bid: int, views: list):
        self.bid, self.views, self.k, self.pending = bid, views, 0, 0
        ids = [bid * SLOTS + k for k in range(SLOTS)]
        self.set_cmds = [("set", i) for i in ids]
        self.der_cmds = [("der", i) for i in ids]
        self.get_cmd = ("get", ids[0])


class WorkerSubsystem(SubsystemBase):
    """An FMI 2.0 co-simulation FMU instance served by a worker process.

    Same interface and call order as :class:`orchestrator.fmu.Subsystem` (see its module
    docstring); ``call_timeout`` [s] bounds every round trip to the worker, instantiation
    included (None: wait as long as it takes). Raises what the in-process adapter raises
    (ScenarioError, FmuError, FmuCallError, rebuilt from the worker's answer) and
    :class:`~orchestrator.errors.FmuCrashError` when the worker dies or times out.
    """

    def __init__(self, name: str, fmu_path: Path | str, *, work_dir: Path | str, call_timeout: float | None = None):
        super().__init__(name)
        self.fmu_path = Path(fmu_path)
        self.md: ModelDescription = read_model_description(self.fmu_path)
        self.can_interpolate_inputs = self.md.can_interpolate_inputs
        self.can_get_set_state = self.md.can_get_and_set_fmu_state
        self.max_output_derivative_order = self.md.max_output_derivative_order
        self.call_timeout = call_timeout
        self.time: float | None = None           # simulation time of the last call (for crash reports)
        self.crash: FmuCrashError | None = None  # set once the worker is dead
        self._queue: list[tuple] = []
        self._pending: list[_Slot] = []          # slots holding values the worker has not read yet
        self._outstanding: tuple | None = None   # (message, function) sent, reply not yet read
        self._slots: dict[int, tuple[RealBatch, _Slot]] = {}
        self._used = _REGISTER
        self._next_state = 0
        self._freed = False
        self._arena_fd, self._arena = _arena()
        self._register = np.ndarray((2,), dtype=np.float64, buffer=self._arena)
        self._code = np.ndarray((1,), dtype=np.int64, buffer=self._arena)
        mine, theirs = socket.socketpair()
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "orchestrator.fmi.worker_main", str(theirs.fileno()), str(self._arena_fd), name,
                 str(self.fmu_path), str(work_dir)],
                pass_fds=(theirs.fileno(), self._arena_fd), env=_worker_env(), stdin=subprocess.DEVNULL)
        except BaseException:
            mine.close()
            theirs.close()
            self._release()
            raise
        theirs.close()
        self._conn = mp_connection.Connection(mine.detach())
        # at interpreter exit, kill a worker nobody freed (it ignores SIGTERM)
        self._finalizer = weakref.finalize(self, _kill_process, self._proc)
        try:
            self._started()
            self._round_trip([("init",)], "fmi2Instantiate")
        except BaseException:
            self._shutdown()
            raise
        self.calls["instantiate"] += 1

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

    # -- the channel -----------------------------------------------------------
    def _round_trip(self, msg: list, function: str) -> Any:
        """Send ``msg`` (queued commands are sent first), wait for the reply, raise what it reports."""
        if self._outstanding is not None:
            self._receive()
        self._send(msg, function)
        return self._receive()

    def _send(self, msg: list, function: str) -> None:
        if self.crash is not None:
            raise self.crash
        if self._queue:
            msg = self._queue + msg
            self._queue = []
        self._outstanding = (msg, function)
        try:
            self._conn.send(msg)
        except (BrokenPipeError, ConnectionResetError, OSError):
            self._outstanding = None
            raise self._died(function) from None

    def _receive(self) -> Any:
        """Wait for the reply to the message sent last; raise what it reports."""
        msg, function = self._outstanding
        try:
            reply = self._wait(function)
        except (EOFError, ConnectionResetError, OSError):
            raise self._died(function) from None
        finally:
            self._outstanding = None
            for slot in self._pending:           # the worker has read every value sent (or is dead)
                slot.pending = 0
            self._pending.clear()
        if reply[0] == "ok":
            self._relog(reply[2])
            return reply[1]
        _, index, kind, payload, logs = reply
        self._relog(logs)
        raise self._rebuild(kind, payload, msg[index])

    def _wait(self, function: str):
        # the worker holds the only other end of the socket: its death makes the socket
        # readable (EOF), so one wait covers answer, crash and timeout
        try:
            if self._conn.poll(self.call_timeout):
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

    def _slot(self, batch: RealBatch) -> _Slot:
        entry = self._slots.get(id(batch))
        if entry is not None:
            return entry[1]
        nbytes = 8 * max(batch.n, 1)
        if self._used + SLOTS * nbytes > ARENA_BYTES:
            raise FmuError(f"FMU instance '{self.name}': the value buffers exceed the worker's shared memory "
                           f"({ARENA_BYTES} bytes); record fewer signals or run it with isolation: none")
        views = [np.ndarray((batch.n,), dtype=np.float64, buffer=self._arena, offset=self._used + k * nbytes)
                 for k in range(SLOTS)]
        slot = _Slot(len(self._slots), views)
        orders = None if batch.orders is None else [int(o) for o in batch.orders]
        self._queue.append(("reg", slot.bid, self._used, nbytes, [int(v) for v in batch.vrs], orders))
        self._used += SLOTS * nbytes
        self._slots[id(batch)] = (batch, slot)     # the batch is kept alive: id() stays unique
        return slot

    # -- description ------------------------------------------------------------
    def variable(self, name: str) -> Variable:
        try:
            return self.md.variables[name]
        except KeyError:
            raise ScenarioError(f"FMU instance '{self.name}' ({self.fmu_path.name}) has no variable '{name}'; "
                                f"valid names: {', '.join(self.md.variables)}") from None

    # -- life cycle ---------------------------------------------------------------
    def set_parameters(self, values: Mapping[str, Any], *, out_dir: Path | str | None = None) -> None:
        self._round_trip([("params", dict(values), None if out_dir is None else str(out_dir))],
                         "fmi2Set* (parameters)")

    def setup_experiment(self, start_time: float, stop_time: float | None) -> None:
        self.time = float(start_time)
        self.calls["setupExperiment"] += 1
        self._round_trip([("setup", float(start_time), stop_time)], "fmi2SetupExperiment")

    def enter_initialization_mode(self) -> None:
        self.calls["enterInitializationMode"] += 1
        self._round_trip([("enter",)], "fmi2EnterInitializationMode")

    def exit_initialization_mode(self) -> None:
        self.calls["exitInitializationMode"] += 1
        self._round_trip([("exit",)], "fmi2ExitInitializationMode")

    # -- hot path -----------------------------------------------------------------
    def _stage(self, batch: RealBatch, cmds: list, function: str) -> None:
        """Copy ``batch.values`` into the batch's next free slot and queue ``cmds[slot]``."""
        if self._outstanding is not None:
            self._receive()
        if self.crash is not None:
            raise self.crash
        slot = self._slot(batch)
        if slot.pending == SLOTS:
            self._round_trip([], function)           # every slot holds an unsent value: send them first
        k = slot.k
        np.copyto(slot.views[k], batch.values)
        self._queue.append(cmds[k] if cmds is not None else slot.set_cmds[k])
        slot.k = (k + 1) % SLOTS
        if not slot.pending:
            self._pending.append(slot)
        slot.pending += 1

    def set_real(self, batch: RealBatch) -> None:
        """Queued: the values are copied now and reach the FMU with the next round trip."""
        self._stage(batch, None, "fmi2SetReal")
        self.calls["set"] += 1

    def get_real(self, batch: RealBatch) -> np.ndarray:
        slot = self._slot(batch)
        self.calls["get"] += 1
        self._round_trip([slot.get_cmd], "fmi2GetReal")
        np.copyto(batch.values, slot.views[0])
        return batch.values

    def set_real_input_derivatives(self, batch: RealBatch) -> None:
        if not self.can_interpolate_inputs:
            super().set_real_input_derivatives(batch)
        slot = self._slot(batch)
        self._stage(batch, slot.der_cmds, "fmi2SetRealInputDerivatives")
        self.calls["setRealInputDerivatives"] += 1

    def do_step(self, t: float, h: float) -> None:
        """Queued like a set: the step runs when the next call that needs an answer (get_real,
        state calls, terminate ...) sends the queue, and a failure of the step is raised by
        that call, as an FmuCallError naming fmi2DoStep. :meth:`flush` sends and waits now."""
        if self._outstanding is not None:
            self._receive()
        if self.crash is not None:
            raise self.crash
        self.calls["doStep"] += 1
        self._queue.append(("step", t, h, self.no_set_prior_state))
        self.time = t + h

    def request_real(self, batch: RealBatch) -> None:
        """Send the queued calls and a get of ``batch`` without waiting (the worker starts now);
        :meth:`receive_real` waits for the values. Any other call in between waits first."""
        slot = self._slot(batch)
        self.calls["get"] += 1
        if self._outstanding is not None:
            self._receive()
        self._send([slot.get_cmd], "fmi2GetReal")

    def receive_real(self, batch: RealBatch) -> np.ndarray:
        """The values asked for by :meth:`request_real` (raises what the calls sent with it raised)."""
        if self._outstanding is not None:
            self._receive()
        np.copyto(batch.values, self._slot(batch).views[0])
        return batch.values

    def flush(self) -> None:
        """Send the queued calls and wait until the worker has executed them."""
        if self._queue:
            self._round_trip([], "fmi2DoStep" if self._queue[-1][0] == "step" else "fmi2SetReal")

    # -- state ------------------------------------------------------------------
    def get_state(self) -> int:
        if not self.can_get_set_state:
            super().get_state()
        sid = self._next_state
        self._next_state += 1
        self.calls["getFMUstate"] += 1
        self._round_trip([("gs", sid)], "fmi2GetFMUstate")
        return sid

    def set_state(self, state: int) -> None:
        if not self.can_get_set_state:
            super().set_state(state)
        self.calls["setFMUstate"] += 1
        self._round_trip([("ss", state)], "fmi2SetFMUstate")

    def free_state(self, state: int) -> None:
        if self.crash is not None:
            return                                    # the state died with the worker
        self.calls["freeFMUstate"] += 1
        self._round_trip([("fs", state)], "fmi2FreeFMUstate")

    # -- end --------------------------------------------------------------------
    def terminate(self) -> None:
        """fmi2Terminate in the worker (nothing if the worker is dead)."""
        if self.crash is None and not self._freed:
            self.calls["terminate"] += 1
            self._round_trip([("term",)], "fmi2Terminate")

    def free(self) -> None:
        """fmi2FreeInstance, stop the worker, release the arena; idempotent, never raises."""
        if self._freed:
            return
        self._freed = True
        try:
            if self._outstanding is not None and self.crash is None:
                try:
                    self._receive()                  # a reply nobody read: its failure no longer matters
                except CosimError as e:
                    log.debug("%s", e)
            if self.crash is None and self._proc.poll() is None:
                # bounded: free() runs on every exit path and must not hang on an FMU that does
                if self.call_timeout is None or self.call_timeout > FREE_TIMEOUT:
                    self.call_timeout = FREE_TIMEOUT
                calls = self._round_trip([("free",)], "fmi2FreeInstance")
                if calls:                             # the worker's own count: exactly what reached the FMU
                    self.calls.clear()
                    self.calls.update(calls)
                self._proc.wait(5.0)
        except CosimError as e:
            log.warning("%s", e)
        except Exception as e:   # pragma: no cover - defensive
            log.warning("%s: stopping the worker failed: %s", self.name, e)
        finally:
            self._shutdown()

    def _shutdown(self) -> None:
        self._freed = True
        self._kill()
        self._conn.close()
        self._release()
        self._finalizer.detach()

    def _release(self) -> None:
        self._slots.clear()
        self._register = self._code = None
        try:
            self._arena.close()
        except BufferError as e:   # pragma: no cover - defensive
            log.warning("%s: releasing the shared memory failed: %s", self.name, e)
        os.close(self._arena_fd)

    @property
    def pid(self) -> int | None:
        return self._proc.pid

    def __repr__(self) -> str:
        state = "dead" if self.crash else ("freed" if self._freed else "alive")
        return f"WorkerSubsystem({self.name!r}, {self.fmu_path.name!r}, pid={self.pid}, {state})"


def _kill_process(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.kill()
    try:
        proc.wait(5.0)
    except subprocess.TimeoutExpired:   # pragma: no cover - a process SIGKILL cannot stop
        log.warning("worker process %d did not exit after SIGKILL", proc.pid)


__all__ = ["WorkerSubsystem", "FmuCrashError", "signal_name", "FUNCTIONS", "ARENA_BYTES"]
