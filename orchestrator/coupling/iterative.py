"""Iterative (implicit) coupling: each macro step repeated from saved states until the signals agree.

``coupling.scheme: iterative`` with ``coupling.iteration: {max_iterations, tol,
acceleration}``. One macro step [T(n), T(n+1)]:

1. every FMU's state and the coupling history are saved at T(n);
2. the first iterate ``x_0`` of the interface vector (every coupling signal at
   T(n+1), as the consumers see it, after gain and offset) is the order-k
   extrapolation of the history (``extrapolation_order``);
3. a pass steps the subsystems in the Gauss-Seidel order (``coupling.sequence``)
   with *every* input following the current iterate over the step: the
   Lagrange polynomial through ``x_k`` at T(n+1) and the history at T(n),
   T(n-1), ... of order ``interpolation_order`` (1: the line between the values
   at both ends, as waveform iteration does; 0: held at ``x_k``), delivered as
   the explicit step delivers it (sub-step midpoints or input derivatives);
   a subsystem stepped later in the pass sees the new outputs of the earlier
   ones (serial-implicit coupling in preCICE's terms). The pass maps ``x_k`` to
   the signals it produced, ``G(x_k)``;
4. the step is converged when ``|G(x_k) - x_k| <= tol * scale`` for every signal,
   ``scale`` being the largest magnitude the signal has had in the run so far
   (or in this iteration); the FMU states after that pass are kept. Otherwise
   the states and the history are restored to T(n) and the next iterate
   comes from :mod:`orchestrator.coupling.acceleration` (none, aitken, iqn-ils);
5. a pass an FMU discards (fmi2Discard: e.g. a quasi-Newton update that moved a journal
   outside its bearing) is not a failure of the step but of the iterate: the next pass
   is at the middle between it and the last evaluated iterate (at most 8 times per
   step, :func:`~orchestrator.coupling.acceleration.solve_fixed_point`); a discard in
   the first pass (the extrapolated iterate, what an explicit step would feed) fails
   the step as in the explicit schemes (``discard_retries`` may then halve it);
6. not converged in ``max_iterations`` passes (or a non-finite signal): the run
   fails with a message naming the signal, its residual and what to change.
   (Halving the step instead was considered and not done: a step that does not
   converge at H is usually a sign of a coupling the chosen acceleration cannot
   handle, and a silent smaller step would hide it; the message says so.)

7. interface-Jacobian coefficients (the ``k..``/``c..`` inputs of a force that has its
   coefficients, :func:`~orchestrator.coupling.signal_scales.jacobian_groups`) are held at
   their first iterate during the passes (``coupling.iteration.hold_jacobian``, default
   true): they enter neither the convergence test nor the acceleration, and the step
   commits the values the FMUs produced in the kept pass, which the next step starts from.
   They linearise the force over the step for the receiving FMU, a preconditioner of the
   iteration rather than a coupled quantity: at convergence the force and the kinematics
   agree and the correction they scale vanishes at the step's nodes. Iterated with the
   other signals they made the map discontinuous (the film refreshes them by a rule,
   ``linearize_tol``) and the stiff asperity contact's first step from rest never converged
   (200 passes; docs/coupling.md "Iterative coupling": held, 5.8 passes per step).

The statistics count passes per macro step (``iterations``).

Local error estimate for the error-controlled step (``coupling.step_control: {type:
error}``, coupling/adaptive.py): after convergence the subsystems were fed the
order-q interpolant of the converged signals, so the coupling error of the step is
that interpolant's error, ``O(H^(q+1))``. It is estimated as the difference, at the
step's midpoint, between the fed interpolant (nodes T(n+1), T(n), ..., T(n+1-q)) and
the one of order q+1 (one older node more): orders q and q+1, as in Meyer, Kraft &
Schweizer, J. Comput. Nonlinear Dyn. 16 (2021) 041002 (:meth:`error_signals`). The
extrapolation error ``y(T+H) - P_k(T+H)`` the explicit scheme uses is *not* an
estimate here: it measures only how good the first iterate was (``O(H^(k+1))``, with
k = 0 the size of one step's change), and driving the step by it made a run with
``extrapolation_order: 0`` and a small ``atol`` creep at 1e-7 s steps for minutes.
"""

from __future__ import annotations

import math

import numpy as np

from orchestrator.coupling.acceleration import PassRejected, make_acceleration, solve_fixed_point
from orchestrator.coupling.macro_step import MacroStep
from orchestrator.coupling.signals import lagrange_weights
from orchestrator.errors import CouplingError, FmuCallError
from orchestrator.scenario.model import IterationSpec


STALL_HINT = 1e4        # a final residual within this x tol: the message also suggests a larger tol


def _above(r: float) -> float:
    """The power of ten above ``r`` (a tolerance the stalled residual meets)."""
    return 10.0 ** math.ceil(math.log10(r)) if r > 0 else r


class IterationStats:
    """Passes per macro step: total, largest, and a histogram ``{passes: steps}``."""

    def __init__(self):
        self.total = 0
        self.steps = 0
        self.max = 0
        self.histogram: dict[int, int] = {}

    def add(self, n: int) -> None:
        self.total += n
        self.steps += 1
        self.max = max(self.max, n)
        self.histogram[n] = self.histogram.get(n, 0) + 1

    def as_dict(self) -> dict:
        return {"total": self.total, "max_per_step": self.max,
                "mean_per_step": self.total / self.steps if self.steps else 0.0,
                "histogram": {str(k): v for k, v in sorted(self.histogram.items())}}


class IterativeMacroStep(MacroStep):
    """A :class:`MacroStep` whose ``step`` iterates to convergence (module docstring); every
    step-size controller (constant, discard halving, error-controlled) uses it unchanged.
    ``signal_names`` names the history store's columns for messages."""

    def __init__(self, plan, predictor, *, spec: IterationSpec, signal_names: list[str],
                 held: list[int] | tuple[int, ...] = (), **kw):
        super().__init__(plan, predictor, **kw)
        self.spec = spec
        self.names = signal_names
        # the interface-Jacobian coefficient columns held during a step's passes (module docstring, 7.)
        self.held = np.asarray(sorted(held), dtype=np.intp)
        self.acceleration = make_acceleration(spec.acceleration)
        self.stats = IterationStats()
        self.scale = np.zeros(len(signal_names))

    def prediction(self, t: float, h: float) -> np.ndarray:
        """Order-k extrapolation of every signal to T(n+1) from the history."""
        hist = self.history
        p = min(self.predictor.k, hist.count - 1)
        past = (hist.times[1:p + 2] - t) / h
        return lagrange_weights(past, [1.0])[0] @ hist.store[1:p + 2]

    @property
    def error_order(self) -> int:
        """Order in H of :meth:`error_signals` (q + 1): the PI controller's exponent."""
        return self.predictor.q + 1

    def error_signals(self):
        """After a committed step: ``(fed, higher)``, the fed order-q interpolant and the order-(q+1)
        one at the step's midpoint (module docstring), or None while the history is too short
        for the order-(q+1) interpolant (the controller then uses the prediction error)."""
        hist = self.history
        q = min(self.predictor.q, hist.count - 1)
        if hist.count < q + 2:
            return None
        t1, t0 = hist.times[1], hist.times[2]
        h = t1 - t0
        nodes = (hist.times[1:q + 3] - t0) / h           # 1, 0, -h1/h, ...
        store = hist.store
        fed = lagrange_weights(nodes[:q + 1], [0.5])[0] @ store[1:q + 2]
        higher = lagrange_weights(nodes, [0.5])[0] @ store[1:q + 3]
        return fed, higher

    def step(self, t: float, t_next: float) -> None:
        hist = self.history
        store = hist.store
        q = min(self.predictor.q, hist.count)
        self.scale = np.maximum(self.scale, np.abs(store[1]))
        for u in self.units:
            u.sub.no_set_prior_state = False
        cp = self.save()
        first = [True]
        x0 = self.prediction(t, t_next - t)
        held = self.held
        produced = [x0]             # the last pass's own outputs, held columns included

        def one_pass(x):
            if not first[0]:
                self.restore(cp)
            first[0] = False
            if len(held):
                x = x.copy()
                x[held] = x0[held]
            store[0] = x
            try:
                self.advance(t, t_next, commit=False, startup_q=q)
            except FmuCallError as e:       # an FMU refused this iterate: backtrack (acceleration.py)
                if e.status == "discard" and not self.fmu_ended(e):
                    raise PassRejected(e) from e
                raise
            g = store[0].copy()
            if len(held):
                produced[0] = g.copy()
                g[held] = x0[held]        # a fixed point in these columns: out of the test and the update
            return g

        try:
            res = solve_fixed_point(one_pass, x0, acceleration=self.acceleration,
                                    tol=self.spec.tol, scale=self.scale, max_iterations=self.spec.max_iterations)
            self.stats.add(res.iterations)
            if not res.converged:
                raise CouplingError(self._message(res, t, t_next))
            store[0] = res.x
            if len(held):
                store[0][held] = produced[0][held]     # what the FMUs computed in the kept pass
            hist.commit()
        finally:
            self.release(cp)

    def _message(self, res, t: float, t_next: float) -> str:
        name = self.names[res.worst] if self.names else "?"
        sp = self.spec
        what = ("became non-finite" if not math.isfinite(res.residual)
                else f"still changed by {res.residual:.3g} of its scale (tol {sp.tol:g})")
        hint = ("use acceleration: iqn-ils (plain and Aitken iteration diverge on stiff couplings)"
                if sp.acceleration != "iqn-ils" else "raise coupling.iteration.max_iterations")
        if math.isfinite(res.residual) and res.residual <= STALL_HINT * sp.tol:
            # close but not there: the FMUs' own solvers may not compute their outputs to tol
            # (measured: the mass-conserving films' Newton stalls a pass's outputs at 2.4e-6)
            hint += (f"; a residual this small may be as far as the FMUs compute their outputs (an internal "
                     f"solver's tolerance): then a coupling.iteration.tol above it, e.g. {_above(res.residual):g}, "
                     f"is the setting to change")
        return (f"iterative coupling did not converge in the macro step t={t:.12g}..{t_next:.12g} s: after "
                f"{res.iterations} pass(es) (coupling.iteration.max_iterations = {sp.max_iterations}, acceleration "
                f"{sp.acceleration}) the coupling signal {name} {what}. Rows up to t={t:.12g} s are kept. "
                f"Try a smaller coupling.macro_step, or {hint}")
