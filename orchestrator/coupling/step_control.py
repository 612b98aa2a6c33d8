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
* ``is_output(n, stride)`` (default: every ``stride`` steps) and ``over_tolerance_note()``
  (default None): which steps end on an output time, and what a finished run must say
  (adaptive.py's controllers answer both their own way).

:class:`ConstantStep` accepts every step or fails; :class:`DiscardHalving` rejects a
step an FMU discards (fmi2Discard, FMI 2.0 sec. 4.2.3) and redoes it in halves, and with
``coupling.defect_retries`` also a step whose coupling defect is over the limit
(:mod:`.defect`).
"""

from __future__ import annotations

import logging
import math

from orchestrator.errors import FmuCallError, ScenarioError
from orchestrator.scenario.limits import step_slack

log = logging.getLogger(__name__)

RETRY_LOG_LINES = 20              # INFO lines about retried macro steps before only counting them


class DefectOver(Exception):
    """A (sub-)step's coupling defect exceeded coupling.defect_limit x the typical force
    (coupling.defect_retries): it is redone in halves like a discarded one."""


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

    def is_output(self, n: int, stride: int) -> bool:
        """Does the constant step ending at the master's step ``n`` end on an output time?"""
        return n % stride == 0

    def over_tolerance_note(self) -> str | None:
        """What a finished run must say about steps accepted above a tolerance (error control), or None."""
        return None

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
    """Constant steps; a step an FMU discards is redone in halves, down to H / 2^max_halvings; with a
    defect monitor (``defect``, ``defect_halvings`` > 0: coupling.defect_retries) so is a step whose
    coupling defect is over the limit, down to H / 2^defect_halvings (a piece still over it there is
    accepted and counted by the monitor).

    Before each macro step every FMU's state and the coupling history are saved;
    on fmi2Discard both are restored and [t, t_next] is redone as two halves (each
    an ordinary step that commits its end point to the history, so later halves
    use the newest values like a run with the smaller step), recursively. Afterwards
    the history is rebuilt on the nominal grid, so the following macro steps
    extrapolate exactly as without the retry.
    """

    needs_states = True

    def __init__(self, t0: float, t_stop: float, h: float, max_halvings: int, *, defect_halvings: int = 0):
        super().__init__(t0, t_stop, h)
        self.max_halvings = max_halvings
        # coupling.defect_retries: a (sub-)step whose coupling defect is over the limit is redone in halves
        # while it is at most this many halvings deep (the monitor, ``defect``, is set by the master)
        self.defect_halvings = defect_halvings
        self.defect = None
        self.retried_steps = 0          # macro steps redone after a discard
        self.retry_substeps = 0         # extra doStep rounds (sub-intervals attempted) in those retries
        self.rejected_steps = 0         # (sub-)step attempts discarded and rolled back
        self._depth = 0
        self._unresolved = False        # a piece of this macro step stayed over the defect limit at the deepest level

    def statistics(self):
        st = {"rejected_steps": self.rejected_steps, "retried_steps": self.retried_steps,
              "retry_substeps": self.retry_substeps}
        if self.defect_halvings:
            # of retried_steps: those first rejected for their coupling defect (the monitor counts them)
            st["defect_retried_steps"] = self.defect.retried_steps if self.defect is not None else 0
        return st

    def _retryable(self, e: Exception, stepper, level: int) -> bool:
        """Reject-and-retry a defect over the limit, and fmi2Discard within coupling.discard_retries when
        the FMU did not end the simulation (fmi2Terminated); any other failure fails the step."""
        if isinstance(e, DefectOver):
            return True
        return e.status == "discard" and not stepper.fmu_ended(e) and level < self.max_halvings

    def _attempt(self, stepper, a: float, b: float, level: int) -> None:
        """Step [a, b], ``level`` halvings deep; with the defect monitor, judge its defect (DefectOver
        while ``level < defect_halvings``; accepted otherwise, and kept by the monitor)."""
        mon = self.defect
        if mon is None:
            stepper.step(a, b)
            return
        startup = stepper.starting()       # iterated from saved states: it integrated no prediction
        mon.before(stepper.history, a, b)
        stepper.step(a, b)
        if startup:
            mon.after(stepper.history, b, skip=True)
            return
        worst = mon.measure(stepper.history)
        if worst > 1.0 and level >= self.defect_halvings:
            self._unresolved = True
        elif worst > 1.0:
            mon.drop()
            raise DefectOver(f"coupling defect {worst * mon.limit:.3g}x the typical force over t={a:.12g}..{b:.12g} "
                             f"s (coupling.defect_limit {mon.limit:g}); redone in halves (coupling.defect_retries)")
        mon.accept(b, piece=level > 0)

    def take_step(self, stepper, t, t_next):
        cp = stepper.save()
        self._unresolved = False
        try:
            try:
                self._attempt(stepper, t, t_next, 0)
                return                                      # accept
            except (FmuCallError, DefectOver) as e:
                if not self._retryable(e, stepper, 0):
                    raise                                   # fail
                first = e
            self.retried_steps += 1                         # reject, retry in halves
            self.rejected_steps += 1
            over = isinstance(first, DefectOver)
            self._depth = 0
            rounds0 = self.retry_substeps
            self._split(stepper, t, t_next, 1, cp, first)
            stepper.keep_end_only(cp, t_next)
            if self.defect is not None:
                self.defect.commit(t_next)
                self.defect.retried_steps += over
                self.defect.unresolved_steps += over and self._unresolved
            if self.retried_steps <= RETRY_LOG_LINES:
                what = ("the coupling defect of the macro step t=%.12g..%.12g s was over coupling.defect_limit "
                        "(coupling.defect_retries)" % (t, t_next) if over else
                        "FMU instance '%s' discarded the macro step t=%.12g..%.12g s" % (first.instance, t, t_next))
                log.info("%s; redone from the saved states with %d halving(s) (smallest step %g s, %d extra step "
                         "rounds)%s", what, self._depth, (t_next - t) / 2 ** self._depth,
                         self.retry_substeps - rounds0,
                         "; further retried macro steps are only counted (statistics: retried_steps)"
                         if self.retried_steps == RETRY_LOG_LINES else "")
        finally:
            stepper.release(cp)

    def _split(self, stepper, t_a, t_b, level, cp_a, error) -> None:
        """Restore the checkpoint at ``t_a`` and do [t_a, t_b] as two halves; a half that is
        discarded again (or whose defect is over the limit) is split further while allowed."""
        stepper.restore(cp_a)
        self.on_rejected(t_a, t_b, error)
        self._depth = max(self._depth, level)
        t_m = t_a + 0.5 * (t_b - t_a)
        deepest = level >= max(self.max_halvings, self.defect_halvings)
        for a, b in ((t_a, t_m), (t_m, t_b)):
            # the first half starts from the restored state; at the deepest level nothing is reused
            cp = cp_a if (a == t_a or deepest) else stepper.save()
            try:
                self.retry_substeps += 1
                try:
                    self._attempt(stepper, a, b, level)
                except (FmuCallError, DefectOver) as e:
                    if not self._retryable(e, stepper, level):
                        if (isinstance(e, FmuCallError) and e.status == "discard" and not stepper.fmu_ended(e)
                                and self.max_halvings):
                            raise RetriesExhausted(e, a, b) from e
                        raise                   # failed, or discarded without discard_retries: as ConstantStep
                    self.rejected_steps += 1
                    self._split(stepper, a, b, level + 1, cp, e)
            finally:
                if cp is not cp_a:
                    stepper.release(cp)
