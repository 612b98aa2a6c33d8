"""Step-size control: the macro-step grid and what happens when a step attempt fails.

Protocol (rules for implementers, in the style of scipy's ``OdeSolver``):

* ``n_steps`` and ``time(n)``: the nominal grid; T(n) is computed from the index,
  never accumulated; ``time(n_steps)`` is stop_time. The master asks ``time(n)``
  and ``time(n + 1)`` before each macro step: that is the *next step* decision.
* ``take_step(stepper, t, t_next)``: do the macro step [t, t_next] with ``stepper``
  (a :class:`~orchestrator.coupling.macro_step.MacroStep`: ``step``, ``save``,
  ``restore``, ``release``, ``keep_end_only``) and *decide* on every attempt:
  **accept** (return normally: the history's newest level is ``t_next``),
  **reject and retry** (roll back to a checkpoint, call ``on_rejected(t_a, t_b, error)``,
  redo the interval in smaller pieces), or **fail** (raise: :class:`FmuCallError`,
  :class:`~orchestrator.errors.CouplingError` or :class:`RetriesExhausted`; the master
  turns these into a FAILED status).
* ``needs_states``: True when the controller restores FMU states (the master then
  refuses FMUs without ``canGetAndSetFMUstate`` and tells the FMUs that a prior
  state may be set).
* ``statistics()``: counters for summary.json (``rejected_steps``, ``retried_steps``,
  ``retry_substeps``).

:class:`ConstantStep` accepts every step or fails; :class:`DiscardHalving` rejects a
step an FMU discards (fmi2Discard, FMI 2.0 sec. 4.2.3) and redoes it in halves.
"""

from __future__ import annotations

import logging
import math

from orchestrator.errors import FmuCallError, ScenarioError
from orchestrator.scenario.limits import step_slack

log = logging.getLogger(__name__)

RETRY_LOG_LINES = 20              # INFO lines about retried macro steps before only counting them


class RetriesExhausted(Exception):
    """A sub-step at the smallest allowed step (H / 2^N) was discarded again."""

    def __init__(self, error: FmuCallError, t_a: float, t_b: float):
        super().__init__(str(error))
        self.error, self.t_a, self.t_b = error, t_a, t_b


class StepSizeController:
    """Base of the controllers (the protocol is in the module docstring)."""

    n_steps: int
    needs_states: bool = False

    def time(self, n: int) -> float:
        raise NotImplementedError

    def take_step(self, stepper, t: float, t_next: float) -> None:
        raise NotImplementedError

    def statistics(self) -> dict:
        return {"rejected_steps": 0, "retried_steps": 0, "retry_substeps": 0}

    def on_rejected(self, t_a: float, t_b: float, error: Exception) -> None:
        """Called after each rejected attempt, once it is rolled back (the master sets it
        to tell the observers, ``on_step_rejected``)."""


class ConstantStep(StepSizeController):
    """T(n) = t0 + n*H; the last step is shortened to end exactly at stop_time
    (a remainder that rounding of the times alone can make, 1e-9*H or more at large times,
    :func:`~orchestrator.scenario.limits.step_slack`, is absorbed, not stepped). Accepts every step."""

    def __init__(self, t0: float, t_stop: float, h: float):
        if not (h > 0 and math.isfinite(h)):
            raise ScenarioError(f"coupling.macro_step must be a positive number (got {h!r})")
        if not t_stop > t0:
            raise ScenarioError(f"stop_time ({t_stop}) must be greater than start_time ({t0})")
        self.t0, self.t_stop, self.h = float(t0), float(t_stop), float(h)
        slack = step_slack(self.t0, self.t_stop, self.h)
        self.n_steps = max(1, math.ceil((self.t_stop - self.t0) / self.h - slack))

    def time(self, n: int) -> float:
        if n >= self.n_steps:
            return self.t_stop
        return self.t0 + n * self.h

    def take_step(self, stepper, t, t_next):
        stepper.step(t, t_next)


class DiscardHalving(ConstantStep):
    """Constant steps; a step an FMU discards is redone in halves, down to H / 2^max_halvings.

    Before each macro step every FMU's state and the coupling history are saved;
    on fmi2Discard both are restored and [t, t_next] is redone as two halves (each
    an ordinary step that commits its end point to the history, so later halves
    use the newest values like a run with the smaller step), recursively. Afterwards
    the history is rebuilt on the nominal grid, so the following macro steps
    extrapolate exactly as without the retry.
    """

    needs_states = True

    def __init__(self, t0: float, t_stop: float, h: float, max_halvings: int):
        super().__init__(t0, t_stop, h)
        self.max_halvings = max_halvings
        self.retried_steps = 0          # macro steps redone after a discard
        self.retry_substeps = 0         # extra doStep rounds (sub-intervals attempted) in those retries
        self.rejected_steps = 0         # (sub-)step attempts discarded and rolled back
        self._depth = 0

    def statistics(self):
        return {"rejected_steps": self.rejected_steps, "retried_steps": self.retried_steps,
                "retry_substeps": self.retry_substeps}

    @staticmethod
    def _retryable(e: FmuCallError, stepper) -> bool:
        """Reject-and-retry only fmi2Discard, and not when the FMU ended the simulation (fmi2Terminated);
        any other failure fails the step."""
        return e.status == "discard" and not stepper.fmu_ended(e)

    def take_step(self, stepper, t, t_next):
        cp = stepper.save()
        try:
            try:
                stepper.step(t, t_next)
                return                                      # accept
            except FmuCallError as e:
                if not self._retryable(e, stepper):
                    raise                                   # fail
                first = e
            self.retried_steps += 1                         # reject, retry in halves
            self.rejected_steps += 1
            self._depth = 0
            rounds0 = self.retry_substeps
            self._split(stepper, t, t_next, 1, cp, first)
            stepper.keep_end_only(cp, t_next)
            if self.retried_steps <= RETRY_LOG_LINES:
                log.info("FMU instance '%s' discarded the macro step t=%.12g..%.12g s; redone from the saved "
                         "states with %d halving(s) (smallest step %g s, %d extra step rounds)%s", first.instance,
                         t, t_next, self._depth, (t_next - t) / 2 ** self._depth,
                         self.retry_substeps - rounds0,
                         "; further retried macro steps are only counted (statistics: retried_steps)"
                         if self.retried_steps == RETRY_LOG_LINES else "")
        finally:
            stepper.release(cp)

    def _split(self, stepper, t_a, t_b, level, cp_a, error) -> None:
        """Restore the checkpoint at ``t_a`` and do [t_a, t_b] as two halves; a half that is
        discarded again is split further while ``level < max_halvings``."""
        stepper.restore(cp_a)
        self.on_rejected(t_a, t_b, error)
        self._depth = max(self._depth, level)
        t_m = t_a + 0.5 * (t_b - t_a)
        deepest = level >= self.max_halvings
        for a, b in ((t_a, t_m), (t_m, t_b)):
            # the first half starts from the restored state; at the deepest level nothing is reused
            cp = cp_a if (a == t_a or deepest) else stepper.save()
            try:
                self.retry_substeps += 1
                try:
                    stepper.step(a, b)
                except FmuCallError as e:
                    if not self._retryable(e, stepper):
                        raise
                    if deepest:
                        raise RetriesExhausted(e, a, b) from e
                    self.rejected_steps += 1
                    self._split(stepper, a, b, level + 1, cp, e)
            finally:
                if cp is not cp_a:
                    stepper.release(cp)
