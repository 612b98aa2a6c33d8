"""Linear stability of rotors in short (Ocvirk) journal bearings with the pi film.

* :func:`short_bearing_force` - closed-form short-bearing (Ocvirk 1952, NACA TN 2808)
  film force with the half-Sommerfeld (pi-film) condition, including squeeze and whirl
  velocities (Childs 1993, "Turbomachinery Rotordynamics", ch. 3; Vance 1988
  "Rotordynamics of Turbomachinery", ch. 5).  With ``s = eta R L^3 / C^2``, eccentricity
  ratio eps, eccentricity angle psi (from +x, CCW) and the journal spinning at omega::

      F_r = -s [(omega - 2 psi') eps^2 / (1 - eps^2)^2
                + eps' pi (1 + 2 eps^2) / (2 (1 - eps^2)^(5/2))]
      F_t =  s [(omega - 2 psi') pi eps / (4 (1 - eps^2)^(3/2))
                + 2 eps eps' / (1 - eps^2)^2]

  along e_r = (cos psi, sin psi) and e_t = (-sin psi, cos psi).  As usual for these
  closed forms (and for the linearized coefficients), the film is the converging half
  of the gap relative to the line of centres; with squeeze/whirl velocities the true
  positive-pressure region shifts slightly (exact for the static equilibrium).
* :func:`short_bearing_equilibrium` - eccentricity from the load (Ocvirk load
  ``W = s omega eps sqrt(pi^2 (1 - eps^2) + 16 eps^2) / (4 (1 - eps^2)^2)``) and the
  attitude angle ``tan(beta) = pi sqrt(1 - eps^2) / (4 eps)``.
* :func:`short_bearing_coefficients` - linearized stiffness and damping coefficients
  ``K_ij = -dF_i/dx_j``, ``C_ij = -dF_i/dv_j`` (fixed x, y frame) in closed form,
  obtained by differentiating the forces above in the (r, t) frame::

      K_rr = s w A'/C,  K_rt = s w B/(eps C),  K_tr = -s w B'/C,  K_tt = s w A/(eps C)
      C_rr = s Cr/C,    C_rt = -2 s A/(eps C), C_tr = -s Ct/C,    C_tt = 2 s B/(eps C)

  with A = eps^2/(1-eps^2)^2, B = pi eps/(4 (1-eps^2)^1.5),
  Cr = pi (1+2 eps^2)/(2 (1-eps^2)^2.5), Ct = 2 eps/(1-eps^2)^2,
  A' = 2 eps (1+eps^2)/(1-eps^2)^3, B' = pi (1+2 eps^2)/(4 (1-eps^2)^2.5)
  (equivalent to the dimensionless short-bearing coefficients tabulated e.g. in
  Friswell et al. 2010, "Dynamics of Rotating Machines", sec. 5.5).
* :func:`lund_threshold` - Lund's stability threshold of a rigid (or, with a shaft
  stiffness per bearing, Jeffcott-flexible) rotor on linear bearing coefficients
  (Lund 1966, "Self-excited, stationary whirl orbits of a journal in a sleeve bearing",
  PhD thesis RPI; Lund 1974 J. Eng. Ind. 96:509; Childs 1993 sec. 3.6)::

      K_eq = (Kxx Cyy + Kyy Cxx - Kxy Cyx - Kyx Cxy) / (Cxx + Cyy)
      nu^2 = ((K_eq - Kxx)(K_eq - Kyy) - Kxy Kyx) / (Cxx Cyy - Cxy Cyx)
      stable  <=>  m nu^2 < K_eq            (rigid rotor, mass m per bearing)
              <=>  m nu^2 < K_eq k_s / (K_eq + k_s)   (disc on a shaft of stiffness k_s
                                                       per bearing, massless journals)
* :func:`threshold_speed` - eigenvalue-based: the lowest speed at which an eigenvalue
  of the rotor (any :class:`~rotor_fmu.linear_rotor.LinearRotor`) with speed-dependent
  linear bearing coefficients crosses into the right half plane.

Conventions: x horizontal, y up, the journal spins CCW about +z (omega > 0); the film
force acts on the journal.  SI units.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq


def _parts(eps):
    e2 = 1.0 - eps * eps
    A = eps * eps / e2**2
    B = math.pi * eps / (4.0 * e2**1.5)
    Cr = math.pi * (1.0 + 2.0 * eps * eps) / (2.0 * e2**2.5)
    Ct = 2.0 * eps / e2**2
    dA = 2.0 * eps * (1.0 + eps * eps) / e2**3
    dB = math.pi * (1.0 + 2.0 * eps * eps) / (4.0 * e2**2.5)
    return A, B, Cr, Ct, dA, dB


def short_bearing_force(x, y, vx, vy, omega, *, R, L, C, eta):
    """Film force (Fx, Fy) [N] on the journal at (x, y) [m] moving at (vx, vy) [m/s]."""
    e = math.hypot(x, y)
    eps = e / C
    if not eps < 1.0:
        raise ValueError(f"short_bearing_force: eccentricity ratio must be < 1 (got {eps:.4g})")
    if e == 0.0:
        return 0.0, 0.0
    psi = math.atan2(y, x)
    er = (math.cos(psi), math.sin(psi))
    et = (-er[1], er[0])
    eps_d = (vx * er[0] + vy * er[1]) / C
    psi_d = (vx * et[0] + vy * et[1]) / e
    s = eta * R * L**3 / C**2
    A, B, Cr, Ct, _, _ = _parts(eps)
    wr = omega - 2.0 * psi_d
    Fr = -s * (wr * A + eps_d * Cr)
    Ft = s * (wr * B + eps_d * Ct)
    return Fr * er[0] + Ft * et[0], Fr * er[1] + Ft * et[1]


def short_bearing_load(eps, omega, *, R, L, C, eta):
    """Load capacity [N] at eccentricity ratio eps and speed omega [rad/s] (Ocvirk)."""
    s = eta * R * L**3 / C**2
    return s * omega * eps * math.sqrt(math.pi**2 * (1 - eps**2) + 16 * eps**2) / (4 * (1 - eps**2) ** 2)


def short_bearing_equilibrium(load, omega, *, R, L, C, eta):
    """Static equilibrium under a load vector [N] (force the film must supply is -load).

    Returns (eps, psi): eccentricity ratio and the angle of the journal displacement
    from +x (CCW).  For a downward load (0, -W) and CCW rotation the journal sits
    below and to the +x side of the bearing centre (psi = -pi/2 + attitude angle).
    """
    load = np.asarray(load, float)
    W = float(np.hypot(*load))
    if not (W > 0.0 and omega > 0.0):
        raise ValueError(f"short_bearing_equilibrium: need a nonzero load and omega > 0 "
                         f"(got load={load.tolist()}, omega={omega})")
    f = lambda e: short_bearing_load(e, omega, R=R, L=L, C=C, eta=eta) - W
    with np.errstate(over="ignore", invalid="ignore"):     # a capacity beyond float range is just "too large"
        lo, hi = f(1e-12), f(1.0 - 1e-12)
    if not hi >= 0.0:       # the film's capacity s omega ~ eta R L^3 omega / C^2 is too small for the load
        raise ValueError(f"the short-bearing film cannot carry the load {W:.4g} N at {omega / (2 * math.pi):.4g} Hz "
                         f"(eccentricity ratio above 1 - 1e-12): speed, viscosity, radius or length far too small, "
                         f"or clearance far too large, for the load")
    if not lo <= 0.0:       # capacity so large that the eccentricity is below 1e-12 (or not a number)
        raise ValueError(f"the short-bearing film's eccentricity under the load {W:.4g} N at "
                         f"{omega / (2 * math.pi):.4g} Hz is below 1e-12 of the clearance (its load capacity "
                         f"{short_bearing_load(1e-12, omega, R=R, L=L, C=C, eta=eta):.4g} N at that eccentricity "
                         f"already exceeds the load): speed, viscosity, radius or length far too large, or the load "
                         f"far too small")
    eps = brentq(f, 1e-12, 1.0 - 1e-12, xtol=1e-15, rtol=1e-14)
    beta = math.atan2(math.pi * math.sqrt(1 - eps**2), 4 * eps)
    ang_film = math.atan2(-load[1], -load[0])       # direction of the film force
    psi = ang_film + math.pi + beta
    psi = (psi + math.pi) % (2 * math.pi) - math.pi
    return eps, psi


def short_bearing_coefficients(load, omega, *, R, L, C, eta):
    """Linearized (K, C) 2x2 [N/m], [N s/m] in x, y at the static equilibrium under
    ``load`` (force on the journal from the rotor, e.g. (0, -m g)) at speed omega."""
    eps, psi = short_bearing_equilibrium(load, omega, R=R, L=L, C=C, eta=eta)
    s = eta * R * L**3 / C**2
    A, B, Cr, Ct, dA, dB = _parts(eps)
    w = omega
    Krt = np.array([[s * w * dA / C, s * w * B / (eps * C)],
                    [-s * w * dB / C, s * w * A / (eps * C)]])
    Crt = np.array([[s * Cr / C, -2.0 * s * A / (eps * C)],
                    [-s * Ct / C, 2.0 * s * B / (eps * C)]])
    T = np.array([[math.cos(psi), -math.sin(psi)], [math.sin(psi), math.cos(psi)]])  # [e_r e_t]
    return T @ Krt @ T.T, T @ Crt @ T.T


def lund_threshold(K, Cm, m, k_shaft=None):
    """Lund's threshold quantities for linear coefficients K, C (2x2).

    Returns (m_crit, nu): the critical mass per bearing [kg] (rigid rotor; with
    ``k_shaft`` [N/m] per bearing: disc on a flexible shaft with massless journals) and
    the whirl frequency at the threshold nu [rad/s].  The rotor is stable for m < m_crit.
    """
    Kxx, Kxy, Kyx, Kyy = K[0, 0], K[0, 1], K[1, 0], K[1, 1]
    Cxx, Cxy, Cyx, Cyy = Cm[0, 0], Cm[0, 1], Cm[1, 0], Cm[1, 1]
    Keq = (Kxx * Cyy + Kyy * Cxx - Kxy * Cyx - Kyx * Cxy) / (Cxx + Cyy)
    nu2 = ((Keq - Kxx) * (Keq - Kyy) - Kxy * Kyx) / (Cxx * Cyy - Cxy * Cyx)
    if nu2 <= 0.0:
        return math.inf, 0.0
    Kd = Keq if k_shaft is None else Keq * k_shaft / (Keq + k_shaft)
    return Kd / nu2, math.sqrt(nu2)


def lund_threshold_speed(m, *, R, L, C, eta, g=9.81, k_shaft=None, omega_max=2 * math.pi * 5000.0):
    """Threshold speed [rad/s] of a symmetric rotor with mass m per bearing carried by
    gravity (load (0, -m g)) in short bearings; None if stable up to omega_max."""
    def margin(w):
        K, Cm = short_bearing_coefficients((0.0, -m * g), w, R=R, L=L, C=C, eta=eta)
        mc, _ = lund_threshold(K, Cm, m, k_shaft)
        return mc - m
    ws = np.geomspace(2 * math.pi * 1.0, omega_max, 200)
    vals = [margin(w) for w in ws]
    for a, b, fa, fb in zip(ws[:-1], ws[1:], vals[:-1], vals[1:]):
        if fa > 0 and fb <= 0:
            return brentq(margin, a, b, xtol=1e-10, rtol=1e-12)
    return None


def static_bearing_loads(rotor) -> np.ndarray:
    """Forces (n_bearings, 2) [N] the rotor puts on its bearings under gravity (statics
    with the bearing stations held at 0); the film must supply the opposite."""
    n = rotor.n_dof
    b = rotor.bearing_dofs.reshape(-1)
    i = np.setdiff1d(np.arange(n), b)
    K = rotor.K
    qi = np.linalg.solve(K[np.ix_(i, i)], rotor.f_g[i])
    film = K[np.ix_(b, i)] @ qi - rotor.f_g[b]        # film force needed at equilibrium
    return -film.reshape(-1, 2)


def short_bearing_coefficient_fn(rotor, *, R, L, C, eta):
    """omega -> (K, C) arrays (n_bearings, 2, 2) of short bearings under the rotor's
    static gravity loads (for :func:`threshold_speed`)."""
    loads = static_bearing_loads(rotor)

    def fn(omega):
        KC = [short_bearing_coefficients(ld, omega, R=R, L=L, C=C, eta=eta) for ld in loads]
        return np.array([k for k, _ in KC]), np.array([c for _, c in KC])
    return fn


def max_real_eigenvalue(rotor, omega, coeff_fn):
    """(max Re(lambda), Im of that eigenvalue) of the rotor at constant speed omega
    with the bearing coefficients coeff_fn(omega) at its bearing stations."""
    M, Cm, K = rotor.system_matrices(omega)
    Kb, Cb = coeff_fn(omega)
    for j, (ix, iy) in enumerate(rotor.bearing_dofs):
        idx = np.ix_([ix, iy], [ix, iy])
        K[idx] += Kb[j]
        Cm[idx] += Cb[j]
    n = M.shape[0]
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ K, -Mi @ Cm]])
    return rightmost(np.linalg.eigvals(A))


def rightmost(lam) -> tuple[float, float]:
    """(largest real part, |Im| of that eigenvalue) of eigenvalues ``lam``, a real part within
    rounding of zero counted as -that rounding: an undamped mode (a shaft bending mode of a full
    or finely reduced rotor model, ~400 kHz) has Re = +-1e-10 1/s from rounding alone (eps
    |lambda|), and max Re >= 0 then read "unstable at 10 Hz" (or a threshold at any speed)."""
    lam = np.asarray(lam)
    noise = _ROUNDING * float(np.max(np.abs(lam)))
    re = np.where(np.abs(lam.real) <= noise, -noise, lam.real)
    k = int(np.argmax(re))
    return float(re[k]), float(abs(lam.imag[k]))


#: real parts within this many rounding units of the largest |eigenvalue| count as zero (seen: 1.2e-9
#: at |lambda| 2.85e6, 2 units; the crossing mode's real part changes by 1/s over a few Hz)
_ROUNDING = 64 * np.finfo(float).eps


def threshold_speed(rotor, coeff_fn, *, omega_min=2 * math.pi * 1.0,
                    omega_max=2 * math.pi * 2000.0, n_scan=120):
    """Lowest speed [rad/s] in [omega_min, omega_max] at which the rotor with linear
    bearing coefficients ``coeff_fn(omega) -> (K (n_b,2,2), C (n_b,2,2))`` becomes
    unstable (an eigenvalue crosses Re = 0), and the whirl frequency there [rad/s].
    Returns (None, None) if stable over the whole range.  Scan on a geometric grid,
    then Brent on the crossing (:func:`first_crossing`)."""
    return first_crossing(lambda w: max_real_eigenvalue(rotor, w, coeff_fn),
                          np.geomspace(omega_min, omega_max, n_scan))


def first_crossing(max_re, ws):
    """(lowest speed [rad/s] among the increasing speeds ``ws`` and between them where
    ``max_re(omega) -> (max Re(lambda), |Im| of that eigenvalue)`` turns >= 0, |Im| there), or
    (None, None): ``max_re`` at each speed in turn, then :func:`refine_crossing` on the first
    bracket; (ws[0], |Im|) when already >= 0 there."""
    prev_w = ws[0]
    prev = max_re(prev_w)
    if prev[0] >= 0:
        return float(prev_w), prev[1]
    for w in ws[1:]:
        v = max_re(w)
        if v[0] >= 0:
            return refine_crossing(max_re, prev_w, w, known={prev_w: prev, w: v})
        prev_w, prev = w, v
    return None, None


def refine_crossing(max_re, w0, w1, xtol=1e-9, known=None):
    """(speed [rad/s] in [w0, w1] where the largest real part ``max_re(omega)[0]`` crosses 0, the
    |Im| of that eigenvalue there): Brent, to ``xtol`` [rad/s] (1e-9) and 1e-11 of the speed; the signs at w0
    and w1 must differ. The one refinement of every threshold search (also the floating ring's,
    rotor_fmu/floating_ring_stability.py, and ``rotorcosim stability``'s crossings).

    ``known``: ``{omega: max_re(omega)}`` already computed (a scan's values at w0 or w1), which
    Brent takes instead of computing them again; no speed is computed twice (Brent's root is one
    of the speeds it evaluated, so its |Im| costs nothing more)."""
    seen = dict(known or {})

    def once(w):
        if w not in seen:
            seen[w] = max_re(w)
        return seen[w]
    wc = brentq(lambda w: once(w)[0], w0, w1, xtol=xtol, rtol=1e-11)
    return wc, once(wc)[1]


def bearing_radius_for_threshold(make_rotor, f_target, *, B_over_R=1.6, psi=2.8e-3,
                                 eta=0.012, R_lo=0.002, R_hi=0.05):
    """Bearing radius R [m] (with L = B_over_R R, C = psi R) at which the eigenvalue
    threshold of ``make_rotor()`` in short pi-film bearings equals f_target [Hz].

    The threshold decreases with R for the paper's Jeffcott rotor (lighter-loaded,
    softer films); raises ValueError if f_target is not bracketed by [R_lo, R_hi].
    """
    rotor = make_rotor()

    def g(R):
        fn = short_bearing_coefficient_fn(rotor, R=R, L=B_over_R * R, C=psi * R, eta=eta)
        w, _ = threshold_speed(rotor, fn, n_scan=60)
        return (math.inf if w is None else w / (2 * math.pi)) - f_target

    a, b = g(R_lo), g(R_hi)
    if a * b > 0:
        raise ValueError(f"bearing_radius_for_threshold: {f_target} Hz is not reached for R in "
                         f"[{R_lo}, {R_hi}] m (threshold offsets {a:+.1f} Hz, {b:+.1f} Hz); "
                         f"widen R_lo/R_hi")
    return brentq(g, R_lo, R_hi, xtol=1e-7)


def film_system_eigenvalues(rotor, omega, films):
    """Finite eigenvalues [1/s] (largest real part first) of the rotor at constant speed omega
    with a linearised mass-conserving film at each bearing station (``films``: one object per
    station with the arrays of :class:`bearing_fmu.linearize.MCFilmLinear`: ``Js`` (n, n) sparse,
    ``Mdiag`` (n,), ``Rq``, ``Rv`` (n, 2), ``Fu`` (2, n), ``Fq``, ``Fv`` (2, 2), ``contact`` (K_c, C_c)
    or None).

    The descriptor system ``E x' = A x``, ``x = (q, q', u_1, u_2, ...)``: the rotor
    ``M q'' + C q' + K q = sum P_j^T (F_u u_j + F_q P_j q + F_v P_j q')`` and each film
    ``M_j u_j' = -J_s u_j - R_q P_j q - R_v P_j q'`` (:func:`rotor_fmu.film_system.pencil`). Eliminating
    the u_j gives ``det(s^2 M + s C + K + sum P_j^T Z_j(s) P_j) = 0`` with the film impedances Z_j
    (:func:`bearing_fmu.linearize.mc_impedance`), so these are exactly its roots; solved densely
    (all roots: the least damped one cannot be missed; the reference of
    :func:`rotor_fmu.film_system.rightmost`, which finds the least-damped ones ~50 x faster), the
    infinite ones (algebraic full-film cells, M = 0) dropped."""
    from .film_system import eigenvalues_dense
    return eigenvalues_dense(rotor, omega, films)
