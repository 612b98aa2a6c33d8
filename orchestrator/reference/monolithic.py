"""Monolithic reference: the coupled system integrated as one ODE/DAE, no co-simulation.

``run_monolithic(scenario, out_dir)`` is what ``orchestrator.run`` calls for
``coupling.scheme: monolithic``. It recognizes *our own* models by the model name
of each FMU's ``modelDescription.xml``, builds the plain-Python model directly
from the FMU instance's parameters (the FMU's start values, overridden by the
scenario's ``parameters``), and integrates all states together with one implicit
integrator at tight tolerance. Signals flow through the scenario's connections (gain
and offset included) exactly as in the co-simulation, but every evaluation sees the
*current* outputs of every model: there is no macro step, no hold, no extrapolation,
so a difference to a co-simulation run is a coupling error (plus the reference's own
time-discretisation error, which the options control and ``compare`` checks by halving).

Supported models (``MODELS`` of :mod:`orchestrator.reference.models`):

* ``JeffcottRotor``: :class:`rotor_fmu.jeffcott.JeffcottModel` in its first-order form
  (``state_vector``, ``rhs(t, s, F)``, ``journal_kinematics``);
* ``JournalBearing`` with ``cavitation = 0`` (half-Sommerfeld, quasi-static: no state,
  outputs are a function of the journal kinematics, so the coupled ODE is exact);
* ``JournalBearing`` with ``cavitation = 1`` (mass-conserving: the film has its own
  state, the universal variable u per cell = pressure in the full film, fluid fraction
  theta in the cavity): only with ``method: BDF2`` (the default when such a bearing is
  present), below;
* ``LeftMass``, ``RightMass``: the two-mass oscillator of the orchestrator tests
  (``tests/fmus_src``), a linear system with a closed-form solution.

Two integrators
---------------
``method`` = a ``scipy.integrate.solve_ivp`` method (default ``"Radau"`` when every
model is an ODE or quasi-static): all states as one ODE ``S' = f(t, S)``, options
``rtol``, ``atol``, ``max_step``.

``method = "BDF2"`` (default, and required, with a mass-conserving bearing): ONE
implicit BDF2 integrator over the ODE states S (rotor) and the film states u of every
mass-conserving bearing. The film's semi-discrete equation (paper eq. 4, finite volumes,
bearing_fmu/film.py) is ``2 H d(theta(u))/dt = R(u; H, dH/dt, omega)`` with the gap H
and its rate given by the journal kinematics x, y, vx, vy of the rotor state S; the
rotor is ``S' = f(t, S, F(u, S))``. Both are discretised with the same variable-step
BDF2 formula (Hairer, Norsett & Wanner, Solving ODEs I, sec. III.5, eq. (5.9); the
film solver's own time discretisation, bearing_fmu/solver.py), with
``w = h_n / h_{n-1}``::

    a0 y_{n+1} + a1 y_n + a2 y_{n-1} = h_n g(t_{n+1}, y_{n+1}),
    a0 = (1 + 2w) / (1 + w),  a1 = -(1 + w),  a2 = w^2 / (1 + w)

(BDF1, a = (1, -1, 0), for the first step), applied to S (g = f) and to theta (g = the
film's flux balance / 2H). Per step the coupled nonlinear system at t_{n+1}

    rotor:  a0 S + a1 S_n + a2 S_{n-1} - h f(t_{n+1}, S, F(u))   = 0
    film:   the film's BDF step from (theta_n, theta_{n-1}) to u with the kinematics of S

is solved by Newton's method on S with the film equation eliminated: every residual
evaluation restores each film to its state at t_n and takes exactly one film step of
size h with the end-of-step kinematics of the current S iterate (the public
``JournalBearing.step``/``get_state``/``set_state``; the film's own error control is
switched off so that the step is one BDF step of size h, with the same coefficients;
its Newton solves ``R = 0`` to ``newton_atol = newton_rtol = max(rtol, 1e-12)``). The
Newton matrix ``a0 I - h df/dS`` includes the film's response to the kinematics (one-
sided differences of the film step in x, y, vx, vy with bearing_fmu.linearize's step
sizes: the interface Jacobian of the *discrete* step), is reused over steps (chord
Newton) and refreshed when the iteration contracts by less than 2 per iteration or
fails. A step is accepted when the Newton increment at the last evaluated S is below
``atol + rtol |S|`` in every component; the films keep the state of that evaluation,
so rotor and films are consistent to that tolerance: no coupling error is left, only
BDF2's O(h^2) time-discretisation error, controlled by ``step``.

Steps: every output interval is split into equal steps no longer than ``step`` (option,
default ``DEFAULT_STEP`` capped by the output interval), so outputs fall on step points
(no interpolation). The first step of a run is taken as H/16, H/16, H/8, H/4, H/2
(BDF1, then BDF2 with step ratio 2, zero-stable below 1 + sqrt 2), which keeps the
start-up error of BDF1 in a fast initial transient (journals landing on the film) at
second order. Measured (docs/compare.md, tests/test_monolithic_mc.py): observed order
2.0 under step halving; halving rtol/atol changes nothing visible.

Coupling-scheme options (``coupling.options``): ``method``, ``rtol`` (default
``DEFAULT_RTOL``), ``atol`` (default ``DEFAULT_ATOL``, SI units of the states),
``max_step`` [s] (solve_ivp; default the output interval), ``step`` [s] (BDF2).

Output: ``results.csv`` on the grid ``t0 + k * interval`` (``output.interval``,
else ``coupling.macro_step``) and ``summary.json`` as written by ``run``
(``macro_steps`` is the number of accepted integrator steps, ``fmu_calls`` is
empty: no FMU is called; ``rhs_evaluations`` counts the coupled right-hand sides; BDF2
adds ``newton_iterations``, ``jacobians`` and ``film_steps``, trial steps included).
The run-up ``analysis:`` is added by ``orchestrator.run`` afterwards, as for the master.

Length: the system assembly and its two integrators (solve_ivp and the BDF2 with the
mass-conserving film's Newton matrix) share the evaluation order and are documented together
above; above ~400 lines for that reason.
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
from orchestrator.reference.models import MODELS, ModelAdapter
from orchestrator.scenario import Scenario

log = logging.getLogger(__name__)

__all__ = ["run_monolithic", "MonolithicSystem", "DEFAULT_RTOL", "DEFAULT_ATOL", "DEFAULT_STEP"]

DEFAULT_RTOL = 1e-8
DEFAULT_ATOL = 1e-12
DEFAULT_STEP = 1e-6       # BDF2 step [s] (capped by the output interval)
_OPTIONS = {"rtol", "atol", "method", "max_step", "step"}


class MonolithicSystem:
    """The scenario's models and connections as one first-order ODE ``S' = f(t, S)``.

    Evaluation order of ``f``: outputs of the models without direct feedthrough
    (functions of their state), then the feedthrough models in the topological
    order of the connections between them (an algebraic loop between feedthrough
    models is rejected at construction), then every model's inputs from the
    connections and its state derivative.
    """

    def __init__(self, scenario: Scenario):
        from orchestrator.fmi.archive import read_model_description

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

    @property
    def implicit(self) -> list[str]:
        """Instances with an internal discrete state (the mass-conserving film)."""
        return [n for n, a in self.adapters.items() if a.implicit]

    def evaluate(self, t: float, S: np.ndarray, *, full: bool = True, trial_h: float | None = None,
                 lin: dict | None = None, start: dict | None = None) -> tuple[dict, dict]:
        """Inputs and outputs of every model at ``(t, S)``: ``({inst: {in: v}}, {inst: {out: v}})``.
        ``full=False`` (right-hand side) lets adapters skip outputs that feed nothing physical.
        ``trial_h``: implicit adapters take a trial step of that size to ``t`` with their
        current inputs (BDF2 path); ``lin``: ``{inst: (u0, y0, D)}`` replaces those adapters
        by their linearization (Jacobian of the BDF2 path); ``start``: ``{"step", "tol"}``,
        implicit adapters are initialised at their inputs first (t0)."""
        u = {n: dict(a.input_defaults) for n, a in self.adapters.items()}
        y: dict[str, dict[str, float]] = {}
        for n in self.order:
            for si, sv, di, dv, g, o in self.connections:
                if di == n and si in y:
                    u[n][dv] = g * y[si][sv] + o
            a = self.adapters[n]
            if lin is not None and n in lin:
                u0, y0, D = lin[n]
                du = np.array([u[n][k] - u0[k] for k in a.input_names])
                dy = D @ du
                y[n] = {k: y0[k] + dy[i] for i, k in enumerate(a.output_names)}
            elif a.implicit and trial_h is not None:
                y[n] = a.trial(trial_h, u[n])
            else:
                if a.implicit and start is not None:
                    a.start(u[n], step=start["step"], tol=start["tol"])
                y[n] = a.outputs(t, S[self.slices[n]], u[n], full=full)
        for si, sv, di, dv, g, o in self.connections:
            u[di][dv] = g * y[si][sv] + o
        return u, y

    def derivative(self, t: float, S: np.ndarray, u: dict) -> np.ndarray:
        dS = np.empty_like(S)
        for n, a in self.adapters.items():
            if a.n_states:
                dS[self.slices[n]] = a.rhs(t, S[self.slices[n]], u[n])
        return dS

    def rhs(self, t: float, S: np.ndarray) -> np.ndarray:
        self.n_rhs += 1
        u, _ = self.evaluate(t, S, full=False)
        return self.derivative(t, S, u)


def _columns(scenario: Scenario, system: MonolithicSystem) -> list[str]:
    if scenario.output.signals is not None:
        return list(scenario.output.signals)
    return [f"{n}.{v}" for n, a in system.adapters.items() for v in a.output_names]


def preflight(scenario: Scenario):
    """The checks :func:`run_monolithic` makes before integrating (``rotorcosim validate`` makes them too).

    Returns ``(system, plan)`` with ``plan`` = ``{"opts", "method", "step", "columns"}``; raises
    :class:`ScenarioError` for an unsupported model or option.
    """
    opts = dict(scenario.coupling.options)
    unknown = set(opts) - _OPTIONS
    if unknown:
        raise ScenarioError(f"coupling.options {sorted(unknown)} are not options of the monolithic "
                            f"reference (valid: {sorted(_OPTIONS)})")
    system = MonolithicSystem(scenario)
    interval = float(scenario.output.interval or scenario.coupling.macro_step)
    method = str(opts.get("method", "BDF2" if system.implicit else "Radau"))
    step = float(opts.get("step", min(DEFAULT_STEP, interval)))
    if method == "BDF2":
        if not (step > 0 and math.isfinite(step)):
            raise ScenarioError(f"coupling.options.step must be a positive time [s] (got {step!r})")
    elif system.implicit:
        raise ScenarioError(
            f"coupling.options.method {method!r}: {system.implicit} have a mass-conserving film, "
            "whose state only the monolithic BDF2 integrator advances; use method: BDF2 (default)")
    return system, {"opts": opts, "method": method, "step": step, "columns": _columns(scenario, system)}


def run_monolithic(scenario: Scenario, out_dir: str | Path | None = None, progress=None):
    """Integrate ``scenario`` monolithically; write results.csv and summary.json; return CoSimResult.

    Output rows stream through the master's observers (``CsvWriter``, ``Progress``,
    ``Recorder`` of :mod:`orchestrator.coupling.observers`); ``progress`` is as for ``run``
    (None: shown on a terminal for long runs). Bad input (an unsupported model, an
    unknown option) raises :class:`ScenarioError`; an integrator failure is a
    ``failed`` status with the integrator's message.
    """
    from orchestrator.coupling.observers import CsvWriter, Progress, Recorder, RunView
    from orchestrator.results.result import CoSimResult, Status
    from orchestrator.results.summary import make_summary, write_summary

    t_wall = time.perf_counter()
    for f in scenario.fmus:
        if f.parameters.get("fields_file"):
            warnings.warn(f"monolithic reference: '{f.name}.fields_file' is ignored (no film fields "
                          "are written by the monolithic integrator)", stacklevel=2)
    system, plan = preflight(scenario)
    opts, method, step, columns = plan["opts"], plan["method"], plan["step"], plan["columns"]
    t0, t1 = float(scenario.start_time), float(scenario.stop_time)
    interval = float(scenario.output.interval or scenario.coupling.macro_step)
    n_out = int(math.floor((t1 - t0) / interval * (1 + 1e-12))) + 1
    t_grid = t0 + interval * np.arange(n_out)
    if not math.isclose(t_grid[-1], t1, rel_tol=1e-12, abs_tol=1e-12 * interval):
        t_grid = np.append(t_grid, t1)
    rtol = float(opts.get("rtol", DEFAULT_RTOL))
    atol = float(opts.get("atol", DEFAULT_ATOL))
    max_step = float(opts.get("max_step", interval))
    S0 = system.initial_state()
    if method == "BDF2":                   # implicit adapters are initialised at t0's inputs
        system.evaluate(t0, S0, start={"step": step, "tol": _film_tol(rtol)})
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
    extra: dict = {}
    if method == "BDF2":
        ok, message, n_steps, extra = _integrate_bdf2(system, S0, t_grid, emit, step=step,
                                                      rtol=rtol, atol=atol)
    else:
        ok, message, n_steps = _integrate(system.rhs, S0, t_grid, emit, method=method, rtol=rtol,
                                          atol=atol, max_step=max_step)
    view.status = Status.FINISHED if ok else Status.FAILED
    view.message = message
    for o in observers:
        o.on_terminated(view)
    t_out, outputs = recorder.arrays()
    wall = time.perf_counter() - t_wall
    stats = {"macro_steps": n_steps, "wall_time_s": wall, "fmu_calls": {},
             "rhs_evaluations": system.n_rhs, **extra}
    if out_dir is not None:
        coupling = dataclasses.asdict(scenario.coupling)
        coupling["sequence"] = list(coupling["sequence"])
        coupling["options"] = dict(coupling["options"], method=method, rtol=rtol, atol=atol,
                                   **({"step": step} if method == "BDF2" else {"max_step": max_step}))
    res = CoSimResult(status=view.status, message=message, t=t_out, outputs=outputs, stats=stats,
                      out_dir=out_dir, end_time=view.end_time)
    if out_dir is not None:
        write_summary(out_dir / "summary.json", make_summary(scenario, res, stats=stats, coupling=coupling))
    return res


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


def _film_tol(rtol: float) -> float:
    """Newton tolerance of the film steps (theta, and p relative to its range) for ``rtol``."""
    return max(float(rtol), 1e-12)


def _bdf_coefficients(h: float, h_prev: float, first: bool) -> tuple[float, float, float]:
    """(a0, a1, a2) of ``a0 y_{n+1} + a1 y_n + a2 y_{n-1} = h f(t_{n+1}, y_{n+1})``:
    BDF1 (first step) or variable-step BDF2 with w = h / h_prev (Hairer, Norsett & Wanner I,
    III.5, eq. 5.9; the film solver's formula, bearing_fmu/solver.py)."""
    if first:
        return 1.0, -1.0, 0.0
    w = h / h_prev
    return (1 + 2 * w) / (1 + w), -(1 + w), w * w / (1 + w)


def _integrate_bdf2(system: MonolithicSystem, S0, t_grid, emit, *, step, rtol, atol,
                    max_iter: int = 8) -> tuple[bool, str, int, dict]:
    """One BDF2 integrator over the rotor states and the film states (module docstring).

    Every output interval is split into equal steps no longer than ``step``, so outputs
    fall on step points (no interpolation). Per step, the coupled system is solved by a
    (chord) Newton iteration on the ODE states S_{n+1}; every residual evaluation takes
    the implicit adapters' film step to t_{n+1} with the kinematics of the current S_{n+1}
    iterate. Returns (ok, message, steps, counters)."""
    from bearing_fmu.model import StepFailed
    cnt = {"newton_iterations": 0, "jacobians": 0}
    if not emit(0, float(t_grid[0]), S0):
        return False, f"non-finite outputs at t = {t_grid[0]:g} s", 0, cnt
    n = S0.size
    S_n, S_nm1 = S0.copy(), S0.copy()
    h_prev, n_steps, t = 0.0, 0, float(t_grid[0])
    J_f = None                      # df/dS (with the film's step response), reused (chord)
    expensive = [name for name, a in system.adapters.items() if hasattr(a, "fd_steps")]

    def residual(t1, S, h, a):
        system.n_rhs += 1
        u, _ = system.evaluate(t1, S, full=False, trial_h=h)
        return a[0] * S + a[1] * S_n + a[2] * S_nm1 - h * system.derivative(t1, S, u), u

    def jacobian(t1, S, h):
        """df/dS by differences: the expensive (bearing) adapters by their inputs with their
        own steps, then the cheap rest (linear here) through their linearization."""
        cnt["jacobians"] += 1
        u, y = system.evaluate(t1, S, full=False, trial_h=h)
        lin = {}
        for name in expensive:
            a = system.adapters[name]
            outs = a.output_names
            y0 = np.array([y[name][k] for k in outs])
            D = np.zeros((len(outs), len(a.input_names)))
            for i, (k, d) in enumerate(a.fd_steps(u[name]).items()):
                up = dict(u[name])
                up[k] += d
                yp = a.trial(h, up) if a.implicit else a.outputs(t1, np.zeros(0), up, full=False)
                col = (np.array([yp[o] for o in outs]) - y0) / d
                D[:, a.input_names.index(k)] = np.where(np.isfinite(col), col, 0.0)
            lin[name] = (dict(u[name]), dict(y[name]), D)
        f0 = system.derivative(t1, S, system.evaluate(t1, S, full=False, lin=lin)[0])
        J = np.empty((n, n))
        scale = max(float(np.max(np.abs(S))), 1e-12)
        for j in range(n):
            d = 1e-6 * max(abs(S[j]), scale)
            Sp = S.copy()
            Sp[j] += d
            up = system.evaluate(t1, Sp, full=False, lin=lin)[0]
            J[:, j] = (system.derivative(t1, Sp, up) - f0) / d
        return J

    for k in range(1, len(t_grid)):
        t_out = float(t_grid[k])
        m = max(1, int(math.ceil((t_out - t) / step * (1 - 1e-9))))   # t rounds: 1e-12 too tight
        H = (t_out - t) / m
        ends = [t + i * H for i in range(1, m)] + [t_out]
        if n_steps == 0:    # start: BDF1 at H/16, then doubling (ratio 2 < 1 + sqrt 2) to H
            ends = [t + f * H for f in (1 / 16, 1 / 8, 1 / 4, 1 / 2)] + ends
        for t1 in ends:
            h = t1 - t
            a = _bdf_coefficients(h, h_prev, n_steps == 0)
            if n_steps == 0:
                S = S_n.copy()
            else:        # linear extrapolation as the Newton start
                S = S_n + (h / h_prev) * (S_n - S_nm1)
            refreshed = 0
            try:
                while True:
                    if J_f is None:
                        J_f = jacobian(t1, S, h)
                        refreshed += 1
                    lu = _lu(a[0] * np.eye(n) - h * J_f)
                    prev, done = None, False
                    for it in range(max_iter):
                        G, u = residual(t1, S, h, a)
                        cnt["newton_iterations"] += 1
                        if not np.all(np.isfinite(G)):
                            break
                        dS = -_lu_solve(lu, G)
                        nrm = float(np.max(np.abs(dS) / (atol + rtol * np.abs(S))))
                        if nrm <= 1.0:    # S (where G was evaluated) is within the tolerance
                            done = True
                            break
                        if prev is not None and nrm > 0.5 * prev:
                            break         # slow: the chord Jacobian is stale
                        prev = nrm
                        S = S + dS
                    if done:
                        break
                    if refreshed >= 2 or not np.all(np.isfinite(S)):
                        return (False, f"BDF2: the coupled Newton iteration did not converge at "
                                f"t = {t1:.9g} s (h = {h:g} s); reduce coupling.options.step",
                                n_steps, cnt)
                    J_f = None    # refresh at the current iterate and iterate on
            except StepFailed as exc:
                return False, f"BDF2 at t = {t1:.9g} s (h = {h:g} s): {exc}", n_steps, cnt
            for name in system.implicit:
                system.adapters[name].commit(h, u[name])
            S_nm1, S_n = S_n, S
            h_prev, t = h, t1
            n_steps += 1
        if not emit(k, t, S_n):
            return False, f"non-finite outputs at t = {t:.9g} s", n_steps, cnt
    cnt["film_steps"] = int(sum(getattr(a, "film_steps", 0) for a in system.adapters.values()))
    return True, "finished", n_steps, cnt


def _lu(A):
    import scipy.linalg
    return scipy.linalg.lu_factor(A)


def _lu_solve(lu, b):
    import scipy.linalg
    return scipy.linalg.lu_solve(lu, b)
