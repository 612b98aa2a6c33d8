"""Common core of the rotor models: a linear, speed-dependent structure driven kinematically.

Equations of motion (generalized coordinates ``q``, n dofs)::

    M q'' + (C + Omega(t) G) q' + (K + Omega(t) Kc + alpha(t) Ka) q
        = f_g + B F + f_unb(t)

* ``M`` mass, ``C`` non-rotating + rotating viscous damping, ``K`` stiffness;
* ``G`` gyroscopic (skew), ``Kc`` circulatory stiffness of rotating (internal)
  damping, ``Ka`` the angular-acceleration term of the gyroscopic moments
  (Friswell et al. 2010, "Dynamics of Rotating Machines", sec. 5.2 / eq. 5.50ff);
* ``f_g`` gravity (-y), ``B F`` the film forces on the bearing stations (``F`` of
  shape (n_bearings, 2) held constant over a step), ``f_unb`` the unbalance forces
  from the prescribed angle (``Omega`` = d angle / dt, ``alpha`` = d Omega / dt)::

      f_unb = m e [Omega^2 cos(phi) + alpha sin(phi),  Omega^2 sin(phi) - alpha cos(phi)]

  with ``phi = angle(t) + phase`` (from the acceleration of the unbalance mass at
  ``r + e (cos phi, sin phi)``).

First-order form (for the monolithic reference): ``s = [q, v]``,
``ds/dt = [v, M^-1 (f - (C + Omega G) v - (K + Omega Kc + alpha Ka) q)]``.

Time integration inside ``step(dt, F)``: the trapezoidal rule (A-stable, second
order, no numerical damping; for undamped linear systems it conserves the energy
``v'Mv/2 + q'Kq/2`` exactly) on ``n_sub`` equal sub-steps, with the speed-dependent
matrices evaluated at the macro step's mid time (factorized once per step).
``n_sub`` is chosen so that ``omega_max * h <= max_phase_per_substep`` where
``omega_max`` is the highest undamped natural frequency of the free structure
(precomputed), i.e. the stiff journal/shaft modes are resolved (relative frequency
error of the trapezoidal rule ~ (omega h)^2 / 12).  Each sub-step solves::

    (I + h/2 A_C + h^2/4 A_K) v1 = v0 + h/2 (f0 + f1 - 2 A_K q0 - A_C v0 - h/2 A_K v0)
    q1 = q0 + h/2 (v0 + v1)

with ``A_C = M^-1 (C + Omega G)``, ``A_K = M^-1 (K + Omega Kc + alpha Ka)`` and
``f = M^-1 (f_g + B F + f_unb)``; all ``M^-1`` products are precomputed.  Kernels:
numpy (default; the sub-steps as one affine map, cached per quantized speed, see
:func:`_numpy_substeps`) or numba (``ROTORCOSIM_ROTOR_KERNEL=numba``); see
docs/rotor-models.md.
"""

from __future__ import annotations

import math
import os

import numpy as np
import scipy.linalg as sla

# Kernel of the sub-step loop: "numpy" (default) or "numba" (set ROTORCOSIM_ROTOR_KERNEL=numba).
# numba is not the default: its on-disk cache has known segfaulting races when several
# processes compile the same module concurrently (numba issues #4807, #10128), which is
# the normal situation on a shared checkout; without the cache every process pays a
# multi-second compile.  The numpy kernel is within the cost goal (docs/rotor-models.md).
KERNEL = os.environ.get("ROTORCOSIM_ROTOR_KERNEL", "numpy").strip().lower()
_numba = None
if KERNEL == "numba":
    try:
        import numba as _numba
    except ImportError:  # pragma: no cover
        _numba = None

# Above this many entries nsub * n_dof^2 (= 1/2 of the sub-step matrix R's size), the numpy
# sub-steps iterate the affine map instead of building R (see _numpy_substeps): 2 M entries =
# 32 MB for R. The Jeffcott rotor (n_dof 6) never gets there; the turbocharger (n_dof ~40) at
# nsub > ~1250, i.e. only with a near-contact film through the interface Jacobian.
DIRECT_SUBSTEP_SIZE = 2_000_000
#: internal sub-steps of one macro step at most (n_substeps; the shipped run-ups take a few)
MAX_SUBSTEPS = 10_000_000


def _drive_eval(t, tt, ww, aa):
    """(omega, alpha, angle) at t of a piecewise-linear speed table with constant
    extrapolation; aa = exact angle at the table points (same as rotor_fmu.drive)."""
    m = tt.shape[0]
    if t <= tt[0]:
        return ww[0], 0.0, aa[0] + ww[0] * (t - tt[0])
    if t >= tt[m - 1]:
        return ww[m - 1], 0.0, aa[m - 1] + ww[m - 1] * (t - tt[m - 1])
    i = 0
    while tt[i + 1] <= t:
        i += 1
    sl = (ww[i + 1] - ww[i]) / (tt[i + 1] - tt[i])
    d = t - tt[i]
    return ww[i] + sl * d, sl, aa[i] + ww[i] * d + 0.5 * sl * d * d


def _forcing(t, fF, tt, ww, aa, me, ph, MiU, out):
    """out = fF + M^-1 f_unb(t) (accelerations)."""
    w, al, ang = _drive_eval(t, tt, ww, aa)
    n = out.shape[0]
    for i in range(n):
        out[i] = fF[i]
    for j in range(me.shape[0]):
        phi = ang + ph[j]
        c = math.cos(phi)
        s = math.sin(phi)
        fx = me[j] * (w * w * c + al * s)
        fy = me[j] * (w * w * s - al * c)
        for i in range(n):
            out[i] += MiU[i, 2 * j] * fx + MiU[i, 2 * j + 1] * fy


def _trapezoid_substeps(q, v, t0, h, nsub, fF, tt, ww, aa, me, ph, MiU,
                        MiK, MiKc, MiKa, MiC, MiG):
    """Trapezoidal sub-steps (see module doc) from t0, nsub steps of h.  The speed-
    dependent matrices are evaluated once, at the macro step's mid time (the speed
    changes by alpha * dt, e.g. 5e-2 rad/s per 2e-5 s step at 800 Hz / 2 s), so the
    n x n matrix is factorized once (Gaussian elimination, partial pivoting) and each
    sub-step costs two mat-vecs and a triangular solve.  The forcing (unbalance from
    the exact angle) is evaluated at every sub-step end."""
    n = q.shape[0]
    fa = np.empty(n)
    fb = np.empty(n)
    r = np.empty(n)
    AK = np.empty((n, n))
    AC = np.empty((n, n))
    S = np.empty((n, n))
    perm = np.empty(n, dtype=np.int64)
    q = q.copy()
    v = v.copy()
    hh = 0.5 * h
    h2 = 0.25 * h * h
    w, a, _ = _drive_eval(t0 + 0.5 * nsub * h, tt, ww, aa)
    for i in range(n):
        perm[i] = i
        for j in range(n):
            AK[i, j] = MiK[i, j] + w * MiKc[i, j] + a * MiKa[i, j]
            AC[i, j] = MiC[i, j] + w * MiG[i, j]
            S[i, j] = hh * AC[i, j] + h2 * AK[i, j]
        S[i, i] += 1.0
    # LU with partial pivoting, in place (L below the diagonal, unit diagonal)
    for c in range(n):
        p = c
        big = abs(S[c, c])
        for i in range(c + 1, n):
            if abs(S[i, c]) > big:
                big = abs(S[i, c])
                p = i
        if p != c:
            for j in range(n):
                tmp = S[c, j]
                S[c, j] = S[p, j]
                S[p, j] = tmp
            k = perm[c]
            perm[c] = perm[p]
            perm[p] = k
        piv = S[c, c]
        for i in range(c + 1, n):
            f = S[i, c] / piv
            S[i, c] = f
            if f != 0.0:
                for j in range(c + 1, n):
                    S[i, j] -= f * S[c, j]
    _forcing(t0, fF, tt, ww, aa, me, ph, MiU, fa)
    for k in range(nsub):
        _forcing(t0 + (k + 1) * h, fF, tt, ww, aa, me, ph, MiU, fb)
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += AK[i, j] * (2.0 * q[j] + hh * v[j]) + AC[i, j] * v[j]
            fb_i = fb[i]
            r[i] = v[i] + hh * (fa[i] + fb_i - acc)
        # solve L U x = P r
        x = np.empty(n)
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
        for i in range(n):
            q[i] += hh * (v[i] + x[i])
            v[i] = x[i]
            fa[i] = fb[i]
    return q, v


_drive_eval_py = _drive_eval


def _jit(f):
    try:   # cache by source content: the FMU extracts this file afresh for every run (bearing_fmu/_numba_cache.py)
        from bearing_fmu._numba_cache import njit_cached as jit
    except ImportError:  # pragma: no cover - an FMU used without rotorcosim installed: numba's default
        jit = _numba.njit(cache=True)
    try:
        return jit(f)
    except Exception:  # pragma: no cover - unwritable cache location
        return _numba.njit(cache=False)(f)


if _numba is not None:
    _drive_eval = _jit(_drive_eval)
    _forcing = _jit(_forcing)
    _kernel = _jit(_trapezoid_substeps)
else:
    _kernel = None


def _segment_drive(t0, t1, tt, ww, aa):
    """(omega, alpha, angle) at t0 if [t0, t1] lies inside one linear segment of the
    speed table (or outside it), else None."""
    w0, a0, ang0 = _drive_eval_py(t0, tt, ww, aa)
    m = tt.shape[0]
    for k in range(m):
        if t0 < tt[k] < t1:
            return None
    return w0, a0, ang0


def _numpy_substeps(rotor, q, v, t0, h, nsub, fF):
    """numpy form of :func:`_trapezoid_substeps` (same scheme).

    With the matrices frozen over the macro step, one trapezoidal sub-step is the affine
    map x1 = P x0 + Q (f_a + f_b) on x = [q, v].  P and Q depend on (h, Omega, alpha)
    only; they are cached for the last key, with Omega quantized to the grid
    ``rotor.omega_quantum`` (deterministic in t, so save/restore stays exact; the speed-
    dependent terms then use Omega within omega_quantum / 2 of the mid-step value).
    """
    n = q.shape[0]
    tt, ww, aa = rotor._drive_tab
    w, a, _ = _drive_eval_py(t0 + 0.5 * nsub * h, tt, ww, aa)
    dq = rotor.omega_quantum
    if rotor._speed_dependent and dq > 0.0:
        w = round(w / dq) * dq
    elif not rotor._speed_dependent:
        w, a = 0.0, 0.0
    # the key holds the matrices themselves (compared by identity: a swapped-in matrix,
    # e.g. the interface-Jacobian augmented one, never hits a stale entry)
    mats = (rotor._MiK, rotor._MiC, rotor._MiG, rotor._MiKc, rotor._MiKa)
    key = (h, nsub, w, a)
    cache = rotor._pq_cache
    # many sub-steps (a stiff film near contact through the interface Jacobian, whose
    # matrices change every macro step): iterate the affine map instead of building the
    # (2n, nsub n) matrix R -- memory O(n^2) instead of O(nsub n^2) (4.5 GB were seen for
    # the turbocharger at eps 0.9998) and O(nsub n^2) work instead of O(nsub n^3). The
    # key holds nsub, so a cache entry of the same key is always of the same kind.
    direct = nsub * n * n > DIRECT_SUBSTEP_SIZE
    if (cache is None or cache[0] != key
            or any(m1 is not m2 for m1, m2 in zip(cache[4], mats))):
        hh, h2 = 0.5 * h, 0.25 * h * h
        AK = rotor._MiK + w * rotor._MiKc + a * rotor._MiKa
        AC = rotor._MiC + w * rotor._MiG
        Si = np.linalg.inv(rotor._eye + hh * AC + h2 * AK)
        SiAK = Si @ AK
        Pvq = (-2.0 * hh) * SiAK
        Pvv = Si - hh * (Si @ AC) - h2 * SiAK
        P = np.empty((2 * n, 2 * n))
        P[:n, :n] = hh * Pvq + rotor._eye
        P[:n, n:] = hh * Pvv + hh * rotor._eye
        P[n:, :n] = Pvq
        P[n:, n:] = Pvv
        Q = np.empty((2 * n, n))
        Q[:n] = (hh * hh) * Si
        Q[n:] = hh * Si
        if direct:
            cache = rotor._pq_cache = (key, P, Q, None, mats)
        else:
            # x_N = P^N x_0 + sum_k P^(N-1-k) Q g_k,  g_k = f_k + f_(k+1)
            R = np.empty((2 * n, nsub * n))
            Pk = np.eye(2 * n)
            for k in range(nsub - 1, -1, -1):
                R[:, k * n:(k + 1) * n] = Pk @ Q
                Pk = P @ Pk
            Rsum = R.reshape(2 * n, nsub, n).sum(axis=1)
            cache = rotor._pq_cache = (key, Pk, R, Rsum, mats)
    if direct:
        _, P, Q, _, _ = cache
        g = np.empty((nsub, n))
        g[:] = 2.0 * fF
        if rotor._me.size:
            g += _unbalance_pairs(rotor, t0, h, nsub) @ rotor._MiU.T
        x = np.concatenate([q, v])
        for k in range(nsub):
            x = P @ x + Q @ g[k]
        return x[:n], x[n:]
    _, PN, R, Rsum, _ = cache
    x = PN @ np.concatenate([q, v]) + Rsum @ (2.0 * fF)
    if rotor._me.size:
        x = x + R @ (_unbalance_pairs(rotor, t0, h, nsub) @ rotor._MiU.T).reshape(-1)
    return x[:n], x[n:]


def _unbalance_pairs(rotor, t0, h, nsub):
    """f_k + f_(k+1) of the unbalance forces at the sub-step times t0 + k h, (nsub, 2 n_unb)."""
    tt, ww, aa = rotor._drive_tab
    tau = h * np.arange(nsub + 1)
    seg = _segment_drive(t0, t0 + nsub * h, tt, ww, aa)
    if seg is None:
        ev = np.array([_drive_eval_py(t0 + x_, tt, ww, aa) for x_ in tau])
        wt, at, ang = ev[:, 0:1], ev[:, 1:2], ev[:, 2:3]
    else:
        w0, a0, g0 = seg
        tau = tau[:, None]
        wt = w0 + a0 * tau
        at = a0
        ang = g0 + w0 * tau + 0.5 * a0 * tau * tau
    phi = ang + rotor._ph
    c, s_ = np.cos(phi), np.sin(phi)
    fu = np.empty((nsub + 1, 2 * rotor._me.size))
    fu[:, 0::2] = rotor._me * (wt * wt * c + at * s_)
    fu[:, 1::2] = rotor._me * (wt * wt * s_ - at * c)
    return fu[:-1] + fu[1:]


class LinearRotor:
    """Base class: state, stepping, outputs and first-order form of a linear rotor.

    Subclasses build the matrices and call :meth:`_setup`.  Call order:
    ``initialize()`` once, then ``step(dt, F)`` repeatedly; ``outputs`` is valid
    after ``initialize``.  ``get_state``/``set_state`` restore exactly.
    """

    #: :meth:`get_state` returns copies the model does not keep (the FMU wrapper's state
    #: need not deep-copy them again: fmu_common.slave.get_slave_state)
    STATE_IS_COPY = True

    n_bearings: int

    # ------------------------------------------------------------------ set-up
    def _setup(self, *, M, C, G, K, Kc, Ka, bearing_dofs, unbalances, f_g, drive,
               t0, max_phase_per_substep, extra_outputs, journal_q0=None, initial_sag=True,
               omega_quantum=0.5):
        """Store the matrices and precompute everything that depends only on parameters.

        bearing_dofs: int array (n_bearings, 2), indices of (x, y) of each bearing station.
        unbalances: list of (dof_x, dof_y, m_e [kg m], phase [rad]).
        extra_outputs: dict name -> ("q"|"v", dof index).
        journal_q0: (n_bearings, 2) initial bearing-station positions [m] (default 0).
        omega_quantum: grid [rad/s] of the speed used in the speed-dependent matrices of
            the numpy kernel (lets it reuse the step matrices; 0 = exact mid-step speed).
        initial_sag: start the other dofs at the static equilibrium under gravity with
            the bearing stations held at journal_q0 (else at 0).
        """
        self.M = np.asarray(M, float)
        self.C = np.asarray(C, float)
        self.G = np.asarray(G, float)
        self.K = np.asarray(K, float)
        self.Kc = np.asarray(Kc, float)
        self.Ka = np.asarray(Ka, float)
        self.n_dof = n = self.M.shape[0]
        self.bearing_dofs = np.asarray(bearing_dofs, dtype=int).reshape(-1, 2)
        self.n_bearings = self.bearing_dofs.shape[0]
        self.unbalances = [(int(a), int(b), float(me), float(ph)) for a, b, me, ph in unbalances]
        self.f_g = np.asarray(f_g, float)
        self.drive = drive
        self.t0 = float(t0)
        self.max_phase_per_substep = float(max_phase_per_substep)
        self.omega_quantum = float(omega_quantum)
        self.extra_outputs = dict(extra_outputs)
        self._journal_q0 = (np.zeros((self.bearing_dofs.shape[0], 2)) if journal_q0 is None
                            else np.asarray(journal_q0, float).reshape(-1, 2))
        self._initial_sag = bool(initial_sag)
        self._supports_k = np.zeros((self.n_bearings, 2, 2))
        self._supports_c = np.zeros((self.n_bearings, 2, 2))
        self._precompute()
        self.t = self.t0
        self.s = np.zeros(2 * n)
        self._initialized = False
        self._outputs = None

    def add_linear_supports(self, k, c=None):
        """Add linear isotropic/anisotropic supports at the bearing stations.

        k, c: arrays (n_bearings, 2, 2) [N/m], [N s/m] (or scalars, isotropic); the
        support force on station i is ``-k[i] @ [x, y] - c[i] @ [vx, vy]``.  Used by
        the validation tests and the linear stability analysis; call before
        ``initialize``.  Film forces ``F`` passed to ``step`` still add.
        """
        k = self._as_coeff(k, "k")
        c = self._as_coeff(0.0 if c is None else c, "c")
        for i, (ix, iy) in enumerate(self.bearing_dofs):
            idx = np.ix_([ix, iy], [ix, iy])
            self.K[idx] += k[i]
            self.C[idx] += c[i]
        self._supports_k += k
        self._supports_c += c
        self._precompute()

    def _as_coeff(self, a, name):
        a = np.asarray(a, float)
        if a.ndim == 0:
            return np.broadcast_to(a * np.eye(2), (self.n_bearings, 2, 2)).copy()
        if a.shape == (2, 2):
            return np.broadcast_to(a, (self.n_bearings, 2, 2)).copy()
        if a.shape != (self.n_bearings, 2, 2):
            raise ValueError(f"support {name}: expected a scalar, (2, 2) or "
                             f"({self.n_bearings}, 2, 2) array (got shape {a.shape})")
        return a

    def _precompute(self):
        n = self.n_dof
        Mi = np.linalg.inv(self.M)
        self._MiK = Mi @ self.K
        self._MiC = Mi @ self.C
        self._MiG = Mi @ self.G
        self._MiKc = Mi @ self.Kc
        self._MiKa = Mi @ self.Ka
        self._Mifg = Mi @ self.f_g
        B = np.zeros((n, 2 * self.n_bearings))
        for i, (ix, iy) in enumerate(self.bearing_dofs):
            B[ix, 2 * i] = 1.0
            B[iy, 2 * i + 1] = 1.0
        self.B = B
        self._MiB = Mi @ B
        U = np.zeros((n, 2 * len(self.unbalances)))
        for j, (ix, iy, _, _) in enumerate(self.unbalances):
            U[ix, 2 * j] = 1.0
            U[iy, 2 * j + 1] = 1.0
        self._MiU = np.ascontiguousarray(Mi @ U)
        self._me = np.array([u[2] for u in self.unbalances], dtype=float)
        self._drive_tab = tuple(np.ascontiguousarray(a, dtype=float) for a in self.drive.table())
        self._ph = np.array([u[3] for u in self.unbalances], dtype=float)
        self._eye = np.eye(n)
        # highest undamped natural frequency of the structure (Omega = 0)
        lam = sla.eigh(0.5 * (self.K + self.K.T), 0.5 * (self.M + self.M.T), eigvals_only=True)
        self.omega_max = float(np.sqrt(max(lam.max(), 0.0)))
        self._nsub_cache: dict[float, int] = {}
        self._pq_cache = None
        self._speed_dependent = bool(np.any(self._MiG) or np.any(self._MiKc) or np.any(self._MiKa))
        out_index = []
        for i, (ix, iy) in enumerate(self.bearing_dofs, start=1):
            out_index += [(f"x_{i}", ix), (f"y_{i}", iy), (f"vx_{i}", n + ix), (f"vy_{i}", n + iy)]
        for name, (kind, idx) in self.extra_outputs.items():
            out_index.append((name, int(idx) if kind == "q" else n + int(idx)))
        self._out_index = [(name, int(k)) for name, k in out_index]

    # --------------------------------------------------------------- forcing
    def _unbalance_acc(self, t: float) -> np.ndarray:
        """M^-1 f_unb(t)."""
        if not self.unbalances:
            return np.zeros(self.n_dof)
        w = self.drive.omega(t)
        a = self.drive.alpha(t)
        phi = self.drive.angle(t) + self._ph
        c, s = np.cos(phi), np.sin(phi)
        fu = np.empty(2 * len(self._me))
        fu[0::2] = self._me * (w * w * c + a * s)
        fu[1::2] = self._me * (w * w * s - a * c)
        return self._MiU @ fu

    def _unbalance_acc_many(self, ts: np.ndarray) -> np.ndarray:
        """M^-1 f_unb at the times ts, shape (len(ts), n_dof)."""
        if not self.unbalances:
            return np.zeros((ts.size, self.n_dof))
        w = np.atleast_1d(self.drive.omega(ts))[:, None]
        a = np.atleast_1d(self.drive.alpha(ts))[:, None]
        phi = np.atleast_1d(self.drive.angle(ts))[:, None] + self._ph
        c, s = np.cos(phi), np.sin(phi)
        fu = np.empty((ts.size, 2 * self._me.size))
        fu[:, 0::2] = self._me * (w * w * c + a * s)
        fu[:, 1::2] = self._me * (w * w * s - a * c)
        return fu @ self._MiU.T

    def unbalance_forces(self, t: float) -> np.ndarray:
        """Unbalance forces [N], shape (n_unbalances, 2), at time t (for checks and plots)."""
        w, a = self.drive.omega(t), self.drive.alpha(t)
        phi = self.drive.angle(t) + self._ph
        return np.stack([self._me * (w * w * np.cos(phi) + a * np.sin(phi)),
                         self._me * (w * w * np.sin(phi) - a * np.cos(phi))], axis=1)

    def _check_F(self, F) -> np.ndarray:
        F = np.asarray(F, dtype=float)
        if F.shape != (self.n_bearings, 2):
            try:
                F = F.reshape(self.n_bearings, 2)
            except ValueError:
                raise ValueError(
                    f"{type(self).__name__}.step: F must have shape ({self.n_bearings}, 2) "
                    f"[N] (film forces Fx, Fy per bearing; got shape {F.shape}); pass "
                    f"np.array([[Fx_1, Fy_1], [Fx_2, Fy_2]])") from None
        if not np.all(np.isfinite(F)):
            raise ValueError(f"{type(self).__name__}.step: F must be finite (got {F.tolist()})")
        return F

    # ------------------------------------------------------------------ API
    def initial_state(self) -> np.ndarray:
        """Initial condition: all velocities 0; bearing stations at ``journal_q0``; the
        other dofs at the static equilibrium under gravity with the bearing stations held
        there (``K_ii q_i = f_g,i - K_ib q_b``, supports excluded) if ``initial_sag``,
        else 0."""
        n = self.n_dof
        q = np.zeros(n)
        b = self.bearing_dofs.reshape(-1)
        q[b] = self._journal_q0.reshape(-1)
        if self._initial_sag:
            i = np.setdiff1d(np.arange(n), b)
            K = self.K.copy()
            for j, (ix, iy) in enumerate(self.bearing_dofs):
                K[np.ix_([ix, iy], [ix, iy])] -= self._supports_k[j]
            q[i] = np.linalg.solve(K[np.ix_(i, i)], self.f_g[i] - K[np.ix_(i, b)] @ q[b])
        return np.concatenate([q, np.zeros(n)])

    def initialize(self):
        """Set t = t0 and the state to :meth:`initial_state`; outputs become valid."""
        self.t = self.t0
        self.s = self.initial_state()
        self._initialized = True
        self._outputs = None

    def n_substeps(self, dt: float) -> int:
        """Number of internal trapezoidal sub-steps used for a macro step dt."""
        n = self._nsub_cache.get(dt)
        if n is None:
            want = self.omega_max * dt / self.max_phase_per_substep - 1e-12
            if not want <= MAX_SUBSTEPS:        # also NaN; 1e300 sub-steps hung, or failed in numba
                raise ValueError(
                    f"{type(self).__name__}: a macro step of {dt:g} s needs {want:.3g} internal sub-steps "
                    f"(highest natural frequency {self.omega_max:.4g} rad/s, max_phase_per_substep = "
                    f"{self.max_phase_per_substep:g} rad), more than {MAX_SUBSTEPS}; use a smaller macro "
                    "step or a larger max_phase_per_substep (0.25 is a good value)")
            n = max(1, int(math.ceil(want)))
            self._nsub_cache[dt] = n
        return n

    def step(self, dt: float, F, K=None, C=None) -> None:
        """Advance from t to t + dt with the film forces F (n_bearings, 2) held constant.

        Optional K, C (n_bearings, 2, 2) [N/m], [N s/m]: film coefficients for
        interface-Jacobian coupling, F_i(t) = F_i - K_i (r_i(t) - r_i(t0)) - C_i (v_i(t)
        - v_i(t0)) integrated implicitly (rotor_fmu/interface.py); None/0: plain step."""
        if not self._initialized:
            raise RuntimeError(f"{type(self).__name__}.step called before initialize(); "
                               "call initialize() first")
        if K is not None or C is not None:
            from .interface import step_with_interface_jacobian
            if step_with_interface_jacobian(self, dt, F, K, C):
                return
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"{type(self).__name__}.step: dt must be > 0 and finite [s] (got {dt!r})")
        F = self._check_F(F)
        n = self.n_dof
        nsub = self.n_substeps(dt)
        h = dt / nsub
        fF = self._Mifg + self._MiB @ F.reshape(-1)
        if _kernel is None:
            q, v = _numpy_substeps(self, self.s[:n], self.s[n:], self.t, h, nsub, fF)
        else:
            q, v = _kernel(self.s[:n], self.s[n:], self.t, h, nsub, fF, *self._drive_tab,
                           self._me, self._ph, self._MiU, self._MiK, self._MiKc, self._MiKa,
                           self._MiC, self._MiG)
        self.s = np.concatenate([q, v])
        self.t = self.t + dt
        if not np.all(np.isfinite(self.s)):
            raise FloatingPointError(
                f"{type(self).__name__}.step: state became non-finite at t={self.t:.6g} s "
                f"(film forces {F.tolist()}); check the film forces and dt")
        self._outputs = None

    def _step_lstable(self, dt: float, F, nsub: int) -> None:
        """Advance from t to t + dt with an L-stable scheme instead of the trapezoidal rule.

        Used by the interface-Jacobian step when a near-contact film makes the step stiff
        (rotor_fmu/interface.py); it integrates the CURRENT matrices (``_MiK``, ``_MiC``,
        possibly the augmented ones swapped in by the caller) in first-order form
        ``x = [q, v]``, ``x' = A x + b(t)``::

            A = [[0, I], [-A_K, -A_C]],   b(t) = [0; M^-1 (f_g + B F) + M^-1 f_unb(t)]

        with ``A_K = M^-1 (K + Omega Kc + alpha Ka)``, ``A_C = M^-1 (C + Omega G)`` frozen
        at the macro step's mid time like :func:`_numpy_substeps` (exact mid-step speed,
        no ``omega_quantum`` rounding) and the unbalance at the stage times.

        Scheme: the 2-stage, second-order, L-stable, stiffly accurate SDIRK of Alexander
        (1977, "Diagonally implicit Runge-Kutta methods for stiff O.D.E.'s", SIAM J. Numer.
        Anal. 14(6)); Hairer & Wanner, "Solving Ordinary Differential Equations II",
        sec. IV.6 (SDIRK methods)::

            gamma = 1 - 1/sqrt(2);  c = [gamma, 1];  A_rk = [[gamma, 0], [1 - gamma, gamma]];
            b_rk = [1 - gamma, gamma]

        on ``nsub`` equal sub-steps h = dt / nsub: stage i solves
        ``(I - h gamma A) X_i = x_n + h sum_{j<i} a_ij K_j + h gamma b(t_n + c_i h)`` with
        the stage derivative ``K_1 = A X_1 + b_1 = (X_1 - x_n) / (h gamma)`` and
        ``x_{n+1} = X_2`` (stiffly accurate).  Its stability function R(z) = (1 + (1 - 2 gamma) z) /
        (1 - gamma z)^2 -> 0 for z -> -inf, so overdamped film modes (h d / m >> 1) are
        damped out within a sub-step (their quasi-static limit) instead of ringing as
        with the trapezoidal rule (R -> -1).  One LU of the 2n x 2n matrix per call,
        two triangular solves per sub-step.  On a non-finite result FloatingPointError
        is raised and the state is left unchanged.
        """
        if not self._initialized:
            raise RuntimeError(f"{type(self).__name__}.step called before initialize(); "
                               "call initialize() first")
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"{type(self).__name__}.step: dt must be > 0 and finite [s] (got {dt!r})")
        F = self._check_F(F)
        nsub = int(nsub)
        if nsub < 1:
            raise ValueError(f"{type(self).__name__}._step_lstable: nsub must be >= 1 (got {nsub})")
        n = self.n_dof
        h = dt / nsub
        gam = 1.0 - 1.0 / math.sqrt(2.0)
        hg = h * gam
        t0 = self.t
        if self._speed_dependent:
            w, a, _ = _drive_eval_py(t0 + 0.5 * dt, *self._drive_tab)
        else:
            w, a = 0.0, 0.0
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = self._eye
        A[n:, :n] = -(self._MiK + w * self._MiKc + a * self._MiKa)
        A[n:, n:] = -(self._MiC + w * self._MiG)
        lu = sla.lu_factor(np.eye(2 * n) - hg * A, check_finite=False)
        fF = self._Mifg + self._MiB @ F.reshape(-1)
        # accelerations at the stage times t0 + k h + c_i h, shape (nsub, 2, n)
        ts = t0 + h * (np.arange(nsub)[:, None] + np.array([gam, 1.0])).reshape(-1)
        fs = (self._unbalance_acc_many(ts) + fF).reshape(nsub, 2, n)
        c21 = (1.0 - gam) / gam                  # h a_21 K_1 = c21 (X_1 - x_n)
        x = self.s.copy()
        for k in range(nsub):
            b1, b2 = fs[k]
            r = x.copy()
            r[n:] += hg * b1
            X1 = sla.lu_solve(lu, r, check_finite=False)
            # stage 2: x_n + h a_21 K_1 + h gamma b_2, with K_1 = (X_1 - x_n) / (h gamma)
            # from stage 1 (no product with the stiff A)
            r = x + c21 * (X1 - x)
            r[n:] += hg * b2
            x = sla.lu_solve(lu, r, check_finite=False)
        if not np.all(np.isfinite(x)):
            raise FloatingPointError(
                f"{type(self).__name__}.step (L-stable): state became non-finite at "
                f"t={t0 + dt:.6g} s (film forces {F.tolist()}); check the film forces, "
                "coefficients and dt")
        self.s = x
        self.t = t0 + dt
        self._outputs = None

    @property
    def outputs(self) -> dict:
        """Outputs at the current time (dict name -> float, SI): x_i, y_i, vx_i, vy_i per
        bearing station i = 1.., omega [rad/s], angle [rad], alpha [rad/s^2], extras."""
        if self._outputs is None:
            self._update_outputs()
        return self._outputs

    def _update_outputs(self):
        sl = self.s.tolist()
        out = {name: sl[k] for name, k in self._out_index}
        w, al, ang = _drive_eval_py(self.t, *self._drive_tab)
        out["omega"] = float(w)
        out["angle"] = float(ang)
        out["alpha"] = float(al)
        self._outputs = out

    def get_state(self) -> dict:
        """Copy of the complete state: {"t": float, "s": array (2 n_dof,)}."""
        return {"t": float(self.t), "s": self.s.copy(), "initialized": self._initialized}

    def set_state(self, state: dict) -> None:
        """Restore a state from :meth:`get_state` exactly (outputs are recomputed)."""
        s = np.asarray(state["s"], dtype=float)
        if s.shape != self.s.shape:
            raise ValueError(f"{type(self).__name__}.set_state: 's' must have shape "
                             f"{self.s.shape} (got {s.shape}); pass a dict from get_state()")
        self.t = float(state["t"])
        self.s = s.copy()
        self._initialized = bool(state.get("initialized", True))
        self._outputs = None

    # ------------------------------------------------ first-order form (monolithic)
    def state_vector(self) -> np.ndarray:
        """Copy of the current first-order state s = [q, v] (2 n_dof,)."""
        return self.s.copy()

    def rhs(self, t: float, s, F) -> np.ndarray:
        """ds/dt of the first-order form at time t, state s, film forces F (n_bearings, 2)."""
        n = self.n_dof
        s = np.asarray(s, float)
        q, v = s[:n], s[n:]
        w = self.drive.omega(t)
        al = self.drive.alpha(t)
        F = np.asarray(F, float).reshape(-1)
        a = (self._Mifg + self._MiB @ F + self._unbalance_acc(t)
             - (self._MiK + w * self._MiKc + al * self._MiKa) @ q
             - (self._MiC + w * self._MiG) @ v)
        return np.concatenate([v, a])

    def jacobian(self, t: float):
        """(ds/dt)/ds (2n x 2n) and (ds/dt)/dF (2n x 2 n_bearings) at time t (linear model)."""
        n = self.n_dof
        w = self.drive.omega(t)
        al = self.drive.alpha(t)
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:, :n] = -(self._MiK + w * self._MiKc + al * self._MiKa)
        J[n:, n:] = -(self._MiC + w * self._MiG)
        JF = np.zeros((2 * n, 2 * self.n_bearings))
        JF[n:] = self._MiB
        return J, JF

    def journal_kinematics(self, t: float, s) -> np.ndarray:
        """Bearing-station kinematics (n_bearings, 4): [x, y, vx, vy] from state s."""
        n = self.n_dof
        s = np.asarray(s, float)
        bd = self.bearing_dofs
        return np.stack([s[bd[:, 0]], s[bd[:, 1]], s[n + bd[:, 0]], s[n + bd[:, 1]]], axis=1)

    # ------------------------------------------------------------ linear analysis
    def system_matrices(self, omega: float, alpha: float = 0.0):
        """(M, C + omega G, K + omega Kc + alpha Ka) at a constant speed (incl. supports)."""
        return (self.M.copy(), self.C + omega * self.G,
                self.K + omega * self.Kc + alpha * self.Ka)

    def energy(self, s=None) -> float:
        """Mechanical energy v'Mv/2 + q'Kq/2 [J] (no gravity potential)."""
        s = self.s if s is None else np.asarray(s, float)
        n = self.n_dof
        q, v = s[:n], s[n:]
        return float(0.5 * v @ self.M @ v + 0.5 * q @ self.K @ q)
