"""Linearized film coefficients for interface-Jacobian coupling (docs/stiff-coupling.md).

``linearization(bearing) -> (K, C)``: 2x2 stiffness ``K = -dF/dr`` [N/m] and damping
``C = -dF/dv`` [N s/m] (r = (x, y), v = (vx, vy), F = film force ON the journal,
x-y frame of docs/dev/contracts.md) at the bearing's current state, without changing
it. The rotor uses them to integrate the film force's first-order variation over a
macro step implicitly (Kuebler & Schiehlen 2000; Sicklinger et al. 2014, "Interface
Jacobian-based co-simulation", IJNME 98(6); Schweizer & Lu 2015); they only need to
be accurate enough to stabilize, the converged answer does not depend on them.

* Half-Sommerfeld (``cavitation = 0``, quasi-static): central finite differences of
  the discrete quasi-static force ``F(x, y, vx, vy, omega)`` (the same DST/cyclic
  tridiagonal solver and force integral as :meth:`JournalBearing.step`). The 8 perturbed
  pressure fields are ``P0 +- s dP/dz`` from ONE tangent solve
  (:meth:`.hs.HalfSommerfeld.solve_tangent`: the base field and its 4 directional
  derivatives, each axial mode factored once), equal to the 8 perturbed solves of
  :func:`hs_linearization_fd` (the former path, one batched solve) to O(s^2), which cancels
  in the central difference: the coefficients agree to ~5e-9 relative (tests), in
  0.59 vs 0.90 ms (interleaved, 40 x 40, load ~8). Steps ``dx = rel_step c`` and ``dv = rel_step max(c |omega|, |v|, c / t_ref)``.
  The clipped pressure ``max(P, 0)`` makes F piecewise smooth; where a cell switches
  inside the stencil the result is the mean of the one-sided slopes (the classical
  linearized coefficients of the short bearing, Lund 1987 / Childs 1993 sec. 3.6,
  are the limit; see the tests vs ``reference.short_bearing_coefficients``).

* Static equilibrium (:func:`hs_static_equilibrium`): the journal position at rest where the
  half-Sommerfeld force balances a static load (Newton with the coefficients above); the
  coefficients of the linear stability analyses are taken there.

* Mass-conserving (``cavitation = 1``, transient): by default (and in the FMU) the
  half-Sommerfeld coefficients at the same kinematics (see :func:`linearization` for
  the measured reasons). With ``method="film"``: the instantaneous sensitivity of
  the film force to the journal kinematics with the film history held, i.e. of the
  last implicit (BDF1/2) step ``R(u; kin) = 0`` the film took::

      dF/dkin = dF/du|kin (du/dkin) + dF/dkin|u,   du/dkin = -J^-1 dR/dkin,

  with ``J = dR/du`` the exact stencil Jacobian at the accepted solution (own band
  LU, the solver's factorisation and buffers are not touched), ``dR/dkin`` and
  ``dF/dkin|u`` by central differences in the kinematics, ``dF/du (du)`` by a central
  directional difference through the cavitation law. The full-film part of the
  Reynolds equation is elliptic, so its squeeze response is instantaneous and
  captured exactly; the theta transport in the cavity responds over the BDF step
  ``h`` only (the held history). Before the first film step (no BDF history yet) the
  half-Sommerfeld coefficients at the same kinematics are returned (documented
  approximation; they have the right squeeze-damping magnitude).

* Mass-conserving film about its STEADY state, with its theta dynamics (for linear stability,
  not for the coupling): :func:`mc_impedance` / :class:`MCFilmLinear`, the frequency-dependent
  impedance ``Z(s) = -(F_q + s F_v) + F_u (s M + J_s)^-1 (R_q + s R_v)`` of the semi-discrete
  film ``M du/dt + J_s du + R_q dq + R_v dq' = 0`` (docs/analysis.md, "Linear threshold of the
  mass-conserving film (film impedance)").
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from scipy.linalg import lapack

from .contact import H_AVG, average_gap, contact_coefficients, contact_force
from .film import assemble, assemble_muscl, hs_force_pressure, integrals, stencil_to_band
from .grid import _gap
from .hs import _tangent_modes

__all__ = ["linearization", "hs_force", "film_force_at", "hs_static_equilibrium", "HSEquilibriumError",
           "mc_impedance", "MCFilmLinear", "mc_static_equilibrium"]


def _kin(b, x, y, vx, vy, omega, grid=None):
    H, He, Hdot = b.gap(x, y, vx, vy, grid)
    return (H, He, Hdot, float(omega))


def _force(b, p, th, kin, film=True):
    """Force of fields on the transient solver's grid (``film=True``: b.grid, which
    is the lower half of the width when ``b.sym``) or on the full grid."""
    H, He, Hdot, omega = kin
    prm = b.params
    sym = bool(film and b.sym)
    g = b.grid if film else b.grid_full
    Fx, Fy, *_ = integrals(
        np.ascontiguousarray(p).ravel(), np.ascontiguousarray(th).ravel(), H, He, g.groove,
        g.phi, omega, b.a_phi, b.a_z, g.dphi, g.dz, b.bath, b.p0, prm.penalty_a,
        prm.penalty_b, prm.penalty_smoothing, prm.R, prm.B, b.c, prm.eta0, sym,
        prm.theta_transport if film else 0, g.wrel, g.frel, b.law.delta, b.law.K)
    return np.array([Fx, Fy])


def hs_force(b, x, y, vx, vy, omega) -> np.ndarray:
    """Quasi-static half-Sommerfeld film force [N] (2,) of bearing ``b`` at the given
    kinematics; side-effect free (any ``cavitation`` setting)."""
    kin = _kin(b, x, y, vx, vy, omega, b.grid_full)
    p = b._hs_pressure(kin)
    return _force(b, p, np.ones_like(p), kin, film=False)


def _central(f, z0, steps):
    """-(df/dz) by central differences: columns j = 0..3 over z = (x, y, vx, vy)."""
    D = np.empty((2, 4))
    for j in range(4):
        zp, zm = z0.copy(), z0.copy()
        zp[j] += steps[j]
        zm[j] -= steps[j]
        D[:, j] = -(f(zp) - f(zm)) / (2.0 * steps[j])
    return D


@nb.njit(cache=True, nogil=True)
def _hs_forces_many(P, phi, p0, area, F):
    """Half-Sommerfeld forces F (m, 2) of m unclipped gauge pressure fields P (m, n_z, n_phi):
    the cell pressures of the force quadrature (:func:`.film.hs_force_pressure`, exactly
    what ``JournalBearing._hs_pressure`` returns, minus p0) summed as
    :func:`.film.integrals` sums Fx, Fy (same order and operations, so each row equals
    ``_force(b, b._hs_pressure(kin), ..., film=False)`` bit for bit)."""
    m, n_z, n_phi = P.shape
    pf = np.empty((n_z, n_phi))
    for k in range(m):
        hs_force_pressure(P[k], pf)
        Fx = 0.0
        Fy = 0.0
        for i in range(n_phi):
            cs = math.cos(phi[i])
            sn = math.sin(phi[i])
            for j in range(n_z):
                p = p0 + pf[j, i]
                Fx -= (p - p0) * cs
                Fy -= (p - p0) * sn
        F[k, 0] = Fx * area
        F[k, 1] = Fy * area


def hs_forces_many(b, Z, omega) -> np.ndarray:
    """:func:`hs_force` at m kinematics ``Z`` (m, 4) rows (x, y, vx, vy), one omega: (m, 2) [N].
    One batched half-Sommerfeld solve (:meth:`.hs.HalfSommerfeld.solve_many`); equal to m
    :func:`hs_force` calls to round-off (tests/test_interface_jacobian_bearing.py)."""
    g = b.grid_full
    c = b.c
    prm = b.params
    x, y, vx, vy = (Z[:, k:k + 1] for k in range(4))
    cs, sn = np.cos(g.phi), np.sin(g.phi)           # the operations of Grid.gap
    H = 1.0 - (x * cs + y * sn) / c
    He = 1.0 - (x * np.cos(g.phi_e) + y * np.sin(g.phi_e)) / c
    Hdot = -(vx * cs + vy * sn) / c
    if prm.contact:     # the expected gap of the roughness, as JournalBearing.gap
        H, He, Hdot = average_gap(H, He, Hdot, prm.sigma_rough / c)
    P = b.hs.solve_many(H, He, Hdot, float(omega))
    F = np.empty((Z.shape[0], 2))
    _hs_forces_many(P, g.phi, b.p0, prm.R * g.dphi * prm.B * g.dz, F)
    return F


def _central_many(fm, z0, steps):
    """:func:`_central` with the 8 perturbed evaluations in one call ``fm(Z) -> (8, 2)``."""
    Z = np.empty((8, 4))
    for j in range(4):
        zp, zm = z0.copy(), z0.copy()
        zp[j] += steps[j]
        zm[j] -= steps[j]
        Z[2 * j], Z[2 * j + 1] = zp, zm
    F = fm(Z)
    D = np.empty((2, 4))
    for j in range(4):
        D[:, j] = -(F[2 * j] - F[2 * j + 1]) / (2.0 * steps[j])
    return D


def _steps(b, z, omega, rel_step, t_ref):
    c = b.c
    dv = rel_step * max(c * abs(omega), float(np.hypot(z[2], z[3])), c / t_ref)
    return np.array([rel_step * c, rel_step * c, dv, dv])


def hs_linearization(b, x, y, vx, vy, omega, *, rel_step=1e-5, t_ref=1e-3, with_force=False):
    """(K, C) of the half-Sommerfeld force at the given kinematics (see module doc); with
    ``with_force``, (F, K, C): F the force itself [N] (2,), from the tangent solve's base field
    (:func:`_hs_coefficients`; equal to :func:`hs_force` to round-off, not bit for bit: another
    DST path and, for a field symmetric about the mid-plane, half the rows weighted 2), or
    :func:`hs_force` where the finite differences are taken instead. The
    central differences of :func:`hs_linearization_fd`, with the 8 perturbed pressure
    fields ``P0 +- s dP/dz`` from ONE tangent solve (:meth:`.hs.HalfSommerfeld.solve_tangent`:
    the base field and its 4 directional derivatives, one factorisation per axial mode)
    instead of 8 solves. The pressure is linear in the squeeze velocity and smooth in the
    position, so the fields agree with the perturbed solves to O(s^2) and the differences,
    where those terms cancel, to round-off; the force of each field (the clipping and the
    rupture inside the cells) is computed exactly as there. With asperity contact
    (``contact = 1``) the film sees the expected gap of the roughness, a nonlinear map of the
    nominal gap below 8 roughness heights (:func:`.contact.average_gap`): above it (the journal
    away from the shell, most of a run that starts from rest) the expected gap is the nominal
    one exactly and the tangent solve is the one without contact; below it the tangent solve
    takes the expected gap and its directions by the chain rule through the map
    (:func:`_rough_tangent`, which leaves the entries above it alone; the map is smooth:
    dh_T/dh = Phi(h / sigma)), again equal to :func:`hs_linearization_fd` with contact to
    O(s^2) (tests/test_hs_batched.py). Issue 16: 0.07 instead of 0.4 ms a call away from the
    shell; on the shell (the contact phase of a run from rest, the turbocharger's rub) 0.05
    instead of 0.32 ms (40 x 40, one process, nothing else running)."""
    z0 = np.array([x, y, vx, vy], dtype=float)
    steps = _steps(b, z0, omega, rel_step, t_ref)
    # with contact the expected gap of the roughness (_rough_tangent leaves every entry at or
    # above 8 sigma as it is, so away from the shell this is the tangent solve without contact)
    rough = b.params.sigma_rough / b.c if b.params.contact else 0.0
    g = b.grid_full
    hs = b.hs
    cs, sn, ce, se, dH, dHe, dHdot = _tangent_directions(b)
    D = np.empty((2, 4))
    F0 = np.empty(2)
    _hs_coefficients(float(x), float(y), float(vx), float(vy), float(omega), b.c, cs, sn, ce, se,
                     dH, dHe, dHdot, g.dz, g.dphi, hs.a_phi, g.dphi * hs.a_z / g.dz, hs.lam, hs.ck,
                     hs.gr, hs.feed_hat, *hs.coefficient_rows, steps, g.phi,
                     b.params.R * g.dphi * b.params.B * g.dz, D, F0, rough)
    if with_force:
        return F0, D[:, :2].copy(), D[:, 2:].copy()
    return D[:, :2].copy(), D[:, 2:].copy()


@nb.njit(cache=True, nogil=True)
def _rough_tangent(H, He, Hdot, dH, dHe, dHdot, s):
    """The expected gap of Gaussian roughness (``s = sigma / c``; :func:`.contact.average_gap`,
    with Phi from ``erfc`` instead of scipy's ``ndtr``, the same to ~1e-16) at the centres, the
    east faces and for dH/dt, and the directions (m, n) of each carried through the map by the
    chain rule: h_T = s (hs Phi(hs) + phi(hs)) with hs = H / s, so dh_T = Phi dH, and
    dh_T/dt = Phi Hdot, so d(dh_T/dt) = phi(hs) / s dH Hdot + Phi dHdot (Patir & Cheng's
    expected gap, Greenwood & Tripp roughness; the map and its slope are those of
    average_gap, unchanged where hs >= 8). Returns (H_T, He_T, Hdot_T, dH_T, dHe_T, dHdot_T)."""
    n = H.size
    m = dH.shape[0]
    HT, HeT, HdT = H.copy(), He.copy(), Hdot.copy()
    dHT, dHeT, dHdT = dH.copy(), dHe.copy(), dHdot.copy()
    r2 = math.sqrt(2.0)
    r2pi = math.sqrt(2.0 * math.pi)
    for i in range(n):
        hs = H[i] / s
        if hs < H_AVG:
            Phi = 0.5 * math.erfc(-hs / r2)
            ph = math.exp(-0.5 * hs * hs) / r2pi
            HT[i] = s * (hs * Phi + ph)
            HdT[i] = Hdot[i] * Phi
            for r in range(m):
                dHT[r, i] = Phi * dH[r, i]
                dHdT[r, i] = ph / s * dH[r, i] * Hdot[i] + Phi * dHdot[r, i]
        he = He[i] / s
        if he < H_AVG:
            Phe = 0.5 * math.erfc(-he / r2)
            HeT[i] = s * (he * Phe + math.exp(-0.5 * he * he) / r2pi)
            for r in range(m):
                dHeT[r, i] = Phe * dHe[r, i]
    return HT, HeT, HdT, dHT, dHeT, dHdT


@nb.njit(cache=True, nogil=True)
def _hs_coefficients(x, y, vx, vy, omega, c, cs, sn, ce, se, dH, dHe, dHdot, dz, dphi, a_phi,
                     coef, lam, ck, groove, feed_hat, Mh, modes, wrow, steps, phi, area, D, F0,
                     rough=0.0):
    """:func:`hs_linearization` after its steps, in one call without the GIL: the gap (the
    operations of ``Grid.gap``), the tangent solve (:func:`.hs._tangent_modes`), the inverse
    DST-II of every field as a product with ``Mh`` (rows and mode columns of
    :meth:`.hs.HalfSommerfeld.idst_matrix`, :meth:`.hs.HalfSommerfeld.coefficient_rows`;
    equal to scipy's transform to round-off) and the central differences
    (:func:`_hs_central_tangent`, row r of the fields weighted ``wrow[r]``), into ``D``
    (2, 4), and the force of the base field into ``F0`` (2,). ``modes``: the axial modes that
    carry the fields (the others are exactly zero). ``rough`` > 0: the film sees the expected
    gap of roughness sigma = rough c (:func:`_rough_tangent`)."""
    n = cs.size
    m = dH.shape[0]
    n_z = lam.size
    H, He, Hdot = _gap(x, y, vx, vy, c, cs, sn, ce, se)
    if rough > 0.0:
        H, He, Hdot, dH, dHe, dHdot = _rough_tangent(H, He, Hdot, dH, dHe, dHdot, rough)
    X = np.empty((m + 1, n_z, n))
    _tangent_modes(H, He, Hdot, omega, dH, dHe, dHdot, dz, dphi, a_phi, coef, lam, ck, groove,
                   feed_hat, X)
    Xh = np.empty((m + 1, modes.size, n))
    for f in range(m + 1):
        for q in range(modes.size):
            Xh[f, q] = X[f, modes[q]]
    rows = Mh.shape[0]
    P0 = np.dot(Mh, Xh[0])
    dP = np.empty((m, rows, n))
    for r in range(m):
        dP[r] = np.dot(Mh, Xh[r + 1])
    _hs_central_tangent(P0, dP, steps, phi, area, D, wrow, F0)


def _tangent_directions(b):
    """cos, sin of the cell centres and east faces and the gap directions (dH, dHe, dHdot)
    (4, n_phi) of x, y, vx, vy on the full grid, kept on the bearing (they depend on the grid
    and the clearance only)."""
    d = getattr(b, "_hs_tangent_dirs", None)
    if d is None:
        g, c = b.grid_full, b.c
        cs, sn = np.cos(g.phi), np.sin(g.phi)
        ce, se = np.cos(g.phi_e), np.sin(g.phi_e)
        zero = np.zeros_like(cs)
        d = (cs, sn, ce, se, np.array([-cs / c, -sn / c, zero, zero]),
             np.array([-ce / c, -se / c, zero, zero]), np.array([zero, zero, -cs / c, -sn / c]))
        b._hs_tangent_dirs = d
    return d


@nb.njit(cache=True, nogil=True)
def _hs_central_tangent(P0, dP, steps, phi, area, D, wrow, F0):
    """-(F(P0 + s_j dP_j) - F(P0 - s_j dP_j)) / (2 s_j) into D[:, j] (2, 4): the central
    differences of :func:`_hs_forces_many`'s force (cell pressures of the force quadrature,
    :func:`.film.hs_force_pressure`), with the perturbed fields from the tangent solve;
    row r of the fields weighted ``wrow[r]`` (2 for a row that stands for its mirror image
    about the mid-plane too, :func:`_hs_coefficients`); the force of P0 itself into F0 (2,)."""
    n_z, n_phi = P0.shape
    Pq = np.empty((n_z, n_phi))
    pf = np.empty((n_z, n_phi))
    cs_, sn_ = np.empty(n_phi), np.empty(n_phi)      # cos, sin of the columns: once, not 8 times
    for i in range(n_phi):
        cs_[i] = math.cos(phi[i])
        sn_[i] = math.sin(phi[i])
    hs_force_pressure(P0, pf)
    Fx = 0.0
    Fy = 0.0
    for i in range(n_phi):
        for r in range(n_z):
            Fx -= wrow[r] * pf[r, i] * cs_[i]
            Fy -= wrow[r] * pf[r, i] * sn_[i]
    F0[0] = Fx * area
    F0[1] = Fy * area
    for j in range(4):
        F = np.zeros((2, 2))
        for side in range(2):
            sg = 1.0 if side == 0 else -1.0
            for r in range(n_z):
                for i in range(n_phi):
                    Pq[r, i] = P0[r, i] + sg * steps[j] * dP[j, r, i]
            hs_force_pressure(Pq, pf)
            Fx = 0.0
            Fy = 0.0
            for i in range(n_phi):
                cs = cs_[i]
                sn = sn_[i]
                for r in range(n_z):
                    Fx -= wrow[r] * pf[r, i] * cs
                    Fy -= wrow[r] * pf[r, i] * sn
            F[side, 0] = Fx * area
            F[side, 1] = Fy * area
        D[0, j] = -(F[0, 0] - F[1, 0]) / (2.0 * steps[j])
        D[1, j] = -(F[0, 1] - F[1, 1]) / (2.0 * steps[j])


def hs_linearization_fd(b, x, y, vx, vy, omega, *, rel_step=1e-5, t_ref=1e-3):
    """(K, C) of the half-Sommerfeld force by central differences of 8 perturbed solves
    (one batched solve, :func:`hs_forces_many`); the reference of :func:`hs_linearization`."""
    z0 = np.array([x, y, vx, vy], dtype=float)
    D = _central_many(lambda Z: hs_forces_many(b, Z, omega), z0,
                      _steps(b, z0, omega, rel_step, t_ref))
    return D[:, :2].copy(), D[:, 2:].copy()


def hs_linearization_scalar(b, x, y, vx, vy, omega, *, rel_step=1e-5, t_ref=1e-3):
    """:func:`hs_linearization` with 8 separate :func:`hs_force` calls (the reference the
    batched version is tested against; ~8x slower)."""
    z0 = np.array([x, y, vx, vy], dtype=float)
    D = _central(lambda z: hs_force(b, z[0], z[1], z[2], z[3], omega), z0,
                 _steps(b, z0, omega, rel_step, t_ref))
    return D[:, :2].copy(), D[:, 2:].copy()


def _newton_step_inside(q, K, f, c, max_ecc, who, why_singular=""):
    """The Newton step of the static equilibria, ``F(q + dq) ~ F(q) - K dq = F_target`` (``f`` =
    F(q) - F_target, ``K = -dF/dq``), halved (at most 40 times) until the centre lies inside
    ``max_ecc`` c; :class:`HSEquilibriumError` naming ``who`` for a singular K or no such step."""
    try:
        step = np.linalg.solve(K, f)
    except np.linalg.LinAlgError:
        raise HSEquilibriumError(f"{who}: singular film stiffness at eccentricity {math.hypot(*q) / c:.4f}"
                                 f"{why_singular}") from None
    lam = 1.0
    for _ in range(40):
        if math.hypot(*(q + lam * step)) < max_ecc * c:
            return q + lam * step
        lam *= 0.5
    raise HSEquilibriumError(f"{who}: no Newton step stays inside {max_ecc} c (eccentricity "
                             f"{math.hypot(*q) / c:.4f})", eps=math.hypot(*q) / c)


class HSEquilibriumError(RuntimeError):
    """:func:`hs_static_equilibrium` found no journal position carrying the load; ``eps``: the
    eccentricity ratio where the search ended (None when not known)."""

    def __init__(self, message: str, eps: float | None = None):
        super().__init__(message)
        self.eps = eps


def hs_static_equilibrium(b, F_target, omega, *, guess=None, contact=None, ftol=1e-9, max_iter=60,
                          max_ecc=0.995):
    """Journal centre (x, y) [m] at rest where the quasi-static half-Sommerfeld film force of
    bearing ``b`` at journal speed ``omega`` [rad/s] equals ``F_target`` (2,) [N]: the static
    equilibrium of a journal under a static load W, ``F_target = -W`` (the film carries the load;
    a downward weight m g is carried by ``F_target = (0, m g)``). The one Newton solve of the
    rotor-bearing statics: ``rotorcosim stability`` (orchestrator/stability/films.py), the docs scripts
    (docs/paper_cases_radius.py, docs/sweeps_threshold.py, docs/turbocharger_threshold.py) and the
    floating ring's films (:func:`.floating_ring_statics.static_equilibrium`).

    Equations: the film force is that of the Reynolds equation of the paper
    (../shared/paper/transient-run-up-mass-conserving-cavitation.md, eq. (2)) with constant
    density and viscosity (fluid fraction 1), the journal at rest (no squeeze term: the
    stationary film), the Dirichlet edges p = p0 of eq. (5) (or the bearing's own axial and groove
    conditions) and the half-Sommerfeld (Guembel) condition - the pressure clipped at p0 in the
    force integral (Dowson & Taylor 1979; Szeri 2011) - on the bearing's full grid, exactly
    :func:`hs_force`; with asperity contact (``contact`` true; default ``b.params.contact``) plus
    the contact force :func:`.contact.contact_force`, as the FMU adds it. The equilibrium is the
    root of ``r(q) = F(q, 0, omega) - F_target`` (the linear-stability setting of Lund 1974 /
    Childs 1993 sec. 3.6: the coefficients are taken there).

    Newton on q = (x, y) with the film stiffness ``K = -dF/dq`` of :func:`hs_linearization`
    (plus :func:`.contact.contact_coefficients`): ``q <- q + lam K^-1 r``, where ``lam`` is halved
    until the new centre lies inside ``max_ecc`` c (the film force is singular at the wall; at most
    40 halvings). Converged when ``max |r| <= ftol |F_target|``; the position is returned without a
    further step. ``guess``: the start (x, y) [m]; default 0.5 c from the bearing centre in the
    direction of the load (-F_target) turned 45 deg in the direction of rotation (roughly where
    the journal of a plain bearing sits: down and to +x for a downward load and omega > 0).

    Raises :class:`ValueError` for a zero or non-finite ``F_target``, ``max_ecc`` outside (0, 1),
    ``max_iter`` below 1 or a guess outside ``max_ecc`` c, and :class:`HSEquilibriumError` naming the eccentricity (and,
    after ``max_iter`` steps, the last residual) when the stiffness is singular (e.g. omega = 0), a
    force is not finite, 40 halvings leave a step outside ``max_ecc`` c, or ``max_iter`` Newton
    steps do not converge (e.g. a load the film cannot carry inside ``max_ecc`` c)."""
    c = b.c
    target = np.asarray(F_target, dtype=float).reshape(2)
    W = float(np.hypot(*target))
    if not (W > 0.0 and math.isfinite(W)):
        raise ValueError(f"hs_static_equilibrium: F_target must be a finite nonzero force (got {target.tolist()} N)")
    if not 0.0 < max_ecc < 1.0:
        raise ValueError(f"hs_static_equilibrium: max_ecc must lie in (0, 1) (got {max_ecc})")
    if not max_iter >= 1:
        raise ValueError(f"hs_static_equilibrium: max_iter must be at least 1 (got {max_iter})")
    if guess is None:
        a = math.atan2(-target[1], -target[0]) + math.copysign(math.pi / 4, omega)
        q = 0.5 * c * np.array([math.cos(a), math.sin(a)])
    else:
        q = np.array(guess, dtype=float).reshape(2)
        if not math.hypot(*q) < max_ecc * c:
            raise ValueError(f"hs_static_equilibrium: the guess {q.tolist()} m lies outside {max_ecc} c "
                             f"(c = {c:.4g} m)")
    with_contact = bool(b.params.contact if contact is None else contact)
    f = np.full(2, np.nan)
    for _ in range(max_iter):
        x, y = float(q[0]), float(q[1])
        F = hs_force(b, x, y, 0.0, 0.0, omega)
        if with_contact:
            F = F + np.array(contact_force(x, y, 0.0, 0.0, omega, **b.contact_kw)[:2])
        f = F - target
        if not np.all(np.isfinite(f)):
            raise HSEquilibriumError(f"hs_static_equilibrium: non-finite film force {F.tolist()} N at "
                                     f"eccentricity {math.hypot(x, y) / c:.4f}")
        if np.max(np.abs(f)) <= ftol * W:
            return q
        K, _ = hs_linearization(b, x, y, 0.0, 0.0, omega)
        if with_contact:
            K = K + contact_coefficients(x, y, 0.0, 0.0, omega, **b.contact_kw)[0]
        q = _newton_step_inside(q, K, f, c, max_ecc, "hs_static_equilibrium",
                                f", omega = {omega:.6g} rad/s (a film at rest carries no load)")
    raise HSEquilibriumError(
        f"hs_static_equilibrium: no journal position carries {W:.6g} N at omega = {omega:.6g} rad/s in "
        f"{max_iter} Newton steps (residual {np.max(np.abs(f)) / W:.3g} of the load at eccentricity "
        f"{math.hypot(x, y) / c:.4f} before the last step; steps kept inside {max_ecc} c)", eps=math.hypot(x, y) / c)


def _last_bdf(film):
    """(th_dot0, th_dot1) of the film's last accepted step, or None without history."""
    if film.n_hist == 0 or film.h_prev <= 0.0:
        return None
    h = film.h_prev
    if film.n_hist == 1:
        return 1.0 / h, -film.th_nm1 / h
    w = h / film.h_prev2
    a0, a1, a2 = (1 + 2 * w) / (1 + w), -(1 + w), w * w / (1 + w)
    return a0 / h, (a1 * film.th_nm1 + a2 * film.th_nm2) / h


def film_force_at(b, u, kin) -> np.ndarray:
    """Film force [N] (2,) of the universal-variable field ``u`` at kinematics ``kin``."""
    p, th = b.law.p_theta(u)
    return _force(b, p, th, kin)


def mc_linearization(b, *, rel_step=1e-5, t_ref=1e-3, horizon=None):
    """(K, C) of the mass-conserving film at its current state (see module doc).

    ``horizon`` [s] (optional): instead of the last internal BDF step, linearize an
    implicit Euler step of that length from the current film (Jacobian at the current
    u, theta history = theta(u)): the film's response over a macro step of that length
    (cavity transport included to first order), not only the instantaneous one."""
    film = b.film
    x, y, vx, vy, omega = b._inputs
    if horizon:
        bdf = (1.0 / horizon, -film.theta(film.u) / horizon)
    else:
        bdf = _last_bdf(film)
    if bdf is None:
        return hs_linearization(b, x, y, vx, vy, omega, rel_step=rel_step, t_ref=t_ref)
    th_dot0, th_dot1 = bdf
    g = b.grid
    n = film.n
    u = film.u.copy()
    residual = _Residual(b)
    jst = residual.jst

    def res(kin, want_jac=False):
        return residual(u, kin, th_dot0, th_dot1, want_jac)

    kin0 = _kin(b, x, y, vx, vy, omega)
    res(kin0, want_jac=True)
    ab = np.zeros((3 * g.bw + 1, n), order="F")
    stencil_to_band(jst, g.n_phi, g.pos, g.bw, ab)
    lu, piv, info = lapack.dgbtrf(ab, g.bw, g.bw, overwrite_ab=1)
    if info != 0:   # singular Newton matrix: fall back to the quasi-static coefficients
        return hs_linearization(b, x, y, vx, vy, omega, rel_step=rel_step, t_ref=t_ref)
    z0 = np.array([x, y, vx, vy], dtype=float)
    steps = _steps(b, z0, omega, rel_step, t_ref)
    p_u, th_u = b.law.p_theta(u)
    D = np.empty((2, 4))
    for j in range(4):
        zp, zm = z0.copy(), z0.copy()
        zp[j] += steps[j]
        zm[j] -= steps[j]
        kp, km = _kin(b, *zp, omega), _kin(b, *zm, omega)
        dR = (res(kp) - res(km)) / (2.0 * steps[j])
        du, _ = lapack.dgbtrs(lu, g.bw, g.bw, -dR[g.order], piv)
        du = du[g.pos]
        # directional difference of F through the cavitation law, scaled to a small u change
        s = 1e-6 * max(1.0, float(np.abs(u).max())) / max(float(np.abs(du).max()), 1e-300)
        dF_u = (film_force_at(b, u + s * du, kin0) - film_force_at(b, u - s * du, kin0)) / (2 * s)
        dF_k = (_force(b, p_u, th_u, kp) - _force(b, p_u, th_u, km)) / (2.0 * steps[j])
        D[:, j] = -(dF_u + dF_k)
    return D[:, :2].copy(), D[:, 2:].copy()


def linearization(b, *, method="quasi-static", rel_step=1e-5, t_ref=1e-3, horizon=None):
    """(K, C) 2x2 [N/m], [N s/m] of :class:`bearing_fmu.model.BearingModel` ``b`` at
    its current state (after ``initialize``/``step``); the state is not changed.

    ``method="quasi-static"`` (default, what the FMU outputs): the half-Sommerfeld
    coefficients at the bearing's current kinematics, for both film models.
    ``method="film"``: for the mass-conserving film its own sensitivity
    (:func:`mc_linearization`, ``horizon`` see there); half-Sommerfeld is the same.

    Why the quasi-static default for the mass-conserving film (measured,
    docs/stiff-coupling.md): the film's instantaneous sensitivity is exact for its last
    BDF step but jumps from step to step where cells cavitate/reform (damping 5e3 <->
    5e4 N s/m between consecutive 10 us steps) and is exactly 0 for a just-cavitated
    film, and coefficients that underestimate the film make the coupling unstable
    (amplification 1 - c_true / (m/H + c_used)); the smooth quasi-static coefficients
    have the right magnitude, gave 2-4x smaller coupling errors at 10-100 us, and can be
    held over several steps. The coefficients only set the stabilizing correction; the
    force itself is always the film's.

    With ``contact = 1`` the coefficients of the asperity contact force
    (:func:`.contact.contact_coefficients`) are added."""
    b._check_init("linearization")
    if method not in ("quasi-static", "film"):
        raise ValueError(f"linearization: method must be 'quasi-static' or 'film' (got {method!r})")
    if b.film is None or method == "quasi-static":
        K, C = hs_linearization(b, *b._inputs, rel_step=rel_step, t_ref=t_ref)
    else:
        K, C = mc_linearization(b, rel_step=rel_step, t_ref=t_ref, horizon=horizon)
    if b.params.contact:        # asperity contact (bearing_fmu/contact.py): its own exact part
        Kc, Cc = contact_coefficients(*b._inputs, **b.contact_kw)
        K, C = K + Kc, C + Cc
    return K, C


# --------------------------------------------------------------------------- film impedance
def _stencil_sparse(jst, n_phi):
    """The stencil Jacobian ``jst`` (5 or 7 columns, the neighbours of
    :func:`.film.stencil_to_band`) as a scipy CSR matrix in the film's flat cell order."""
    import scipy.sparse as sp
    n = jst.shape[0]
    n_z = n // n_phi
    g = np.arange(n)
    i, j = g % n_phi, g // n_phi
    row = j * n_phi
    cols = [g, row + (i + 1) % n_phi, row + (i - 1) % n_phi,
            np.where(j + 1 < n_z, g + n_phi, -1), np.where(j > 0, g - n_phi, -1)]
    if jst.shape[1] > 5:
        cols += [row + (i + 2) % n_phi, row + (i - 2) % n_phi]
    R, C, V = [], [], []
    for k, c in enumerate(cols):
        m = (c >= 0) & (jst[:, k] != 0.0)
        R.append(g[m])
        C.append(c[m])
        V.append(jst[m, k])
    return sp.csr_matrix((np.concatenate(V), (np.concatenate(R), np.concatenate(C))), shape=(n, n))


class _Residual:
    """The film's residual at ``u`` and kinematics ``kin`` with the BDF time term ``th_dot0 theta(u) +
    th_dot1`` (0, 0: the steady residual), through the solver's own assembly (``film.assemble`` or
    ``assemble_muscl``); with ``want_jac`` the stencil Jacobian is left in ``jst``. ``bufs`` hold p,
    dp/du, theta and dtheta/du of the last call. One object per film, reused for every call."""

    def __init__(self, b):
        n, prm = b.film.n, b.params
        self.b = b
        self.asm = assemble_muscl if prm.theta_transport == 1 else assemble
        self.bufs = [np.empty(n) for _ in range(4)]
        self.r = np.empty(n)
        self.jst = np.zeros((n, 7 if prm.theta_transport == 1 else 5))
        self.zero = np.zeros(n)

    def __call__(self, u, kin, th_dot0=0.0, th_dot1=None, want_jac=False):
        b, g, prm = self.b, self.b.grid, self.b.params
        H, He, Hdot, om = kin
        self.asm(u, th_dot0, self.zero if th_dot1 is None else th_dot1, H, He, Hdot, g.groove, b.u_feed, om,
                 b.a_phi, b.a_z, g.dphi, g.dz, b.bath, b.p0, b.law.p_cav, b.law.K,
                 b.law.delta, prm.penalty_a, prm.penalty_b, prm.penalty_smoothing,
                 self.r, want_jac, self.jst, *self.bufs, b.sym, g.wrel, g.frel)
        return self.r.copy()


class MCFilmLinear:
    """The linearised semi-discrete mass-conserving film about its steady state, and its
    impedance (see :func:`mc_impedance` for the derivation).

    Built from a :class:`bearing_fmu.model.BearingModel` ``b`` (``cavitation = 1``) whose film
    is at (or near: ``polish`` Newton steps on the steady residual are taken, on a copy) the
    steady state of its current kinematics ``b._inputs`` (journal at rest: vx = vy = 0;
    ``solve_stationary`` / ``initialize(..., init="stationary")``). The model is not changed.

    Attributes (n film unknowns, the solver grid's cells, flat order): ``Js`` (n, n) CSC, the
    exact stencil Jacobian of the steady residual; ``Mdiag`` (n,), the time-derivative (mass)
    part, ``dR/d(du/dt)`` = cell area x 2 H dtheta/du (0 in groove cells); ``Rq``, ``Rv``
    (n, 2) ``dR/d(x, y)``, ``dR/d(vx, vy)`` (central differences; R is linear in v); ``Fu``
    (2, n) ``dF/du`` exactly (F = -int (p(u) - p0) (cos, sin) dA); ``Fq``, ``Fv`` (2, 2) the
    force's explicit kinematic dependence (0 for this film: F depends on p only);
    ``contact`` (K_c, C_c) of the asperity contact with ``contact = 1``, else None (its force is
    ``-K_c dq - C_c dq'``; added to Z);
    ``u`` the (polished) steady field, ``F0`` its force [N], ``polish_step`` the largest
    Newton increment of the last polishing step (small: the film was steady).
    """

    def __init__(self, b, *, rel_step=1e-5, polish=2):
        if b.film is None:
            raise ValueError("MCFilmLinear: the bearing has no mass-conserving film (cavitation = 0)")
        b._check_init("mc_impedance")
        self.b = b
        self.rel_step = rel_step
        self._res = _Residual(b)
        g = b.grid
        i = np.arange(b.film.n) % g.n_phi
        w = np.ones(g.n_phi) if g.wrel is None else g.wrel
        self._cos_w, self._sin_w = np.cos(g.phi)[i] * w[i], np.sin(g.phi)[i] * w[i]     # of Fu
        self.update(polish=polish)

    def update(self, *, polish=2):
        """Linearise again, about the film and kinematics ``b`` holds now (a new steady state:
        :func:`mc_static_equilibrium` moves the journal every Newton step), with ``polish``
        Newton steps as in the constructor; what depends on the grid only (the residual's work
        arrays, the force's weights) is kept. Every attribute is as a new object's
        ``MCFilmLinear(b, rel_step=..., polish=polish)``, to the bit. Returns the object."""
        import scipy.sparse.linalg as spla
        b = self.b
        b._check_init("mc_impedance")
        film = b.film
        x, y, vx, vy, omega = b._inputs
        g = b.grid
        prm = b.params
        n = film.n
        rel_step = self.rel_step
        self._template = None                  # _shifted's matrix was J_s's of the last state
        u = film.u.copy()
        res = self._res
        jst, bufs = res.jst, res.bufs          # bufs: p, dp/du, theta, dtheta/du of the last call

        kin0 = _kin(b, x, y, vx, vy, omega)
        self.polish_step = 0.0
        for _ in range(polish):
            r0 = res(u, kin0, want_jac=True)
            du = spla.splu(_stencil_sparse(jst, g.n_phi).tocsc()).solve(-r0)
            u = u + du
            self.polish_step = float(np.abs(du).max())
        self.r0 = res(u, kin0, want_jac=True)
        self.Js = _stencil_sparse(jst, g.n_phi).tocsc()
        dp = bufs[1].copy()
        d0 = jst[:, 0].copy()
        # the time term A 2 H (th_dot0 theta + th_dot1) is the only one with th_dot0: its
        # Jacobian is th_dot0 M + J_s, M diagonal; M = J(th_dot0 = 1) - J(th_dot0 = 0)
        res(u, kin0, 1.0, -bufs[2].copy(), want_jac=True)
        self.Mdiag = jst[:, 0] - d0
        self.u = u
        c = b.c
        Rq, Rv = np.empty((n, 2)), np.empty((n, 2))
        Fq, Fv = np.empty((2, 2)), np.empty((2, 2))
        p_u, th_u = b.law.p_theta(u)
        z0 = np.array([x, y, vx, vy], float)
        steps = [rel_step * c] * 2 + [rel_step * max(c * abs(omega), 1e-12)] * 2
        for k in range(4):
            zp, zm = z0.copy(), z0.copy()
            zp[k] += steps[k]
            zm[k] -= steps[k]
            kp, km = _kin(b, *zp, omega), _kin(b, *zm, omega)
            dR = (res(u, kp) - res(u, km)) / (2 * steps[k])
            dF = (_force(b, p_u, th_u, kp) - _force(b, p_u, th_u, km)) / (2 * steps[k])
            if k < 2:
                Rq[:, k], Fq[:, k] = dR, dF
            else:
                Rv[:, k - 2], Fv[:, k - 2] = dR, dF
        self.Rq, self.Rv, self.Fq, self.Fv = Rq, Rv, Fq, Fv
        area = prm.R * g.dphi * prm.B * g.dz * (2.0 if b.sym else 1.0)
        self.Fu = -area * np.vstack([self._cos_w * dp, self._sin_w * dp])
        self.F0 = _force(b, p_u, th_u, kin0)
        self.omega = omega
        self.contact = (contact_coefficients(x, y, vx, vy, omega, **b.contact_kw)
                         if prm.contact else None)
        return self

    def impedance(self, s, *, slope=False):
        """Z(s) (2, 2) complex [N/m] at complex s [1/s] (:func:`mc_impedance`): one sparse complex LU
        of ``s M + J_s``, assembled into a kept copy of ``J_s``'s pattern (its diagonal added). With
        ``slope``: (Z(s), dZ/ds), ``dZ/ds = -F_v + F_u (s M + J_s)^-1 (R_v - M X)``,
        ``X = (s M + J_s)^-1 (R_q + s R_v)``, from the same LU."""
        import scipy.sparse.linalg as spla
        s = complex(s)
        lu = spla.splu(self._shifted(s))
        X = lu.solve(np.asarray(self.Rq + s * self.Rv, dtype=complex))
        Z = -(self.Fq + s * self.Fv) + self.Fu @ X
        if slope:
            dZ = -self.Fv + self.Fu @ lu.solve(self.Rv - self.Mdiag[:, None] * X)
            if self.contact is not None:
                return Z + self.contact[0] + s * self.contact[1], dZ + self.contact[1]
            return Z, dZ
        if self.contact is not None:
            Z = Z + self.contact[0] + s * self.contact[1]
        return Z

    def _shifted(self, s: complex):
        """``J_s + s diag(M)`` (complex CSC) in one kept matrix: the pattern of ``J_s`` with every
        diagonal entry stored, its values ``J_s`` plus ``s M`` on the diagonal (the matrix is reused
        by the next call; splu copies it)."""
        import scipy.sparse as sp
        t = getattr(self, "_template", None)
        if t is None:
            n = self.Js.shape[0]
            J = self.Js.tocoo()
            i = np.arange(n)                   # explicit zeros on the diagonal keep its entries stored
            A = sp.csc_matrix((np.concatenate([J.data, np.zeros(n)]).astype(complex),
                               (np.concatenate([J.row, i]), np.concatenate([J.col, i]))), shape=(n, n))
            A.sum_duplicates()
            A.sort_indices()
            cols = np.repeat(i, np.diff(A.indptr))
            diag = np.flatnonzero(A.indices == cols)
            t = self._template = (A, A.data.copy(), diag[np.argsort(cols[diag])])
        A, base, diag = t
        A.data[:] = base
        A.data[diag] += s * self.Mdiag
        return A

    def quasi_steady(self):
        """(K, C) of the quasi-steady film: ``-dF/dq``, ``-dF/dv`` of steady solves (theta
        storage ignored, M = 0); K = Z(0)."""
        import scipy.sparse.linalg as spla
        lu = spla.splu(self.Js)
        K, C = -self.Fq + self.Fu @ lu.solve(self.Rq), -self.Fv + self.Fu @ lu.solve(self.Rv)
        if self.contact is not None:
            K, C = K + self.contact[0], C + self.contact[1]
        return K, C

    def slope0(self):
        """dZ/ds at s = 0: ``-F_v + F_u J_s^-1 (R_v - M J_s^-1 R_q)``, the quasi-steady damping
        plus the theta-storage term ``-F_u J_s^-1 M J_s^-1 R_q``."""
        import scipy.sparse.linalg as spla
        lu = spla.splu(self.Js)
        X1 = lu.solve(self.Rv - self.Mdiag[:, None] * lu.solve(self.Rq))
        D = -self.Fv + self.Fu @ X1
        return D + self.contact[1] if self.contact is not None else D

    def poles(self):
        """The film's own modes with the journal held: the finite generalised eigenvalues s of
        ``(s M + J_s) v = 0`` (dense; largest real part first)."""
        import scipy.linalg as sl
        lam = sl.eigvals(-self.Js.toarray(), np.diag(self.Mdiag))
        lam = lam[np.isfinite(lam)]
        return lam[np.argsort(-lam.real)]


def mc_impedance(b, s, *, rel_step=1e-5):
    """Film impedance Z(s) (2, 2) complex [N/m] of the mass-conserving film of ``b`` (a
    :class:`bearing_fmu.model.BearingModel` at the steady state of its current kinematics,
    journal at rest) at the complex frequency ``s`` [1/s], or (m, 2, 2) for a sequence.
    Sign convention of K: ``dF(s) = -Z(s) dq(s)`` (dq the journal displacement, dF the film
    force on the journal), so ``Z(0)`` is the stiffness and, for a film without dynamics,
    ``Z(s) = K + s C``.

    Derivation. The film (paper eq. 4 with the density and viscosity of eq. 3, axial
    boundary conditions eq. 5 or 6; finite volumes, bearing_fmu/film.py) is, semi-discretely,
    ``R(u, du/dt; q, v) = 0`` with one time derivative only, that of the fluid fraction:
    per cell ``A (2 H dtheta(u)/dt + 2 Hdot theta(u)) + (fluxes) = 0``, H = H(q), Hdot = Hdot(v)
    (the kinematics enter eq. 4 as inputs). The implicit BDF steps of the solver replace
    ``dtheta/dt`` by ``th_dot0 theta(u) + th_dot1``, so their Newton matrix is
    ``th_dot0 M + J_s``: ``M = diag(A 2 H dtheta/du)`` (0 in the groove and, to the
    smoothing, in the full film) and ``J_s`` the Jacobian of the steady residual (``th_dot0 =
    0``). About a steady state u0 at q0 (v = 0) the linearised film is

        M du/dt + J_s du + R_q dq + R_v dq' = 0,       dF = F_u du + F_q dq + F_v dq'

    and, Laplace transformed, ``du = -(s M + J_s)^-1 (R_q + s R_v) dq``, so

        Z(s) = -(F_q + s F_v) + F_u (s M + J_s)^-1 (R_q + s R_v).

    ``Z(0)`` is the quasi-steady stiffness (central differences of steady solves);
    ``dZ/ds(0) = C_qs - F_u J_s^-1 M J_s^-1 R_q``: the quasi-steady damping C_qs plus the
    storage of fluid in the cavity (the theta dynamics), which is not small for these films
    (docs/analysis.md, "Linear threshold of the mass-conserving film"). The poles of Z are the
    film's own modes (:meth:`MCFilmLinear.poles`). Each value is a sparse complex LU of
    ``s M + J_s`` with two right-hand sides (R_q + s R_v). The rotor's characteristic
    equation with this film is ``det(s^2 M_r + s C_r + K_r + sum_j P_j^T Z_j(s) P_j) = 0``;
    its roots are the finite eigenvalues of the descriptor system of rotor and films
    (docs/scripts/mc_linear_stability.py). With ``contact = 1`` the asperity contact's
    ``K_c + s C_c`` is added. For many values at one state build :class:`MCFilmLinear` once
    and call its ``impedance``."""
    lin = MCFilmLinear(b, rel_step=rel_step)
    if np.ndim(s) == 0:
        return lin.impedance(s)
    return np.array([lin.impedance(v) for v in np.ravel(s)])


def mc_static_equilibrium(b, F_target, omega, *, guess, ftol=1e-9, max_iter=60, max_ecc=0.995):
    """Journal centre (x, y) [m] at rest where the STEADY mass-conserving film of ``b``
    (``cavitation = 1``) at journal speed ``omega`` carries ``F_target`` (2,) [N] (``-W`` for a
    static load W, as :func:`hs_static_equilibrium`), and the :class:`MCFilmLinear` there.

    The steady film (paper eq. 4 with constant kinematics, section 3.1) by Newton on its steady
    residual from the last one (``BearingModel._steady_newton``, pseudo-transient continuation as
    fallback, ``BearingModel._steady``); the journal by Newton on q with the stiffness of that
    film, ``Z(0)`` = :meth:`MCFilmLinear.quasi_steady`, steps halved to stay inside ``max_ecc`` c,
    converged at ``max |r| <= ftol |F_target|``. ``b`` is left initialised at the equilibrium with
    its steady film (a warm start for the next speed). Raises :class:`HSEquilibriumError` (no
    position found) like :func:`hs_static_equilibrium`."""
    if b.params.cavitation != 1:
        raise ValueError("mc_static_equilibrium: the bearing's film is not mass-conserving (cavitation = 0)")
    c = b.c
    target = np.asarray(F_target, dtype=float).reshape(2)
    W = float(np.hypot(*target))
    if not (W > 0.0 and math.isfinite(W)):
        raise ValueError(f"mc_static_equilibrium: F_target must be a finite nonzero force (got {target.tolist()} N)")
    q = np.array(guess, dtype=float).reshape(2)
    u = b.film.u.copy() if b._initialized else None      # warm start: the film b holds

    def steady(q):
        nonlocal u
        if u is None:
            b.initialize(q[0], q[1], 0.0, 0.0, omega, init="stationary")
            u = b.film.u.copy()
        kin = b._kinematics(q[0], q[1], 0.0, 0.0, omega)
        us, _ = b._steady_newton(kin, u, np.zeros_like(u), 40)
        u = b._steady(kin, u) if us is None else us
        b.initialize(q[0], q[1], 0.0, 0.0, omega)        # the inputs, then the steady film
        b.film.init_state(u)
        b._update_outputs()
        p, th = b.law.p_theta(u)
        F = np.asarray(_force(b, p, th, b._kin))
        if b.params.contact:        # as hs_static_equilibrium, and as K = Z(0) includes it
            F = F + np.array(contact_force(q[0], q[1], 0.0, 0.0, omega, **b.contact_kw)[:2])
        return F

    f = np.full(2, np.nan)
    lin = None                  # one linearisation, updated at each Newton step's steady film
    for _ in range(max_iter):
        f = steady(q) - target
        if not np.all(np.isfinite(f)):
            raise HSEquilibriumError(f"mc_static_equilibrium: non-finite film force at eccentricity "
                                     f"{math.hypot(*q) / c:.4f}")
        if np.max(np.abs(f)) <= ftol * W:
            return q, (MCFilmLinear(b) if lin is None else lin.update())
        lin = MCFilmLinear(b, polish=0) if lin is None else lin.update(polish=0)
        K = lin.quasi_steady()[0]
        q = _newton_step_inside(q, K, f, c, max_ecc, "mc_static_equilibrium")
    raise HSEquilibriumError(
        f"mc_static_equilibrium: no journal position carries {W:.6g} N at omega = {omega:.6g} rad/s in "
        f"{max_iter} Newton steps (residual {np.max(np.abs(f)) / W:.3g} of the load at eccentricity "
        f"{math.hypot(*q) / c:.4f})")

