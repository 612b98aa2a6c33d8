"""The macro step T(n) -> T(n+1) over a :class:`~orchestrator.coupling.plan.Plan`.

For each unit in stepping order: the step's Lagrange weights (cached in the predictor,
:meth:`~orchestrator.coupling.signals.LagrangePredictor.step_weights`), the unit's input
delivery (:mod:`.delivery`), the outputs read at T(n+1) and sent through gain/offset
into the consumers' histories (:meth:`MacroStep.propagate`), NaN/inf stopped there.

Seam for iterative schemes and step-size control: :meth:`MacroStep.save` takes a
:class:`Checkpoint` (every FMU state and the history), :meth:`restore` goes back to
it, :meth:`release` frees it, and :meth:`advance` with ``commit=False`` computes the
new level T(n+1) without committing it, so a scheme can repeat the step from the
checkpoint (the start-up iteration, :meth:`startup_step`, does exactly that) and
commit once (``history.commit()``).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

from orchestrator.coupling.plan import Link, Plan, Unit
from orchestrator.coupling.signals import LagrangePredictor
from orchestrator.errors import CouplingError, FmuCallError
from orchestrator.scenario.limits import step_slack

log = logging.getLogger(__name__)


@dataclass
class Checkpoint:
    """Saved FMU states (one per unit, in stepping order), a history snapshot and the held
    non-Real signals (:meth:`orchestrator.coupling.discrete.DiscreteSignals.snapshot`)."""

    states: list
    snap: tuple
    disc: list


class MacroStep:
    """Advances the plan's units over one macro step (see the module docstring).

    ``startup_iterations``: repeat the first steps from saved states while the
    history is shorter than the extrapolation order (every FMU can save its state);
    ``no_prior``: value of ``noSetFMUStatePriorToCurrentPoint`` for ordinary steps.
    """

    def __init__(self, plan: Plan, predictor: LagrangePredictor, *, macro_step: float,
                 startup_iterations: bool, no_prior: bool, stages: list | None = None,
                 threads=None):
        self.plan = plan
        self.units = plan.units
        self.history = plan.history
        self.discrete = plan.discrete
        self.predictor = predictor
        self.macro_step = macro_step
        self.startup_iterations = startup_iterations
        self.no_prior = no_prior
        # (stage, members, members to step concurrently or None, step the members in threads);
        # default: one unit per stage
        self.stages = stages if stages is not None else [(None, [u], None, False) for u in self.units]
        # orchestrator.coupling.threads.StageThreads for the stages stepped in threads, or None
        self.threads = threads

    # ------------------------------------------------------------ checkpoints
    def save(self) -> Checkpoint:
        states = []
        try:
            for u in self.units:
                states.append(u.sub.get_state())
        except BaseException:
            self._free_states(states)
            raise
        return Checkpoint(states, self.history.snapshot(), self.discrete.snapshot())

    def snapshot(self, states: list) -> Checkpoint:
        """A checkpoint of already saved ``states`` and the history now."""
        return Checkpoint(states, self.history.snapshot(), self.discrete.snapshot())

    def restore(self, cp: Checkpoint) -> None:
        for u, s in zip(self.units, cp.states, strict=True):
            u.sub.set_state(s)
        self.history.restore(cp.snap)
        self.discrete.restore(cp.disc)

    def release(self, cp: Checkpoint) -> None:
        self._free_states(cp.states)

    def _free_states(self, states) -> None:
        for u, s in zip(self.units, states, strict=False):     # states may be partial
            try:
                u.sub.free_state(s)
            except FmuCallError as e:   # pragma: no cover - defensive
                log.warning("%s", e)

    def keep_end_only(self, cp: Checkpoint, t_next: float) -> None:
        """After sub-steps committed their end points since ``cp``: rebuild the history on the
        nominal grid, newest level ``t_next``, older levels those of ``cp``."""
        hist = self.history
        new_rows = [b[1].copy() for b in hist.blocks]
        hist.restore(cp.snap)
        hist.times[0] = t_next
        for b, r in zip(hist.blocks, new_rows, strict=True):
            b[0] = r
        hist.commit()

    def fmu_ended(self, e: FmuCallError) -> bool:
        """Did the FMU that discarded a step end the simulation (fmi2Terminated, FMI 2.0 sec. 4.2.3)?"""
        if e.status != "discard" or e.function != "fmi2DoStep":
            return False
        return any(u.name == e.instance and u.sub.terminated_by_fmu() for u in self.units)

    # ------------------------------------------------------------------ steps
    def starting(self) -> bool:
        """The next step is a start-up iteration (repeated from saved states while the history is
        shorter than the extrapolation order), not an ordinary step on the prediction."""
        return bool(self.startup_iterations) and self.history.count < self.predictor.k

    def step(self, t: float, t_next: float) -> None:
        """One ordinary step [t, t_next] (start-up iteration while the history is short)."""
        if self.starting():
            self.startup_step(t, t_next)
        else:
            self.advance(t, t_next)

    def startup_step(self, t: float, t_next: float) -> None:
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
        dsnap = self.discrete.snapshot()
        for u in self.units:
            u.sub.no_set_prior_state = False      # we will restore the saved state
        try:
            self.advance(t, t_next, commit=False)
            q = min(self.predictor.k, hist.count)
            for _ in range(self.predictor.k):
                new_rows = [b[0].copy() for b in hist.blocks]
                for u, s in zip(self.units, states):
                    u.sub.set_state(s)
                hist.restore(snap)
                self.discrete.restore(dsnap)
                for b, r in zip(hist.blocks, new_rows):
                    b[0] = r
                self.advance(t, t_next, commit=False, startup_q=q)
            hist.commit()
            self.discrete.commit()
        finally:
            for u in self.units:
                u.sub.no_set_prior_state = self.no_prior
            for u, s in zip(self.units, states):
                try:
                    u.sub.free_state(s)
                except FmuCallError as e:   # pragma: no cover - defensive
                    log.warning("%s", e)

    def advance(self, t: float, t_next: float, *, commit: bool = True, startup_q: int | None = None) -> None:
        """Every unit over [t, t_next]; the new level T(n+1) is committed unless ``commit=False``.

        A whole macro step is passed to the FMUs as ``macro_step`` itself, not as ``t_next - t``:
        the grid times t0 + n*H differ by H only up to rounding (0.3 - 0.2 = 0.09999999999999998;
        at t0 = 1e6 by 1e-9 H), and an FMU that cannot vary its step size compares every
        communicationStepSize with its first one (FMPy and libcosim pass H too)."""
        h = t_next - t
        H = self.macro_step
        if h != H and abs(h - H) <= step_slack(t, t_next, H) * H:   # only rounding made it differ
            h = H
        hist = self.history
        hist.times[0] = t_next
        predictor = self.predictor
        discrete = self.discrete
        for st, members, together, threaded in self.stages:
            if threaded and self.threads is not None and st.concurrent(startup=startup_q is not None):
                self.advance_threaded(members, t, h, t_next, startup_q)
                continue
            if together is not None and st.concurrent(startup=startup_q is not None):
                for u in together:           # every member's inputs and doSteps sent: workers compute now
                    w = predictor.step_weights(hist, t, h, u.substeps, q=startup_q)
                    if u.disc:
                        discrete.set_inputs(u.name)
                    u.delivery.advance(u, w, t, h)
                    u.sub.request_real(u.outb)
                self.collect(together, t_next)
                continue
            for u in members:
                w = predictor.step_weights(hist, t, h, u.substeps, q=startup_q)
                if u.disc:
                    discrete.set_inputs(u.name)          # non-Real inputs: held over the whole step
                u.delivery.advance(u, w, t, h)
                u.sub.get_real(u.outb)
                self.propagate(u, t_next)
                if u.disc:
                    discrete.read(u.name)
        if commit:
            hist.commit()
            if discrete.active:
                discrete.commit()

    def advance_threaded(self, members: list, t: float, h: float, t_next: float,
                         startup_q: int | None) -> None:
        """The members of one stage over [t, t + h] at the same time, on the master's threads
        (``coupling.parallel: threads``, :mod:`.threads`). The weights and non-Real inputs are
        set here first; the threads only deliver the inputs, doStep and read the outputs of
        their own unit; the outputs are then propagated in stepping order, and the first
        failure in stepping order is raised once every member has finished."""
        predictor, discrete = self.predictor, self.discrete
        jobs = []
        for u in members:
            w = predictor.step_weights(self.history, t, h, u.substeps, q=startup_q)
            if u.disc:
                discrete.set_inputs(u.name)
            jobs.append(_StepJob(u, w, t, h))
        errors = self.threads.run(jobs)
        for u, e in zip(members, errors, strict=True):
            if e is not None:
                raise e
            self.propagate(u, t_next)
            if u.disc:
                discrete.read(u.name)

    def collect(self, members: list, t_next: float) -> None:
        """The outputs of a concurrently stepped stage, in order; every member's reply is read
        before the first failure is raised (a worker must not be left with an unread reply)."""
        first = None
        for u in members:
            try:
                u.sub.receive_real(u.outb)
                if first is None:
                    self.propagate(u, t_next)
                    if u.disc:
                        self.discrete.read(u.name)
            except (FmuCallError, CouplingError) as e:
                first = first or e
        if first is not None:
            raise first

    def read_outputs(self, t: float, ask_first: list | None = None) -> None:
        """Every unit's outputs now into the consumers' newest level, in stepping order (the
        initial exchange at t0: nothing reaches an FMU between these reads).

        ``ask_first``: the units in worker processes (``coupling.parallel``). Each is asked first
        (``request_real``), the in-process units are read while the workers compute, then the
        workers' replies (a bearing FMU builds its film at its first output: numba kernels and
        the stationary film, about a second each, so these run at the same time). Propagation
        and the error raised follow stepping order, so the result is that of one read after
        the other; every asked worker's reply is read before a failure is raised.
        """
        asked = ask_first or []
        if not asked or len(self.units) < 2:
            for u in self.units:
                u.sub.get_real(u.outb)
                self.propagate(u, t)
            return
        for u in asked:
            u.sub.request_real(u.outb)
        errors: dict[str, Exception] = {}
        for u in self.units:
            if u not in asked and not errors:
                try:
                    u.sub.get_real(u.outb)
                except (FmuCallError, CouplingError) as e:
                    errors[u.name] = e
        for u in asked:
            try:
                u.sub.receive_real(u.outb)
            except (FmuCallError, CouplingError) as e:
                errors[u.name] = e
        for u in self.units:                 # every unit before the first failure was read
            if u.name in errors:
                raise errors[u.name]
            self.propagate(u, t)

    def propagate(self, u: Unit, t: float) -> None:
        """Unit ``u``'s outputs (in ``u.outb``) through gain/offset into the consumers' new level."""
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

    def _nonfinite(self, u: Unit, lk: Link, name: str, value: float, t: float):
        raise CouplingError(
            f"coupling signal {name} is {float(value)} at t={t:.12g} s (output of '{u.name}'); "
            "the coupled system is probably unstable at this macro step or the FMU failed silently. "
            f"Try a smaller coupling.macro_step (now {self.macro_step:g}), a lower "
            "extrapolation_order, or the gauss-seidel scheme")


class _StepJob:
    """One member's part of a threaded stage: input delivery, doSteps, output read."""

    __slots__ = ("u", "w", "t", "h")

    def __init__(self, u, w, t: float, h: float):
        self.u, self.w, self.t, self.h = u, w, t, h

    def __call__(self) -> None:
        u = self.u
        u.delivery.advance(u, self.w, self.t, self.h)
        u.sub.get_real(u.outb)
