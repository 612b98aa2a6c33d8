"""The master algorithm: explicit Jacobi / Gauss-Seidel co-simulation.

Call order::

    m = MasterAlgorithm(scenario, out_dir=..., observers=[...])
    m.setup()          # load FMUs (checked, extracted), set parameters, precompute the plan
    m.initialize()     # FMI 2.0 initialization and exchange of initial outputs
    while m.status is Status.RUNNING:
        m.step()       # one macro step; numerical failure -> Status.FAILED (no exception)
    m.terminate()      # fmi2Terminate + fmi2FreeInstance for every FMU, observers told
    res = m.result()

:meth:`run` does exactly that. Bad input and misuse raise (ScenarioError,
FmuError, LifecycleError); a failure *during* the run (an FMU returning
Discard/Error/Fatal or raising, a NaN/inf in a coupling signal) makes the
status FAILED with a message that names what, where and what to try.

One macro step T(n) -> T(n+1) (T(n) = t0 + n*H from the index):
for each subsystem in the scheme's stepping order, its inputs are the Lagrange
polynomials of the coupling signals (extrapolated from T(n), T(n-1), ... or,
for Gauss-Seidel, interpolated through the producer's new value at T(n+1));
the polynomial reaches the FMU

* through fmi2SetRealInputDerivatives (value and derivatives at each
  sub-step start) when the FMU declares ``canInterpolateInputs``, or
* by ``substeps`` doStep calls of H/substeps each, with the input set to the
  polynomial's value at the *midpoint* of each sub-step (a piecewise-constant
  input sampled at midpoints is second-order accurate in the sub-step; sampling
  at the start would be first order; see docs/coupling.md).

Before the outputs at T(n+1) are read the inputs are set to the polynomial's
value at T(n+1), so outputs with direct feedthrough are consistent with the
inputs at the same time. Each output then goes through gain/offset into the
consumers' histories.

Discard retries (``coupling.discard_retries`` = N > 0, FMI 2.0 sec. 4.2.3):
every FMU's state and the coupling history are saved before each macro step;
if an FMU returns fmi2Discard, everything is restored to T(n) and the step is
redone as two half steps (each an ordinary step that commits its end point to
the history, so later half steps use the newest values like a run with the
smaller step), recursively down to H/2^N. Afterwards the history is rebuilt on
the nominal grid (levels T(n+1), T(n), T(n-1), ...), so the following macro
steps extrapolate exactly as without the retry. N = 0 is the old behaviour.
"""

from __future__ import annotations

import logging
import math
import shutil
import tempfile
import time as _time
import warnings
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .errors import CouplingError, FmuCallError, LifecycleError, ScenarioError
from .fmu import RealBatch, Subsystem, SubsystemBase
from .observers import Observer, Recorder, RunView
from .results import CoSimResult, Status
from .coupling.acceleration import IQNILS, solve_fixed_point
from .coupling.iterative import IterationSpec, IterativeStep
from .coupling.adaptive import ErrorControlledStep, OutputGrid
from .coupling.loops import loop_through
from .coupling.sections import StepControlSpec
from .schemes import ConstantStep, CouplingScheme, GaussSeidel, StepSizeController, scheme_from_spec
from .signals import MAX_ORDER, History, LagrangePredictor

log = logging.getLogger(__name__)

INIT_LOOP_ITERATIONS = 50         # IQN-ILS iterations for an algebraic loop in the initial exchange
MAX_DISCARD_RETRIES = 30          # coupling.discard_retries: smallest step H / 2^30
RETRY_LOG_LINES = 20              # INFO lines about retried macro steps before only counting them


class _RetriesExhausted(Exception):
    """A sub-step at the smallest allowed step (H / 2^N) was discarded again."""

    def __init__(self, error: FmuCallError, t_a: float, t_b: float):
        super().__init__(str(error))
        self.error, self.t_a, self.t_b = error, t_a, t_b


def _variable_step(sub) -> bool:
    """canHandleVariableCommunicationStepSize of a subsystem (fakes without a model description: True)."""
    md = getattr(sub, "md", None)
    if md is not None and hasattr(md, "can_handle_variable_step"):
        return bool(md.can_handle_variable_step)
    return bool(getattr(sub, "can_handle_variable_step", True))


class _Link:
    """Outputs of one producer going into one consumer block (vectorised)."""

    __slots__ = ("pos", "block", "cols", "gain", "offset", "names", "identity", "tmp", "small", "row0")

    def __init__(self, pos, block, cols, gain, offset, names):
        self.pos = np.asarray(pos, dtype=np.intp)
        self.block = block
        self.cols = np.asarray(cols, dtype=np.intp)
        self.gain = np.asarray(gain, dtype=float)
        self.offset = np.asarray(offset, dtype=float)
        self.names = names          # "src -> dst" per entry, for messages
        self.identity = bool(np.all(self.gain == 1.0) and np.all(self.offset == 0.0))
        self.tmp = np.zeros(len(self.pos))
        self.row0 = block[0]
        self.small = None
        if len(self.pos) <= 4:
            self.small = [(int(p), int(c), float(g), float(o))
                          for p, c, g, o in zip(self.pos, self.cols, self.gain, self.offset)]
        c = self.cols
        if len(c) and np.array_equal(c, np.arange(c[0], c[0] + len(c))):
            self.cols = slice(int(c[0]), int(c[0]) + len(c))     # contiguous: cheaper assignment


class _Unit:
    """Per-subsystem plan, precomputed at setup."""

    def __init__(self, sub: SubsystemBase, substeps: int):
        self.sub = sub
        self.name = sub.name
        self.substeps = substeps
        self.ext_names: list[str] = []      # inputs extrapolated (producer not yet stepped)
        self.int_names: list[str] = []      # inputs interpolated (producer stepped before)
        self.out_names: list[str] = []
        self.links: list[_Link] = []
        self.inb: RealBatch | None = None
        self.outb: RealBatch | None = None
        self.derb: RealBatch | None = None
        self.HE = None
        self.HI = None
        self.nE = 0
        self.nI = 0


class MasterAlgorithm:
    """Explicit co-simulation master (see the module docstring for the call order).

    Parameters
    ----------
    scenario : orchestrator.scenario.Scenario
    out_dir : run directory (for ``{out_dir}`` in String parameters); may be None.
    observers : Observer objects (CSV writer, progress, ...); a Recorder is always added.
    subsystems : optional ``{name: SubsystemBase}`` to use instead of loading the
        scenario's FMUs (tests use plain-Python fakes); the master still frees them.
    scheme, step_size, predictor : policy objects; default from ``scenario.coupling``.
    """

    def __init__(self, scenario, *, out_dir: Path | str | None = None, observers: Sequence[Observer] = (),
                 subsystems: Mapping[str, SubsystemBase] | None = None, scheme: CouplingScheme | None = None,
                 step_size: StepSizeController | None = None, predictor: LagrangePredictor | None = None):
        self.scenario = scenario
        c = scenario.coupling
        self.out_dir = Path(out_dir) if out_dir is not None else None
        self.iterative = c.scheme == "iterative"
        # iterative coupling: Gauss-Seidel passes repeated until the signals agree (coupling/iterative.py)
        self.scheme = scheme or (GaussSeidel(c.sequence) if self.iterative else scheme_from_spec(c.scheme, c.sequence))
        self.iteration = getattr(c, "iteration", None) or IterationSpec()
        self.step_control = getattr(c, "step_control", None) or StepControlSpec()
        self.adaptive: ErrorControlledStep | None = None       # set up in _plan for step_control type error
        self.grid = step_size or ConstantStep(scenario.start_time, scenario.stop_time, c.macro_step)
        self.predictor = predictor or LagrangePredictor(extrapolation_order=c.extrapolation_order,
                                                        interpolation_order=c.interpolation_order)
        self.recorder = Recorder()
        self.observers = [self.recorder, *observers]
        self._given = dict(subsystems) if subsystems is not None else None
        self.subsystems: dict[str, SubsystemBase] = {}
        self.status = Status.NOT_STARTED
        self.message = ""
        # set (e.g. by a SIGINT handler, see orchestrator.run) to stop cleanly between macro
        # steps: run() then raises KeyboardInterrupt from master code, never inside an FMU
        self.interrupt_requested = False
        self.n = 0
        self.t = float(scenario.start_time)
        self.end_time = float(scenario.start_time)
        self.wall_time = 0.0
        self._work_dir: str | None = None
        self._phase = "new"
        self._t_wall0 = 0.0
        self._wkey = None
        self._wcache: dict = {}
        n_retry = getattr(c, "discard_retries", 0)
        if isinstance(n_retry, bool) or not isinstance(n_retry, int) or not 0 <= n_retry <= MAX_DISCARD_RETRIES:
            raise ScenarioError(f"{self._where()}coupling.discard_retries must be an integer between 0 and "
                                f"{MAX_DISCARD_RETRIES} (got {n_retry!r}); use 0 (stop on fmi2Discard) or the "
                                "number of step halvings to try, e.g. 3")
        self.discard_retries = n_retry
        # noSetFMUStatePriorToCurrentPoint for every doStep: False while the master may restore a state
        self._no_prior = not n_retry
        self.retried_steps = 0          # macro steps redone after a discard
        self.retry_substeps = 0         # extra doStep rounds (sub-intervals attempted) in those retries
        self.rejected_steps = 0         # (sub-)step attempts discarded and rolled back
        self._retry_depth = 0

    def _where(self) -> str:
        src = getattr(self.scenario, "source", None)
        return f"{src}: " if src else ""

    # ------------------------------------------------------------------ setup
    def setup(self) -> None:
        """Load the subsystems, set parameters and precompute the stepping plan."""
        if self._phase != "new":
            raise LifecycleError(f"setup() called twice (phase '{self._phase}'); create a new MasterAlgorithm")
        self._phase = "setup"
        self._t_wall0 = _time.perf_counter()
        sc = self.scenario
        names = [f.name for f in sc.fmus]
        try:
            if self._given is not None:
                missing = [n for n in names if n not in self._given]
                if missing:
                    raise ScenarioError(f"no subsystem given for FMU instances {missing}")
                self.subsystems = {n: self._given[n] for n in names}
            else:
                self._work_dir = tempfile.mkdtemp(prefix="rotorcosim-")
                for f in sc.fmus:
                    self.subsystems[f.name] = Subsystem(f.name, f.path, work_dir=self._work_dir)
            for f in sc.fmus:
                self.subsystems[f.name].set_parameters(dict(f.parameters), out_dir=self.out_dir)
            self._plan()
        except BaseException:
            self._release()
            self._phase = "terminated"      # nothing left to terminate; observers never started
            raise

    def _plan(self) -> None:
        sc = self.scenario
        order = self.scheme.stepping_order(list(self.subsystems))
        self.order = order
        self.history = History(MAX_ORDER + 1)
        units = {}
        for f in sc.fmus:
            sub = self.subsystems[f.name]
            m = f.substeps if f.substeps is not None else sc.coupling.substeps
            if not (isinstance(m, int) and m >= 1):
                raise ScenarioError(f"substeps of '{f.name}' must be an integer >= 1 (got {m!r})")
            units[f.name] = _Unit(sub, m)
        problems = []
        seen_dst = {}
        conns = []
        for c in sc.connections:
            si, di = c.src_instance, c.dst_instance
            for inst, what in ((si, c.src), (di, c.dst)):
                if inst not in units:
                    problems.append(f"connection {c.src} -> {c.dst}: no FMU instance '{inst}' "
                                    f"(instances: {', '.join(units)})")
            if si not in units or di not in units:
                continue
            try:
                vs = units[si].sub.variable(c.src_variable)
                vd = units[di].sub.variable(c.dst_variable)
            except ScenarioError as e:
                problems.append(f"connection {c.src} -> {c.dst}: {e.problems[0]}")
                continue
            if vs.type != "Real" or vd.type != "Real":
                problems.append(f"connection {c.src} -> {c.dst}: types {vs.type} -> {vd.type}; the master couples "
                                "Real variables only")
                continue
            if vd.causality != "input":
                problems.append(f"connection {c.src} -> {c.dst}: '{c.dst}' has causality '{vd.causality}', "
                                "expected an input")
                continue
            if c.dst in seen_dst:
                problems.append(f"input '{c.dst}' is connected twice (from {seen_dst[c.dst]} and {c.src}); "
                                "connect each input once")
                continue
            seen_dst[c.dst] = c.src
            conns.append(c)
        if problems:
            raise ScenarioError(problems)

        # inputs of each consumer, split by whether the producer is stepped earlier
        for c in conns:
            u = units[c.dst_instance]
            if self.scheme.uses_new_value(c.src_instance, c.dst_instance, order):
                u.int_names.append(c.dst_variable)
            else:
                u.ext_names.append(c.dst_variable)
        # outputs to read: coupling sources + recorded signals
        columns = self._columns(units)
        for c in conns:
            u = units[c.src_instance]
            if c.src_variable not in u.out_names:
                u.out_names.append(c.src_variable)
        for col in columns:
            inst, var = col.split(".", 1)
            if var not in units[inst].out_names:
                units[inst].out_names.append(var)
        sizes = []
        self.signal_names = []          # the history store's columns ("consumer.input"), for messages
        for u in units.values():
            u.nE, u.nI = len(u.ext_names), len(u.int_names)
            sizes += [u.nE, u.nI]
            self.signal_names += [f"{u.name}.{n}" for n in u.ext_names + u.int_names]
        views = iter(self.history.allocate(sizes))
        for u in units.values():
            u.inb = u.sub.real_batch(u.ext_names + u.int_names)
            u.outb = u.sub.real_batch(u.out_names)
            u.HE = next(views)
            u.HI = next(views)
            if u.sub.can_interpolate_inputs and (u.nE + u.nI):
                u.derb = u.sub.derivative_batch(u.ext_names + u.int_names, MAX_ORDER)
        # links producer -> consumer block
        for prod in units.values():
            groups: dict[tuple[str, str], list] = {}
            for c in conns:
                if c.src_instance != prod.name:
                    continue
                cu = units[c.dst_instance]
                if c.dst_variable in cu.ext_names:
                    key, col = (cu.name, "E"), cu.ext_names.index(c.dst_variable)
                else:
                    key, col = (cu.name, "I"), cu.int_names.index(c.dst_variable)
                groups.setdefault(key, []).append((prod.out_names.index(c.src_variable), col, c.gain, c.offset,
                                                   f"{c.src} -> {c.dst}"))
            for (cname, grp), entries in groups.items():
                block = units[cname].HE if grp == "E" else units[cname].HI
                pos, cols, gains, offs, nm = zip(*entries)
                prod.links.append(_Link(pos, block, cols, gains, offs, list(nm)))
        self.units = [units[n] for n in order]
        # record plan: (outb values, positions, row columns)
        self.columns = columns
        col_index = {c: i for i, c in enumerate(columns)}
        self._rec = []
        for u in self.units:
            pos = [u.out_names.index(c.split(".", 1)[1]) for c in columns if c.split(".", 1)[0] == u.name]
            cols = [col_index[c] for c in columns if c.split(".", 1)[0] == u.name]
            if pos:
                self._rec.append((u.outb.values, np.asarray(pos, dtype=np.intp), np.asarray(cols, dtype=np.intp)))
        H = self.scenario.coupling.macro_step
        interval = self.scenario.output.interval or H
        stride = max(1, int(round(interval / H)))
        if self.step_control.type != "error" and not math.isclose(stride * H, interval, rel_tol=1e-9):
            warnings.warn(f"output.interval {interval} is not a multiple of coupling.macro_step {H}; "
                          f"writing every {stride} macro steps ({stride * H} s)", stacklevel=3)
        self.stride = stride
        k = self.predictor.k
        can_state = all(u.sub.can_get_set_state for u in self.units)
        self._startup_iterations = k >= 2 and can_state
        if k >= 2 and not can_state:
            log.info("extrapolation_order %d: not every FMU can save its state (canGetAndSetFMUstate), so the "
                     "first %d macro steps use lower-order extrapolation; this adds an O(H^2) start-up error "
                     "(see docs/coupling.md)", k, k - 1)
        if self.iterative:
            self._check_states("coupling.scheme = iterative", "repeats every macro step from the saved states",
                               "use scheme gauss-seidel or jacobi")
            self._iterate = IterativeStep(self, self.iteration, self.signal_names)
        if self.discard_retries:
            stateless = [u.name for u in self.units if not u.sub.can_get_set_state]
            if stateless:
                raise ScenarioError(
                    f"{self._where()}coupling.discard_retries = {self.discard_retries} needs every FMU to save and "
                    f"restore its state (canGetAndSetFMUstate=\"true\"), but {', '.join(map(repr, stateless))} "
                    "cannot (got canGetAndSetFMUstate false); set coupling.discard_retries: 0 or use an FMU "
                    "built with state support")
            for u in self.units:
                u.sub.no_set_prior_state = False    # we may restore the state saved before each macro step
        if self.step_control.type == "error":
            self._setup_adaptive(interval)
        self.view = RunView(columns, self.grid.time(0), self.grid.time(self.grid.n_steps), self.grid.n_steps)

    def _setup_adaptive(self, interval: float) -> None:
        """The error-controlled macro step (coupling/adaptive.py): refuse FMUs with a fixed step,
        adapt forward only when some FMU cannot restore a state."""
        fixed = [u.name for u in self.units if not _variable_step(u.sub)]
        if fixed:
            raise ScenarioError(
                f"{self._where()}coupling.step_control type error varies the macro step, but "
                f"{', '.join(map(repr, fixed))} cannot take varying steps (canHandleVariableCommunicationStepSize "
                "false); use step_control type constant")
        can_reject = all(u.sub.can_get_set_state for u in self.units)
        if can_reject:
            for u in self.units:
                u.sub.no_set_prior_state = False
            self._no_prior = False
        else:
            log.warning("coupling.step_control type error: %s cannot restore a saved state, so no macro step "
                        "is rejected: the step adapts forward only",
                        ", ".join(repr(u.name) for u in self.units if not u.sub.can_get_set_state))
        sc = self.scenario
        atol = np.full(len(self.signal_names), self.step_control.atol)
        self.adaptive = ErrorControlledStep(self, self.step_control, h0=sc.coupling.macro_step,
                                            grid=OutputGrid(sc.start_time, sc.stop_time, interval),
                                            can_reject=can_reject, atol=atol)

    def _check_states(self, what: str, why: str, fix: str) -> None:
        """Every FMU must save and restore its state for ``what``; the master will restore."""
        stateless = [u.name for u in self.units if not u.sub.can_get_set_state]
        if stateless:
            raise ScenarioError(
                f"{self._where()}{what} {why}, so every FMU must save and restore its state "
                f"(canGetAndSetFMUstate=\"true\"), but {', '.join(map(repr, stateless))} cannot (got "
                f"canGetAndSetFMUstate false); {fix}, or use an FMU built with state support")
        for u in self.units:
            u.sub.no_set_prior_state = False
        self._no_prior = False

    def _columns(self, units) -> list[str]:
        sig = self.scenario.output.signals
        if sig is None:
            cols = []
            for u in units.values():
                md = getattr(u.sub, "md", None)
                if md is not None:
                    cols += [f"{u.name}.{v.name}" for v in md.outputs() if v.type == "Real"]
                else:
                    cols += [f"{u.name}.{n}" for n in getattr(u.sub, "output_names", ())]
            return cols
        problems = []
        for s in sig:
            if "." not in s or s.split(".", 1)[0] not in units:
                problems.append(f"output signal '{s}': expected '<instance>.<variable>' with an instance in "
                                f"{list(units)}")
                continue
            inst, var = s.split(".", 1)
            try:
                v = units[inst].sub.variable(var)
                if v.type != "Real":
                    problems.append(f"output signal '{s}' is of type {v.type}; record Real variables only")
            except ScenarioError as e:
                problems.append(f"output signal '{s}': {e.problems[0]}")
        if problems:
            raise ScenarioError(problems)
        return list(dict.fromkeys(sig))

    # ------------------------------------------------------------ initialize
    def initialize(self) -> None:
        """FMI 2.0 initialization: setupExperiment, enter init mode, exchange
        initial values (fixed point over feed-through), exit init mode, exchange again."""
        if self._phase != "setup":
            raise LifecycleError(f"initialize() needs setup() first and runs once (phase '{self._phase}')")
        self._phase = "initializing"
        sc = self.scenario
        t0 = self.grid.time(0)
        try:
            for u in self.units:
                u.sub.setup_experiment(t0, sc.stop_time)
            for u in self.units:
                u.sub.enter_initialization_mode()
            self._exchange_initial()
            for u in self.units:
                u.sub.exit_initialization_mode()
            self._exchange_initial()
        except (FmuCallError, CouplingError) as e:
            self._fail(f"initialization failed: {e}; check the FMU's parameters and start values", t0)
            self._phase = "running"
            self.view.is_output = False        # observers start (results.csv gets its header), no row
            for o in self.observers:
                o.on_initialized(self.view)
            return
        self.history.start(t0)
        self.status = Status.RUNNING
        self._phase = "running"
        self.t = t0
        self.end_time = t0
        self._record(t0, 0, True)
        for o in self.observers:
            o.on_initialized(self.view)

    def _exchange_initial(self) -> None:
        """Outputs -> inputs at t0 until they agree (direct feedthrough).

        Plain passes first: a chain of feedthrough FMUs settles exactly in as many
        passes as it is long. If the signals still change after ``len(units) + 1``
        passes there is an algebraic loop: it is solved as the fixed point ``x = G(x)``
        of one exchange (IQN-ILS, coupling/acceleration.py) to the iteration tolerance;
        no convergence raises CouplingError naming the loop (coupling/loops.py).
        """
        store = self.history.store
        t0 = self.grid.time(0)

        def exchange(x=None):
            if x is not None:
                store[0] = x
                self._push_inputs()
            for u in self.units:
                u.sub.get_real(u.outb)
                self._propagate(u, t0)
            return store[0].copy()

        x = exchange()
        for _ in range(len(self.units) + 1):
            g = exchange(x)
            if np.array_equal(g, x):
                return
            x = g
        spec = self.iteration
        res = solve_fixed_point(exchange, x, acceleration=IQNILS(), tol=spec.tol, scale=np.abs(x),
                                max_iterations=max(spec.max_iterations, INIT_LOOP_ITERATIONS))
        if res.converged:
            store[0] = res.x
            self._push_inputs()
            log.info("initial exchange: algebraic loop solved in %d iterations (IQN-ILS, residual %.3g of the "
                     "signals' scale)", res.iterations, res.residual)
            return
        name = self.signal_names[res.worst] if self.signal_names else "?"
        loop = loop_through(self.scenario.connections, name.split(".", 1)[0])
        raise CouplingError(
            f"the initial exchange at t={t0:g} s has an algebraic loop that does not converge: after "
            f"{len(self.units) + 1 + res.iterations} passes (IQN-ILS) the input {name} still changes by "
            f"{res.residual:.3g} of its scale (tol {spec.tol:g}); the loop is "
            f"{', '.join(loop) if loop else 'not a cycle of connections (an FMU output that keeps changing)'}. "
            "The loop's equations have no (or no reachable) solution: check the gains, offsets and the FMUs' "
            "feedthrough in it, or break it with a state (e.g. a first-order lag)")

    def _push_inputs(self) -> None:
        for u in self.units:
            if u.nE + u.nI:
                u.inb.values[:u.nE] = u.HE[0]
                u.inb.values[u.nE:] = u.HI[0]
                u.sub.set_real(u.inb)

    # ------------------------------------------------------------------ step
    def step(self) -> Status:
        """Advance one macro step. Returns the status (RUNNING, FINISHED or FAILED)."""
        if self.status is not Status.RUNNING:
            raise LifecycleError(f"step() called with status {self.status.short}; "
                                 + ("call setup() and initialize() first" if self.status is Status.NOT_STARTED
                                    else "the run is over; read result()"))
        n = self.n
        on_output = False
        if self.adaptive is not None:
            t = self.t
            t_next = min(t + self.adaptive.h, self.scenario.stop_time)      # for messages if the step fails
        else:
            t = self.grid.time(n)
            t_next = self.grid.time(n + 1)
        try:
            if self.adaptive is not None:
                t_next, on_output = self.adaptive.step(t)
            else:
                self._one_step(t, t_next)
        except _RetriesExhausted as x:
            n_h = self.discard_retries
            self._fail(self._fmu_message(x.error, t, t_next)
                       + f". The master restored every FMU's state and retried this macro step with {n_h} "
                       f"halving{'s' if n_h != 1 else ''} of the step (coupling.discard_retries = {n_h}, smallest "
                       f"step {(t_next - t) / 2 ** n_h:g} s); the sub-step from t={x.t_a:.12g} s to "
                       f"t={x.t_b:.12g} s was still discarded. Allow more halvings (a larger "
                       "coupling.discard_retries) or use a smaller coupling.macro_step", t)
            return self.status
        except FmuCallError as e:
            self._fail(self._fmu_message(e, t, t_next), t)
            return self.status
        except CouplingError as e:
            self._fail(str(e), t)
            return self.status
        self.n = n + 1
        self.t = t_next
        self.end_time = t_next
        if self.adaptive is not None:
            last = t_next >= self.scenario.stop_time
            self._record(t_next, self.n, last or on_output)
        else:
            last = self.n >= self.grid.n_steps
            self._record(t_next, self.n, last or self.n % self.stride == 0)
        if last:
            self.status = Status.FINISHED
            self.message = f"finished at t={t_next:g} s after {self.n} macro steps"
        for o in self.observers:
            o.on_step_complete(self.view)
        return self.status

    def _one_step(self, t: float, t_next: float) -> None:
        """The macro step [t, t_next] by the configured scheme (retries, iteration, start-up)."""
        if self.discard_retries:
            self._retry_step(t, t_next)
        elif self.iterative:
            self._iterate(t, t_next)
        elif self._startup_iterations and self.history.count < self.predictor.k:
            self._startup_step(t, t_next)
        else:
            self._step_impl(t, t_next)

    def _rejected(self, t: float, t_end: float, err: float) -> None:
        """An error-controlled attempt [t, t_end] was rejected and rolled back: tell the observers."""
        view = self.view
        view.t = t
        view.is_output = False
        for o in self.observers:
            o.on_step_rejected(view)

    def _startup_step(self, t: float, t_next: float) -> None:
        """A start-up step while the history is shorter than the extrapolation order.

        With only ``count`` past values the extrapolation has order count-1 < k,
        whose error (O(H^(count+1)) in the states after the step) would cap the
        global order below k+1. When every subsystem can save and restore its
        state, the step is repeated ``k`` times from saved states with *all*
        inputs interpolated through the new values of the previous pass (a
        fixed-point iteration that gains one order per pass), so the start-up
        error is O(H^(k+2)) and the full order k+1 is kept.
        """
        hist = self.history
        states = [u.sub.get_state() for u in self.units]
        snap = hist.snapshot()
        for u in self.units:
            u.sub.no_set_prior_state = False      # we will restore the saved state
        try:
            self._step_impl(t, t_next, commit=False)
            q = min(self.predictor.k, hist.count)
            for _ in range(self.predictor.k):
                new_rows = [b[0].copy() for b in hist.blocks]
                for u, s in zip(self.units, states):
                    u.sub.set_state(s)
                hist.restore(snap)
                for b, r in zip(hist.blocks, new_rows):
                    b[0] = r
                self._step_impl(t, t_next, commit=False, startup_q=q)
            hist.commit()
        finally:
            for u in self.units:
                u.sub.no_set_prior_state = self._no_prior
            for u, s in zip(self.units, states):
                try:
                    u.sub.free_state(s)
                except FmuCallError as e:   # pragma: no cover - defensive
                    log.warning("%s", e)

    def _advance(self, t: float, t_next: float) -> None:
        """One ordinary step [t, t_next] (start-up iteration while the history is short)."""
        if self.iterative:
            self._iterate(t, t_next)
        elif self._startup_iterations and self.history.count < self.predictor.k:
            self._startup_step(t, t_next)
        else:
            self._step_impl(t, t_next)

    def _save_states(self) -> list:
        states = []
        try:
            for u in self.units:
                states.append(u.sub.get_state())
        except BaseException:
            self._free_states(states)
            raise
        return states

    def _restore_states(self, states) -> None:
        for u, s in zip(self.units, states, strict=True):
            u.sub.set_state(s)

    def _free_states(self, states) -> None:
        for u, s in zip(self.units, states, strict=False):     # states may be partial
            try:
                u.sub.free_state(s)
            except FmuCallError as e:   # pragma: no cover - defensive
                log.warning("%s", e)

    def _retry_step(self, t: float, t_next: float) -> None:
        """A macro step that may be redone in halves after an fmi2Discard (coupling.discard_retries > 0).

        Saves every FMU's state and the history at ``t``, tries the step; on a
        discard restores both and redoes [t, t_next] as halves (:meth:`_split`).
        The history is then rebuilt so that its newest level is ``t_next`` and
        the older ones are the nominal grid points before the step.
        """
        hist = self.history
        states = self._save_states()
        try:
            snap = hist.snapshot()
            try:
                self._advance(t, t_next)
                return
            except FmuCallError as e:
                if e.status != "discard":
                    raise
                first = e
            self.retried_steps += 1
            self.rejected_steps += 1
            self._retry_depth = 0
            rounds0 = self.retry_substeps
            self._split(t, t_next, 1, states, snap)
            # the sub-steps committed their end points; keep only t_next on the nominal grid
            new_rows = [b[1].copy() for b in hist.blocks]
            hist.restore(snap)
            hist.times[0] = t_next
            for b, r in zip(hist.blocks, new_rows, strict=True):
                b[0] = r
            hist.commit()
            if self.retried_steps <= RETRY_LOG_LINES:
                log.info("FMU instance '%s' discarded the macro step t=%.12g..%.12g s; redone from the saved "
                         "states with %d halving(s) (smallest step %g s, %d extra step rounds)%s", first.instance,
                         t, t_next, self._retry_depth, (t_next - t) / 2 ** self._retry_depth,
                         self.retry_substeps - rounds0,
                         "; further retried macro steps are only counted (statistics: retried_steps)"
                         if self.retried_steps == RETRY_LOG_LINES else "")
        finally:
            self._free_states(states)

    def _split(self, t_a: float, t_b: float, level: int, states_a: list, snap_a) -> None:
        """Restore the FMU states and history at ``t_a`` and do [t_a, t_b] as two halves; a half that
        is discarded again is split further while ``level < discard_retries``."""
        hist = self.history
        for u, s in zip(self.units, states_a, strict=True):
            u.sub.set_state(s)
        hist.restore(snap_a)
        self._retry_depth = max(self._retry_depth, level)
        t_m = t_a + 0.5 * (t_b - t_a)
        deepest = level >= self.discard_retries
        for a, b in ((t_a, t_m), (t_m, t_b)):
            if a == t_a or deepest:
                st, sn = states_a, snap_a        # first half starts from the restored state; deepest: no reuse
            else:
                st, sn = self._save_states(), hist.snapshot()
            try:
                self.retry_substeps += 1
                try:
                    self._advance(a, b)
                except FmuCallError as e:
                    if e.status != "discard":
                        raise
                    if deepest:
                        raise _RetriesExhausted(e, a, b) from e
                    self.rejected_steps += 1
                    self._split(a, b, level + 1, st, sn)
            finally:
                if st is not states_a:
                    self._free_states(st)

    def _step_impl(self, t: float, t_next: float, *, commit: bool = True, startup_q: int | None = None) -> None:
        h = t_next - t
        hist = self.history
        hist.times[0] = t_next
        # weights depend only on the order available and the step sizes of the
        # levels used: reuse them while those are unchanged (constant steps)
        ts = hist.times.tolist()
        d = (ts[0] - ts[1], ts[1] - ts[2], ts[2] - ts[3], ts[3] - ts[4])
        lk = self._wkey
        if (lk is not None and lk[0] == hist.count and lk[1] == startup_q
                and abs(d[0] - lk[2]) + abs(d[1] - lk[3]) + abs(d[2] - lk[4]) + abs(d[3] - lk[5]) <= 1e-9 * h):
            cache = self._wcache
        else:
            cache = self._wcache = {}
            self._wkey = (hist.count, startup_q, *d)
        predictor = self.predictor
        for u in self.units:
            sub = u.sub
            m = u.substeps
            w = cache.get(m)
            if w is None:
                w = cache[m] = predictor.weights(hist, t, h, m, q=startup_q, all_interp=startup_q is not None)
            nE, nI = u.nE, u.nI
            vals = u.inb.values
            hs = h / m
            if u.derb is None:
                if nE or nI:
                    HE = u.HE[w.e0:w.e1]
                    HI = u.HI[0:w.q + 1]
                    for i in range(m):
                        if nE:
                            np.dot(w.extrap[i], HE, out=vals[:nE])
                        if nI:
                            np.dot(w.interp[i], HI, out=vals[nE:])
                        sub.set_real(u.inb)
                        sub.do_step(t + i * hs, hs)
                    if not ((w.end_same_e or not nE) and (w.end_same_i or not nI)):
                        if nE:
                            np.dot(w.extrap_end, HE, out=vals[:nE])
                        if nI:
                            np.dot(w.interp_end, HI, out=vals[nE:])
                        sub.set_real(u.inb)
                else:
                    for i in range(m):
                        sub.do_step(t + i * hs, hs)
            else:
                HE = u.HE[w.e0:w.e1]
                HI = u.HI[0:w.q + 1]
                der = u.derb.values.reshape(MAX_ORDER, nE + nI)
                for i in range(m):
                    if nE:
                        np.dot(w.extrap_start[i], HE, out=vals[:nE])
                        der[:, :nE] = w.extrap_der[i] @ HE
                    if nI:
                        np.dot(w.interp_start[i], HI, out=vals[nE:])
                        der[:, nE:] = w.interp_der[i] @ HI
                    sub.set_real(u.inb)
                    sub.set_real_input_derivatives(u.derb)
                    sub.do_step(t + i * hs, hs)
                if nE:
                    np.dot(w.extrap_end, HE, out=vals[:nE])
                if nI:
                    np.dot(w.interp_end, HI, out=vals[nE:])
                sub.set_real(u.inb)
            sub.get_real(u.outb)
            self._propagate(u, t_next)
        if commit:
            hist.commit()

    def _propagate(self, u: _Unit, t: float) -> None:
        out = u.outb.values
        for lk in u.links:
            if lk.small is not None:       # few signals: plain Python floats are faster than numpy calls
                row = lk.row0
                for p, c, g, o in lk.small:
                    x = float(out[p]) * g + o
                    if x - x != 0.0:
                        self._nonfinite(u, lk, lk.names[lk.small.index((p, c, g, o))], x, t)
                    row[c] = x
                continue
            v = lk.tmp
            out.take(lk.pos, out=v)
            if not lk.identity:
                v *= lk.gain
                v += lk.offset
            if not math.isfinite(v.sum()):          # NaN or inf somewhere (cheap test first)
                bad = [i for i in range(len(v)) if not math.isfinite(v[i])]
                if bad:
                    self._nonfinite(u, lk, lk.names[bad[0]], v[bad[0]], t)
            lk.block[0, lk.cols] = v

    def _nonfinite(self, u: _Unit, lk: _Link, name: str, value: float, t: float):
        raise CouplingError(
            f"coupling signal {name} is {float(value)} at t={t:.12g} s (output of '{u.name}'); "
            "the coupled system is probably unstable at this macro step or the FMU failed silently. "
            f"Try a smaller coupling.macro_step (now {self.scenario.coupling.macro_step:g}), a lower "
            "extrapolation_order, or the gauss-seidel scheme")

    # ---------------------------------------------------------------- helpers
    def _fmu_message(self, e: FmuCallError, t: float, t_next: float) -> str:
        what = {"discard": "could not complete the step (fmi2Discard)",
                "error": "reported an error (fmi2Error)",
                "fatal": "reported a fatal error (fmi2Fatal; PythonFMU reports Python exceptions this way)",
                "exception": "raised an exception"}.get(e.status, f"returned {e.status}")
        return (f"FMU instance '{e.instance}' {what} in {e.function} during the macro step from t={t:.12g} s to "
                f"t={t_next:.12g} s ({e}). Rows up to t={t:.12g} s are kept. Follow the fix the FMU's message "
                "gives, if any; a numerically unstable coupling shows up the same way, so also try a smaller "
                f"coupling.macro_step (now {self.scenario.coupling.macro_step:g}) or more substeps for "
                f"'{e.instance}', and check the FMU's log above")

    def _fail(self, message: str, t: float) -> None:
        self.status = Status.FAILED
        self.message = message
        self.end_time = t
        self.view.status = self.status
        self.view.message = message
        log.error("%s", message)

    def _record(self, t: float, n: int, is_output: bool) -> None:
        view = self.view
        view.t = t
        view.n = n
        view.end_time = t
        view.is_output = is_output
        view.status = self.status
        if is_output:
            row = view.row
            for values, pos, cols in self._rec:
                row[cols] = values[pos]

    # ------------------------------------------------------------- terminate
    def terminate(self) -> None:
        """fmi2Terminate and fmi2FreeInstance for every subsystem (always), then
        tell the observers. Idempotent."""
        if self._phase in ("terminated", "new"):
            return
        if self.status is Status.RUNNING:
            self._fail(f"terminated early at t={self.t:.12g} s by the caller", self.t)
        self.view.status = self.status
        self.view.message = self.message
        self.view.end_time = self.end_time
        if self.retried_steps:
            log.info("%d macro step(s) were redone in smaller steps after an fmi2Discard (%d extra step rounds, "
                     "%d rejected attempts)%s", self.retried_steps, self.retry_substeps, self.rejected_steps,
                     f"; only the first {RETRY_LOG_LINES} were logged" if self.retried_steps > RETRY_LOG_LINES else "")
        try:
            for u in getattr(self, "units", []):
                try:
                    u.sub.terminate()
                except FmuCallError as e:
                    log.warning("%s", e)
        finally:
            self._release()
            self._phase = "terminated"
            self.wall_time = _time.perf_counter() - self._t_wall0
            for o in self.observers:
                o.on_terminated(self.view)

    def _release(self) -> None:
        for sub in self.subsystems.values():
            try:
                sub.free()
            except Exception as e:   # pragma: no cover - defensive
                log.warning("freeing '%s' failed: %s", sub.name, e)
        if self._work_dir:
            shutil.rmtree(self._work_dir, ignore_errors=True)
            self._work_dir = None

    # ---------------------------------------------------------------- result
    def statistics(self) -> dict:
        """``rejected_steps``: (sub-)step attempts discarded by an FMU and rolled back;
        ``retried_steps``: macro steps redone in smaller steps; ``retry_substeps``: the extra
        step rounds (sub-intervals attempted) of those retries (all 0 without discard_retries)."""
        st = {"macro_steps": self.n, "rejected_steps": self.rejected_steps, "retried_steps": self.retried_steps,
              "retry_substeps": self.retry_substeps, "wall_time_s": self.wall_time,
              "fmu_calls": {name: sub.statistics() for name, sub in self.subsystems.items()}}
        if self.iterative and hasattr(self, "_iterate"):
            st["iterations"] = self._iterate.stats.as_dict()
        if self.adaptive is not None:
            st["step_control"] = self.adaptive.statistics()
        return st

    def result(self) -> CoSimResult:
        t, outputs = self.recorder.arrays()
        return CoSimResult(status=self.status, message=self.message, t=t, outputs=outputs,
                           stats=self.statistics(), out_dir=self.out_dir, end_time=self.end_time)

    def run(self) -> CoSimResult:
        """setup (if needed), initialize, step until done, terminate; return the result."""
        try:
            if self._phase == "new":
                self.setup()
            if self._phase == "setup":
                self.initialize()
            while self.status is Status.RUNNING:
                if self.interrupt_requested:
                    raise KeyboardInterrupt
                self.step()
        finally:
            self.terminate()
        return self.result()
