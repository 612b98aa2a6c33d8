"""Error-controlled macro step for the master (``coupling.step_control: {type: error, ...}``).

Per attempt from T(n) with proposal h (the first is ``coupling.macro_step``):

1. the step end is ``t_end = next_stop(T(n), h)``: the next output time if the step
   would reach or cross it (results rows stay on the output grid), else T(n) + h;
2. the order-k prediction ``P`` of every coupling signal at ``t_end`` is taken from the
   history (what an explicit step feeds; the iterative scheme's first iterate);
3. the step is taken by the configured scheme (explicit, iterative, with discard
   retries); its outputs at ``t_end`` are ``y``;
4. ``err = scaled_error_norm(P, y, y(T(n)))`` (error_control.py; for the iterative
   scheme the fed order-q interpolant against the order-(q+1) one at the step's
   midpoint instead, :meth:`IterativeMacroStep.error_signals`), with ``measure: impulse``
   times ``h / output interval``, goes to the PI controller: accept, or reject -> every
   FMU state and the history are restored to T(n) (saved before the attempt), observers
   get ``on_step_rejected``, and the attempt is redone with the smaller proposal. A step
   accepted as a jump restarts the extrapolation (history order 0) from the value after it.
   An attempt an FMU discards (fmi2Discard, e.g. a journal pushed through the shell's asperity
   layer) is rejected the same way and redone at half its length (``discarded_steps``), down to
   ``min_step``, where the discard ends the run with the FMU's message (so ``discard_retries`` is
   not needed, and not allowed, before ``until``).

``measure: impulse`` (opt-in; ``value`` is the default): a defect d of a force over the step
changes what the receiving subsystem integrates by about the impulse d h (momentum; d h^2 / m
in a position), so the same d matters less in a short step than in a long one. Controlling d
itself asks for the same d in every step, which spends many short steps where the signals
change fast. Measured (docs/coupling.md): on the whole seeded run-up 0.85-0.91x the doSteps
of a constant step at the same error against 0.45-0.53x with ``value`` (the whirl after the
onset took 26 us steps for little gain); on the stepping stiffness erratic (the defect of
the step across the switch shrinks with the step). Not the default: it changes what rtol
means, and neither measure reaches the goal on the run-up. The order of the estimate is
p + 1. The output interval only sets what rtol means (the defect of a step as long as the
output interval), not the first step (``macro_step``), which must not change the accuracy
(a first step 100x too long is rejected and the run ends as accurate as one started well:
tests/test_master_adaptive.py).

``until`` (``step_control: {type: error, ..., until: T}``, :class:`ErrorThenConstant`): this
controller up to T (its output grid ends there, so its last step ends exactly at T), then constant
``macro_step`` steps T + n * macro_step to stop_time with the constant-step machinery
(``discard_retries``, ``defect_retries``), in one run; the history carries over.

Bounded work: at most ``MAX_REJECTIONS`` rejected attempts in a row and
``max(MAX_STEPS, MAX_STEPS_PER_NOMINAL * (t_stop - t0) / macro_step)`` accepted steps; past
either the run fails (CouplingError) naming the signal that limited the step most often,
the step sizes reached and the keys to change (rtol/atol, min_step).

A step shortened to land on an output time does not shrink the next proposal
below the one that was cut. FMUs that cannot save and restore their state
(canGetAndSetFMUstate false): no rejection, the step adapts forward only (the
controller sees every error, so the next step still follows the dynamics); the
master says so at setup and ``validate`` reports it (scenario/coupling_sections.py). FMUs
that cannot take varying steps (canHandleVariableCommunicationStepSize false) are refused.
"""

from __future__ import annotations

import fnmatch
import logging
import math

import numpy as np

from orchestrator.coupling.error_control import MIN_STEP_SLACK, PIController, next_stop, scaled_error_norm
from orchestrator.coupling.signal_scales import (DEFAULT_ATOL, atol_vector, corrected_prediction, force_vectors,
                                                  jacobian_groups, running_scale_mask)
from orchestrator.coupling.signals import lagrange_weights
from orchestrator.coupling.step_control import ConstantStep, DiscardHalving, StepSizeController
from orchestrator.errors import CouplingError, FmuCallError
from orchestrator.errors import ScenarioError
from orchestrator.scenario.limits import step_slack
from orchestrator.scenario.coupling_sections import until_problem, until_reaches_stop
from orchestrator.scenario.model import StepControlSpec

log = logging.getLogger(__name__)
MIN_STEP_FRACTION = 1e-3      # default min_step = macro_step * this
MAX_REJECTIONS = 60           # rejected attempts in a row before the run fails (each shrinks h by >= 0.9x)
MAX_STEPS = 200_000           # accepted steps before the run fails (DOPRI5's nmax is 100000) ...
MAX_STEPS_PER_NOMINAL = 100   # ... or this many times (t_stop - t0) / macro_step if that is more


class OutputGrid:
    """Output times ``t0 + j * interval`` (from the index), the last one ``t_stop`` (for
    ``step_control.until`` the grid of the error-controlled part ends at until)."""

    def __init__(self, t0: float, t_stop: float, interval: float):
        self.t0, self.t_stop, self.interval = float(t0), float(t_stop), float(interval)
        self.slack = step_slack(self.t0, self.t_stop, self.interval)   # rounding of the times alone

    def after(self, t: float) -> float:
        j = math.floor((t - self.t0) / self.interval + self.slack) + 1
        t_out = self.t0 + j * self.interval
        # an output time that rounding alone puts just below t_stop is t_stop (no sliver step after
        # it; the grid of step_control.until ends at until, which t0 + k * interval may miss by an ulp)
        return self.t_stop if t_out >= self.t_stop - self.slack * self.interval else t_out


class ErrorControlled(StepSizeController):
    """The error-controlled step-size controller (module docstring).

    Extends the controller protocol (step_control.py) with a variable grid:
    ``variable = True``; the master calls ``take_variable_step(stepper, t)``, which returns
    ``(t_end, on_output_time)`` of the accepted step, instead of ``time(n)`` /
    ``take_step``. ``n_steps`` is only the estimate ``(t_stop - t0) / macro_step``
    (progress display). ``can_reject`` is set by the master at setup (False when some
    FMU cannot restore its state: forward adaptation only).
    """

    variable = True
    needs_states = False

    def __init__(self, spec: StepControlSpec, *, t0: float, t_stop: float, h0: float, interval: float,
                 order: int, ij_order: int | None = None):
        self.spec = spec
        self.impulse = getattr(spec, "measure", "value") == "impulse"
        order += self.impulse                  # the impulse of an O(H^p) defect is O(H^(p+1))
        self.ij_order = None if ij_order is None else ij_order + self.impulse   # (bind), if other
        self.t0, self.t_stop = float(t0), float(t_stop)
        self.grid = OutputGrid(t0, t_stop, interval)
        self.n_steps = max(1, math.ceil((t_stop - t0) / h0 - step_slack(t0, t_stop, h0)))
        min_step = spec.min_step if spec.min_step is not None else h0 * MIN_STEP_FRACTION
        max_step = spec.max_step if spec.max_step is not None else interval
        self.pi = PIController(order=order, min_step=min(min_step, max_step), max_step=max_step)
        self.h = min(max(h0, self.pi.min_step), self.pi.max_step)
        self.h0 = float(h0)
        self.max_steps = max(MAX_STEPS, MAX_STEPS_PER_NOMINAL * self.n_steps)
        self.signal_names: list[str] = []      # set by the master (bind), for messages
        self.atol: np.ndarray | None = None    # per signal (bind); None: spec.atol as given
        self.ij_groups: list = []              # interface-Jacobian forces (bind)
        self.nominal_scaled: list[str] = []    # signals with a declared nominal (bind)
        self.running = np.zeros(0, dtype=bool)  # signals whose atol is rtol x their running scale (bind)
        self.scale = np.zeros(0)               # largest |y| of those signals at accepted step ends so far
        self._run_idx = np.zeros(0, dtype=np.intp)  # np.flatnonzero(running), computed once (bind)
        self._vec = np.zeros((2, 0), dtype=np.intp)  # (x columns, y columns) of force vectors sharing a scale (bind)
        self._ij_forces: set[int] = set()      # columns of the interface-Jacobian forces (bind)
        self.limiting: dict[int, int] = {}     # signal index -> steps it had the largest error
        self.over_signals: dict[int, int] = {}  # signal index -> accepted steps it took above tolerance
        self.accepted = 0
        self.discarded = 0                     # attempts an FMU discarded (fmi2Discard), redone at half the step
        self.h_min_taken = math.inf
        self.h_max_taken = 0.0

    @property
    def can_reject(self) -> bool:
        return self.pi.can_reject

    @can_reject.setter
    def can_reject(self, value: bool) -> None:
        self.pi.can_reject = bool(value)

    def time(self, n: int) -> float:
        return self.t0 if n == 0 else self.t_stop

    @staticmethod
    def prediction(stepper, t: float, t_end: float) -> np.ndarray:
        hist = stepper.history
        p = min(stepper.predictor.k, hist.count - 1)
        past = (hist.times[1:p + 2] - t) / (t_end - t)
        return lagrange_weights(past, [1.0])[0] @ hist.store[1:p + 2]

    def bind(self, names: list[str], connections, nominals=None) -> None:
        """Per-signal atol (from ``nominals``, one per column or None, where no atol key names
        a signal) and the interface-Jacobian forces of the columns ``names`` (signal_scales.py);
        called by the master at setup."""
        self.signal_names = list(names)
        self.atol = atol_vector(self.spec.atol, self.signal_names, rtol=self.spec.rtol, nominals=nominals)
        self.nominal_scaled = [n for n, v in zip(names, nominals or ()) if v is not None]
        self.ij_groups = jacobian_groups(self.signal_names, connections) if self.spec.interface_jacobian else []
        for _, terms in self.ij_groups:        # the coefficients act through the force's defect
            for kc, _, _ in terms:
                self.atol[kc] = math.inf
        self.running = running_scale_mask(self.spec.atol, len(names), nominals) & np.isfinite(self.atol)
        self.scale = np.zeros(len(names))
        self._run_idx = np.flatnonzero(self.running)
        self._vec = force_vectors(self.signal_names, [j for j, _ in self.ij_groups], self.running)
        self._ij_forces = {j for j, _ in self.ij_groups}
        if self.ij_groups:
            if self.ij_order and all(j in self._ij_forces for j in np.flatnonzero(np.isfinite(self.atol))):
                self.pi.p = self.ij_order      # only IJ defects in the norm: their order (ij_order_of)
            log.info("error-controlled step: interface-Jacobian estimate for %s (order %d)",
                     ", ".join(self.signal_names[j] for j, _ in self.ij_groups), self.pi.p)

    def _order_of(self, worst: int) -> int | None:
        """Order in H of the defect of the signal ``worst`` when it is an interface-Jacobian force
        and that order differs from the controller's (None: the controller's own p)."""
        if self.ij_order and self.ij_order != self.pi.p and worst in self._ij_forces:
            return self.ij_order
        return None

    def error(self, stepper, pred: np.ndarray, prev: np.ndarray, h: float | None = None) -> tuple[float, int]:
        """Scaled local error of the step of size ``h`` just committed (module docstring, item 4);
        ``measure: impulse`` weighs it by h / the output interval."""
        hist = stepper.history
        pair = stepper.error_signals() if hasattr(stepper, "error_signals") else None
        if pair is not None:
            a, b = pair
        else:
            a, b = pred, hist.store[1]
            if self.ij_groups:
                a = corrected_prediction(pred, b, prev, self.ij_groups)
        atol = self.atol if self.atol is not None and len(self.atol) == len(b) else \
            atol_vector(self.spec.atol, [""] * len(b))
        r = self._run_idx                      # indices, not the mask: half the cost per attempt
        if r.size and len(self.running) == len(b):
            atol = atol.copy()
            size = np.abs(prev)
            if self._vec.size:                 # a force vector's components: its length
                vx, vy = self._vec
                size[vx] = size[vy] = np.hypot(prev[vx], prev[vy])
            atol[r] = np.maximum(DEFAULT_ATOL, self.spec.rtol * np.maximum(self.scale[r], size[r]))
        err, worst = scaled_error_norm(a, b, prev, rtol=self.spec.rtol, atol=atol)
        if self.impulse and h is not None:
            err *= h / self.grid.interval
        return err, worst

    def take_variable_step(self, stepper, t: float) -> tuple[float, bool]:
        """Take one accepted step from ``t``; returns ``(t_end, on_output_time)``."""
        hist = stepper.history
        if self.accepted >= self.max_steps:
            raise CouplingError(self._too_many(t, f"took {self.accepted} accepted steps (the limit is "
                                                  f"max({MAX_STEPS}, {MAX_STEPS_PER_NOMINAL} x (stop_time - "
                                                  "start_time) / macro_step))"))
        rejected = 0
        while True:
            h = self.h
            t_end, on_out = next_stop(t, h, self.grid.after)
            pred = self.prediction(stepper, t, t_end)
            prev = hist.store[1].copy()
            cp = stepper.save() if self.can_reject else None
            try:
                try:
                    stepper.step(t, t_end)
                except FmuCallError as e:
                    if not self._discard_retryable(e, stepper, t_end - t):
                        raise
                    # an FMU refused the step (fmi2Discard): a rejected attempt, redone at half the step
                    self.discarded += 1
                    h_retry, why, last = self.pi.discarded(t_end - t), e, f"the last discarded by an FMU: {e}"
                else:
                    err, worst = self.error(stepper, pred, prev, t_end - t)
                    d = self.pi.decide(t_end - t, err, order=self._order_of(worst))
                    if d.accept:
                        h_retry = None
                    else:
                        self.limiting[worst] = self.limiting.get(worst, 0) + 1
                        h_retry, why = d.h_next, RuntimeError(f"scaled error {err:.3g} > 1")
                        last = f"last h {t_end - t:.3g} s, scaled error {err:.3g}"
                if h_retry is not None:
                    stepper.restore(cp)
                    self.on_rejected(t, t_end, why)
                    self.h = h_retry
                    rejected += 1
                    if rejected >= MAX_REJECTIONS:
                        raise CouplingError(self._too_many(t, f"rejected {rejected} attempts in a row at "
                                                              f"t={t:.12g} s ({last})"))
                    continue
            finally:
                if cp is not None:
                    stepper.release(cp)
            self.limiting[worst] = self.limiting.get(worst, 0) + 1
            r = self._run_idx
            if r.size:                       # only accepted values (a rejected attempt is rolled back)
                self.scale[r] = np.maximum(self.scale[r], np.maximum(np.abs(prev[r]), np.abs(hist.store[1][r])))
                if self._vec.size:
                    vx, vy = self._vec
                    new = hist.store[1]
                    self.scale[vx] = self.scale[vy] = np.maximum.reduce(
                        [self.scale[vx], self.scale[vy], np.hypot(prev[vx], prev[vy]), np.hypot(new[vx], new[vy])])
            if err > 1.0:
                self.over_signals[worst] = self.over_signals.get(worst, 0) + 1
            if d.jump:          # restart the extrapolation from the value after the jump
                hist.count = min(hist.count, 1)
            # a step shortened onto an output time does not shrink the proposal (the steps of an
            # even split on the way to it are < h too, but the PI's proposal after them holds)
            self.h = max(d.h_next, h) if (on_out and t_end - t < h and err <= 1.0) else d.h_next
            self.accepted += 1
            self.h_min_taken = min(self.h_min_taken, t_end - t)
            self.h_max_taken = max(self.h_max_taken, t_end - t)
            return t_end, on_out

    def _discard_retryable(self, e: FmuCallError, stepper, h: float) -> bool:
        """An fmi2Discard the controller redoes: states can be restored, the FMU did not end the
        simulation (fmi2Terminated), and the step is above min_step (at min_step the discard ends the
        run with the FMU's message, as a discard on a constant step without discard_retries)."""
        return (self.can_reject and e.status == "discard" and not stepper.fmu_ended(e)
                and h > self.pi.min_step * MIN_STEP_SLACK)

    def _uses_nominal(self, name: str) -> bool:
        """True when ``name`` took its atol from its nominal (no atol key names it)."""
        a = self.spec.atol
        if a is not None and not isinstance(a, tuple):
            return False
        return not any(name == k or fnmatch.fnmatchcase(name, k) for k, _ in (a or ()))

    def _limiting(self) -> dict:
        """The (at most 5) signals that had the largest scaled error most often: name -> attempts."""
        names = self.signal_names
        top = sorted(self.limiting.items(), key=lambda kv: -kv[1])[:5]
        return {(names[i] if i < len(names) else str(i)): n for i, n in top}

    def _too_many(self, t: float, what: str) -> str:
        top = list(self._limiting().items())[:3]
        lim = ", ".join(f"{name} ({n} steps)" for name, n in top) or "?"
        return (f"the error-controlled macro step {what}; smallest step taken "
                f"{self.h_min_taken if self.accepted else self.h:.3g} s (min_step {self.pi.min_step:.3g} s), "
                f"rows up to t={t:.12g} s are kept. The signals with the largest scaled error: {lim}. Loosen "
                f"coupling.step_control.rtol ({self.spec.rtol:g}) or atol for them, or raise "
                "coupling.step_control.min_step (steps at min_step are accepted whatever their error)")

    def over_tolerance_note(self) -> str | None:
        """What a finished run must say when it accepted steps above its tolerance, or None.

        Such steps are accepted so that a run never stalls (at ``min_step``, a jump, or any step
        when no FMU state can be restored); the run then finishes, but not to ``rtol``/``atol``
        there. Before, only summary.json's counters showed it (the Modelica Reference FMU
        Dahlquist, whose output changes only every 0.1 s, internal fixed step: 82 forced steps,
        23 jumps, and ``status: finished``)."""
        p = self.pi
        if not p.over:
            return None
        names = self.signal_names
        top = sorted(self.over_signals.items(), key=lambda kv: -kv[1])[:3]
        where = ", ".join(f"{names[i] if i < len(names) else i} ({n})" for i, n in top) or "?"
        kinds = [f"{p.forced} at min_step {p.min_step:.3g} s" if p.forced else "",
                 f"{p.jumps} across a jump in a signal" if p.jumps else "",
                 (f"{p.over - p.forced - p.jumps} that could not be rejected (an FMU cannot restore its state)"
                  if not p.can_reject and p.over > p.forced + p.jumps else "")]
        fixes = []
        if p.forced or p.jumps:
            fixes.append("A signal that jumps or changes in stairs (an FMU with a fixed internal step, events) is "
                         "not resolved by smaller steps: leave it out of the estimate (coupling.step_control.atol: "
                         "{SIGNAL: .inf}) or use a constant step that is a multiple of the FMU's own; otherwise "
                         "lower min_step or loosen rtol/atol")
        if p.over > p.forced + p.jumps:
            fixes.append("Steps that cannot be rejected are only followed by a smaller next step: ask for a "
                         "tighter rtol than you need, or use FMUs that can save their state "
                         "(canGetAndSetFMUstate)")
        return (f"{p.over} of {self.accepted} accepted macro steps had a scaled error above 1, so the run does not "
                f"meet coupling.step_control rtol {self.spec.rtol:g} / atol there "
                f"({'; '.join(k for k in kinds if k)}); "
                f"signals: {where}. " + ". ".join(fixes))

    def statistics(self) -> dict:
        return {"rejected_steps": 0, "retried_steps": 0, "retry_substeps": 0,
                "step_control": {"type": "error", "accepted_steps": self.accepted,
                                 "rejected_steps": self.pi.rejected, "forced_steps": self.pi.forced,
                                 "jumps": self.pi.jumps, "can_reject": self.can_reject,
                                 "discarded_steps": self.discarded,
                                 "over_tolerance_steps": self.pi.over,
                                 "limiting_signals": self._limiting(),
                                 "interface_jacobian": [self.signal_names[j] for j, _ in self.ij_groups],
                                 "estimate_order": self.pi.p,
                                 "atol_from_nominal": [n for n in self.nominal_scaled
                                                       if self._uses_nominal(n)],
                                 "atol_running_scale": {n: max(DEFAULT_ATOL, self.spec.rtol * float(v))
                                                        for n, v, r in zip(self.signal_names, self.scale,
                                                                           self.running) if r},
                                 "min_step_taken": self.h_min_taken if self.accepted else None,
                                 "max_step_taken": self.h_max_taken if self.accepted else None}}


def ij_order_of(coupling) -> int | None:
    """Order in H of the interface-Jacobian estimate (signal_scales.py) when it is not k + 1.

    Explicit schemes with held forces (k = 0): the defect F(T+H) - F(T) + K dr + C dv is the
    second-order remainder of the film force's linearisation (dr, dv are O(H)), so 2; the
    change through what is not linearised (the speed) is first order but small. Measured on
    the seeded half-Sommerfeld run-up (0.55-0.95 s): log(err1/err2) / log(h1/h2) of the 515
    rejected attempts and their retries, median 1.95 (10-90 % 1.82-2.12); with p = 1 the PI
    controller overreacted to every change of the error (11 % of the attempts rejected).
    With k >= 1 the extrapolated slope of F and the K dr + C dv the rotor subtracts count the
    same change twice: the defect is then first order (None: k + 1 holds). Iterative: its own
    estimate (None)."""
    if coupling.scheme == "iterative" or coupling.extrapolation_order != 0:
        return None
    return 2


class ErrorThenConstant(StepSizeController):
    """``coupling.step_control: {type: error, ..., until: T_u}``: the error-controlled step
    (:class:`ErrorControlled`, its output grid ending at ``T_u``, so its last step is clipped to end
    exactly there) from start_time to ``T_u``, then ``constant`` (a :class:`ConstantStep` or, with
    ``discard_retries``/``defect_retries``, a :class:`DiscardHalving` whose grid starts at ``T_u``:
    T = T_u + n * macro_step from the index n, never accumulated) to stop_time.

    The master asks :attr:`variable` before each step: True until the step that ends at ``T_u``
    has been taken, False after it; then :meth:`time` answers the constant grid by the master's step
    index (``n_offset``: the error-controlled steps taken). One run: the FMUs, the coupling history
    and the observers carry on across the switch. The history is not restarted: the first constant
    steps extrapolate through the newest (uneven) error-controlled levels with weights from their
    actual times, as the pieces of a step redone in halves do (signals.LagrangePredictor); a restart
    would drop to order 0 for k steps. ``until`` must be an output time (scenario loader,
    ``coupling_sections.until_problem``): rows after it are every ``stride`` constant steps from it.
    """

    def __init__(self, error: ErrorControlled, constant: ConstantStep, until: float):
        self.error, self.constant, self.until = error, constant, float(until)
        self.t0, self.t_stop = error.t0, constant.t_stop
        self.n_offset: int | None = None     # the master's step count when the constant steps began
        # the progress estimate: the error-controlled part as if at macro_step, then the constant steps
        self.n_steps = error.n_steps + constant.n_steps
        self._on_rejected = None
        self.constant_taken = 0              # constant steps accepted after until

    # the master sets and reads these on the controller; they belong to one of the two parts
    needs_states = property(lambda self: self.constant.needs_states)
    h = property(lambda self: self.error.h)
    defect_halvings = property(lambda self: getattr(self.constant, "defect_halvings", 0))
    retried_steps = property(lambda self: getattr(self.constant, "retried_steps", 0))

    @property
    def variable(self) -> bool:
        return self.n_offset is None

    @property
    def defect(self):
        return getattr(self.constant, "defect", None)

    @defect.setter
    def defect(self, mon) -> None:
        self.constant.defect = mon

    @property
    def can_reject(self) -> bool:
        return self.error.can_reject

    @can_reject.setter
    def can_reject(self, value: bool) -> None:
        self.error.can_reject = value

    @property
    def on_rejected(self):
        return self._on_rejected

    @on_rejected.setter
    def on_rejected(self, fn) -> None:
        self._on_rejected = self.error.on_rejected = self.constant.on_rejected = fn

    def bind(self, names: list[str], connections, nominals=None) -> None:
        self.error.bind(names, connections, nominals)

    def time(self, n: int) -> float:
        if self.n_offset is None:
            return self.t0 if n == 0 else self.t_stop
        return self.constant.time(n - self.n_offset)

    def take_variable_step(self, stepper, t: float) -> tuple[float, bool]:
        t_end, on_out = self.error.take_variable_step(stepper, t)
        if t_end >= self.until:              # the error-controlled grid ends exactly at until
            self.n_offset = self.error.accepted
            self.n_steps = self.n_offset + self.constant.n_steps
            log.info("coupling.step_control.until: error-controlled up to t=%.12g s (%d steps), constant steps of "
                     "%g s from there (%d steps)", self.until, self.n_offset, self.constant.h, self.constant.n_steps)
        return t_end, on_out

    def take_step(self, stepper, t: float, t_next: float) -> None:
        self.constant.take_step(stepper, t, t_next)
        self.constant_taken += 1

    def is_output(self, n: int, stride: int) -> bool:
        """Does the constant step ending at the master's step ``n`` end on an output time (every
        ``stride`` steps from ``until``)?"""
        return (n - (self.n_offset or 0)) % stride == 0

    def over_tolerance_note(self) -> str | None:
        note = self.error.over_tolerance_note()
        n = self.error.accepted
        return note and note.replace(f" of {n} accepted macro steps ", f" of the {n} error-controlled macro steps "
                                     f"(up to step_control.until, {self.until:g} s) ", 1)

    def statistics(self) -> dict:
        """The constant part's counters at the top (``rejected_steps``, ``retried_steps``,
        ``retry_substeps``, ``defect_retried_steps``: discard and defect retries, which act after
        ``until`` only); ``step_control`` as for the error-controlled step (its counters cover the part
        before ``until``) with ``until``, ``constant_steps`` (macro steps after it) and
        ``constant_macro_step``."""
        st = self.constant.statistics()
        sc = dict(self.error.statistics()["step_control"])
        sc.update(until=self.until, constant_steps=self.constant_taken, constant_macro_step=self.constant.h)
        st["step_control"] = sc
        return st


def controller_from_spec(scenario) -> StepSizeController:
    """The controller of ``scenario.coupling`` (discard_retries or defect_retries > 0:
    :class:`DiscardHalving`; step_control type error: :class:`ErrorControlled`; type error with
    ``until``: :class:`ErrorThenConstant`, whose constant part after ``until`` is a DiscardHalving when
    discard_retries or defect_retries > 0)."""
    c = scenario.coupling
    n_retry = getattr(c, "discard_retries", 0)
    sc = getattr(c, "step_control", None)
    n_defect = getattr(c, "defect_retries", 0)
    until = getattr(sc, "until", None) if sc is not None else None
    if until is not None and sc.type != "error":
        raise ScenarioError(until_problem(sc, scenario.start_time, scenario.stop_time, c.macro_step))
    if sc is not None and sc.type == "error" and until is None and n_defect:
        raise ScenarioError("coupling.step_control type error and coupling.defect_retries cannot be combined "
                            "(the error-controlled step rejects steps on its own estimate of the same defect); "
                            "set defect_retries: 0, or give step_control.until (the time after which constant "
                            "steps, with defect_retries, take over)")
    if sc is not None and sc.type == "error":
        if n_retry and until is None:
            raise ScenarioError("coupling.step_control type error and coupling.discard_retries cannot be combined "
                                "(the error-controlled step has its own rejection); set discard_retries: 0, or give "
                                "step_control.until (the time after which constant steps, with discard_retries, "
                                "take over)")
        interval = scenario.output.interval or c.macro_step
        if until is not None:
            why = until_problem(sc, scenario.start_time, scenario.stop_time, interval)
            if why:
                raise ScenarioError(why)
        if until is not None and until_reaches_stop(until, scenario.start_time, scenario.stop_time, interval):
            log.info("coupling.step_control.until (%g s) is at or after stop_time (%g s): the whole run is "
                     "error-controlled", until, scenario.stop_time)
            until = None                 # no constant part (the retries keys have nothing to act on)
        error = ErrorControlled(sc, t0=scenario.start_time, t_stop=scenario.stop_time if until is None else until,
                                h0=c.macro_step, interval=interval,
                                # the iterative scheme's estimate is of order q+1 (coupling/iterative.py)
                                order=(c.interpolation_order if c.scheme == "iterative" else c.extrapolation_order) + 1,
                                ij_order=ij_order_of(c))
        if until is None:
            return error
        constant = (DiscardHalving(until, scenario.stop_time, c.macro_step, n_retry, defect_halvings=n_defect)
                    if n_retry or n_defect else ConstantStep(until, scenario.stop_time, c.macro_step))
        return ErrorThenConstant(error, constant, until)
    if n_retry or n_defect:
        return DiscardHalving(scenario.start_time, scenario.stop_time, c.macro_step, n_retry,
                              defect_halvings=n_defect)
    return ConstantStep(scenario.start_time, scenario.stop_time, c.macro_step)
