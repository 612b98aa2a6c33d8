"""Linear stability of a rotor in floating-ring bearings (docs/floating-ring.md).

For each bearing station with its static load W (:func:`rotor_fmu.stability.static_bearing_loads`)
and journal speed omega:

1. the steady operating point: ring speed Omega from the torque balance of the two films
   at their static equilibria (``T_ring,inner + T_ring,outer = 0``, secant in Omega; the
   eccentric films spin the ring slower than the concentric Petroff ratio), journal and ring
   positions from :func:`bearing_fmu.floating_ring.static_equilibrium`;
2. the films' linearized coefficients there (:func:`bearing_fmu.linearize.linearization`,
   our finite half-Sommerfeld film on the same grid as the run-up): inner ``K_i, C_i`` in the
   journal-minus-ring coordinates at the wedge speed omega + Omega, outer ``K_o, C_o``;
3. the rotor's matrices at omega (:meth:`LinearRotor.system_matrices`) augmented with the two
   ring translation DOFs per station (mass m_r), coupled by the films::

       K[j, j] += K_i,  K[j, r] -= K_i,  K[r, j] -= K_i,  K[r, r] += K_i + K_o   (same for C)

   and the eigenvalues of the first-order system; the threshold is the lowest speed at which
   an eigenvalue crosses Re = 0 (scan + Brent, as :func:`rotor_fmu.stability.threshold_speed`).

``spin=False`` holds the ring spin at its steady value, as the classical linear analyses do
(Tatara 1970, Tanaka & Hori 1972, Li & Rohde 1981); ``spin=True`` adds the spin perturbation
of each ring as a first-order DOF, ``J_r dOmega' = dT/dq q + dT/dq' q' + dT/dOmega dOmega``, and the
films' force sensitivity to Omega (wedge speeds omega + Omega and Omega), all by central
differences of the quasi-static model (:func:`_spin_terms`): with eccentric films the torque
depends linearly on the whirl displacement.
"""

from __future__ import annotations

import math

import numpy as np

from bearing_fmu.floating_ring import FloatingRing, RingParams, petroff_ratio, static_equilibrium
from bearing_fmu.linearize import linearization

from .stability import first_crossing, rightmost, static_bearing_loads

__all__ = ["operating_point", "ring_system_eigen", "ring_threshold_speed", "RingRotor", "MCRingStation",
           "MCRingPoint", "mc_ring_films"]


#: :meth:`MCRingStation.continued`: halvings of a failing step in a row, and operating points tried
CONTINUATION_HALVINGS = 4
CONTINUATION_POINTS = 24


def _point_errors() -> tuple:
    """What an operating point that cannot be found raises (a film without equilibrium, a steady film
    that does not converge, no torque balance, numerics at a film's edge)."""
    from bearing_fmu.linearize import HSEquilibriumError
    from bearing_fmu.model import StepFailed
    return HSEquilibriumError, StepFailed, ArithmeticError, ValueError, RuntimeError, np.linalg.LinAlgError


def _ring_torque(params: RingParams, load: float, omega: float, Om: float):
    """(net torque on the ring [N m], model) at the static equilibrium with ring speed Om."""
    journal, ring = static_equilibrium(params, load, omega, omega_ring=Om)
    fr = FloatingRing(params.replace(floating=1))
    fr.initialize(*journal, 0.0, 0.0, omega, ring=(*ring, 0.0, 0.0), omega_ring=Om)
    return fr.outputs["T_ring_inner"] + fr.outputs["T_ring_outer"], fr


def operating_point(params: RingParams, load: float, omega: float, omega_ring=None) -> FloatingRing:
    """Initialised model at the steady operating point (ring speed from the torque balance,
    journal and ring at their static equilibria; semi-floating: Omega = 0). ``omega_ring``
    [rad/s]: the ring speed given instead (e.g. the one a run-up has, lagging the steady one on
    a ramp by about tau dOmega/dt); the journal and ring at their static equilibria for it."""
    if params.floating and omega_ring is not None:
        return _ring_torque(params, load, omega, float(omega_ring))[1]
    if not params.floating:
        journal, ring = static_equilibrium(params, load, omega)
        fr = FloatingRing(params)
        fr.initialize(*journal, 0.0, 0.0, omega, ring=(*ring, 0.0, 0.0))
        return fr
    from bearing_fmu.model import StepFailed

    def torque(Om, toward):
        """The ring torque at Om, or, when the outer film cannot carry the load at that ring speed
        (a trial of the secant too slow: no static equilibrium inside 0.98 c), at the first of up to
        4 points halfway towards ``toward`` (a speed where it could) that it can carry."""
        for _ in range(4):
            try:
                return Om, *_ring_torque(params, load, omega, Om)
            except StepFailed:
                if toward is None:
                    raise
                Om = 0.5 * (Om + toward)
        return Om, *_ring_torque(params, load, omega, Om)

    a, fa, fr = torque(petroff_ratio(params) * omega, None)
    b, fb, fr_b = torque(0.6 * a, a)
    for _ in range(30):                       # secant; the torque is monotone in Omega
        if abs(fb) < 1e-10 * abs(fr_b.outputs["T_journal"]) or fb == fa:
            return fr_b
        new = min(max(b - fb * (b - a) / (fb - fa), 0.0), omega)
        a, fa = b, fb
        b, fb, fr_b = torque(new, a)
    return fr_b


def _augmented(rotor, omega, points):
    M, C, K = rotor.system_matrices(omega)
    n = M.shape[0]
    nb = len(points)
    N = n + 2 * nb
    Ma, Ca, Ka = (np.zeros((N, N)) for _ in range(3))
    Ma[:n, :n], Ca[:n, :n], Ka[:n, :n] = M, C, K
    for k, fr in enumerate(points):
        Ki, Ci = linearization(fr.inner)
        Ko, Co = linearization(fr.outer)
        j = list(rotor.bearing_dofs[k])
        r = [n + 2 * k, n + 2 * k + 1]
        Ma[np.ix_(r, r)] = fr.params.m_ring * np.eye(2)
        for A, Ai, Ao in ((Ka, Ki, Ko), (Ca, Ci, Co)):
            A[np.ix_(j, j)] += Ai
            A[np.ix_(j, r)] -= Ai
            A[np.ix_(r, j)] -= Ai
            A[np.ix_(r, r)] += Ai + Ao
    return Ma, Ca, Ka


def _spin_terms(fr: FloatingRing):
    """Central differences of the quasi-static ring bearing at its state: (dT, dFi, dFo) with
    dT (9,) the net ring torque per (x_j, y_j, vx_j, vy_j, x_r, y_r, vx_r, vy_r, Omega) and
    dFi, dFo (2,) the inner/outer film force per Omega."""
    j = np.array(fr._journal, dtype=float)
    z0 = np.concatenate([j[:4], fr._ring, [fr._Om]])
    c = fr.params.inner.c
    steps = np.array([1e-5 * c] * 2 + [1e-5 * c * j[4]] * 2 + [1e-5 * c] * 2 + [1e-5 * c * j[4]] * 2
                     + [1e-6 * j[4]])

    def ev(z):
        m = FloatingRing(fr.params.replace(floating=1))
        m.initialize(*z[:4], j[4], ring=tuple(z[4:8]), omega_ring=z[8])
        o = m.outputs
        return o["T_ring_inner"] + o["T_ring_outer"], np.array([o["Fx"], o["Fy"]]), m._Fo.copy()

    dT = np.empty(9)
    for k in range(9):
        zp, zm = z0.copy(), z0.copy()
        zp[k] += steps[k]
        zm[k] -= steps[k]
        (tp, fip, fop), (tm, fim, fom) = ev(zp), ev(zm)
        dT[k] = (tp - tm) / (2 * steps[k])
    dFi, dFo = (fip - fim) / (2 * steps[8]), (fop - fom) / (2 * steps[8])
    return dT, dFi, dFo


def ring_system_eigen(rotor, params_list, omega, spin=False, omega_ring=None, loads=None):
    """Eigenvalues [1/s] of the rotor in floating-ring bearings (one RingParams per bearing
    station) at journal speed omega [rad/s], and the operating points used (module doc).
    ``omega_ring``: one ring speed [rad/s] per station instead of the torque balance's.
    ``loads`` (n_stations, 2) [N]: the static forces on the bearings (default the rotor's weight,
    :func:`static_bearing_loads`); only their y components are used (downward loads)."""
    loads = static_bearing_loads(rotor) if loads is None else loads
    oms = [None] * len(params_list) if omega_ring is None else list(omega_ring)
    points = [operating_point(p, float(-ld[1]), omega, om) for p, ld, om in zip(params_list, loads, oms)]
    M, C, K = _augmented(rotor, omega, points)
    N = M.shape[0]
    n = rotor.n_dof
    Mi = np.linalg.inv(M)
    ns = len(points) if spin and all(p.floating for p in params_list) else 0
    A = np.zeros((2 * N + ns, 2 * N + ns))
    A[:N, N:2 * N] = np.eye(N)
    A[N:2 * N, :N] = -Mi @ K
    A[N:2 * N, N:2 * N] = -Mi @ C
    for k in range(ns):
        fr = points[k]
        dT, dFi, dFo = _spin_terms(fr)
        jd = list(rotor.bearing_dofs[k])
        rd = [n + 2 * k, n + 2 * k + 1]
        col = 2 * N + k
        F = np.zeros(N)                            # force per Omega on each DOF
        F[jd] += dFi
        F[rd] += -dFi + dFo
        A[N:2 * N, col] = Mi @ F
        row = np.zeros(2 * N + ns)
        row[jd] += dT[0:2]
        row[[N + d for d in jd]] += dT[2:4]
        row[rd] += dT[4:6]
        row[[N + d for d in rd]] += dT[6:8]
        row[col] = dT[8]
        A[col] = row / fr.params.J_ring
    return np.linalg.eigvals(A), points


def _max_re(rotor, params_list, omega, spin=False):
    lam, _ = ring_system_eigen(rotor, params_list, omega, spin)
    return rightmost(lam)


def ring_threshold_speed(rotor, params_list, omega_min, omega_max, n_scan=40, spin=False):
    """(lowest unstable speed [rad/s], whirl frequency there [rad/s]) in [omega_min, omega_max],
    or (None, None); (omega_min, whirl) when already unstable at omega_min: ``n_scan`` speeds
    evenly spaced, then Brent (:func:`rotor_fmu.stability.first_crossing`)."""
    return first_crossing(lambda w: _max_re(rotor, params_list, w, spin), np.linspace(omega_min, omega_max, n_scan))


# --------------------------------------------------------------------------------------------
# Mass-conserving films (``rotorcosim stability --film mc`` with floating rings)
# --------------------------------------------------------------------------------------------

class RingRotor:
    """The rotor with each station's ring translation as two more degrees of freedom, in the
    coordinates the films act on, for :mod:`rotor_fmu.film_system` (its ``rotor`` argument:
    ``system_matrices``, ``bearing_dofs``, ``n_dof``).

    Degrees of freedom ``q' = (rotor dofs with each journal pair replaced by d_k, r_k ...)``:
    ``d_k = q_j,k - r_k`` the journal relative to its ring (the inner film's coordinates, as
    :meth:`bearing_fmu.floating_ring.FloatingRing._film_inputs` gives them to the inner film) and
    ``r_k`` the ring (the outer film's). With ``q = T q'`` (``q_j = d + r``) the matrices are
    ``T^T M_a T`` etc. of the rotor augmented with the ring masses (``M_a = diag(M, m_r I)``,
    no rotor stiffness or damping on the ring); the generalised film forces are then exactly
    ``F_i`` on ``d_k`` and ``F_o`` on ``r_k`` (virtual work: ``F_i . dq_j - F_i . dr + F_o . dr``),
    so each film couples to one pair, as a plain bearing does. ``bearing_dofs`` lists the pairs
    ``d_1, r_1, d_2, r_2, ...``: the films go in that order (inner, outer per station). The
    eigenvalues are those of the rotor-ring system in its own coordinates (T is invertible).
    """

    def __init__(self, rotor, m_rings):
        self.rotor = rotor
        n = rotor.n_dof
        ns = len(m_rings)
        self.n_dof = n + 2 * ns
        self.m_rings = [float(m) for m in m_rings]
        T = np.eye(self.n_dof)
        pairs = []
        for k, (ix, iy) in enumerate(np.asarray(rotor.bearing_dofs).reshape(-1, 2)):
            rx, ry = n + 2 * k, n + 2 * k + 1
            T[ix, rx] = T[iy, ry] = 1.0
            pairs += [(int(ix), int(iy)), (rx, ry)]
        self.T = T
        self.bearing_dofs = np.array(pairs, dtype=int)

    def system_matrices(self, omega):
        M, C, K = self.rotor.system_matrices(omega)
        n = M.shape[0]
        out = []
        for A, ring in ((M, True), (C, False), (K, False)):
            Aa = np.zeros((self.n_dof, self.n_dof))
            Aa[:n, :n] = A
            if ring:
                for k, m in enumerate(self.m_rings):
                    Aa[n + 2 * k, n + 2 * k] = Aa[n + 2 * k + 1, n + 2 * k + 1] = m
            out.append(self.T.T @ Aa @ self.T)
        return tuple(out)


class MCRingPoint:
    """A floating ring's steady operating point with its two mass-conserving films
    (:func:`mc_operating_point`): ``inner``, ``outer`` the :class:`bearing_fmu.linearize.MCFilmLinear`
    of each film there, ``Om`` the ring speed [rad/s], ``e`` the journal centre relative to the
    ring's, ``r`` the ring centre [m], ``torques`` (T_ring_inner, T_ring_outer, T_journal) [N m],
    ``outputs`` (``eps``, ``eps_outer``, ``omega_ring``, ``x_ring``, ``y_ring``, as
    :class:`~bearing_fmu.floating_ring.FloatingRing`'s), ``iterations`` of the torque balance."""

    def __init__(self, params, inner, outer, Om, e, r, torques, iterations):
        self.params, self.inner, self.outer, self.Om = params, inner, outer, float(Om)
        self.e, self.r, self.torques, self.iterations = np.asarray(e), np.asarray(r), torques, iterations
        self.outputs = {"eps": float(np.hypot(*e) / params.inner.c), "eps_outer": float(np.hypot(*r) / params.outer.c),
                        "omega_ring": float(Om), "x_ring": float(r[0]), "y_ring": float(r[1])}


class MCRingStation:
    """One station's floating ring with mass-conserving films (both ``cavitation = 1``): its two
    :class:`~bearing_fmu.model.BearingModel` kept between speeds (warm starts of the steady films
    and of the equilibria) and :meth:`point`."""

    def __init__(self, params: RingParams):
        from bearing_fmu.model import BearingModel
        for side in ("inner", "outer"):
            if getattr(params, side).cavitation != 1:
                raise ValueError(f"MCRingStation: the {side} film is half-Sommerfeld (cavitation_{side} = 0); "
                                 "the mass-conserving ring linearisation needs cavitation_inner = cavitation_outer = 1")
        self.params = params
        self.inner, self.outer = BearingModel(params.inner), BearingModel(params.outer)
        self.qi = self.qo = None
        self.ratio = None            # the last speed's Omega / omega (the next speed's first guess)
        #: journal speed [rad/s] -> the warm start of the operating point found there (:meth:`continued`)
        self.converged: dict[float, tuple] = {}

    def _films(self, load, omega, Om):
        """Both films' steady states at ring speed Om: inner (journal relative to ring) carries the
        load at wedge speed omega + Om, outer the load plus the ring's weight at Om; returns
        (net torque on the ring, (T_ri, T_ro, T_j), e, r, lin_inner, lin_outer)."""
        from bearing_fmu.floating_ring_statics import shear_torques
        from bearing_fmu.linearize import mc_static_equilibrium
        p = self.params
        ld = np.asarray(load, float)
        Fi = -ld                                             # the inner film's force on the journal
        Fo = Fi + np.array([0.0, p.m_ring * p.gravity])      # ring: -F_i + F_o - m_r g e_y = 0
        out = []
        for b, F, w, q in ((self.inner, Fi, omega + Om, self.qi), (self.outer, Fo, Om, self.qo)):
            if q is None:       # mid-gap on the side opposite the force, a quarter turn with the spin
                a = math.atan2(-F[1], -F[0]) + math.pi / 4
                q = 0.5 * b.c * np.array([math.cos(a), math.sin(a)])
            with np.errstate(all="ignore"):
                out.append(mc_static_equilibrium(b, F, w, guess=q))
        (e, lin_i), (r, lin_o) = out
        self.qi, self.qo = e, r
        pi_, po = p.inner, p.outer
        Tj, Tri = shear_torques(self.inner.fields(), e[0], e[1], pi_.c, pi_.R, pi_.B, pi_.eta0, omega, Om, omega + Om)
        Tro, _ = shear_torques(self.outer.fields(), r[0], r[1], po.c, po.R, po.B, po.eta0, Om, 0.0, Om)
        return Tri + Tro, (Tri, Tro, Tj), e, r, lin_i, lin_o

    def _reset(self):
        """New films and no guesses: a failed equilibrium leaves a film near its clearance's edge."""
        from bearing_fmu.model import BearingModel
        self.inner, self.outer = BearingModel(self.params.inner), BearingModel(self.params.outer)
        self.qi = self.qo = None

    def _snapshot(self) -> tuple:
        """The warm start the station holds after an operating point: (Omega / omega, journal and
        ring positions, the two steady films' states)."""
        return self.ratio, self.qi.copy(), self.qo.copy(), self.inner.film.u.copy(), self.outer.film.u.copy()

    def _restore(self, snapshot: tuple) -> None:
        """Films (new models) and guesses of a :meth:`_snapshot`: the next :meth:`point` starts there
        as from the speed it was taken at (:func:`bearing_fmu.linearize.mc_static_equilibrium` reads
        only the film state a model holds)."""
        from bearing_fmu.model import BearingModel
        ratio, qi, qo, ui, uo = snapshot
        self.inner, self.outer = BearingModel(self.params.inner), BearingModel(self.params.outer)
        for b, q, u in ((self.inner, qi, ui), (self.outer, qo, uo)):
            b.initialize(q[0], q[1], 0.0, 0.0, 0.0)
            b.film.init_state(u)
        self.ratio, self.qi, self.qo = ratio, qi.copy(), qo.copy()

    def _trial(self, load, omega, Om, toward):
        """(Om, :meth:`_films` there); when a film has no equilibrium at Om (a secant trial too slow for
        the outer film to carry its load), up to 4 points halfway towards ``toward``, as
        :func:`operating_point` does."""
        from bearing_fmu.linearize import HSEquilibriumError
        from bearing_fmu.model import StepFailed
        for _ in range(4 if toward is not None else 0):
            try:
                return Om, self._films(load, omega, Om)
            except (HSEquilibriumError, StepFailed):
                self._reset()
                Om = 0.5 * (Om + toward)
        try:
            return Om, self._films(load, omega, Om)
        except (HSEquilibriumError, StepFailed):
            self._reset()
            raise

    def point(self, load, omega, omega_ring=None, rtol=1e-6, max_iter=30) -> MCRingPoint:
        """The steady operating point at journal speed omega under the static ``load`` (2,) [N]:
        ring speed Omega where the two films' torques on the ring balance (secant in Omega from
        the last speed's ratio, or the concentric Petroff ratio; converged when the step is below
        ``rtol`` omega), each film at its mass-conserving static equilibrium
        (:func:`bearing_fmu.linearize.mc_static_equilibrium`) for that Omega. ``omega_ring``: the
        ring speed given instead (no torque balance)."""
        if omega_ring is not None:
            T, Ts, e, r, li, lo = self._films(load, omega, float(omega_ring))
            return MCRingPoint(self.params, li, lo, omega_ring, e, r, Ts, 0)
        ratio = petroff_ratio(self.params) if self.ratio is None else self.ratio
        a = ratio * omega
        fa = self._trial(load, omega, a, None)[1][0]
        b = 0.95 * a
        for it in range(1, max_iter + 1):
            b, (fb, Ts, e, r, li, lo) = self._trial(load, omega, b, a)
            if abs(b - a) < rtol * omega or fb == 0.0:
                self.ratio = b / omega
                self.converged[float(omega)] = self._snapshot()
                return MCRingPoint(self.params, li, lo, b, e, r, Ts, it)
            new = b - fb * (b - a) / (fb - fa) if fb != fa else b
            a, fa, b = b, fb, min(max(new, 0.05 * b), omega)
        raise RuntimeError(f"no torque balance of the ring's mass-conserving films at {omega / (2 * math.pi):.4g} Hz "
                           f"in {max_iter} secant steps (last ring speed ratio {b / omega:.5f})")

    def continued(self, load, omega, *, halvings=CONTINUATION_HALVINGS, max_points=CONTINUATION_POINTS) -> MCRingPoint:
        """:meth:`point` at omega by natural-parameter continuation in the speed, for a speed whose
        :meth:`point` fails from the warm start the station holds (a lightly loaded ring's steady film
        from the cold start) while a neighbouring speed's operating point is known: from the warm start
        of the converged speed nearest omega (:attr:`converged`), steps towards omega, each from the
        last operating point found; a step that fails is halved (up to ``halvings`` times in a row), at
        most ``max_points`` operating points are tried. Raises RuntimeError naming where it started,
        how far it came and what failed (or that no speed has converged yet). The station is left at
        the operating point found, or after a failure as :meth:`point` leaves it."""
        hz = lambda w: f"{w / (2 * math.pi):.6g}"      # noqa: E731
        if not self.converged:
            raise RuntimeError("no speed has an operating point yet to continue from")
        start = min(self.converged, key=lambda w: (abs(w - omega), w))
        w0, step, halved, last, w = start, omega - start, 0, None, omega
        self._restore(self.converged[w0])
        for _ in range(max_points):
            w = omega if abs(step) >= abs(omega - w0) else w0 + step
            try:
                pt = self.point(load, w)
            except _point_errors() as exc:
                last = exc
                if halved == halvings:
                    break
                step, halved = 0.5 * step, halved + 1
                self._restore(self.converged[w0])      # a failed point leaves new films (_reset)
                continue
            if w == omega:
                return pt
            w0, halved = w, 0
        why = (f"the step to {hz(w)} Hz ({abs(step) / (2 * math.pi):.3g} Hz) failed after {halved} halvings in a row "
               f"({last})" if last is not None and halved == halvings
               else f"{max_points} operating points tried"
               + (f", the last failed ({last})" if last is not None else ""))
        raise RuntimeError(f"continuation from {hz(start)} Hz reached {hz(w0)} Hz: {why}")


def mc_ring_films(points) -> list:
    """The films of the rotor-ring system in :class:`RingRotor`'s order: inner, outer per station."""
    return [f for p in points for f in (p.inner, p.outer)]
