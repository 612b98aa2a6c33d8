"""FMUs in worker processes: :class:`WorkerSubsystem`, the proxy the master drives.

``fmus.<name>.isolation: process`` runs an FMU in a process of its own, so that a crash
in its binary (abort, segfault, ``_exit``) or a hang cannot take the master down, and
so that independent FMUs can step at the same time on several cores.

The worker loads the FMU with the ordinary in-process adapter
(:class:`orchestrator.fmi.subsystem.Subsystem`, fmpy underneath) and serves its calls. The proxy
implements the same :class:`~orchestrator.fmi.subsystem.SubsystemBase` interface, so the master
cannot tell the two apart. The channel:

* control: a Unix socket pair wrapped in :class:`multiprocessing.connection.Connection`,
  carrying lists of small command tuples (pickled by multiprocessing); one list per
  round trip;
* values: one shared memory arena per worker (a memfd mapped by both processes).
  Every :class:`~orchestrator.fmi.subsystem.RealBatch` gets a slot in it when first used; the
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

Crashes (:mod:`orchestrator.fmi.channel`): the proxy waits for a reply with ``Connection.poll(call_timeout)`` (seconds,
None = forever); the worker holds the only other end of the socket, so its death wakes
the wait too (end of file).
A dead worker becomes :class:`~orchestrator.errors.FmuCrashError` naming the instance,
FMU file, FMI function, simulation time and cause (the signal name for a negative exit
code, e.g. SIGSEGV; the exit code otherwise); a timeout kills the worker (SIGKILL) and
raises the same error with ``status='timeout'``. A KeyboardInterrupt while waiting
(the second Ctrl-C) kills the worker too. After that the proxy is dead: ``terminate``
does nothing and ``free`` only releases the arena.

Workers are process groups of their own and ignore SIGINT and SIGTERM (the master stops
them in order: a Ctrl-C that the terminal sends to the whole foreground process group, or a
SIGTERM to the run's group, must not kill them in the middle of a step, nor while they start);
they exit when the socket closes, and on Linux they are killed when the master dies
(``PR_SET_PDEATHSIG``). A worker is a fresh interpreter (``python -m
orchestrator.fmi.worker_main``, :mod:`subprocess`), not a multiprocessing child: forking the
master would copy its threads and in-process FMUs, and multiprocessing's spawn and
forkserver methods re-run the user's ``__main__`` script in every child, which a script
without an ``if __name__ == "__main__":`` guard does not survive. Start-up costs about
0.3 s of CPU per worker (importing numpy and fmpy); with ``wait=False`` the constructor
returns once the process is started and its instantiation sent, and :meth:`ready` (or the
first call) waits, so the master starts all its workers side by side. ``cpu`` keeps the
worker on one CPU (``coupling.pin_workers``, see :func:`orchestrator.fmi.channel._pin`).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from orchestrator.errors import CosimError, FmuCrashError, FmuError
from orchestrator.fmi.subsystem import RealBatch, SubsystemBase, md_variable
from orchestrator.fmi.archive import ModelDescription, Variable, read_model_description
from orchestrator.scenario.model import MAX_ORDER
from .channel import ARENA_BYTES, FREE_TIMEOUT, FUNCTIONS, REGISTER_BYTES, WorkerChannel, arena_bytes, signal_name

log = logging.getLogger(__name__)

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

    Same interface and call order as :class:`orchestrator.fmi.subsystem.Subsystem` (see its module
    docstring); ``call_timeout`` [s] bounds every round trip to the worker, instantiation
    included (None: wait as long as it takes). Raises what the in-process adapter raises
    (ScenarioError, FmuError, FmuCallError, rebuilt from the worker's answer) and
    :class:`~orchestrator.errors.FmuCrashError` when the worker dies or times out.
    """

    def __init__(self, name: str, fmu_path: Path | str, *, work_dir: Path | str, call_timeout: float | None = None,
                 wait: bool = True, cpu: int | None = None, spin: float | None = None):
        super().__init__(name)
        self.fmu_path = Path(fmu_path)
        self.md: ModelDescription = read_model_description(self.fmu_path)
        self.can_interpolate_inputs = self.md.can_interpolate_inputs
        self.can_get_set_state = self.md.can_get_and_set_fmu_state
        self.max_output_derivative_order = self.md.max_output_derivative_order
        self._queue: list[tuple] = []
        self._pending: list[_Slot] = []          # slots holding values the worker has not read yet
        self._slots: dict[int, tuple[RealBatch, _Slot]] = {}
        self._used = REGISTER_BYTES
        self._next_state = 0
        self._freed = False
        n_real = sum(1 for v in self.md.variables.values() if v.type == "Real")
        self._arena_bytes = arena_bytes(n_real, SLOTS, MAX_ORDER)     # room for every batch of this FMU
        self._chan = WorkerChannel(name, self.fmu_path, work_dir, call_timeout, cpu, spin,
                                   arena_bytes=self._arena_bytes)
        self._starting = True
        try:
            self._chan.send([("init",)], "fmi2Instantiate")
        except BaseException:
            self._shutdown()
            raise
        if wait:
            self.ready()

    def ready(self) -> None:
        """Wait until the worker is up and has instantiated the FMU (``wait=False`` returns from the
        constructor at once, so that several workers start side by side); raises what
        instantiation raised, after which the proxy is shut down."""
        if not self._starting:
            return
        self._starting = False
        try:
            self._chan.receive()
        except BaseException:
            self._shutdown()
            raise
        self.calls["instantiate"] += 1

    @property
    def crash(self) -> FmuCrashError | None:
        """The FmuCrashError once the worker is dead, else None."""
        return self._chan.crash

    @property
    def pid(self) -> int:
        return self._chan.pid

    # -- the channel: queued commands go with the next message ----------------------
    def _round_trip(self, msg: list, function: str) -> Any:
        if self._chan.outstanding is not None:
            self._receive()
        self._send(msg, function)
        return self._receive()

    def _send(self, msg: list, function: str) -> None:
        if self._queue:
            msg = self._queue + msg
            self._queue = []
        self._chan.send(msg, function)

    def _receive(self) -> Any:
        if self._starting:                  # the outstanding message is the instantiation
            self.ready()
            return None
        try:
            return self._chan.receive()
        finally:
            for slot in self._pending:           # the worker has read every value sent (or is dead)
                slot.pending = 0
            self._pending.clear()

    def _slot(self, batch: RealBatch) -> _Slot:
        entry = self._slots.get(id(batch))
        if entry is not None:
            return entry[1]
        nbytes = 8 * max(batch.n, 1)
        if self._used + SLOTS * nbytes > self._arena_bytes:
            raise FmuError(f"FMU instance '{self.name}': the value buffers exceed the worker's shared memory "
                           f"({self._arena_bytes} bytes, made for the Real variables its model description "
                           "declares); record fewer signals or run it with isolation: none")
        views = [np.ndarray((batch.n,), dtype=np.float64, buffer=self._chan.arena, offset=self._used + k * nbytes)
                 for k in range(SLOTS)]
        slot = _Slot(len(self._slots), views)
        orders = None if batch.orders is None else [int(o) for o in batch.orders]
        self._queue.append(("reg", slot.bid, self._used, nbytes, [int(v) for v in batch.vrs], orders))
        self._used += SLOTS * nbytes
        self._slots[id(batch)] = (batch, slot)     # the batch is kept alive: id() stays unique
        return slot

    # -- description ------------------------------------------------------------
    def variable(self, name: str) -> Variable:
        return md_variable(self.md, name, self.name, self.fmu_path)

    # -- life cycle ---------------------------------------------------------------
    def set_parameters(self, values: Mapping[str, Any], *, out_dir: Path | str | None = None) -> None:
        self._round_trip([("params", dict(values), None if out_dir is None else str(out_dir))],
                         "fmi2Set* (parameters)")

    def setup_experiment(self, start_time: float, stop_time: float | None) -> None:
        self._chan.time = float(start_time)
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
        if self._chan.outstanding is not None:
            self._receive()
        if self._chan.crash is not None:
            raise self._chan.crash
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
        if self._chan.outstanding is not None:
            self._receive()
        if self._chan.crash is not None:
            raise self._chan.crash
        self.calls["doStep"] += 1
        self._queue.append(("step", t, h, self.no_set_prior_state))
        self._chan.time = t + h

    # non-Real signals (Integer, Boolean, String): values travel pickled in the message (rare, small)
    def set_values(self, batch) -> None:
        if batch.n:
            if self._chan.outstanding is not None:
                self._receive()
            values = batch.strings() if batch.family == "String" else batch.values.tolist()
            self._queue.append(("setv", batch.family, list(batch.names), [int(v) for v in batch.c_vrs[:batch.n]],
                                values))

    def get_values(self, batch) -> None:
        if batch.n:
            values = self._round_trip([("getv", batch.family, list(batch.names),
                                        [int(v) for v in batch.c_vrs[:batch.n]])], f"fmi2Get{batch.family}")
            if batch.family == "String":
                batch.set_strings(values)
            else:
                batch.values[:] = values

    def terminated_by_fmu(self) -> bool:
        if self._chan.crash is not None:
            return False
        return bool(self._round_trip([("ended",)], "fmi2GetBooleanStatus"))

    def request_real(self, batch: RealBatch) -> None:
        """Send the queued calls and a get of ``batch`` without waiting (the worker starts now);
        :meth:`receive_real` waits for the values. Any other call in between waits first."""
        slot = self._slot(batch)
        self.calls["get"] += 1
        if self._chan.outstanding is not None:
            self._receive()
        self._send([slot.get_cmd], "fmi2GetReal")

    def receive_real(self, batch: RealBatch) -> np.ndarray:
        """The values asked for by :meth:`request_real` (raises what the calls sent with it raised)."""
        if self._chan.outstanding is not None:
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
        if self._starting:                          # never waited for: not worth waiting for now
            self._shutdown()
            return
        self._freed = True
        try:
            chan = self._chan
            if chan.outstanding is not None and chan.crash is None:
                try:
                    self._receive()                  # a reply nobody read: its failure no longer matters
                except CosimError as e:
                    log.debug("%s", e)
            if chan.alive():
                # bounded: free() runs on every exit path and must not hang on an FMU that does
                if chan.call_timeout is None or chan.call_timeout > FREE_TIMEOUT:
                    chan.call_timeout = FREE_TIMEOUT
                calls = self._round_trip([("free",)], "fmi2FreeInstance")
                if calls:                             # the worker's own count: exactly what reached the FMU
                    self.calls.clear()
                    self.calls.update(calls)
                chan.wait_exit(5.0)
        except CosimError as e:
            log.warning("%s", e)
        except Exception as e:   # pragma: no cover - defensive
            log.warning("%s: stopping the worker failed: %s", self.name, e)
        finally:
            self._shutdown()

    def _shutdown(self) -> None:
        self._freed = True
        self._slots.clear()                          # the numpy views into the arena go first
        self._pending.clear()
        self._chan.close()

    def __repr__(self) -> str:
        state = "dead" if self.crash else ("freed" if self._freed else "alive")
        return f"WorkerSubsystem({self.name!r}, {self.fmu_path.name!r}, pid={self.pid}, {state})"




__all__ = ["WorkerSubsystem", "FmuCrashError", "signal_name", "FUNCTIONS", "ARENA_BYTES", "SLOTS"]
