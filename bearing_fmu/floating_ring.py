"""Floating-ring bearing: a ring with mass and polar inertia between two oil films (no FMI import).

Physics (docs/floating-ring.md)
-------------------------------
* **Inner film** (journal to ring bore, radius ``R_i``): our Reynolds film
  (:class:`bearing_fmu.model.BearingModel`, any of its options) on the ring's own
  kinematics. The gap depends on the journal centre relative to the ring centre,
  ``h = c_i - (x - x_r) cos(phi) - (y - y_r) sin(phi)``, its squeeze on the relative
  velocity, and the wedge on the *sum* of the surface speeds: the Couette flux of the
  generalised Reynolds equation is ``(U_journal + U_ring) h / 2`` (Hamrock, Schmid &
  Jacobson 2004, *Fundamentals of Fluid Film Lubrication*, eq. 7.57; Szeri 2011 ch. 2),
  so the film is evaluated with the spin ``omega + Omega``. The film force on the
  journal is ``F_i``; the ring gets ``-F_i``.
* **Outer film** (ring to housing, radius ``R_o``): a plain film on the ring's position,
  velocity and spin ``Omega`` (housing at rest). Its force on the ring is ``F_o``.
* **Friction torques** from the wall shear of each film (:func:`shear_torques`), the
  Couette part carrying the fluid fraction (``eta = theta eta0``, paper eq. 3) and the
  Poiseuille part ``(h / 2) dp / (R dphi)``; on the journal (y = 0) and on the shell
  (y = h) of the velocity profile ``u = U_j (1 - y/h) + U_s y/h + dp/dx (y^2 - y h)/(2 eta)``::

      tau_journal =  theta eta (U_s - U_j) / h - (h / 2) dp/dx
      tau_shell   =  theta eta (U_j - U_s) / h - (h / 2) dp/dx,  T = R int tau dA.

  A centred journal in a full film gives Petroff's ``T = -2 pi eta R^3 B (omega - Omega) / c``.
* **Ring**: ``m_r r'' = -F_i + F_o - m_r g e_y`` and ``J_r Omega' = T_ring,inner +
  T_ring,outer`` (the issue's ``T_inner - T_outer`` with magnitudes). ``floating = 0``
  (semi-floating): ``Omega = 0`` always, translation free (the outer film is then a
  squeeze-film damper).

Time integration (one :meth:`FloatingRing.step` = one FMU step)
---------------------------------------------------------------
The journal kinematics are held over the step (FMI zero-order hold). The ring is light
(its films damp it with time constants ``m_r / (C_i + C_o)`` of some 10 us), so it is
advanced *inside* the step, together with its films, in ``ceil(dt / h_ring)`` sub-steps
of a linearly implicit BDF2 (second order, L-stable: the ring's stiffest mode, ``m_r / C`` of
about 1 us, is damped in one sub-step; the trapezoidal rule tried first leaves it oscillating
and stalled the convergence, tests/test_floating_ring.py) for ``q = (r, v)``::

    (3/2 - h J) dq = h (f(q0) + B dj) + (q0 - q_-1) / 2      (implicit Euler on the first
                                                              step or when h changes)
    J = [[0, I], [-K / m_r, -C / m_r]],  B dj = [0, (K_i dx_j + C_i dv_j) / m_r]
    (J_r + h/2 D) dOmega = h T0                                 (spin, not stiff)

with ``K = K_i + K_o``, ``C = C_i + C_o`` the films' quasi-static coefficients
(:func:`bearing_fmu.linearize.linearization`, refreshed after every ``jacobian_every`` steps),
``dj`` the journal input change over the sub-step (``input_hold``: 0 the new input over the
whole step, 1 linear from the previous step's input; equal for one sub-step) and ``D`` the
Petroff torque slope. Each sub-step then advances both films over ``h`` with the new ring
kinematics and reads their forces and torques.

Interface coefficients seen by the journal (:meth:`FloatingRing.linearization`), for the
master's interface-Jacobian coupling: by default (``H = 0``, what the FMU outputs) the
*instantaneous* response, the inner film's own ``K_i, C_i``: the ring's inertia holds it at the
instant the journal moves. :func:`step_coefficients` gives the response over a step of length
H with the ring following both films linearly (ring perturbation ``q = (r, w)``,
``q' = A q + B u`` with the held input ``u = (x_j, v_j)``)::

    A = [[0, I], [-S_K / m_r, -S_C / m_r]],   B = [[0, 0], [K_i / m_r, C_i / m_r]],
    S_K = K_i + K_o,  S_C = C_i + C_o,   q(H) = Phi_qu u   (Phi = expm(H [[A, B], [0, 0]]))

    K = K_i - K_i Phi_ru,x - C_i Phi_wu,x,   C = C_i - K_i Phi_ru,v - C_i Phi_wu,v

-> K_i, C_i as H -> 0 and the films in series, ``K_i (K_i + K_o)^-1 K_o``, as H -> infinity.
Measured (docs/floating-ring.md): both the low-frequency series and the step response (lower
than K_i, C_i: the ring moves within a 0.1 ms step, its velocity relaxes in m_r / c ~ 0.2 ms)
made the Jeffcott run-up unstable at the macro-step rate; coefficients that underestimate the
force's response destabilise the coupling (bearing_fmu/linearize.py), the instantaneous ones
bound it from above. They only set the stabilising correction; the converged answer does not
depend on them.

Units SI; frame of docs/dev/contracts.md (x horizontal, y up, spin CCW about +z).
"""

from __future__ import annotations

import math

import numpy as np

from .floating_ring_statics import (MAX_RING_SUBSTEPS, RingParams, petroff_coefficient, petroff_ratio, shear_torques,
                                    static_equilibrium, step_coefficients)
from .floating_ring_expm import expm_small
from .linearize import linearization as film_linearization
from .model import BearingModel, StepFailed

__all__ = ["RingParams", "FloatingRing", "shear_torques", "petroff_coefficient", "petroff_ratio",
           "static_equilibrium", "step_coefficients", "StepFailed"]


class FloatingRing:
    """A floating-ring bearing; call order ``initialize`` then ``step`` ... (module doc).

    ``outputs``: ``Fx, Fy`` [N] inner-film force on the journal; ``eps`` [-] inner
    eccentricity |r_j - r_r| / c_i; ``eps_outer`` [-] |r_r| / c_o; ``omega_ring`` [rad/s];
    ``x_ring, y_ring`` [m], ``vx_ring, vy_ring`` [m/s]; ``T_journal`` [N m] friction torque
    on the journal about +z; ``T_ring_inner, T_ring_outer`` [N m] torques of the two films
    on the ring; ``P_loss`` [W] friction power of both films ``-(T_journal omega +
    (T_ring_inner + T_ring_outer) Omega)``; ``p_max``, ``h_min`` of the inner film and
    ``p_max_outer``, ``h_min_outer``; ``ax_ring, ay_ring`` [m/s^2] the ring's acceleration
    from its force balance; ``kxx_outer .. cyy_outer`` the outer film's coefficients.
    """

    def __init__(self, params: RingParams):
        if not isinstance(params, RingParams):
            raise TypeError(f"FloatingRing(params): expected RingParams, got {type(params).__name__}")
        self.params = params
        self.inner = BearingModel(params.inner)
        self.outer = BearingModel(params.outer)
        self.D = 2 * math.pi * (petroff_coefficient(params.inner) + petroff_coefficient(params.outer))
        self.outputs: dict[str, float] = {}
        self._initialized = False

    # ------------------------------------------------------------- kinematics
    def _film_inputs(self, journal, ring, Om):
        x, y, vx, vy, om = journal
        xr, yr, vxr, vyr = ring
        return (x - xr, y - yr, vx - vxr, vy - vyr, om + Om), (xr, yr, vxr, vyr, Om)

    def _read_films(self):
        """Forces and torques of both films at their current states."""
        j, r, Om = self._journal, self._ring, self._Om
        pi_, po = self.params.inner, self.params.outer
        xi, yi = j[0] - r[0], j[1] - r[1]
        Tj, Tri = shear_torques(self.inner.fields(), xi, yi, pi_.c, pi_.R, pi_.B, pi_.eta0,
                                j[4], Om, j[4] + Om)
        Tro, _ = shear_torques(self.outer.fields(), r[0], r[1], po.c, po.R, po.B, po.eta0,
                               Om, 0.0, Om)
        oi, oo = self.inner.outputs, self.outer.outputs
        self._Fi = np.array([oi["Fx"], oi["Fy"]])
        self._Fo = np.array([oo["Fx"], oo["Fy"]])
        self._T = (Tj, Tri, Tro)

    def _refresh_jacobians(self):
        self._Ki, self._Ci = film_linearization(self.inner)
        self._Ko, self._Co = film_linearization(self.outer)
        self._jac_age = 0

    def _update_outputs(self):
        j, r, Om = self._journal, self._ring, self._Om
        p = self.params
        pi_, po = p.inner, p.outer
        Tj, Tri, Tro = self._T
        oi, oo = self.inner.outputs, self.outer.outputs
        self.outputs = dict(
            Fx=float(self._Fi[0]), Fy=float(self._Fi[1]),
            eps=math.hypot(j[0] - r[0], j[1] - r[1]) / pi_.c, eps_outer=math.hypot(r[0], r[1]) / po.c,
            omega_ring=float(Om), x_ring=float(r[0]), y_ring=float(r[1]), vx_ring=float(r[2]),
            vy_ring=float(r[3]), T_journal=Tj, T_ring_inner=Tri, T_ring_outer=Tro,
            P_loss=-(Tj * j[4] + (Tri + Tro) * Om), p_max=oi["p_max"], h_min=oi["h_min"],
            p_max_outer=oo["p_max"], h_min_outer=oo["h_min"])
        # what the rotor's ring-interface step needs (rotor_fmu/ring_interface.py): the ring's
        # acceleration from its force balance now, and the outer film's coefficients
        a = (-self._Fi + self._Fo + np.array([0.0, -p.m_ring * p.gravity])) / p.m_ring
        self.outputs["ax_ring"], self.outputs["ay_ring"] = float(a[0]), float(a[1])
        for kind, mat in (("k", self._Ko), ("c", self._Co)):
            for a_, ci in enumerate("xy"):
                for b_, cj in enumerate("xy"):
                    self.outputs[f"{kind}{ci}{cj}_outer"] = float(mat[a_, b_])

    # ------------------------------------------------------------- API
    def initialize(self, x, y, vx, vy, omega, *, ring=(0.0, 0.0, 0.0, 0.0), omega_ring=None,
                   init="flooded"):
        """Build both films at t = 0 with the journal at (x, y, vx, vy, omega) and the ring at
        ``ring`` = (x_r, y_r, vx_r, vy_r) [m, m/s], or ``ring="equilibrium"`` (the ring's
        static balance of the two quasi-static films and its weight, :meth:`equilibrium`).
        ``omega_ring`` [rad/s] defaults to the concentric Petroff ratio times omega
        (:func:`petroff_ratio`; 0 when semi-floating). ``init``: initial film of the
        mass-conserving model, as :meth:`BearingModel.initialize`.
        """
        p = self.params
        self._journal = tuple(float(v) for v in (x, y, vx, vy, omega))
        if omega_ring is None:
            omega_ring = petroff_ratio(p) * omega
        self._Om = float(omega_ring) if p.floating else 0.0
        if isinstance(ring, str):
            if ring != "equilibrium":
                raise ValueError(f"initialize: ring must be (x, y, vx, vy) or 'equilibrium' (got {ring!r})")
            if omega == 0.0 and self._Om == 0.0:     # no wedge: nothing to balance (e.g. inputs not set yet)
                ring = (*self._ring_guess(), 0.0, 0.0)
            else:
                ring = (*self.equilibrium(), 0.0, 0.0)
        self._ring = np.array([float(v) for v in ring])
        if self._ring.shape != (4,) or not np.all(np.isfinite(self._ring)):
            raise ValueError(f"initialize: ring must be 4 finite numbers (x, y, vx, vy) (got {ring!r})")
        ki, ko = self._film_inputs(self._journal, self._ring, self._Om)
        self.inner.initialize(*ki, init=init)
        self.outer.initialize(*ko, init=init)
        self._t = 0.0
        self._q_prev, self._h_prev = None, 0.0
        self._last_dt = self.params.h_ring
        self._read_films()
        self._refresh_jacobians()
        self._initialized = True
        self._update_outputs()

    def _ring_guess(self):
        """Ring position with the journal half an inner clearance off its centre (or concentric
        with it when closer): inside both clearances whenever the journal is."""
        x, y = self._journal[:2]
        rj = math.hypot(x, y)
        return np.array([x, y]) * (max(0.0, 1 - 0.5 * self.params.inner.c / rj) if rj > 0 else 0.0)

    def equilibrium(self, tol=1e-9, max_iter=50):
        """Ring position (x_r, y_r) [m] where the quasi-static (half-Sommerfeld) forces of both
        films and the ring's weight balance, for the current journal kinematics and ring spin
        (Newton with the films' stiffness, damped to stay inside both clearances)."""
        from .linearize import hs_force, hs_linearization
        x, y, vx, vy, om = self._journal
        p = self.params
        r = self._ring_guess()
        W = np.array([0.0, -p.m_ring * p.gravity])
        for _ in range(max_iter):
            Fi = hs_force(self.inner, x - r[0], y - r[1], vx, vy, om + self._Om)
            Fo = hs_force(self.outer, r[0], r[1], 0.0, 0.0, self._Om)
            res = -Fi + Fo + W
            Ki, _ = hs_linearization(self.inner, x - r[0], y - r[1], vx, vy, om + self._Om)
            Ko, _ = hs_linearization(self.outer, r[0], r[1], 0.0, 0.0, self._Om)
            J = -(Ki + Ko)
            try:
                dr = np.linalg.solve(J, -res)
            except np.linalg.LinAlgError:
                raise StepFailed("FloatingRing.equilibrium: singular film stiffness (journal and ring "
                                 "at rest?); start the ring at a given position instead") from None
            lam = 1.0
            while lam > 1e-4:
                rn = r + lam * dr
                if (math.hypot(*rn) < 0.995 * p.outer.c      # a loaded ring sits at eps_outer 0.97
                        and math.hypot(x - rn[0], y - rn[1]) < 0.995 * p.inner.c):
                    break
                lam *= 0.5
            r = rn
            if np.linalg.norm(lam * dr) < tol * p.outer.c:
                return float(r[0]), float(r[1])
        raise StepFailed(f"FloatingRing.equilibrium: Newton did not converge in {max_iter} iterations "
                         f"(last ring position {r} m)")

    def _check_init(self, what):
        if not self._initialized:
            raise RuntimeError(f"FloatingRing.{what}: call initialize(x, y, vx, vy, omega) first")

    def step(self, dt, x, y, vx, vy, omega):
        """Advance ring and both films by dt [s] with the journal kinematics held (module doc).
        Raises :class:`StepFailed` (state unchanged) when a film cannot be advanced."""
        self._check_init("step")
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"FloatingRing.step: dt must be a positive finite time [s] (got {dt!r})")
        journal = tuple(float(v) for v in (x, y, vx, vy, omega))
        if not all(math.isfinite(v) for v in journal):
            raise ValueError(f"FloatingRing.step: non-finite journal input (x, y, vx, vy, omega) = {journal}")
        saved = self.get_state()
        try:
            self._advance(dt, journal)
            self._last_dt = dt
        except StepFailed:
            self.set_state(saved)
            raise
        self._jac_age += 1
        if self._jac_age >= self.params.jacobian_every:
            self._refresh_jacobians()
        self._update_outputs()

    def _advance(self, dt, journal):
        p = self.params
        want = dt / p.h_ring - 1e-9
        if not want <= MAX_RING_SUBSTEPS:
            raise ValueError(f"a step of {dt:g} s needs {want:.3g} ring sub-steps of at most h_ring = {p.h_ring:g} s, "
                             f"more than {MAX_RING_SUBSTEPS}; use a larger h_ring or a smaller macro step")
        n = max(1, math.ceil(want))
        h = dt / n
        if p.ring_integrator == 1:
            return self._advance_exponential(dt, journal, n)
        Ki, Ci, Ko, Co = self._Ki, self._Ci, self._Ko, self._Co
        j_old, j_new = np.array(self._journal), np.array(journal)
        dj = j_new - j_old
        if p.input_hold == 0:
            # zero-order hold: the new input over the whole step; the inner-film force at the
            # start corrected to first order for the jump of the input
            self._Fi = self._Fi - Ki @ dj[:2] - Ci @ dj[2:4]
            self._journal = journal
            j_step = np.zeros(5)
        else:
            j_step = dj / n                  # first-order hold: linear from the previous input
        Z2, I2 = np.zeros((2, 2)), np.eye(2)
        Jq = np.block([[Z2, I2], [-(Ki + Ko) / p.m_ring, -(Ci + Co) / p.m_ring]])
        W = np.array([0.0, -p.m_ring * p.gravity])
        for k in range(1, n + 1):
            q0 = self._ring.copy()
            F0 = -self._Fi + self._Fo + W
            f0 = np.concatenate([q0[2:], F0 / p.m_ring])
            fj = np.concatenate([np.zeros(2), (Ki @ j_step[:2] + Ci @ j_step[2:4]) / p.m_ring])
            if self._q_prev is not None and abs(self._h_prev - h) <= 1e-12 * h:
                # linearly implicit BDF2: (3/2 - h J) dq = h (f0 + f_j) + (q0 - q_-1) / 2
                dq = np.linalg.solve(1.5 * np.eye(4) - h * Jq, h * (f0 + fj) + 0.5 * (q0 - self._q_prev))
            else:       # first step or new step size: linearly implicit Euler
                dq = np.linalg.solve(np.eye(4) - h * Jq, h * (f0 + fj))
            self._q_prev, self._h_prev = q0, h
            if p.floating:
                T0 = self._T[1] + self._T[2]
                self._Om += h * T0 / (p.J_ring + 0.5 * h * self.D)
            self._ring = q0 + dq
            jk = tuple(journal) if (p.input_hold == 0 or k == n) else tuple(j_old + k * j_step)
            self._journal = jk
            ki, ko = self._film_inputs(jk, self._ring, self._Om)
            self.inner.step(h, *ki)
            self.outer.step(h, *ko)
            self._t += h
            self._read_films()

    def _journal_polynomial(self, dt, j_old, j_new):
        """Journal position and velocity over the step as polynomials in t in [0, dt]:
        (P, V) each (4, 2), ``r_j(t) = sum_k P[k] t^k`` (module doc, ``input_hold``)."""
        P, V = np.zeros((4, 2)), np.zeros((4, 2))
        x0, v0, x1, v1 = j_old[:2], j_old[2:4], j_new[:2], j_new[2:4]
        hold = self.params.input_hold
        if hold == 0:                       # the new input over the whole step
            P[0], V[0] = x1, v1
        elif hold == 1:                     # linear from the previous input, each on its own
            P[0], P[1], V[0], V[1] = x0, (x1 - x0) / dt, v0, (v1 - v0) / dt
        else:                               # cubic Hermite: position and velocity consistent
            d = (x1 - x0) / dt
            P[0], P[1] = x0, v0
            P[2] = (3 * d - 2 * v0 - v1) / dt
            P[3] = (v0 + v1 - 2 * d) / dt ** 2
            V[0], V[1], V[2] = P[1], 2 * P[2], 3 * P[3]
        return P, V

    def _advance_exponential(self, dt, journal, n):
        """``ring_integrator = 1``: each sub-step integrates the ring's ODE linearised at the
        sub-step's start, ``q' = f(q0, u0) + J (q - q0) + B (u(t) - u0)``, EXACTLY for the
        polynomial journal input u(t) (:meth:`_journal_polynomial`) by one matrix exponential
        of the ODE augmented with the input's monomials (Van Loan 1978, IEEE TAC 23(3) 395-404;
        the phi-functions of exponential integrators, Hochbruck & Ostermann 2010, Acta Numerica
        19, 209-286). Exact for the linear ring, so no truncation error at the whirl frequency
        (the BDF2 of ``ring_integrator = 0`` damps and shifts a 540 Hz relative whirl by tens of
        1/s at one 0.1 ms sub-step, docs/floating-ring.md), and the stiff ring mode decays as
        it should (exp(-h C / m_r) ~ 0). The spin is advanced as in :meth:`_advance`."""
        p = self.params
        h = dt / n
        Ki, Ci, Ko, Co = self._Ki, self._Ci, self._Ko, self._Co
        j_old, j_new = np.array(self._journal), np.array(journal)
        P, V = self._journal_polynomial(dt, j_old, j_new)
        om0, om1 = (j_new[4], j_new[4]) if p.input_hold == 0 else (j_old[4], j_new[4])
        W = np.array([0.0, -p.m_ring * p.gravity])
        A = np.zeros((8, 8))
        A[:2, 2:4] = np.eye(2)
        A[2:4, :2], A[2:4, 2:4] = -(Ki + Ko) / p.m_ring, -(Ci + Co) / p.m_ring
        A[5, 4] = A[6, 5] = A[7, 6] = 1.0          # monomials s_k = t^k / k!: s_k' = s_(k-1)
        u_eval = j_old[:4]                          # the input the films were last evaluated at
        for k in range(1, n + 1):
            ta = (k - 1) * h
            # the input polynomial shifted to the sub-step's start: coefficients of tau^m
            Ps = np.array([sum(math.comb(i, m) * ta ** (i - m) * P[i] for i in range(m, 4)) for m in range(4)])
            Vs = np.array([sum(math.comb(i, m) * ta ** (i - m) * V[i] for i in range(m, 4)) for m in range(4)])
            Ps[0] -= u_eval[:2]
            Vs[0] -= u_eval[2:4]
            g = (Ps @ Ki.T + Vs @ Ci.T) / p.m_ring          # (4, 2): accel. forcing per tau^m
            q0 = self._ring.copy()
            F0 = -self._Fi + self._Fo + W
            A[:2, 4] = q0[2:]
            A[2:4, 4] = F0 / p.m_ring + g[0]
            for m in range(1, 4):                            # tau^m = m! s_m
                A[2:4, 4 + m] = math.factorial(m) * g[m]
            dq = expm_small(h * A)[:4, 4]
            self._q_prev, self._h_prev = q0, h
            if p.floating:
                T0 = self._T[1] + self._T[2]
                self._Om += h * T0 / (p.J_ring + 0.5 * h * self.D)
            self._ring = q0 + dq
            tb = k * h
            pos = sum(P[i] * tb ** i for i in range(4))
            vel = sum(V[i] * tb ** i for i in range(4))
            om = om0 + (om1 - om0) * tb / dt
            jk = tuple(journal) if k == n else (float(pos[0]), float(pos[1]), float(vel[0]), float(vel[1]), float(om))
            self._journal = jk
            u_eval = np.array(jk[:4])
            ki, ko = self._film_inputs(jk, self._ring, self._Om)
            self.inner.step(h, *ki)
            self.outer.step(h, *ko)
            self._t += h
            self._read_films()

    def linearization(self, H: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(K, C) 2x2 of the whole ring bearing as the journal sees it over a step of H [s]
        (default 0: the instantaneous response K_i, C_i; module doc, :func:`step_coefficients`)."""
        self._check_init("linearization")
        if H == 0.0:
            return self._Ki.copy(), self._Ci.copy()
        return step_coefficients(self._Ki, self._Ci, self._Ko, self._Co, self.params.m_ring, H)

    def film_coefficients(self) -> dict[str, np.ndarray]:
        """The films' own quasi-static coefficients at the current state: Ki, Ci (inner, in
        the journal-minus-ring coordinates), Ko, Co (outer)."""
        self._check_init("film_coefficients")
        return dict(Ki=self._Ki.copy(), Ci=self._Ci.copy(), Ko=self._Ko.copy(), Co=self._Co.copy())

    @property
    def t(self) -> float:
        return self._t

    def get_state(self) -> dict:
        """Complete state (both films, ring, coefficients) as a dict of arrays and floats."""
        self._check_init("get_state")
        return dict(t=self._t, journal=np.array(self._journal), ring=self._ring.copy(), Om=self._Om,
                    inner=self.inner.get_state(), outer=self.outer.get_state(),
                    jac=np.array([self._Ki, self._Ci, self._Ko, self._Co]),
                    jac_age=self._jac_age, last_dt=self._last_dt, h_prev=self._h_prev,
                    q_prev=None if self._q_prev is None else self._q_prev.copy())

    def set_state(self, s: dict):
        """Restore a state from :meth:`get_state` exactly."""
        self._check_init("set_state")
        self._t = float(s["t"])
        self._journal = tuple(float(v) for v in s["journal"])
        self._ring = np.array(s["ring"], dtype=float)
        self._Om = float(s["Om"])
        self.inner.set_state(s["inner"])
        self.outer.set_state(s["outer"])
        self._Ki, self._Ci, self._Ko, self._Co = (np.array(m) for m in s["jac"])
        self._jac_age = int(s["jac_age"])
        self._last_dt = float(s["last_dt"])
        self._h_prev = float(s["h_prev"])
        self._q_prev = None if s["q_prev"] is None else np.array(s["q_prev"], dtype=float)
        self._read_films()
        self._update_outputs()
