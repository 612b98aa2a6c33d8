"""Error-controlled macro step: a local error estimate from the coupling signals and a PI controller.

Local error estimate (explicit predictor / corrector indicator)
---------------------------------------------------------------
Over the macro step [T, T + H] the subsystems were fed the order-k Lagrange
prediction ``P_k`` of every coupling signal ``y``; after the step the signal's
actual value ``y(T + H)`` is known. Their difference is the extrapolation error
of the input, ``y(T + H) - P_k(T + H) = O(H^(k+1))``, the quantity that drives the
coupling error (Busch & Schweizer, "Numerical stability and accuracy of
different co-simulation techniques", Proc. Appl. Math. Mech. 10 (2010); Meyer,
Kraft & Schweizer, "Co-simulation: error estimation and macro-step size
control", J. Comput. Nonlinear Dyn. 16 (2021) 041002: predicted versus
corrected coupling variables; Kyllingstad, Sadjina & Skjong, "Error estimation
and step size control with minimal subsystem interfaces", arXiv:2406.17353
(2024): the "explicit predictor/corrector" indicator, which needs no rollback).
Per signal it is scaled as in Hairer, Norsett & Wanner, Solving ODEs I, sec.
II.4, eq. (4.11):

    err = sqrt( mean_i ( (y_i - P_i) / (atol_i + rtol * max(|y_i(T)|, |y_i(T+H)|)) )^2 )

so ``err <= 1`` means "within tolerance".

PI step-size controller
-----------------------
Gustafsson's PI controller in the form of Hairer & Wanner, Solving ODEs II,
sec. IV.2, eq. (2.43c)::

    H_new = H * min(fac_max, max(fac_min, safety * err^(-alpha) * err_old^beta)),
    alpha = 0.7 / p, beta = 0.4 / p,    p = k + 1 (the order of the estimate),

(K. Gustafsson, "Control theoretic techniques for stepsize selection in
explicit Runge-Kutta methods", ACM TOMS 17 (1991) 533-554). A step with
``err > 1`` is rejected and redone from the saved states with
``H * max(fac_min, safety * err^(-1/p))``; right after a rejection the step may not
grow (Hairer & Wanner I, sec. II.4). ``min_step`` and ``max_step`` bound every
proposal; a step at ``min_step`` is accepted whatever its error (counted as
``forced_steps``), so a run never stalls. A jump in a coupling signal (a
stiffness that switches, an event) gives an error that does not shrink with the
step: when an attempt at <= 0.3 of a step rejected at most 3 accepted steps
before (the controller closing in on the jump) still has >= 0.5 of its error,
both above 10, it is accepted as a jump (``jumps``; the master then restarts the
extrapolation from the new value, as ODE codes restart after a discontinuity).

Without state save/restore the controller cannot reject: it only adapts the
*next* step (``can_reject=False``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SAFETY = 0.9
FAC_MIN = 0.2
FAC_MAX = 5.0
ALPHA = 0.7        # PI gains (Hairer & Wanner II, IV.2, eq. (2.43c)), divided by the order p
BETA = 0.4
ERR_FLOOR = 1e-10  # err below this is taken as this (a step with no visible error grows by fac_max)
JUMP_STEP_RATIO = 0.3    # a rejected attempt at <= 0.3 of a recently rejected step whose error is
JUMP_ERROR_RATIO = 0.5   # still >= 0.5 of that one's is a jump in a signal: accepted
JUMP_MEMORY = 3          # "recently": at most this many accepted steps ago
JUMP_MIN_ERROR = 10.0    # and both errors above this (a step near a stability limit fails by ~1)
STRETCH = 1e-3           # next_stop takes a step up to (1 + STRETCH) x the proposal (no sliver steps);
                         # 0.1 was tried: 4x the rejections on the stiff two-mass (105 vs 29 of 525)
MIN_STEP_SLACK = 1.0 + 2 * STRETCH   # a step up to this x min_step counts as at min_step: next_stop
                         # stretches a step onto an output time, and rejecting such a step retried the
                         # same stretched step for ever (found by the rejection limit, adaptive.py)


def scaled_error_norm(predicted: np.ndarray, actual: np.ndarray, previous: np.ndarray, *,
                      rtol: float, atol: np.ndarray) -> tuple[float, int]:
    """RMS of the scaled prediction errors (module docstring) and the index of the largest.

    ``previous`` are the signals at the start of the step; ``atol`` a number or one per
    signal, where ``inf`` leaves the signal out (the mean is over the others). A non-finite
    error gives ``inf``.
    """
    sc = atol + rtol * np.maximum(np.abs(previous), np.abs(actual))
    e = (actual - predicted) / sc          # an atol of inf gives 0 (the signal is left out), NaN stays NaN
    n = int(np.count_nonzero(np.isfinite(atol))) if np.ndim(atol) else len(e)
    if not len(e) or not n:
        return 0.0, 0
    if not np.all(np.isfinite(e)):
        return math.inf, int(np.flatnonzero(~np.isfinite(e))[0])
    return float(math.sqrt(float(e @ e) / n)), int(np.argmax(np.abs(e)))


@dataclass(frozen=True)
class Decision:
    """``accept``: keep the step just taken; ``h_next``: the step to try next
    (the retry of a rejected step, or the following step)."""

    accept: bool
    h_next: float
    forced: bool = False       # accepted at min_step although err > 1
    jump: bool = False         # accepted as a jump in a signal (the error did not shrink with the step)


class PIController:
    """Macro-step PI controller (module docstring).

    Parameters
    ----------
    order : p, the order of the error estimate in H (extrapolation order + 1).
    min_step, max_step : bounds of every step [s].
    can_reject : False when some FMU cannot restore a saved state: every step is
        accepted and only the next one adapts.
    """

    def __init__(self, *, order: int, min_step: float, max_step: float, can_reject: bool = True,
                 safety: float = SAFETY, fac_min: float = FAC_MIN, fac_max: float = FAC_MAX):
        if not (0.0 < min_step <= max_step and math.isfinite(max_step)):
            raise ValueError(f"need 0 < min_step <= max_step < inf (got min_step={min_step!r}, "
                             f"max_step={max_step!r})")
        if order < 1:
            raise ValueError(f"order of the error estimate must be >= 1 (got {order!r})")
        self.p = int(order)
        self.min_step, self.max_step = float(min_step), float(max_step)
        self.can_reject = can_reject
        self.safety, self.fac_min, self.fac_max = float(safety), float(fac_min), float(fac_max)
        self.err_old = 1.0
        self.after_reject = False
        self.rejected = 0
        self.forced = 0
        self.jumps = 0
        self.over = 0              # accepted with err > 1: forced, jumps, and (can_reject False) every such step
        self._last_reject = None   # (h, err) of the last rejected attempt
        self._since_reject = 0     # accepted steps since then

    def _clip(self, h: float) -> float:
        return min(self.max_step, max(self.min_step, h))

    def discarded(self, h: float) -> float:
        """An attempt of size ``h`` that an FMU discarded (fmi2Discard): the retry's step, half of
        it (within the bounds); the next accepted step may not grow, as after a rejection."""
        self.after_reject = True
        return self._clip(0.5 * h)

    def decide(self, h: float, err: float, order: int | None = None) -> Decision:
        """Accept or reject the step of size ``h`` with scaled error ``err``; propose the next step
        (``order``: the estimate's order for this decision, when the signal that set ``err`` has
        another than ``p``)."""
        p = self.p if order is None else int(order)
        if not math.isfinite(err):
            err = 1e6
        if err > 1.0 and self.can_reject and h > self.min_step * MIN_STEP_SLACK:
            last = self._last_reject
            if (last is not None and self._since_reject <= JUMP_MEMORY and h <= JUMP_STEP_RATIO * last[0]
                    and err >= JUMP_ERROR_RATIO * last[1] and min(err, last[1]) > JUMP_MIN_ERROR):
                # the step shrank but the error did not: a jump in a signal, which no step resolves
                self._last_reject = None
                self.jumps += 1
                self.over += 1
                self.after_reject = False
                return Decision(True, h, jump=True)
            fac = max(self.fac_min, self.safety * err ** (-1.0 / p))
            self.after_reject = True
            self.rejected += 1
            if last is None or self._since_reject > JUMP_MEMORY:
                self._last_reject = (h, err)     # the first rejection of a cluster is the reference
            self._since_reject = 0
            return Decision(False, self._clip(h * min(fac, 1.0)))
        self._since_reject += 1
        forced = err > 1.0 and self.can_reject
        if forced:
            self.forced += 1
        if err > 1.0:
            self.over += 1
        e = max(err, ERR_FLOOR)
        fac = self.safety * e ** (-ALPHA / p) * max(self.err_old, ERR_FLOOR) ** (BETA / p)
        fac = min(self.fac_max, max(self.fac_min, fac))
        if self.after_reject:
            fac = min(fac, 1.0)
        self.after_reject = False
        self.err_old = max(err, 1e-4)          # Hairer's DOPRI5 keeps err_old >= 1e-4
        return Decision(True, self._clip(h * fac), forced)


def next_stop(t: float, h: float, output_times_after) -> tuple[float, bool]:
    """The end of the next step from ``t`` with proposal ``h``, landing on the next output time.

    ``output_times_after(t)`` gives the first output time > t. A step that would
    overshoot it is shortened to end on it; one that would stop within STRETCH h
    short of it is stretched onto it (no sliver steps). Returns ``(t_end, on_output)``.
    Splitting the way to the output time evenly instead (n = ceil(r / h) steps of r / n) was
    tried in session 4 and reverted: on the stepping stiffness 703 doSteps at error 4.9e-4
    against 673 at 4.4e-4, on ci_coupling 7 033 FMU calls at 7.8e-5 against 6 625 at 6.5e-5.
    """
    t_out = output_times_after(t)
    if t + h >= t_out - STRETCH * h:
        return t_out, True
    return t + h, False
