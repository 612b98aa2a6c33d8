"""The execution of a co-simulation: life cycle, observers and result of the master.

Call order::

    m = MasterAlgorithm(scenario, out_dir=..., observers=[...])
    m.setup()          # load FMUs (checked, extracted), set parameters, precompute the plan
    m.initialize()     # FMI 2.0 initialization and exchange of initial outputs
    while m.status is Status.RUNNING:
        m.step()       # one macro step; numerical failure -> Status.FAILED (no exception)
    m.terminate()      # fmi2Terminate + fmi2FreeInstance for every FMU, observers told
    res = m.result()

:meth:`MasterAlgorithm.run` does exactly that. Bad input and misuse raise (ScenarioError,
FmuError, LifecycleError); a failure *during* the run (an FMU returning
Discard/Error/Fatal or raising, a NaN/inf in a coupling signal) makes the
status FAILED with a message that names what, where and what to try.

The pieces: the plan (:mod:`.plan`: units, links, sequence), one macro step
(:mod:`.macro_step`, inputs delivered by a per-unit policy of :mod:`.delivery`), the
step-size controller (:mod:`.step_control`: the grid, accept / reject / retry, the
discard halving), the scheme (:mod:`.schemes`), the Lagrange history (:mod:`.signals`)
and the observers (:mod:`.observers`). docs/dev/architecture.md gives the call order.

Length: the life cycle of one execution (setup, initialization with its initial exchange,
stepping with its failure paths, termination and the result) is one state machine whose
methods share the FMU handles and the status; the numerics live in the modules above, so
the file stays above ~400 lines for that reason.
"""

from __future__ import annotations

import logging
import math
import os
import time as _time
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from orchestrator.coupling.defect import LIMIT as DEFECT_LIMIT, DefectMonitor
from orchestrator.coupling.macro_step import MacroStep
from orchestrator.coupling.observers import Observer, Recorder, RunView, check_observers
from orchestrator.coupling.plan import make_plan
from orchestrator.coupling.schemes import CouplingScheme, scheme_from_spec
from orchestrator.coupling.acceleration import IQNILS, solve_fixed_point
from orchestrator.coupling.iterative import IterativeMacroStep
from orchestrator.coupling.loops import loop_through, signal_loop
from orchestrator.coupling.signals import LagrangePredictor
from orchestrator.coupling.step_control import (
    RETRY_LOG_LINES, ConstantStep, RetriesExhausted, StepSizeController)
from orchestrator.coupling.adaptive import controller_from_spec
from orchestrator.coupling.signal_scales import jacobian_groups, signal_nominals
from orchestrator.coupling.stages import stages as make_stages
from orchestrator.coupling.threads import StageThreads
from orchestrator.errors import CouplingError, FmuCallError, FmuCrashError, LifecycleError, ScenarioError
from orchestrator.fmi.extraction import ExtractionPool
from orchestrator.fmi.subsystem import Subsystem, SubsystemBase
from orchestrator.fmi.worker import WorkerSubsystem
from orchestrator.results.result import CoSimResult, Status
from orchestrator.results.writer import TimeGrid
from orchestrator.scenario.completion import fixed_step_problem
from orchestrator.scenario.model import MAX_DISCARD_RETRIES

log = logging.getLogger(__name__)

INIT_LOOP_ITERATIONS = 50         # IQN-ILS iterations for an algebraic loop in the initial exchange


def variable_step_ok(sub) -> bool:
    """canHandleVariableCommunicationStepSize of a subsystem (fakes without a model description: True)."""
    md = getattr(sub, "md", None)
    if md is not None and hasattr(md, "can_handle_variable_step"):
        return bool(md.can_handle_variable_step)
    return bool(getattr(sub, "can_handle_variable_step", True))


def plan_units_in_store_order(scenario, units) -> list:
    """The units in the order of the history store's columns (the scenario's FMU order, plan.py)."""
    by_name = {u.name: u for u in units}
    return [by_name[f.name] for f in scenario.fmus]


class MasterAlgorithm:
    """Explicit co-simulation master (see the module docstring for the call order).

    Parameters
    ----------
    scenario : orchestrator.scenario.Scenario
    out_dir : run directory (for ``{out_dir}`` in String parameters); may be None.
    observers : Observer objects (CSV writer, progress, ...); a Recorder is always added.
    subsystems : optional ``{name: SubsystemBase}`` to use instead of loading the
        scenario's FMUs (tests use plain-Python fakes); the master still frees them.
    scheme, step_size, predictor : policy objects; default from ``scenario.coupling``
        (``step_size``: a :class:`~orchestrator.coupling.step_control.StepSizeController`).
    record_in_memory : keep the output rows for :meth:`result` (False: the caller streams them to
        a file and reads them back, so memory stays flat in the number of rows).
    """

    def __init__(self, scenario, *, out_dir: Path | str | None = None, observers: Sequence[Observer] = (),
                 subsystems: Mapping[str, SubsystemBase] | None = None, scheme: CouplingScheme | None = None,
                 step_size: StepSizeController | None = None, predictor: LagrangePredictor | None = None,
                 record_in_memory: bool = True):
        from orchestrator.scenario.model import Scenario
        if not isinstance(scenario, Scenario):
            raise TypeError(f"MasterAlgorithm() takes a Scenario from load_scenario() (got {type(scenario).__name__} "
                            f"{scenario!r:.60}); write MasterAlgorithm(load_scenario('file.yaml'))")
        self.scenario = scenario
        c = scenario.coupling
        self.out_dir = Path(out_dir) if out_dir is not None else None
        self.scheme = scheme or scheme_from_spec(c.scheme, c.sequence)
        n_retry = getattr(c, "discard_retries", 0)
        if isinstance(n_retry, bool) or not isinstance(n_retry, int) or not 0 <= n_retry <= MAX_DISCARD_RETRIES:
            raise ScenarioError(f"{self._where()}coupling.discard_retries must be an integer between 0 and "
                                f"{MAX_DISCARD_RETRIES} (got {n_retry!r}); use 0 (stop on fmi2Discard) or the "
                                "number of step halvings to try, e.g. 3")
        self.discard_retries = n_retry
        self.grid = step_size or controller_from_spec(scenario)
        self.grid.on_rejected = self._rejected
        self.predictor = predictor or LagrangePredictor(extrapolation_order=c.extrapolation_order,
                                                        interpolation_order=c.interpolation_order)
        self.recorder = Recorder(keep=record_in_memory)
        self.observers = [self.recorder, *check_observers(observers, "MasterAlgorithm(observers=...)")]
        self._given = dict(subsystems) if subsystems is not None else None
        self.subsystems: dict[str, SubsystemBase] = {}
        self.status = Status.NOT_STARTED
        self.message = ""
        # set (e.g. by a SIGINT handler, see orchestrator.run) to stop cleanly between macro
        # steps: run() then raises KeyboardInterrupt from master code, never inside an FMU
        self.interrupt_requested = False
        # called once by terminate() after fmi2Terminate and the observers, before fmi2FreeInstance
        # (orchestrator.workflow writes the final summary.json there)
        self.before_release = None
        # orchestrator.fmi.call_record.CallRecord of the run folder (set by orchestrator.workflow):
        # which FMI call each FMU in this process is in, readable after a crash of the process
        self.call_record = None
        self.n = 0
        self.t = float(scenario.start_time)
        self.end_time = float(scenario.start_time)
        self.wall_time = 0.0
        self._work_dir: ExtractionPool | None = None
        self._pool: StageThreads | None = None   # coupling.parallel: threads (kept after close: its count)
        self.isolation: dict[str, str] = {}      # instance -> "process" | "none" (FMUs the master loaded)
        self.failure: dict | None = None         # what failed (summary.json "failure"), see _fail_fmu
        self._phase = "new"
        self._t_wall0 = 0.0
        self.defect: DefectMonitor | None = None  # the interface-Jacobian forces' defect (coupling/defect.py)

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
                from orchestrator.scenario.limits import max_worker_processes
                in_workers = [f.name for f in sc.fmus
                              if (getattr(f, "isolation", None) or getattr(sc.coupling, "isolation", "none")) == "process"]
                limit = max_worker_processes()
                if len(in_workers) > limit:
                    raise ScenarioError(f"{self._where()}{len(in_workers)} FMU instances run in worker processes "
                                        f"(isolation: process), more than {limit} at once (each is a Python process "
                                        "of about 35 MB); run fewer in processes (fmus.<name>.isolation: none) or "
                                        "raise the limit with the environment variable ROTORCOSIM_MAX_WORKERS=N")
                self._work_dir = ExtractionPool()      # one extraction per FMU file, shared
                for f in sc.fmus:
                    self.subsystems[f.name] = self._load(f)
                for sub in self.subsystems.values():   # the workers started side by side
                    if isinstance(sub, WorkerSubsystem):
                        sub.ready()
            for f in sc.fmus:
                try:
                    self.subsystems[f.name].set_parameters(dict(f.parameters), out_dir=self.out_dir)
                except FmuCallError as e:
                    hint = self._origins_hint(e)
                    if hint:
                        e.args = (f"{e.args[0] if e.args else e}{hint}",) + tuple(e.args[1:])
                    raise
            self._plan()
        except BaseException:
            self._release()
            self._phase = "terminated"      # nothing left to terminate; observers never started
            raise

    def _load(self, f) -> SubsystemBase:
        """The adapter of FMU instance ``f``: in this process, or in a worker (``isolation: process``)."""
        c = self.scenario.coupling
        mode = getattr(f, "isolation", None) or getattr(c, "isolation", "none")
        self.isolation[f.name] = mode
        if mode == "process":
            # the worker extracts its own copy under this run's extraction folder (removed with it)
            cpu = self._next_cpu()
            return WorkerSubsystem(f.name, f.path, work_dir=self._work_dir.root / "workers",
                                   call_timeout=getattr(c, "call_timeout", None), wait=False, cpu=cpu,
                                   spin=None if cpu is None or self._cpu_left() else 0.0)
        rec = self.call_record
        return Subsystem(f.name, f.path, extraction=self._work_dir,
                         call_slot=rec.slot(f.name) if rec is not None else None)

    def _cpu_left(self) -> bool:
        """Is a CPU left for the master beside the pinned workers? Only then may they and the
        master poll instead of sleeping (orchestrator.fmi.channel.WorkerChannel.spin)."""
        c = self.scenario.coupling
        n = sum(1 for f in self.scenario.fmus
                if (getattr(f, "isolation", None) or getattr(c, "isolation", "none")) == "process")
        return n < len(os.sched_getaffinity(0))

    def _next_cpu(self) -> int | None:
        """``coupling.pin_workers``: the CPU of the next worker, round robin over the CPUs this
        process may use (os.sched_getaffinity), in the order of ``fmus``; else None."""
        if not getattr(self.scenario.coupling, "pin_workers", False) or not hasattr(os, "sched_getaffinity"):
            return None
        cpus = sorted(os.sched_getaffinity(0))
        k = sum(1 for s in self.subsystems.values() if isinstance(s, WorkerSubsystem))
        return cpus[k % len(cpus)]

    def _stages(self) -> list:
        """(stage, members in stepping order, members to step concurrently or None) per stage of the
        connection graph (orchestrator.coupling.stages); concurrently when ``coupling.parallel`` and a
        member runs in a worker process, workers first (they compute while in-process members step)."""
        links = [(c.src_instance, c.dst_instance) for c in self.scenario.connections]
        by_name = {u.name: u for u in self.units}
        parallel = self._parallel()
        threads = self._threads()
        out = []
        for st in make_stages([u.name for u in self.units], links, self.scheme.uses_new_value):
            members = [by_name[n] for n in st.names]
            workers = [u for u in members if isinstance(u.sub, WorkerSubsystem)]
            together = workers + [u for u in members if u not in workers] if workers and len(members) > 1 else None
            # parallel: threads, a stage of FMUs all in this process: each member in a thread
            threaded = threads and len(members) > 1 and not workers
            out.append((st, members, together if parallel else None, threaded))
        return out

    def _threads(self) -> bool:
        """``coupling.parallel: threads`` (orchestrator.coupling.threads)."""
        return getattr(self.scenario.coupling, "parallel", True) == "threads"

    def _stage_threads(self, stages: list):
        """The thread pool of the stages stepped in threads, or None when there are none."""
        n = max((len(m) - 1 for _, m, _, threaded in stages if threaded), default=0)
        if n == 0:
            return None
        self._pool = StageThreads(n)
        return self._pool

    def _plan(self) -> None:
        plan = make_plan(self.scenario, self.subsystems, self.scheme)
        self.plan = plan
        self.order, self.units, self.history = plan.order, plan.units, plan.history
        self.columns, self._rec, self.stride = plan.columns, plan.rec, plan.stride
        self.kinds, self._rec_typed, self.discrete = plan.kinds, plan.rec_typed, plan.discrete
        k = self.predictor.k
        can_state = all(u.sub.can_get_set_state for u in self.units)
        startup = k >= 2 and can_state
        if k >= 2 and not can_state:
            log.info("extrapolation_order %d: not every FMU can save its state (canGetAndSetFMUstate), so the "
                     "first %d macro steps use lower-order extrapolation; this adds an O(H^2) start-up error "
                     "(see docs/coupling.md)", k, k - 1)
        fixed = [u.name for u in self.units if getattr(getattr(u.sub, "md", None), "can_handle_variable_step", True)
                 is False]
        if isinstance(self.grid, ConstantStep):
            why = fixed_step_problem(self.grid.t0, self.grid.t_stop, self.grid.h, fixed, self.discard_retries,
                                     getattr(self.grid, "defect_halvings", 0))
            if why:
                raise ScenarioError(f"{self._where()}{why}")
        if self.grid.needs_states:
            stateless = [u.name for u in self.units if not u.sub.can_get_set_state]
            if stateless:
                key = ("discard_retries" if self.discard_retries or not getattr(self.grid, "defect_halvings", 0)
                       else "defect_retries")
                n = self.discard_retries if key == "discard_retries" else self.grid.defect_halvings
                raise ScenarioError(
                    f"{self._where()}coupling.{key} = {n} needs every FMU to save and "
                    f"restore its state (canGetAndSetFMUstate=\"true\"), but {', '.join(map(repr, stateless))} "
                    f"cannot (got canGetAndSetFMUstate false); set coupling.{key}: 0 or use an FMU "
                    "built with state support")
            for u in self.units:
                u.sub.no_set_prior_state = False    # we may restore the state saved before each macro step
        # noSetFMUStatePriorToCurrentPoint for every doStep: False while the master may restore a state
        self.signal_names = [f"{u.name}.{n}" for u in plan_units_in_store_order(self.scenario, self.units)
                             for n in u.ext_names + u.int_names]
        stages = self._stages()
        kw = dict(macro_step=self.scenario.coupling.macro_step, startup_iterations=startup,
                  no_prior=not self.grid.needs_states, stages=stages,
                  threads=self._stage_threads(stages))
        c = self.scenario.coupling
        if c.scheme == "iterative":
            self._require_states("coupling.scheme = iterative repeats every macro step from the saved states",
                                 "use scheme gauss-seidel or jacobi")
            kw.update(startup_iterations=False, no_prior=False)
            held = ([kc for _, terms in jacobian_groups(self.signal_names, self.scenario.connections)
                     for kc, _, _ in terms] if c.iteration.hold_jacobian else [])
            self.stepper = IterativeMacroStep(plan, self.predictor, spec=c.iteration,
                                              signal_names=self.signal_names, held=held, **kw)
        else:
            self.stepper = MacroStep(plan, self.predictor, **kw)
        watch = tuple(getattr(c, "defect_signals", ()) or ())
        # step_control.until (adaptive.ErrorThenConstant): error-controlled, then constant steps, which the
        # defect monitor watches (and defect_retries redoes) as any constant step
        phased = getattr(self.grid, "constant", None) is not None
        if getattr(self.grid, "variable", False):
            self._setup_variable_grid()
        if (phased or not getattr(self.grid, "variable", False)) and c.scheme != "iterative":
            ext = {f"{u.name}.{n}" for u in self.units for n in u.ext_names}
            mon = DefectMonitor(self.signal_names, ext, self.scenario.connections, k=k, unit_of=self._unit_of,
                                limit=getattr(c, "defect_limit", DEFECT_LIMIT), macro_step=c.macro_step,
                                signals=watch)
            if mon.unmatched:
                inputs = [n for n in self.signal_names if n in ext]
                raise ScenarioError(
                    f"{self._where()}coupling.defect_signals: {', '.join(map(repr, mon.unmatched))} match"
                    f"{'es' if len(mon.unmatched) == 1 else ''} no coupling input that its consumer receives "
                    f"extrapolated (got {len(inputs)} such inputs: {', '.join(inputs[:8])}"
                    f"{', ...' if len(inputs) > 8 else ''}); name a connection's 'to' (consumer.input) or a "
                    "pattern such as 'rotor.F*' (inputs a Gauss-Seidel consumer receives after their producer "
                    "stepped are interpolated, not predicted: they have no defect)")
            self.defect = mon or None
            if self.defect is not None and getattr(self.grid, "defect_halvings", 0):
                self.grid.defect = mon         # the controller judges every (sub-)step (coupling.defect_retries)
                mon.halvings = self.grid.defect_halvings
        if getattr(self.grid, "defect_halvings", 0) and getattr(self.grid, "defect", None) is None:
            log.warning("coupling.defect_retries = %d has nothing to judge: no coupling input is monitored (forces "
                        "with interface-Jacobian coefficients, or coupling.defect_signals); only discarded steps are "
                        "redone", self.grid.defect_halvings)
        if watch and self.defect is None:
            log.warning("coupling.defect_signals is not used with %s: %s", "the error-controlled step" if getattr(
                self.grid, "variable", False) else "scheme iterative", "that step has its own estimate")
        g = self.grid
        tgrid = TimeGrid(g.t0, g.h, t_stop=g.t_stop, n_stop=g.n_steps) if isinstance(g, ConstantStep) else None
        self.view = RunView(self.columns, g.time(0), g.time(g.n_steps), g.n_steps, kinds=self.kinds, grid=tgrid)

    def _require_states(self, what: str, fix: str) -> None:
        stateless = [u.name for u in self.units if not u.sub.can_get_set_state]
        if stateless:
            raise ScenarioError(
                f"{self._where()}{what}, so every FMU must save and restore its state "
                f"(canGetAndSetFMUstate=\"true\"), but {', '.join(map(repr, stateless))} cannot (got "
                f"canGetAndSetFMUstate false); {fix}, or use an FMU built with state support")
        for u in self.units:
            u.sub.no_set_prior_state = False

    def _variable_or_none(self, instance: str, name: str):
        """``instance``'s variable ``name`` (its model description), or None if it has none."""
        u = next((u for u in self.units if u.name == instance), None)
        try:
            return None if u is None else u.sub.variable(name)
        except Exception:          # a fake without a model description, or an unknown name
            return None

    def _unit_of(self, column: str) -> str | None:
        """The declared unit of the input ``instance.variable`` (its own or its type's), or None."""
        inst, _, name = column.partition(".")
        v = self._variable_or_none(inst, name)
        return getattr(v, "unit", None) or None

    def _setup_variable_grid(self) -> None:
        """The error-controlled step (coupling/adaptive.py): FMUs with a fixed step are refused;
        without state save/restore in every FMU the step adapts forward only."""
        fixed = [u.name for u in self.units if not variable_step_ok(u.sub)]
        if fixed:
            raise ScenarioError(
                f"{self._where()}coupling.step_control type error varies the macro step, but "
                f"{', '.join(map(repr, fixed))} cannot take varying steps (canHandleVariableCommunicationStepSize "
                "false); use step_control type constant")
        can_reject = all(u.sub.can_get_set_state for u in self.units)
        self.grid.can_reject = can_reject
        self.grid.bind(self.signal_names, self.scenario.connections,
                       signal_nominals(self.signal_names, self.scenario.connections, self._variable_or_none))
        if can_reject:
            for u in self.units:
                u.sub.no_set_prior_state = False
            self.stepper.no_prior = False
        else:
            log.warning("coupling.step_control type error: %s cannot restore a saved state, so no macro step "
                        "is rejected: the step adapts forward only",
                        ", ".join(repr(u.name) for u in self.units if not u.sub.can_get_set_state))

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
            if isinstance(e, FmuCrashError):
                self.failure = e.report()
            self._fail(f"initialization failed: {e}; check the FMU's parameters and start values"
                       f"{self._origins_hint(e)}", t0)
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
        of one exchange (IQN-ILS, coupling/acceleration.py) to ``coupling.iteration.tol``;
        no convergence raises CouplingError naming the loop (coupling/loops.py).
        """
        store = self.history.store
        t0 = self.grid.time(0)
        workers = [u for u in self.units if isinstance(u.sub, WorkerSubsystem)] if self._parallel() else None
        # (read while the others compute: results as one read after the other, MacroStep.read_outputs)

        def exchange(x=None):
            if x is not None:
                store[0] = x
                self._push_inputs()
            if self.discrete.active:
                self.discrete.exchange_all()
            self.stepper.read_outputs(t0, workers)
            return store[0].copy()

        x = exchange()
        for _ in range(len(self.units) + 1):
            d_before = self.discrete.snapshot() if self.discrete.active else ()
            g = exchange(x)
            d_after = self.discrete.snapshot() if self.discrete.active else ()
            if np.array_equal(g, x) and all(np.array_equal(a, b) for a, b in zip(d_before, d_after)):
                return
            x = g
        spec = self.scenario.coupling.iteration
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
        feed = {u.name: _declared_feedthrough(u.sub) for u in self.units}
        declared = signal_loop(self.scenario.connections, name, feed) if loop else None
        if declared:
            loop = declared + ["(the FMUs' declared direct dependencies, ModelStructure)"]
        elif declared == []:
            loop = loop + ["though the FMUs' declared direct dependencies (ModelStructure) close no cycle through "
                           f"{name}: an output changes that should not depend on these inputs"]
        raise CouplingError(
            f"the initial exchange at t={t0:g} s has an algebraic loop that does not converge: after "
            f"{len(self.units) + 1 + res.iterations} passes (IQN-ILS) the input {name} still changes by "
            f"{res.residual:.3g} of its scale (tol {spec.tol:g}); the loop is "
            f"{', '.join(loop) if loop else 'not a cycle of connections (an FMU output that keeps changing)'}. "
            "The loop's equations have no (or no reachable) solution: check the gains, offsets and the FMUs' "
            "feedthrough in it, or break it with a state (e.g. a first-order lag)")

    def _parallel(self) -> bool:
        return bool(getattr(self.scenario.coupling, "parallel", True))

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
        grid = self.grid
        variable = getattr(grid, "variable", False)
        on_output = False
        if variable:
            t = self.t
            t_next = min(t + grid.h, self.scenario.stop_time)      # for messages if the step fails
        else:
            t = grid.time(n)
            t_next = grid.time(n + 1)
        try:
            if variable:
                t_next, on_output = grid.take_variable_step(self.stepper, t)
                if not grid.variable:          # step_control.until reached: constant steps from here
                    self._switched_to_constant()
            elif self.defect is not None and getattr(grid, "defect", None) is None:
                mon, retried, st = self.defect, getattr(grid, "retried_steps", 0), self.stepper
                startup = st.starting()        # iterated from saved states: it integrated no prediction
                mon.before(st.history, t, t_next)
                grid.take_step(st, t, t_next)
                mon.after(st.history, t_next, skip=startup or getattr(grid, "retried_steps", 0) != retried)
            else:
                grid.take_step(self.stepper, t, t_next)
        except RetriesExhausted as x:
            n_h = self.discard_retries
            self._fail(self._fmu_message(x.error, t, t_next)
                       + f". The master restored every FMU's state and retried this macro step with {n_h} "
                       f"halving{'s' if n_h != 1 else ''} of the step (coupling.discard_retries = {n_h}, smallest "
                       f"step {(t_next - t) / 2 ** n_h:g} s); the sub-step from t={x.t_a:.12g} s to "
                       f"t={x.t_b:.12g} s was still discarded. Allow more halvings (a larger "
                       "coupling.discard_retries) or use a smaller coupling.macro_step", t)
            return self.status
        except FmuCallError as e:
            if self.stepper.fmu_ended(e):
                return self._stopped_by_fmu(e.instance, t)
            self._fail_fmu(e, t, t_next)
            return self.status
        except CouplingError as e:
            self._fail(str(e), t)
            return self.status
        self.n = n + 1
        self.t = t_next
        self.end_time = t_next
        if variable:
            last = t_next >= self.scenario.stop_time
            self._record(t_next, self.n, last or on_output)
        else:
            last = self.n >= self.grid.n_steps
            self._record(t_next, self.n, last or grid.is_output(self.n, self.stride))
        if last:
            self.status = Status.FINISHED
            self.message = f"finished at t={t_next:g} s after {self.n} macro steps"
            note = grid.over_tolerance_note()
            if note:
                self.message += f"; {note}"
                log.warning("%s", note)
        for o in self.observers:
            o.on_step_complete(self.view)
        return self.status

    def _switched_to_constant(self) -> None:
        """``step_control.until`` reached (adaptive.ErrorThenConstant): the rows after it take their
        time from the constant grid's index (as a constant-step run's), the progress its step count."""
        g = self.grid
        c = g.constant
        self.view.grid = _ShiftedGrid(TimeGrid(c.t0, c.h, t_stop=c.t_stop, n_stop=c.n_steps), g.n_offset)
        self.view.n_steps = g.n_steps

    def _rejected(self, t_a: float, t_b: float, error: Exception) -> None:
        """The controller rolled back the attempt [t_a, t_b]: tell the observers (row unchanged)."""
        view = self.view
        view.rejected = (t_a, t_b, str(error))
        for o in self.observers:
            o.on_step_rejected(view)
        view.rejected = None

    # ---------------------------------------------------------------- helpers
    def _stopped_by_fmu(self, instance: str, t: float) -> Status:
        """Finish cleanly at ``t`` (the last communication point every FMU completed): rows kept, no retry."""
        self.status = Status.STOPPED_BY_FMU
        self.message = (f"FMU instance '{instance}' ended the simulation at t={t:.12g} s (fmi2DoStep returned "
                        f"fmi2Discard and fmi2GetBooleanStatus(fmi2Terminated) is true) after {self.n} macro steps; "
                        f"rows up to t={t:.12g} s are kept")
        self.end_time = t
        self.view.status = self.status
        self.view.message = self.message
        log.info("%s", self.message)
        return self.status

    def _fmu_message(self, e: FmuCallError, t: float, t_next: float) -> str:
        what = {"discard": "could not complete the step (fmi2Discard)",
                "error": "reported an error (fmi2Error)",
                "fatal": "reported a fatal error (fmi2Fatal; PythonFMU reports Python exceptions this way)",
                "exception": "raised an exception",
                "pending": "returned fmi2Pending (an asynchronous step)"}.get(e.status, f"returned {e.status}")
        head = (f"FMU instance '{e.instance}' {what} in {e.function} during the macro step from t={t:.12g} s to "
                f"t={t_next:.12g} s ({e}). Rows up to t={t:.12g} s are kept. ")
        if e.status == "pending":      # not numerics: whatever the macro step
            return head + ("rotorcosim does not run asynchronous steps (fmi2Pending, FMI 2.0 sec. 4.2.3), whatever "
                           "the macro step: ask the FMU's maker for an FMU whose fmi2DoStep completes before it "
                           "returns, or replace the FMU")
        if e.status == "no state" or e.status.startswith("illegal status"):
            # a status code FMI 2.0 does not have, or no state although fmi2OK
            return head + ("This breaks the FMI 2.0 standard (sec. 2.1.3, 2.1.8), whatever the macro step: "
                           "report it to the FMU's maker with the FMU's log above, or replace the FMU")
        if "not a coupling instability" in str(e):     # the FMU named a cause no macro step changes
            return head + ("Follow the fix the FMU's message gives: it names a cause (an input or parameter "
                           "value) that a smaller coupling.macro_step or more substeps do not change")
        return head + ("Follow the fix the FMU's message gives, if any; a numerically unstable coupling shows up "
                       f"the same way, so also try a smaller coupling.macro_step (now "
                       f"{self.scenario.coupling.macro_step:g}) or more substeps for '{e.instance}', and check the "
                       "FMU's log above")

    def _origins_hint(self, e: Exception) -> str:
        """``"; 'bearing1' gets p_feed from file:21 and p0 from file:20"`` for the parameters of the failing
        instance that its message names (:meth:`FmuSpec.origins_named_in`), else ``""``."""
        instance = getattr(e, "instance", None)
        try:
            spec = self.scenario.fmu(instance) if instance else None
        except KeyError:
            return ""
        hits = spec.origins_named_in(str(e)) if spec is not None else []
        if not hits:
            return ""
        where = [f"{name} from {origin}" for name, origin in hits]
        listed = where[0] if len(where) == 1 else ", ".join(where[:-1]) + " and " + where[-1]
        return f"; '{instance}' gets {listed}"

    def _fail_fmu(self, e: FmuCallError, t: float, t_next: float) -> None:
        if isinstance(e, FmuCrashError):
            self.failure = e.report()
            self._fail(f"{e}. The run stopped in the macro step from t={t:.12g} s to t={t_next:.12g} s; rows up "
                       f"to t={t:.12g} s are kept and the other FMUs were terminated", t)
            return
        sub = self.subsystems.get(e.instance)
        self.failure = {"instance": e.instance, "fmu": str(getattr(sub, "fmu_path", "")) or None,
                        "function": e.function, "time": t, "cause": e.status}
        self._fail(self._fmu_message(e, t, t_next), t)

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
            if self._rec_typed:
                typed = view.typed
                for i, read in self._rec_typed:
                    v = typed[i] = read()
                    row[i] = math.nan if isinstance(v, str) else float(v)

    # ------------------------------------------------------------- terminate
    def terminate(self, *, preflight: bool = False) -> None:
        """fmi2Terminate and fmi2FreeInstance for every subsystem (always), then
        tell the observers. Idempotent. ``preflight``: the end of ``validate``'s
        setup and initialization (orchestrator/preflight.py), not logged as a run
        terminated early."""
        if self._phase in ("terminated", "new"):
            return
        if self.status is Status.RUNNING and not preflight:
            self._fail(f"terminated early at t={self.t:.12g} s by the caller", self.t)
        self.view.status = self.status
        self.view.message = self.message
        self.view.end_time = self.end_time
        st = self.grid.statistics()
        note = self.defect.note() if self.defect is not None else None
        if note:
            log.warning("%s", note)
        if st["retried_steps"]:
            n_def = st.get("defect_retried_steps", 0)
            n_dis = st["retried_steps"] - n_def
            why = ("after an fmi2Discard" if not n_def else "for their coupling defect" if not n_dis
                   else f"({n_dis} after an fmi2Discard, {n_def} for their coupling defect)")
            log.info("%d macro step(s) were redone in smaller steps %s (%d extra step rounds, "
                     "%d rejected attempts)%s", st["retried_steps"], why, st["retry_substeps"], st["rejected_steps"],
                     f"; only the first {RETRY_LOG_LINES} were logged" if st["retried_steps"] > RETRY_LOG_LINES
                     else "")
        try:
            for u in getattr(self, "units", []):
                try:
                    u.sub.terminate()
                except FmuCallError as e:
                    log.warning("%s", e)
        finally:
            # the observers (results file closed) and the caller's hook (the final summary.json) come
            # before fmi2FreeInstance: an FMU that crashes or hangs while it is freed, after a run
            # that is complete, leaves the run's record complete (it used to leave "running")
            self.wall_time = _time.perf_counter() - self._t_wall0
            try:
                for o in self.observers:
                    o.on_terminated(self.view)
                if self.before_release is not None:
                    self.before_release()
            finally:
                self._release()
                self._phase = "terminated"

    def _release(self) -> None:
        if self._pool is not None:          # no FMU steps in a thread once it is closed
            self._pool.close()
        for sub in self.subsystems.values():
            try:
                sub.free()
            except Exception as e:   # pragma: no cover - defensive
                log.warning("freeing '%s' failed: %s", sub.name, e)
        if self._work_dir is not None:
            self._work_dir.close()
            self._work_dir = None

    # ---------------------------------------------------------------- result
    def statistics(self) -> dict:
        """``rejected_steps``: (sub-)step attempts discarded by an FMU and rolled back;
        ``retried_steps``: macro steps redone in smaller steps; ``retry_substeps``: the extra
        step rounds (sub-intervals attempted) of those retries (all 0 without discard_retries)."""
        st = {"macro_steps": self.n, **self.grid.statistics(), "wall_time_s": self.wall_time,
              "fmu_calls": {name: sub.statistics() for name, sub in self.subsystems.items()},
              "isolation": dict(self.isolation), "failure": self.failure}
        if self._threads():
            # stage steps whose members stepped at the same time in threads (parallel: threads)
            st["threaded_stage_steps"] = self._pool.runs if self._pool else 0
            # of them with watching hand-offs (the pool chooses: coupling/threads.py)
            st["threaded_stage_steps_watched"] = self._pool.watched if self._pool else 0
        stats = getattr(getattr(self, "stepper", None), "stats", None)
        if stats is not None:
            st["iterations"] = stats.as_dict()
        if self.defect is not None:
            st["coupling_defect"] = cd = self.defect.statistics()
            g = self.grid
            if getattr(g, "constant", None) is not None:     # step_control.until: the constant steps only
                cd["monitored_from"] = g.until
                cd["steps_not_monitored"] += g.n_offset if g.n_offset is not None else self.n
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
        except BaseException as exc:
            if self.status is Status.RUNNING:   # say why it stopped (not "terminated by the caller")
                why = "interrupted by the user" if isinstance(exc, KeyboardInterrupt) else (
                    f"stopped by an error ({type(exc).__name__}: {exc})")
                self.status, self.message, self.end_time = Status.FAILED, f"{why} at t={self.t:.12g} s", self.t
                self.view.status, self.view.message = self.status, self.message
            raise
        finally:
            self.terminate()
        return self.result()


class _ShiftedGrid:
    """The time of the master's row ``n`` from a :class:`TimeGrid` that starts at step ``n0``."""

    def __init__(self, grid: TimeGrid, n0: int):
        self.grid, self.n0 = grid, n0

    def time(self, n: int) -> float:
        return self.grid.time(n - self.n0)


def _declared_feedthrough(sub) -> dict | None:
    """``{output: inputs it depends on directly}`` as the FMU's ModelStructure declares it, or None
    (a subsystem without a model description, or one that declares nothing)."""
    md = getattr(sub, "md", None)
    feed = md.direct_feedthrough() if md is not None else None
    return feed if feed and all(d is not None for d in feed.values()) else None
