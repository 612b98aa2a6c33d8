"""Floating-ring bearing: parameters and quasi-static relations (no FMI import).

Split out of :mod:`bearing_fmu.floating_ring` (which re-exports every name here): the
parameter set :class:`RingParams`, Petroff's torque coefficient and the concentric ring speed
ratio, the films' wall-shear torques (:func:`shear_torques`), the static equilibrium of journal
and ring (:func:`static_equilibrium`) and the ring bearing's step coefficients
(:func:`step_coefficients`). Physics and equations: the module doc of
:mod:`bearing_fmu.floating_ring` and docs/floating-ring.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields as dc_fields

import numpy as np

from .model import BearingParams, BearingModel, StepFailed

#: accepted ranges (inclusive) of the ring's own parameters, declared by the FloatingRingBearing FMU
#: (modelDescription.xml min/max: refused when a scenario is loaded) and checked by RingParams:
#: ``h_ring: 1e-300`` asked for 1e296 ring sub-steps per FMU step (the run hung), ``m_ring: 1e300``
#: made `stability` say "raise the lower end of --speeds"
RING_RANGES: dict[str, tuple[float, float, str]] = {
    "m_ring": (1e-6, 1e3, "kg"),
    "J_ring": (1e-12, 1e6, "kg m^2"),         # a test holds the spin with J_ring = 1e3
    "h_ring": (1e-8, 1.0, "s"),
    "gravity": (-1e4, 1e4, "m/s^2"),
}
#: ring sub-steps of one FMU step at most (ceil(dt / h_ring); the shipped run-ups take one or two)
MAX_RING_SUBSTEPS = 1_000_000

__all__ = ["RingParams", "shear_torques", "petroff_coefficient", "petroff_ratio",
           "static_equilibrium", "step_coefficients"]


@dataclass(frozen=True, kw_only=True)
class RingParams:
    """Floating-ring bearing: the two films and the ring (SI units).

    inner: film between journal and ring bore (``R`` the journal radius, ``psi`` its
    relative clearance); outer: film between ring and housing (``R`` the ring's outer
    radius). m_ring [kg], J_ring [kg m^2] ring mass and polar inertia; floating: 1 full
    floating (spin free), 0 semi-floating (spin locked, translation free); gravity
    [m/s^2] acting on the ring in -y; h_ring [s] largest ring sub-step inside a step;
    jacobian_every: the films' coefficients (ring integration and :meth:`FloatingRing.linearization`)
    are recomputed after every jacobian_every-th step and held in between (1: every step);
    input_hold: journal inputs inside a step, 0 zero-order hold (the new input over the whole
    step, FMI semantics), 1 first-order hold (linear from the previous step's input to the new
    one: second order in time when the master steps the bearing after the rotor, Gauss-Seidel),
    2 cubic Hermite (position and velocity of the previous and the new input, consistent);
    ring_integrator: 0 linearly implicit BDF2, 1 exponential (the ring's ODE linearised at each
    sub-step's start integrated exactly for the held or interpolated input; module doc of
    :mod:`bearing_fmu.floating_ring`).
    """

    inner: BearingParams
    outer: BearingParams
    m_ring: float = 0.01
    J_ring: float = 1.0e-6
    floating: int = 1
    gravity: float = 9.81
    h_ring: float = 1.0e-4
    jacobian_every: int = 1
    input_hold: int = 2
    ring_integrator: int = 1

    def __post_init__(self):
        problems = []
        for name in ("inner", "outer"):
            v = getattr(self, name)
            if not isinstance(v, BearingParams):
                problems.append(f"RingParams.{name} must be a BearingParams (got {type(v).__name__})")
            elif v.contact:
                problems.append(f"RingParams.{name}.contact must be 0: asperity contact is not "
                                "modelled in the floating-ring bearing (got 1)")
        for name, (lo, hi, unit) in RING_RANGES.items():
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and lo <= v <= hi):
                problems.append(f"RingParams.{name} must be a finite number in [{lo:g}, {hi:g}] {unit} (got {v!r})")
        if not (isinstance(self.jacobian_every, int) and self.jacobian_every >= 1):
            problems.append(f"RingParams.jacobian_every must be an integer >= 1 (got {self.jacobian_every!r})")
        if self.input_hold not in (0, 1, 2):
            problems.append(f"RingParams.input_hold must be 0 (zero-order hold), 1 (first-order hold) "
                            f"or 2 (cubic Hermite) (got {self.input_hold!r})")
        if self.ring_integrator not in (0, 1):
            problems.append(f"RingParams.ring_integrator must be 0 (BDF2) or 1 (exponential) "
                            f"(got {self.ring_integrator!r})")
        if self.floating not in (0, 1):
            problems.append(f"RingParams.floating must be 1 (full floating) or 0 (semi-floating) "
                            f"(got {self.floating!r})")
        if not problems and self.outer.R <= self.inner.R * (1 + self.inner.psi):
            problems.append(f"RingParams: the ring's outer radius R_outer = {self.outer.R:g} m must exceed "
                            f"its bore R_inner (1 + psi_inner) = {self.inner.R * (1 + self.inner.psi):g} m")
        if problems:
            raise ValueError("invalid floating-ring parameters:\n  " + "\n  ".join(problems))

    def replace(self, **kw) -> "RingParams":
        vals = {f.name: getattr(self, f.name) for f in dc_fields(self)}
        vals.update(kw)
        return RingParams(**vals)


def petroff_coefficient(p: BearingParams) -> float:
    """``eta0 R^3 B / c`` [N m s]: Petroff's torque is ``-2 pi`` times this times the slip."""
    return p.eta0 * p.R ** 3 * p.B / p.c


def petroff_ratio(params: RingParams) -> float:
    """Steady ring speed ratio Omega / omega of two concentric full films: a / (a + b)
    with a = eta_i R_i^3 B_i / c_i, b = eta_o R_o^3 B_o / c_o (Petroff torque balance)."""
    a, b = petroff_coefficient(params.inner), petroff_coefficient(params.outer)
    return a / (a + b)


def shear_torques(fields: dict, x: float, y: float, c: float, R: float, B: float, eta0: float,
                  omega_j: float, omega_s: float, omega_film: float) -> tuple[float, float]:
    """(T_journal, T_shell) [N m] about +z: wall-shear torques of a film ON its journal
    (inner surface, speed ``omega_j``) and ON its shell (outer surface, ``omega_s``).

    ``fields`` from :meth:`BearingModel.fields` (full grid), (x, y) the journal centre
    relative to the shell's. Shear at the phi-faces as in :func:`.film.integrals`: the gap
    at the face, the fluid fraction from the upwind cell of the film's Couette transport
    (``omega_film = omega_j + omega_s``), the pressure gradient across the face (module doc).
    """
    phi, p, th = fields["phi"], fields["p"], fields["theta"]
    n_z, n_phi = p.shape
    dphi = 2 * math.pi / n_phi
    phi_e = phi + 0.5 * dphi
    h_e = c - x * np.cos(phi_e) - y * np.sin(phi_e)                 # (n_phi,) [m]
    th_up = th if omega_film >= 0 else np.roll(th, -1, axis=1)
    dpdx = (np.roll(p, -1, axis=1) - p) / (R * dphi)
    couette = th_up * eta0 * R * (omega_j - omega_s) / h_e         # eta (U_j - U_s) / h
    poise = 0.5 * h_e * dpdx
    dA = R * dphi * B / n_z
    T_j = R * float(np.sum(-couette - poise)) * dA
    T_s = R * float(np.sum(couette - poise)) * dA
    return T_j, T_s


def _film_balance(b: BearingModel, F_target, omega, max_iter=60):
    """Journal position (x, y) [m] in film ``b`` at which its quasi-static force at spin
    ``omega`` is ``F_target``: :func:`.linearize.hs_static_equilibrium` (Newton with the film
    stiffness, kept inside 0.98 c, from (0, -0.3 c), residual below 1e-10 of the load)."""
    from .linearize import HSEquilibriumError, hs_static_equilibrium
    try:
        return hs_static_equilibrium(b, F_target, omega, guess=(0.0, -0.3 * b.c), ftol=1e-10,
                                     max_iter=max_iter, max_ecc=0.98)
    except HSEquilibriumError as exc:
        raise StepFailed(f"static_equilibrium: no film position carries {F_target} N at omega = {omega:g} "
                         f"rad/s: the load is too high for this film ({exc})") from None


def static_equilibrium(params: RingParams, load: float, omega: float, omega_ring=None):
    """Static equilibrium of a journal carrying ``load`` [N] (downwards, -y) in a floating-ring
    bearing at journal speed ``omega``: returns ((x, y) journal, (x_r, y_r) ring) [m].

    The inner film carries the load (F_i = (0, load)), the outer film the load plus the ring
    weight (F_o = F_i + m_r g e_y), each at its own spin (omega + Omega, Omega); Omega defaults
    to the concentric Petroff ratio times omega (0 semi-floating). Quasi-static (half-Sommerfeld)
    films, as :meth:`FloatingRing.equilibrium`."""
    Om = (petroff_ratio(params) * omega if omega_ring is None else omega_ring) if params.floating else 0.0
    inner, outer = BearingModel(params.inner), BearingModel(params.outer)
    e = _film_balance(inner, np.array([0.0, load]), omega + Om)
    r = _film_balance(outer, np.array([0.0, load + params.m_ring * params.gravity]), Om)
    return (float(r[0] + e[0]), float(r[1] + e[1])), (float(r[0]), float(r[1]))


def step_coefficients(Ki, Ci, Ko, Co, m_ring, H):
    """(K, C) of the ring bearing seen by the journal over a step H [s] (module doc)."""
    from scipy.linalg import expm
    Z, I = np.zeros((2, 2)), np.eye(2)
    G = np.block([[Z, I, Z, Z],
                  [-(Ki + Ko) / m_ring, -(Ci + Co) / m_ring, Ki / m_ring, Ci / m_ring],
                  [Z, Z, Z, Z], [Z, Z, Z, Z]])
    Phi = expm(H * G)[:4, 4:]                  # ring (r, w) at H per held input (x_j, v_j)
    resp = Ki @ Phi[:2] + Ci @ Phi[2:]        # force from the ring's motion, per input
    return Ki - resp[:, :2], Ci - resp[:, 2:]
