"""One-dimensional model of the mass-conserving film's reformation front (issue 16 item 2).

Why: the free-to-air film with a groove of its true width is not in its asymptotic range
circumferentially on 48 ... 384 cells (docs/bearing-validation.md, "Where the circumferential
error comes from"); the suspected cause is the layer of width ~ cav_width / (dp/dphi) at the
reformation front. This script isolates it on the steady, infinitely long film in phi.

Model (the 2-D film of bearing_fmu/film.py without axial flow, steady):

    d/dphi q = 0,   q = omega H theta(p) - a H^3 dp/dphi,   a = psi^2 / (6 eta0)

with the law theta(p) of bearing_fmu/cavitation.py (``law_eval``, universal variable u, the
same K, delta, p_cav), gap ``H = 1 + eps cos(phi - phi_hmax)``, and a groove held at p_feed
from ``-groove_width / 2`` to ``+groove_width / 2``. The film cells cover the rest of the
circle, ``[groove_width / 2, 2 pi - groove_width / 2]``, uniformly; their outer faces are the
groove edges (so no cut cell: the 2-D "faces" sequence of groove_cut_study.py).

Discretisation (as film.py ``assemble`` along phi, omega > 0): face flux
``F = omega H_f theta_up - a H_f^3 (p_E - p_W) / d``; theta_up the upwind cell's theta
(``muscl``: film.py's limited second-order face value, first order next to the groove);
Poiseuille two-point with the exact face gap, the half-cell distance to the groove edges;
at the groove exit (west edge of the film) film.py's ``groove_exit`` (Scharfetter-Gummel
blend of the distance; ``exit="plain"``: the plain half-cell flux; ``exit="rupture"``: the
sub-cell rupture model of :func:`rupture_exit_flux`).
Cell residual ``F_east - F_west``. Newton on u with a banded finite-difference Jacobian.

Semi-analytic reference: with q constant the ODE ``a H^3 dp/dphi = omega H theta(p) - q``
(in u: ``du/dphi = (omega H theta(u) - q) / (a H^3 dp/du)``) holds on the whole film; it is
unstable forward wherever dtheta/dp > 0 (the cavity) and stable backward, so it is
integrated BACKWARD from the groove's west edge (p = p_feed) with scipy's Radau, and q is
the root of ``p(groove east edge) = p_feed`` (brentq).

Run: ``nice -n 10 .venv/bin/python docs/scripts/reformation_front_1d.py [check] [widths]
[split]`` (all three by default, about two minutes; prints markdown tables).

``free`` (not in the default set; 2026-12-07, about two minutes): the same film with the groove
at the MAXIMUM gap (``phi_hmax = 0``), so that the full film leaving the groove runs through
the minimum gap and ruptures freely after it (at 212.8 deg for 1 kPa), the Swift-Stieber
rupture that the 2-D free-to-air film has near its minimum gap and the default problem above
lacks (its full film ends at the groove). Load and q errors against the semi-analytic
solution, both transports, cav_width 1 kPa and 100 Pa.

``rupture`` (2026-12-07, about a minute): the ``free`` film with a defect correction at its
free rupture (:func:`rupture_correction`, :func:`solve_rupture`): the local 1-D problem about
the rupture given the cavity flux q (on the gap linearised there, or the exact gap), the
scheme's flux error on that profile added to the faces in its window, q iterated to a fixed
point. MUSCL, cav_width 1 kPa, 100 Pa, 10 Pa.
"""

from __future__ import annotations

import copy
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numba as nb
import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import solve_banded
from scipy.optimize import brentq

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))          # repo root

from bearing_fmu.cavitation import CavitationLaw, law_eval  # noqa: E402
from bearing_fmu.film import groove_exit, limiter  # noqa: E402

BW = 3                      # half bandwidth of the finite-difference Jacobian
#: Radau tolerance of the semi-analytic solutions (1e-11 moves the shot's end value by 1e-13)
RTOL = 1e-9


@dataclass(frozen=True)
class Problem:
    """The 1-D film. Defaults: the Jeffcott bearing's psi, eta0, p0 (grid_convergence.py);
    omega and eps chosen so that the pressure scale omega / a and the front gradient are
    close to the 2-D free-to-air film's (the reformation band 0.54 deg at 1 kPa, :func:`layers`)."""
    eps: float = 0.6
    phi_hmax: float = math.radians(160.0)     # the minimum gap 20 deg before the groove
    groove_width: float = math.radians(15.0)
    omega: float = 2 * math.pi * 3.5
    psi: float = 2.8e-3
    eta0: float = 0.012
    p0: float = 1.0e5
    p_feed: float = 1.0e5
    cav_width: float = 1.0e3
    delta: float = 0.05

    @property
    def a(self):
        return self.psi ** 2 / (6 * self.eta0)

    @property
    def law(self):
        return CavitationLaw(self.p0, self.cav_width, self.delta)

    @property
    def span(self):
        """(start, end) of the film: the groove's east and (next turn) west edge."""
        return 0.5 * self.groove_width, 2 * math.pi - 0.5 * self.groove_width

    def H(self, phi):
        return 1.0 + self.eps * np.cos(phi - self.phi_hmax)


def evaluate(u, law):
    """p, dp/du, theta, dtheta/du of u (bearing_fmu.cavitation.law_eval)."""
    u = np.ascontiguousarray(u, dtype=float)
    p, dp, th, dth = (np.empty_like(u) for _ in range(4))
    law_eval(u, law.p_cav, law.K, law.delta, p, dp, th, dth)
    return p, dp, th, dth


@nb.njit(cache=True)
def _muscl_faces(th, th_feed):
    """Couette theta at the faces 0 ... n (omega > 0): film.py's limited second-order
    value (``limiter``) at interior faces with two upwind cells, first order at face 1 (its
    upwind-upwind is the groove) and the groove's theta at face 0 (film.py face_theta)."""
    n = th.size
    f = np.empty(n + 1)
    f[0] = th_feed
    for k in range(1, n + 1):
        if k == 1 or k == n:
            f[k] = th[k - 1]
        else:
            L, _, _ = limiter(th[k - 1] - th[k - 2], th[k] - th[k - 1])
            f[k] = th[k - 1] + 0.5 * L
    return f


class Film1D:
    """The discrete 1-D film on n uniform cells (module doc)."""

    def __init__(self, prob: Problem, n: int, muscl=False, exit="sg"):
        self.prob, self.n, self.muscl = prob, n, muscl
        self.exit = exit
        self.layer_corr = None
        self.rupture_corr = None        # free-rupture defect correction (rupture_correction)
        a0, a1 = prob.span
        self.dphi = (a1 - a0) / n
        self.phi_f = a0 + self.dphi * np.arange(n + 1)
        self.phi = self.phi_f[:-1] + 0.5 * self.dphi
        self.Hf = prob.H(self.phi_f)
        self.Hc = prob.H(self.phi)
        self.law = prob.law
        self.u_feed = float(self.law.u_from_p(prob.p_feed))
        _, _, th_feed, _ = evaluate(np.array([self.u_feed]), self.law)
        self.th_feed = th_feed[0]
        d = np.full(n + 1, self.dphi)
        d[0] = d[-1] = 0.5 * self.dphi
        self.cond = prob.a * self.Hf ** 3 / d

    def fluxes(self, u):
        """Face fluxes F_0 ... F_n (omega > 0)."""
        pr = self.prob
        p, dp, th, dth = evaluate(u, self.law)
        pe = np.concatenate([[pr.p_feed], p, [pr.p_feed]])
        if self.muscl:
            thf = _muscl_faces(th, self.th_feed)
        else:
            thf = np.concatenate([[self.th_feed], th])
        F = pr.omega * self.Hf * thf - self.cond * np.diff(pe)
        if self.exit == "sg":       # film.py groove_exit: the face where the flow leaves the groove
            B, _, _ = groove_exit(self.Hf[:1], 1, 0, 1, 0.5, self.dphi, pr.omega, pr.a,
                                  self.cond[0], pr.p_feed - p[0], dth[0], self.law.K)
            F[0] = pr.omega * self.Hf[0] * thf[0] + B
        elif self.exit in ("layer", "layer0", "layer_lin"):
            B, _, _ = groove_exit(self.Hf[:1], 1, 0, 1, 0.5, self.dphi, pr.omega, pr.a,
                                  self.cond[0], pr.p_feed - p[0], dth[0], self.law.K)
            F[0] = pr.omega * self.Hf[0] * thf[0] + B
            if self.layer_corr is None:       # set once, from the uncorrected fluxes
                self.layer_corr = 0.0
                self.layer_corr = layer_correction(self, first_only=self.exit == "layer0")
            F = F + self.layer_corr
        elif self.exit == "rupture":
            dH = (self.Hf[1] - self.Hf[0]) / self.dphi
            F[0] = pr.omega * self.Hf[0] * thf[0] + rupture_exit_flux(
                pr.p_feed - p[0], 0.5 * self.dphi, pr.a * self.Hf[0] ** 3, pr.omega * dH)
        if self.rupture_corr is not None:
            F = F + self.rupture_corr
        return F

    def residual(self, u):
        return np.diff(self.fluxes(u))

    def jacobian_banded(self, u, r0):
        """Banded (BW, BW) Jacobian by coloured forward differences."""
        n = self.n
        ab = np.zeros((2 * BW + 1, n))
        h = 1e-7 * (1.0 + np.abs(u))
        for c in range(2 * BW + 1):
            idx = np.arange(c, n, 2 * BW + 1)
            up = u.copy()
            up[idx] += h[idx]
            dr = (self.residual(up) - r0)
            for o in range(-BW, BW + 1):          # row i = j + o: ab[BW + o, j]
                j = idx[(idx + o >= 0) & (idx + o < n)]
                ab[BW + o, j] = dr[j + o] / h[j]
        return ab

    def newton(self, u0, tol=1e-10, maxit=60):
        """Damped Newton; returns (u, converged). tol on |r| relative to the Couette scale."""
        u = u0.copy()
        scale = self.prob.omega * self.dphi * 0 + self.prob.omega
        r = self.residual(u)
        nr = np.max(np.abs(r)) / scale
        for it in range(maxit):
            if nr < tol:
                return u, True
            J = self.jacobian_banded(u, r)
            du = solve_banded((BW, BW), J, -r)
            lam = 1.0
            while lam > 1e-4:
                un = u + lam * du
                rn = self.residual(un)
                nrn = np.max(np.abs(rn)) / scale
                if np.isfinite(nrn) and nrn < (1 - 1e-4 * lam) * nr:
                    break
                lam *= 0.5
            else:
                return u, False
            u, r, nr = un, rn, nrn
        return u, nr < tol

    def ptc(self, u0, steps=400):
        """Pseudo-transient continuation (BDF1 in theta, dt growing by SER), then Newton."""
        u = u0.copy()
        dt = 0.1 / self.prob.omega
        mass = 2 * self.Hc * self.dphi
        base = self.residual
        r0 = np.max(np.abs(base(u)))
        for _ in range(steps):
            _, _, th_old, _ = evaluate(u, self.law)

            def rt(v, th_old=th_old, dt=dt):
                _, _, th, _ = evaluate(v, self.law)
                return base(v) + mass * (th - th_old) / dt
            self.residual = rt
            un, ok = self.newton(u, tol=1e-9, maxit=20)
            self.residual = base
            if not ok:
                dt *= 0.25
                continue
            u = un
            r1 = np.max(np.abs(base(u)))
            dt *= min(10.0, max(1.5, r0 / max(r1, 1e-300)))
            r0 = r1
            if dt * self.prob.omega > 1e8:
                break
        return self.newton(u)

    def solve(self, u0=None):
        if u0 is None:
            u0 = np.full(self.n, self.u_feed)
        u, ok = self.newton(u0)
        if not ok:
            u, ok = self.ptc(u0)
        if not ok:
            raise RuntimeError(f"no convergence on n = {self.n}")
        return u

    def load(self, u):
        """(Wx, Wy): integral of (p - p0) (cos, sin) over the film (midpoint rule; the
        groove at p_feed = p0 adds nothing) [Pa rad]."""
        p, _, _, _ = evaluate(u, self.law)
        x = (p - self.prob.p0) * self.dphi
        return np.array([np.sum(x * np.cos(self.phi)), np.sum(x * np.sin(self.phi))])

    def q(self, u):
        return float(np.mean(self.fluxes(u)))


def rupture_exit_flux(dp, d, c, s):
    """Poiseuille flux from the groove into the first film cell, with the rupture placed
    inside the cell (issue 16 item 2, this study): ``dp = p_feed - p_cell``, ``d`` the
    distance groove edge - cell centre, ``c = a H^3`` at the edge, ``s = omega dH/dphi``.

    Local model: in the diverging gap after the groove the full film obeys ``a H^3 p'' =
    omega H'`` (q constant, theta = 1, H^3 frozen at the edge), so with the exit flux P
    (``P = -a H^3 p'`` at the edge) ``p = p_feed - P x / c + s x^2 / (2 c)``, which ruptures
    (p' = 0, JFO) at ``x_r = P / s`` with the pressure ``p_feed - P^2 / (2 c s)``. If the
    rupture lies beyond the centre (dp >= D = s d^2 / (2 c)) the cell is full and
    ``P = c dp / d + s d / 2`` (the two-point flux plus the curvature term: the one-sided
    second-order gradient at the edge); if it lies before the centre the cell holds the
    cavity pressure and ``P = sqrt(2 c s dp)``. The two branches meet with equal value and
    slope at dp = D (C1: the square root is the envelope of the lines), so Newton sees a C1
    function; below dp = D / 4 the square root is continued by its tangent (finite slope at
    dp -> 0). For s <= 0 (no rupture possible) the plain two-point flux ``c dp / d``. In the
    resolved limit (d -> 0) the flux differs from the two-point one by s d / 2 = O(d)."""
    if s <= 0.0:
        return c * dp / d
    D = s * d * d / (2.0 * c)
    if dp >= D:
        return c * dp / d + 0.5 * s * d
    if dp >= 0.25 * D:
        return math.sqrt(2.0 * c * s * dp)
    return 0.5 * s * d + 2.0 * c * (dp - 0.25 * D) / d


def layer_solution(gap, dH, a0, a, omega, law, p_feed, n_len=8.0):
    """The rupture layer after a groove exit at phi = a0 as a local 1-D problem (issue 16
    item 2, this study): (P0, u(phi) dense, phi_far), P0 the Poiseuille flux from the groove
    into the film at the groove edge. ``gap(phi)`` the film gap, ``dH`` its slope at a0
    (> 0: diverging), ``a`` the circumferential film conductance, ``law`` a CavitationLaw.

    Downstream of the exit the film in the diverging gap falls from p_feed through the
    soft part of the law onto the slow manifold of the cavity, ``theta(p) = q / (omega H)``;
    with ``q = omega H(a0) theta(p_feed) + P0`` the ODE ``a H^3 p' = omega H theta(p) - q``
    is integrated BACKWARD (stable) from phi_far = a0 + n_len L, L = sqrt(2 a H^3 cav_width /
    (omega H')) the sharp-law (JFO) length of the layer, starting on the manifold, and P0
    is the root of p(a0) = p_feed. It depends only on the gap after the exit, omega and the
    law, not on the film's unknowns."""
    Hg = float(gap(a0))
    c = a * Hg ** 3
    if dH <= 0.0:
        raise ValueError("layer_solution: the gap must diverge at the groove exit")
    L = math.sqrt(2 * c * law.width / (omega * dH))
    phi_far = a0 + n_len * L
    u_feed = float(law.u_from_p(p_feed))
    th_feed = float(evaluate(np.array([u_feed]), law)[2][0])
    rhs, jac = _ode(gap, a, omega, law)

    def u_on_manifold(q):
        target = q / (omega * float(gap(phi_far)))
        return brentq(lambda v: evaluate(np.array([v]), law)[2][0] - target, -5.0, 1e3,
                      xtol=1e-14)

    def run(P0, dense=False):
        q = omega * Hg * th_feed + P0
        return solve_ivp(rhs, (phi_far, a0), [u_on_manifold(q)], method="Radau", args=(q,),
                         rtol=RTOL, atol=0.1 * RTOL, dense_output=dense, jac=jac)
    P_jfo = math.sqrt(2 * c * omega * dH * law.width)
    P0 = brentq(lambda P: run(P).y[0, -1] - u_feed, 1e-6 * P_jfo, 3 * P_jfo,
                xtol=1e-13 * P_jfo)
    return P0, run(P0, dense=True).sol, phi_far


def exit_layer(prob, n_len=8.0, linear_gap=False):
    """:func:`layer_solution` for the 1-D film: (P0, u(phi) dense, phi_far, gap). In 1-D
    P0 is the exact continuous q - omega H theta_feed up to the manifold start
    (exponentially small). ``linear_gap``: the gap linearised at the exit, ``H(phi_a) +
    H'(phi_a) (phi - phi_a)`` (local information only)."""
    a0 = prob.span[0]
    Hg = float(prob.H(a0))
    dH = -prob.eps * math.sin(a0 - prob.phi_hmax)
    gap = (lambda phi: Hg + dH * (phi - a0)) if linear_gap else prob.H
    P0, sol, phi_far = layer_solution(gap, dH, a0, prob.a, prob.omega, prob.law, prob.p_feed,
                                      n_len)
    return P0, sol, phi_far, gap


def layer_correction(film, first_only=False):
    """Deferred (defect) correction of the face fluxes in the exit layer (``exit="layer"``):
    per face k, ``q_L - F_k(u_L)``, the layer's exact flux ``q_L = omega H(phi_a)
    theta_feed + P0`` (:func:`exit_layer`) minus the scheme's flux evaluated on the layer's
    own profile u_L at the cell centres, for the faces whose cells all lie within the layer
    (centres up to phi_far); 0 elsewhere. ``first_only``: the groove-exit face only.

    Added to the scheme's fluxes it makes them exact wherever the cells hold the layer's
    values, on any grid, so the discrete q is the layer's; it is a constant (no Jacobian
    change, C-infinity in the unknowns) and vanishes with the scheme's truncation error once
    the grid resolves the layer, so the limit is the unmodified scheme's."""
    pr = film.prob
    P0, sol, phi_far, gap = exit_layer(pr, linear_gap=film.exit == "layer_lin")
    q_L = pr.omega * film.Hf[0] * film.th_feed + P0
    inside = np.flatnonzero(film.phi <= phi_far)
    corr = np.zeros(film.n + 1)
    if inside.size == 0:
        return corr
    u = np.full(film.n, float(sol(phi_far)[0]))
    u[inside] = sol(film.phi[inside])[0]
    model = copy.copy(film)             # the scheme on the layer's own gap (truncation error
    model.exit = "sg"                   # of the scheme on the model problem, -> 0 with h)
    model.Hf = gap(film.phi_f)
    model.cond = film.cond * (model.Hf / film.Hf) ** 3
    F = model.fluxes(u)
    last = 1 if first_only else inside.size     # faces 0 ... K-1 have all their cells inside
    corr[:last] = q_L - F[:last]
    return corr


def rupture_layer(prob, q, half_width, n_len=8.0, gap="linear"):
    """The film around its free (Swift-Stieber) rupture as a local 1-D problem, given the flux
    q through the cavity (``free`` part; 2026-12-07): (u(phi) dense, phi_r, window half width,
    the gap used). phi_r is where the full film's Couette flux equals q, ``omega H(phi_r) = q``
    (first such point after the minimum gap), ``ell = sqrt(s / A)`` the width of the law's soft
    rupture (s = K delta the law's shoulder, ``A = omega H' / (2 a H^3)`` the full film's
    curvature at a sharp rupture), and the window ``max(half_width, n_len ell)`` about phi_r.
    The ODE ``a H^3 p' = omega H theta(p) - q`` is integrated BACKWARD (stable) from the
    window's far end plus ``half_width``, starting on the cavity's manifold ``theta(p) = q /
    (omega H)``, to its near end minus ``half_width``. ``gap``: "linear" (H and H' at phi_r only:
    the local information a 2-D film has per row) or "exact" (prob.H)."""
    phi_min = prob.phi_hmax + math.pi                     # minimum gap
    phi_r = brentq(lambda x: prob.omega * prob.H(x) - q, phi_min + 1e-9, phi_min + math.pi - 1e-6,
                   xtol=1e-15)
    Hr = float(prob.H(phi_r))
    dH = -prob.eps * math.sin(phi_r - prob.phi_hmax)
    law = prob.law
    A = prob.omega * dH / (2 * prob.a * Hr ** 3)
    ell = math.sqrt(law.K * law.delta / A)
    W = max(half_width, n_len * ell)
    if gap == "linear":
        def H(x):
            return Hr + dH * (x - phi_r)
    else:
        H = prob.H
    x_far, x_near = phi_r + W + half_width, phi_r - W - half_width
    target = q / (prob.omega * float(H(x_far)))
    u_far = brentq(lambda v: evaluate(np.array([v]), law)[2][0] - target, -5.0, 1e3, xtol=1e-14)
    rhs, jac = _ode(H, prob.a, prob.omega, law)
    r = solve_ivp(rhs, (x_far, x_near), [u_far], method="Radau", args=(q,), rtol=RTOL,
                  atol=0.1 * RTOL, dense_output=True, jac=jac)

    def sol(x):
        return r.sol(np.clip(x, x_near, x_far))[0]
    return sol, phi_r, W, H


def rupture_correction(film, q, n_len=8.0, gap="linear"):
    """Defect correction of the face fluxes at the free rupture, given the cavity flux q: per
    face whose two cells lie in the window of :func:`rupture_layer`, ``q - F_k(u_R)``, the
    local problem's exact flux minus the scheme's own face flux on the local profile u_R at the
    cell centres (the scheme evaluated on the local problem's gap, so the correction vanishes
    with the scheme's truncation error whatever the local gap); 0 elsewhere. The same idea as
    :func:`layer_correction` at the groove exit, but the rupture lies where the film puts it,
    so the correction depends on the solution through q: :func:`solve_rupture` iterates."""
    sol, phi_r, W, H = rupture_layer(film.prob, q, 2 * film.dphi, n_len, gap)
    inwin = np.abs(film.phi - phi_r) <= W
    model = copy.copy(film)
    model.rupture_corr = None
    model.Hf = H(film.phi_f)
    model.cond = film.cond * (model.Hf / film.Hf) ** 3
    F = model.fluxes(sol(film.phi))
    corr = np.zeros(film.n + 1)
    both = np.zeros(film.n + 1, dtype=bool)
    both[1:-1] = inwin[:-1] & inwin[1:]
    corr[both] = q - F[both]
    return corr, phi_r, int(both.sum())


def solve_rupture(film, u0=None, n_len=8.0, gap="linear", max_iter=20):
    """The film with the free-rupture correction: the correction for the current q, the film
    solved with it, q updated by a secant on ``q -> q(film solved with the correction for q)``
    until q changes by < 1e-12 relative (3 to 5 solves). Returns (u, iterations)."""
    film.rupture_corr = None
    u = film.solve(u0)
    q = film.q(u)
    prev = None
    for it in range(1, max_iter + 1):
        film.rupture_corr, _, _ = rupture_correction(film, q, n_len, gap)
        u = film.solve(u)
        g = film.q(u) - q
        if abs(g) < 1e-12 * abs(q):
            return u, it
        q_next = q + g if prev is None or g == prev[1] else q - g * (q - prev[0]) / (g - prev[1])
        prev = (q, g)
        q = q_next
    raise RuntimeError(f"free-rupture correction: q not converged on n = {film.n}")


def interpolate(film_from: Film1D, u, film_to: Film1D):
    """u of one grid on another (linear in phi, constant extrapolation to the edges)."""
    return np.interp(film_to.phi, film_from.phi, u)


def solve_sequence(prob, grids, rupture=None, **kw):
    """Solutions on grids (ascending), each warm-started from the previous one; ``rupture``
    ("linear" or "exact"): with the free-rupture correction (:func:`solve_rupture`)."""
    out = {}
    prev = None
    for n in grids:
        f = Film1D(prob, n, **kw)
        u0 = None if prev is None else interpolate(prev[0], prev[1], f)
        u = f.solve(u0) if rupture is None else solve_rupture(f, u0, gap=rupture)[0]
        out[n] = (f, u)
        prev = (f, u)
    return out


def reference(prob, n_ref=2 ** 14, **kw):
    """The discrete solution on n_ref cells (grid sequence from 64)."""
    grids = [64 * 2 ** k for k in range(int(math.log2(n_ref // 64)) + 1)]
    return solve_sequence(prob, grids, **kw)[n_ref]


# ---------------------------------------------------------------- semi-analytic reference

def _ode(gap, a, omega, law):
    """(rhs, jac) of ``du/dphi = (omega H theta(u) - q) / (a H^3 dp/du)`` (args q) for
    scipy's Radau; the Jacobian from law_eval's dp/du and dtheta/du, with ``d2p/du2 =
    dp/du (1 - dp/du / K) / delta`` (the derivative of K sigmoid(u / delta))."""
    buf = [np.empty(1) for _ in range(4)]
    ua = np.empty(1)

    def ev(y):
        ua[0] = y[0]
        law_eval(ua, law.p_cav, law.K, law.delta, *buf)
        return buf[1][0], buf[2][0], buf[3][0]

    def rhs(phi, y, q):
        dp, th, _ = ev(y)
        H = gap(phi)
        return [(omega * H * th - q) / (a * H ** 3 * dp)]

    def jac(phi, y, q):
        dp, th, dth = ev(y)
        H = gap(phi)
        d2p = dp * (1.0 - dp / law.K) / law.delta
        return [[(omega * H * dth * dp - (omega * H * th - q) * d2p) / (a * H ** 3 * dp * dp)]]
    return rhs, jac


def shoot(prob, q, dense=False, rtol=RTOL, atol=0.1 * RTOL):
    """Integrate u backward from the groove's west edge (p_feed) to its east edge."""
    rhs, jac = _ode(prob.H, prob.a, prob.omega, prob.law)
    a0, a1 = prob.span
    u_feed = float(prob.law.u_from_p(prob.p_feed))
    return solve_ivp(rhs, (a1, a0), [u_feed], method="Radau", args=(q,), rtol=rtol,
                     atol=atol, dense_output=dense, jac=jac)


def semi_analytic(prob, q_guess, rel=2e-3):
    """(q, dense u(phi)) of the continuous regularised problem: brentq on q for
    p(groove east edge) = p_feed, bracket q_guess (1 -+ rel)."""
    law = prob.law
    u_feed = float(law.u_from_p(prob.p_feed))

    def g(q):
        s = shoot(prob, q)
        return s.y[0, -1] - u_feed
    lo, hi = q_guess * (1 - rel), q_guess * (1 + rel)
    q = brentq(g, lo, hi, xtol=1e-14 * q_guess, rtol=1e-14)
    return q, shoot(prob, q, dense=True).sol


def semi_analytic_load(prob, sol, m=200001):
    """Load of the semi-analytic solution (composite Simpson on m points)."""
    from scipy.integrate import simpson
    a0, a1 = prob.span
    phi = np.linspace(a0, a1, m)
    p, _, _, _ = evaluate(sol(phi)[0], prob.law)
    x = p - prob.p0
    return np.array([simpson(x * np.cos(phi), x=phi), simpson(x * np.sin(phi), x=phi)])


# ---------------------------------------------------------------- reports

def layers(prob, sol):
    """(rupture layer, reformation band, front) [deg] of the semi-analytic solution: from
    the groove exit to where p first falls below p_cav + 0.1 cav_width; from where p last
    is below p_cav + 0.1 cav_width to where it reaches p0 at the reformation front; and
    that last point."""
    phi = np.linspace(*prob.span, 400001)
    p, _, _, _ = evaluate(sol(phi)[0], prob.law)
    low = np.flatnonzero(p < prob.law.p_cav + 0.1 * prob.cav_width)
    k1, k2 = low[0], low[-1]
    k3 = k2 + np.flatnonzero(p[k2:] >= prob.p0)[0]
    return (math.degrees(phi[k1] - phi[0]), math.degrees(phi[k3] - phi[k2]),
            math.degrees(phi[k2]))


def orders(vals):
    d = np.diff(vals)
    return [math.log2(d[i] / d[i + 1]) if d[i + 1] != 0 and d[i] / d[i + 1] > 0 else float("nan")
            for i in range(len(d) - 1)]


GRIDS = [20, 40, 80, 160, 320, 640, 1280, 2560, 5120]
WIDTHS = [1e2, 1e3, 3e3]


def study(prob, muscl, grids=GRIDS, exit="sg", rupture=None):
    """Discrete solutions on grids, the semi-analytic q, W and solution, and per grid
    (n, W, q, Wq, film, u): Wq the load of the backward ODE solution with the DISCRETE q,
    i.e. what the exact full film, front and cavity carry for that q."""
    sols = solve_sequence(prob, grids, muscl=muscl, exit=exit, rupture=rupture)
    f, u = sols[grids[-1]]
    qs, sol = semi_analytic(prob, f.q(u))
    Ws = semi_analytic_load(prob, sol)
    rows = []
    for n in grids:
        f, u = sols[n]
        q = f.q(u)
        Wq = semi_analytic_load(prob, shoot(prob, q, dense=True).sol)
        rows.append((n, f.load(u), q, Wq, f, u))
    return qs, Ws, sol, rows


POINTS_DEG = [260.0, 300.0, 330.0]
EXITS = {"sg": "film.py groove_exit (today)", "layer": "layer correction, exact gap",
         "layer_lin": "layer correction, gap linear at the exit"}


def _table_head(column, grids):
    """The head of a table of errors per grid: cav_width, ``column``, quantity, the grids, orders."""
    print(f"| cav_width | {column} | quantity | " + " | ".join(str(n) for n in grids)
          + " | orders (successive) |")
    print("|---|---|---|" + "---|" * (len(grids) + 1))


def _load_rows(label, qs, Ws, rows):
    """The Wx, Wy and q rows of a table: relative errors against the semi-analytic solution on
    each grid and the successive orders."""
    for key, k in (("Wx", 0), ("Wy", 1)):
        vals = [r[1][k] for r in rows]
        print(f"| {label} | {key} | " + " | ".join(f"{v / Ws[k] - 1:+.2e}" for v in vals) + " | "
              + ", ".join(f"{x:.2f}" for x in orders(vals)) + " |")
    print("| | | q | " + " | ".join(f"{r[2] / qs - 1:+.1e}" for r in rows) + " | |", flush=True)


def main(argv):
    parts = argv or ["check", "widths", "split", "treatment", "points"]
    base = Problem()
    if "check" in parts:
        print("\n### Fine discrete solution against the semi-analytic one (1 kPa)\n")
        print("| transport | n | q discrete | q semi-analytic | rel | Wx rel | Wy rel |")
        print("|---|---|---|---|---|---|---|")
        for muscl in (False, True):
            f, u = reference(base, muscl=muscl)
            q_d = f.q(u)
            q_s, sol = semi_analytic(base, q_d)
            W_d, W_s = f.load(u), semi_analytic_load(base, sol)
            print(f"| {'MUSCL' if muscl else 'upwind'} | {f.n} | {q_d:.9g} | {q_s:.9g} | "
                  f"{q_d / q_s - 1:+.2e} | {W_d[0] / W_s[0] - 1:+.2e} | {W_d[1] / W_s[1] - 1:+.2e} |")
        lr, lb, pf = layers(base, sol)
        print(f"\nsemi-analytic W = ({W_s[0]:.6g}, {W_s[1]:.6g}) Pa rad, q = {q_s:.9g}; "
              f"rupture layer {lr:.2f} deg, reformation band {lb:.2f} deg at {pf:.2f} deg")
    if "widths" in parts:
        print("\n### Wy error against the semi-analytic solution, per cav_width\n")
        print("| cav_width | transport | rupture layer / reformation band [deg] | "
              + " | ".join(str(n) for n in GRIDS) + " | orders of Wy (successive) |")
        print("|---|---|---|" + "---|" * (len(GRIDS) + 1))
        for w in WIDTHS:
            prob = replace(base, cav_width=w)
            for muscl in (False, True):
                qs, Ws, sol, rows = study(prob, muscl)
                lr, lb, _ = layers(prob, sol)
                errs = [r[1][1] / Ws[1] - 1 for r in rows]
                o = orders([r[1][1] for r in rows])
                print(f"| {w:g} Pa | {'MUSCL' if muscl else 'upwind'} | {lr:.2f} / {lb:.2f} | "
                      + " | ".join(f"{e:+.2e}" for e in errs) + " | "
                      + ", ".join(f"{x:.2f}" for x in o) + " |", flush=True)
    if "split" in parts:
        for w in WIDTHS:
            prob = replace(base, cav_width=w)
            qs, Ws, sol, rows = study(prob, True)
            print(f"\n### Where the error comes from: cav_width {w:g} Pa, MUSCL "
                  f"(semi-analytic q = {qs:.6g})\n")
            print("| n | q error | Wy error | Wy of the exact film with the discrete q, error "
                  "| discrete Wy against that |")
            print("|---|---|---|---|---|")
            for n, W, q, Wq, _, _ in rows:
                print(f"| {n} | {q / qs - 1:+.2e} | {W[1] / Ws[1] - 1:+.2e} | "
                      f"{Wq[1] / Ws[1] - 1:+.2e} | {W[1] / Wq[1] - 1:+.2e} |", flush=True)
    if "treatment" in parts:
        print("\n### Exit-layer correction: Wy and q error against the semi-analytic solution "
              "(MUSCL)\n")
        _table_head("exit flux", GRIDS)
        for w in WIDTHS:
            prob = replace(base, cav_width=w)
            for ex, label in EXITS.items():
                qs, Ws, sol, rows = study(prob, True, exit=ex)
                o = orders([r[1][1] for r in rows])
                print(f"| {w:g} Pa | {label} | Wy | "
                      + " | ".join(f"{r[1][1] / Ws[1] - 1:+.2e}" for r in rows) + " | "
                      + ", ".join(f"{x:.2f}" for x in o) + " |")
                print("| | | q | " + " | ".join(f"{r[2] / qs - 1:+.1e}" for r in rows)
                      + " | |", flush=True)
    if "free" in parts:
        print("\n### Free rupture: groove at the maximum gap (phi_hmax = 0); errors against the "
              "semi-analytic solution\n")
        grids = GRIDS[:-1]
        _table_head("transport", grids)
        for w in (1e3, 1e2):
            prob = replace(base, phi_hmax=0.0, cav_width=w)
            for muscl in (False, True):
                qs, Ws, _, rows = study(prob, muscl, grids)
                _load_rows(f"{w:g} Pa | {'MUSCL' if muscl else 'upwind'}", qs, Ws, rows)
    if "rupture" in parts:
        print("\n### Free rupture with the rupture defect correction (groove at the maximum gap, "
              "MUSCL); errors against the semi-analytic solution\n")
        grids = GRIDS[:-2]
        _table_head("local gap", grids)
        for w in (1e3, 1e2, 1e1):
            prob = replace(base, phi_hmax=0.0, cav_width=w)
            for gap in ("linear", "exact"):
                qs, Ws, _, rows = study(prob, True, grids, rupture=gap)
                _load_rows(f"{w:g} Pa | {gap}", qs, Ws, rows)
    if "points" in parts:
        print("\n### Pressure at fixed points, cav_width 1 kPa, MUSCL: p - p_exact [Pa] "
              "(linear interpolation of the cell values)\n")
        print("| exit flux | phi | p_exact - p0 [Pa] | " + " | ".join(str(n) for n in GRIDS)
              + " |")
        print("|---|---|---|" + "---|" * len(GRIDS))
        for ex in ("sg", "layer"):
            qs, Ws, sol, rows = study(base, True, exit=ex)
            for deg in POINTS_DEG:
                x = math.radians(deg)
                pe = evaluate(sol(x), base.law)[0][0]
                errs = []
                for r in rows:
                    f, u = r[4], r[5]
                    errs.append(np.interp(x, f.phi, evaluate(u, base.law)[0]) - pe)
                print(f"| {EXITS[ex]} | {deg:g} deg | {pe - base.p0:.1f} | "
                      + " | ".join(f"{e:+.3g}" for e in errs) + " |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
