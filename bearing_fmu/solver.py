"""Time integration of the mass-conserving film: BDF1/2 + Newton-Krylov.

Method
------
* Unknown: universal variable u per cell (:mod:`.cavitation`); the dynamic
  state is theta(u) (paper eq. 4: only 2 H dtheta/dt carries a time
  derivative, H and dH/dt are inputs held over the step).
* Time: variable-step BDF2 (BDF1 for the first two steps after
  initialisation, while history builds up), one nonlinear solve per sub-step.
* Local error: Milne's device on theta, the difference between the corrector
  and an extrapolation predictor of the same order (linear for BDF1, quadratic
  for BDF2), times 1/3 resp. 2/11 (the ratio of the error constants, exact for
  constant steps). RMS norm over film cells divided by ``theta_atol``; a step is
  accepted when <= 1; the next step is ``0.9 err^(-1/(q+1))`` times the last,
  limited to [0.2, 2] (Hairer, Norsett & Wanner, I.II.4).
* Nonlinear solve: Newton. Every iteration assembles the exact 5-point
  stencil Jacobian (numba; 7-point with ``theta_transport = 1``, whose limited
  second-order face values couple i +- 2; the band ordering covers them). Default (``krylov_refactor = 0``): band LU
  (``dgbtrf``, ordering of :mod:`.grid`) and a direct solve every iteration, except that an
  iteration after a Newton step of at most ``LU_REUSE_BELOW`` (10) tolerances keeps the
  last LU (simplified Newton), so does one whose Newton matrix moved by at most
  ``JACOBIAN_REUSE_BELOW`` in every row, and a later LU of the same solve is redone only
  from the first band row that moved by more (:func:`refactor_partial`);
  on the half-width grid the LU is cheap (n_z/2 bandwidth), and this measured
  fastest on 40x40, 80x80 and 160x40. Option ``krylov_refactor = m > 0``:
  Newton-Krylov, GMRES preconditioned by the LAST band LU, REUSED across
  iterations and time steps, refreshed when GMRES needs more than m
  iterations (pays off when the LU is expensive relative to a solve). Converged when the increment in theta is below
  ``newton_atol`` and in p below ``newton_rtol`` of the pressure range (directly
  or by the contraction-rate estimate). A step whose Newton iteration fails is
  retried with h/4.
* Exact restore: the factorisation is a pure function of (u_jac, the BDF
  coefficient and the kinematics at the last refactorisation), which are part of
  the state; :meth:`TransientFilm.set_state` refactorises from them, so a
  restored run repeats the original bit for bit.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import scipy.sparse as sp
from scipy.linalg import lapack
from scipy.sparse.linalg import splu

from .film import assemble, assemble_muscl, stencil_matvec, stencil_rows_to_band, stencil_to_band


@nb.njit(cache=True, nogil=True)
def _limit_switch(u, un, delta, valid=None):
    """Newton damping across the cavitation switch (in place on ``un``).

    A full Newton step taken with the film-branch slope dp/du = K can throw a
    cell deep into the cavity branch (where dp/du ~ 0) and vice versa, and the
    iteration then cycles. A cell that crosses the switch u = 0 is stopped one
    switch width ``delta`` beyond it (film -> cavity: at the switch u = 0,
    where both branches have slope 1/2); the next iteration, with the Jacobian of
    the new branch, continues from there. Cells are also kept above u = -2
    (theta = -1), which no solution reaches. Only the path changes, not the
    solution. ``valid`` (optional, :func:`dominant_update`): cleared where a cell is moved.
    """
    for k in range(u.size):
        v = un[k]
        if u[k] > 0.0 and un[k] < 0.0:
            un[k] = 0.0
        elif u[k] < 0.0 and un[k] > delta:
            un[k] = delta
        if un[k] < -2.0:
            un[k] = -2.0
        if valid is not None and un[k] != v:
            valid[k] = 0            # e and log1p(e) kept for un are not those of the new value


@nb.njit(cache=True, nogil=True)
def dominant_weights(H, He, Hdot, th_dot0, omega, a_phi, a_z, dphi, dz, wrel, frel, wp, wth):
    """Per column: the own-cell (diagonal) coefficients of p and of theta in a cell's
    residual, ``wp`` [1/Pa] (Poiseuille conductances of its four faces) and ``wth``
    (time, squeeze and upwind Couette outflow), as :func:`.film.assemble` builds them
    (interior cells; the edge and mid-plane rows differ by one axial face, which is
    irrelevant for the choice they serve, see :func:`dominant_update`)."""
    n_phi = H.size
    A = dphi * dz
    for i in range(n_phi):
        ie = i
        iw = i - 1 if i > 0 else n_phi - 1
        wr = 1.0 if wrel is None else wrel[i]
        fe = 1.0 if frel is None else frel[ie]
        fw = 1.0 if frel is None else frel[iw]
        cond = a_phi * (He[ie] ** 3 / fe + He[iw] ** 3 / fw) / dphi
        wp[i] = dz * cond + 2.0 * dphi * wr * a_z * H[i] ** 3 / dz
        up = He[ie] if omega >= 0.0 else He[iw]
        wth[i] = abs(A * wr * (2.0 * H[i] * th_dot0 + 2.0 * Hdot[i])) + dz * abs(omega) * up


@nb.njit(cache=True, inline="always")
def _own_part_el(x, e, l1, wp, wth, K, delta):
    """``wp p(v) + wth theta(v)`` (without constants) and its derivative in v, from ``x = v /
    delta``, ``e = exp(-|x|)`` and ``l1 = log1p(e)``
    (what :func:`.cavitation.law_eval` computes for the same v, bit for bit)."""
    s = 1.0 / (1.0 + e)              # sigmoid(|x|); sigmoid(-|x|) = e s
    if x >= 0.0:
        return wp * K * delta * (x + l1) - wth * delta * l1, wp * K * s + wth * e * s
    return wp * K * delta * l1 - wth * delta * (l1 - x), wp * K * e * s + wth * s


@nb.njit(cache=True, nogil=True)
def law_el(u, delta, e_out, l1_out):
    """``e = exp(-|u / delta|)`` and ``log1p(e)`` of each cell, as
    :func:`.cavitation.law_eval` computes them (for :func:`dominant_update`)."""
    for k in range(u.size):
        x = u[k] / delta
        e = math.exp(-abs(x))
        e_out[k] = e
        l1_out[k] = math.log1p(e)


@nb.njit(cache=True, nogil=True)
def dominant_update(u, dx, wp, wth, n_phi, p_cav, K, delta, un, e_u, l1_u, e_n=None,
                    l1_n=None, valid=None):
    """New iterate ``un`` from the Newton increment ``dx`` in u, with each cell's own
    nonlinearity taken exactly: the cell moves to the u at which its own (diagonal) part of
    the residual, ``wp p(u) + wth theta(u)`` (coefficients of :func:`dominant_weights`),
    takes the value the Newton linearisation predicts, ``f(u) + f'(u) dx``. A scalar,
    strictly increasing equation (f' >= min(wp K, wth) > 0), solved by safeguarded
    Newton-bisection (``rtsafe``, Press et al., Numerical Recipes, sec. 9.4) in the bracket
    ``v0 +- |f(v0) - T| / min f'``. It generalises primary-variable switching (Forsyth, Wu &
    Pruess 1995, Adv. Water Resour. 18(1); Lehmann & Ackerer 1998, Transp. Porous Media
    31): a cell governed by theta moves to the linearised theta, one governed by p to the
    linearised p. Why: near the switch theta(u) has the exponential tail
    ``1 - delta e^(-u/delta)`` and Newton in u crawled along it by about delta per
    iteration (BENCHMARKS.md, issue 16). On one branch far from the switch (u and u + dx
    both beyond 12 delta on the same side) f is linear to e^-12 and the plain step
    ``u + dx`` is kept; otherwise the solve ends within 1e-9 delta of the root. The
    solution (r = 0) is the same: only the Newton path changes. ``e_u``, ``l1_u``: e and
    log1p(e) of u (:func:`law_el`; the residual's :func:`.cavitation.law_eval` at u gives
    them), so that f(u) costs no exp or log1p here (1 of the ~2.6-5 evaluations per cell).
    ``e_n``, ``l1_n``, ``valid`` (optional, together): receive e and log1p(e) of ``un`` where
    the root was solved (``valid`` 1 there, 0 elsewhere), for the residual at ``un``."""
    for k in range(u.size):
        i = k % n_phi
        d = dx[k]
        v = u[k] + d
        un[k] = v
        lim = 12.0 * delta
        if (u[k] > lim and v > lim) or (u[k] < -lim and v < -lim):
            if valid is not None:
                valid[k] = 0
            continue            # one branch, far from the switch: f linear to e^-12
        a, b = wp[i], wth[i]
        f0, df0 = _own_part_el(u[k] / delta, e_u[k], l1_u[k], a, b, K, delta)
        un[k], ev, l1v = _own_root(v, f0 + df0 * d, a, b, K, delta)
        if valid is not None:
            e_n[k] = ev
            l1_n[k] = l1v
            valid[k] = 1


@nb.njit(cache=True, inline="always")
def _own_part(v, wp, wth, K, delta):
    """:func:`_own_part_el` of v with the second derivative: f, f' and f'' = (wp K - wth) sigma(x)
    sigma(-x) / delta of ``f = wp p(v) + wth theta(v)`` (x = v / delta; f is convex where
    wp K > wth and concave where wp K < wth, everywhere), and e = exp(-|x|), log1p(e) as
    :func:`.cavitation.law_eval` computes them for v."""
    x = v / delta
    e = math.exp(-abs(x))
    l1 = math.log1p(e)
    f, df = _own_part_el(x, e, l1, wp, wth, K, delta)
    s = 1.0 / (1.0 + e)
    return f, df, (wp * K - wth) * e * s * s / delta, e, l1


@nb.njit(cache=True, nogil=True)
def _own_root(v, target, a, b, K, delta):
    """The v with ``a p(v) + b theta(v) = target`` (strictly increasing in v), from the
    guess v: safeguarded Halley-bisection in the bracket ``v +- |f(v) - target| / min f'``,
    to 1e-9 delta (see :func:`dominant_update`). Halley's step ``-2 e f' / (2 f'^2 - e f'')``
    (cubic convergence; f'' costs no exp or log more than f') needs about one evaluation per
    cell less than Newton's on the run-up films. Returns (v, e, log1p(e)) of the v returned
    (always the last one evaluated), which the residual at the new iterate reads instead of
    computing them again (:func:`.cavitation.law_eval`'s ``valid``)."""
    m = max(min(a * K, b), 1e-300)   # f' >= m; b = 0 only at rest without squeeze
    fv, dfv, d2, ev, l1v = _own_part(v, a, b, K, delta)
    e = fv - target
    lo = v - abs(e) / m
    hi = v + abs(e) / m
    for _ in range(60):
        if abs(e) <= 1e-9 * delta * dfv:
            break           # |v - root| below 1e-9 delta
        if e > 0.0:
            hi = v
        else:
            lo = v
        den = 2.0 * dfv * dfv - e * d2
        vn = v - 2.0 * e * dfv / den if den > 0.0 else v - e / dfv
        if not (lo <= vn <= hi):
            # closed bracket: on a branch where f is linear with slope m, the step lands
            # exactly on the bracket end, which is then the root (an open test sent such
            # cells to bisection, ~35 iterations each)
            vn = 0.5 * (lo + hi)
        if vn == v or hi - lo <= 1e-14 * (abs(v) + delta):
            break
        v = vn
        fv, dfv, d2, ev, l1v = _own_part(v, a, b, K, delta)
        e = fv - target
    return v, ev, l1v


@nb.njit(cache=True, nogil=True)
def dominant_extrapolate(u, u_prev, ratio, wp, wth, n_phi, p_cav, K, delta, out, el,
                         e_n=None, l1_n=None, valid=None):
    """Newton start ``out`` for the next internal step, extrapolated linearly in each cell's
    own part ``f = wp p(u) + wth theta(u)`` (:func:`dominant_update`) instead of in u:
    ``f(out) = f(u) + ratio (f(u) - f(u_prev))``, ``ratio = h / h_prev``. A line in u through
    a cell on theta's exponential tail (or crossing the switch) extrapolates the wrong
    curve; in f it extrapolates the quantity the cell's equation is nearly linear in.
    Cells on one branch far from the switch (u_prev, u and the line's end beyond 12 delta,
    same side) keep the line in u (identical there to e^-12). Measured in the whirl orbit
    of benchmarks/bench_bearing_whirl.py: 7.06 -> 5.22 Newton iterations per macro step.
    ``el`` (4, n): e = exp(-|x|) and log1p(e) of u (rows 0, 1) and of u_prev (rows 2, 3)
    (:func:`law_el`; kept from the steps that accepted them, so f(u) and f(u_prev) cost
    no exp or log1p here). ``e_n``, ``l1_n``, ``valid``: as in :func:`dominant_update`."""
    lim = 12.0 * delta
    for k in range(u.size):
        i = k % n_phi
        v = u[k] + ratio * (u[k] - u_prev[k])
        out[k] = v
        if (u[k] > lim and v > lim and u_prev[k] > lim) or \
                (u[k] < -lim and v < -lim and u_prev[k] < -lim):
            if valid is not None:
                valid[k] = 0
            continue
        a, b = wp[i], wth[i]
        f0, _ = _own_part_el(u[k] / delta, el[0, k], el[1, k], a, b, K, delta)
        f1, _ = _own_part_el(u_prev[k] / delta, el[2, k], el[3, k], a, b, K, delta)
        out[k], ev, l1v = _own_root(v, f0 + ratio * (f0 - f1), a, b, K, delta)
        if valid is not None:
            e_n[k] = ev
            l1_n[k] = l1v
            valid[k] = 1


@nb.njit(cache=True, nogil=True)
def _increment_norm_kernel(dx, p, dp, dth, atol, rtol, K):
    """:meth:`TransientFilm._increment_norm` in one pass (the same maxima and products as
    the numpy expression it replaces, so the same value bit for bit; nan if dx has one)."""
    pmax = -np.inf
    pmin = np.inf
    mth = 0.0
    mp = 0.0
    for k in range(dx.size):
        pmax = max(pmax, p[k])
        pmin = min(pmin, p[k])
        a = abs(dx[k])
        if not (a == a):
            return np.nan
        mth = max(mth, a * dth[k])
        mp = max(mp, a * dp[k])
    p_tol = rtol * (pmax - pmin) + atol * K
    return max(mth / atol, mp / p_tol)


#: simplified-Newton rule of :meth:`TransientFilm.newton`: an iteration reuses the LU of the
#: previous one (no new factorisation) when the previous Newton step was at most this many
#: Newton tolerances (the increment norm of :meth:`TransientFilm._increment_norm`). The
#: iterate is then within ~10 tolerances of the point the LU was factored at, so the chord
#: step contracts nearly as a Newton step would, and the convergence test (on the increments,
#: with the contraction-rate estimate, Hairer & Wanner IV.8, made for simplified Newton)
#: is unchanged. Measured (benchmarks/bench_bearing_ab.py cases, BENCHMARKS.md, issue 16
#: session 5): bound 10: LUs per macro step 5.46 -> 5.10 (whirl), 2.88 -> 2.39 (air), the same
#: Newton iterations, force distance from a 1000x tighter Newton run 1.58e-5 -> 1.59e-5 (whirl),
#: 4.8e-9 -> 5.4e-9 (air); bound 30: 4.64 LUs but 5.2e-5 (3x); 1000: Newton failures.
LU_REUSE_BELOW = 10.0

#: second simplified-Newton rule (issue 16): an iteration also keeps the LU of this solve's last
#: factorisation when the Newton matrix assembled at the current iterate differs from the
#: factored one by at most this fraction in every row (:func:`jacobian_moved`: the sum of the
#: row's changes over its factored diagonal), however far the iterate moved. The film's Newton
#: matrix depends on the iterate only through each cell's cavitation law (dp/du, dtheta/du) and
#: the edge penalty, so a step that moves the pressure of the full film by a hundred tolerances
#: but switches no cell leaves it nearly unchanged, and the chord step with the kept LU then
#: contracts by about this fraction; where cells cross the cavitation switch the rows of those
#: cells change by O(1) and the rule factors again. Measured on recorded run-up kinematics of
#: the shipped Jeffcott bearings (benchmarks/bench_newton_reuse.py, BENCHMARKS.md "Session
#: 16"): 0.1 saves 26 % of the LUs in the oil-bath whirl and 47 % in its quiet phase for +2 %
#: and +0.2 % Newton iterations (free to air: 4-11 % of the LUs); in the quiet phase the force
#: stays within 3e-6 of a run 1000x tighter in Newton (full Newton: 5e-8); in the whirl the
#: film amplifies any perturbation (full Newton itself is 1.3e-2 from the tight run there).
#: 0.2 saves a few more LUs for 11 % more iterations in the oil-bath whirl.
JACOBIAN_REUSE_BELOW = 0.1

#: a chord step (an iteration on a kept LU under :data:`JACOBIAN_REUSE_BELOW`) that reduced the
#: Newton increment by less than this factor makes the next iteration factor again
CHORD_RATE_MAX = 0.5


@nb.njit(cache=True, inline="always")
def _row_change(jst, jst_f, g):
    """(sum_k |jst[g, k] - jst_f[g, k]|, |jst_f[g, 0]|): how far row g moved, and its
    factored diagonal."""
    s = 0.0
    for k in range(jst.shape[1]):
        s += abs(jst[g, k] - jst_f[g, k])
    return s, abs(jst_f[g, 0])


@nb.njit(cache=True, nogil=True)
def jacobian_moved(jst, jst_f):
    """How far the stencil Jacobian ``jst`` is from ``jst_f`` (the one factored): the largest
    over rows of ``sum_k |jst[g, k] - jst_f[g, k]| / |jst_f[g, 0]|`` (inf for a zero factored
    diagonal). See :data:`JACOBIAN_REUSE_BELOW`."""
    worst = 0.0
    for g in range(jst.shape[0]):
        s, d = _row_change(jst, jst_f, g)
        if s > 0.0:
            if not d > 0.0:
                return np.inf
            worst = max(worst, s / d)
    return worst


@nb.njit(cache=True, nogil=True)
def keep_lu(prev, prev2, chord_prev, lu_reuse_below, jac_reuse_below, jst, jst_f):
    """The simplified-Newton rules of an iteration that follows a Newton step of ``prev``
    tolerances (``prev2`` the one before, ``chord_prev`` whether that step was a chord step of
    the second rule): keep the LU of this solve's last factorisation when ``prev <=
    lu_reuse_below`` (:data:`LU_REUSE_BELOW`), or when the Newton matrix ``jst`` moved by at
    most ``jac_reuse_below`` from the factored ``jst_f`` (:data:`JACOBIAN_REUSE_BELOW`)
    unless the last chord step contracted by less than :data:`CHORD_RATE_MAX`. Shared by
    :meth:`TransientFilm.newton` and :func:`.fused.advance_fused`."""
    if prev <= lu_reuse_below:
        return True
    if jac_reuse_below <= 0.0 or (chord_prev and prev > CHORD_RATE_MAX * prev2):
        return False
    return jacobian_moved(jst, jst_f) <= jac_reuse_below


class StepFailed(RuntimeError):
    """The film could not be advanced (Newton or step-size control failed)."""


#: threshold of :func:`band_lu_nopivot`: the pivot must be at least this fraction of the
#: largest entry below it (threshold partial pivoting; Duff, Erisman & Reid, Direct Methods
#: for Sparse Matrices, 2nd ed., sec. 4.4: 0.1 is the customary value, growth per step <= 11)
PIVOT_THRESHOLD = 0.1


@nb.njit(cache=True, nogil=True)
def band_lu_nopivot(ab, bw, thresh):
    """In-place LU without row interchanges of a matrix in LAPACK band storage
    (``ab[2 bw + i - j, j] = A[i, j]``, kl = ku = bw, Fortran order; rows 0 .. bw-1 are not
    used: without interchanges L keeps bandwidth kl and U ku). Returns 0, or k + 1 when at
    column k the pivot is below ``thresh`` times the largest entry under it, or 0 / not
    finite: the caller then factors with partial pivoting. Accepting a pivot down to a
    fraction ``thresh`` of the column is threshold pivoting (Duff, Erisman & Reid, sec. 4.4;
    the element growth per step is at most 1 + 1/thresh); the film's Newton matrix is
    column diagonally dominant up to the upwind Couette coupling, for which elimination
    needs no interchange at all (Golub & Van Loan, Matrix Computations, 4th ed., 3.4.6)."""
    return _band_lu_from(ab, bw, thresh, 0)


#: pivots per panel of the blocked elimination of :func:`_band_lu_from`
LU_PANEL = 4


@nb.njit(cache=True, nogil=True)
def _band_lu_from(ab, bw, thresh, k_from):
    """:func:`band_lu_nopivot` from column ``k_from`` on (columns before it are factored and
    their updates applied to the rest).

    Blocked by panels of :data:`LU_PANEL` = 4 pivots (issue 16, speed): the panel's four
    columns are factored first (:func:`_band_lu_rank1_from`'s steps restricted to them), then
    every later column the panel reaches gets the four pivots' updates in one pass: its four
    panel rows (the U entries, in registers: each row takes the updates of the panel pivots
    above it, in order) and then the rows below the panel, each element updated
    ``a - u0 l0 - u1 l1 - u2 l2 - u3 l3`` from left to right (:func:`_axpy4`). Every element
    sees the same operations with the same operands in the same order as in the rank-1
    elimination, so the factors are the same bit for bit; only the loads and stores of the
    trailing matrix fall to a quarter (the rank-1 update is bound by them at the film's
    bandwidth). Multipliers of rows past a pivot's band are held as 0, and a U entry that is
    0 is applied (the rank-1 code skips the column): both add a signed zero, which changes
    no nonzero value (an entry that is exactly 0 may change its sign, nothing else; the
    test compares the factors with ``array_equal``). The panels need ``bw >= 4`` and stop
    where a pivot's column would be cut by the end of the matrix; the last columns are
    eliminated one by one. Measured (BENCHMARKS.md session 25): at the oil bath's bw 40,
    n 800, 0.74x the time of the rank-1 elimination."""
    rows = ab.shape[0]
    n = ab.shape[1]
    P = LU_PANEL
    if bw < P:
        return _band_lu_rank1_from(ab, bw, thresh, k_from)
    a = ab.T.ravel()                 # a view: entry (r, c) at c * rows + r
    d = 2 * bw
    col = np.empty(bw)
    mult = np.zeros((P, bw))         # mult[p, i]: L[k + P + i, k + p] (0 past its band)
    k = k_from
    while k + P - 1 + bw <= n - 1:   # every pivot of the panel has its full column
        for p in range(P):
            kk = k + p
            ck = kk * rows + d
            if not _pivot_column(a, ck, bw, thresh, col):
                return kk + 1
            for j in range(1, P - p):                # the panel's later columns
                cj = (kk + j) * rows + d - j
                akj = a[cj]
                if akj != 0.0:
                    _axpy(a, cj + 1, col, bw, -akj)
            off = P - p                              # row k + P is row kk + off
            for i in range(bw - off + 1):
                mult[p, i] = col[off - 1 + i]
            for i in range(bw - off + 1, bw):
                mult[p, i] = 0.0
        l0, l1, l2, l3 = mult[0], mult[1], mult[2], mult[3]
        # the panel's own multipliers below its pivots (L[k + r, k + q], q < r < P)
        c0 = k * rows + d - k
        c1 = c0 + rows - 1
        c2 = c1 + rows - 1
        l10, l20, l30 = a[c0 + k + 1], a[c0 + k + 2], a[c0 + k + 3]
        l21, l31 = a[c1 + k + 2], a[c1 + k + 3]
        l32 = a[c2 + k + 3]
        # columns k + P .. k + bw: all four panel pivots reach them
        for j in range(k + P, k + bw + 1):
            cb = j * rows + d - j                    # A[r, j] at a[cb + r]
            u0 = a[cb + k]
            u1 = a[cb + k + 1]
            u2 = a[cb + k + 2]
            u3 = a[cb + k + 3]
            if u0 != 0.0:
                u1 += -u0 * l10
                u2 += -u0 * l20
                u3 += -u0 * l30
            if u1 != 0.0:
                u2 += -u1 * l21
                u3 += -u1 * l31
            if u2 != 0.0:
                u3 += -u2 * l32
            a[cb + k + 1] = u1
            a[cb + k + 2] = u2
            a[cb + k + 3] = u3
            _axpy4(a[cb + k + P:cb + k + P + bw], l0, l1, l2, l3, -u0, -u1, -u2, -u3, bw)
        # columns k + bw + 1 .. k + bw + 3: reached by the pivots k + p with k + p + bw >= j
        for j in range(k + bw + 1, k + P + bw):
            cb = j * rows + d - j
            r1 = j <= k + 1 + bw
            r2 = j <= k + 2 + bw
            u1 = a[cb + k + 1] if r1 else 0.0
            u2 = a[cb + k + 2] if r2 else 0.0
            u3 = a[cb + k + 3]
            if u1 != 0.0:
                u2 += -u1 * l21
                u3 += -u1 * l31
            if u2 != 0.0:
                u3 += -u2 * l32
            if r2:
                a[cb + k + 2] = u2
            a[cb + k + 3] = u3
            _axpy4(a[cb + k + P:cb + k + P + bw], l0, l1, l2, l3, 0.0, -u1, -u2, -u3, bw)
        k += P
    return _band_lu_rank1_from(ab, bw, thresh, k)


@nb.njit(cache=True, nogil=True)
def _band_lu_rank1_from(ab, bw, thresh, k_from):
    """The elimination of :func:`_band_lu_from` one pivot at a time (a rank-1 update of the
    trailing band per pivot): the end of the blocked elimination, small bandwidths, and the
    reference of its test."""
    rows = ab.shape[0]
    n = ab.shape[1]
    a = ab.T.ravel()                 # a view: entry (r, c) at c * rows + r
    d = 2 * bw
    col = np.empty(max(bw, 1))
    for k in range(k_from, n):
        ck = k * rows + d            # flat index of the pivot A[k, k]
        m = min(bw, n - 1 - k)
        if not _pivot_column(a, ck, m, thresh, col):
            return k + 1
        for j in range(1, m + 1):
            cj = (k + j) * rows + d - j   # flat index of A[k, k + j]
            akj = a[cj]
            if akj != 0.0:
                _axpy(a, cj + 1, col, m, -akj)
    return 0


@nb.njit(cache=True, inline="always")
def _pivot_column(a, ck, m, thresh, col):
    """Check the pivot ``a[ck]`` against the ``m`` entries below it (threshold of
    :func:`band_lu_nopivot`) and turn them into the multipliers, copied to ``col`` (apart
    from ``a``: no aliasing, SIMD); False when the pivot fails."""
    piv = a[ck]
    big = 0.0
    for i in range(1, m + 1):
        big = max(big, abs(a[ck + i]))
    if not (abs(piv) > 0.0) or not math.isfinite(piv) or thresh * big > abs(piv):
        return False
    inv = 1.0 / piv
    for i in range(1, m + 1):
        a[ck + i] *= inv
        col[i - 1] = a[ck + i]       # the multipliers, apart (no aliasing: SIMD)
    return True


@nb.njit(cache=True, inline="always")
def _axpy4(seg, c0, c1, c2, c3, x0, x1, x2, x3, m):
    """``seg[i] += x0 c0[i]``, then ``+= x1 c1[i]``, ``x2 c2[i]``, ``x3 c3[i]``: four rank-1
    updates of a segment in one pass, each element's in order."""
    for i in range(m):
        s = seg[i]
        s += x0 * c0[i]
        s += x1 * c1[i]
        s += x2 * c2[i]
        s += x3 * c3[i]
        seg[i] = s


#: a partial refactorisation (:func:`refactor_partial`) starts no earlier than this many
#: bandwidths into the band; before that a full one costs about as much
PARTIAL_MIN_BW = 2


@nb.njit(cache=True, nogil=True)
def first_moved_position(jst, jst_f, pos, bound):
    """The smallest band position of a row of ``jst`` that moved by more than ``bound`` from
    ``jst_f`` (the measure of :func:`jacobian_moved`), or the number of rows when none did."""
    n = jst.shape[0]
    kmin = n
    for g in range(n):
        if pos[g] >= kmin:
            continue
        s, d = _row_change(jst, jst_f, g)
        if s > bound * d or (s > 0.0 and not d > 0.0):
            kmin = pos[g]
    return kmin


@nb.njit(cache=True, nogil=True)
def _zero_band(ab, bw):
    """``ab[bw:, :] = 0`` one contiguous column at a time (numba's 2-D slice assignment walks
    the slice element by element: 42 against 8 us at bw 40, n 800)."""
    rows = ab.shape[0]
    a = ab.T.ravel()
    for c in range(ab.shape[1]):
        a[c * rows + bw:(c + 1) * rows] = 0.0


@nb.njit(cache=True, nogil=True)
def factor_full(jst, jst_f, n_phi, pos, bw, ab, thresh):
    """The band LU of the stencil Jacobian ``jst`` into ``ab`` (:func:`band_lu_nopivot`'s
    return code), ``jst_f`` set to the matrix factored."""
    _zero_band(ab, bw)
    stencil_to_band(jst, n_phi, pos, bw, ab)
    jst_f[:, :] = jst
    return band_lu_nopivot(ab, bw, thresh)


@nb.njit(cache=True, nogil=True)
def refactor_partial(jst, jst_f, n_phi, pos, bw, ab, thresh, bound):
    """Refactor the band LU ``ab`` of the stencil Jacobian ``jst_f`` for ``jst``, keeping the
    rows before the first band position ``kmin`` whose row moved by more than ``bound``
    (:func:`first_moved_position`; those rows moved by at most ``bound`` each, the tolerance
    of the second simplified-Newton rule, :data:`JACOBIAN_REUSE_BELOW`).

    Without interchanges, U's rows before ``kmin`` and L's columns before ``kmin - bw`` depend
    on those rows only, so they stand. The rows from ``kmin`` on are scattered anew. The
    eliminations of the pivots ``kmin - bw .. kmin - 1`` are replayed on those rows only,
    with the multipliers they give. Then elimination continues from ``kmin``
    (:func:`_band_lu_from`). The cost is (N - kmin) / N of a full LU plus about bw^3. The
    result is the LU of the matrix whose rows before ``kmin`` are ``jst_f``'s and whose
    other rows are ``jst``'s, and ``jst_f`` is updated to it. Returns (code, kmin): code 0,
    or k + 1 for a pivot below ``thresh`` (as :func:`band_lu_nopivot`; the caller factors
    again from scratch). When ``kmin < PARTIAL_MIN_BW * bw``, or when no row moved by more
    than ``bound``, this is a full factorisation of ``jst`` (kmin returned as 0)."""
    n = jst.shape[0]
    kmin = first_moved_position(jst, jst_f, pos, bound)
    if kmin < PARTIAL_MIN_BW * bw or kmin >= n:
        # early, or no row moved by more than bound (the rules asked for a new LU because the
        # chord steps contracted too slowly): the whole matrix
        return factor_full(jst, jst_f, n_phi, pos, bw, ab, thresh), 0
    rows = ab.shape[0]
    a = ab.T.ravel()
    d = 2 * bw
    k0 = kmin - bw
    col = np.empty(bw)
    # zero the entries of the rows >= kmin (columns k0 .. n-1) and scatter them anew (each
    # column's part is contiguous: one slice assignment, a memset)
    for j in range(k0, n):
        base = j * rows + d - j
        a[base + max(kmin, j - bw):base + min(n - 1, j + bw) + 1] = 0.0
    stencil_rows_to_band(jst, n_phi, pos, bw, ab, kmin)
    for g in range(n):
        if pos[g] >= kmin:
            jst_f[g, :] = jst[g, :]
    # replay the eliminations of the pivots k0 .. kmin-1 on the rows >= kmin
    for k in range(k0, kmin):
        ck = k * rows + d
        piv = a[ck]
        m = min(bw, n - 1 - k)
        s = kmin - k - 1                   # col[s:m]: the multipliers of the rows >= kmin
        big = 0.0
        for i in range(1, s + 1):          # kept multipliers, times the pivot
            big = max(big, abs(a[ck + i] * piv))
        for i in range(s + 1, m + 1):
            big = max(big, abs(a[ck + i]))
        if thresh * big > abs(piv):
            return k + 1, kmin
        inv = 1.0 / piv
        for i in range(s + 1, m + 1):
            a[ck + i] *= inv
            col[i - 1 - s] = a[ck + i]     # the multipliers of the rows >= kmin, apart (SIMD)
        for j in range(1, m + 1):
            cj = (k + j) * rows + d - j    # flat index of U[k, k + j]
            ukj = a[cj]
            if ukj != 0.0:
                _axpy(a, cj + 1 + s, col, m - s, -ukj)     # a - u l, as a + (-u) l: the same
    return _band_lu_from(ab, bw, thresh, kmin), kmin


@nb.njit(cache=True, inline="always")
def _axpy(a, start, x, m, alpha):
    """``a[start:start + m] += alpha x[:m]``."""
    seg = a[start:start + m]
    for i in range(m):
        seg[i] += alpha * x[i]


@nb.njit(cache=True, nogil=True)
def band_solve_nopivot(ab, bw, b, x):
    """Solve ``A x = b`` with the factors of :func:`band_lu_nopivot` (``b`` may be ``x``).

    Each elimination is an :func:`_axpy` of a slice of the band column into a slice of x:
    with the two as separate arrays numba vectorises the loop (2.4x faster alone than indexing
    one flat view of ``ab`` at the film's bandwidth; 0.977-0.988x the time per macro step of the
    whirl benchmark as a whole). Four columns of L (forward) and of U (backward) are applied
    in one pass (:func:`_axpy4`; the entries of x the four reach only in part and the four
    pivots' own entries written out): x is loaded and stored a quarter as often, 0.65x the
    time at bw 40 (issue 16 speed). Each entry of x sees the same operations in the same
    order as with one column at a time, so the values are the same bit for bit
    (BENCHMARKS.md, issue 16)."""
    n = ab.shape[1]
    d = 2 * bw
    for k in range(n):
        x[k] = b[k]
    k = 0
    if bw >= 4:
        while k + 3 + bw <= n - 1:          # forward, the pivots k .. k + 3
            x0 = x[k]
            x1 = x[k + 1] + -x0 * ab[d + 1, k]
            x2 = x[k + 2] + -x0 * ab[d + 2, k]
            x3 = x[k + 3] + -x0 * ab[d + 3, k]
            x2 = x2 + -x1 * ab[d + 1, k + 1]
            x3 = x3 + -x1 * ab[d + 2, k + 1]
            x3 = x3 + -x2 * ab[d + 1, k + 2]
            x[k + 1] = x1
            x[k + 2] = x2
            x[k + 3] = x3
            m = bw - 3                      # rows k + 4 .. k + bw: all four columns
            _axpy4(x[k + 4:k + 4 + m], ab[d + 4:d + 4 + m, k], ab[d + 3:d + 3 + m, k + 1],
                   ab[d + 2:d + 2 + m, k + 2], ab[d + 1:d + 1 + m, k + 3], -x0, -x1, -x2, -x3, m)
            i = k + bw + 1                  # rows k + bw + 1 .. k + bw + 3: the later columns
            x[i] = ((x[i] + -x1 * ab[d + bw, k + 1]) + -x2 * ab[d + bw - 1, k + 2]) \
                + -x3 * ab[d + bw - 2, k + 3]
            x[i + 1] = (x[i + 1] + -x2 * ab[d + bw, k + 2]) + -x3 * ab[d + bw - 1, k + 3]
            x[i + 2] = x[i + 2] + -x3 * ab[d + bw, k + 3]
            k += 4
    for kk in range(k, n):
        xk = x[kk]
        m = min(bw, n - 1 - kk)
        _axpy(x, kk + 1, ab[d + 1:d + 1 + m, kk], m, -xk)     # L[kk + 1 .. kk + m, kk]
    k = n - 1
    if bw >= 4:
        while k - 3 - bw >= 0:              # backward, the pivots k .. k - 3
            x[k] /= ab[d, k]
            x0 = x[k]
            x1 = x[k - 1] + -x0 * ab[d - 1, k]
            x2 = x[k - 2] + -x0 * ab[d - 2, k]
            x3 = x[k - 3] + -x0 * ab[d - 3, k]
            x1 /= ab[d, k - 1]
            x2 = x2 + -x1 * ab[d - 1, k - 1]
            x3 = x3 + -x1 * ab[d - 2, k - 1]
            x2 /= ab[d, k - 2]
            x3 = x3 + -x2 * ab[d - 1, k - 2]
            x3 /= ab[d, k - 3]
            x[k - 1] = x1
            x[k - 2] = x2
            x[k - 3] = x3
            m = bw - 3                      # rows k - bw .. k - 4: all four columns
            lo = k - bw
            _axpy4(x[lo:lo + m], ab[d - bw:d - bw + m, k], ab[d - bw + 1:d - bw + 1 + m, k - 1],
                   ab[d - bw + 2:d - bw + 2 + m, k - 2], ab[d - bw + 3:d - bw + 3 + m, k - 3],
                   -x0, -x1, -x2, -x3, m)
            i = lo - 1                      # rows k - bw - 1 .. k - bw - 3: the later columns
            x[i] = ((x[i] + -x1 * ab[d - bw, k - 1]) + -x2 * ab[d - bw + 1, k - 2]) \
                + -x3 * ab[d - bw + 2, k - 3]
            x[i - 1] = (x[i - 1] + -x2 * ab[d - bw, k - 2]) + -x3 * ab[d - bw + 1, k - 3]
            x[i - 2] = x[i - 2] + -x3 * ab[d - bw, k - 3]
            k -= 4
    for kk in range(k, -1, -1):
        x[kk] /= ab[d, kk]
        xk = x[kk]
        m = min(bw, kk)
        _axpy(x, kk - m, ab[d - m:d, kk], m, -xk)              # U[kk - m .. kk - 1, kk]


@nb.njit(cache=True, nogil=True)
def band_newton_step_nopivot(ab, bw, r, order, pos, work, dx):
    """The Newton step ``dx = -J^-1 r`` with the factors of :func:`band_lu_nopivot` in the
    band ordering (``order``: flat cell at each position, ``pos`` its inverse): the
    gather ``-r[order]``, :func:`band_solve_nopivot` and the scatter back in one call (the
    same operations, so the same values bit for bit as ``TransientFilm._solve``). ``work``
    (n,) is scratch. Returns False when dx has a non-finite entry."""
    n = r.size
    for k in range(n):
        work[k] = -r[order[k]]
    band_solve_nopivot(ab, bw, work, work)
    ok = True
    for k in range(n):
        v = work[pos[k]]
        dx[k] = v
        if not math.isfinite(v):
            ok = False
    return ok


_FUSED = []


def _fused():
    """The :mod:`.fused` module (imported on first use, not at the top: it imports this
    module's kernels; kept, since an import statement costs microseconds every call)."""
    if not _FUSED:
        from . import fused
        _FUSED.append(fused)
    return _FUSED[0]


#: ``TransientFilm.stats`` keys of the fused call's counters, in the order of
#: ``fused.S_STEPS .. S_REUSED``
_FUSED_STATS = ("steps", "rejected", "newton", "factor", "failed_newton", "reused")


class BandLU:
    """Band LU of a matrix in LAPACK band storage: elimination without interchanges
    (numba, :func:`band_lu_nopivot`, threshold ``PIVOT_THRESHOLD``), the film's usual case;
    when a pivot fails the threshold, LAPACK ``dgbtrf``/``dgbtrs`` (partial pivoting) on the
    same matrix, counted in ``fallbacks``. Without interchanges the factors keep the band
    (no kl fill-in columns as in ``dgbtrf``): about half its work at the film's bandwidth."""

    name = "band"

    def __init__(self, bw: int):
        self.bw = bw
        self.fallbacks = 0

    def factor(self, ab, rebuild=None):
        """Factor ``ab`` in place. ``rebuild()``, if given, refills ``ab`` with the matrix
        (for the pivoting fallback; without it a copy is kept beforehand)."""
        keep = ab.copy(order="F") if rebuild is None else None
        if band_lu_nopivot(ab, self.bw, PIVOT_THRESHOLD) == 0:
            self.lu, self.piv = ab, None
            return
        self.fallbacks += 1
        if rebuild is None:
            ab[...] = keep
        else:
            rebuild()
        lu, piv, info = lapack.dgbtrf(ab, self.bw, self.bw, overwrite_ab=1)
        if info != 0:
            raise StepFailed(f"band LU: singular Newton matrix (dgbtrf info={info})")
        self.lu, self.piv = lu, piv

    def solve(self, b):
        if self.piv is None:
            x = np.empty(b.size)
            band_solve_nopivot(self.lu, self.bw, np.ascontiguousarray(b, dtype=float), x)
            return x
        x, info = lapack.dgbtrs(self.lu, self.bw, self.bw, b, self.piv)
        return x


class LapackBandLU(BandLU):
    """LAPACK ``dgbtrf``/``dgbtrs`` (partial pivoting) always: the benchmark peer of
    :class:`BandLU` (``linear_solver = "lapack"``)."""

    name = "lapack"

    def factor(self, ab, rebuild=None):
        lu, piv, info = lapack.dgbtrf(ab, self.bw, self.bw, overwrite_ab=1)
        if info != 0:
            raise StepFailed(f"band LU: singular Newton matrix (dgbtrf info={info})")
        self.lu, self.piv = lu, piv


class SpluLU:
    """SuperLU (scipy ``splu``) of the same matrix: the reference peer."""

    name = "splu"

    def __init__(self, bw: int):
        self.bw = bw
        self.offsets = np.arange(-bw, bw + 1)

    def factor(self, ab, rebuild=None):
        bw = self.bw
        data = ab[2 * bw - self.offsets]
        n = ab.shape[1]
        A = sp.dia_matrix((data, self.offsets), shape=(n, n)).tocsc()
        self.lu = splu(A)

    def solve(self, b):
        return self.lu.solve(b)


class TransientFilm:
    """Integrator of the mass-conserving film on a fixed grid.

    ``ctx`` is a :class:`bearing_fmu.model.BearingModel`-like object with the
    grid, constants and law (see ``model.py``); the integrator only owns the
    numerical state. Diagnostics switches (attributes, default True unless said):
    ``predictor`` (extrapolate u as Newton start), ``predictor_limited`` (the
    extrapolation stopped at the cavitation switch, as :func:`_limit_switch`
    stops a Newton step; False = the plain line, the benchmark peer), ``line_search``
    (backtracking on |r|), ``predictor_dominant`` (the extrapolation in each cell's own part,
    :func:`dominant_extrapolate`, when ``dominant``; False = the line in u), ``dominant`` (the Newton step taken in each cell's dominant variable,
    :func:`dominant_update`; False = the plain step in u, the benchmark peer), ``search_converged``
    (default False: a converged Newton step is taken whole, without the line search's
    residual; True = the line search first, the older order); ``full_newton=True`` refactorises every iteration
    whatever ``krylov_refactor`` says (the benchmark peer); ``lu_reuse_below`` (default
    :data:`LU_REUSE_BELOW`; 0 = a fresh LU every iteration, the benchmark peer) the
    simplified-Newton rule of :meth:`newton`; ``fused`` (default True) advances a macro step
    in one numba call without the GIL (:mod:`.fused`, :meth:`fused_eligible`; False = the
    Python loop of :meth:`_advance_loop`, the benchmark peer and the reference the fused
    path is tested against).
    """

    def __init__(self, ctx, linear_solver="band", full_newton=False):
        self.ctx = ctx
        g = ctx.grid
        n = g.n
        self.n = n
        self.lin = {"band": BandLU, "lapack": LapackBandLU, "splu": SpluLU}[linear_solver](g.bw)
        self.full_newton = full_newton
        self.predictor = True
        self.predictor_limited = True
        self.line_search = True
        self.dominant = True
        self.predictor_dominant = True
        self.lu_reuse_below = LU_REUSE_BELOW
        self.jac_reuse_below = JACOBIAN_REUSE_BELOW
        self.search_converged = False
        self.fused = True
        self.pivot_threshold = PIVOT_THRESHOLD      # of the fused path's LU (a test changes it)
        self.ab = np.zeros((3 * g.bw + 1, n), order="F")
        # theta_transport = 1: limited second-order Couette transport of theta, whose
        # exact Jacobian has the 7-point stencil (i +- 2; the grid's band covers it)
        self.muscl = ctx.params.theta_transport == 1
        self._assemble = assemble_muscl if self.muscl else assemble
        self.jst = np.zeros((n, 7 if self.muscl else 5))
        self.jst_f = np.zeros_like(self.jst)     # the stencil Jacobian of the last LU
        self.r = np.empty(n)
        self._work, self._dx = np.empty(n), np.empty(n)
        self._w = np.empty(n)
        self.wp, self.wdp, self.wth, self.wdth = (np.empty(n) for _ in range(4))
        self.film = ~np.tile(g.groove, g.n_z)
        self.stats = dict(steps=0, rejected=0, newton=0, factor=0, failed_newton=0, krylov=0,
                          restarts=0, reused=0)
        self._factored = False

    # ------------------------------------------------------------ kernels
    def residual(self, u, th_dot0, th_dot1, kin, want_jac=False):
        c, g = self.ctx, self.ctx.grid
        H, He, Hdot, omega = kin
        self._assemble(u, th_dot0, th_dot1, H, He, Hdot, g.groove, c.u_feed, omega,
                       c.a_phi, c.a_z, g.dphi, g.dz, c.bath, c.p0, c.law.p_cav, c.law.K,
                       c.law.delta, c.params.penalty_a, c.params.penalty_b, c.params.penalty_smoothing,
                       self.r, want_jac, self.jst,
                       self.wp, self.wdp, self.wth, self.wdth, c.sym, g.wrel, g.frel)
        return self.r

    def _factor(self, u, th_dot0, kin, jst_ready=False):
        if not jst_ready:
            self.residual(u, th_dot0, self._zero, kin, want_jac=True)
        g = self.ctx.grid
        # rows 0 .. bw-1 of LAPACK band storage are dgbtrf's fill-in workspace and "need not
        # be set" on entry (it zeroes them itself); splu reads rows bw .. 3 bw only
        self._scatter()
        self.lin.factor(self.ab, self._scatter)
        self.jst_f[:] = self.jst
        self._factored = True
        self.stats["factor"] += 1
        self.jac = dict(u=u.copy(), th_dot0=th_dot0, kin=kin)

    def _refactor_partial(self, u, th_dot0, kin):
        """A later LU of this Newton solve by :func:`refactor_partial` (from the first band
        row that moved by more than ``jac_reuse_below`` on); False when it does not apply
        (no factor of this solve without interchanges, the rule off, full Newton) or a
        pivot failed its threshold (the caller then factors the whole matrix)."""
        lin = self.lin
        if not (self._factored and type(lin) is BandLU and lin.piv is None
                and self.jac_reuse_below > 0.0 and not self.full_newton
                and self.ctx.params.krylov_refactor == 0):
            return False
        g = self.ctx.grid
        code, _ = refactor_partial(self.jst, self.jst_f, g.n_phi, g.pos, g.bw, self.ab,
                                   PIVOT_THRESHOLD, self.jac_reuse_below)
        if code != 0:
            return False
        lin.lu, lin.piv = self.ab, None
        self.stats["factor"] += 1
        self.jac = dict(u=u.copy(), th_dot0=th_dot0, kin=kin)
        return True

    def _scatter(self):
        g = self.ctx.grid
        self.ab[g.bw:].fill(0.0)
        stencil_to_band(self.jst, g.n_phi, g.pos, g.bw, self.ab)

    def _solve(self, r):
        g = self.ctx.grid
        x = self.lin.solve(-r[g.order])
        return x[g.pos]

    def _newton_step(self, r):
        """(dx, finite): the Newton step ``-J^-1 r`` of :meth:`_solve` (same values bit for
        bit) into a buffer of the film, in one numba call when the LU has no interchanges
        (:func:`band_newton_step_nopivot`), and whether it is finite."""
        lin = self.lin
        if isinstance(lin, BandLU) and lin.piv is None:
            g = self.ctx.grid
            ok = band_newton_step_nopivot(lin.lu, lin.bw, r, g.order, g.pos, self._work,
                                          self._dx)
            return self._dx, ok
        dx = self._solve(r)
        return dx, bool(np.all(np.isfinite(dx)))

    def _psolve(self, v):
        g = self.ctx.grid
        return self.lin.solve(v[g.order])[g.pos]

    def _gmres(self, b, tol, maxit):
        """Right-preconditioned GMRES for ``J x = b`` with J the current stencil
        Jacobian and the last LU factorisation as preconditioner (Saad & Schultz
        1986; CGS2 orthogonalisation, Givens rotations). Returns (x, its, ok)."""
        n = b.size
        beta = float(np.linalg.norm(b))
        if beta == 0.0:
            return np.zeros(n), 0, True
        nphi = self.ctx.grid.n_phi
        V = np.empty((maxit + 1, n))
        Z = np.empty((maxit, n))
        Hm = np.zeros((maxit + 1, maxit))
        cs = np.zeros(maxit)
        sn = np.zeros(maxit)
        gv = np.zeros(maxit + 1)
        gv[0] = beta
        V[0] = b / beta
        w = self._w
        k = 0
        ok = False
        for j in range(maxit):
            Z[j] = self._psolve(V[j])
            stencil_matvec(self.jst, nphi, Z[j], w)
            # classical Gram-Schmidt, twice (CGS2: as stable as modified GS,
            # but two matrix-vector products instead of 2 (j + 1) dot/axpy calls)
            hcol = V[:j + 1] @ w
            w -= hcol @ V[:j + 1]
            h2 = V[:j + 1] @ w
            w -= h2 @ V[:j + 1]
            Hm[:j + 1, j] = hcol + h2
            Hm[j + 1, j] = np.linalg.norm(w)
            if Hm[j + 1, j] > 0:
                V[j + 1] = w / Hm[j + 1, j]
            for i in range(j):
                t = cs[i] * Hm[i, j] + sn[i] * Hm[i + 1, j]
                Hm[i + 1, j] = -sn[i] * Hm[i, j] + cs[i] * Hm[i + 1, j]
                Hm[i, j] = t
            d = np.hypot(Hm[j, j], Hm[j + 1, j])
            cs[j], sn[j] = Hm[j, j] / d, Hm[j + 1, j] / d
            Hm[j, j], Hm[j + 1, j] = d, 0.0
            gv[j + 1] = -sn[j] * gv[j]
            gv[j] = cs[j] * gv[j]
            k = j + 1
            if abs(gv[j + 1]) <= tol * beta:
                ok = True
                break
        y = np.zeros(k)
        for i in range(k - 1, -1, -1):
            y[i] = (gv[i] - Hm[i, i + 1:k] @ y[i + 1:k]) / Hm[i, i]
        return Z[:k].T @ y, k, ok

    def theta(self, u):
        p, th = self.ctx.law.p_theta(u)
        return th

    # ------------------------------------------------------------ Newton
    def _weights(self, th_dot0, kin):
        """Per-column own-cell coefficients (:func:`dominant_weights`) for this step."""
        c, g = self.ctx, self.ctx.grid
        H, He, Hdot, omega = kin
        wcol_p, wcol_th = np.empty(g.n_phi), np.empty(g.n_phi)
        dominant_weights(H, He, Hdot, th_dot0, omega, c.a_phi, c.a_z, g.dphi, g.dz,
                         g.wrel, g.frel, wcol_p, wcol_th)
        return wcol_p, wcol_th

    def newton(self, u0, th_dot0, th_dot1, kin, max_iter=None, weights=None):
        """Solve r(u) = 0 from u0; return (u, iterations) or (None, its).

        Newton-Krylov: each iteration assembles the exact stencil Jacobian
        (cheap) and solves with GMRES preconditioned by the last band LU,
        which is typically from an earlier step: it differs from the current
        Jacobian mainly in the few cells where the film ruptures or reforms, a
        low-rank change GMRES resolves in a few iterations. When GMRES needs more
        than ``krylov_refactor`` iterations, the LU is refreshed at the current
        iterate and the system is solved directly.
        """
        prm = self.ctx.params
        max_iter = max_iter or prm.newton_max_iter
        atol, rtol = prm.newton_atol, prm.newton_rtol
        u = u0.copy()
        prev = prev2 = None
        its = 0
        r_ready = False
        g = self.ctx.grid
        if self.dominant:
            wcol_p, wcol_th = weights if weights is not None else self._weights(th_dot0, kin)
        chord_prev = False          # the last step was taken on a kept LU by the Jacobian rule
        while its < max_iter:
            if r_ready:             # evaluated at u by the line search below
                r = self.r
            else:
                r = self.residual(u, th_dot0, th_dot1, kin, want_jac=True)
            r_ready = False
            its += 1
            fresh = False
            keep = (prev is not None and self._factored and not self.full_newton
                    and prm.krylov_refactor == 0
                    and keep_lu(prev, prev2 or 0.0, chord_prev, self.lu_reuse_below,
                                self.jac_reuse_below, self.jst, self.jst_f))
            chord_prev = keep and prev > self.lu_reuse_below
            if keep:
                # simplified Newton (refactorisation rules): the last Newton step moved the
                # iterate by at most lu_reuse_below tolerances, or the Newton matrix moved by
                # at most jac_reuse_below since the LU of this solve's last factorisation (same
                # step, kinematics and BDF coefficient), so that LU is kept for this iteration
                self.stats["reused"] += 1
                dx, finite = self._newton_step(r)
            elif not self._factored or self.full_newton or prm.krylov_refactor == 0:
                if prev is None or not self._refactor_partial(u, th_dot0, kin):
                    self._factor(u, th_dot0, kin, jst_ready=True)
                fresh = True
                dx, finite = self._newton_step(r)
            else:
                dx, kits, ok = self._gmres(-r, prm.krylov_tol, prm.krylov_refactor)
                self.stats["krylov"] += kits
                if not ok:
                    self._factor(u, th_dot0, kin, jst_ready=True)
                    fresh = True
                    dx = self._solve(r)
                finite = bool(np.all(np.isfinite(dx)))
            if not finite:
                break
            if self.dominant:
                law = self.ctx.law
                un = np.empty_like(u)
                e_u, l1_u = np.empty_like(u), np.empty_like(u)
                law_el(u, law.delta, e_u, l1_u)
                dominant_update(u, dx, wcol_p, wcol_th, g.n_phi, law.p_cav, law.K, law.delta, un,
                                e_u, l1_u)
            else:
                un = u + dx
            _limit_switch(u, un, self.ctx.law.delta)
            # convergence is judged on the Newton step itself (after the switch limit),
            # not on the step the line search below may shorten: a step backtracked to
            # 1/16 looks 16x smaller without being closer to the solution, and testing that
            # accepted iterates whose residual was 70x that of the start (measured: a
            # free-to-air step at default tolerances, its force 9 % off)
            nrm = self._increment_norm(un - u, atol, rtol)
            # converged: increment small, or the remaining error estimated from
            # the contraction rate, rho/(1 - rho) |dx|, is (Hairer & Wanner IV.8).
            # rho is the larger of the last two ratios of increments: a single ratio
            # after a first step from a poor start (increment 3e4 tolerances, then
            # 1e2) says 0.003 and accepted an iterate 100 tolerances from converged.
            # Tested before the line search: a converged step is taken whole (the test
            # is on the whole step), and the residual the line search would evaluate
            # at it (one assembly per Newton solve) is not needed
            rho = max(nrm / prev, prev / prev2) if prev2 else 1.0
            done = nrm <= 1.0 or (rho < 0.9 and rho / (1.0 - rho) * nrm <= 1.0)
            if done and not self.search_converged:
                self.stats["newton"] += its
                return un, its
            if prev is not None and self.line_search:
                # backtracking on |r| (the Newton step is a descent direction);
                # the residual and Jacobian at the accepted point are kept for
                # the next iteration
                r0 = float(np.linalg.norm(r))
                lam = 1.0
                rn = float(np.linalg.norm(
                    self.residual(un, th_dot0, th_dot1, kin, want_jac=True)))
                while rn > r0 and lam > 0.1:
                    lam *= 0.5
                    un = u + 0.5 * (un - u)
                    rn = float(np.linalg.norm(
                        self.residual(un, th_dot0, th_dot1, kin, want_jac=True)))
                r_ready = True
            u = un
            if done:
                self.stats["newton"] += its
                return u, its
            prev2, prev = prev, nrm
        self.stats["newton"] += its
        self.stats["failed_newton"] += 1
        return None, its

    def _increment_norm(self, dx, atol, rtol):
        """Newton increment in physical terms: max over cells of
        ``max(|dtheta| / atol, |dp| / (rtol (p_max - p_min) + atol K))`` with
        dtheta, dp linearised at the last residual evaluation: theta to
        ``newton_atol``, pressure to ``newton_rtol`` of the pressure range."""
        return _increment_norm_kernel(dx, self.wp, self.wdp, self.wdth, atol, rtol,
                                      self.ctx.law.K)

    # ------------------------------------------------------------ stepping
    def init_state(self, u):
        self.u = np.array(u, dtype=float)
        self.u_prev = self.u.copy()
        n = self.n
        self.th_nm1 = np.zeros(n)
        self.th_nm2 = np.zeros(n)
        self.h_prev = 0.0
        self.h_prev2 = 0.0
        self.n_hist = 0
        self.h_next = self.ctx.params.h_init
        self.t = 0.0
        self._zero = np.zeros(n)
        self._factored = False
        self._theta_u = None
        self._p_u = np.empty(n)     # p(u) of the state the fused call accepted last
        self._pth_of = None         # ... and that state's u (the array object): see p_theta
        self._el = np.empty((4, n))  # law_el of u, u_prev kept by the fused call ...
        self._el_of = (None, None)  # ... and the arrays they belong to (identity, as _pth_of)
        self._fused_cache = None    # the constant arguments of the fused call (_fused_args)

    def p_theta(self, copy=True):
        """(p, theta) of the current state, new arrays: kept from the fused call that
        accepted it (the same :func:`.cavitation.law_eval` of the same u, so bit for bit
        what ``law.p_theta(u)`` returns), else evaluated. The film's u is rebound by every
        other path that changes it (``init_state``, ``set_state``, the Python loop), and
        only the fused call writes it in place, so the object identity tells whether the
        kept values belong to it. ``copy=False``: the kept arrays themselves when they are
        valid (to be read at once: the next fused call overwrites them)."""
        if self._pth_of is self.u:
            if not copy:
                return self._p_u, self._theta_u
            return self._p_u.copy(), self._theta_u.copy()
        return self.ctx.law.p_theta(self.u)

    def restart_history(self):
        """Forget the BDF history: the next internal step is a BDF1 (backward Euler) step
        from the current state, accepted without a history-based error estimate, with
        step ``h_init``. See :meth:`advance_restarting`."""
        self.n_hist = 0
        self.h_prev = self.h_prev2 = 0.0
        self.u_prev = self.u.copy()
        self.h_next = self.ctx.params.h_init

    def advance_restarting(self, dt, kin, saved):
        """:meth:`advance`; if that fails (step size below h_min), restore ``saved`` (the
        caller's :meth:`get_state` from before the call) and retry the macro step once with
        the BDF history restarted (:meth:`restart_history`). On a second failure the
        state is ``saved`` again and StepFailed names both attempts.

        Why: the kinematics are piecewise constant over macro steps, so the film
        solution's time derivative jumps at each macro-step boundary. BDF2 and its Milne
        error estimate extrapolate the history across that jump; that is harmless as
        long as the film responds smoothly, but when a nearly starved film is squeezed
        (a whirling journal at eps ~0.97, measured in the free-to-air turbocharger
        run-up) cells at the cavity edge reform within nanoseconds, the estimate stays
        above theta_atol for every step size and the macro step failed. Restarting a
        multistep method at a discontinuity of its input is the textbook remedy (Hairer,
        Norsett & Wanner, Solving ODEs I, sec. II.6 and III.5; Brenan, Campbell &
        Petzold 1996, sec. 5.4). Only a step that would otherwise fail takes this path,
        so every run that worked before is unchanged bit for bit; ``stats["restarts"]``
        counts them."""
        try:
            return self.advance(dt, kin)
        except StepFailed as first:
            self.set_state(saved)
            self.restart_history()
            try:
                its = self.advance(dt, kin)
            except StepFailed as second:
                self.set_state(saved)
                raise StepFailed(f"{second} (also after restarting the BDF history; "
                                 f"the first attempt: {first})") from None
            self.stats["restarts"] += 1
            return its

    def fused_eligible(self) -> bool:
        """Does :meth:`advance` take the one-call path of :mod:`.fused`? Yes for the
        default configuration (``fused`` True, the numba band LU, direct Newton with the
        simplified-Newton rule, every diagnostics switch at its default); the benchmark
        peers and the Newton-Krylov option take the Python loop."""
        return (self.fused and type(self.lin) is BandLU and not self.full_newton
                and self.ctx.params.krylov_refactor == 0 and self.predictor
                and self.predictor_limited and self.line_search and self.dominant
                and self.predictor_dominant and not self.search_converged)

    def advance(self, dt, kin):
        """Advance from t to t + dt with kinematics ``kin`` held constant: in one numba
        call without the GIL (:func:`.fused.advance_fused`) when :meth:`fused_eligible`,
        else (or to finish a macro step whose LU needs row interchanges) the Python loop."""
        t_end = self.t + dt
        if self.fused_eligible():
            done, its = self._advance_fused(dt, kin)
            if done:
                return its
        return self._advance_loop(t_end, dt, kin)

    def _advance_fused(self, dt, kin):
        """(finished, iterations): :func:`.fused.advance_fused` on this film's state; not
        finished when an LU pivot needs interchanges (the state is then that of the last
        accepted internal step, and :meth:`_advance_loop` goes on from it)."""
        H, He, Hdot, omega = kin
        t_end = self.t + dt
        if self._theta_u is None:
            th_u, valid = np.empty(self.n), 0.0
        else:
            th_u, valid = self._theta_u, 1.0
        u, u_prev, th_nm1, th_nm2 = self.u, self.u_prev, self.th_nm1, self.th_nm2
        if len({id(u), id(u_prev), id(th_nm1), id(th_nm2), id(th_u)}) < 5:
            # the kernel writes each in place: no aliases
            arrays = [u, u_prev, th_nm1, th_nm2, th_u]
            for k in range(1, 5):
                if any(arrays[k] is a for a in arrays[:k]):
                    arrays[k] = arrays[k].copy()
            u, u_prev, th_nm1, th_nm2, th_u = arrays
        el_u, el_up = self._el_of
        sc = np.array((self.t, self.h_prev, self.h_prev2, self.h_next, float(self.n_hist),
                       valid, 0.0, 1.0 if el_u is u else 0.0, 1.0 if el_up is u_prev else 0.0))
        st = np.zeros(6, dtype=np.int64)
        F = _fused()
        code, its = F.advance_fused(float(dt), H, He, Hdot, float(omega), u, u_prev, th_nm1,
                                    th_nm2, th_u, sc, st, *self._fused_args())
        if st[F.S_STEPS] > 0:
            self._pth_of = u            # p_u, th_u are p(u), theta(u) of this state
        self.u, self.u_prev, self.th_nm1, self.th_nm2 = u, u_prev, th_nm1, th_nm2
        self._el_of = (u, u_prev)       # the kernel leaves _el valid for both
        self.t, self.h_prev, self.h_prev2, self.h_next, n_hist = sc[:F.N_HIST + 1].tolist()
        self.n_hist = int(n_hist)
        self._theta_u = th_u if sc[F.TH_U_VALID] else None
        stats = self.stats
        for key, v in zip(_FUSED_STATS, st.tolist()):
            stats[key] += v
        self._factored = False
        if code == F.H_MIN:
            raise self._h_min_failure(t_end - self.t)
        return code == F.DONE, int(its)

    def _fused_args(self):
        """The arguments of :func:`.fused.advance_fused` after the state and counters: the
        film's constants, buffers and solver settings, built once and kept while the
        parameters object, the simplified-Newton bound, the pivot threshold and the buffers of
        the kept law values are the same objects (:meth:`init_state` makes new buffers; a test
        may replace the model's parameters between steps)."""
        prm = self.ctx.params
        key = (prm, self.lu_reuse_below, self.jac_reuse_below, self.pivot_threshold, self._p_u,
               self._el)
        cached = self._fused_cache
        if cached is not None and all(a is b for a, b in zip(cached[0], key)):
            return cached[1]
        c, g = self.ctx, self.ctx.grid
        args = (self.muscl, g.groove, self.film, c.u_feed, c.a_phi, c.a_z, g.dphi, g.dz, c.bath,
                c.p0, c.law.p_cav, c.law.K, c.law.delta, prm.penalty_a, prm.penalty_b,
                prm.penalty_smoothing, c.sym, g.wrel, g.frel, g.n_phi, g.order, g.pos, g.bw,
                self.ab, self.jst, self.r, self.wp, self.wdp, self.wth, self.wdth,
                prm.h_min, prm.h_max, prm.theta_atol, prm.newton_atol, prm.newton_rtol,
                prm.newton_max_iter, float(self.lu_reuse_below), self._p_u, self._el,
                self.jst_f, float(self.jac_reuse_below), self.pivot_threshold)
        self._fused_cache = (key, args)
        return args

    def _h_min_failure(self, remaining):
        prm = self.ctx.params
        return StepFailed(
            f"film step size fell below h_min = {prm.h_min:g} s "
            f"{remaining:.3g} s before the end of the macro step (film time "
            f"{self.t:.9g} s since its initialisation; Newton failures {self.stats['failed_newton']}, "
            f"rejections {self.stats['rejected']}); the kinematics may be "
            "outside the clearance or jump too fast; reduce the macro step "
            "or loosen theta_atol")

    def _advance_loop(self, t_end, dt, kin):
        """The Python loop of :meth:`advance` (from ``self.t`` to ``t_end``)."""
        prm = self.ctx.params
        last_its = 0
        while t_end - self.t > 1e-12 * max(abs(t_end), dt):
            rem = t_end - self.t
            h = min(self.h_next, prm.h_max, rem)
            if rem <= 1.1 * h:
                h = rem
            while True:
                if h < prm.h_min:
                    raise self._h_min_failure(t_end - self.t)
                # theta(u) of the current state: kept from the last accepted step (same
                # array, so bit for bit what theta(self.u) returns; one law evaluation less)
                th_n = self._theta_u if self._theta_u is not None else self.theta(self.u)
                self._theta_u = th_n
                if self.n_hist == 0:
                    q, th_dot0, th_dot1 = 1, 1.0 / h, -th_n / h
                else:
                    w = h / self.h_prev
                    q = 2
                    a0, a1, a2 = (1 + 2 * w) / (1 + w), -(1 + w), w * w / (1 + w)
                    th_dot0 = a0 / h
                    th_dot1 = (a1 * th_n + a2 * self.th_nm1) / h
                weights = self._weights(th_dot0, kin) if self.dominant else None
                if self.n_hist >= 1 and self.predictor:
                    # linear extrapolation as Newton start (not a state change): in each
                    # cell's own part (dominant_extrapolate), or in u
                    if self.predictor_dominant and weights is not None:
                        law, g = self.ctx.law, self.ctx.grid
                        u_start = np.empty_like(self.u)
                        el = np.empty((4, self.n))
                        law_el(self.u, law.delta, el[0], el[1])
                        law_el(self.u_prev, law.delta, el[2], el[3])
                        dominant_extrapolate(self.u, self.u_prev, h / self.h_prev, *weights,
                                             g.n_phi, law.p_cav, law.K, law.delta, u_start, el)
                    else:
                        u_start = self.u + (h / self.h_prev) * (self.u - self.u_prev)
                    if self.predictor_limited:
                        # not across the cavitation switch: u is p / K in the film and
                        # theta - 1 in the cavity, so a line through a rupturing cell
                        # (u 0.8 -> 0.09) lands at u ~ -3 (theta ~ -2) and costs
                        # Newton iterations to undo; stop it at the switch instead
                        _limit_switch(self.u, u_start, self.ctx.law.delta)
                else:
                    u_start = self.u
                u_new, its = self.newton(u_start, th_dot0, th_dot1, kin, weights=weights)
                last_its = its
                if u_new is None:
                    self.stats["rejected"] += 1
                    h *= 0.25
                    self._factored = False
                    continue
                th_new = self.theta(u_new)
                # Milne error estimate
                if self.n_hist >= 2:
                    h1, h2 = self.h_prev, self.h_prev2
                    Ln = (h + h1) * (h + h1 + h2) / (h1 * (h1 + h2))
                    Lm = -h * (h + h1 + h2) / (h1 * h2)
                    Lmm = h * (h + h1) / ((h1 + h2) * h2)
                    pred = Ln * th_n + Lm * self.th_nm1 + Lmm * self.th_nm2
                    est = (2.0 / 11.0) * (th_new - pred)
                elif self.n_hist == 1:
                    # BDF2 corrector vs linear predictor: a conservative estimate
                    pred = th_n + (h / self.h_prev) * (th_n - self.th_nm1)
                    est = (1.0 / 3.0) * (th_new - pred)
                else:
                    est = None
                if est is not None:
                    err = float(np.sqrt(np.mean(est[self.film] ** 2))) / prm.theta_atol
                else:
                    err = 0.5
                fac = 0.9 * err ** (-1.0 / (q + 1)) if err > 0 else 2.0
                if err > 1.0:
                    self.stats["rejected"] += 1
                    h *= max(0.2, fac)
                    continue
                break
            # accept
            self.th_nm2 = self.th_nm1
            self.th_nm1 = th_n
            self.u_prev = self.u
            self.u = u_new
            self._theta_u = th_new
            self.h_prev2 = self.h_prev
            self.h_prev = h
            self.n_hist += 1
            self.t = t_end if h == rem else self.t + h
            self.stats["steps"] += 1
            self.h_next = min(prm.h_max, h * min(2.0, max(0.2, fac)))
            if self.n_hist == 1:
                self.h_next = min(self.h_next, h)
        self.t = t_end
        return last_its

    # ------------------------------------------------------------ state
    def _reuses_lu(self):
        """True when a factorisation carries over between steps (Newton-Krylov);
        with a fresh LU every Newton iteration it is not part of the state."""
        return self.ctx.params.krylov_refactor > 0 and not self.full_newton

    def get_state(self):
        s = dict(u=self.u.copy(), u_prev=self.u_prev.copy(), th_nm1=self.th_nm1.copy(), th_nm2=self.th_nm2.copy(),
                 h_prev=self.h_prev, h_prev2=self.h_prev2, n_hist=self.n_hist,
                 h_next=self.h_next, t=self.t,
                 jac_valid=bool(self._factored and self._reuses_lu()))
        if s["jac_valid"]:
            H, He, Hdot, omega = self.jac["kin"]
            s.update(jac_u=self.jac["u"].copy(), jac_th_dot0=self.jac["th_dot0"],
                     jac_H=H.copy(), jac_He=He.copy(), jac_Hdot=Hdot.copy(),
                     jac_omega=omega)
        return s

    def set_state(self, s):
        self.u = np.array(s["u"], dtype=float)
        self.u_prev = np.array(s["u_prev"], dtype=float)
        self.th_nm1 = np.array(s["th_nm1"], dtype=float)
        self.th_nm2 = np.array(s["th_nm2"], dtype=float)
        self.h_prev = float(s["h_prev"])
        self.h_prev2 = float(s["h_prev2"])
        self.n_hist = int(s["n_hist"])
        self.h_next = float(s["h_next"])
        self.t = float(s["t"])
        self._factored = False
        self._theta_u = None
        if s.get("jac_valid", False):
            kin = (np.array(s["jac_H"]), np.array(s["jac_He"]), np.array(s["jac_Hdot"]),
                   float(s["jac_omega"]))
            self._factor(np.array(s["jac_u"]), float(s["jac_th_dot0"]), kin)
            self.stats["factor"] -= 1      # a restore is not a solver factorisation
