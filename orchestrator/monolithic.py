"""Monolithic reference: the coupled system integrated as one ODE, no co-simulation.

``run_monolithic(scenario, out_dir)`` is what ``orchestrator.run`` calls for
``coupling.scheme: monolithic``. It recognizes *our own* models by the model name
of each FMU's ``modelDescription.xml``, builds the plain-Python model directly
from the FMU instance's parameters (the FMU's start values, overridden by the
scenario's ``parameters``), and integrates all states together with one implicit
integrator at tight tolerance (``scipy.integrate.solve_ivp``, Radau by default).
Signals flow through the scenario's connections (gain and offset included)
exactly as in the co-simulation, but every right-hand-side evaluation sees the
*current* outputs of every model: there is no macro step, no hold, no
extrapolation, so a difference to a co-simulation run is a coupling error.

Supported models (``MODELS``):

* ``JeffcottRotor``: :class:`rotor_fmu.jeffcott.JeffcottRotor` in its first-order form
  (``state_vector``, ``rhs(t, s, F)``, ``journal_kinematics``);
* ``JournalBearing`` with ``cavitation = 0`` (half-Sommerfeld, quasi-static: no state,
  outputs are a function of the journal kinematics, so the coupled ODE is exact);
  ``cavitation = 1`` (mass-conserving, the film has its own state) is **not
  supported** and raises :class:`ScenarioError`;
* ``LeftMass``, ``RightMass``: the two-mass oscillator of the orchestrator tests
  (``tests/fmus_src``), a linear system with a closed-form solution.

Coupling-scheme options (``coupling.options``): ``rtol`` (default ``DEFAULT_RTOL``),
``atol`` (default ``DEFAULT_ATOL``, SI units of the states), ``method`` (a
``solve_ivp`` method, default ``"Radau"``), ``max_step`` [s] (default: the output
interval, so that no output interval is skipped over).

Output: ``results.csv`` on the grid ``t0 + k * interval`` (``output.interval``,
else ``coupling.macro_step``) and ``summary.json`` as written by ``run``
(``macro_steps`` is the number of accepted integrator steps, ``fmu_calls`` is
empty: no FMU is called; ``rhs_evaluations`` counts the coupled right-hand sides).
The run-up ``analysis:`` is added by ``orchestrator.run`` afterwards, as for the master.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
import warnings
from pathlib import Path


import numpy as np

from orchestrator.errors import ScenarioError
from orchestrator.monolithic_models import MODELS, ModelAdapter
from orchestrator.scenario import Scenario

log = logging.getLogger(__name__)

__all__ = ["run_monolithic", "MonolithicSystem", "DEFAULT_RTOL", "DEFAULT_ATOL"]

DEFAULT_RTOL = 1e-8
DEFAULT_ATOL = 1e-12
_OPTIONS = {"rtol", "atol", "method", "max_step"}


class MonolithicSystem:
    """The scenario's models and connections as one first-order ODE ``S' = f(t, S)``.

    Evaluation order of ``f``: outputs of the models without direct feedthrough
    (functions of their state), then the feedthrough models in the topological
    order of the connections between them (an algebraic loop between feedthrough
    models is rejected at construction), then every model's inputs from the
    connections and its state derivative.
    """

    def __init__(self, scenario: Scenario):
        from orchestrator.fmu_archive import read_model_description

        problems = []
        self.adapters: dict[str, ModelAdapter] = {}
        for spec in scenario.fmus:
            md = read_model_description(spec.path)
            factory = MODELS.get(md.model_name)
            if factory is None:
                problems.append(
                    f"FMU instance '{spec.name}' ({spec.path.name}) has the model '{md.model_name}', "
                    f"which the monolithic reference cannot build (it knows {sorted(MODELS)}); use a "
                    "co-simulation variant with a much smaller macro step as the reference")
                continue
            try:
                self.adapters[spec.name] = factory(spec.name, md, dict(spec.parameters),
                                                  start_time=float(scenario.start_time))
            except (ValueError, TypeError, KeyError) as exc:
                problems.append(f"FMU instance '{spec.name}': {exc}")
        if problems:
            raise ScenarioError(problems)
        self.connections = [(c.src_instance, c.src_variable, c.dst_instance, c.dst_variable,
                             float(c.gain), float(c.offset)) for c in scenario.connections]
        for si, sv, di, dv, _, _ in self.connections:
            a, b = self.adapters[si], self.adapters[di]
            if sv not in a.output_names:
                problems.append(f"connection {si}.{sv} -> {di}.{dv}: the monolithic model of '{si}' "
                                f"has no output '{sv}' (has {list(a.output_names)})")
            if dv not in b.input_names:
                problems.append(f"connection {si}.{sv} -> {di}.{dv}: the monolithic model of '{di}' "
                                f"has no input '{dv}' (has {list(b.input_names)})")
        if problems:
            raise ScenarioError(problems)
        self.order = self._evaluation_order()
        sizes = [a.n_states for a in self.adapters.values()]
        offs = np.cumsum([0] + sizes)
        self.slices = {name: slice(int(offs[i]), int(offs[i + 1]))
                       for i, name in enumerate(self.adapters)}
        self.n_rhs = 0

    def _evaluation_order(self) -> list[str]:
        ft = {n for n, a in self.adapters.items() if a.feedthrough}
        order = [n for n in self.adapters if n not in ft]
        deps = {n: {si for si, _, di, _, _, _ in self.connections if di == n and si in ft} for n in ft}
        while deps:
            ready = [n for n, d in deps.items() if not (d - set(order))]
            if not ready:
                raise ScenarioError(f"algebraic loop between the direct-feedthrough models "
                                    f"{sorted(deps)}; the monolithic reference cannot solve it")
            for n in ready:
                order.append(n)
                del deps[n]
        return order

    def initial_state(self) -> np.ndarray:
        parts = [a.initial_state() for a in self.adapters.values()]
        return np.concatenate(parts) if parts else np.zeros(0)

    def evaluate(self, t: float, S: np.ndarray, *, full: bool = True) -> tuple[dict, dict]:
        """Inputs and outputs of every model at ``(t, S)``: ``({inst: {in: v}}, {inst: {out: v}})``.
        ``full=False`` (right-hand side) lets adapters skip outputs that feed nothing physical."""
        u = {n: dict(a.input_defaults) for n, a in self.adapters.items()}
        y: dict[str, dict[str, float]] = {}
        for n in self.order:
            for si, sv, di, dv, g, o in self.connections:
                if di == n and si in y:
                    u[n][dv] = g * y[si][sv] + o
            y[n] = self.adapters[n].outputs(t, S[self.slices[n]], u[n], full=full)
        for si, sv, di, dv, g, o in self.connections:
            u[di][dv] = g * y[si][sv] + o
        return u, y

    def rhs(self, t: float, S: np.ndarray) -> np.ndarray:
        self.n_rhs += 1
        u, _ = self.evaluate(t, S, full=False)
        dS = np.empty_like(S)
        for n, a in self.adapters.items():
            if a.n_states:
                dS[self.slices[n]] = a.rhs(t, S[self.slices[n]], u[n])
        return dS


def _columns(scenario: Scenario, system: MonolithicSystem) -> list[str]:
    if scenario.output.signals is not None:
        return list(scenario.output.signals)
    return [f"{n}.{v}" for n, a in system.adapters.items() for v in a.output_names]


def run_monolithic(scenario: Scenario, out_dir: str | Path | None = None, progress=None):
    """Integrate ``scenario`` monolithically; write results.csv and summary.json; return CoSimResult.

    Output rows stream through the master's observers (``CsvWriter``, ``Progress``,
    ``Recorder`` of :mod:`orchestrator.observers`); ``progress`` is as for ``run``
    (None: shown on a terminal for long runs). Bad input (an unsupported model, an
    unknown option) raises :class:`ScenarioError`; an integrator failure is a
    ``failed`` status with the integrator's message.
    """
    from orchestrator.observers import CsvWriter, Progress, Recorder, RunView, versions, write_summary
    from orchestrator.results import CoSimResult, Status

    t_wall = time.perf_counter()
    opts = dict(scenario.coupling.options)
    unknown = set(opts) - _OPTIONS
    if unknown:
        raise ScenarioError(f"coupling.options {sorted(unknown)} are not options of the monolithic "
                            f"reference (valid: {sorted(_OPTIONS)})")
    for f in scenario.fmus:
        if f.parameters.get("fields_file"):
            warnings.warn(f"monolithic reference: '{f.name}.fields_file' is ignored (no film fields "
                          "are written by the monolithic integrator)", stacklevel=2)
    system = MonolithicSystem(scenario)
    t0, t1 = float(scenario.start_time), float(scenario.stop_time)
    interval = float(scenario.output.interval or scenario.coupling.macro_step)
    n_out = int(math.floor((t1 - t0) / interval * (1 + 1e-12))) + 1
    t_grid = t0 + interval * np.arange(n_out)
    if not math.isclose(t_grid[-1], t1, rel_tol=1e-12, abs_tol=1e-12 * interval):
        t_grid = np.append(t_grid, t1)
    rtol = float(opts.get("rtol", DEFAULT_RTOL))
    atol = float(opts.get("atol", DEFAULT_ATOL))
    method = str(opts.get("method", "Radau"))
    max_step = float(opts.get("max_step", interval))
    columns = _columns(scenario, system)
    S0 = system.initial_state()
    _row(system, columns, t0, S0)          # unknown output.signals fail before anything is written

    recorder = Recorder()
    observers = [recorder, Progress(progress)]
    if out_dir is not None:
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        observers.insert(0, CsvWriter(out_dir / "results.csv"))
    view = RunView(columns, t0, t1, len(t_grid) - 1)
    view.is_output = True

    def emit(k: int, t: float, S: np.ndarray) -> bool:
        view.t, view.n, view.end_time = t, k, t
        view.row = _row(system, columns, t, S)
        for o in observers:
            (o.on_initialized if k == 0 else o.on_step_complete)(view)
        return bool(np.all(np.isfinite(view.row)))

    log.info("monolithic: %d states, %s rtol=%g atol=%g, t = %g .. %g", S0.size, method, rtol, atol, t0, t1)
    ok, message, n_steps = _integrate(system.rhs, S0, t_grid, emit, method=method, rtol=rtol,
                                      atol=atol, max_step=max_step)
    view.status = Status.FINISHED if ok else Status.FAILED
    view.message = message
    for o in observers:
        o.on_terminated(view)
    t_out, outputs = recorder.arrays()
    wall = time.perf_counter() - t_wall
    stats = {"macro_steps": n_steps, "wall_time_s": wall, "fmu_calls": {},
             "rhs_evaluations": system.n_rhs}
    if out_dir is not None:
        coupling = dataclasses.asdict(scenario.coupling)
        coupling["sequence"] = list(coupling["sequence"])
        coupling["options"] = dict(coupling["options"], method=method, rtol=rtol, atol=atol,
                                   max_step=max_step)
        summary = {"scenario": scenario.name,
                   "scenario_file": str(scenario.source) if scenario.source else None,
                   "status": view.status.short, "message": message,
                   "start_time": t0, "stop_time": t1, "end_time": view.end_time, **stats,
                   "coupling": coupling, "versions": versions()}
        write_summary(out_dir / "summary.json", summary)
    return CoSimResult(status=view.status, message=message, t=t_out, outputs=outputs, stats=stats,
                       out_dir=out_dir, end_time=view.end_time)


def _row(system: MonolithicSystem, columns: list[str], t: float, S: np.ndarray) -> np.ndarray:
    _, y = system.evaluate(float(t), S)
    row = np.empty(len(columns))
    for i, c in enumerate(columns):
        inst, var = c.split(".", 1)
        if var not in y.get(inst, {}):
            raise ScenarioError(f"output.signals lists '{c}', which the monolithic model of "
                                f"'{inst}' does not compute (has {sorted(y.get(inst, {}))})")
        row[i] = y[inst][var]
    return row


def _integrate(fun, S0, t_grid, emit, *, method, rtol, atol, max_step) -> tuple[bool, str, int]:
    """Step a ``scipy.integrate`` solver over ``t_grid`` as ``solve_ivp`` does, but counting
    accepted steps and handing every grid point to ``emit(k, t, S)`` (False: stop, non-finite)."""
    from scipy.integrate._ivp.ivp import METHODS
    if method not in METHODS:
        raise ScenarioError(f"coupling.options.method must be one of {sorted(METHODS)} (got {method!r})")
    if not emit(0, float(t_grid[0]), S0):
        return False, f"non-finite outputs at t = {t_grid[0]:g} s", 0
    if S0.size == 0:       # no state: outputs are functions of time only
        for k in range(1, len(t_grid)):
            if not emit(k, float(t_grid[k]), S0):
                return False, f"non-finite outputs at t = {t_grid[k]:g} s", 0
        return True, "finished", 0
    solver = METHODS[method](fun, float(t_grid[0]), S0, float(t_grid[-1]), rtol=rtol, atol=atol,
                             max_step=max_step)
    k, n_steps = 1, 0
    while solver.status == "running":
        message = solver.step()
        if solver.status == "failed":
            return False, f"{method} failed at t = {solver.t:.9g} s: {message}", n_steps
        n_steps += 1
        j = int(np.searchsorted(t_grid, solver.t, side="right"))
        if j > k:
            dense = solver.dense_output()
            for i in range(k, j):
                if not emit(i, float(t_grid[i]), dense(t_grid[i])):
                    return False, f"non-finite outputs at t = {t_grid[i]:.9g} s", n_steps
            k = j
    return True, "finished", n_steps
