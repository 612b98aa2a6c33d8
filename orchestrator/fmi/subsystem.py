"""Subsystems: the one place that calls FMI.

:class:`SubsystemBase` is the interface the master drives; :class:`Subsystem`
implements it for an FMI 2.0 co-simulation FMU through fmpy's ``FMU2Slave``.
Tests implement it with plain Python (fake subsystems).

Call order (FMI 2.0 co-simulation, enforced by the master)::

    sub = Subsystem(name, fmu_path, work_dir=...)   # check archive, extract, load, instantiate
    sub.set_parameters({...}, out_dir=...)          # instantiated state
    sub.setup_experiment(t0, t_stop)
    sub.enter_initialization_mode()
    sub.set_real(batch) / sub.get_real(batch)       # initial exchange
    sub.exit_initialization_mode()
    loop: sub.set_real(inputs); [sub.set_real_input_derivatives(d)]; sub.do_step(t, h); sub.get_real(outputs)
    sub.terminate(); sub.free()                     # free() always, also after errors

Values travel in :class:`RealBatch` objects made once at setup: the value
references and a value buffer live in ctypes arrays, and ``batch.values`` is a
numpy view of that buffer, so the hot path allocates nothing. Callers write
``batch.values[:] = ...`` and call :meth:`set_real`, or call :meth:`get_real`
and read ``batch.values``.

Every FMI call goes through :meth:`Subsystem._call`, which counts it and turns
every status worse than fmi2Warning, and every exception, into
:class:`orchestrator.errors.FmuCallError` carrying the FMU's last log messages.

Length: every FMI call of the project lives here (the one place that calls FMI), with its
status handling; above ~400 lines for that reason.
"""

from __future__ import annotations

import ast
import collections
import ctypes
import logging
import math
import os
import re
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from orchestrator.errors import FmuCallError, FmuError, LifecycleError, ScenarioError
from orchestrator.fmi.archive import ModelDescription, Variable, binary_path, read_model_description, safe_extract
from orchestrator.fmi.bundled_python import own_imports
from orchestrator.fmi.call_record import CODE as CALL_CODE
from orchestrator.fmi import fmu_logging
from orchestrator.fmi.fmu_logging import RUNNING as _RUNNING
from orchestrator.fmi.values import FAMILY, TypedBatch, settable_problem
from orchestrator.untrusted import OUT_DIR_FIELD, UNSHOWN as _UNSHOWN, out_dir_escape, shown_char as _shown


#: True once this process has loaded an FMU's shared library in-process (read by
#: :func:`orchestrator.cli.console_main`, which then skips the interpreter's teardown).
native_fmu_loaded = False

log = logging.getLogger(__name__)

STATUS_NAMES = ("ok", "warning", "discard", "error", "fatal", "pending")

# Statistics keys for the FMI functions (contracts.md: {"doStep", "set", "get", ...}).
_SET_REAL, _GET_REAL, _DO_STEP = CALL_CODE["fmi2SetReal"], CALL_CODE["fmi2GetReal"], CALL_CODE["fmi2DoStep"]
_STAT_KEY = {
    "fmi2SetReal": "set", "fmi2SetInteger": "set", "fmi2SetBoolean": "set", "fmi2SetString": "set",
    "fmi2GetReal": "get", "fmi2GetInteger": "get", "fmi2GetBoolean": "get", "fmi2GetString": "get",
    "fmi2DoStep": "doStep", "fmi2SetRealInputDerivatives": "setRealInputDerivatives",
    "fmi2GetFMUstate": "getFMUstate", "fmi2SetFMUstate": "setFMUstate", "fmi2FreeFMUstate": "freeFMUstate",
    "fmi2SetupExperiment": "setupExperiment", "fmi2EnterInitializationMode": "enterInitializationMode",
    "fmi2ExitInitializationMode": "exitInitializationMode", "fmi2Terminate": "terminate",
    "fmi2FreeInstance": "freeInstance", "fmi2Instantiate": "instantiate",
}


class RealBatch:
    """Value references and a value buffer for batched Real set/get.

    ``values`` is a float64 numpy view of the ctypes buffer passed to FMI.
    ``orders`` is set for input-derivative batches (one entry per (vr, order)).
    """

    __slots__ = ("names", "vrs", "n", "c_vrs", "c_values", "values", "c_orders", "orders")

    def __init__(self, names: Sequence[str], vrs: Sequence[int], orders: Sequence[int] | None = None):
        self.names = tuple(names)
        self.vrs = np.asarray(vrs, dtype=np.int64)
        self.n = len(vrs)
        self.c_vrs = (ctypes.c_uint * max(self.n, 1))(*[int(v) for v in vrs])
        self.c_values = (ctypes.c_double * max(self.n, 1))()
        self.values = np.ctypeslib.as_array(self.c_values)[: self.n]
        if orders is not None:
            self.c_orders = (ctypes.c_int * max(self.n, 1))(*[int(o) for o in orders])
            self.orders = np.asarray(orders, dtype=np.int64)
        else:
            self.c_orders = None
            self.orders = None


#: PythonFMU's report of a Python exception in the slave: "[fatal] Fatal py exception
#: encountered: [getReal] PyObject_CallMethod\nValueError('invalid bearing parameters: ...')"
_PY_EXCEPTION = re.compile(r"Fatal py exception encountered: \[(\w+)\] PyObject_CallMethod\s*"
                           r"([A-Za-z_][\w.]*)\((.*)\)\s*$", re.S)
_LOG_HEAD, _LOG_TAIL = 1200, 400       # characters kept of a long log message: its start and its end


def _batch_text(fname: str, batch, md=None) -> str:
    """``"the call read Fx (value reference 7), ghost (value reference 21)"``: the variables of a failed
    get/set call (the FMU's "unknown value reference 21" named no variable); "" without a batch.
    Names that are only the value reference (batches made in a worker) are looked up in ``md``."""
    names = getattr(batch, "names", None)
    if not names:
        return ""
    n = min(len(names), 8)
    vrs = [int(batch.c_vrs[i]) for i in range(n)]
    family = fname.replace("fmi2Get", "").replace("fmi2Set", "")
    by_vr = {}
    if md is not None and any(str(nm) == str(v) for nm, v in zip(names, vrs)):
        kinds = ("Integer", "Enumeration") if family == "Integer" else (family,)
        by_vr = {v.value_reference: v.name for v in md.variables.values() if v.type in kinds}
    shown = [f"{by_vr.get(v, nm) if str(nm) == str(v) else nm} (value reference {v})"
             for nm, v in zip(names[:n], vrs)]
    more = f" and {len(names) - n} more" if len(names) > n else ""
    verb = "read" if "Get" in fname else "set"
    return f"the call {verb} {', '.join(shown)}{more}"


def log_message_text(message: str) -> str:
    """One FMU log message on one line, for an error: a Python exception that PythonFMU
    reports is shown as ``ValueError in getReal: <its message>`` (the repr unquoted, its
    line breaks kept as ' / '), and a long message keeps its start and its end (the start says
    what is wrong, the end where). Control characters and direction overrides are shown
    escaped (``\\x1b``), so an FMU cannot clear or rewrite the terminal."""
    text = message.strip()
    m = _PY_EXCEPTION.search(text)
    if m:
        where, kind, args = m.groups()
        try:
            value = ast.literal_eval(args)
        except (ValueError, SyntaxError, MemoryError, RecursionError):
            value = args
        if isinstance(value, str):
            text = f"{kind} in the FMU's {where}: {value}"
    text = " / ".join(line.strip() for line in text.splitlines() if line.strip())
    text = _UNSHOWN.sub(_shown, text)
    if len(text) > _LOG_HEAD + _LOG_TAIL + 5:
        text = f"{text[:_LOG_HEAD]} ... {text[-_LOG_TAIL:]}"
    return text


# FMU log messages. The logger that formats the printf arguments (ours, or fmpy's proxy)
# keeps one Python logger for the process, so one callback serves every
# instance and dispatches on the instance name to that instance's recent
# messages (used in FmuCallError details).
_LOG_SINKS: dict[str, collections.deque] = {}
_CALLBACKS = None
_KEEP: list = []        # the Python logger the C logger calls: alive as long as the module
#: an instance's log messages of status warning or worse shown (logged at WARNING) per run; the
#: rest are counted and summed up once when the instance is freed (an FMU that logs thousands of
#: messages a step flooded the terminal with megabytes, and in a worker process its memory)
LOG_SHOWN = 20
#: sink key -> [shown, not shown]
_LOG_COUNTS: dict[str, list] = {}
#: the same for instance names no live instance has (an FMU logging under another name, or
#: after it was freed), at most _MAX_OTHER_NAMES of them (the rest share "*")
_LOG_OTHERS: dict[str, list] = {}
_MAX_OTHER_NAMES = 64


def _fmu_logger(env, instance_name, status, category, message):
    try:
        inst = instance_name.decode("utf-8", "replace") if instance_name else "?"
        text = message.decode("utf-8", "replace") if message else ""
    except Exception:   # pragma: no cover - defensive
        inst, text = "?", "<undecodable message>"
    label = STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else str(status)
    counts = None
    for key, sink in list(_LOG_SINKS.items()):
        if key.rsplit("#", 1)[0] == inst:
            sink.append(f"[{label}] {text}")
            counts = _LOG_COUNTS.get(key, counts)
    # the FMU chooses the name it logs under: shown escaped and cut like the message
    shown_inst = log_message_text(inst)[:80] or "?"
    if status >= 1:
        own = counts is not None
        if not own:      # a name no live instance has: capped the same way, per name
            name = inst if inst in _LOG_OTHERS or len(_LOG_OTHERS) < _MAX_OTHER_NAMES else "*"
            counts = _LOG_OTHERS.setdefault(name, [0, 0])
        if counts[0] >= LOG_SHOWN:
            counts[1] += 1
            return
        counts[0] += 1
        log.warning("%s: [%s] %s", shown_inst, label, log_message_text(text))
        if counts[0] == LOG_SHOWN:
            log.warning("%s: the FMU's further log messages are not shown (%d shown)%s", shown_inst, LOG_SHOWN,
                        "; their number is given when the run ends, and the last ones with an FMU error" if own
                        else " (no instance of the run has this name: the FMU logs under a name of its own)")
    elif log.isEnabledFor(logging.DEBUG):
        log.debug("%s: [%s] %s", shown_inst, label, log_message_text(text))


def is_python_fmu(unzip_dir) -> bool:
    """True for a PythonFMU FMU (the library is PythonFMU's runtime: it reads the slave module's
    name from ``resources/slavemodule.txt`` and runs the slave class in this interpreter)."""
    return (Path(unzip_dir) / "resources" / "slavemodule.txt").is_file()


def _holding_the_gil(dll, functions: dict, names) -> tuple:
    """The FMI functions ``names`` of a PythonFMU FMU called without releasing the GIL
    (``ctypes.PyDLL`` semantics on the same library handle, same argument and return types).

    Through ``ctypes.CDLL`` every call released the GIL and PythonFMU's runtime took it back at
    once (``PyGILState_Ensure``) to run the slave's Python: two hand-overs per call that buy
    nothing, and in a threaded stage each was a chance for the other member's thread to take
    the GIL in between, so a call waited for that thread's Python (issue 16: the master's
    exchange with two bearings in threads). Holding it is safe: ``PyGILState_Ensure`` on the
    thread that holds the GIL only counts, the slave's Python still lets other threads run
    every switch interval, and a compiled kernel called without the GIL (the film) releases it
    as before. Python errors the runtime leaves set would raise here; PythonFMU clears them
    (it logs them and returns fmi2Error), and :class:`Subsystem` turns either into an
    ``FmuCallError``. Only for PythonFMU FMUs: a C FMU's long doStep must not hold the GIL."""
    py = ctypes.PyDLL(None, handle=dll._handle)
    out = []
    for name in names:
        f = getattr(py, name)
        f.argtypes, f.restype = functions[name].argtypes, functions[name].restype
        out.append(f)
    return tuple(out)


def _callbacks():
    global _CALLBACKS
    if _CALLBACKS is None:
        from fmpy import calloc, free
        from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                               fmi2CallbackLoggerTYPE)
        from orchestrator.fmi.safe_log import safe_logger
        cb = fmi2CallbackFunctions()
        target = fmi2CallbackLoggerTYPE(_fmu_logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        # the message is a printf format: formatted by our C logger, which does not trust the
        # FMU's arguments (orchestrator/fmi/safe_log.py), else by fmpy's proxy
        address = safe_logger(target)
        if address:
            cb.logger = fmi2CallbackLoggerTYPE(address)
        else:
            cb.logger = target
            try:
                from fmpy.logging import addLoggerProxy
                addLoggerProxy(ctypes.byref(cb))
            except Exception:   # pragma: no cover - the proxy only formats printf arguments
                pass
        _KEEP.append(target)
        _CALLBACKS = cb     # module lifetime: FMUs may log until freed
    return _CALLBACKS


def md_variable(md: ModelDescription, name: str, instance: str, fmu_path: Path) -> Variable:
    """The variable ``name`` of an FMU's model description; a ScenarioError listing the valid names
    if it has none (the lookup of :class:`Subsystem` and of the worker proxy alike)."""
    try:
        return md.variables[name]
    except KeyError:
        raise ScenarioError(f"FMU instance '{instance}' ({Path(fmu_path).name}) has no variable '{name}'; "
                            f"valid names: {', '.join(md.variables)}") from None


class SubsystemBase(ABC):
    """One simulation unit driven by the master (an FMU, or a plain-Python fake).

    Rules for implementers: see the module docstring for the call order.
    ``do_step(t, h)`` advances from ``t`` to ``t + h`` with the inputs set
    before it held constant, unless ``can_interpolate_inputs`` is True, in
    which case the derivatives given by ``set_real_input_derivatives`` (at
    ``t``) extend them to a polynomial over the step. Failures raise
    :class:`FmuCallError`. ``calls`` counts calls per statistics key.
    """

    name: str
    can_interpolate_inputs: bool = False

    def warn_once(self, key: tuple, text: str, *args) -> None:
        """``log.warning(text, *args)`` the first time ``key`` (e.g. (what, variable)) is met for
        this instance in the run: a flaw of a value the FMU repeats every step is said once."""
        said = self.__dict__.setdefault("_said", set())
        if key not in said:
            said.add(key)
            log.warning(text, *args)
    can_get_set_state: bool = False
    # passed to fmi2DoStep as noSetFMUStatePriorToCurrentPoint; the master sets
    # it False while it may still restore an earlier state (start-up iteration)
    no_set_prior_state: bool = True

    def __init__(self, name: str):
        self.name = name
        self.calls: dict[str, int] = collections.defaultdict(int)

    # -- description --------------------------------------------------------
    @abstractmethod
    def variable(self, name: str) -> Variable:
        """The variable called ``name``; ScenarioError listing valid names if unknown."""

    def real_batch(self, names: Sequence[str]) -> RealBatch:
        vs = [self.variable(n) for n in names]
        for v in vs:
            if v.type != "Real":
                raise ScenarioError(f"'{self.name}.{v.name}' is of type {v.type}, expected Real for a coupling "
                                    "or recorded signal; connect or record Real variables only")
        return RealBatch([v.name for v in vs], [v.value_reference for v in vs])

    def typed_batch(self, names: Sequence[str], family: str) -> TypedBatch:
        """A :class:`TypedBatch` of ``family`` ("Integer" also holds Enumeration) for variables ``names``."""
        vs = [self.variable(n) for n in names]
        for v in vs:
            if FAMILY.get(v.type) != family:
                raise ScenarioError(f"'{self.name}.{v.name}' is of type {v.type}, not of the {family} family")
        return TypedBatch(family, [v.name for v in vs], [v.value_reference for v in vs])

    def set_values(self, batch: TypedBatch) -> None:
        """fmi2SetInteger/Boolean/String with ``batch`` (non-Real coupling signals)."""
        raise LifecycleError(f"subsystem '{self.name}' has no {batch.family} variables to set")

    def get_values(self, batch: TypedBatch) -> None:
        """fmi2GetInteger/Boolean/String into ``batch``."""
        raise LifecycleError(f"subsystem '{self.name}' has no {batch.family} variables to get")

    def terminated_by_fmu(self) -> bool:
        """True if the FMU has ended the simulation (fmi2GetBooleanStatus(fmi2Terminated) after fmi2Discard)."""
        return False

    def derivative_batch(self, names: Sequence[str], max_order: int) -> RealBatch:
        """Batch of entries (vr, order) for orders 1..max_order, order-major."""
        vs = [self.variable(n) for n in names]
        vrs = [v.value_reference for _ in range(max_order) for v in vs]
        orders = [o for o in range(1, max_order + 1) for _ in vs]
        nm = [f"der({v.name},{o})" for o in range(1, max_order + 1) for v in vs]
        return RealBatch(nm, vrs, orders)

    # -- lifecycle -----------------------------------------------------------
    def set_parameters(self, values: Mapping[str, Any], *, out_dir: Path | str | None = None) -> None:
        """Set parameter values by name (before ``setup_experiment``)."""

    def setup_experiment(self, start_time: float, stop_time: float | None) -> None:
        pass

    def enter_initialization_mode(self) -> None:
        pass

    def exit_initialization_mode(self) -> None:
        pass

    @abstractmethod
    def set_real(self, batch: RealBatch) -> None:
        """Set ``batch.values`` for ``batch.vrs``."""

    @abstractmethod
    def get_real(self, batch: RealBatch) -> np.ndarray:
        """Fill and return ``batch.values``."""

    def set_real_input_derivatives(self, batch: RealBatch) -> None:
        raise LifecycleError(f"subsystem '{self.name}' cannot interpolate inputs; the master must not call "
                             "set_real_input_derivatives on it")

    # split get for concurrent stepping (coupling.parallel): request_real starts everything
    # queued and the get, receive_real returns the values. In process the request does the get.
    def request_real(self, batch: RealBatch) -> None:
        self.get_real(batch)

    def receive_real(self, batch: RealBatch) -> np.ndarray:
        return batch.values

    @abstractmethod
    def do_step(self, t: float, h: float) -> None:
        """Advance from ``t`` to ``t + h``."""

    def get_state(self) -> Any:
        raise LifecycleError(f"subsystem '{self.name}' cannot get/set its state (canGetAndSetFMUstate is false)")

    def set_state(self, state: Any) -> None:
        raise LifecycleError(f"subsystem '{self.name}' cannot get/set its state (canGetAndSetFMUstate is false)")

    def free_state(self, state: Any) -> None:
        pass

    def terminate(self) -> None:
        pass

    def free(self) -> None:
        pass

    def statistics(self) -> dict[str, int]:
        return dict(self.calls)


class Subsystem(SubsystemBase):
    """An FMI 2.0 co-simulation FMU instance (through fmpy's ``FMU2Slave``).

    Parameters
    ----------
    name : instance name in the scenario (also the FMI instance name).
    fmu_path : the ``.fmu`` file; checked with :mod:`orchestrator.fmi.archive`.
    work_dir : directory to extract into (``work_dir/name``); the caller
        removes it after :meth:`free`.
    extraction : instead of ``work_dir``, an
        :class:`orchestrator.fmi.extraction.ExtractionPool`: the run's one extraction of
        this FMU file, shared with the other instances of the same file.
    """

    def __init__(self, name: str, fmu_path: Path | str, *, work_dir: Path | str | None = None,
                 extraction=None, call_slot: tuple[memoryview, int] | None = None):
        super().__init__(name)
        # (array, k) of an orchestrator.fmi.call_record.CallRecord: the FMI function this instance
        # is in (code at k, simulation time at k + 1), readable after a crash of this process
        self._slot, self._k = call_slot if call_slot is not None else (None, 0)
        self._now = math.nan                 # simulation time of the instance (NaN before the first step)
        self.fmu_path = Path(fmu_path)
        self.md: ModelDescription = read_model_description(self.fmu_path)
        self.can_interpolate_inputs = self.md.can_interpolate_inputs
        self.can_get_set_state = self.md.can_get_and_set_fmu_state
        self.max_output_derivative_order = self.md.max_output_derivative_order
        self._log_messages: collections.deque[str] = collections.deque(maxlen=8)
        self._state = "new"      # new -> instantiated -> initializing -> stepping -> terminated -> freed; "error"
        self._slave = None
        if extraction is not None:
            self.unzip_dir = extraction.extract(self.fmu_path)
        elif work_dir is not None:
            self.unzip_dir = safe_extract(self.fmu_path, Path(work_dir) / name)
        else:
            raise LifecycleError(f"Subsystem('{name}'): give work_dir= or extraction= (where to extract the FMU)")
        binary_path(self.unzip_dir, self.md)   # clear error when no binary for this platform

        from fmpy.fmi2 import FMU2Slave

        # the logger first: a SettingError there (ROTORCOSIM_SAFE_LOGGER, CC) leaves no library loaded
        cb = _callbacks()
        fmu_logging.install()      # the FMU's Python log records name this instance, capped
        global native_fmu_loaded
        native_fmu_loaded = True     # the CLI then leaves without interpreter teardown (cli.console_main)
        # fmpy changes into binaries/<platform> to load the library and, when loading fails, stays
        # there: a relative --out then named a folder inside the extraction (summary.json.tmp: no
        # such file) and the load failure itself was never reported
        cwd = os.getcwd()
        try:
            self._slave = FMU2Slave(guid=self.md.guid, unzipDirectory=str(self.unzip_dir),
                                    modelIdentifier=self.md.model_identifier, instanceName=name)
        except Exception as e:   # library load failure
            raise FmuError(f"{self.fmu_path}: cannot load the FMU's shared library ({e}); "
                           "check that the FMU was built for this platform and its dependencies are installed") from e
        finally:
            if os.getcwd() != cwd:
                os.chdir(cwd)

        self._callbacks = cb
        self._sink_key = f"{name}#{id(self)}"
        _LOG_SINKS[self._sink_key] = self._log_messages
        _LOG_COUNTS[self._sink_key] = [0, 0]
        self._f = self._slave._functions
        self._c_set_real = self._f["fmi2SetReal"]
        self._c_get_real = self._f["fmi2GetReal"]
        self._c_do_step = self._f["fmi2DoStep"]
        if is_python_fmu(self.unzip_dir):
            self._c_set_real, self._c_get_real, self._c_do_step = _holding_the_gil(
                self._slave.dll, self._f, ("fmi2SetReal", "fmi2GetReal", "fmi2DoStep"))
        self.calls["instantiate"] += 1
        try:
            self._enter("fmi2Instantiate")
            with own_imports(self.unzip_dir):   # a PythonFMU FMU imports the packages it bundles, not a cached copy
                self._slave.instantiate(callbacks=cb, loggingOn=True)
        except Exception as e:
            self._free_library()
            raise FmuCallError(name, "fmi2Instantiate", "failed", self._detail(str(e))) from e
        finally:
            self._leave()
        self._component = self._slave.component
        self._state = "instantiated"

    # -- the choke point -----------------------------------------------------
    def _detail(self, extra: str = "") -> str:
        msgs = " | ".join(log_message_text(m) for m in self._log_messages)
        parts = [p for p in (extra, f"FMU log: {msgs}" if msgs else "") if p]
        return "; ".join(parts)

    def _enter(self, fname: str, t: float | None = None) -> None:
        """Record that this instance is in FMI function ``fname`` (at ``t``, else its time now)."""
        _RUNNING.name = self.name          # the FMU's Python log records name this instance
        a = self._slot
        if a is not None:
            k = self._k
            a[k + 1] = self._now if t is None else t
            a[k] = CALL_CODE.get(fname, 0.0)

    def _leave(self) -> None:
        _RUNNING.name = None
        if self._slot is not None:
            self._slot[self._k] = 0.0

    def _call(self, fname: str, *args, batch=None) -> int:
        """Call FMI function ``fname``; raise FmuCallError unless OK/warning (``batch``: the variables
        a get/set call passed, named in the error)."""
        self.calls[_STAT_KEY.get(fname, fname)] += 1
        self._enter(fname)
        try:
            res = self._f[fname](*args)
        except Exception as e:
            self._state = "error"
            raise FmuCallError(self.name, fname, "exception", self._detail(f"{type(e).__name__}: {e}")) from e
        finally:
            self._leave()
        if res:
            self._status(fname, res, batch)
        return res

    def _status(self, fname: str, res: int, batch=None) -> None:
        if res == 1:
            log.warning("%s: %s returned warning%s", self.name, fname,
                        (": " + self._log_messages[-1]) if self._log_messages else "")
            return
        label = STATUS_NAMES[res] if 0 <= res < len(STATUS_NAMES) else f"illegal status {res}"
        if res == 5 and fname != "fmi2DoStep":
            label = "illegal status 5 (fmi2Pending, which only fmi2DoStep may return)"
        if res in (3, 4) or label.startswith("illegal"):
            self._state = "fatal" if res == 4 else "error"
        raise FmuCallError(self.name, fname, label, self._detail(_batch_text(fname, batch, self.md)))

    # -- description ------------------------------------------------------------
    def variable(self, name: str) -> Variable:
        return md_variable(self.md, name, self.name, self.fmu_path)

    # -- lifecycle ----------------------------------------------------------------
    def set_parameters(self, values: Mapping[str, Any], *, out_dir: Path | str | None = None) -> None:
        from fmpy.fmi2 import fmi2Boolean, fmi2Integer, fmi2Real, fmi2String, fmi2ValueReference
        for pname, value in values.items():
            v = self.variable(pname)
            why = settable_problem(v)
            if why is not None:
                raise ScenarioError(f"'{self.name}.{pname}' cannot be given a value before initialization: it is "
                                    f"{why}; remove it from 'parameters:'")
            vr = (fmi2ValueReference * 1)(v.value_reference)
            try:
                if v.type == "Real":
                    if isinstance(value, bool) or not isinstance(value, (int, float)):
                        raise TypeError
                    self._call("fmi2SetReal", self._component, vr, 1, (fmi2Real * 1)(float(value)))
                elif v.type in ("Integer", "Enumeration"):
                    if isinstance(value, bool) or not (isinstance(value, int) or
                                                       (isinstance(value, float) and value.is_integer())):
                        raise TypeError
                    self._call("fmi2SetInteger", self._component, vr, 1, (fmi2Integer * 1)(int(value)))
                elif v.type == "Boolean":
                    if not isinstance(value, (bool, int)) or value not in (0, 1):
                        raise TypeError
                    self._call("fmi2SetBoolean", self._component, vr, 1, (fmi2Boolean * 1)(1 if value else 0))
                elif v.type == "String":
                    if not isinstance(value, str):
                        raise TypeError
                    if out_dir is not None:
                        why = out_dir_escape(value)
                        if why:          # (scenarios made in Python do not pass the loader's check)
                            raise ScenarioError(f"parameter '{self.name}.{pname}' is a path in the run "
                                                f"folder, but {why}")
                        value = value.replace(OUT_DIR_FIELD, str(Path(out_dir).resolve()))
                    self._call("fmi2SetString", self._component, vr, 1, (fmi2String * 1)(value.encode("utf-8")))
            except TypeError:
                raise ScenarioError(f"parameter '{self.name}.{pname}' is of type {v.type}, got {value!r} "
                                    f"({type(value).__name__}); give a {v.type} value") from None
            except FmuCallError as e:
                # "fmi2SetReal returned error" named neither the parameter nor its value: an FMU that
                # declares a parameter and then refuses it (or refuses the value) was untraceable
                head = f"FMU instance '{e.instance}': {e.function} returned {e.status}"
                text = str(e)
                detail = text[len(head) + 2:] if text.startswith(head + ": ") else ""
                shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:57] + "..."
                raise FmuCallError(e.instance, e.function, e.status,
                                   f"the FMU refused parameter '{pname}' = {shown} ({v.type}, value reference "
                                   f"{v.value_reference}), which its model description declares; check the "
                                   "value against the FMU's documentation, or remove the parameter from "
                                   "'parameters:' to keep its start value" + (f"; {detail}" if detail else "")) from None

    def setup_experiment(self, start_time: float, stop_time: float | None) -> None:
        self._now = float(start_time)
        self._call("fmi2SetupExperiment", self._component, 0, 0.0, float(start_time),
                   1 if stop_time is not None else 0, float(stop_time or 0.0))

    def enter_initialization_mode(self) -> None:
        self._call("fmi2EnterInitializationMode", self._component)
        self._state = "initializing"

    def exit_initialization_mode(self) -> None:
        self._call("fmi2ExitInitializationMode", self._component)
        self._state = "stepping"

    def set_values(self, batch: TypedBatch) -> None:
        if batch.n:
            self._call(f"fmi2Set{batch.family}", self._component, batch.c_vrs, batch.n, batch.c_values, batch=batch)

    def get_values(self, batch: TypedBatch) -> None:
        if batch.n:
            self._call(f"fmi2Get{batch.family}", self._component, batch.c_vrs, batch.n, batch.c_values, batch=batch)
            if batch.family == "String":
                for name, why in batch.own_strings():
                    self.warn_once(("bad string", name), "FMU instance '%s' gave %s for the String '%s' in "
                                   "fmi2GetString; what could be read is recorded and passed on (\"\" for "
                                   "nothing); only its first such value is reported", self.name, why, name)

    def terminated_by_fmu(self) -> bool:
        """fmi2GetBooleanStatus(fmi2Terminated) (FMI 2.0 sec. 4.2.3); False if the FMU cannot answer.

        FMUs generated by PythonFMU (0.6, 0.7) answer True after *every* discarded step (its
        ``do_step`` returning False), so for them the flag tells nothing: their discard stays a
        discard (``coupling.discard_retries`` applies), as our own FMUs rely on.
        """
        if self.md.generation_tool.startswith("PythonFMU"):
            return False
        from fmpy.fmi2 import fmi2Boolean
        flag = fmi2Boolean(0)
        try:
            res = self._f["fmi2GetBooleanStatus"](self._component, 3, ctypes.byref(flag))   # 3 = fmi2Terminated
        except Exception as e:   # PythonFMU and others may not implement it
            log.debug("%s: fmi2GetBooleanStatus(fmi2Terminated) raised %s", self.name, e)
            return False
        self.calls["getStatus"] += 1
        return res == 0 and bool(flag.value)

    # -- hot path (no allocation) ------------------------------------------------
    def set_real(self, batch: RealBatch) -> None:
        self.calls["set"] += 1
        a = self._slot
        if a is not None:                   # the call record, inline (two stores; see _enter)
            a[self._k + 1] = self._now
            a[self._k] = _SET_REAL
        _RUNNING.name = self.name
        try:
            res = self._c_set_real(self._component, batch.c_vrs, batch.n, batch.c_values)
        except Exception as e:
            self._state = "error"
            raise FmuCallError(self.name, "fmi2SetReal", "exception", self._detail(str(e))) from e
        finally:
            _RUNNING.name = None
            if a is not None:
                a[self._k] = 0.0
        if res:
            self._status("fmi2SetReal", res, batch)

    def get_real(self, batch: RealBatch) -> np.ndarray:
        self.calls["get"] += 1
        a = self._slot
        if a is not None:
            a[self._k + 1] = self._now
            a[self._k] = _GET_REAL
        _RUNNING.name = self.name
        try:
            res = self._c_get_real(self._component, batch.c_vrs, batch.n, batch.c_values)
        except Exception as e:
            self._state = "error"
            raise FmuCallError(self.name, "fmi2GetReal", "exception", self._detail(str(e))) from e
        finally:
            _RUNNING.name = None
            if a is not None:
                a[self._k] = 0.0
        if res:
            self._status("fmi2GetReal", res, batch)
        return batch.values

    def do_step(self, t: float, h: float) -> None:
        self.calls["doStep"] += 1
        a = self._slot
        if a is not None:
            a[self._k + 1] = t
            a[self._k] = _DO_STEP
        _RUNNING.name = self.name
        try:
            res = self._c_do_step(self._component, t, h, 1 if self.no_set_prior_state else 0)
        except Exception as e:
            self._state = "error"
            raise FmuCallError(self.name, "fmi2DoStep", "exception", self._detail(str(e))) from e
        finally:
            _RUNNING.name = None
            if a is not None:
                a[self._k] = 0.0
        if res:
            self._status("fmi2DoStep", res)
        self._now = t + h

    def set_real_input_derivatives(self, batch: RealBatch) -> None:
        if not self.can_interpolate_inputs:
            super().set_real_input_derivatives(batch)
        self._call("fmi2SetRealInputDerivatives", self._component, batch.c_vrs, batch.n,
                   batch.c_orders, batch.c_values)

    # -- state --------------------------------------------------------------------
    def get_state(self):
        if not self.can_get_set_state:
            super().get_state()
        from fmpy.fmi2 import fmi2FMUstate
        s = fmi2FMUstate()
        self._call("fmi2GetFMUstate", self._component, ctypes.byref(s))
        if not s.value:        # a NULL state handed back later to fmi2SetFMUstate: a crash or a silent no-op
            raise FmuCallError(self.name, "fmi2GetFMUstate", "no state",
                               self._detail("it returned fmi2OK but gave no FMU state (NULL), although the "
                                            "FMU declares canGetAndSetFMUstate; a coupling that saves no states "
                                            "runs it (scheme gauss-seidel or jacobi, step_control constant, "
                                            "discard_retries 0)"))
        return s

    def set_state(self, state) -> None:
        if not self.can_get_set_state:
            super().set_state(state)
        self._call("fmi2SetFMUstate", self._component, state)

    def free_state(self, state) -> None:
        self._call("fmi2FreeFMUstate", self._component, ctypes.byref(state))

    # -- end ----------------------------------------------------------------------
    def terminate(self) -> None:
        """fmi2Terminate after initialization (states stepComplete/stepFailed) only: FMI 2.0 allows
        fmi2Terminate in no other state (sec. 4.2.4), so an instance still instantiated or in
        initialization mode, or in an error state, is only freed."""
        if self._state == "stepping":
            self._state = "terminated"
            self._call("fmi2Terminate", self._component)

    def free(self) -> None:
        """fmi2FreeInstance and unload the library; idempotent, never raises."""
        if self._slave is None or self._state == "freed":
            return
        if self._state == "fatal":
            # FMI 2.0 allows no call after fmi2Fatal, fmi2FreeInstance included:
            # the instance and its library are left alone (a small leak). This also
            # avoids a PythonFMU 0.7.0 bug: after a Python exception escaped a
            # callback (reported as Fatal) its handle_py_exception() has already
            # released the slave class, instance and log queue, and
            # fmi2FreeInstance releases them a second time; the cyclic GC then
            # crashes later in an unrelated place (docs/dev/requests.md).
            log.warning("%s: not freeing the instance after fmi2Fatal (FMI 2.0 forbids "
                        "any further call); its memory stays allocated until exit", self.name)
            self._state = "freed"
            self._forget_log()
            return
        try:
            self.calls["freeInstance"] += 1
            self._enter("fmi2FreeInstance")
            self._f["fmi2FreeInstance"](self._component)
        except Exception as e:   # pragma: no cover - defensive
            log.warning("%s: fmi2FreeInstance raised %s", self.name, e)
        finally:
            self._leave()
        self._state = "freed"
        self._forget_log()
        self._free_library()

    def _forget_log(self) -> None:
        fmu_logging.forget(self.name)
        _LOG_SINKS.pop(self._sink_key, None)
        if not _LOG_SINKS:
            _LOG_OTHERS.clear()          # the next run (a script, a warm sweep process) starts afresh
        counts = _LOG_COUNTS.pop(self._sink_key, None)
        if counts and counts[1]:
            last = log_message_text(self._log_messages[-1]) if self._log_messages else ""
            log.warning("%s: %d more log messages of the FMU were not shown (%d shown); the last: %s",
                        self.name, counts[1], counts[0], last[:300])

    def _free_library(self) -> None:
        try:
            self._slave.freeLibrary()
        except Exception as e:   # pragma: no cover - defensive
            log.warning("%s: unloading the FMU library failed: %s", self.name, e)

    def __repr__(self) -> str:
        return f"Subsystem({self.name!r}, {self.fmu_path.name!r}, state={self._state})"
