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

from functools import cached_property

import numba as nb
import numpy as np
import scipy.fft as sfft


@nb.njit(cache=True, nogil=True)
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


@nb.njit(cache=True, nogil=True)
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


@nb.njit(inline="always", cache=True, nogil=True)
def _cyclic_solve_modes(y, a, inv, cp, zz, beta, gamma, zden, modes, fact, xr):
    """Solve the factored cyclic tridiagonal systems of :func:`_tangent_kernel`, one lane per
    driven mode q: ``y`` (n_phi, nm) holds the right-hand sides on entry and the solutions on
    exit, which are also written to ``xr[modes[q], :]``. The forward sweep with the reciprocal
    pivots ``inv`` and ``cp``, the backward sweep, then the Sherman-Morrison correction with
    ``zz`` (the solution for the corner vector) and its denominator ``zden``; ``fact`` (nm,)
    scratch."""
    n, nm = y.shape
    for i in range(n):
        for q in range(nm):
            y[i, q] = (y[i, q] - a[i] * y[i - 1, q]) * inv[i, q] if i > 0 else y[0, q] * inv[0, q]
    for i in range(n - 2, -1, -1):
        for q in range(nm):
            y[i, q] -= cp[i, q] * y[i + 1, q]
    for q in range(nm):
        fact[q] = (y[0, q] + beta * y[n - 1, q] / gamma[q]) / zden[q]
    for i in range(n):
        for q in range(nm):
            y[i, q] -= fact[q] * zz[i, q]
            xr[modes[q], i] = y[i, q]


@nb.njit(cache=True, nogil=True)
def _tangent_kernel(ce, H3, rhs, dce, dH3, drhs, lam, ck, coef, groove, feed_hat, x):
    """Modes of the pressure and of its directional derivatives, into ``x`` (1 + m, n_z,
    n_phi): x[0] the modes of :meth:`HalfSommerfeld.solve` at the base kinematics, x[1 + q]
    the derivative in direction q, ``M_k dx = dd_k - dM_k x0`` (M_k the cyclic tridiagonal
    system of mode k, :func:`_solve_many_kernel`; ``dce, dH3, drhs`` (m, n_phi) the
    directional derivatives of the east-face conductances, H^3 and the right-hand side).
    Each mode's system is factored once (Thomas with Sherman-Morrison, Press et al.,
    Numerical Recipes, sec. 2.7, reciprocal pivots) and solved for the m derivative
    right-hand sides together. The modes are independent, so their recurrences run side by
    side, one lane per mode (the innermost loops, which the compiler vectorises): each mode
    sees the same operations in the same order as when the modes were solved one after the
    other, so the values are the same bit for bit; the recurrences over the columns are
    sequential, and side by side their latency is shared (issue 16 speed: 0.4x the time at
    n_z = n_phi = 40)."""
    n = ce.size
    m = dce.shape[0]
    n_z = lam.size
    nm = 0                          # the modes something drives (the others are exactly zero)
    for k in range(n_z):
        if ck[k] == 0.0 and feed_hat[k] == 0.0:
            # a mode odd about the mid-plane: nothing drives it (the gap, and so every
            # right-hand side, is uniform in z), so it and its derivatives are zero
            x[:, k, :] = 0.0
        else:
            nm += 1
    modes = np.empty(nm, dtype=np.int64)
    q = 0
    for k in range(n_z):
        if not (ck[k] == 0.0 and feed_hat[k] == 0.0):
            modes[q] = k
            q += 1
    lam_m = np.empty(nm)
    ck_m = np.empty(nm)
    fh_m = np.empty(nm)
    lk = np.empty(nm)
    for q in range(nm):
        lam_m[q] = lam[modes[q]]
        ck_m[q] = ck[modes[q]]
        fh_m[q] = feed_hat[modes[q]]
        lk[q] = coef * lam_m[q]
    a = np.empty(n)
    c = np.empty(n)
    b = np.empty((n, nm))
    cp = np.empty((n, nm))
    inv = np.empty((n, nm))
    zz = np.empty((n, nm))
    y = np.empty((m + 1, n, nm))
    gamma = np.empty(nm)
    zden = np.empty(nm)
    fact = np.empty(nm)
    db = np.empty((m, n))
    for r in range(m):
        for i in range(n):
            iw = i - 1 if i > 0 else n - 1
            db[r, i] = dce[r, i] + dce[r, iw]
    for i in range(n):
        iw = i - 1 if i > 0 else n - 1
        if groove[i]:
            a[i] = 0.0
            c[i] = 0.0
            for q in range(nm):
                b[i, q] = 1.0
        else:
            a[i] = -ce[iw]
            c[i] = -ce[i]
            for q in range(nm):
                b[i, q] = (ce[i] + ce[iw]) + coef * (lam_m[q] * H3[i])
    alpha = c[n - 1]
    beta = a[0]
    # the modified tridiagonal systems factored once (Sherman-Morrison for the corners)
    for q in range(nm):
        gamma[q] = -b[0, q]
        den = b[0, q] - gamma[q]
        inv[0, q] = 1.0 / den
        cp[0, q] = c[0] * inv[0, q]
        zz[0, q] = gamma[q] * inv[0, q]
    for i in range(1, n):
        ui = alpha if i == n - 1 else 0.0
        for q in range(nm):
            den = (b[i, q] - alpha * beta / gamma[q] if i == n - 1 else b[i, q]) - a[i] * cp[i - 1, q]
            inv[i, q] = 1.0 / den
            cp[i, q] = c[i] * inv[i, q]
            zz[i, q] = (ui - a[i] * zz[i - 1, q]) * inv[i, q]
    for i in range(n - 2, -1, -1):
        for q in range(nm):
            zz[i, q] -= cp[i, q] * zz[i + 1, q]
    for q in range(nm):
        zden[q] = 1.0 + zz[0, q] + beta * zz[n - 1, q] / gamma[q]
    # the base right-hand side first: the derivative ones need its solution x0
    x0 = y[0]
    for i in range(n):
        for q in range(nm):
            x0[i, q] = fh_m[q] if groove[i] else ck_m[q] * rhs[i]
    _cyclic_solve_modes(x0, a, inv, cp, zz, beta, gamma, zden, modes, fact, x[0])
    for r in range(m):
        yr = y[1 + r]
        for i in range(n):
            iw = i - 1 if i > 0 else n - 1
            ie = i + 1 if i + 1 < n else 0
            for q in range(nm):
                if groove[i]:
                    yr[i, q] = 0.0
                else:       # dd - dM x0 (dM: the derivatives of a, b, c; 0 on groove rows)
                    yr[i, q] = (ck_m[q] * drhs[r, i] + dce[r, iw] * x0[iw, q]
                                - (db[r, i] + lk[q] * dH3[r, i]) * x0[i, q] + dce[r, i] * x0[ie, q])
        _cyclic_solve_modes(yr, a, inv, cp, zz, beta, gamma, zden, modes, fact, x[1 + r])


@nb.njit(cache=True, nogil=True)
def _tangent_modes(H, He, Hdot, omega, dH, dHe, dHdot, dz, dphi, a_phi, coef, lam, ck, groove,
                   feed_hat, x):
    """The coefficients of :func:`_tangent_kernel` from the gap and its directions (east-face
    conductances ``dz a_phi He^3 / dphi``, H^3, the Couette and squeeze right-hand side and
    their directional derivatives), then the kernel, in one call without the GIL (the
    interface coefficients are computed every macro step in a whirl; issue 16)."""
    n = H.size
    m = dH.shape[0]
    ce = np.empty(n)
    H3 = np.empty(n)
    rhs = np.empty(n)
    dce = np.empty((m, n))
    dH3 = np.empty((m, n))
    drhs = np.empty((m, n))
    k = dz * a_phi / dphi
    for i in range(n):
        iw = i - 1 if i > 0 else n - 1
        ce[i] = k * He[i] ** 3
        H3[i] = H[i] ** 3
        rhs[i] = -(dz * omega * (He[i] - He[iw]) + 2.0 * dphi * dz * Hdot[i])
        for r in range(m):
            dce[r, i] = k * 3.0 * He[i] ** 2 * dHe[r, i]
            dH3[r, i] = 3.0 * H[i] ** 2 * dH[r, i]
            drhs[r, i] = -(dz * omega * (dHe[r, i] - dHe[r, iw]) + 2.0 * dphi * dz * dHdot[r, i])
    _tangent_kernel(ce, H3, rhs, dce, dH3, drhs, lam, ck, coef, groove, feed_hat, x)


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

    @cached_property
    def coefficient_rows(self):
        """(Mh, modes, wrow) for the interface coefficients (:func:`.linearize._hs_coefficients`):
        the axial modes that carry the film (``modes``: ``ck`` or ``feed_hat`` nonzero; the
        others are exactly zero, :func:`_tangent_kernel`), the rows of the field to compute
        and their weights in the force. The gap depends on phi only, both edges are at p0
        and the groove spans the width, so the field is symmetric about the mid-plane: where
        the rows of :attr:`idst_matrix` on those modes are mirror images of each other bit
        for bit (even n_z: the odd modes are exactly zero), the lower half of the rows is
        computed and each weighted 2, which is a quarter of the transform's products and half
        the force quadrature (issue 16; equal to the full field to round-off,
        tests/test_hs_batched.py); otherwise every row, weight 1."""
        n_z = self.grid.n_z
        M = self.idst_matrix
        modes = np.flatnonzero((self.ck != 0.0) | (self.feed_hat != 0.0))
        Mm = M[:, modes]
        half = (n_z + 1) // 2
        if n_z % 2 == 0 and np.array_equal(Mm, Mm[::-1]):
            return np.ascontiguousarray(Mm[:half]), modes.astype(np.int64), np.full(half, 2.0)
        return np.ascontiguousarray(Mm), modes.astype(np.int64), np.ones(n_z)

    @cached_property
    def idst_matrix(self):
        """(n_z, n_z) matrix of the inverse orthonormal DST-II along z (``M @ X`` equals
        ``scipy.fft.idst(X, type=2, norm="ortho", axis=0)`` to round-off), built once: the
        interface coefficients transform their 5 fields inside one numba call with it."""
        return np.ascontiguousarray(sfft.idst(np.eye(self.grid.n_z), type=2, norm="ortho", axis=0))

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

    def solve_tangent(self, H, He, Hdot, omega, dH, dHe, dHdot):
        """Unclipped gauge pressure P (n_z, n_phi) at (H, He, Hdot) and its directional
        derivatives dP (m, n_z, n_phi) along the m gap directions ``dH, dHe, dHdot`` (m,
        n_phi): the linear system differentiated (:func:`_tangent_kernel`), one factorisation
        per axial mode for all m + 1 right-hand sides, one batched inverse DST. Equal to the
        derivative of :meth:`solve` to round-off (tests/test_hs_batched.py)."""
        g = self.grid
        n_z, n_phi = g.n_z, g.n_phi
        x = np.empty((dH.shape[0] + 1, n_z, n_phi))
        _tangent_modes(H, He, Hdot, float(omega), dH, dHe, dHdot, g.dz, g.dphi, self.a_phi,
                       g.dphi * self.a_z / g.dz, self.lam, self.ck, self.gr, self.feed_hat, x)
        P = sfft.idst(x, type=2, norm="ortho", axis=1)
        return P[0], P[1:]
