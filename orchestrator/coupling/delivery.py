"""Input delivery: how one unit's input polynomials reach its FMU within a macro step.

Chosen once per unit at setup (:func:`choose_delivery`); the macro step calls
``delivery.advance(unit, w, t, h)`` with the step's :class:`~orchestrator.coupling.signals.StepWeights`.
Every policy ends with the inputs set to their value at T(n+1) (so outputs with direct
feedthrough are read consistently) and the subsystem stepped from ``t`` to ``t + h`` in
``unit.substeps`` equal sub-steps:

* :class:`NoInputs`: nothing to set, only doStep calls;
* :class:`HeldAtMidpoints`: the input held at the polynomial's value at each sub-step's
  midpoint (second-order accurate in the sub-step, docs/coupling.md);
* :class:`InputDerivatives`: value and time derivatives at each sub-step start through
  fmi2SetRealInputDerivatives (FMUs that declare ``canInterpolateInputs``).
"""

from __future__ import annotations

import numpy as np

from orchestrator.scenario.model import MAX_ORDER


class InputDelivery:
    """Rules for implementers: ``advance`` does the doStep calls of one unit for [t, t + h],
    sets the inputs at T(n+1) last and reads nothing (the macro step reads the outputs)."""

    def advance(self, u, w, t: float, h: float) -> None:
        raise NotImplementedError


def _operands(u, w, h):
    """What a delivery with inputs works on: subsystem, sub-steps, block sizes, the input
    values buffer, the sub-step size and the history rows the weights apply to."""
    m = u.substeps
    return u.sub, m, u.nE, u.nI, u.inb.values, h / m, u.HE[w.e0:w.e1], u.HI[0:w.q + 1]


class NoInputs(InputDelivery):
    def advance(self, u, w, t, h):
        sub, m = u.sub, u.substeps
        hs = h / m
        for i in range(m):
            sub.do_step(t + i * hs, hs)


class HeldAtMidpoints(InputDelivery):
    def advance(self, u, w, t, h):
        sub, m, nE, nI, vals, hs, HE, HI = _operands(u, w, h)
        for i in range(m):
            if nE:
                np.dot(w.extrap[i], HE, out=vals[:nE])
            if nI:
                np.dot(w.interp[i], HI, out=vals[nE:])
            sub.set_real(u.inb)
            sub.do_step(t + i * hs, hs)
        if not ((w.end_same_e or not nE) and (w.end_same_i or not nI)):
            if nE:
                np.dot(w.extrap_end, HE, out=vals[:nE])
            if nI:
                np.dot(w.interp_end, HI, out=vals[nE:])
            sub.set_real(u.inb)


class InputDerivatives(InputDelivery):
    def advance(self, u, w, t, h):
        sub, m, nE, nI, vals, hs, HE, HI = _operands(u, w, h)
        der = u.derb.values.reshape(MAX_ORDER, nE + nI)
        for i in range(m):
            if nE:
                np.dot(w.extrap_start[i], HE, out=vals[:nE])
                der[:, :nE] = w.extrap_der[i] @ HE
            if nI:
                np.dot(w.interp_start[i], HI, out=vals[nE:])
                der[:, nE:] = w.interp_der[i] @ HI
            sub.set_real(u.inb)
            sub.set_real_input_derivatives(u.derb)
            sub.do_step(t + i * hs, hs)
        if nE:
            np.dot(w.extrap_end, HE, out=vals[:nE])
        if nI:
            np.dot(w.interp_end, HI, out=vals[nE:])
        sub.set_real(u.inb)


NO_INPUTS, HELD_AT_MIDPOINTS, INPUT_DERIVATIVES = NoInputs(), HeldAtMidpoints(), InputDerivatives()


def choose_delivery(u) -> InputDelivery:
    """The policy of unit ``u`` (after its batches are made): derivatives when the FMU can
    interpolate inputs, held values when it has inputs, else none."""
    if u.derb is not None:
        return INPUT_DERIVATIVES
    return HELD_AT_MIDPOINTS if (u.nE or u.nI) else NO_INPUTS
