"""Compiled interface-Jacobian step: the scheme of :mod:`rotor_fmu.interface` in one numba call.

Why: in the interface-Jacobian run-ups (scenarios/jeffcott_runup_*.yaml) the rotor's step is
the serial part of every Gauss-Seidel macro step (rotor, then the two bearings at once with
``coupling.parallel``). The numpy form (``interface.step_with_interface_jacobian``) costs
about 1 ms per macro step on the 6-dof Jeffcott rotor, almost all of it fixed overhead of
~60 numpy calls on 6 x 6 matrices: an eigen-decomposition per station (dissipative
projection), two SVDs (spectral norms for the sub-step count) and a fresh
``(2n, nsub n)`` affine-map matrix every step (the film coefficients change every step, so
its cache never hits). This module does the same arithmetic in one compiled call.

Same scheme, same discrete decisions (module doc of :mod:`rotor_fmu.interface`):

* dissipative projection of each station's symmetric damping part (closed-form 2 x 2
  eigenvalues ``m -+ r``; the projection ``max(lam_2, 0) (S - lam_1 I) / (2 r)`` equals
  ``Q diag(max(lam, 0)) Q^T``), the skew part kept; a positive semi-definite part is used
  unchanged;
* augmented matrices ``M^-1 K + M^-1 B K_b B^T`` (for a diagonal mass matrix, as the
  Jeffcott rotor's, every entry is one product and one sum: the same bits as numpy's);
* sub-steps ``max(n_substeps(H), ceil(H rho / 2 - 1e-12))`` with ``rho = max(||M^-1 C_aug||_2,
  ||M^-1 K_aug||_2^(1/2))``; the 2-norms from the largest eigenvalue of ``A^T A`` (Jacobi
  rotations: plain loops, which numba compiles in seconds, unlike its LAPACK bindings);
* trapezoidal sub-steps with the speed-dependent matrices at the macro step's mid time
  and the speed quantized to ``omega_quantum`` (as :func:`rotor_fmu.linear_rotor._numpy_substeps`),
  the unbalance forcing from the exact angle at every sub-step end (its segment formula).

What differs is only floating-point order: the sub-step map is applied by solving with an
LU factorization instead of multiplying by an explicit inverse and the precomputed powers
``P^N``, ``P^j Q``; sums run in another order than BLAS's. Results agree with the numpy form
to round-off (tests/test_ij_kernel.py; the seeded run-ups: BENCHMARKS.md).

Where a discrete decision could go either way by round-off, the kernel does not decide: it
returns :data:`FALLBACK` and the caller runs the numpy form for that macro step, which then
decides exactly as before. That is: a station's smallest damping eigenvalue within
``1e-12 (|m| + r)`` of 0, a sub-step count ``H rho / 2`` within 1e-9 (relative) of an
integer that matters, more than ``LSTABLE_SWITCH`` sub-steps needed (the L-stable path
stays numpy), non-finite inputs or a non-finite result (the numpy form raises its errors).
"""

from __future__ import annotations

import math

import numpy as np

from . import linear_rotor as _linear_rotor

DONE, FALLBACK = 0, 1
DECIDE_TOL = 1e-9          # relative distance of H rho / 2 - 1e-12 to an integer below which numpy decides
PSD_TOL = 1e-12            # relative size of a station's smallest damping eigenvalue below which numpy decides


def _project(C, out):
    """Dissipative projection of the station damping ``C`` (nb, 2, 2) into ``out``; False when
    the sign of a smallest eigenvalue is not clear (see the module doc)."""
    for i in range(C.shape[0]):
        c00, c01, c10, c11 = C[i, 0, 0], C[i, 0, 1], C[i, 1, 0], C[i, 1, 1]
        s00 = 0.5 * (c00 + c00)              # S = 0.5 (C + C^T), as numpy forms it
        s01 = 0.5 * (c01 + c10)
        s11 = 0.5 * (c11 + c11)
        m = 0.5 * (s00 + s11)
        dd = 0.5 * (s00 - s11)
        r = math.sqrt(dd * dd + s01 * s01)
        lam1, lam2 = m - r, m + r
        scale = abs(m) + r
        if lam1 > PSD_TOL * scale or scale == 0.0:
            out[i, 0, 0], out[i, 0, 1], out[i, 1, 0], out[i, 1, 1] = c00, c01, c10, c11
            continue
        if lam1 >= -PSD_TOL * scale:
            return False
        if lam2 <= 0.0:
            p00 = p01 = p11 = 0.0
        else:                                 # lam2 q2 q2^T, q2 q2^T = (S - lam1 I) / (lam2 - lam1)
            f = lam2 / (2.0 * r)
            p00, p01, p11 = f * (s00 - lam1), f * s01, f * (s11 - lam1)
        out[i, 0, 0] = p00 + (c00 - s00)
        out[i, 0, 1] = p01 + (c01 - s01)
        out[i, 1, 0] = p01 + (c10 - s01)
        out[i, 1, 1] = p11 + (c11 - s11)
    return True


def _augment(A0, MiB, bdofs, X, out):
    """out = A0 + M^-1 B X_b B^T with the station blocks X (nb, 2, 2)."""
    n = A0.shape[0]
    for r in range(n):
        for c in range(n):
            out[r, c] = A0[r, c]
    for i in range(X.shape[0]):
        for b in range(2):
            col = bdofs[i, b]
            for r in range(n):
                acc = 0.0
                for a in range(2):
                    acc += MiB[r, 2 * i + a] * X[i, a, b]
                out[r, col] = out[r, col] + acc


def _norm2(A):
    """Spectral norm of A: the square root of the largest eigenvalue of the symmetric A^T A,
    by cyclic Jacobi rotations (Golub & Van Loan, "Matrix Computations", 4th ed., sec. 8.5;
    eigenvalues to ~eps ||A^T A||, so the largest to relative ~n eps) until the off-diagonal
    part is below 1e-15 of the diagonal's (at most 50 sweeps)."""
    n = A.shape[0]
    S = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for k in range(n):
                acc += A[k, i] * A[k, j]
            S[i, j] = acc
            S[j, i] = acc
    for _sweep in range(50):
        off, diag = 0.0, 0.0
        for i in range(n):
            diag += S[i, i] * S[i, i]
            for j in range(i + 1, n):
                off += S[i, j] * S[i, j]
        if off <= 1e-30 * diag or off == 0.0:
            break
        for p in range(n - 1):
            for q in range(p + 1, n):
                apq = S[p, q]
                if apq == 0.0:
                    continue
                theta = (S[q, q] - S[p, p]) / (2.0 * apq)
                t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                sn = t * c
                for k in range(n):            # S <- J^T S J, J the rotation in the (p, q) plane
                    skp, skq = S[k, p], S[k, q]
                    S[k, p] = c * skp - sn * skq
                    S[k, q] = sn * skp + c * skq
                for k in range(n):
                    spk, sqk = S[p, k], S[q, k]
                    S[p, k] = c * spk - sn * sqk
                    S[q, k] = sn * spk + c * sqk
    big = 0.0
    for i in range(n):
        big = max(big, S[i, i])
    return math.sqrt(big)


# (omega, alpha, angle) of the speed table: the rotor's own evaluation, compiled here with the
# rest of the kernel (linear_rotor jits it only with ROTORCOSIM_ROTOR_KERNEL=numba)
_drive = getattr(_linear_rotor._drive_eval, "py_func", _linear_rotor._drive_eval)


def _unbalance(t0, h, nsub, tt, ww, aa, me, ph, fu):
    """Unbalance forces at t0 + k h, k = 0..nsub, into fu (nsub + 1, 2 n_unb), as
    :func:`rotor_fmu.linear_rotor._unbalance_pairs` evaluates them (one speed-table segment:
    omega, angle as polynomials of the offset; else the table at each time)."""
    t1 = t0 + nsub * h
    inside = False
    for k in range(tt.shape[0]):
        if t0 < tt[k] < t1:
            inside = True
    w0, a0, g0 = _drive(t0, tt, ww, aa)
    for k in range(nsub + 1):
        tau = h * k
        if inside:
            wt, at, ang = _drive(t0 + tau, tt, ww, aa)
        else:
            wt, at, ang = w0 + a0 * tau, a0, g0 + w0 * tau + 0.5 * a0 * tau * tau
        for j in range(me.shape[0]):
            phi = ang + ph[j]
            c, s = math.cos(phi), math.sin(phi)
            fu[k, 2 * j] = me[j] * (wt * wt * c + at * s)
            fu[k, 2 * j + 1] = me[j] * (wt * wt * s - at * c)


def _round_half_even(x):
    """Python's ``round(x)`` of a finite float (ties to even), as a float."""
    r = math.floor(x)
    d = x - r
    if d > 0.5 or (d == 0.5 and r % 2.0 != 0.0):
        r += 1.0
    return r


def _lu(S, perm):
    """In-place LU with partial pivoting (L below the diagonal, unit diagonal)."""
    n = S.shape[0]
    for i in range(n):
        perm[i] = i
    for c in range(n):
        p, big = c, abs(S[c, c])
        for i in range(c + 1, n):
            if abs(S[i, c]) > big:
                big, p = abs(S[i, c]), i
        if p != c:
            for j in range(n):
                S[c, j], S[p, j] = S[p, j], S[c, j]
            perm[c], perm[p] = perm[p], perm[c]
        piv = S[c, c]
        for i in range(c + 1, n):
            f = S[i, c] / piv
            S[i, c] = f
            if f != 0.0:
                for j in range(c + 1, n):
                    S[i, j] -= f * S[c, j]


def _lu_solve(S, perm, r, x):
    n = S.shape[0]
    for i in range(n):
        acc = r[perm[i]]
        for j in range(i):
            acc -= S[i, j] * x[j]
        x[i] = acc
    for i in range(n - 1, -1, -1):
        acc = x[i]
        for j in range(i + 1, n):
            acc -= S[i, j] * x[j]
        x[i] = acc / S[i, i]


def _substeps(s, t0, h, nsub, fF, MiK, MiC, MiG, MiKc, MiKa, MiU, me, ph, tt, ww, aa, wq, speed_dep, out):
    """``nsub`` trapezoidal sub-steps of h from state s (2n) at t0 into out (module doc)."""
    n = MiK.shape[0]
    w, a, _ = _drive(t0 + 0.5 * nsub * h, tt, ww, aa)
    if speed_dep and wq > 0.0:
        w = _round_half_even(w / wq) * wq     # Python's round()
    elif not speed_dep:
        w, a = 0.0, 0.0
    hh, h2 = 0.5 * h, 0.25 * h * h
    AK = np.empty((n, n))
    AC = np.empty((n, n))
    S = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            AK[i, j] = MiK[i, j] + w * MiKc[i, j] + a * MiKa[i, j]
            AC[i, j] = MiC[i, j] + w * MiG[i, j]
            S[i, j] = (1.0 if i == j else 0.0) + hh * AC[i, j] + h2 * AK[i, j]
    perm = np.empty(n, dtype=np.int64)
    _lu(S, perm)
    nu = me.shape[0]
    fu = np.empty((nsub + 1, 2 * nu))
    _unbalance(t0, h, nsub, tt, ww, aa, me, ph, fu)
    q = s[:n].copy()
    v = s[n:].copy()
    g = np.empty(n)
    r = np.empty(n)
    x = np.empty(n)
    for k in range(nsub):
        for i in range(n):
            acc = 2.0 * fF[i]
            for j in range(2 * nu):
                acc += MiU[i, j] * (fu[k, j] + fu[k + 1, j])
            g[i] = acc
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += AK[i, j] * (2.0 * q[j] + hh * v[j]) + AC[i, j] * v[j]
            r[i] = v[i] + hh * (g[i] - acc)
        _lu_solve(S, perm, r, x)
        for i in range(n):
            q[i] += hh * (v[i] + x[i])
            v[i] = x[i]
    for i in range(n):
        out[i] = q[i]
        out[n + i] = v[i]


def _finite(a):
    for x in a.flat:
        if not math.isfinite(x):
            return False
    return True


def ij_step(s, t0, dt, nsub_struct, F, K, C, bdofs, MiK, MiC, MiG, MiKc, MiKa, MiB, Mifg, MiU,
            me, ph, tt, ww, aa, wq, speed_dep, lstable_switch, out):
    """One interface-Jacobian macro step (module doc) from state s at t0 into out;
    returns (DONE or FALLBACK, sub-steps used)."""
    n = MiK.shape[0]
    nb = K.shape[0]
    if not (_finite(F) and _finite(K) and _finite(C)):
        return FALLBACK, 0
    Cp = np.empty((nb, 2, 2))
    if not _project(C, Cp):
        return FALLBACK, 0
    MiKa_ = np.empty((n, n))
    MiCa_ = np.empty((n, n))
    _augment(MiK, MiB, bdofs, K, MiKa_)
    _augment(MiC, MiB, bdofs, Cp, MiCa_)
    if not (_finite(MiKa_) and _finite(MiCa_)):
        return FALLBACK, 0
    need = dt * max(_norm2(MiCa_), math.sqrt(_norm2(MiKa_))) / 2.0
    if not need <= lstable_switch * (1.0 - DECIDE_TOL):
        return FALLBACK, 0
    x = need - 1e-12
    k = _round_half_even(x)
    if k >= nsub_struct and abs(x - k) <= DECIDE_TOL * max(1.0, x):
        return FALLBACK, 0
    nsub = max(nsub_struct, int(math.ceil(x)))
    # F_eff = F + K r0 + C v0 per station, then M^-1 (f_g + B F_eff)
    Fe = np.empty(2 * nb)
    for i in range(nb):
        ix, iy = bdofs[i, 0], bdofs[i, 1]
        for a in range(2):
            Fe[2 * i + a] = F[i, a] + ((K[i, a, 0] * s[ix] + K[i, a, 1] * s[iy])
                                       + (Cp[i, a, 0] * s[n + ix] + Cp[i, a, 1] * s[n + iy]))
    fF = np.empty(n)
    for r in range(n):
        acc = 0.0
        for j in range(2 * nb):
            acc += MiB[r, j] * Fe[j]
        fF[r] = Mifg[r] + acc
    _substeps(s, t0, dt / nsub, nsub, fF, MiKa_, MiCa_, MiG, MiKc, MiKa, MiU, me, ph, tt, ww, aa,
              wq, speed_dep, out)
    if not _finite(out):
        return FALLBACK, nsub
    return DONE, nsub


def _compile():
    """The compiled ij_step, or None without numba or without the content-keyed cache (the
    caller then keeps the numpy form)."""
    try:
        import numba  # noqa: F401
    except ImportError:  # pragma: no cover - numba is a dependency
        return None
    try:   # numba cache keyed by source content (bearing_fmu/_numba_cache.py): FMUs extract afresh
        from bearing_fmu._numba_cache import njit_cached
    except ImportError:  # pragma: no cover - the FMU used without rotorcosim installed: numba's
        return None      # default cache lies in the fresh extraction folder, so every run would compile
    g = globals()
    for name in ("_project", "_augment", "_norm2", "_drive", "_unbalance", "_round_half_even", "_lu",
                 "_lu_solve", "_substeps", "_finite"):
        g[name] = njit_cached(g[name])
    return njit_cached(ij_step)


kernel = _compile()
