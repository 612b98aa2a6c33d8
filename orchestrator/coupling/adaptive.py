"""Error-controlled macro step for the master (``coupling.step_control: {type: error, ...}``).

Per attempt from T(n) with proposal h (the first is ``coupling.macro_step``):

1. the step end is ``t_end = next_stop(T(n), h)``: the next output time if the step
   would reach or cross it (results rows stay on the output grid), else T(n) + h;
2. the order-k prediction ``P`` of every coupling signal at ``t_end`` is taken from the
   history (what an explicit step feeds; the iterative scheme's first iterate);
3. the step is taken by the configured scheme (explicit, iterative, with discard
   retries); its outputs at ``t_end`` are ``y``;
4. ``err = scaled_error_norm(P, y, y(T(n)))`` (error_control.py) goes to the PI
   controller: accept, or reject -> every FMU state and the history are restored
   to T(n) (saved before the attempt), observers get ``on_step_rejected``, and the
   attempt is redone with the smaller proposal. A step accepted as a jump restarts
   the extrapolation (history order 0) from the value after it.

A step shortened to land on an output time does not shrink the next proposal
below the one that was cut. FMUs that cannot save and restore their state
(canGetAndSetFMUstate false): no rejection, the step adapts forward only (the
controller sees every error, so the next step still follows the dynamics); the
master says so at setup and ``validate`` reports it (scenario/coupling_sections.py). FMUs that cannot take
varying steps (canHandleVariableCommunicationStepSize false) are refused.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from orchestrator.coupling.error_control import PIController, next_stop, scaled_error_norm
from orchestrator.coupling.signals import lagrange_weights
from orchestrator.coupling.step_control import StepSizeController
from orchestrator.scenario.model import StepControlSpec

log = logging.getLogger(__name__)
MIN_STEP_FRACTION = 1e-3      # default min_step = macro_step * this


class OutputGrid:
    """Output times ``t0 + j * interval`` (from the index), the last one ``t_stop``."""

    def __init__(self, t0: float, t_stop: float, interval: float):
        self.t0, self.t_stop, self.interval = float(t0), float(t_stop), float(interval)

    def after(self, t: float) -> float:
        j = math.floor((t - self.t0) / self.interval + 1e-9) + 1
        return min(self.t0 + j * self.interval, self.t_stop)


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
                 order: int):
        self.spec = spec
        self.t0, self.t_stop = float(t0), float(t_stop)
        self.grid = OutputGrid(t0, t_stop, interval)
        self.n_steps = max(1, math.ceil((t_stop - t0) / h0 - 1e-9))
        min_step = spec.min_step if spec.min_step is not None else h0 * MIN_STEP_FRACTION
        max_step = spec.max_step if spec.max_step is not None else interval
        self.pi = PIController(order=order, min_step=min(min_step, max_step), max_step=max_step)
        self.h = min(max(h0, self.pi.min_step), self.pi.max_step)
        self.accepted = 0
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

    def take_variable_step(self, stepper, t: float) -> tuple[float, bool]:
        """Take one accepted step from ``t``; returns ``(t_end, on_output_time)``."""
        hist = stepper.history
        atol = self.spec.atol
        while True:
            h = self.h
            t_end, on_out = next_stop(t, h, self.grid.after)
            pred = self.prediction(stepper, t, t_end)
            prev = hist.store[1].copy()
            cp = stepper.save() if self.can_reject else None
            try:
                stepper.step(t, t_end)
                err, _ = scaled_error_norm(pred, hist.store[1], prev, rtol=self.spec.rtol, atol=atol)
                d = self.pi.decide(t_end - t, err)
                if not d.accept:
                    stepper.restore(cp)
                    self.on_rejected(t, t_end, RuntimeError(f"scaled error {err:.3g} > 1"))
                    self.h = d.h_next
                    continue
            finally:
                if cp is not None:
                    stepper.release(cp)
            if d.jump:          # restart the extrapolation from the value after the jump
                hist.count = min(hist.count, 1)
            self.h = max(d.h_next, h) if (on_out and t_end - t < h and err <= 1.0) else d.h_next
            self.accepted += 1
            self.h_min_taken = min(self.h_min_taken, t_end - t)
            self.h_max_taken = max(self.h_max_taken, t_end - t)
            return t_end, on_out

    def statistics(self) -> dict:
        return {"rejected_steps": 0, "retried_steps": 0, "retry_substeps": 0,
                "step_control": {"type": "error", "accepted_steps": self.accepted,
                                 "rejected_steps": self.pi.rejected, "forced_steps": self.pi.forced,
                                 "jumps": self.pi.jumps, "can_reject": self.can_reject,
                                 "min_step_taken": self.h_min_taken if self.accepted else None,
                                 "max_step_taken": self.h_max_taken if self.accepted else None}}
