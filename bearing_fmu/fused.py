"""The film's macro step in one numba call, without the GIL (issue 16, speed).

:func:`advance_fused` is :meth:`.solver.TransientFilm.advance` (variable-step BDF1/2 with
Milne's error estimate) and :meth:`.solver.TransientFilm.newton` (Newton in each cell's
dominant variable, simplified-Newton LU reuse, backtracking on |r|) for the default
configuration of the integrator, written as one ``nopython`` function over the kernels the
Python loop calls (:func:`.film.assemble`, :func:`.solver.band_lu_nopivot`, ...), in the
same order and with the same arithmetic. Two things follow:

* the Python glue between the kernels (about 10 % of a film step) is gone;
* the call holds no GIL (``nogil=True``), so two films advanced from two threads
  (``coupling.parallel: threads``, :mod:`orchestrator.coupling.execution`) run on two
  cores at the same time.

The only reductions computed differently are the two norms (the line search's |r| and
the RMS of the error estimate): sequential sums here, numpy's pairwise sums in the Python
loop, so the two paths agree to rounding, not bit for bit (a line-search or step-size
decision at a tie could go the other way; measured in BENCHMARKS.md, issue 16).

Return codes: :data:`DONE`; :data:`H_MIN` (the step size fell below ``h_min``: the state
is that of the last accepted internal step, the caller raises StepFailed); :data:`PIVOT`
(an LU pivot failed the threshold of :func:`.solver.band_lu_nopivot`: the state is that of
the last accepted internal step with ``h_next`` the step being tried, and the caller
finishes the macro step with the Python loop, whose LU falls back to LAPACK with row
interchanges). The state is changed only when an internal step is accepted, as in the
Python loop.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .cavitation import law_eval
from .film import assemble, assemble_muscl
from .solver import (PIVOT_THRESHOLD, _increment_norm_kernel, _limit_switch,
                     band_newton_step_nopivot, dominant_extrapolate, dominant_update,
                     dominant_weights, factor_full, keep_lu, law_el, refactor_partial)

DONE, H_MIN, PIVOT = 0, 1, 2
#: indices of the scalar state ``sc``
T, H_PREV, H_PREV2, H_NEXT, N_HIST, TH_U_VALID, H_FAILED, EL_U_VALID, EL_UP_VALID = range(9)
#: indices of the counters ``st`` (added to ``TransientFilm.stats`` by the caller)
S_STEPS, S_REJECTED, S_NEWTON, S_FACTOR, S_FAILED_NEWTON, S_REUSED = range(6)


@nb.njit(cache=True)
def _residual(muscl, u, th_dot0, th_dot1, H, He, Hdot, groove, u_feed, omega, a_phi, a_z,
              dphi, dz, bath, p0, p_cav, K, delta, pa, pb, s_pen, r, jst, p, dp, th, dth,
              sym, wrel, frel, e_u, l1_u, valid):
    if muscl:
        assemble_muscl(u, th_dot0, th_dot1, H, He, Hdot, groove, u_feed, omega, a_phi, a_z,
                       dphi, dz, bath, p0, p_cav, K, delta, pa, pb, s_pen, r, True, jst,
                       p, dp, th, dth, sym, wrel, frel, e_u, l1_u, valid)
    else:
        assemble(u, th_dot0, th_dot1, H, He, Hdot, groove, u_feed, omega, a_phi, a_z,
                 dphi, dz, bath, p0, p_cav, K, delta, pa, pb, s_pen, r, True, jst,
                 p, dp, th, dth, sym, wrel, frel, e_u, l1_u, valid)


@nb.njit(cache=True)
def _norm(x):
    s = 0.0
    for k in range(x.size):
        s += x[k] * x[k]
    return math.sqrt(s)


@nb.njit(cache=True, nogil=True)
def advance_fused(dt, H, He, Hdot, omega,
                  u, u_prev, th_nm1, th_nm2, th_u, sc, st,
                  muscl, groove, film, u_feed, a_phi, a_z, dphi, dz, bath, p0, p_cav, K, delta,
                  pa, pb, s_pen, sym, wrel, frel,
                  n_phi, order, pos, bw, ab, jst, r, p, dp, th, dth,
                  h_min, h_max, theta_atol, atol, rtol, max_iter, lu_reuse_below,
                  p_u, el, jst_f, jac_reuse_below, pivot_threshold=PIVOT_THRESHOLD):
    """Advance the film state from ``sc[T]`` to ``sc[T] + dt`` (module doc). Arrays ``u,
    u_prev, th_nm1, th_nm2, th_u`` (n,) and ``sc`` (7,), ``st`` (6,) are the state and
    counters, changed in place; ``ab, jst, r, p, dp, th, dth`` the integrator's buffers;
    ``p_u`` (n,) receives p(u) of each accepted state (with ``th_u`` = theta(u): the same
    :func:`.cavitation.law_eval` values, so the caller's outputs need not evaluate the law);
    ``el`` (4, n) e = exp(-|u / delta|) and log1p(e) of u and of u_prev
    (:func:`.solver.dominant_extrapolate`), valid on entry where ``sc[EL_U_VALID]``,
    ``sc[EL_UP_VALID]`` say so (else computed here) and kept valid for both on return;
    ``jst_f`` (as ``jst``) receives the stencil Jacobian of every LU (the second
    simplified-Newton rule, ``jac_reuse_below``: :data:`.solver.JACOBIAN_REUSE_BELOW`);
    ``pivot_threshold`` that of :func:`.solver.band_lu_nopivot` (a test forces the
    :data:`PIVOT` return with a threshold no pivot meets).
    Returns (code, Newton iterations of the last solve)."""
    n = u.size
    u_start = np.empty(n)
    u_new = np.empty(n)
    un = np.empty(n)
    step = np.empty(n)
    th_dot1 = np.empty(n)
    th_new = np.empty(n)
    est = np.empty(n)
    s1, s2, s3 = np.empty(n), np.empty(n), np.empty(n)
    work, dx = np.empty(n), np.empty(n)
    # e = exp(-|u / delta|) and log1p(e) of the iterate: written by the residual (law_eval),
    # and by the predictor and the Newton update for the cells whose own root they solved
    # (``valid`` 1), so that the residual at the new iterate reads them there
    e_it, l1_it = np.empty(n), np.empty(n)
    valid = np.zeros(n, dtype=np.uint8)
    wcol_p, wcol_th = np.empty(n_phi), np.empty(n_phi)
    n_film = 0
    for k in range(n):
        if film[k]:
            n_film += 1
    if sc[EL_U_VALID] == 0.0:
        law_el(u, delta, el[0], el[1])
    if sc[EL_UP_VALID] == 0.0:
        law_el(u_prev, delta, el[2], el[3])
    e_new, l1_new = np.empty(n), np.empty(n)
    t = sc[T]
    t_end = t + dt
    last_its = 0
    while t_end - t > 1e-12 * max(abs(t_end), dt):
        rem = t_end - t
        h = min(sc[H_NEXT], h_max, rem)
        if rem <= 1.1 * h:
            h = rem
        fac = 2.0
        while True:
            if h < h_min:
                sc[T] = t
                sc[H_FAILED] = h
                return H_MIN, last_its
            if sc[TH_U_VALID] == 0.0:
                law_eval(u, p_cav, K, delta, s1, s2, th_u, s3)
                sc[TH_U_VALID] = 1.0
            n_hist = int(sc[N_HIST])
            if n_hist == 0:
                q = 1
                th_dot0 = 1.0 / h
                for k in range(n):
                    th_dot1[k] = -th_u[k] / h
            else:
                w = h / sc[H_PREV]
                q = 2
                a0, a1, a2 = (1 + 2 * w) / (1 + w), -(1 + w), w * w / (1 + w)
                th_dot0 = a0 / h
                for k in range(n):
                    th_dot1[k] = (a1 * th_u[k] + a2 * th_nm1[k]) / h
            dominant_weights(H, He, Hdot, th_dot0, omega, a_phi, a_z, dphi, dz, wrel, frel,
                             wcol_p, wcol_th)
            if n_hist >= 1:
                dominant_extrapolate(u, u_prev, h / sc[H_PREV], wcol_p, wcol_th, n_phi, p_cav,
                                     K, delta, u_start, el, e_it, l1_it, valid)
                _limit_switch(u, u_start, delta, valid)
            else:
                u_start[:] = u
                valid[:] = 0
            # ---- Newton (TransientFilm.newton, default branches) ----
            uu = u_start           # current iterate (u_start is scratch from here on)
            prev = -1.0
            prev2 = -1.0
            its = 0
            r_ready = False
            ok = False
            chord_prev = False
            while its < max_iter:
                if not r_ready:
                    _residual(muscl, uu, th_dot0, th_dot1, H, He, Hdot, groove, u_feed, omega,
                              a_phi, a_z, dphi, dz, bath, p0, p_cav, K, delta, pa, pb, s_pen,
                              r, jst, p, dp, th, dth, sym, wrel, frel, e_it, l1_it, valid)
                r_ready = False
                its += 1
                keep = prev >= 0.0 and keep_lu(prev, prev2, chord_prev, lu_reuse_below,
                                               jac_reuse_below, jst, jst_f)
                chord_prev = keep and prev > lu_reuse_below
                if keep:
                    st[S_REUSED] += 1
                else:
                    if prev >= 0.0 and jac_reuse_below > 0.0:
                        # a later LU of this solve: from the first row that moved on
                        code, _ = refactor_partial(jst, jst_f, n_phi, pos, bw, ab,
                                                   pivot_threshold, jac_reuse_below)
                    else:
                        code = factor_full(jst, jst_f, n_phi, pos, bw, ab, pivot_threshold)
                    if code != 0:
                        sc[T] = t       # this solve is redone by the Python loop: not counted
                        sc[H_NEXT] = h
                        return PIVOT, last_its
                    st[S_FACTOR] += 1
                if not band_newton_step_nopivot(ab, bw, r, order, pos, work, dx):
                    break
                # e_it, l1_it: of uu on entry, of un where valid on return (per cell: read,
                # then written)
                dominant_update(uu, dx, wcol_p, wcol_th, n_phi, p_cav, K, delta, un, e_it,
                                l1_it, e_it, l1_it, valid)
                _limit_switch(uu, un, delta, valid)
                for k in range(n):
                    step[k] = un[k] - uu[k]
                nrm = _increment_norm_kernel(step, p, dp, dth, atol, rtol, K)
                if prev2 > 0.0:
                    rho = max(nrm / prev, prev / prev2)
                else:
                    rho = 1.0
                done = nrm <= 1.0 or (rho < 0.9 and rho / (1.0 - rho) * nrm <= 1.0)
                if done:
                    u_new[:] = un
                    ok = True
                    break
                if prev >= 0.0:
                    r0 = _norm(r)
                    lam = 1.0
                    _residual(muscl, un, th_dot0, th_dot1, H, He, Hdot, groove, u_feed, omega,
                              a_phi, a_z, dphi, dz, bath, p0, p_cav, K, delta, pa, pb, s_pen,
                              r, jst, p, dp, th, dth, sym, wrel, frel, e_it, l1_it, valid)
                    rn = _norm(r)
                    while rn > r0 and lam > 0.1:
                        lam *= 0.5
                        valid[:] = 0
                        for k in range(n):
                            un[k] = uu[k] + 0.5 * (un[k] - uu[k])
                        _residual(muscl, un, th_dot0, th_dot1, H, He, Hdot, groove, u_feed,
                                  omega, a_phi, a_z, dphi, dz, bath, p0, p_cav, K, delta, pa,
                                  pb, s_pen, r, jst, p, dp, th, dth, sym, wrel, frel, e_it, l1_it,
                                  valid)
                        rn = _norm(r)
                    r_ready = True
                uu[:] = un
                prev2, prev = prev, nrm
            st[S_NEWTON] += its
            last_its = its
            if not ok:
                st[S_FAILED_NEWTON] += 1
                st[S_REJECTED] += 1
                h *= 0.25
                continue
            # ---- Milne error estimate ----
            law_eval(u_new, p_cav, K, delta, s1, s2, th_new, s3, e_it, l1_it, valid)
            e_new[:] = e_it
            l1_new[:] = l1_it
            if n_hist >= 2:
                h1, h2 = sc[H_PREV], sc[H_PREV2]
                Ln = (h + h1) * (h + h1 + h2) / (h1 * (h1 + h2))
                Lm = -h * (h + h1 + h2) / (h1 * h2)
                Lmm = h * (h + h1) / ((h1 + h2) * h2)
                for k in range(n):
                    pred = Ln * th_u[k] + Lm * th_nm1[k] + Lmm * th_nm2[k]
                    est[k] = (2.0 / 11.0) * (th_new[k] - pred)
            elif n_hist == 1:
                ratio = h / sc[H_PREV]
                for k in range(n):
                    pred = th_u[k] + ratio * (th_u[k] - th_nm1[k])
                    est[k] = (1.0 / 3.0) * (th_new[k] - pred)
            if n_hist >= 1:
                s = 0.0
                for k in range(n):
                    if film[k]:
                        s += est[k] * est[k]
                err = math.sqrt(s / n_film) / theta_atol
            else:
                err = 0.5
            fac = 0.9 * err ** (-1.0 / (q + 1)) if err > 0 else 2.0
            if err > 1.0:
                st[S_REJECTED] += 1
                h *= max(0.2, fac)
                continue
            break
        # ---- accept ----
        th_nm2[:] = th_nm1
        th_nm1[:] = th_u
        u_prev[:] = u
        u[:] = u_new
        el[2, :] = el[0]
        el[3, :] = el[1]
        el[0, :] = e_new
        el[1, :] = l1_new
        th_u[:] = th_new
        p_u[:] = s1                 # p(u_new) of the law_eval above
        sc[H_PREV2] = sc[H_PREV]
        sc[H_PREV] = h
        sc[N_HIST] += 1.0
        t = t_end if h == rem else t + h
        st[S_STEPS] += 1
        h_next = min(h_max, h * min(2.0, max(0.2, fac)))
        if sc[N_HIST] == 1.0:
            h_next = min(h_next, h)
        sc[H_NEXT] = h_next
    sc[T] = t_end
    return DONE, last_its
