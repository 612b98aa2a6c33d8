"""Interface-Jacobian (linearly-implicit) coupling on the rotor side.

Problem: a journal of mass ``m`` on a film with squeeze damping ``d`` coupled
explicitly (forces held over the macro step ``H``) is stable only for
``H < ~2 m / d`` (a few microseconds for the paper's rotor, see
``compare/ci_jeffcott.yaml``).

Fix (Kuebler & Schiehlen 2000, "Two methods of simulator coupling", Math. Comp.
Model. Dyn. Syst. 6(2); Sicklinger et al. 2014, "Interface Jacobian-based
co-simulation", IJNME 98(6); Schweizer & Lu 2015, "Stabilized index-2
co-simulation approach for solver coupling with algebraic constraints" /
"semi-implicit co-simulation approach", Multibody Syst. Dyn.): the bearing also
outputs its film coefficients at the current state,
``K = -dF/dr``, ``C = -dF/dv`` (2x2, r = (x, y), v = (vx, vy)), and the rotor
applies over its step ``[t0, t0 + H]`` at station i the force::

    F_i(t) = F_i,in - K_i (r_i(t) - r_i(t0)) - C_i (v_i(t) - v_i(t0))

The correction is linear, so the rotor's implicit (trapezoidal) integrator takes
it exactly: ``K_i``, ``C_i`` are added to the station dofs' stiffness and damping
for the step, and the constant force becomes ``F_in + K r(t0) + C v(t0)``. The
first-order Taylor model of the film is exact to first order in the deviation
over the step, so the converged co-simulation answer is unchanged (the
correction vanishes as H -> 0); the explicit stability limit of the stiff
film/journal loop is removed because the film's stiffness and damping now act
implicitly inside the rotor's A-stable integrator.

Sub-steps: the rotor's trapezoidal rule is A-stable but not L-stable; a film
damping rate ``lambda = d / m`` (~7e5 1/s) with ``h lambda >> 2`` would leave a
slowly decaying, sign-alternating velocity error (amplification
``(1 - h lambda / 2) / (1 + h lambda / 2) -> -1``).  We therefore use at least
``ceil(H rho / 2)`` sub-steps, ``rho = max(||M^-1 C_aug||_2, ||M^-1 K_aug||_2^(1/2))``
(an upper bound of the fast eigenvalues), which keeps the amplification of the
fastest damped mode in [0, 1] (no ringing); the structural bound
(``max_phase_per_substep``) still applies.

Dissipative damping: the symmetric part of each station's ``C`` is projected onto the
positive semi-definite matrices (negative eigenvalues set to 0, skew part kept) before
it is used (:func:`dissipative_damping`).  A physical film dissipates, but the
finite-difference half-Sommerfeld coefficients near contact are not smooth (40 x 40,
eps >= ~0.988: the pressure spike at the minimum gap spans about one cell; a 0.1 %
change of eps moved ``cyy`` 9e6 -> 3e6 -> 1.2e7 N s/m) and their symmetric part is
then sometimes indefinite (down to -4e5 N s/m at eps 0.988, 66 Hz, measured). Held
over a macro step, a negative damping ``-d`` on a ~0.26 kg journal is an exponential
instability at ~d / m ~ 1e6 1/s, i.e. a factor ~e^165 per 0.1 ms step in the linear
model (any integrator): the turbocharger mass-conserving run-ups blew up there
(docs/runups.md section 4).  The correction only has to stabilize, so changing C
keeps the scheme consistent; a positive semi-definite C is used unchanged (bit-identical).

L-stable path near contact: the film coefficients grow without bound near the shell
(cyy ~1e8-1e9 N s/m at eps > ~0.995), and ``ceil(H rho / 2)`` trapezoidal sub-steps with
them (~3e4 per 0.1 ms at 1e8 N s/m on the turbocharger; the shipped free-to-air run-up
used to stop at 5.1867 s asking for 5.02e4).  Above :data:`LSTABLE_SWITCH` needed
sub-steps the step therefore uses :meth:`LinearRotor._step_lstable` instead: Alexander's
2-stage L-stable SDIRK (second order, stiffly accurate) on
``max(rotor.n_substeps(H), ceil(H ||M^-1 K_aug||_2^(1/2) / 2))`` sub-steps, i.e. the
structure's and the film stiffness's oscillations are resolved as before, while the
overdamped film modes (rate ~ d / m, h d / m >> 1) are damped out by L-stability -- their
physical quasi-static limit -- instead of by sub-steps.  The rest of the coupling (augmented
matrices, ``F_eff``, dissipative projection) is the same.  Below the switch the trapezoidal
path is unchanged (bit-identical).  This only removes the cost barrier; what happens at
the shell is the bearing model's business (its optional asperity contact, ``contact = 1``,
bearing_fmu/contact.py; without it the bearing FMU refuses eps >= 1).  :class:`StiffFilmError`
(a FloatingPointError: the rotor FMU returns fmi2Discard with its message) is raised only
when the augmented matrices or the L-stable result are not finite (it used to be raised
above 50 000 trapezoidal sub-steps).

With K = C = 0 the rotor's plain ``step`` is used unchanged.

Compiled step: :func:`step_with_interface_jacobian` first tries :mod:`rotor_fmu.ij_kernel`,
the same scheme and the same discrete decisions (sub-step count, projection) in one numba
call, ~10x cheaper on the Jeffcott rotor; it leaves every step it cannot decide exactly as
this code does (and the L-stable path, bad input, rotors above :data:`FAST_MAX_DOF`) to the
numpy form below. Its states differ from the numpy form's by round-off only (another
floating-point order: LU solves instead of the explicit inverse and its powers).
"""

from __future__ import annotations

import math
import os

import numpy as np

from . import ij_kernel as _kernel

FAST = _kernel.kernel is not None and os.environ.get("ROTORCOSIM_ROTOR_KERNEL", "").strip().lower() != "numpy"
"""Use the compiled step (:mod:`rotor_fmu.ij_kernel`, same scheme to round-off); off without numba
or with ``ROTORCOSIM_ROTOR_KERNEL=numpy`` (every step then the numpy form below)."""

FAST_MAX_DOF = 48
"""Largest rotor (n_dof) the compiled step takes: its 2-norms use Jacobi rotations, O(n^3) per
sweep, which beat LAPACK's SVD for the Jeffcott rotor (6 dofs) and the reduced turbocharger
(~18) but not for a full finite-element model (124 dofs: the numpy form then steps)."""

LSTABLE_SWITCH = 2000
"""Trapezoidal sub-steps ``ceil(H rho / 2)`` above which a macro step uses the L-stable path.

Why 2000: every step that worked before and needs at most this many sub-steps stays
bit-identical (same trapezoidal code, same sub-step count), so the shipped runs that worked
before are unchanged as long as their need stays below it.  On the turbocharger at 0.1 ms,
need ~ 3.4e-4 x (station damping [N s/m]), so the switch sits at ~6e6 N s/m; ~1400
sub-steps per 50 us (~2800 per 0.1 ms) were seen at eps 0.99 (docs/runups.md section 4), so
(estimated, not measured per run) the runs change only beyond eps ~0.98, past the whirl
onsets the results are about.  The trapezoidal cost grows linearly with C / m, while the
L-stable path needs O(omega_max H + H ||M^-1 K_aug||^(1/2)) sub-steps, a few dozen
(measured, turbocharger, 0.1 ms steps: trapezoidal 14.7 ms/step at need 1971 and 75 ms/step
at need 3.4e4 (C = 1e8 N s/m); L-stable 0.6-0.8 ms/step, 31-44 sub-steps)."""

class StiffFilmError(FloatingPointError):
    """The film coefficients make the rotor step non-finite (overflowing augmented matrices
    or a non-finite L-stable result)."""


def as_station_coeffs(a, n_bearings: int, name: str) -> np.ndarray:
    """Coefficients as an array (n_bearings, 2, 2); None -> zeros."""
    if a is None:
        return np.zeros((n_bearings, 2, 2))
    a = np.asarray(a, dtype=float)
    try:
        a = a.reshape(n_bearings, 2, 2)
    except ValueError:
        raise ValueError(f"interface Jacobian {name}: expected shape ({n_bearings}, 2, 2) "
                         f"[{'N/m' if name == 'K' else 'N s/m'}] (got {a.shape})") from None
    if not np.all(np.isfinite(a)):
        raise ValueError(f"interface Jacobian {name} must be finite (got {a.tolist()})")
    return a


def dissipative_damping(C: np.ndarray) -> np.ndarray:
    """Station damping matrices (n_bearings, 2, 2) with the symmetric part of each
    projected onto the positive semi-definite cone (eigenvalues < 0 -> 0), the skew
    (gyroscopic-like, non-dissipative) part kept; ``C`` itself is returned when every
    symmetric part is already positive semi-definite (see the module doc)."""
    S = 0.5 * (C + np.swapaxes(C, -1, -2))
    lam, Q = np.linalg.eigh(S)
    if not np.any(lam < 0.0):
        return C
    out = C.copy()
    for i in np.nonzero(np.any(lam < 0.0, axis=-1))[0]:
        Si = (Q[i] * np.maximum(lam[i], 0.0)) @ Q[i].T
        out[i] = Si + (C[i] - S[i])
    return out


def augmented(rotor, F, K, C):
    """(MiK_aug, MiC_aug, F_eff) of the linearly-implicit step (see module doc)."""
    n = rotor.n_dof
    q, v = rotor.s[:n], rotor.s[n:]
    F = np.asarray(F, dtype=float).reshape(rotor.n_bearings, 2)
    Kb = np.zeros((2 * rotor.n_bearings, 2 * rotor.n_bearings))
    Cb = np.zeros_like(Kb)
    F_eff = F.copy()
    for i, (ix, iy) in enumerate(rotor.bearing_dofs):
        sl = slice(2 * i, 2 * i + 2)
        Kb[sl, sl] = K[i]
        Cb[sl, sl] = C[i]
        r0 = np.array([q[ix], q[iy]])
        v0 = np.array([v[ix], v[iy]])
        F_eff[i] += K[i] @ r0 + C[i] @ v0
    MiK = rotor._MiK + rotor._MiB @ Kb @ rotor.B.T
    MiC = rotor._MiC + rotor._MiB @ Cb @ rotor.B.T
    return MiK, MiC, F_eff


def step_with_interface_jacobian(rotor, dt: float, F, K=None, C=None) -> bool:
    """Linearly-implicit rotor step; returns False (nothing done) when K = C = 0.

    ``rotor`` is a :class:`rotor_fmu.linear_rotor.LinearRotor` (Jeffcott or
    turbocharger). The augmented matrices are swapped in for this one call (restored
    afterwards, also on errors); up to :data:`LSTABLE_SWITCH` needed sub-steps the
    rotor's own ``step`` (trapezoidal) integrates, above it ``_step_lstable`` (L-stable
    SDIRK, see the module doc).
    """
    if FAST and K is not None and C is not None and _fast_step(rotor, dt, F, K, C):
        return True
    nb = rotor.n_bearings
    K = as_station_coeffs(K, nb, "K")
    C = as_station_coeffs(C, nb, "C")
    if not (np.any(K) or np.any(C)):
        return False
    C = dissipative_damping(C)
    if not (dt > 0.0 and math.isfinite(dt)):
        raise ValueError(f"{type(rotor).__name__}.step: dt must be > 0 and finite [s] (got {dt!r})")
    F = rotor._check_F(F)
    MiK, MiC, F_eff = augmented(rotor, F, K, C)
    step_linear_implicit(rotor, dt, MiK, MiC, F_eff, K, C)
    return True


def _fast_step(rotor, dt: float, F, K, C) -> bool:
    """The compiled step (:mod:`rotor_fmu.ij_kernel`); False when the numpy form must do this
    step (all coefficients 0, a decision the kernel leaves to it, bad input: it raises)."""
    if rotor.n_dof > FAST_MAX_DOF:
        return False
    nb = rotor.n_bearings
    try:
        F = np.ascontiguousarray(F, dtype=float).reshape(nb, 2)
        K = np.ascontiguousarray(K, dtype=float).reshape(nb, 2, 2)
        C = np.ascontiguousarray(C, dtype=float).reshape(nb, 2, 2)
    except ValueError:
        return False
    if not (dt > 0.0 and math.isfinite(dt)) or not (K.any() or C.any()):
        return False
    out = np.empty_like(rotor.s)
    code, _ = _kernel.kernel(
        rotor.s, rotor.t, dt, rotor.n_substeps(dt), F, K, C, rotor.bearing_dofs, rotor._MiK, rotor._MiC,
        rotor._MiG, rotor._MiKc, rotor._MiKa, rotor._MiB, rotor._Mifg, rotor._MiU, rotor._me, rotor._ph,
        *rotor._drive_tab, rotor.omega_quantum, rotor._speed_dependent, float(LSTABLE_SWITCH), out)
    if code != _kernel.DONE:
        return False
    rotor.s = out
    rotor.t = rotor.t + dt
    rotor._outputs = None
    return True


def step_linear_implicit(rotor, dt: float, MiK, MiC, F_eff, K, C) -> None:
    """One macro step of ``rotor`` with the augmented matrices ``MiK``, ``MiC`` swapped in and the
    station forces ``F_eff`` held: trapezoidal sub-steps up to :data:`LSTABLE_SWITCH`, else the
    L-stable SDIRK (module doc). ``K``, ``C`` (stations, 2, 2) only name the coefficients in errors."""
    if not (np.all(np.isfinite(MiK)) and np.all(np.isfinite(MiC)) and np.all(np.isfinite(F_eff))):
        raise StiffFilmError(
            f"{type(rotor).__name__}: the film coefficients give non-finite rotor matrices "
            f"(overflow; largest station damping {float(np.max(np.abs(C))):.3g} N s/m, "
            f"largest station stiffness {float(np.max(np.abs(K))):.3g} N/m)")
    rho_k = math.sqrt(np.linalg.norm(MiK, 2))
    rho = max(np.linalg.norm(MiC, 2), rho_k)
    need = dt * rho / 2.0
    if need <= LSTABLE_SWITCH:
        # trapezoidal sub-steps (unchanged, bit-identical to the code before the L-stable path)
        nsub = max(rotor.n_substeps(dt), int(math.ceil(need - 1e-12)))
        saved = (rotor._MiK, rotor._MiC, rotor._nsub_cache)
        try:
            rotor._MiK, rotor._MiC, rotor._nsub_cache = MiK, MiC, {dt: nsub}
            rotor.step(dt, F_eff)
        finally:
            rotor._MiK, rotor._MiC, rotor._nsub_cache = saved
        return
    # stiff film: L-stable SDIRK; sub-steps resolve the structure and the film stiffness,
    # the overdamped film modes are damped by L-stability (see the module doc)
    nsub = max(rotor.n_substeps(dt), int(math.ceil(dt * rho_k / 2.0 - 1e-12)))
    saved = (rotor._MiK, rotor._MiC)
    try:
        rotor._MiK, rotor._MiC = MiK, MiC
        rotor._step_lstable(dt, F_eff, nsub)
    except FloatingPointError as exc:
        raise StiffFilmError(
            f"{exc} (L-stable interface-Jacobian step, {nsub} sub-steps, ||M^-1 C_aug|| = "
            f"{rho:.3g} 1/s, largest station damping {float(np.max(np.abs(C))):.3g} N s/m)") from exc
    finally:
        rotor._MiK, rotor._MiC = saved
