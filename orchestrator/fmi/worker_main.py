"""The worker side of :mod:`orchestrator.fmi.worker`: ``python -m orchestrator.fmi.worker_main``.

Started by :class:`~orchestrator.fmi.worker.WorkerSubsystem` with the socket and the
shared-memory descriptors it inherits; loads the FMU with the in-process adapter
(:class:`orchestrator.fmi.subsystem.Subsystem`) and executes the command lists it receives until
``free`` or the end of the socket. Replies: ``("ok", result, log records)`` or
``("err", index of the failed command, kind, payload, log records)``; the call register
at the start of the shared memory holds the FMI function being executed and its time.
"""

from __future__ import annotations

import ctypes
import logging
import mmap
import os
import select
import signal
import sys
import traceback
import warnings
from multiprocessing import connection as mp_connection
from typing import Any

import numpy as np

from orchestrator.errors import FmuCallError, ScenarioError
from orchestrator.fmi.subsystem import RealBatch
from .channel import CODES, WARNING_LOGGER, spin_poll
from .worker import SLOTS

class ArenaViews:
    """Every view of the worker into its shared memory: the call register (``reg``: the FMI
    function's time; ``code``: the command being executed) and the Real batches whose ctypes
    buffers lie in the arena (``batches``: {slot id: RealBatch}).

    They live here, not in the locals of ``_serve`` / ``_execute``, so that :meth:`release` drops
    them all before the arena is closed, whatever still references a frame or a batch: a ctypes
    ``from_buffer`` array pins the mmap (``mmap.close`` raises ``BufferError: cannot close exported
    pointers exist``), and a frame of a failed FMU call can outlive the call (its exception's
    traceback, a cache of compile errors such as numba's, an exception cycle the GC has not
    collected yet), with the batch it was given as a local. Release empties every batch
    (``c_values`` and ``values`` become None), so a batch kept by such a frame no longer pins it.
    """

    def __init__(self, arena: mmap.mmap):
        self.arena = arena
        self.reg = np.ndarray((2,), dtype=np.float64, buffer=arena)
        self.code = np.ndarray((1,), dtype=np.int64, buffer=arena)
        self.batches: dict[int, RealBatch] = {}

    def register(self, bid: int, offset: int, nbytes: int, vrs, orders) -> None:
        """The SLOTS batches of batch ``bid``, their buffers at ``offset + k * nbytes`` in the arena."""
        for k in range(SLOTS):
            b = RealBatch([str(v) for v in vrs], vrs, orders)
            b.c_values = (ctypes.c_double * max(b.n, 1)).from_buffer(self.arena, offset + k * nbytes)
            b.values = np.ctypeslib.as_array(b.c_values)[: b.n]
            self.batches[bid * SLOTS + k] = b

    def drop_batches(self) -> None:
        """Empty and forget the batches (see the class doc); the call register stays."""
        for b in self.batches.values():
            b.c_values = b.values = None
        self.batches.clear()

    def release(self) -> None:
        """Drop every view, the call register too (before the arena is closed). Idempotent."""
        self.drop_batches()
        self.reg = self.code = None


def _drop_traceback(e: BaseException) -> None:
    """Clear the frames of ``e``'s traceback (and of its causes and contexts) once it has been
    reported: their locals (the batch a failed get/set was given) go now, not whenever the last
    reference to the traceback goes."""
    seen = set()
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        traceback.clear_frames(e.__traceback__)
        e.__traceback__ = None
        e = e.__cause__ or e.__context__


class _Collect(logging.Handler):
    """Log records of the worker at WARNING and above, sent to the master with each reply."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.records: list = []

    def emit(self, record):
        self.records.append((record.name, record.levelno, record.getMessage()))

    def take(self) -> list:
        out, self.records = self.records, []
        return out


def _encode(e: BaseException) -> tuple[str, Any]:
    """(kind, payload) of an exception, for :meth:`WorkerSubsystem._rebuild` in the master."""
    if isinstance(e, FmuCallError):
        head = f"FMU instance '{e.instance}': {e.function} returned {e.status}"
        text = str(e)
        detail = text[len(head) + 2:] if text.startswith(head + ": ") else ""
        return "FmuCallError", (e.instance, e.function, e.status, detail)
    if isinstance(e, ScenarioError):
        return "ScenarioError", e.problems
    return type(e).__name__, str(e)


def _worker_setup() -> _Collect:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)   # PR_SET_PDEATHSIG
        except (OSError, AttributeError):   # pragma: no cover
            pass
    handler = _Collect()
    root = logging.getLogger()
    root.addHandler(handler)
    root.setLevel(logging.WARNING)
    warnings.showwarning = _warning_to_master
    return handler


def _warning_to_master(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning raised in the worker (an FMU's own, e.g. BearingParams' note on an oil bath without
    a groove) goes to the master with its text and category only; it was printed on the worker's
    stderr with the worker's temporary path and the source line that raised it. The master shows it
    as its own warnings (:meth:`WorkerChannel._relog`)."""
    # a LogRecord made here, not by the record factory: fmu_logging's showwarning has already put the
    # instance's name in front of the text (and counted it toward its cap); the factory would again
    logger = logging.getLogger(f"{WARNING_LOGGER}.{category.__name__}")
    logger.handle(logging.LogRecord(logger.name, logging.WARNING, filename, lineno, "%s", (str(message),), None))


def _serve(conn_fd: int, arena_fd: int, name: str, fmu_path: str, work_dir: str, spin: float = 0.0) -> None:
    """Worker main: load the FMU, then execute command lists until 'free' or the socket closes;
    ``spin`` > 0: poll that long for the next message before blocking (WorkerChannel.spin)."""
    from orchestrator.fmi.subsystem import Subsystem

    import fmpy.fmi2  # noqa: F401  (imported before "hello": the start-up is not the FMU's time)

    logs = _worker_setup()
    conn = mp_connection.Connection(conn_fd)
    conn.send(("hello",))
    arena = mmap.mmap(arena_fd, os.fstat(arena_fd).st_size)     # as large as the master made it
    os.close(arena_fd)
    views = ArenaViews(arena)
    sub = None
    states: dict[int, Any] = {}
    try:
        msg = conn.recv()                         # [("init",)]
        views.code[0] = 1
        try:
            sub = Subsystem(name, fmu_path, work_dir=work_dir)
        except Exception as e:
            conn.send(("err", 0, *_encode(e), logs.take()))
            _drop_traceback(e)
            return
        views.code[0] = 0
        conn.send(("ok", None, logs.take()))
        poller = select.poll()
        poller.register(conn.fileno(), select.POLLIN)
        while True:
            try:
                if spin:
                    spin_poll(poller, spin)
                msg = conn.recv()
            except (EOFError, OSError):
                return
            result, done = None, False
            for i, cmd in enumerate(msg):
                op = cmd[0]
                views.code[0] = CODES[op]
                try:
                    result, done = _execute(sub, op, cmd, views, states)
                except Exception as e:
                    reply = ("err", i, *_encode(e), logs.take())
                    _drop_traceback(e)
                    conn.send(reply)
                    break
            else:
                views.code[0] = 0
                conn.send(("ok", result, logs.take()))
            views.code[0] = 0
            if done:
                sub = None
                return
    finally:
        if sub is not None:
            sub.free()
        views.release()
        _close_arena(arena, name)
        conn.close()


def _close_arena(arena: mmap.mmap, name: str = "?") -> None:
    """Close the worker's shared memory at its exit, after :meth:`ArenaViews.release`. Should
    something outside the worker's own views still point into it (an FMU that kept a pointer,
    a ctypes array made elsewhere), the cyclic GC gets one chance to collect it, and then the
    arena is left to the process exit, which releases it, with one line on stderr instead of
    the bare ``BufferError`` traceback the worker printed before 2026-12-06."""
    try:
        arena.close()
        return
    except BufferError:
        pass
    import gc
    gc.collect()
    try:
        arena.close()
    except BufferError:
        sys.stderr.write(f"rotorcosim FMU worker '{name}': its shared memory is still referenced at exit "
                         "(left to the process exit)\n")


def _execute(sub, op: str, cmd: tuple, views: ArenaViews, states: dict) -> tuple[Any, bool]:
    """One command in the worker; returns (result, worker done). The arena's views are reached
    through ``views`` only (no view as a local: a frame kept after a failure must not pin it)."""
    batches = views.batches
    if op == "set":
        sub.set_real(batches[cmd[1]])
    elif op == "step":
        views.reg[1] = cmd[1]
        sub.no_set_prior_state = cmd[3]
        sub.do_step(cmd[1], cmd[2])
        views.reg[1] = cmd[1] + cmd[2]
    elif op == "get":
        sub.get_real(batches[cmd[1]])
    elif op == "der":
        sub.set_real_input_derivatives(batches[cmd[1]])
    elif op == "setv":
        from orchestrator.fmi.values import TypedBatch
        b = TypedBatch(cmd[1], cmd[2], cmd[3])
        if cmd[1] == "String":
            b.set_strings(cmd[4])
        else:
            b.values[:] = cmd[4]
        sub.set_values(b)
    elif op == "getv":
        from orchestrator.fmi.values import TypedBatch
        b = TypedBatch(cmd[1], cmd[2], cmd[3])
        sub.get_values(b)
        return (b.strings(keep_null=True) if cmd[1] == "String" else b.values.tolist()), False
    elif op == "ended":
        return sub.terminated_by_fmu(), False
    elif op == "reg":
        _, bid, offset, nbytes, vrs, orders = cmd
        views.register(bid, offset, nbytes, vrs, orders)
    elif op == "gs":
        states[cmd[1]] = sub.get_state()
    elif op == "ss":
        sub.set_state(states[cmd[1]])
    elif op == "fs":
        sub.free_state(states.pop(cmd[1]))
    elif op == "params":
        sub.set_parameters(cmd[1], out_dir=cmd[2])
    elif op == "setup":
        views.reg[1] = cmd[1]
        sub.setup_experiment(cmd[1], cmd[2])
    elif op == "enter":
        sub.enter_initialization_mode()
    elif op == "exit":
        sub.exit_initialization_mode()
    elif op == "term":
        sub.terminate()
    elif op == "free":
        for s in list(states.values()):
            sub.free_state(s)
        states.clear()
        views.drop_batches()
        sub.free()
        return dict(sub.calls), True
    return None, False


if __name__ == "__main__":       # started by WorkerSubsystem
    _serve(int(sys.argv[1]), int(sys.argv[2]), *sys.argv[3:6], *map(float, sys.argv[6:7]))
    # leave without the interpreter's teardown, where PythonFMU-built FMUs abort
    # intermittently (orchestrator.cli.console_main); the FMU is freed and the reply sent
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)
