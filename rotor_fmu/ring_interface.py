"""Interface-Jacobian coupling through a floating ring: the ring's translation inside the rotor's step.

Problem (docs/floating-ring.md, "Why the run-ups did not whirl"): with the plain
interface-Jacobian step (:mod:`rotor_fmu.interface`) the rotor applies over its macro step
``[t_n, t_n + H]`` the inner-film force ``F_n - K_i (r_j(t) - r_j,n) - C_i (v_j(t) - v_j,n)``,
which holds the ring where it was at ``t_n``. The light ring, on an inner film about ten
times stiffer than the outer one at the whirl frequency, moves with the journal within the
step; the missing ``K_i (r_r(t) - r_r,n)`` acts on the journal like a delayed cross-coupled
stiffness, an artificial direct damping of about ``K_i,xy H / 2``. The co-simulation is then
first order in H with a large constant: growth rate of the outer-film whirl about
``-6e5 H`` 1/s off, i.e. a whirl threshold about ``3e6 H`` Hz too high (300 Hz at 0.1 ms).

Fix: the rotor's linearly-implicit step integrates the journals together with a linear
model of each ring (mass ``m_r``, the inner film's ``K_i, C_i`` between journal and ring, the
outer film's ``K_o, C_o`` between ring and housing), linearised at the start of the step:

    journal:  F_j(t) = F_j,n - K_i (dr_j - dr_r) - C_i (dv_j - dv_r)
    ring:     m_r a_r(t) = A_n + K_i (dr_j - dr_r) + C_i (dv_j - dv_r) - K_o dr_r - C_o dv_r

with ``d. = .(t) - .(t_n)`` and ``A_n = m_r a_r,n = -F_j,n + F_o,n + m_r g`` the ring's net
force at ``t_n`` (the bearing FMU outputs ``ax_ring, ay_ring``). This is the interface-Jacobian
idea of Kuebler & Schiehlen (2000) and Sicklinger et al. (2014) (the coupled subsystem's
linearised response taken into the implicit step) applied to the ring's states rather than
condensed into the journal's coefficients: the ring's dynamics are then implicit in the
rotor's step, as the journal's own film is, and the correction vanishes as H -> 0 (same
converged answer). The ring's motion predicted by the rotor is discarded; the bearing FMU
advances its own ring with both nonlinear films, as before.

Implementation: an augmented :class:`~rotor_fmu.linear_rotor.LinearRotor` with two extra
dofs per ring (mass ``m_r``, no structural stiffness or damping; the journals and rings are
its bearing stations) is built once per rotor and ring masses; per step the station
coefficient blocks ``[[K_i, -K_i], [-K_i, K_i + K_o]]`` (and C alike, each film's symmetric
damping projected as in :func:`rotor_fmu.interface.dissipative_damping`) are added for the
step, the state is copied in, and the augmented rotor takes the same trapezoidal or L-stable
sub-steps as the plain interface-Jacobian step; its journal state is copied back.
"""

from __future__ import annotations

import numpy as np

from .interface import as_station_coeffs, dissipative_damping, step_linear_implicit


def _augmented_rotor(rotor, m_ring: np.ndarray):
    """The rotor with two translational dofs per ring (stations with ``m_ring > 0``) appended,
    cached on ``rotor``; its bearing stations are the journals, then the rings."""
    # the rotor's matrices change only in _precompute, which makes a new _MiK: key on it by identity
    # (no copy of the matrices per step)
    masses_key = tuple(m_ring.tolist())
    cached = getattr(rotor, "_ring_aug", None)
    if cached is not None and cached[0] == masses_key and cached[1] is rotor._MiK:
        return cached[2]
    from .linear_rotor import LinearRotor

    n = rotor.n_dof
    masses = m_ring[m_ring > 0]
    N = n + 2 * masses.size

    def pad(A, diag=None):
        out = np.zeros((N, N))
        out[:n, :n] = A
        if diag is not None:
            out[n:, n:] = np.diag(diag)
        return out

    ring_dofs = np.arange(n, N).reshape(-1, 2)
    aug = LinearRotor.__new__(LinearRotor)
    aug._setup(M=pad(rotor.M, np.repeat(masses, 2)), C=pad(rotor.C), G=pad(rotor.G), K=pad(rotor.K),
               Kc=pad(rotor.Kc), Ka=pad(rotor.Ka),
               bearing_dofs=np.vstack([rotor.bearing_dofs, ring_dofs]), unbalances=rotor.unbalances,
               f_g=np.concatenate([rotor.f_g, np.zeros(N - n)]), drive=rotor.drive, t0=rotor.t0,
               max_phase_per_substep=rotor.max_phase_per_substep, extra_outputs={},
               initial_sag=False, omega_quantum=rotor.omega_quantum)
    aug._initialized = True
    rotor._ring_aug = (masses_key, rotor._MiK, aug)
    return aug


def _ring_arrays(ring: dict, nb: int, name: str):
    m = np.asarray(ring["m"], dtype=float).reshape(nb)
    rs = np.asarray(ring["s"], dtype=float).reshape(nb, 4)
    a = np.asarray(ring["a"], dtype=float).reshape(nb, 2)
    if not (np.all(m >= 0) and np.any(m > 0) and np.all(np.isfinite(m)) and np.all(np.isfinite(rs))
            and np.all(np.isfinite(a))):
        raise ValueError(f"{name}.step: ring inputs must be finite, m_ring >= 0 and one m_ring > 0 "
                         f"(got m_ring {m.tolist()}, ring state {rs.tolist()}, acceleration {a.tolist()})")
    return m, rs, a


def step_with_ring_interface(rotor, dt: float, F, K, C, ring: dict) -> None:
    """Linearly-implicit rotor step with the rings' translation integrated alongside (module doc).

    ``F`` (n_bearings, 2) [N] film force on each journal at t_n; ``K``, ``C``
    (n_bearings, 2, 2) the (inner) films' coefficients, in journal-minus-ring coordinates at
    a ring station; ``ring``: ``m`` (n_bearings,) [kg] ring masses (0: a plain bearing at
    that station, stepped as in :func:`rotor_fmu.interface.step_with_interface_jacobian`),
    ``s`` (n_bearings, 4) ring x, y [m], vx, vy [m/s] at t_n, ``a`` (n_bearings, 2)
    [m/s^2] ring accelerations at t_n, ``Ko``, ``Co`` (n_bearings, 2, 2) the outer films'
    coefficients. The values at stations with m = 0 are not used.
    """
    nb, n = rotor.n_bearings, rotor.n_dof
    if not (dt > 0.0 and np.isfinite(dt)):
        raise ValueError(f"{type(rotor).__name__}.step: dt must be > 0 and finite [s] (got {dt!r})")
    Ki = as_station_coeffs(K, nb, "K")
    Ci = dissipative_damping(as_station_coeffs(C, nb, "C"))
    Ko = as_station_coeffs(ring["Ko"], nb, "K_outer")
    Co = dissipative_damping(as_station_coeffs(ring["Co"], nb, "C_outer"))
    m, rs, a = _ring_arrays(ring, nb, type(rotor).__name__)
    F = rotor._check_F(F)
    aug = _augmented_rotor(rotor, m)
    q, v = rotor.s[:n], rotor.s[n:]
    jd = rotor.bearing_dofs
    rj = np.stack([q[jd[:, 0]], q[jd[:, 1]]], axis=1)
    vj = np.stack([v[jd[:, 0]], v[jd[:, 1]]], axis=1)
    rings = np.nonzero(m > 0)[0]
    S = nb + rings.size             # stations of the augmented rotor: journals, then rings
    Kb = np.zeros((2 * S, 2 * S))
    Cb = np.zeros_like(Kb)
    F_eff = F + np.einsum("iab,ib->ia", Ki, rj) + np.einsum("iab,ib->ia", Ci, vj)   # plain stations
    F_eff = np.vstack([F_eff, np.zeros((rings.size, 2))])
    for i in range(nb):
        j = slice(2 * i, 2 * i + 2)
        Kb[j, j], Cb[j, j] = Ki[i], Ci[i]
    for k, i in enumerate(rings):
        j, r = slice(2 * i, 2 * i + 2), slice(2 * (nb + k), 2 * (nb + k) + 2)
        for blk, Ai, Ao in ((Kb, Ki[i], Ko[i]), (Cb, Ci[i], Co[i])):
            blk[j, r] = -Ai
            blk[r, j] = -Ai
            blk[r, r] = Ai + Ao
        rr, vr = rs[i, :2], rs[i, 2:]
        rel = Ki[i] @ (rj[i] - rr) + Ci[i] @ (vj[i] - vr)
        F_eff[i] = F[i] + rel
        F_eff[nb + k] = m[i] * a[i] - rel + Ko[i] @ rr + Co[i] @ vr
    MiK = aug._MiK + aug._MiB @ Kb @ aug.B.T
    MiC = aug._MiC + aug._MiB @ Cb @ aug.B.T
    aug.t = rotor.t
    aug.s = np.concatenate([q, rs[rings, :2].reshape(-1), v, rs[rings, 2:].reshape(-1)])
    aug._outputs = None
    step_linear_implicit(aug, dt, MiK, MiC, F_eff, np.concatenate([Ki, Ko]), np.concatenate([Ci, Co]))
    N = aug.n_dof
    rotor.s = np.concatenate([aug.s[:n], aug.s[N:N + n]])
    rotor.t = aug.t
    rotor._outputs = None
    if not np.all(np.isfinite(rotor.s)):
        raise FloatingPointError(f"{type(rotor).__name__}.step: state became non-finite at t={rotor.t:.6g} s "
                                 f"(ring interface step, film forces {F.tolist()})")
