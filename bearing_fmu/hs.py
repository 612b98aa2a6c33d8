"""Fast half-Sommerfeld (Guembel) solver: quasi-static linear Reynolds, p >= p0.

The full-film (theta = 1) form of the finite-volume equations of
:mod:`.film`, with Dirichlet p = p0 at both axial edges, groove columns held
at p_feed, and the squeeze velocity dH/dt as input:

    dz [omega (H_e - H_w) - a_phi (H_e^3 (P_E - P) - H_w^3 (P - P_W)) / dphi]
      + dphi a_z H^3 (T P)_j / dz + 2 dphi dz dH/dt = 0,      P = p - p0,

where ``T`` is the axial second-difference operator with half-cell Dirichlet
edges (diag 3, 2, ..., 2, 3; off-diagonals -1). Because the gap depends on
phi only, the orthonormal DST-II in z diagonalises T (eigenvalues
``4 sin^2(pi k / (2 n_z))``, k = 1..n_z) and the problem separates into n_z
independent cyclic tridiagonal systems in phi (Sherman-Morrison + Thomas),
O(n_z n_phi log n_z) in all. The pressure is then clipped at p0 (Guembel,
half-Sommerfeld condition). For ``axial_bc = 1`` (free to air) the same
Dirichlet edges are used: the penalty of eq. (6) only matters for p < p0,
which the half-Sommerfeld condition removes anyway (b -> infinity limit).
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.fft as sfft


@nb.njit(cache=True)
def cyclic_tridiag_many(a, b, c, d, x):
    """Solve n_sys cyclic tridiagonal systems (rows of a, b, c, d) into x.

    Row i of system k: ``a[k,i] x[i-1] + b[k,i] x[i] + c[k,i] x[i+1] = d[k,i]``,
    indices periodic. Sherman-Morrison on the Thomas algorithm (Press et al.,
    Numerical Recipes, section 2.7).
    """
    n_sys, n = b.shape
    cp = np.empty(n)
    bb = np.empty(n)
    y = np.empty(n)
    zz = np.empty(n)
    for k in range(n_sys):
        alpha = c[k, n - 1]
        beta = a[k, 0]
        gamma = -b[k, 0]
        for i in range(n):
            bb[i] = b[k, i]
        bb[0] -= gamma
        bb[n - 1] -= alpha * beta / gamma
        # forward sweep for two right-hand sides: d and (gamma, 0, ..., alpha)
        m = bb[0]
        cp[0] = c[k, 0] / m
        y[0] = d[k, 0] / m
        zz[0] = gamma / m
        for i in range(1, n):
            m = bb[i] - a[k, i] * cp[i - 1]
            cp[i] = c[k, i] / m
            ui = alpha if i == n - 1 else 0.0
            y[i] = (d[k, i] - a[k, i] * y[i - 1]) / m
            zz[i] = (ui - a[k, i] * zz[i - 1]) / m
        for i in range(n - 2, -1, -1):
            y[i] -= cp[i] * y[i + 1]
            zz[i] -= cp[i] * zz[i + 1]
        fact = (y[0] + beta * y[n - 1] / gamma) / (1.0 + zz[0] + beta * zz[n - 1] / gamma)
        for i in range(n):
            x[k, i] = y[i] - fact * zz[i]


@nb.njit(cache=True)
def _solve_many_kernel(ce, cw, H3, rhs, lam, ck, coef, groove, feed_hat, x):
    """:func:`cyclic_tridiag_many` over the m n_z systems of :meth:`HalfSommerfeld.solve_many`,
    building each system's coefficients on the fly from the per-kinematics vectors
    (m, n_phi) with the operations ``solve`` uses (a = -cw, c = -ce,
    b = (ce + cw) + coef (lam_k H^3), d = ck_k rhs; groove rows identity / feed), so the
    result is the same to the last bit."""
    m, n = ce.shape
    n_z = lam.size
    a = np.empty(n)
    b = np.empty(n)
    c = np.empty(n)
    d = np.empty(n)
    cp = np.empty(n)
    bb = np.empty(n)
    y = np.empty(n)
    zz = np.empty(n)
    for q in range(m):
        for k in range(n_z):
            for i in range(n):
                if groove[i]:
                    a[i] = 0.0
                    c[i] = 0.0
                    b[i] = 1.0
                    d[i] = feed_hat[k]
                else:
                    a[i] = -cw[q, i]
                    c[i] = -ce[q, i]
                    b[i] = (ce[q, i] + cw[q, i]) + coef * (lam[k] * H3[q, i])
                    d[i] = ck[k] * rhs[q, i]
            alpha = c[n - 1]
            beta = a[0]
            gamma = -b[0]
            for i in range(n):
                bb[i] = b[i]
            bb[0] -= gamma
            bb[n - 1] -= alpha * beta / gamma
            mm = bb[0]
            cp[0] = c[0] / mm
            y[0] = d[0] / mm
            zz[0] = gamma / mm
            for i in range(1, n):
                mm = bb[i] - a[i] * cp[i - 1]
                cp[i] = c[i] / mm
                ui = alpha if i == n - 1 else 0.0
                y[i] = (d[i] - a[i] * y[i - 1]) / mm
                zz[i] = (ui - a[i] * zz[i - 1]) / mm
            for i in range(n - 2, -1, -1):
                y[i] -= cp[i] * y[i + 1]
                zz[i] -= cp[i] * zz[i + 1]
            fact = (y[0] + beta * y[n - 1] / gamma) / (1.0 + zz[0] + beta * zz[n - 1] / gamma)
            for i in range(n):
                x[q, k, i] = y[i] - fact * zz[i]


class HalfSommerfeld:
    """Quasi-static half-Sommerfeld solver bound to a grid and the constants."""

    def __init__(self, grid, a_phi, a_z, p0, p_feed):
        self.grid = grid
        n_z, n_phi = grid.n_z, grid.n_phi
        self.a_phi, self.a_z, self.p0 = a_phi, a_z, p0
        k = np.arange(1, n_z + 1)
        self.lam = 4.0 * np.sin(np.pi * k / (2 * n_z)) ** 2            # (n_z,)
        self.ck = sfft.dst(np.ones(n_z), type=2, norm="ortho")         # DST of ones
        self.feed_hat = (p_feed - p0) * self.ck
        self.gr = grid.groove
        self._a = np.empty((n_z, n_phi))
        self._b = np.empty((n_z, n_phi))
        self._c = np.empty((n_z, n_phi))
        self._d = np.empty((n_z, n_phi))
        self._x = np.empty((n_z, n_phi))

    def solve(self, H, He, Hdot, omega):
        """Return the unclipped gauge pressure P = p - p0, shape (n_z, n_phi)."""
        g = self.grid
        dphi, dz = g.dphi, g.dz
        He3 = He ** 3
        Hw3 = np.roll(He3, 1)
        Hw = np.roll(He, 1)
        ce = dz * self.a_phi * He3 / dphi
        cw = dz * self.a_phi * Hw3 / dphi
        rhs = -(dz * omega * (He - Hw) + 2.0 * dphi * dz * Hdot)      # (n_phi,)
        a, b, c, d = self._a, self._b, self._c, self._d
        a[:] = -cw
        c[:] = -ce
        b[:] = (ce + cw) + (dphi * self.a_z / dz) * np.outer(self.lam, H ** 3)
        d[:] = np.outer(self.ck, rhs)
        if self.gr.any():
            a[:, self.gr] = 0.0
            c[:, self.gr] = 0.0
            b[:, self.gr] = 1.0
            d[:, self.gr] = self.feed_hat[:, None]
        cyclic_tridiag_many(a, b, c, d, self._x)
        return sfft.idst(self._x, type=2, norm="ortho", axis=0)

    def solve_many(self, H, He, Hdot, omega):
        """:meth:`solve` for m kinematics at once (same omega): ``H, He, Hdot`` of shape
        (m, n_phi), returns P of shape (m, n_z, n_phi). The same operations as ``solve``
        on stacked arrays (one cyclic tridiagonal sweep over all m n_z systems, one
        batched inverse DST), so each slice equals ``solve`` of that kinematics to
        round-off (bit for bit in the tests); used by the interface-Jacobian finite
        differences (bearing_fmu/linearize.py), about 8x cheaper than m calls."""
        g = self.grid
        dphi, dz = g.dphi, g.dz
        n_z, n_phi = g.n_z, g.n_phi
        m = H.shape[0]
        He3 = He ** 3
        Hw3 = np.roll(He3, 1, axis=1)
        Hw = np.roll(He, 1, axis=1)
        ce = dz * self.a_phi * He3 / dphi
        cw = dz * self.a_phi * Hw3 / dphi
        rhs = -(dz * omega * (He - Hw) + 2.0 * dphi * dz * Hdot)      # (m, n_phi)
        x = np.empty((m, n_z, n_phi))
        _solve_many_kernel(ce, cw, H ** 3, rhs, self.lam, self.ck, dphi * self.a_z / dz,
                           self.gr, self.feed_hat, x)
        return sfft.idst(x, type=2, norm="ortho", axis=1)
