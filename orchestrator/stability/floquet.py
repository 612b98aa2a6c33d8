"""The stability of the rotor WITH its unbalance (``rotorcosim stability --unbalance``): at a
constant speed, the rotor's synchronous periodic orbit under its unbalance, and the Floquet
multipliers of the rotor-bearing system linearised along that orbit (docs/analysis.md,
"Stability with the unbalance (Floquet)"; docs/runups.md section 4 for why it matters).

Equations: the rotor FMU's (:mod:`rotor_fmu.linear_rotor`) at a constant speed omega,
``M q'' + (C + omega G) q' + (K + omega Kc) q = f_g + B (F + f_load) + f_unb(t)``, with
``f_unb`` of each unbalance ``m e omega^2 (cos phi, sin phi)``, ``phi = omega t + phase``
(the run's angle origin only shifts the orbit in time), ``F`` each station's nonlinear film
force at its kinematics and ``f_load`` any ``--load``:

* ``film="hs"``: the half-Sommerfeld force of the bearing's own film and grid
  (:func:`bearing_fmu.linearize.hs_force` to round-off, taken with its tangent from the same
  solve; with ``contact = 1`` plus the asperity contact's force
  :func:`bearing_fmu.contact.contact_force`, as the FMU adds it), its tangent (K, C) by
  :func:`bearing_fmu.linearize.hs_linearization` (``with_force=True``; plus
  :func:`bearing_fmu.contact.contact_coefficients`), as ``rotorcosim stability --film hs``;
* ``film="short"``: the short-bearing (Ocvirk) closed form
  :func:`rotor_fmu.stability.short_bearing_force`, its tangent by central differences.

Periodic orbit, by shooting: the state ``s = [q, v]`` at t = 0 such that ``s(T) = s(0)``,
``T = 2 pi / omega``. The start is the static equilibrium (the film's, as the linear
threshold finds it) plus the linear synchronous response with the film coefficients there
(one harmonic, the linearised harmonic balance). One period is integrated on ``n_per_rev``
equal steps by the exponential Rosenbrock-Euler method (Hochbruck, Ostermann & Schweitzer
2009, SIAM J. Numer. Anal. 47:786; second order, exact for the linear and stiff parts): the
unbalance's (cos, sin) carried as two more states of a harmonic oscillator so the system is
autonomous, ``z_{k+1} = z_k + h phi_1(h J_k) f(z_k)`` with ``J_k`` the Jacobian at ``z_k``
(the rotor's matrices plus each film's tangent there). Newton on ``s(T) - s(0)`` with the
monodromy of the frozen system, ``Phi = prod_k expm(h J_k)`` (the product of the exponentials of
docs/scripts/turbocharger_unbalance_floquet.py, the variational equation of this integrator
up to the change of ``J_k`` along the orbit), until the mismatch is below ``1e-9`` c in the
positions and ``1e-9`` c omega in the velocities (c: the smallest clearance).

Floquet multipliers: the eigenvalues of the monodromy along the converged orbit, the product of
``expm(h (J_k + J_{k+1}) / 2)`` (the Jacobian averaged over each step, second order). The growth
rate ``ln|mu| f`` of the multiplier of largest modulus replaces the largest real part of the
linear threshold's eigenvalues in the scan and its refinement; its frequency ``|arg mu| f`` (in
[0, f/2]: a Floquet frequency is defined modulo the speed). mu real near -1: the principal
parametric resonance, a whirl at exactly half speed; near +1: a synchronous (or, modulo the
speed, integer-order) instability; complex: a whirl at ``|arg mu| f`` modulo the speed. Without
unbalance the orbit is the static equilibrium, the monodromy ``expm(T J)`` and the growth rate
the linear threshold's largest real part (to the round-off of the exponentials).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from orchestrator.stability.films import _NUMERIC, _short
from orchestrator.stability.system import StabilityError, System

N_PER_REV = 64          # integration steps (and frozen-system factors) per revolution
TOL = 1e-9              # shooting tolerance, in clearances (positions) and clearance x omega (velocities)
MAX_NEWTON = 30
MAX_ECC = 0.995         # an orbit point beyond this eccentricity ratio is no orbit of a film (as the statics)


class NoPeriodicOrbit(StabilityError):
    """No synchronous periodic orbit found at a speed (shooting diverged, left the clearance, or
    did not converge): the speed is left out of the search, as one without static equilibrium."""


@dataclass
class Orbit:
    """The synchronous periodic orbit at ``omega`` [rad/s] and its Floquet multipliers."""

    omega: float
    states: np.ndarray                  # (n_per_rev + 1, 2 n_dof): s at t_k = k T / n_per_rev (last = first)
    multipliers: np.ndarray             # all, largest modulus first
    iterations: int
    mismatch: float                     # |s(T) - s(0)| of the last integration, scaled (TOL)
    seconds: float
    kin: np.ndarray = field(repr=False, default=None)   # (n_per_rev + 1, n_stations, 4) x, y, vx, vy

    @property
    def growth_rate(self) -> float:
        return math.log(abs(self.multipliers[0])) * self.omega / (2 * math.pi)

    @property
    def whirl(self) -> float:
        """|arg mu| f of the largest multiplier [rad/s], in [0, omega/2]."""
        return abs(float(np.angle(self.multipliers[0]))) * self.omega / (2 * math.pi)


def multiplier_kind(mu: complex, f_hz: float) -> str:
    """Words for a Floquet multiplier at the speed ``f_hz``."""
    if abs(mu.imag) <= 1e-9 * abs(mu):
        if mu.real < 0:
            return "real, negative (near -1 at the threshold): principal parametric resonance, whirl at half speed"
        return "real, positive (near +1 at the threshold): a synchronous (integer-order) instability"
    return (f"complex: a whirl at {abs(np.angle(mu)) / (2 * math.pi) * f_hz:.4g} Hz (modulo the speed "
            f"{f_hz:.4g} Hz)")


class FloquetFilms:
    """``max_re(omega)`` of the Floquet search (module doc) for the films of ``linear`` (the
    linear threshold's :class:`~orchestrator.stability.films._HSFilm` or ``_ShortFilm``, whose
    static equilibria and coefficients start each orbit)."""

    def __init__(self, system: System, film: str, linear, extra: np.ndarray, *, n_per_rev: int = N_PER_REV):
        self.system, self.film, self.linear = system, film, linear
        self.extra = np.asarray(extra, float)
        self.n_per_rev = int(n_per_rev)
        self.orbits: dict[float, Orbit | None] = {}
        self.failures: dict[float, str] = {}
        rotor = system.rotor
        self.rotor = rotor
        self.n = n = rotor.n_dof
        self.Mi = np.linalg.inv(rotor.M)
        self.P = np.asarray(rotor.bearing_dofs, int)
        self.c = np.array([b.params.psi * b.params.R for b in system.bearings])
        self.c_ref = float(self.c.min())
        U = np.zeros((n, 2))            # unbalance force = U[:, 0] omega^2 cos(omega t) + U[:, 1] omega^2 sin(...)
        for ix, iy, me, ph in rotor.unbalances:
            U[ix, 0] += me * math.cos(ph)
            U[ix, 1] -= me * math.sin(ph)
            U[iy, 0] += me * math.sin(ph)
            U[iy, 1] += me * math.cos(ph)
        self.U = U
        f0 = rotor.f_g.copy()
        for j, (ix, iy) in enumerate(self.P):
            f0[ix] += self.extra[j, 0]
            f0[iy] += self.extra[j, 1]
        self.f0 = f0
        force = ("half-Sommerfeld force of each bearing (contact as the FMU adds it)" if film == "hs" else
                 "short-bearing (Ocvirk) force")
        self.method = ("Floquet multipliers of the rotor linearised along its synchronous periodic orbit under its "
                       "unbalance at each constant speed (shooting: Newton on s(T) - s(0) with the frozen-system "
                       f"monodromy, {self.n_per_rev} exponential Rosenbrock-Euler steps per revolution, the nonlinear "
                       f"{force}; start: the static equilibrium plus the linear synchronous response; "
                       "orchestrator/stability/floquet.py); growth rate ln|mu| f of the largest multiplier in place of "
                       "the largest real part")

    @property
    def has_unbalance(self) -> bool:
        return bool(np.any(self.U))

    # ------------------------------------------------------------------ the films
    def film_at(self, j: int, x, y, vx, vy, omega):
        """(F (2,), K (2, 2), C (2, 2)) of station j's film at the kinematics."""
        if self.film == "hs":
            from bearing_fmu.contact import contact_coefficients, contact_force
            from bearing_fmu.linearize import hs_linearization
            m = self.linear.models[j]
            # the force from the tangent solve's base field (hs_force to round-off: one solve, not two)
            F, K, C = hs_linearization(m, x, y, vx, vy, omega, with_force=True)
            if m.params.contact:
                F = F + np.array(contact_force(x, y, vx, vy, omega, **m.contact_kw)[:2])
                Kc, Cc = contact_coefficients(x, y, vx, vy, omega, **m.contact_kw)
                K, C = K + Kc, C + Cc
            return np.asarray(F, float), K, C
        from bearing_fmu.linearize import _central
        from rotor_fmu.stability import short_bearing_force
        kw = _short(self.system.bearings[j].params)
        cl = kw["C"]
        steps = (1e-6 * cl, 1e-6 * cl, 1e-6 * cl * abs(omega), 1e-6 * cl * abs(omega))
        D = _central(lambda z: np.array(short_bearing_force(*z, omega, **kw)), np.array([x, y, vx, vy], float), steps)
        return np.array(short_bearing_force(x, y, vx, vy, omega, **kw)), D[:, :2].copy(), D[:, 2:].copy()

    # ------------------------------------------------------------------ the system
    def _static(self, omega):
        """(static state s (2n,), film K, C (n_b, 2, 2) there) at omega: each journal at its
        film's static equilibrium, the other dofs from the statics with those coefficients."""
        K, C = self.linear.finite_coefficients(omega)      # also each station's equilibrium, self.linear.q
        if self.film == "hs":
            qs = [np.asarray(q, float) for q in self.linear.q]
        else:
            from rotor_fmu.stability import short_bearing_equilibrium
            qs = []
            for b, ld in zip(self.system.bearings, self.linear.loads):
                eps, psi = short_bearing_equilibrium(ld, omega, **_short(b.params))
                qs.append(eps * b.params.psi * b.params.R * np.array([math.cos(psi), math.sin(psi)]))
        _, Cw, Kw = self.rotor.system_matrices(omega)
        A = Kw.copy()
        rhs = self.f0.copy()
        for j, (ix, iy) in enumerate(self.P):
            idx = np.ix_([ix, iy], [ix, iy])
            A[idx] += K[j]
            F, _, _ = self.film_at(j, qs[j][0], qs[j][1], 0.0, 0.0, omega)
            rhs[[ix, iy]] += F + K[j] @ qs[j]
        q = np.linalg.solve(A, rhs)
        return np.concatenate([q, np.zeros(self.n)]), K, C

    def _start(self, omega):
        """The static state plus the linear synchronous response (first harmonic) at t = 0."""
        s0, K, C = self._static(omega)
        M, Cw, Kw = self.rotor.system_matrices(omega)
        Kt, Ct = Kw.copy(), Cw.copy()
        for j, (ix, iy) in enumerate(self.P):
            idx = np.ix_([ix, iy], [ix, iy])
            Kt[idx] += K[j]
            Ct[idx] += C[j]
        fhat = omega ** 2 * (self.U[:, 0] - 1j * self.U[:, 1])    # Re(fhat e^{i w t}) = U0 w^2 cos + U1 w^2 sin
        Q = np.linalg.solve(Kt - omega ** 2 * M + 1j * omega * Ct, fhat)
        s0[:self.n] += Q.real
        s0[self.n:] += (1j * omega * Q).real
        return s0

    def _kin(self, s):
        n = self.n
        return np.stack([s[self.P[:, 0]], s[self.P[:, 1]], s[n + self.P[:, 0]], s[n + self.P[:, 1]]], axis=1)

    def _rhs_jac(self, s, cs, sn, omega, Mw):
        """(ds/dt (2n,), J_s (2n, 2n)) at state s and unbalance phase (cos, sin)."""
        n = self.n
        _, Cw, Kw = Mw
        Kt, Ct = Kw.copy(), Cw.copy()
        force = self.f0 + omega ** 2 * (self.U[:, 0] * cs + self.U[:, 1] * sn) - Kw @ s[:n] - Cw @ s[n:]
        for j, (x, y, vx, vy) in enumerate(self._kin(s)):
            if not math.hypot(x, y) < MAX_ECC * self.c[j]:
                raise NoPeriodicOrbit(f"the orbit of bearing '{self.system.bearings[j].instance}' reaches "
                                      f"eccentricity {math.hypot(x, y) / self.c[j]:.3f} (beyond {MAX_ECC} of its "
                                      "clearance)")
            F, K, C = self.film_at(j, x, y, vx, vy, omega)
            ix, iy = self.P[j]
            force[[ix, iy]] += F
            idx = np.ix_([ix, iy], [ix, iy])
            Kt[idx] += K
            Ct[idx] += C
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:, :n] = -self.Mi @ Kt
        J[n:, n:] = -self.Mi @ Ct
        return np.concatenate([s[n:], self.Mi @ force]), J

    def _period(self, s0, omega, Mw):
        """Integrate one revolution from s0: (states (N+1, 2n), Jacobians (N+1, 2n, 2n), Phi)."""
        n2 = 2 * self.n
        N = self.n_per_rev
        h = 2 * math.pi / omega / N
        Bu = np.zeros((n2, 2))
        Bu[self.n:] = self.Mi @ (omega ** 2 * self.U)
        big = np.zeros((n2 + 3, n2 + 3))
        big[n2:n2 + 2, n2:n2 + 2] = h * np.array([[0.0, -omega], [omega, 0.0]])
        big[:n2, n2:n2 + 2] = h * Bu
        states = np.empty((N + 1, n2))
        jacs = np.empty((N + 1, n2, n2))
        Phi = np.eye(n2)
        s = s0.copy()
        for k in range(N + 1):
            ph = omega * k * h
            f, J = self._rhs_jac(s, math.cos(ph), math.sin(ph), omega, Mw)
            states[k], jacs[k] = s, J
            if k == N:
                break
            big[:n2, :n2] = h * J
            big[:n2, -1] = h * f
            big[n2:n2 + 2, -1] = h * omega * np.array([-math.sin(ph), math.cos(ph)])
            E = sla.expm(big)
            s = s + E[:n2, -1]
            Phi = E[:n2, :n2] @ Phi
            if not np.all(np.isfinite(s)):
                raise NoPeriodicOrbit("the integration over a revolution gave a non-finite state")
        return states, jacs, Phi

    def orbit(self, omega: float) -> Orbit:
        """The periodic orbit at omega and its multipliers (:class:`NoPeriodicOrbit` when none is found)."""
        t0 = time.perf_counter()
        n = self.n
        Mw = self.rotor.system_matrices(omega)
        scale = np.concatenate([np.full(n, self.c_ref), np.full(n, self.c_ref * omega)])
        s0 = self._start(omega)
        err = math.inf
        for it in range(1, MAX_NEWTON + 1):
            states, jacs, Phi = self._period(s0, omega, Mw)
            G = states[-1] - s0
            err = float(np.max(np.abs(G) / scale))
            if err <= TOL:
                break
            try:
                ds = np.linalg.solve(Phi - np.eye(2 * n), -G)
            except np.linalg.LinAlgError:
                raise NoPeriodicOrbit("the shooting Jacobian Phi - I is singular (a multiplier at +1: a fold of "
                                      "the orbit)") from None
            s0 = s0 + ds
        else:
            raise NoPeriodicOrbit(f"the shooting did not converge in {MAX_NEWTON} Newton steps (mismatch "
                                  f"{err:.3g} of the clearance)")
        h = 2 * math.pi / omega / self.n_per_rev
        Phi = np.eye(2 * n)
        for k in range(self.n_per_rev):
            Phi = sla.expm(0.5 * h * (jacs[k] + jacs[k + 1])) @ Phi
        mu = np.linalg.eigvals(Phi)
        mu = mu[np.argsort(-np.abs(mu), kind="stable")]
        kin = np.array([self._kin(s) for s in states])
        return Orbit(omega, states, mu, it, err, time.perf_counter() - t0, kin)

    def max_re(self, omega: float) -> tuple[float, float]:
        """(Floquet growth rate ln|mu| f [1/s], |arg mu| f [rad/s]) of the largest multiplier at omega."""
        try:
            with np.errstate(all="ignore"):
                o = self.orbit(omega)
        except NoPeriodicOrbit as exc:
            self.failures[float(omega)] = str(exc)
            raise NoPeriodicOrbit(f"no synchronous periodic orbit at {omega / (2 * math.pi):.4g} Hz: {exc}") from None
        except _NUMERIC as exc:
            self.failures[float(omega)] = str(exc)
            raise NoPeriodicOrbit(f"no synchronous periodic orbit at {omega / (2 * math.pi):.4g} Hz: "
                                  f"{exc or type(exc).__name__}") from None
        self.orbits[float(omega)] = o
        return o.growth_rate, o.whirl

    def eccentricities(self, omega):
        return self.linear.eccentricities(omega)

    def orbit_entry(self, omega: float) -> dict:
        """Per bearing: the orbit's half peak-to-peak in x and y, its largest and mean eccentricity
        (in clearances), and the static eccentricity, at omega."""
        o = self.orbits.get(float(omega)) or self.orbit(omega)
        eps_static = self.linear.eccentricities(omega)
        out = {}
        for j, b in enumerate(self.system.bearings):
            x, y = o.kin[:-1, j, 0], o.kin[:-1, j, 1]
            c = self.c[j]
            out[b.instance] = {"amplitude_x_c": float((x.max() - x.min()) / 2 / c),
                               "amplitude_y_c": float((y.max() - y.min()) / 2 / c),
                               "eps_max": float(np.hypot(x, y).max() / c), "eps_mean_position":
                               float(math.hypot(x.mean(), y.mean()) / c), "eps_static": float(eps_static[j])}
        return out


def linear_beside(fn, ws: np.ndarray, requests) -> dict:
    """The linear threshold (at the static equilibrium, no unbalance) on the same scan, for the
    result's ``linear`` entry: ``status``, ``threshold_hz``, ``whirl_hz``, ``crossings``, and
    ``threshold_between_hz`` when Brent could not refine it (status ``threshold_bracketed``)."""
    from orchestrator.stability.search import _search
    out: dict = {"notes": [], "crossings": [], "crossings_bracketed": [], "speed_range_hz": None}
    if requests.requested:
        return {"status": "not computed (stopped)", "threshold_hz": None, "whirl_hz": None, "crossings": []}
    try:
        _search(fn.max_re, ws, out)
    except (StabilityError, *_NUMERIC) as exc:
        return {"status": f"not computed: {exc}", "threshold_hz": None, "whirl_hz": None, "crossings": []}
    lin = {"status": out["status"], "threshold_hz": out.get("threshold_hz"), "whirl_hz": out.get("whirl_hz"),
           "crossings": out["crossings"]}
    if out["status"] == "threshold_bracketed":      # a step of Brent's failed there: its bracket, not refined
        lin["threshold_between_hz"] = out["threshold_between_hz"]
    return lin


def floquet_entries(fq: FloquetFilms, result: dict, seen: dict, at: float | None, seconds: float) -> None:
    """Add the Floquet search's own entries to ``result`` (``unbalance``, ``floquet``, and per scan
    row the multiplier and each bearing's orbit amplitude), ``at``: the threshold [rad/s] or None."""
    result["unbalance"] = True
    rows = {round(r["speed_hz"], 12): r for r in result["scan"]}
    for w in seen:
        o = fq.orbits.get(float(w))
        row = rows.get(round(w / (2 * math.pi), 12))
        if o is None or row is None:
            continue
        mu = complex(o.multipliers[0])
        row["floquet_multiplier"] = [mu.real, mu.imag]
        row["orbit_amplitude_c"] = {b.instance: float(max(np.ptp(o.kin[:-1, j, 0]), np.ptp(o.kin[:-1, j, 1]))
                                                      / 2 / fq.c[j]) for j, b in enumerate(fq.system.bearings)}
    n_done = len(fq.orbits) + len(fq.failures)
    entry: dict = {"method": fq.method, "n_per_rev": fq.n_per_rev, "speeds_computed": n_done,
                   "seconds_per_speed": seconds / n_done if n_done else None,
                   "threshold_multiplier": None, "multiplier_kind": None, "orbit_at_threshold": None,
                   "newton_iterations_at_threshold": None,
                   "speeds_without_orbit": [{"speed_hz": w / (2 * math.pi), "reason": why}
                                            for w, why in sorted(fq.failures.items())]}
    near = [w for w in fq.orbits if at is not None and abs(w - at) <= 1e-9 * at]   # at: from the crossing's Hz
    if near:
        at = near[0]
        o = fq.orbits[at]
        mu = complex(o.multipliers[0])
        entry.update(threshold_multiplier=[mu.real, mu.imag], multiplier_kind=multiplier_kind(mu, at / (2 * math.pi)),
                     orbit_at_threshold=fq.orbit_entry(at), newton_iterations_at_threshold=o.iterations)
    lin = result.get("linear") or {}
    if result.get("threshold_hz") is not None and lin.get("threshold_hz") is not None:
        entry["below_linear_hz"] = lin["threshold_hz"] - result["threshold_hz"]
    result["floquet"] = entry
