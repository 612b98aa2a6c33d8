"""Cavitation laws: the smooth fluid fraction theta(p) and its universal variable.

Mass-conserving two-phase model of Nowald et al. (2016) as used in the paper
(``/work/shared/paper/transient-run-up-mass-conserving-cavitation.md``, eq. 3-4,
figure 2): the mixture density and viscosity are proportional to a
pressure-dependent fluid fraction, ``rho/rho0 = eta/eta0 = theta(p)``, a smooth
step that is 1 in the full film (p >= p0) and falls towards 0 just below p0.

Why a universal variable
------------------------
With p itself as the Newton unknown and a tanh-shaped step, Newton failed at
every step (issue 3): in the cavity ``dtheta/dp`` is huge and the pressure
is nearly constant, so the Jacobian is badly scaled and the iteration cycles.
We therefore use an Elrod-type universal variable ``u`` (Elrod 1981; Shi and
Paranjpe 2002; Alakhramsing et al. 2015 use Boolean switches instead), with a
*smooth* (softplus = logarithmic) regularisation so that Newton sees a
C-infinity map:

    p(u)     = p_cav + K * delta * softplus(u / delta)
    theta(u) = 1 - delta * softplus(-u / delta)
    softplus(x) = ln(1 + exp(x))

so that for ``u >> delta`` (full film) ``theta ~ 1`` and ``p - p_cav ~ K u``,
and for ``u << -delta`` (cavity) ``p ~ p_cav`` and ``theta ~ 1 + u``
(Elrod's two branches). Eliminating u gives ONE fixed relation

    theta(p) = 1 + delta * ln(1 - exp(-(p - p_cav) / (K delta)))

(figure 2 shape: theta ~ 0 at p = p_cav, 1 a few ``K delta`` above), so the
change of unknown does not change the model, only the Newton iteration.
Note ``dp/du / K + dtheta/du = 1`` everywhere: the Jacobian never degenerates.

Parameters (see :class:`bearing_fmu.model.BearingParams`):

* ``cav_width`` w [Pa]: the step lies between ``p_cav = p0 - w`` and p0;
  the shoulder scale is ``s = K delta = w / 3`` so that theta(p0) = 1 + delta
  ln(1 - e^-3) (~ 1 - 0.05 delta). The cavity pressure is thus ``p0 - w``:
  "slightly below ambient" as in the paper's figures 5 and 7.
* ``cav_smoothing`` delta [-]: width of the switch in u (Newton smoothness).

Free-to-air penalty (paper eq. 6, figure 3): outward axial flux
``g(p) = a_z * [a x + (b - a) q(x)]`` with ``x = p - p0``, i.e.
slope ``a`` (0.01) for p < p0 and slope ``b`` (1e4; model.BearingParams says why
not the paper's 100) for p > p0, evaluated at the edge pressure (:func:`penalty_edge`), the kink
rounded by a C1 quadratic over ``|x| < penalty_smoothing`` (10 Pa, below
cav_width so that the cavity sees exactly ``a x``). Units: g is a flux in the units of the scaled Reynolds equation (eq. 2
divided by rho0, [1/s] per unit dimensionless length); ``a_z = (R/B)^2
psi^2 / (6 eta0)`` [1/(Pa s)] is the axial film conductance of the nominal
gap (H = 1) over the whole width, so ``b = 1e4`` means the edge resistance is
0.01 % of the nominal film's axial resistance and ``a = 0.01`` that sub-ambient
suction is 100 times weaker than that of the nominal film. This scaling makes
a and b grid- and unit-independent, which is why we chose it.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

#: shoulder scale ``s = K delta`` as a fraction of ``cav_width``
SHOULDER = 1.0 / 3.0


@nb.njit(cache=True, inline="always")
def softplus(x):
    """ln(1 + e^x), overflow-free."""
    if x > 0.0:
        return x + math.log1p(math.exp(-x))
    return math.log1p(math.exp(x))


@nb.njit(cache=True, inline="always")
def sigmoid(x):
    """1 / (1 + e^-x), overflow-free (derivative of softplus)."""
    if x >= 0.0:
        return 1.0 / (1.0 + math.exp(-x))
    e = math.exp(x)
    return e / (1.0 + e)


@nb.njit(cache=True, nogil=True)
def law_eval(u, p_cav, K, delta, p_out, dp_out, th_out, dth_out, e_out=None, l1_out=None,
             valid=None):
    """Evaluate p(u), dp/du, theta(u), dtheta/du for an array u (in place).

    The four functions of x = u / delta share ``e = exp(-|x|)`` and ``log1p(e)``: one exp
    and one log1p per cell instead of four and two, bit for bit what :func:`softplus` and
    :func:`sigmoid` return (the same operations on the same operands). ``e_out``,
    ``l1_out``, if given, receive e and log1p(e) (for :func:`.solver.dominant_update`,
    which needs the same two of the same u). ``valid`` (uint8, with e_out and l1_out), if
    given: where it is set, e_out and l1_out already hold e and log1p(e) of this u (the
    Newton update computed them, :func:`.solver.dominant_update`) and are read instead."""
    for k in range(u.size):
        x = u[k] / delta
        if valid is not None and valid[k]:
            e = e_out[k]
            l1 = l1_out[k]
        else:
            e = math.exp(-abs(x))
            l1 = math.log1p(e)
            if e_out is not None:
                e_out[k] = e
                l1_out[k] = l1
        if x > 0.0:
            sp_pos, sp_neg = x + l1, l1          # softplus(x), softplus(-x)
        else:
            sp_pos, sp_neg = l1, -x + l1
        if x >= 0.0:
            sg_pos = 1.0 / (1.0 + e)             # sigmoid(x)
        else:
            sg_pos = e / (1.0 + e)
        if -x >= 0.0:
            sg_neg = 1.0 / (1.0 + e)             # sigmoid(-x)
        else:
            sg_neg = e / (1.0 + e)
        p_out[k] = p_cav + K * delta * sp_pos
        dp_out[k] = K * sg_pos
        th_out[k] = 1.0 - delta * sp_neg
        dth_out[k] = sg_neg


@nb.njit(cache=True, inline="always")
def penalty(x, a, b, s, a_z):
    """Outward edge flux g(p) of eq. (6) and dg/dp; ``x = p - p0``.

    ``g = a_z [a x + (b - a) q(x)]`` with the C1 ramp ``q = 0`` for x <= -s,
    ``(x + s)^2 / (4 s)`` for |x| < s, ``x`` for x >= s: slope a below p0 - s,
    slope b above p0 + s, and EXACTLY ``a x`` at the cavity pressure as long as
    s < cav_width (no spurious outflow from the cavity).
    """
    if x <= -s:
        q, dq = 0.0, 0.0
    elif x < s:
        q, dq = (x + s) * (x + s) / (4.0 * s), (x + s) / (2.0 * s)
    else:
        q, dq = x, 1.0
    return a_z * (a * x + (b - a) * q), a_z * (a + (b - a) * dq)


@nb.njit(cache=True, inline="always")
def penalty_edge(xc, k, a, b, s, a_z):
    """Outward edge flux of an edge cell under the free-to-air condition, and its
    derivative with respect to the cell pressure; ``xc = p_cell - p0``, ``k`` the
    conductance of the half cell between the cell centre and the edge (``2 a_z H^3 / dz``).

    Eq. (6) prescribes the flux at the EDGE, ``q = g(p_edge)`` (:func:`penalty`). The edge
    pressure follows from the flux continuity through the half cell,

        k (xc - xe) = g(xe),      xe = p_edge - p0,

    solved exactly on each branch of g (slope a below -s, slope b above s, the C1
    quadratic between: a quadratic in xe, its stable root). Returns (q, dq/dxc) with
    ``dq/dxc = k g' / (k + g')`` (implicit differentiation). For b -> infinity this is the
    oil bath's half-cell Dirichlet flux ``k xc``, so the full film converges at second
    order to the Dirichlet solution; in the cavity (xc = -cav_width < -s) it is the
    inflow ``k a_z a xc / (k + a_z a)``, as weak as ``g(xc)`` (no spurious refilling).
    Evaluating g at the cell centre (the scheme before this function) put the edge half
    a cell inside the film: first order, -5 % load at 40 axial cells (B/D 0.5, eps 0.8).
    """
    ga = a_z * a
    gb = a_z * b
    if k * (xc + s) + ga * s <= 0.0:            # xe <= -s: g = a_z a xe
        xe = k * xc / (k + ga)
        gp = ga
    elif k * (xc - s) - gb * s >= 0.0:          # xe >= s: g = a_z b xe
        xe = k * xc / (k + gb)
        gp = gb
    else:                                        # |xe| < s: A y^2 + B y - C = 0, y = xe + s
        A = a_z * (b - a) / (4.0 * s)
        B = k + ga
        Cc = B * s + k * xc
        y = 2.0 * Cc / (B + math.sqrt(B * B + 4.0 * A * Cc))
        xe = y - s
        gp = ga + a_z * (b - a) * y / (2.0 * s)
    return k * (xc - xe), k * gp / (k + gp)


class CavitationLaw:
    """theta(p) and the universal-variable map for given parameters.

    Parameters
    ----------
    p0 : ambient pressure [Pa]
    width : ``cav_width`` [Pa] (> 0)
    delta : ``cav_smoothing`` [-] (> 0)
    """

    def __init__(self, p0: float, width: float, delta: float):
        self.p0 = float(p0)
        self.width = float(width)
        self.delta = float(delta)
        self.p_cav = self.p0 - self.width
        self.s = SHOULDER * self.width
        self.K = self.s / self.delta

    def p_theta(self, u):
        """Return (p, theta) arrays for universal variable u."""
        u = np.ascontiguousarray(u, dtype=float).ravel()
        p, dp, th, dth = (np.empty_like(u) for _ in range(4))
        law_eval(u, self.p_cav, self.K, self.delta, p, dp, th, dth)
        return p, th

    def u_from_p(self, p):
        """Universal variable of a full-film-branch pressure (p > p_cav).

        Inverse of p(u): ``u = delta * ln(exp((p - p_cav)/(K delta)) - 1)``.
        """
        y = (np.asarray(p, dtype=float) - self.p_cav) / (self.K * self.delta)
        if np.any(y <= 0.0):
            raise ValueError(
                f"u_from_p: pressure must exceed the cavity pressure p_cav = "
                f"{self.p_cav:g} Pa (got min {np.min(p):g} Pa)")
        # ln(e^y - 1) = y + ln(1 - e^-y), stable for large y
        return self.delta * (y + np.log(-np.expm1(-y)))

    def theta_of_p(self, p):
        """The fluid fraction relation theta(p) (figure 2); nan for p <= p_cav."""
        y = (np.asarray(p, dtype=float) - self.p_cav) / (self.K * self.delta)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(y > 0, 1.0 + self.delta * np.log(-np.expm1(-y)), np.nan)
