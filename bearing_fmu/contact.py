"""Asperity contact of the journal on the bearing shell (mixed lubrication, "rub").

When the whirl orbit fills the clearance the minimum film thickness falls to the size
of the surface roughness and part of the load is carried by asperity contact. The
model is the statistical rough-surface contact of Greenwood & Tripp (1970, "The
contact of two nominally flat rough surfaces", Proc. IMechE 185, 625-633), the usual
mixed-lubrication closure of journal-bearing codes: the nominal contact pressure at a
point with gap ``h`` (distance of the mean planes, the film thickness of the Reynolds
equation) and composite RMS roughness ``sigma`` (Gaussian summit heights) is::

    p_c(h) = KE * F_5/2(h / sigma),
    F_n(H) = (2 pi)^-1/2 int_H^inf (s - H)^n exp(-s^2 / 2) ds
           = Gamma(n + 1) (2 pi)^-1/2 exp(-H^2 / 4) D_(-n-1)(H)

with ``D`` the parabolic cylinder function (DLMF 12.5.1 with U(a, z) = D_(-a-1/2)(z);
scipy.special.pbdv), exact for every H including H < 0 (mean planes interpenetrating);
the popular curve fit 4.4086e-5 (4 - H)^6.804 (Arcoumanis et al. 1997, SAE 972924) is
11 % low at H = 0 and 74 % low at H = 3, so it is not used. ``KE`` is the product ``K E'``
of the Greenwood-Tripp roughness factor ``K = (8 sqrt 2 / 15) pi (eta beta sigma)^2
sqrt(sigma / beta)`` and the composite elastic modulus ``E'``. The pressure is cut off
where h >= 6 sigma (F_5/2(6) = 6e-9 F_5/2(0)), so a journal away from the shell costs
nothing.

The journal is aligned with the shell, so ``h = c - e cos(psi)`` (``psi`` from the
eccentricity direction) does not depend on z, and the contact force is along the line
of centres, pushing the journal back::

    F_n(e) = R B  int p_c(c - e cos psi) cos psi dpsi      (over |psi| < psi_6,
                                                            where h < 6 sigma)

evaluated by 48-point Gauss-Legendre quadrature on [0, psi_6] (the integrand vanishes
smoothly towards psi_4, so the quadrature is smooth in e; the film grid is not
used: on 40 cells the contact zone is about one cell wide). The feed groove is
ignored (a shell-side recess of a few degrees). Boundary friction ``mu F_n`` acts on
the journal surface against the sliding velocity ``v_t + omega R`` (``v_t`` the
tangential velocity of the journal centre), regularized with ``tanh(v_s / v_reg)``,
``v_reg = 1 mm/s``; it gives a tangential force on the journal centre and the torque
``-mu F_n R sign(v_s)`` about +z.

Interface-Jacobian coefficients ``K = -dF/dr``, ``C = -dF/dv`` of the contact force by
central differences of this closed form (:func:`contact_coefficients`).

Film thickness with contact (:func:`average_gap`): in the asperity layer the nominal gap
``h`` reaches 0 and below (mean planes interpenetrating; the Greenwood-Tripp pressure is
meant for that range), where the Reynolds film would have no thickness left. With
``contact = 1`` the film uses the expected gap of the same Gaussian roughness instead,
``h_T = sigma (H Phi(H) + phi(H))`` (H = h / sigma; Phi, phi the standard normal
distribution and density), the average gap of Patir & Cheng (1978, "An average flow
model for determining effects of three-dimensional roughness on partial hydrodynamic
lubrication", J. Lubr. Technol. 100(1)) and Wu & Zheng (1989, J. Tribol. 111(1)):
``h_T > 0`` for every H, ``h_T - h = sigma (phi(H) - H (1 - Phi(H)))`` (4e-4 sigma at
H = 3, below 1e-15 sigma from H = 8: there ``h`` is used unchanged), and
``dh_T/dt = Phi(H) dh/dt``. The pressure and shear flow factors of the full average-flow
model are not included (they matter for the load of a thin rough film; here the film
only has to stay defined while the contact carries the journal).
"""

from __future__ import annotations

import functools
import math

import numba as nb
import numpy as np
from numpy.polynomial import chebyshev
from scipy.special import ndtr, pbdv

__all__ = ["contact_force", "contact_coefficients", "average_gap", "F52", "H_CUTOFF"]

H_CUTOFF = 6.0               # p_c = 0 for h / sigma >= 6 (F_5/2(6) / F_5/2(0) = 6e-9)
_F52_C = math.gamma(3.5) / math.sqrt(2.0 * math.pi)
_GL_X, _GL_W = np.polynomial.legendre.leggauss(48)
V_REG = 1.0e-3               # friction regularization velocity [m/s]
H_AVG = 8.0                  # average gap = nominal gap where h / sigma >= 8


def F52(H):
    """Greenwood-Tripp integral F_5/2(H) (exact, see module doc); array or scalar."""
    H = np.asarray(H, dtype=float)
    return _F52_C * np.exp(-0.25 * H * H) * pbdv(-3.5, H)[0]


# F_5/2 for the force quadrature: a Chebyshev series of ln F_5/2 on [CHEB_LO, H_CUTOFF], evaluated
# in compiled code. Why: the parabolic cylinder function costs ~3 us per point, 0.16 ms per force
# at 48 points, and a macro step in contact asks for up to five forces per bearing: in the
# from-rest oil-bath run's contact phase F52 took 1.6 s of 14 s (cProfile, serial). The series is
# fitted to the definition integrated by quadrature (_f52_by_quadrature, to 1e-15), not to pbdv,
# whose own relative error reaches 1e-9 near H = 6 and 3e-11 near H = -6 (measured against
# scipy's adaptive quad at 1e-13); degree 50 holds F_5/2 to ~1e-13 relative over the range
# (tests/test_bearing_contact.py). Deeper than CHEB_LO (mean planes interpenetrating by more than
# 8 sigma, past every allowed contact_h_limit) the force falls back to F52.
CHEB_LO, CHEB_DEG = -8.0, 50


def _f52_by_quadrature(H: float) -> float:
    """F_5/2(H) for H >= CHEB_LO by quadrature of its definition (module doc) with s = H + u^2:
    (2 pi)^-1/2 int_0^U 2 u^6 exp(-(H + u^2)^2 / 2) du, a smooth integrand (no fractional power of s - H at
    the lower end), U = 8 (past it the integrand is below exp(-1500) for H >= -8), 16 panels of
    40-point Gauss-Legendre: within 5e-16 of scipy's adaptive quad at relative tolerance 1e-13 on
    [-8, 6]. Not scipy.integrate: importing it costs every bearing FMU 0.2-0.3 s of start-up."""
    x, w = np.polynomial.legendre.leggauss(40)
    edges = np.linspace(0.0, 8.0, 17)
    total = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        u = 0.5 * (b - a) * (x + 1.0) + a
        total += 0.5 * (b - a) * float(np.dot(w, 2.0 * u ** 6 * np.exp(-0.5 * (H + u * u) ** 2)))
    return total / math.sqrt(2.0 * math.pi)


@functools.cache
def f52_series() -> np.ndarray:
    """Chebyshev coefficients of ln F_5/2 on [CHEB_LO, H_CUTOFF], by interpolation at the
    CHEB_DEG + 1 Chebyshev points of the first kind (about 3 ms, once per process)."""
    k = np.arange(CHEB_DEG + 1)
    x = np.cos(np.pi * (k + 0.5) / (CHEB_DEG + 1))
    H = 0.5 * (H_CUTOFF - CHEB_LO) * x + 0.5 * (H_CUTOFF + CHEB_LO)
    return chebyshev.chebfit(x, np.log([_f52_by_quadrature(h) for h in H]), CHEB_DEG)


@nb.njit(cache=True, nogil=True)
def f52_cheb(H, coef):
    """F_5/2(H) for H in [CHEB_LO, H_CUTOFF] from the series ``coef`` of its logarithm (Clenshaw)."""
    x = (2.0 * H - (H_CUTOFF + CHEB_LO)) / (H_CUTOFF - CHEB_LO)
    b1 = 0.0
    b2 = 0.0
    for j in range(coef.size - 1, 0, -1):
        b1, b2 = 2.0 * x * b1 - b2 + coef[j], b1
    return math.exp(x * b1 - b2 + coef[0])


@nb.njit(cache=True, nogil=True)
def _normal_force_series(e, c, R, B, sigma, KE, gl_x, gl_w, coef):
    """:func:`normal_force`'s quadrature with F_5/2 from its series; nan where some H lies
    below CHEB_LO."""
    psi6 = math.acos(max((c - H_CUTOFF * sigma) / e, -1.0))
    total = 0.0
    for k in range(gl_x.size):
        cs = math.cos(0.5 * psi6 * (gl_x[k] + 1.0))
        H = (c - e * cs) / sigma
        if H < CHEB_LO:
            return math.nan
        total += gl_w[k] * f52_cheb(min(H, H_CUTOFF), coef) * cs
    return R * B * KE * psi6 * total


def normal_force(e: float, *, c: float, R: float, B: float, sigma: float, KE: float) -> float:
    """Magnitude [N] of the asperity contact force at eccentricity e [m] (>= 0)."""
    if e <= 0.0:
        return 0.0
    cm = (c - H_CUTOFF * sigma) / e          # cos(psi_6)
    if cm >= 1.0:
        return 0.0
    f = _normal_force_series(e, c, R, B, sigma, KE, _GL_X, _GL_W, f52_series())
    if not math.isnan(f):
        return float(f)
    psi6 = math.acos(max(cm, -1.0))          # deeper than CHEB_LO somewhere: the closed form
    psi = 0.5 * psi6 * (_GL_X + 1.0)
    w = 0.5 * psi6 * _GL_W
    cs = np.cos(psi)
    return float(2.0 * R * B * KE * np.dot(w, F52((c - e * cs) / sigma) * cs))


@functools.lru_cache(maxsize=32)
def _normal_force_of(e, c, R, B, sigma, KE):
    """:func:`normal_force`, remembered for the last few arguments: it is a pure function of
    them costing ~10 us (0.16 ms with the parabolic cylinder function), and a macro step asks
    for it at one eccentricity up to five times (the FMU's outputs, the four velocity steps of
    :func:`contact_coefficients`); the same arguments give the same float."""
    return normal_force(e, c=c, R=R, B=B, sigma=sigma, KE=KE)


def contact_force(x, y, vx, vy, omega, *, c, R, B, sigma, KE, mu):
    """(Fx, Fy, F_n, torque): contact force ON the journal [N] in the bearing frame,
    its normal magnitude [N] and the friction torque on the journal about +z [N m]."""
    e = math.hypot(x, y)
    Fn = _normal_force_of(e, c, R, B, sigma, KE)
    if Fn == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    ex, ey = x / e, y / e                     # line of centres (to the contact point)
    tx, ty = -ey, ex                          # counter-clockwise tangent
    vs = vx * tx + vy * ty + omega * R        # sliding velocity of the journal surface
    s = math.tanh(vs / V_REG)
    Fx = -Fn * ex - mu * Fn * s * tx
    Fy = -Fn * ey - mu * Fn * s * ty
    return Fx, Fy, Fn, -mu * Fn * s * R


def contact_coefficients(x, y, vx, vy, omega, *, c, R, B, sigma, KE, mu, rel_step=1e-5):
    """(K, C) 2x2 of the contact force, K = -dF/dr [N/m], C = -dF/dv [N s/m]; central
    differences with steps rel_step * sigma (positions) and V_REG * 1e-2 (velocities)."""
    kw = dict(c=c, R=R, B=B, sigma=sigma, KE=KE, mu=mu)
    z0 = np.array([x, y, vx, vy], dtype=float)
    steps = (rel_step * sigma, rel_step * sigma, 1e-2 * V_REG, 1e-2 * V_REG)
    if math.hypot(x, y) + 2 * steps[0] < c - H_CUTOFF * sigma:    # no stencil point in contact
        return np.zeros((2, 2)), np.zeros((2, 2))
    D = np.zeros((2, 4))
    for j, hstep in enumerate(steps):
        zp, zm = z0.copy(), z0.copy()
        zp[j] += hstep
        zm[j] -= hstep
        Fp = contact_force(*zp, omega, **kw)[:2]
        Fm = contact_force(*zm, omega, **kw)[:2]
        D[:, j] = -(np.array(Fp) - np.array(Fm)) / (2 * hstep)
    return D[:, :2].copy(), D[:, 2:].copy()


@nb.njit(cache=True)
def _all_above(H, He, s):
    """True when every H / s and He / s is >= H_AVG (avg's test in :func:`average_gap`, entry
    by entry, so the same decision to the last bit)."""
    for i in range(H.size):
        if not H[i] / s >= H_AVG:
            return False
    for i in range(He.size):
        if not He[i] / s >= H_AVG:
            return False
    return True


def average_gap(H, He, Hdot, s):
    """(H_T, He_T, Hdot_T): the non-dimensional gaps (h / c) at cell centres and faces and
    dH/dt replaced by the expected gap of Gaussian roughness (module doc), ``s = sigma / c``.
    Entries with h >= 8 sigma are returned unchanged (new arrays in any case). With every
    entry there (the journal away from its shell: most of a run from rest, whose bearings keep
    contact = 1) only the copies are made: 1 us instead of 10 us a call, the same values."""
    if _all_above(np.asarray(H, dtype=float).ravel(), np.asarray(He, dtype=float).ravel(), s):
        return np.array(H, dtype=float), np.array(He, dtype=float), np.array(Hdot, dtype=float)
    return _average_gap_map(H, He, Hdot, s)


def _average_gap_map(H, He, Hdot, s):
    """:func:`average_gap` without its short path: the map entry by entry (unchanged where
    h >= 8 sigma)."""
    def avg(G):
        """(h_T / c, mask of the entries below 8 sigma, Phi there)."""
        out = np.array(G, dtype=float)
        Hs = out / s
        near = Hs < H_AVG
        Hn = Hs[near]
        Phi = ndtr(Hn)
        out[near] = s * (Hn * Phi + np.exp(-0.5 * Hn * Hn) / math.sqrt(2.0 * math.pi))
        return out, near, Phi

    HT, near, Phi = avg(H)
    HeT = avg(He)[0]
    HdT = np.array(Hdot, dtype=float)
    HdT[near] *= Phi
    return HT, HeT, HdT
