"""Matrix exponential of the floating ring's small augmented ODE (no FMI import).

:meth:`bearing_fmu.floating_ring.FloatingRing._advance_exponential` needs ``expm(h A)`` of an
8 x 8 matrix once per ring sub-step. ``scipy.linalg.expm`` costs 90 us there single-threaded
and 17 ms when OpenBLAS threads on a loaded host (measured on this 2-core machine), more than
the films' own step; this compiled kernel takes a few microseconds.

Method: scaling and squaring with a Taylor polynomial (Moler & Van Loan 2003, "Nineteen dubious
ways to compute the exponential of a matrix, twenty-five years later", SIAM Review 45(1) 3-49,
methods 1 and 3): ``s`` halvings until ``||A h||_1 / 2^s <= 1/2``, the Taylor series to degree
16 (truncation below ``0.5^17 / 17! = 2e-20`` relative), then ``s`` squarings. The ring's
stiff mode (``h C / m_r`` up to a few hundred) takes about ten squarings; its exponential is
then ~0, as it should be.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["expm_small"]


@nb.njit(cache=True)
def _matmul(A, B):
    """A @ B by loops: numba's @ calls BLAS, whose threads cost more than the product here."""
    n, m, p = A.shape[0], A.shape[1], B.shape[1]
    C = np.zeros((n, p))
    for i in range(n):
        for k in range(m):
            a = A[i, k]
            if a != 0.0:
                for j in range(p):
                    C[i, j] += a * B[k, j]
    return C


@nb.njit(cache=True)
def expm_small(A):
    """exp(A) of a small dense square matrix A (module doc)."""
    n = A.shape[0]
    norm = 0.0
    for j in range(n):
        c = 0.0
        for i in range(n):
            c += abs(A[i, j])
        norm = max(norm, c)
    s = 0
    while norm > 0.5:
        norm *= 0.5
        s += 1
    X = A * (0.5 ** s)
    E = np.eye(n)
    T = np.eye(n)
    for k in range(1, 17):
        T = _matmul(T, X) / k
        E += T
    for _ in range(s):
        E = _matmul(E, E)
    return E
